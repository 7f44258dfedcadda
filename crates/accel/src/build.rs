//! Binned SAH construction of the canonical binary BVH.
//!
//! Follows Wald, "On fast Construction of SAH-based Bounding Volume Hierarchies" (RT 2007):
//! primitive centroids are binned along each axis, the surface area heuristic is evaluated
//! at every bin boundary, and primitives are partitioned in place. Subtrees above
//! [`PARALLEL_MIN`] primitives are built in parallel with `rayon::join`, and the binning of
//! very large nodes is itself parallel. Leaf cost counts SIMD blocks (`leaf_block`
//! primitives are tested at once), as Embree's builders do.

use crate::geom::Aabb;
use glam::{Vec3, Vec4};

mod spatial;
pub use spatial::ALPHA;
pub(crate) use spatial::{Clipper, NoClip, TriangleClip};

/// Number of bins per axis.
pub const BINS: usize = 32;
/// Subtrees with more primitives than this are built as separate rayon tasks.
pub const PARALLEL_MIN: usize = 1024;
/// Nodes per parallel task of [`BinaryBvh::cost_of`].
const COST_CHUNK: usize = 8192;
/// Nodes with more primitives than this are binned in parallel.
const PARALLEL_BIN_MIN: usize = 1 << 14;
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
    /// Primitives intersected together (the leaf SIMD width, a power of two); leaf cost is
    /// in blocks.
    pub leaf_block: usize,
    /// SAH cost of one traversal step, relative to one block intersection.
    pub cost_traverse: f32,
    /// Nodes of at most this many primitives are not binned: their primitives are sorted
    /// along the widest centroid axis and halved down to leaves (0: never). For top
    /// levels, whose leaves hold single instances: below the width of a wide node the
    /// binary structure mostly disappears when the tree is collapsed, and binning these
    /// many small nodes was a large part of the build.
    pub median_max: usize,
    /// Spatial splits (Stich et al. 2009, see `spatial`) may add at most this many
    /// references, as a share of the primitives (0: none). Only builds given a clipper
    /// that can split their primitives use it.
    pub spatial: f32,
}

impl Default for BuildConfig {
    fn default() -> Self {
        Self { max_leaf: 8, leaf_block: 4, cost_traverse: 1.0, median_max: 0, spatial: 0.0 }
    }
}

/// One primitive to build over: its box and its id (32 bytes, two SIMD registers).
///
/// PERF: the id rides in the w lane of `lo` (as bits), so box unions are plain SIMD
/// min/max; the w lanes of unions are garbage and never read. The bits are offset by
/// [`ID_BIAS`] so that w always holds a *normal* float: raw small ids would be denormals,
/// and every SIMD operation touching them would take a slow microcode assist.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct PrimRef {
    lo: Vec4,
    hi: Vec4,
}

/// Offset of the id bits: the smallest normal f32. Ids must be below `MAX_PRIMS`.
const ID_BIAS: u32 = 0x0080_0000;
/// Most primitives one build takes (their biased bits stay below +inf).
pub const MAX_PRIMS: u32 = 1 << 30;

impl PrimRef {
    /// A reference to primitive `id` (below [`MAX_PRIMS`]) with box `b`.
    #[must_use]
    pub fn new(b: Aabb, id: u32) -> Self {
        debug_assert!(id < MAX_PRIMS);
        Self { lo: b.min.extend(f32::from_bits(id + ID_BIAS)), hi: b.max.extend(1.0) }
    }
    /// Primitive id.
    #[inline(always)]
    #[must_use]
    pub fn id(&self) -> u32 {
        self.lo.w.to_bits() - ID_BIAS
    }
    /// Lower corner.
    #[must_use]
    pub fn min(&self) -> Vec3 {
        self.lo.truncate()
    }
    /// Upper corner.
    #[must_use]
    pub fn max(&self) -> Vec3 {
        self.hi.truncate()
    }
    #[inline(always)]
    fn centroid2(&self) -> Vec4 {
        self.lo + self.hi
    }
    #[inline(always)]
    fn box4(&self) -> Box4 {
        Box4 { lo: self.lo, hi: self.hi }
    }
    /// A reference to `id` with box `b` (its xyz lanes), marked with `side` (a spatial
    /// partition's mark in the w lane of `hi`, which is otherwise unused: any normal float).
    #[inline(always)]
    fn with_box(b: &Box4, id: u32, side: f32) -> Self {
        Self { lo: b.lo.truncate().extend(f32::from_bits(id + ID_BIAS)), hi: b.hi.truncate().extend(side) }
    }
    #[inline(always)]
    fn set_side(&mut self, side: f32) {
        self.hi.w = side;
    }
    #[inline(always)]
    fn side(&self) -> f32 {
        self.hi.w
    }
}

/// A box in SIMD form for the builder's hot loops.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Box4 {
    lo: Vec4,
    hi: Vec4,
}

impl Box4 {
    const EMPTY: Self = Self { lo: Vec4::INFINITY, hi: Vec4::NEG_INFINITY };
    #[inline(always)]
    fn add(&mut self, p: &PrimRef) {
        self.lo = self.lo.min(p.lo);
        self.hi = self.hi.max(p.hi);
    }
    #[inline(always)]
    fn grow(&mut self, c: Vec4) {
        self.lo = self.lo.min(c);
        self.hi = self.hi.max(c);
    }
    #[inline(always)]
    fn union(self, o: Self) -> Self {
        Self { lo: self.lo.min(o.lo), hi: self.hi.max(o.hi) }
    }
    #[inline(always)]
    fn half_area(&self) -> f32 {
        let e = (self.hi - self.lo).truncate();
        if e.x < 0.0 {
            return 0.0;
        }
        e.x * e.y + e.y * e.z + e.z * e.x
    }
    fn aabb(&self) -> Aabb {
        Aabb { min: self.lo.truncate(), max: self.hi.truncate() }
    }
    /// True when `lo > hi` (or NaN) on some axis.
    #[inline(always)]
    fn is_empty(&self) -> bool {
        !(self.lo.x <= self.hi.x && self.lo.y <= self.hi.y && self.lo.z <= self.hi.z)
    }
    /// Half the surface area of the intersection with `o` (0 when they do not meet).
    fn overlap_area(&self, o: &Self) -> f32 {
        let b = Self { lo: self.lo.max(o.lo), hi: self.hi.min(o.hi) };
        if b.is_empty() {
            0.0
        } else {
            b.half_area()
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
        Self::cost_of(&self.nodes, cfg)
    }

    /// SAH cost of a node array (root first) that may hold unused slots only if they are
    /// reachable; every entry is counted.
    pub(crate) fn cost_of(nodes: &[BinNode], cfg: &BuildConfig) -> f32 {
        let Some(root) = nodes.first() else {
            return 0.0;
        };
        let ra = root.bounds.half_area().max(f32::MIN_POSITIVE);
        let part = |nodes: &[BinNode]| {
            let mut c = 0.0f64;
            for n in nodes {
                let a = (n.bounds.half_area() / ra) as f64;
                if n.is_leaf() {
                    c += a * blocks(n.count as usize, cfg.leaf_block) as f64;
                } else {
                    c += a * cfg.cost_traverse as f64;
                }
            }
            c
        };
        // Chunks summed in parallel, then in order: the same sum on any number of threads.
        use rayon::prelude::*;
        let parts: Vec<f64> = nodes.par_chunks(COST_CHUNK).map(part).collect();
        parts.iter().sum::<f64>() as f32
    }

    /// Checks the tree's invariants: children inside parents, every primitive slot in
    /// exactly one leaf (at most one with `cfg.spatial`, whose spare room may stay unused),
    /// leaf sizes within bounds. Returns a description of the first violation.
    pub fn validate(&self, cfg: &BuildConfig) -> Result<(), String> {
        if self.nodes.is_empty() {
            return if self.prims.is_empty() { Ok(()) } else { Err("primitives but no nodes".into()) };
        }
        let mut seen = vec![0u8; self.prims.len()];
        let mut stack = vec![(0usize, 0u32)];
        while let Some((i, depth)) = stack.pop() {
            let n = self.nodes.get(i).ok_or_else(|| format!("node {i} out of range"))?;
            if depth > MAX_DEPTH {
                return Err(format!("depth {depth} beyond {MAX_DEPTH}"));
            }
            if n.is_leaf() {
                if n.count as usize > cfg.max_leaf.max(1) {
                    return Err(format!("leaf {i} has {} primitives", n.count));
                }
                for p in n.first..n.first + n.count {
                    let pr = self.prims.get(p as usize).ok_or_else(|| format!("leaf {i} prim {p} out of range"))?;
                    if !(n.bounds.contains(pr.min()) && n.bounds.contains(pr.max())) {
                        return Err(format!("leaf {i} does not contain prim {}", pr.id()));
                    }
                    seen[p as usize] += 1;
                }
            } else {
                for c in [n.first as usize, n.right as usize] {
                    let cn = self.nodes.get(c).ok_or_else(|| format!("child {c} of {i} out of range"))?;
                    if !(cn.bounds.is_empty() || n.bounds.contains(cn.bounds.min) && n.bounds.contains(cn.bounds.max)) {
                        return Err(format!("child {c} sticks out of node {i}"));
                    }
                    stack.push((c, depth + 1));
                }
            }
        }
        // With spatial splits, slots of unused spare room are in no leaf.
        let gaps_allowed = cfg.spatial > 0.0;
        if let Some(p) = seen.iter().position(|&s| s > 1 || s == 0 && !gaps_allowed) {
            return Err(format!("prim slot {p} is in {} leaves", seen[p]));
        }
        Ok(())
    }
}

#[inline(always)]
fn blocks(n: usize, block: usize) -> usize {
    n.div_ceil(block.max(1))
}

/// Whether a primitive can be built over: a finite, non-empty box (a point is fine).
/// Nothing else can be hit, and one non-finite box would spread into every box above it.
#[inline]
fn usable(p: &PrimRef) -> bool {
    let b = Aabb { min: p.min(), max: p.max() };
    b.is_finite() && !b.is_empty()
}

/// `prims` without those that are not [`usable`] (their ids are kept, so the rest still
/// name their primitives). One read of the array when all are usable.
fn usable_only(prims: &[PrimRef]) -> Option<Vec<PrimRef>> {
    (!prims.iter().all(usable)).then(|| prims.iter().copied().filter(usable).collect())
}

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
struct Ctx<'a, C> {
    cfg: &'a BuildConfig,
    clip: &'a C,
    /// Spatial splits are searched where the object split's sides overlap by more (α times
    /// the root's half area).
    min_overlap: f32,
}

fn bounds_of(prims: &[PrimRef]) -> (Box4, Box4) {
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
struct Bins<const N: usize> {
    b: [[Box4; N]; 3],
    n: [[u32; N]; 3],
}

impl<const N: usize> Bins<N> {
    fn new() -> Self {
        Self { b: [[Box4::EMPTY; N]; 3], n: [[0; N]; 3] }
    }
    fn merge(mut self, o: &Self) -> Self {
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
struct Binner {
    origin: Vec4,
    scale: Vec4,
    /// Bins in use.
    nb: usize,
}

impl Binner {
    fn new(cb: &Box4, nb: usize) -> Self {
        let ext = cb.hi - cb.lo;
        let s = |e: f32| if e > 0.0 { (nb as f32 * 0.9999) / e } else { 0.0 };
        Self { origin: cb.lo, scale: Vec4::new(s(ext.x), s(ext.y), s(ext.z), 0.0), nb }
    }
    /// Bin indices on all three axes (each below `nb`).
    #[inline(always)]
    fn bins(&self, c2: Vec4) -> [usize; 3] {
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
    fn fill<const N: usize>(&self, prims: &[PrimRef]) -> Bins<N> {
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
fn fill_sets<const N: usize, const S: usize>(prims: &[PrimRef], add: impl Fn(&mut Bins<N>, &PrimRef)) -> Bins<N> {
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

struct Split {
    axis: usize,
    bin: usize,
    cost: f32,
    /// The sides' boxes.
    left: Box4,
    right: Box4,
}

/// Best SAH split of `prims` (bins: fewer for small nodes, where the sweep would dominate).
/// PERF: nodes of 5 to 15 primitives took 60 cycles per primitive with 8 bins, most of it
/// the fixed cost of the bins and the sweep; with 4 they take 36, for a tree within 0.2%
/// of the same SAH cost and 0.2–0.4% more triangle groups.
/// The sides' boxes are filled in only when `sides` is set (else empty).
fn find_split(prims: &[PrimRef], cb: &Box4, cfg: &BuildConfig, sides: bool) -> (Option<Split>, Binner) {
    match prims.len() {
        0..16 => find_split_n::<4>(prims, cb, cfg, sides),
        16..64 => find_split_n::<8>(prims, cb, cfg, sides),
        64..1024 => find_split_n::<16>(prims, cb, cfg, sides),
        _ => find_split_n::<BINS>(prims, cb, cfg, sides),
    }
}

fn find_split_n<const N: usize>(prims: &[PrimRef], cb: &Box4, cfg: &BuildConfig, sides: bool) -> (Option<Split>, Binner) {
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
fn block_shift(block: usize) -> u32 {
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
fn partition(prims: &mut [PrimRef], binner: &Binner, split: &Split) -> (usize, [(Box4, Box4); 2]) {
    // The axis as a constant inside the loop (a run-time lane index was a jump per primitive).
    match split.axis {
        0 => partition_on::<0>(prims, binner, split.bin),
        1 => partition_on::<1>(prims, binner, split.bin),
        _ => partition_on::<2>(prims, binner, split.bin),
    }
}

fn partition_on<const AXIS: usize>(prims: &mut [PrimRef], binner: &Binner, bin: usize) -> (usize, [(Box4, Box4); 2]) {
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

/// Nodes of at most this many primitives are partitioned by [`small_partition`].
const SMALL_PART: usize = 512;

/// [`block_partition`] for at most [`SMALL_PART`] elements: each element is copied to the
/// next free slot at the left or the right end of a buffer, chosen without a branch, and
/// the buffer is copied back. The left side keeps its order and the right side is
/// reversed. PERF: a small node's side of a primitive is a coin toss too, and the block
/// passes need two blocks, so below 16 elements the two-pointer loop (about one
/// misprediction per two elements) did everything. Measured in cycles per primitive:
/// 19 → 13 below 64 primitives, 9.6 → 7 below 1024 (512 elements of buffer, 16 KB of
/// stack, did as well as 1024).
fn small_partition(v: &mut [PrimRef], right: impl Fn(&PrimRef) -> bool) -> usize {
    let n = v.len();
    debug_assert!(n <= SMALL_PART);
    let mut buf = [std::mem::MaybeUninit::<PrimRef>::uninit(); SMALL_PART];
    let (mut lo, mut hi) = (0usize, n);
    for p in v.iter() {
        let r = right(p);
        // One store: at `lo` for the left side, at `hi - 1` for the right (branch-free
        // select); both cursors then move by the flag.
        let at = if r { hi - 1 } else { lo };
        buf[at.min(SMALL_PART - 1)].write(*p);
        lo += usize::from(!r);
        hi -= usize::from(r);
    }
    debug_assert_eq!(lo, hi);
    for (dst, src) in v.iter_mut().zip(&buf[..n]) {
        // SAFETY: every slot of `buf[..n]` was written: the left cursor filled `[0, lo)`,
        // the right one `[hi, n)`, and `lo == hi` at the end (each element moved one of them).
        *dst = unsafe { src.assume_init() };
    }
    lo
}

/// Elements per block of [`block_partition`]'s first pass.
const PART_BLOCK: usize = 64;

/// Moves the elements for which `right` is false before those for which it is true, in
/// place; returns how many are false. The block partition of Edelkamp & Weiß
/// ("BlockQuicksort: Avoiding Branch Mispredictions in Quicksort", ESA 2016): a block at
/// each end is classified without branches into a list of the offsets that must move,
/// and pairs from the two lists are swapped. Blocks of 64, then of 8 for what is left,
/// then a plain loop for the last few. PERF: the side of a primitive is a coin toss near
/// the middle of a node, and the two-pointer loop's branch on it mispredicted about half
/// the time.
fn block_partition(v: &mut [PrimRef], right: impl Fn(&PrimRef) -> bool) -> usize {
    let (l, r) = block_pass::<PART_BLOCK>(v, 0, v.len(), &right);
    let (mut i, mut j) = block_pass::<8>(v, l, r, &right);
    // The plain two-pointer loop settles any order of [i, j).
    while i < j {
        if right(&v[i]) {
            j -= 1;
            v.swap(i, j);
        } else {
            i += 1;
        }
    }
    i
}

/// The block loop of [`block_partition`] over the unsettled range `[l, r)` of `v` (all
/// before `l` is left, all from `r` on is right), while it holds two blocks of `B`
/// (at most 256); returns the range still unsettled, in which elements may be in any order.
#[inline(always)]
fn block_pass<const B: usize>(v: &mut [PrimRef], mut l: usize, mut r: usize, right: &impl Fn(&PrimRef) -> bool) -> (usize, usize) {
    // Besides [l, r), the listed offsets of the current blocks still must move.
    let mut offs_l = [0u8; B];
    let mut offs_r = [0u8; B];
    let (mut start_l, mut num_l, mut start_r, mut num_r) = (0usize, 0usize, 0usize, 0usize);
    while r - l >= 2 * B {
        if num_l == 0 {
            start_l = 0;
            for (k, p) in v[l..l + B].iter().enumerate() {
                offs_l[num_l] = k as u8;
                num_l += usize::from(right(p));
            }
        }
        if num_r == 0 {
            start_r = 0;
            for (k, p) in v[r - B..r].iter().rev().enumerate() {
                offs_r[num_r] = k as u8;
                num_r += usize::from(!right(p));
            }
        }
        let m = num_l.min(num_r);
        for k in 0..m {
            v.swap(l + offs_l[start_l + k] as usize, r - 1 - offs_r[start_r + k] as usize);
        }
        (num_l, num_r, start_l, start_r) = (num_l - m, num_r - m, start_l + m, start_r + m);
        if num_l == 0 {
            l += B;
        }
        if num_r == 0 {
            r -= B;
        }
    }
    (l, r)
}

fn make_leaf(nodes: &mut Vec<BinNode>, bounds: Box4, offset: usize, n: usize) -> u32 {
    nodes.push(BinNode { bounds: bounds.aabb(), first: offset as u32, right: 0, count: n as u32 });
    (nodes.len() - 1) as u32
}

/// Builds the node over the `live` references at the front of `all`; the rest of `all` is
/// spare room for spatial splits. `offset` is where `all` starts in the whole array.
#[allow(clippy::too_many_arguments)]
fn build_rec<C: Clipper>(
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
fn build_small(cfg: &BuildConfig, prims: &mut [PrimRef], offset: usize, nodes: &mut Vec<BinNode>) -> (u32, Box4) {
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
    fn rec(leaf: usize, prims: &[PrimRef], offset: usize, nodes: &mut Vec<BinNode>) -> (u32, Box4) {
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

/// Spreads the low 10 bits of `v` to every third bit (for 30-bit Morton codes).
fn spread3(v: u32) -> u32 {
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
    keys: Vec<(u32, u32)>,
    tmp: Vec<(u32, u32)>,
    codes: Vec<u32>,
    runs: Vec<(u32, u32)>,
    /// Where each run starts in the output's primitives.
    starts: Vec<u32>,
    refs: Vec<PrimRef>,
    /// The tree the last build made.
    pub bvh: BinaryBvh,
}

/// The primitives' Morton order into `s.keys`: `(code, index)` pairs sorted by code (30-bit
/// codes of the centroids in their bounds, an LSD radix sort in three passes of 10 bits;
/// stable, so equal codes keep index order), and the codes alone into `s.codes`.
fn morton_order(prims: &[PrimRef], s: &mut MortonScratch) {
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
fn morton_mid(codes: &[u32], lo: usize, hi: usize) -> usize {
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
    fn cut(codes: &[u32], lo: usize, hi: usize, cluster: usize, runs: &mut Vec<(u32, u32)>) {
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
    fn rec(codes: &[u32], prims: &[PrimRef], lo: usize, hi: usize, max_leaf: usize, nodes: &mut Vec<BinNode>) -> Aabb {
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Spatial splits on seeded soups of long, large and small triangles: the tree is
    /// valid, some triangles were split, the spare room is respected, and every point of
    /// every triangle (a barycentric grid, vertices and edges included) lies in the box of
    /// a leaf that holds that triangle.
    #[test]
    fn split_references_cover_their_triangles() {
        for seed in 0..6u64 {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
            let n = [40usize, 2000, 5000][seed as usize % 3];
            let mut positions = Vec::new();
            let mut indices = Vec::new();
            for i in 0..n {
                // Mostly small triangles; every fifth spans most of the scene.
                let size = if i % 5 == 0 { 10.0 } else { 0.2 };
                let c = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
                for _ in 0..3 {
                    positions.push(c + (Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5) * size);
                }
                let v = 3 * i as u32;
                indices.push([v, v + 1, v + 2]);
            }
            let prims: Vec<PrimRef> = indices
                .iter()
                .enumerate()
                .map(|(i, t)| PrimRef::new(Aabb::from_points(&t.map(|v| positions[v as usize])), i as u32))
                .collect();
            let cfg = BuildConfig { spatial: 0.3, ..BuildConfig::default() };
            let bvh = build_binary_with(prims, &cfg, &TriangleClip { positions: &positions, indices: &indices });
            bvh.validate(&cfg).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            assert!(bvh.prims.len() <= n + (n as f32 * 0.3) as usize, "seed {seed}: spare room overrun");
            let mut leaves_of = vec![Vec::new(); n];
            let mut refs = 0;
            for node in bvh.nodes.iter().filter(|x| x.is_leaf()) {
                for p in &bvh.prims[node.first as usize..(node.first + node.count) as usize] {
                    leaves_of[p.id() as usize].push(node.bounds);
                    refs += 1;
                }
            }
            assert!(refs > n || n < spatial::MIN_REFS, "seed {seed}: no triangle was split ({refs} references)");
            for (id, t) in indices.iter().enumerate() {
                let v = t.map(|i| positions[i as usize]);
                // The points in f64, so that their own rounding does not leave the triangle.
                let inside = |bx: &Aabb, p: [f64; 3]| (0..3).all(|k| f64::from(bx.min[k]) <= p[k] && p[k] <= f64::from(bx.max[k]));
                for a in 0..=16 {
                    for b in 0..=16 - a {
                        let (s, u) = (f64::from(a) / 16.0, f64::from(b) / 16.0);
                        let p: [f64; 3] = std::array::from_fn(|k| {
                            let (x, y, z) = (f64::from(v[0][k]), f64::from(v[1][k]), f64::from(v[2][k]));
                            x * (1.0 - s - u) + y * s + z * u
                        });
                        assert!(
                            leaves_of[id].iter().any(|bx| inside(bx, p)),
                            "seed {seed}: triangle {id} point {p:?} is in none of its leaves"
                        );
                    }
                }
            }
        }
    }

    /// Both partitions against their definition, on sizes around their block boundaries
    /// and size limit, and with every share of right-hand elements (seeded).
    #[test]
    fn partitions_split_every_arrangement() {
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let b = PART_BLOCK;
        type Side = fn(&PrimRef) -> bool;
        let small: fn(&mut [PrimRef], Side) -> usize = |v, r| small_partition(v, r);
        let block: fn(&mut [PrimRef], Side) -> usize = |v, r| block_partition(v, r);
        let cases = (0..5 * b + 3).chain([16 * b, 16 * b + 1, 1000]).map(|n| (n, block, "block"));
        let cases = cases.chain((0..=SMALL_PART).map(|n| (n, small, "small")));
        for (n, partition, name) in cases {
            for share in [0u64, 1, 10, 50, 90, 99, 100] {
                let mut v: Vec<PrimRef> = (0..n)
                    .map(|i| {
                        let x = if next() % 100 < share { 1.0 } else { 0.0 };
                        PrimRef::new(Aabb { min: Vec3::splat(x), max: Vec3::splat(x) }, i as u32)
                    })
                    .collect();
                let right: Side = |p| p.min().x > 0.5;
                let want = v.iter().filter(|p| !right(p)).count();
                let mut before: Vec<(u32, bool)> = v.iter().map(|p| (p.id(), right(p))).collect();
                let nl = partition(&mut v, right);
                assert_eq!(nl, want, "{name}: n {n} share {share}");
                assert!(v[..nl].iter().all(|p| !right(p)) && v[nl..].iter().all(right), "{name}: n {n} share {share}");
                let mut after: Vec<(u32, bool)> = v.iter().map(|p| (p.id(), right(p))).collect();
                before.sort_unstable();
                after.sort_unstable();
                assert_eq!(before, after, "{name}: not a permutation: n {n} share {share}");
            }
        }
    }
}
