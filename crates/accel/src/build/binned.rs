//! Binned SAH construction (Wald, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies", RT 2007): primitive centroids are binned along each axis, the surface area
//! heuristic is evaluated at every bin boundary, and primitives are partitioned in place;
//! spatial splits where they pay (`super::spatial`).

use super::prim::*;
use super::spatial::{self, Clipper, NoClip};
use crate::geom::Aabb;
use glam::Vec4;

/// Builds the binary BVH over `prims` (any order). Primitives with non-finite or empty
/// boxes are left out: no leaf holds them.
#[must_use]
pub fn build_binary(prims: Vec<PrimRef>, cfg: &BuildConfig) -> BinaryBvh {
    let prims = usable_only(&prims).unwrap_or(prims);
    build_binary_with(prims, cfg, &NoClip)
}

/// [`build_binary`] with spatial splits of up to `cfg.spatial` extra references, made by
/// `clip` (none with [`NoClip`]). A primitive may then be in several leaves, each with the
/// box of its part there, and [`BinaryBvh::prims`] may hold gaps that no leaf covers.
pub(crate) fn build_binary_with<C: Clipper>(mut prims: Vec<PrimRef>, cfg: &BuildConfig, clip: &C) -> BinaryBvh {
    if prims.is_empty() {
        return BinaryBvh::default();
    }
    let n = prims.len();
    let (bounds, cbounds) = bounds_of(&prims);
    let spare = if C::ON && cfg.spatial > 0.0 { (n as f64 * f64::from(cfg.spatial)) as usize } else { 0 };
    if spare > 0 {
        // Spare room for the split references; what stays unused keeps these copies.
        prims.resize(n + spare, prims[0]);
    }
    let ctx = Ctx { cfg, clip, min_overlap: spatial::ALPHA * bounds.half_area() };
    let mut nodes = Vec::with_capacity(n / 2 + 1);
    build_rec(&ctx, &mut prims, n, 0, bounds, cbounds, 0, &mut nodes);
    BinaryBvh { nodes, prims }
}

/// What every node of a build shares.
pub(crate) struct Ctx<'a, C> {
    pub(crate) cfg: &'a BuildConfig,
    pub(crate) clip: &'a C,
    /// Spatial splits are searched where the object split's sides overlap by more (α times
    /// the root's half area).
    pub(crate) min_overlap: f32,
}

pub(crate) fn bounds_of(prims: &[PrimRef]) -> (Box4, Box4) {
    // PERF: two sets of accumulators, alternate primitives: with one, each min and max
    // waited on the previous one's result (a latency-bound loop).
    let fold = |s: &[PrimRef]| {
        let mut b = [Box4::EMPTY; 2];
        let mut c = [Box4::EMPTY; 2];
        let mut pairs = s.chunks_exact(2);
        for pair in &mut pairs {
            b[0].add(&pair[0]);
            c[0].grow(pair[0].centroid2());
            b[1].add(&pair[1]);
            c[1].grow(pair[1].centroid2());
        }
        for p in pairs.remainder() {
            b[0].add(p);
            c[0].grow(p.centroid2());
        }
        (b[0].union(b[1]), c[0].union(c[1]))
    };
    if prims.len() > PARALLEL_BIN_MIN {
        use rayon::prelude::*;
        prims.par_chunks(PARALLEL_BIN_MIN / 4).map(fold).reduce(|| (Box4::EMPTY, Box4::EMPTY), |a, b| (a.0.union(b.0), a.1.union(b.1)))
    } else {
        fold(prims)
    }
}

#[derive(Clone, Copy)]
pub(crate) struct Bins<const N: usize> {
    pub(crate) b: [[Box4; N]; 3],
    pub(crate) n: [[u32; N]; 3],
}

impl<const N: usize> Bins<N> {
    pub(crate) fn new() -> Self {
        Self { b: [[Box4::EMPTY; N]; 3], n: [[0; N]; 3] }
    }
    pub(crate) fn merge(mut self, o: &Self) -> Self {
        for k in 0..3 {
            for i in 0..N {
                self.b[k][i] = self.b[k][i].union(o.b[k][i]);
                self.n[k][i] += o.n[k][i];
            }
        }
        self
    }
}

/// Maps doubled centroids to bins along each axis.
#[derive(Clone, Copy)]
pub(crate) struct Binner {
    pub(crate) origin: Vec4,
    pub(crate) scale: Vec4,
    /// Bins in use.
    pub(crate) nb: usize,
}

impl Binner {
    pub(crate) fn new(cb: &Box4, nb: usize) -> Self {
        let ext = cb.hi - cb.lo;
        let s = |e: f32| if e > 0.0 { (nb as f32 * 0.9999) / e } else { 0.0 };
        Self { origin: cb.lo, scale: Vec4::new(s(ext.x), s(ext.y), s(ext.z), 0.0), nb }
    }
    /// Bin indices on all three axes (each below `nb`).
    #[inline(always)]
    pub(crate) fn bins(&self, c2: Vec4) -> [usize; 3] {
        // max/min also turn a NaN into 0 (SSE semantics), so the truncation below is in range.
        let f = ((c2 - self.origin) * self.scale).max(Vec4::ZERO).min(Vec4::splat((self.nb - 1) as f32));
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_cvttps_epi32, _mm_storeu_si128};
            // PERF: one truncating SIMD conversion instead of three saturating `as` casts.
            let mut out = [0i32; 4];
            // SAFETY: SSE2 is baseline on x86-64; `out` holds four i32.
            unsafe { _mm_storeu_si128(out.as_mut_ptr().cast(), _mm_cvttps_epi32(f.into())) };
            [out[0] as usize, out[1] as usize, out[2] as usize]
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            [f.x as usize, f.y as usize, f.z as usize]
        }
    }
    pub(crate) fn fill<const N: usize>(&self, prims: &[PrimRef]) -> Bins<N> {
        // PERF: two sets of bins, alternate primitives: neighbours often fall into the same
        // bin, and one set makes every update wait for the previous one's store (the binning
        // loop was a chain of store-to-load forwards).
        let add = |bins: &mut Bins<N>, p: &PrimRef| {
            let idx = self.bins(p.centroid2());
            for (k, &i) in idx.iter().enumerate() {
                // `i < nb <= N`; the `min` lets the compiler drop the bounds check.
                let i = i.min(N - 1);
                bins.b[k][i].add(p);
                bins.n[k][i] += 1;
            }
        };
        // PERF: a small node takes one set: for it, two sets cost more to set up and merge
        // than the stalls they avoid (copies of empty bins showed as 7% of a 12k-triangle
        // build's profile; one set saved about 1.5% of that build). A large node takes
        // four: its primitives are neighbours in space after the partitions above it, so
        // two apart still often share a bin (14 cycles per primitive with two sets, 11
        // with four; the merges are noise at this size).
        match prims.len() {
            0..64 => fill_sets::<N, 1>(prims, add),
            64..1024 => fill_sets::<N, 2>(prims, add),
            _ => fill_sets::<N, 4>(prims, add),
        }
    }
}

/// Bins `prims` into `S` sets of bins, the primitives in turn, and merges the sets (min,
/// max and counts: the same bins in any order).
#[inline(always)]
pub(crate) fn fill_sets<const N: usize, const S: usize>(prims: &[PrimRef], add: impl Fn(&mut Bins<N>, &PrimRef)) -> Bins<N> {
    let mut sets = [Bins::<N>::new(); S];
    let mut groups = prims.chunks_exact(S);
    for g in &mut groups {
        for (set, p) in sets.iter_mut().zip(g) {
            add(set, p);
        }
    }
    for p in groups.remainder() {
        add(&mut sets[0], p);
    }
    sets[1..].iter().fold(sets[0], |a, b| a.merge(b))
}

pub(crate) struct Split {
    pub(crate) axis: usize,
    pub(crate) bin: usize,
    pub(crate) cost: f32,
    /// The sides' boxes.
    pub(crate) left: Box4,
    pub(crate) right: Box4,
}

/// Best SAH split of `prims` (bins: fewer for small nodes, where the sweep would dominate).
/// PERF: nodes of 5 to 15 primitives took 60 cycles per primitive with 8 bins, most of it
/// the fixed cost of the bins and the sweep; with 4 they take 36, for a tree within 0.2%
/// of the same SAH cost and 0.2–0.4% more triangle groups.
/// The sides' boxes are filled in only when `sides` is set (else empty).
pub(crate) fn find_split(prims: &[PrimRef], cb: &Box4, cfg: &BuildConfig, sides: bool) -> (Option<Split>, Binner) {
    match prims.len() {
        0..16 => find_split_n::<4>(prims, cb, cfg, sides),
        16..64 => find_split_n::<8>(prims, cb, cfg, sides),
        64..1024 => find_split_n::<16>(prims, cb, cfg, sides),
        _ => find_split_n::<BINS>(prims, cb, cfg, sides),
    }
}

pub(crate) fn find_split_n<const N: usize>(prims: &[PrimRef], cb: &Box4, cfg: &BuildConfig, sides: bool) -> (Option<Split>, Binner) {
    let binner = Binner::new(cb, N);
    let bins = if prims.len() > PARALLEL_BIN_MIN {
        use rayon::prelude::*;
        prims.par_chunks(PARALLEL_BIN_MIN / 4).map(|c| binner.fill::<N>(c)).reduce(Bins::new, |a, b| a.merge(&b))
    } else {
        binner.fill::<N>(prims)
    };
    // Block counts by shift and add, not by division, and no branches on the candidates.
    let sh = block_shift(cfg.leaf_block);
    let round = (1u32 << sh) - 1;
    let mut best_cost = f32::INFINITY;
    let mut best = (0usize, 0usize);
    for k in 0..3 {
        if binner.scale[k] == 0.0 {
            continue;
        }
        let mut right_cost = [0.0f32; N];
        let mut acc = Box4::EMPTY;
        let mut n = 0u32;
        for i in (1..N).rev() {
            acc = acc.union(bins.b[k][i]);
            n += bins.n[k][i];
            // An empty side makes the candidate invalid: infinite cost.
            right_cost[i] = if n == 0 { f32::INFINITY } else { acc.half_area() * ((n + round) >> sh) as f32 };
        }
        let mut acc = Box4::EMPTY;
        let mut n = 0u32;
        for (i, &right) in right_cost.iter().enumerate().skip(1) {
            acc = acc.union(bins.b[k][i - 1]);
            n += bins.n[k][i - 1];
            let left = if n == 0 { f32::INFINITY } else { acc.half_area() * ((n + round) >> sh) as f32 };
            let cost = left + right;
            if cost < best_cost {
                best_cost = cost;
                best = (k, i);
            }
        }
    }
    let split = (best_cost < f32::INFINITY).then(|| {
        let (k, i) = best;
        let side = |r: std::ops::Range<usize>| if sides { bins.b[k][r].iter().fold(Box4::EMPTY, |a, b| a.union(*b)) } else { Box4::EMPTY };
        Split { axis: k, bin: i, cost: best_cost, left: side(0..i), right: side(i..N) }
    });
    (split, binner)
}

/// `log2` of the leaf block size (a power of two).
#[inline(always)]
pub(crate) fn block_shift(block: usize) -> u32 {
    debug_assert!(block.max(1).is_power_of_two(), "leaf_block must be a power of two");
    block.max(1).trailing_zeros()
}

/// Partitions `prims` by the split (bin below `split.bin` on `split.axis` goes left), in
/// place; returns the left count and the bounds and centroid bounds of both sides. The bin
/// is computed in scalar with the operations of [`Binner::bins`], so it agrees with the
/// binning. The partition is in place and without branches on the sides
/// ([`block_partition`]); the bounds of each side are taken afterwards, in a pass of
/// their own. (An out-of-place branchless partition was tried: it helped small top levels
/// but its extra copies slowed the builds of large meshes by 15%.)
pub(crate) fn partition(prims: &mut [PrimRef], binner: &Binner, split: &Split) -> (usize, [(Box4, Box4); 2]) {
    // The axis as a constant inside the loop (a run-time lane index was a jump per primitive).
    match split.axis {
        0 => partition_on::<0>(prims, binner, split.bin),
        1 => partition_on::<1>(prims, binner, split.bin),
        _ => partition_on::<2>(prims, binner, split.bin),
    }
}

pub(crate) fn partition_on<const AXIS: usize>(prims: &mut [PrimRef], binner: &Binner, bin: usize) -> (usize, [(Box4, Box4); 2]) {
    let (o, sc, top) = (binner.origin[AXIS], binner.scale[AXIS], (binner.nb - 1) as f32);
    // PERF: `trunc(x) < bin` is `x < bin` for the clamped `x ≥ 0`, so the bin is compared
    // as a float (the saturating `as i32` cast was a compare, a conversion and a
    // conditional move per primitive, on the partition's critical path).
    let bin = bin as f32;
    let right = |p: &PrimRef| ((p.centroid2()[AXIS] - o) * sc).max(0.0).min(top) >= bin;
    let nl = if prims.len() <= SMALL_PART { small_partition(prims, right) } else { block_partition(prims, right) };
    let (l, r) = prims.split_at(nl);
    (nl, [bounds_of(l), bounds_of(r)])
}

pub(crate) fn make_leaf(nodes: &mut Vec<BinNode>, bounds: Box4, offset: usize, n: usize) -> u32 {
    nodes.push(BinNode { bounds: bounds.aabb(), first: offset as u32, right: 0, count: n as u32 });
    (nodes.len() - 1) as u32
}

/// Builds the node over the `live` references at the front of `all`; the rest of `all` is
/// spare room for spatial splits. `offset` is where `all` starts in the whole array.
#[allow(clippy::too_many_arguments)]
pub(crate) fn build_rec<C: Clipper>(
    ctx: &Ctx<C>,
    all: &mut [PrimRef],
    live: usize,
    offset: usize,
    bounds: Box4,
    cbounds: Box4,
    depth: u32,
    nodes: &mut Vec<BinNode>,
) -> u32 {
    let cfg = ctx.cfg;
    let n = live;
    let max_leaf = cfg.max_leaf.max(1);
    // One block fits: a split costs at least cost_traverse·A ≥ the leaf's one block·A, so
    // no SAH evaluation is needed (this skips binning for the many tiny nodes).
    if n <= 1 || (n <= cfg.leaf_block.min(max_leaf) && cfg.cost_traverse >= 1.0) {
        return make_leaf(nodes, bounds, offset, n);
    }
    if n <= cfg.median_max {
        return build_small(cfg, &mut all[..n], offset, nodes).0;
    }
    // Room for more references: spatial splits are possible here.
    let room = C::ON && all.len() > n;
    let (split, binner) = if depth >= MEDIAN_DEPTH { (None, Binner::new(&cbounds, 2)) } else { find_split(&all[..n], &cbounds, cfg, room) };
    // A spatial split, where the object split's sides overlap; taken when it is cheaper.
    let spatial = match &split {
        Some(s) if room && n >= spatial::MIN_REFS && s.left.overlap_area(&s.right) > ctx.min_overlap => {
            spatial::find(&all[..n], &bounds, cfg).filter(|sp| sp.cost < s.cost)
        }
        _ => None,
    };
    let area = bounds.half_area();
    let leaf_cost = blocks(n, cfg.leaf_block) as f32 * area;
    let worth = |cost: f32| n > max_leaf || cfg.cost_traverse * area + cost < leaf_cost;
    let (nl, end, sides) = match (split, spatial) {
        (_, Some(sp)) if worth(sp.cost) => {
            let (nl, end) = spatial::partition(all, n, &sp, ctx.clip);
            let (l, r) = all[..end].split_at(nl);
            (nl, end, [bounds_of(l), bounds_of(r)])
        }
        (Some(s), None) if worth(s.cost) => {
            let (nl, sides) = partition(&mut all[..n], &binner, &s);
            (nl, n, sides)
        }
        _ if n <= max_leaf => return make_leaf(nodes, bounds, offset, n),
        _ => {
            // No useful split (equal centroids, or too deep): object median along the widest axis.
            let prims = &mut all[..n];
            let axis = cbounds.aabb().extent().max_position();
            let mid = n / 2;
            prims.select_nth_unstable_by(mid, |a, b| a.centroid2()[axis].total_cmp(&b.centroid2()[axis]));
            let (l, r) = prims.split_at(mid);
            (mid, n, [bounds_of(l), bounds_of(r)])
        }
    };
    let nr = end - nl;
    // The spare room left, handed on to the children that may still split (in proportion
    // to their references): the right side's references move up past the left side's
    // share. Only min(share, nr) of them move: the order within a side does not matter.
    let spare = all.len() - end;
    let wants = |m: usize| if C::ON && m >= spatial::MIN_REFS { m } else { 0 };
    let (wl, wr) = (wants(nl), wants(nr));
    let give_l = if spare == 0 || wl + wr == 0 { 0 } else { (spare as f64 * wl as f64 / (wl + wr) as f64) as usize };
    let give_r = if wr == 0 { 0 } else { spare - give_l };
    if give_l > 0 {
        let k = give_l.min(nr);
        all.copy_within(nl..nl + k, nl + give_l + nr - k);
    }
    let me = nodes.len();
    nodes.push(BinNode { bounds: bounds.aabb(), first: 0, right: 0, count: 0 });
    let (left, rest) = all.split_at_mut(nl + give_l);
    let right = &mut rest[..nr + give_r];
    let roff = offset + nl + give_l;
    let [(bl, cl), (br, cr)] = sides;
    let (li, ri) = if n > PARALLEL_MIN {
        // The left subtree goes straight into `nodes`; only the right one is built apart
        // and copied in (PERF: copying both halves at every parallel level was 14% of a
        // 10k-instance top-level build). Sized for a typical tree so it does not regrow.
        let mut rn = Vec::with_capacity(nr);
        let (li, _) = rayon::join(
            || build_rec(ctx, left, nl, offset, bl, cl, depth + 1, nodes),
            || build_rec(ctx, right, nr, roff, br, cr, depth + 1, &mut rn),
        );
        (li, append(nodes, rn))
    } else {
        let li = build_rec(ctx, left, nl, offset, bl, cl, depth + 1, nodes);
        let ri = build_rec(ctx, right, nr, roff, br, cr, depth + 1, nodes);
        (li, ri)
    };
    nodes[me].first = li;
    nodes[me].right = ri;
    me as u32
}

/// A small node ([`BuildConfig::median_max`]): its primitives sorted once along the widest
/// centroid axis, then halved down to leaves of one block, bounds computed bottom-up.
/// Returns the node index and its bounds.
pub(crate) fn build_small(cfg: &BuildConfig, prims: &mut [PrimRef], offset: usize, nodes: &mut Vec<BinNode>) -> (u32, Box4) {
    let mut cb = Box4::EMPTY;
    for p in prims.iter() {
        cb.grow(p.centroid2());
    }
    let axis = cb.aabb().extent().max_position();
    // Insertion sort: n is a handful.
    for i in 1..prims.len() {
        let mut j = i;
        while j > 0 && prims[j - 1].centroid2()[axis] > prims[j].centroid2()[axis] {
            prims.swap(j - 1, j);
            j -= 1;
        }
    }
    pub(crate) fn rec(leaf: usize, prims: &[PrimRef], offset: usize, nodes: &mut Vec<BinNode>) -> (u32, Box4) {
        let n = prims.len();
        if n <= leaf {
            let mut b = Box4::EMPTY;
            for p in prims {
                b.add(p);
            }
            return (make_leaf(nodes, b, offset, n), b);
        }
        let me = nodes.len();
        nodes.push(BinNode { bounds: Aabb::EMPTY, first: 0, right: 0, count: 0 });
        let mid = n / 2;
        let (l, bl) = rec(leaf, &prims[..mid], offset, nodes);
        let (r, br) = rec(leaf, &prims[mid..], offset + mid, nodes);
        let b = bl.union(br);
        nodes[me] = BinNode { bounds: b.aabb(), first: l, right: r, count: 0 };
        (me as u32, b)
    }
    rec(cfg.leaf_block.min(cfg.max_leaf).max(1), prims, offset, nodes)
}

/// Appends a subtree built into its own vector (its root at index 0), relocating child
/// indices; returns the new index of its root.
pub(crate) fn append(nodes: &mut Vec<BinNode>, sub: Vec<BinNode>) -> u32 {
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
