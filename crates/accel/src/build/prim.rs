//! The parts of a build: its settings ([`BuildConfig`]), the primitive references it
//! sorts ([`PrimRef`]), boxes four floats wide (`Box4`), the canonical binary BVH it makes
//! ([`BinaryBvh`]), and the in-place partition of references the builders share.

use crate::geom::Aabb;
use glam::{Vec3, Vec4};

/// Number of bins per axis.
pub const BINS: usize = 32;
/// Subtrees with more primitives than this are built as separate rayon tasks.
pub const PARALLEL_MIN: usize = 1024;
/// Nodes per parallel task of [`BinaryBvh::cost_of`].
pub(crate) const COST_CHUNK: usize = 8192;
/// Nodes with more primitives than this are binned in parallel.
pub(crate) const PARALLEL_BIN_MIN: usize = 1 << 14;
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
/// `ID_BIAS` so that w always holds a *normal* float: raw small ids would be denormals,
/// and every SIMD operation touching them would take a slow microcode assist.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct PrimRef {
    pub(crate) lo: Vec4,
    pub(crate) hi: Vec4,
}

/// Offset of the id bits: the smallest normal f32. Ids must be below `MAX_PRIMS`.
pub(crate) const ID_BIAS: u32 = 0x0080_0000;
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
    pub(crate) fn centroid2(&self) -> Vec4 {
        self.lo + self.hi
    }
    #[inline(always)]
    pub(crate) fn box4(&self) -> Box4 {
        Box4 { lo: self.lo, hi: self.hi }
    }
    /// A reference to `id` with box `b` (its xyz lanes), marked with `side` (a spatial
    /// partition's mark in the w lane of `hi`, which is otherwise unused: any normal float).
    #[inline(always)]
    pub(crate) fn with_box(b: &Box4, id: u32, side: f32) -> Self {
        Self { lo: b.lo.truncate().extend(f32::from_bits(id + ID_BIAS)), hi: b.hi.truncate().extend(side) }
    }
    #[inline(always)]
    pub(crate) fn set_side(&mut self, side: f32) {
        self.hi.w = side;
    }
    #[inline(always)]
    pub(crate) fn side(&self) -> f32 {
        self.hi.w
    }
}

/// A box in SIMD form for the builder's hot loops.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Box4 {
    pub(crate) lo: Vec4,
    pub(crate) hi: Vec4,
}

impl Box4 {
    pub(crate) const EMPTY: Self = Self { lo: Vec4::INFINITY, hi: Vec4::NEG_INFINITY };
    #[inline(always)]
    pub(crate) fn add(&mut self, p: &PrimRef) {
        self.lo = self.lo.min(p.lo);
        self.hi = self.hi.max(p.hi);
    }
    #[inline(always)]
    pub(crate) fn grow(&mut self, c: Vec4) {
        self.lo = self.lo.min(c);
        self.hi = self.hi.max(c);
    }
    #[inline(always)]
    pub(crate) fn union(self, o: Self) -> Self {
        Self { lo: self.lo.min(o.lo), hi: self.hi.max(o.hi) }
    }
    #[inline(always)]
    pub(crate) fn half_area(&self) -> f32 {
        let e = (self.hi - self.lo).truncate();
        if e.x < 0.0 {
            return 0.0;
        }
        e.x * e.y + e.y * e.z + e.z * e.x
    }
    pub(crate) fn aabb(&self) -> Aabb {
        Aabb { min: self.lo.truncate(), max: self.hi.truncate() }
    }
    /// True when `lo > hi` (or NaN) on some axis.
    #[inline(always)]
    pub(crate) fn is_empty(&self) -> bool {
        !(self.lo.x <= self.hi.x && self.lo.y <= self.hi.y && self.lo.z <= self.hi.z)
    }
    /// Half the surface area of the intersection with `o` (0 when they do not meet).
    pub(crate) fn overlap_area(&self, o: &Self) -> f32 {
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
pub(crate) fn blocks(n: usize, block: usize) -> usize {
    n.div_ceil(block.max(1))
}

/// Whether a primitive can be built over: a finite, non-empty box (a point is fine).
/// Nothing else can be hit, and one non-finite box would spread into every box above it.
#[inline]
pub(crate) fn usable(p: &PrimRef) -> bool {
    let b = Aabb { min: p.min(), max: p.max() };
    b.is_finite() && !b.is_empty()
}

/// `prims` without those that are not [`usable`] (their ids are kept, so the rest still
/// name their primitives). One read of the array when all are usable.
pub(crate) fn usable_only(prims: &[PrimRef]) -> Option<Vec<PrimRef>> {
    (!prims.iter().all(usable)).then(|| prims.iter().copied().filter(usable).collect())
}

/// Nodes of at most this many primitives are partitioned by [`small_partition`].
pub(crate) const SMALL_PART: usize = 512;

/// [`block_partition`] for at most [`SMALL_PART`] elements: each element is copied to the
/// next free slot at the left or the right end of a buffer, chosen without a branch, and
/// the buffer is copied back. The left side keeps its order and the right side is
/// reversed. PERF: a small node's side of a primitive is a coin toss too, and the block
/// passes need two blocks, so below 16 elements the two-pointer loop (about one
/// misprediction per two elements) did everything. Measured in cycles per primitive:
/// 19 → 13 below 64 primitives, 9.6 → 7 below 1024 (512 elements of buffer, 16 KB of
/// stack, did as well as 1024).
pub(crate) fn small_partition(v: &mut [PrimRef], right: impl Fn(&PrimRef) -> bool) -> usize {
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
pub(crate) const PART_BLOCK: usize = 64;

/// Moves the elements for which `right` is false before those for which it is true, in
/// place; returns how many are false. The block partition of Edelkamp & Weiß
/// ("BlockQuicksort: Avoiding Branch Mispredictions in Quicksort", ESA 2016): a block at
/// each end is classified without branches into a list of the offsets that must move,
/// and pairs from the two lists are swapped. Blocks of 64, then of 8 for what is left,
/// then a plain loop for the last few. PERF: the side of a primitive is a coin toss near
/// the middle of a node, and the two-pointer loop's branch on it mispredicted about half
/// the time.
pub(crate) fn block_partition(v: &mut [PrimRef], right: impl Fn(&PrimRef) -> bool) -> usize {
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
pub(crate) fn block_pass<const B: usize>(
    v: &mut [PrimRef],
    mut l: usize,
    mut r: usize,
    right: &impl Fn(&PrimRef) -> bool,
) -> (usize, usize) {
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
