//! Binned SAH construction of the canonical binary BVH.
//!
//! Follows Wald, "On fast Construction of SAH-based Bounding Volume Hierarchies" (RT 2007):
//! primitive centroids are binned along each axis, the surface area heuristic is evaluated
//! at every bin boundary, and primitives are partitioned in place. Subtrees above
//! [`PARALLEL_MIN`] primitives are built in parallel with `rayon::join`, and the binning of
//! very large nodes is itself parallel. Leaf cost counts SIMD blocks (`leaf_block`
//! primitives are tested at once), as Embree's builders do.

use crate::geom::Aabb;
use glam::Vec3;

/// Number of bins per axis.
pub const BINS: usize = 32;
/// Subtrees with more primitives than this are built as separate rayon tasks.
pub const PARALLEL_MIN: usize = 4096;
/// Nodes with more primitives than this are binned in parallel.
const PARALLEL_BIN_MIN: usize = 1 << 16;
/// Beyond this depth the builder splits at the object median, which bounds the depth
/// (and so the traversal stack) on pathological input.
pub const MEDIAN_DEPTH: u32 = 40;
/// An upper bound on the depth of any tree this builder makes (median splits of up to
/// 2^32 primitives after [`MEDIAN_DEPTH`]).
pub const MAX_DEPTH: u32 = MEDIAN_DEPTH + 33;

/// Builder settings.
#[derive(Clone, Copy, Debug)]
pub struct BuildConfig {
    /// Most primitives in one leaf.
    pub max_leaf: usize,
    /// Primitives intersected together (the leaf SIMD width); leaf cost is in blocks.
    pub leaf_block: usize,
    /// SAH cost of one traversal step, relative to one block intersection.
    pub cost_traverse: f32,
}

impl Default for BuildConfig {
    fn default() -> Self {
        Self {
            max_leaf: 8,
            leaf_block: 4,
            cost_traverse: 1.0,
        }
    }
}

/// One primitive to build over: its box and its id.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct PrimRef {
    /// Lower corner.
    pub min: Vec3,
    /// Primitive id.
    pub id: u32,
    /// Upper corner.
    pub max: Vec3,
    _pad: u32,
}

impl PrimRef {
    /// A reference to primitive `id` with box `b`.
    #[must_use]
    pub fn new(b: Aabb, id: u32) -> Self {
        Self {
            min: b.min,
            id,
            max: b.max,
            _pad: 0,
        }
    }
    #[inline(always)]
    fn centroid2(&self) -> Vec3 {
        self.min + self.max
    }
    fn aabb(&self) -> Aabb {
        Aabb {
            min: self.min,
            max: self.max,
        }
    }
}

/// A node of the binary BVH. `count > 0` marks a leaf over `prims[first..first + count]`;
/// otherwise `first` and `right` are the child node indices.
#[derive(Clone, Copy, Debug)]
pub struct BinNode {
    /// Bounds of everything below.
    pub bounds: Aabb,
    /// Left child (inner) or first primitive (leaf).
    pub first: u32,
    /// Right child (inner).
    pub right: u32,
    /// Number of primitives (leaf) or 0 (inner).
    pub count: u32,
}

impl BinNode {
    /// True for a leaf.
    #[must_use]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// The binary BVH: nodes (root at index 0 when there are primitives) and primitives in
/// leaf order.
#[derive(Clone, Debug, Default)]
pub struct BinaryBvh {
    /// Nodes, root first.
    pub nodes: Vec<BinNode>,
    /// Primitive references, reordered so every leaf is a contiguous range.
    pub prims: Vec<PrimRef>,
}

impl BinaryBvh {
    /// SAH cost of the tree (Goldsmith & Salmon / MacDonald & Booth), with leaf cost in blocks.
    #[must_use]
    pub fn sah_cost(&self, cfg: &BuildConfig) -> f32 {
        let Some(root) = self.nodes.first() else {
            return 0.0;
        };
        let ra = root.bounds.half_area().max(f32::MIN_POSITIVE);
        let mut c = 0.0f64;
        for n in &self.nodes {
            let a = (n.bounds.half_area() / ra) as f64;
            if n.is_leaf() {
                c += a * blocks(n.count as usize, cfg.leaf_block) as f64;
            } else {
                c += a * cfg.cost_traverse as f64;
            }
        }
        c as f32
    }

    /// Checks the tree's invariants: children inside parents, every primitive in exactly
    /// one leaf, leaf sizes within bounds. Returns a description of the first violation.
    pub fn validate(&self, cfg: &BuildConfig) -> Result<(), String> {
        if self.nodes.is_empty() {
            return if self.prims.is_empty() {
                Ok(())
            } else {
                Err("primitives but no nodes".into())
            };
        }
        let mut seen = vec![0u8; self.prims.len()];
        let mut stack = vec![(0usize, 0u32)];
        while let Some((i, depth)) = stack.pop() {
            let n = self
                .nodes
                .get(i)
                .ok_or_else(|| format!("node {i} out of range"))?;
            if depth > MAX_DEPTH {
                return Err(format!("depth {depth} beyond {MAX_DEPTH}"));
            }
            if n.is_leaf() {
                if n.count as usize > cfg.max_leaf.max(1) {
                    return Err(format!("leaf {i} has {} primitives", n.count));
                }
                for p in n.first..n.first + n.count {
                    let pr = self
                        .prims
                        .get(p as usize)
                        .ok_or_else(|| format!("leaf {i} prim {p} out of range"))?;
                    if !(n.bounds.contains(pr.min) && n.bounds.contains(pr.max)) {
                        return Err(format!("leaf {i} does not contain prim {}", pr.id));
                    }
                    seen[p as usize] += 1;
                }
            } else {
                for c in [n.first as usize, n.right as usize] {
                    let cn = self
                        .nodes
                        .get(c)
                        .ok_or_else(|| format!("child {c} of {i} out of range"))?;
                    if !(cn.bounds.is_empty()
                        || n.bounds.contains(cn.bounds.min) && n.bounds.contains(cn.bounds.max))
                    {
                        return Err(format!("child {c} sticks out of node {i}"));
                    }
                    stack.push((c, depth + 1));
                }
            }
        }
        if let Some(p) = seen.iter().position(|&s| s != 1) {
            return Err(format!("prim slot {p} is in {} leaves", seen[p]));
        }
        Ok(())
    }
}

#[inline(always)]
fn blocks(n: usize, block: usize) -> usize {
    n.div_ceil(block.max(1))
}

/// Builds the binary BVH over `prims` (any order; primitives with non-finite or empty
/// boxes must already be left out by the caller).
#[must_use]
pub fn build_binary(mut prims: Vec<PrimRef>, cfg: &BuildConfig) -> BinaryBvh {
    if prims.is_empty() {
        return BinaryBvh::default();
    }
    let (bounds, cbounds) = bounds_of(&prims);
    let mut nodes = Vec::with_capacity(prims.len() / 2 + 1);
    build_rec(cfg, &mut prims, 0, bounds, cbounds, 0, &mut nodes);
    BinaryBvh { nodes, prims }
}

fn bounds_of(prims: &[PrimRef]) -> (Aabb, Aabb) {
    let fold = |s: &[PrimRef]| {
        let mut b = Aabb::EMPTY;
        let mut c = Aabb::EMPTY;
        for p in s {
            b = b.union(p.aabb());
            c = c.grow(p.centroid2());
        }
        (b, c)
    };
    if prims.len() > PARALLEL_BIN_MIN {
        use rayon::prelude::*;
        prims.par_chunks(PARALLEL_BIN_MIN / 4).map(fold).reduce(
            || (Aabb::EMPTY, Aabb::EMPTY),
            |a, b| (a.0.union(b.0), a.1.union(b.1)),
        )
    } else {
        fold(prims)
    }
}

#[derive(Clone, Copy)]
struct Bins {
    b: [[Aabb; BINS]; 3],
    n: [[u32; BINS]; 3],
}

impl Bins {
    fn new() -> Self {
        Self {
            b: [[Aabb::EMPTY; BINS]; 3],
            n: [[0; BINS]; 3],
        }
    }
    fn merge(mut self, o: &Self) -> Self {
        for k in 0..3 {
            for i in 0..BINS {
                self.b[k][i] = self.b[k][i].union(o.b[k][i]);
                self.n[k][i] += o.n[k][i];
            }
        }
        self
    }
}

/// Maps doubled centroids to bins along each axis.
#[derive(Clone, Copy)]
struct Binner {
    origin: Vec3,
    scale: Vec3,
}

impl Binner {
    fn new(cb: &Aabb) -> Self {
        let ext = cb.extent();
        let s = |e: f32| {
            if e > 0.0 {
                (BINS as f32 * 0.9999) / e
            } else {
                0.0
            }
        };
        Self {
            origin: cb.min,
            scale: Vec3::new(s(ext.x), s(ext.y), s(ext.z)),
        }
    }
    #[inline(always)]
    fn bin(&self, c2: Vec3, axis: usize) -> usize {
        let f = (c2[axis] - self.origin[axis]) * self.scale[axis];
        (f.max(0.0) as usize).min(BINS - 1)
    }
    fn fill(&self, prims: &[PrimRef]) -> Bins {
        let mut bins = Bins::new();
        for p in prims {
            let c = p.centroid2();
            let b = p.aabb();
            for k in 0..3 {
                let i = self.bin(c, k);
                bins.b[k][i] = bins.b[k][i].union(b);
                bins.n[k][i] += 1;
            }
        }
        bins
    }
}

struct Split {
    axis: usize,
    bin: usize,
    cost: f32,
}

fn find_split(prims: &[PrimRef], cb: &Aabb, cfg: &BuildConfig) -> (Option<Split>, Binner) {
    let binner = Binner::new(cb);
    let bins = if prims.len() > PARALLEL_BIN_MIN {
        use rayon::prelude::*;
        prims
            .par_chunks(PARALLEL_BIN_MIN / 4)
            .map(|c| binner.fill(c))
            .reduce(Bins::new, |a, b| a.merge(&b))
    } else {
        binner.fill(prims)
    };
    let mut best: Option<Split> = None;
    for k in 0..3 {
        if binner.scale[k] == 0.0 {
            continue;
        }
        let mut right_area = [0.0f32; BINS];
        let mut right_n = [0usize; BINS];
        let mut acc = Aabb::EMPTY;
        let mut n = 0usize;
        for i in (1..BINS).rev() {
            acc = acc.union(bins.b[k][i]);
            n += bins.n[k][i] as usize;
            right_area[i] = acc.half_area();
            right_n[i] = n;
        }
        let mut acc = Aabb::EMPTY;
        let mut n = 0usize;
        for i in 1..BINS {
            acc = acc.union(bins.b[k][i - 1]);
            n += bins.n[k][i - 1] as usize;
            if n == 0 || right_n[i] == 0 {
                continue;
            }
            let cost = acc.half_area() * blocks(n, cfg.leaf_block) as f32
                + right_area[i] * blocks(right_n[i], cfg.leaf_block) as f32;
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(Split {
                    axis: k,
                    bin: i,
                    cost,
                });
            }
        }
    }
    (best, binner)
}

/// Partitions `prims` so that those `go_left` come first; returns the left count and the
/// bounds and centroid bounds of both sides.
fn partition(
    prims: &mut [PrimRef],
    go_left: impl Fn(&PrimRef) -> bool,
) -> (usize, [(Aabb, Aabb); 2]) {
    let mut side = [(Aabb::EMPTY, Aabb::EMPTY); 2];
    let mut i = 0;
    let mut j = prims.len();
    while i < j {
        if go_left(&prims[i]) {
            side[0].0 = side[0].0.union(prims[i].aabb());
            side[0].1 = side[0].1.grow(prims[i].centroid2());
            i += 1;
        } else {
            j -= 1;
            side[1].0 = side[1].0.union(prims[i].aabb());
            side[1].1 = side[1].1.grow(prims[i].centroid2());
            prims.swap(i, j);
        }
    }
    (i, side)
}

fn make_leaf(nodes: &mut Vec<BinNode>, bounds: Aabb, offset: usize, n: usize) -> u32 {
    nodes.push(BinNode {
        bounds,
        first: offset as u32,
        right: 0,
        count: n as u32,
    });
    (nodes.len() - 1) as u32
}

#[allow(clippy::too_many_arguments)]
fn build_rec(
    cfg: &BuildConfig,
    prims: &mut [PrimRef],
    offset: usize,
    bounds: Aabb,
    cbounds: Aabb,
    depth: u32,
    nodes: &mut Vec<BinNode>,
) -> u32 {
    let n = prims.len();
    let max_leaf = cfg.max_leaf.max(1);
    if n <= 1 {
        return make_leaf(nodes, bounds, offset, n);
    }
    let (split, binner) = if depth >= MEDIAN_DEPTH {
        (None, Binner::new(&cbounds))
    } else {
        find_split(prims, &cbounds, cfg)
    };
    let area = bounds.half_area();
    let leaf_cost = blocks(n, cfg.leaf_block) as f32 * area;
    let (nl, sides) = match split {
        Some(s) if n > max_leaf || cfg.cost_traverse * area + s.cost < leaf_cost => {
            partition(prims, |p| binner.bin(p.centroid2(), s.axis) < s.bin)
        }
        _ if n <= max_leaf => return make_leaf(nodes, bounds, offset, n),
        _ => {
            // No useful split (equal centroids, or too deep): object median along the widest axis.
            let axis = cbounds.extent().max_position();
            let mid = n / 2;
            prims.select_nth_unstable_by(mid, |a, b| {
                a.centroid2()[axis].total_cmp(&b.centroid2()[axis])
            });
            let (l, r) = prims.split_at(mid);
            let (bl, cl) = bounds_of(l);
            let (br, cr) = bounds_of(r);
            (mid, [(bl, cl), (br, cr)])
        }
    };
    let me = nodes.len();
    nodes.push(BinNode {
        bounds,
        first: 0,
        right: 0,
        count: 0,
    });
    let (left, right) = prims.split_at_mut(nl);
    let [(bl, cl), (br, cr)] = sides;
    let (li, ri) = if n > PARALLEL_MIN {
        let (mut ln, mut rn) = (Vec::new(), Vec::new());
        rayon::join(
            || build_rec(cfg, left, offset, bl, cl, depth + 1, &mut ln),
            || build_rec(cfg, right, offset + nl, br, cr, depth + 1, &mut rn),
        );
        (append(nodes, ln), append(nodes, rn))
    } else {
        let li = build_rec(cfg, left, offset, bl, cl, depth + 1, nodes);
        let ri = build_rec(cfg, right, offset + nl, br, cr, depth + 1, nodes);
        (li, ri)
    };
    nodes[me].first = li;
    nodes[me].right = ri;
    me as u32
}

/// Appends a subtree built into its own vector (its root at index 0), relocating child
/// indices; returns the new index of its root.
fn append(nodes: &mut Vec<BinNode>, sub: Vec<BinNode>) -> u32 {
    let base = nodes.len() as u32;
    nodes.extend(sub.into_iter().map(|mut n| {
        if !n.is_leaf() {
            n.first += base;
            n.right += base;
        }
        n
    }));
    base
}
