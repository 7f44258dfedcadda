//! Builders by Morton order: clusters of Morton-sorted primitives built by binned SAH
//! (for large top levels), and the linear BVH (Lauterbach et al. 2009).

use super::binned::*;
use super::prim::*;
use crate::geom::Aabb;
use glam::Vec4;

/// Spreads the low 10 bits of `v` to every third bit (for 30-bit Morton codes).
pub(crate) fn spread3(v: u32) -> u32 {
    let mut x = v & 0x3ff;
    x = (x | (x << 16)) & 0x0300_00ff;
    x = (x | (x << 8)) & 0x0300_f00f;
    x = (x | (x << 4)) & 0x030c_30c3;
    (x | (x << 2)) & 0x0924_9249
}

/// Buffers of the Morton-order builders ([`build_clustered_into`], [`build_lbvh_into`]),
/// kept by a caller that rebuilds every frame so that no rebuild allocates. (PERF: at 10k
/// instances the buffers are a few hundred kilobytes: above glibc's threshold they are
/// fresh mappings, and their page faults cost as much as the build.)
#[derive(Clone, Debug, Default)]
pub struct MortonScratch {
    /// `(code, index)` in Morton order.
    pub(crate) keys: Vec<(u32, u32)>,
    pub(crate) tmp: Vec<(u32, u32)>,
    pub(crate) codes: Vec<u32>,
    pub(crate) runs: Vec<(u32, u32)>,
    /// Where each run starts in the output's primitives.
    pub(crate) starts: Vec<u32>,
    pub(crate) refs: Vec<PrimRef>,
    /// The tree the last build made.
    pub bvh: BinaryBvh,
}

/// The primitives' Morton order into `s.keys`: `(code, index)` pairs sorted by code (30-bit
/// codes of the centroids in their bounds, an LSD radix sort in three passes of 10 bits;
/// stable, so equal codes keep index order), and the codes alone into `s.codes`.
pub(crate) fn morton_order(prims: &[PrimRef], s: &mut MortonScratch) {
    let (_, cbounds) = bounds_of(prims);
    let lo = cbounds.lo;
    let ext = cbounds.hi - cbounds.lo;
    let inv = |e: f32| if e > 0.0 { 1023.0 / e } else { 0.0 };
    let scale = Vec4::new(inv(ext.x), inv(ext.y), inv(ext.z), 0.0);
    let code = |p: &PrimRef| {
        let q = ((p.centroid2() - lo) * scale).clamp(Vec4::ZERO, Vec4::splat(1023.0)).as_uvec4();
        spread3(q.x) << 2 | spread3(q.y) << 1 | spread3(q.z)
    };
    s.keys.clear();
    s.keys.extend(prims.iter().enumerate().map(|(i, p)| (code(p), i as u32)));
    s.tmp.clear();
    s.tmp.resize(prims.len(), (0, 0));
    for pass in 0..3 {
        let shift = 10 * pass;
        let mut count = [0usize; 1025];
        for k in &s.keys {
            count[((k.0 >> shift) & 1023) as usize + 1] += 1;
        }
        for i in 0..1024 {
            count[i + 1] += count[i];
        }
        for k in &s.keys {
            let d = &mut count[((k.0 >> shift) & 1023) as usize];
            // `*d < keys.len()`: the prefix sums count every key once.
            if let Some(t) = s.tmp.get_mut(*d) {
                *t = *k;
            }
            *d += 1;
        }
        std::mem::swap(&mut s.keys, &mut s.tmp);
    }
    s.codes.clear();
    s.codes.extend(s.keys.iter().map(|k| k.0));
}

/// Where the Morton-sorted range `lo..hi` splits: at the first code with the highest
/// differing bit set (the middle when all codes are equal), never at an end.
pub(crate) fn morton_mid(codes: &[u32], lo: usize, hi: usize) -> usize {
    let (a, z) = (codes[lo], codes[hi - 1]);
    let mid = if a == z {
        (lo + hi) / 2
    } else {
        let bit = 31 - (a ^ z).leading_zeros();
        let mask = !((1u32 << bit) - 1) & !(1u32 << bit);
        let prefix = a & mask;
        lo + codes[lo..hi].partition_point(|&c| c & (mask | 1 << bit) == prefix)
    };
    mid.clamp(lo + 1, hi - 1)
}

/// A top level by binned SAH over clusters (after Garanzha, Pantaleoni and McAllister,
/// "Simpler and Faster HLBVH with Work Queues", HPG 2011): primitives are sorted along a
/// Morton curve and cut, at the highest differing code bit, into runs of at most
/// `cluster`; the SAH tree is built over the runs' boxes, and each run becomes one leaf.
/// The SAH then sees `cluster`-times fewer items, which is most of the build time, while
/// the tree above the runs keeps its quality. Leaves hold up to `cluster` primitives (more
/// than `cfg.max_leaf`): [`crate::wide::collapse_spread`] gives each its own child slot.
#[must_use]
pub fn build_clustered(prims: Vec<PrimRef>, cfg: &BuildConfig, cluster: usize) -> BinaryBvh {
    let mut s = MortonScratch::default();
    build_clustered_into(&prims, cfg, cluster, &mut s);
    s.bvh
}

/// [`build_clustered`] with reused buffers; the tree is left in `s.bvh`.
pub fn build_clustered_into(prims: &[PrimRef], cfg: &BuildConfig, cluster: usize, s: &mut MortonScratch) {
    if let Some(ok) = usable_only(prims) {
        return build_clustered_into(&ok, cfg, cluster, s);
    }
    let cluster = cluster.max(1);
    if prims.len() <= 4 * cluster {
        s.bvh = build_binary(prims.to_vec(), cfg);
        return;
    }
    morton_order(prims, s);
    s.runs.clear();
    pub(crate) fn cut(codes: &[u32], lo: usize, hi: usize, cluster: usize, runs: &mut Vec<(u32, u32)>) {
        if hi - lo <= cluster {
            runs.push((lo as u32, hi as u32));
            return;
        }
        let mid = morton_mid(codes, lo, hi);
        cut(codes, lo, mid, cluster, runs);
        cut(codes, mid, hi, cluster, runs);
    }
    cut(&s.codes, 0, prims.len(), cluster, &mut s.runs);
    s.refs.clear();
    s.refs.extend(s.runs.iter().enumerate().map(|(i, &(lo, hi))| {
        let mut b = Box4::EMPTY;
        for k in &s.keys[lo as usize..hi as usize] {
            b.add(&prims[k.1 as usize]);
        }
        PrimRef::new(b.aabb(), i as u32)
    }));
    let top_cfg = BuildConfig { max_leaf: 1, leaf_block: 1, median_max: 8, ..*cfg };
    let top = build_binary(std::mem::take(&mut s.refs), &top_cfg);
    // The runs' primitives in the top tree's leaf order; each leaf then covers its run.
    let out = &mut s.bvh;
    out.prims.clear();
    s.starts.clear();
    s.starts.resize(s.runs.len(), 0);
    for r in &top.prims {
        let run = r.id() as usize;
        let (lo, hi) = s.runs[run];
        s.starts[run] = out.prims.len() as u32;
        out.prims.extend(s.keys[lo as usize..hi as usize].iter().map(|k| prims[k.1 as usize]));
    }
    out.nodes.clear();
    out.nodes.extend(top.nodes.iter().map(|n| {
        if n.is_leaf() {
            // One run per leaf (max_leaf 1).
            let run = top.prims[n.first as usize].id() as usize;
            let (lo, hi) = s.runs[run];
            BinNode { bounds: n.bounds, first: s.starts[run], right: 0, count: hi - lo }
        } else {
            *n
        }
    }));
    s.refs = top.prims;
}

/// A linear BVH (Lauterbach, Garland, Sengupta, Luebke, Manocha, "Fast BVH Construction
/// on GPUs", Eurographics 2009): primitives sorted along a Morton curve of their
/// centroids, split top-down at the highest differing code bit. Much faster to build than
/// binned SAH and somewhat worse to trace: for top levels over many instances that are
/// rebuilt every frame.
#[must_use]
pub fn build_lbvh(prims: Vec<PrimRef>, max_leaf: usize) -> BinaryBvh {
    let mut s = MortonScratch::default();
    build_lbvh_into(&prims, max_leaf, &mut s);
    s.bvh
}

/// [`build_lbvh`] with reused buffers; the tree is left in `s.bvh`.
pub fn build_lbvh_into(prims: &[PrimRef], max_leaf: usize, s: &mut MortonScratch) {
    if let Some(ok) = usable_only(prims) {
        return build_lbvh_into(&ok, max_leaf, s);
    }
    s.bvh.nodes.clear();
    s.bvh.prims.clear();
    if prims.is_empty() {
        return;
    }
    morton_order(prims, s);
    let max_leaf = max_leaf.max(1);
    s.bvh.prims.extend(s.keys.iter().map(|k| prims[k.1 as usize]));
    s.bvh.nodes.reserve(2 * prims.len() / max_leaf + 1);
    pub(crate) fn rec(codes: &[u32], prims: &[PrimRef], lo: usize, hi: usize, max_leaf: usize, nodes: &mut Vec<BinNode>) -> Aabb {
        let me = nodes.len();
        nodes.push(BinNode { bounds: Aabb::EMPTY, first: lo as u32, right: 0, count: (hi - lo) as u32 });
        if hi - lo <= max_leaf {
            let mut b = Box4::EMPTY;
            for p in &prims[lo..hi] {
                b.add(p);
            }
            nodes[me].bounds = b.aabb();
            return nodes[me].bounds;
        }
        let mid = morton_mid(codes, lo, hi);
        let left = nodes.len() as u32;
        let bl = rec(codes, prims, lo, mid, max_leaf, nodes);
        let right = nodes.len() as u32;
        let br = rec(codes, prims, mid, hi, max_leaf, nodes);
        let b = bl.union(br);
        nodes[me] = BinNode { bounds: b, first: left, right, count: 0 };
        b
    }
    rec(&s.codes, &s.bvh.prims, 0, prims.len(), max_leaf, &mut s.bvh.nodes);
}
