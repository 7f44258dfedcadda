//! Spatial splits for the binned SAH builder.
//!
//! Stich, Friedrich & Dietrich, "Spatial Splits in Bounding Volume Hierarchies" (HPG 2009):
//! besides the object split (primitives partitioned by centroid), a node may be cut by a
//! plane, and a reference that straddles the plane is split into two references, each with
//! the box of its part of the primitive (the triangle clipped to the side of the plane, and
//! to the reference's box). Large and long triangles (Sponza's floors, walls and columns)
//! then stop inflating every box that holds them.
//!
//! What this module follows from the paper:
//! - the search runs only where the best object split's children overlap by more than a
//!   share `α` of the root's area (§4.4; α = [`ALPHA`]);
//! - chopped binning: a reference is counted in its first bin as an entry and in its last
//!   as an exit, and each bin it spans takes its part (§4.2). Unlike the paper, the parts
//!   are its box cut at the bin planes, not the clipped primitive (see `fill`); only the
//!   chosen plane clips primitives;
//! - reference unsplitting: a straddling reference goes whole to one side when that is
//!   cheaper by the SAH than splitting it (§4.3).
//!
//! Unlike the paper, the number of extra references is bounded (a share of the primitives,
//! [`super::BuildConfig::spatial`]), as in Embree's spatial-split builder: the primitive
//! array is allocated with that much spare room, and each node hands its unused room on to
//! its children in proportion to their references. What a leaf does not use stays a gap in
//! [`super::BinaryBvh::prims`].

use super::prim::{block_partition, blocks, Box4, BuildConfig, PrimRef, PARALLEL_BIN_MIN};
use glam::{BVec4A, Vec3, Vec4};

/// Bins per axis of the spatial search.
pub(super) const BINS: usize = 16;
/// Spatial splits are searched only at nodes whose best object split's children overlap by
/// more than this share of the root's surface area (Stich et al. use 1e-5).
pub const ALPHA: f32 = 1e-5;
/// Nodes with fewer references are not searched for spatial splits (nor given spare room).
/// PERF: most splits worth making are near the top. Measured with 8, 128 and 512, 1
/// thread: Sponza's build 43.6 / 31.9 / 26.9 ms for an SAH cost of 44.82 / 44.86 / 45.02
/// and the same diffuse rays (5.2–5.3 Mrays/s); Conference's 120 / 109 / 105 ms for 28.34
/// / 28.55 / 28.45.
pub(super) const MIN_REFS: usize = 512;

/// How references are split at a plane. The builder is generic over it so that builds
/// without spatial splits compile to the plain builder.
pub(crate) trait Clipper: Sync {
    /// False: the builder never searches for spatial splits.
    const ON: bool;
    /// What [`Clipper::split`] needs of a primitive (its vertices, say).
    type Prim: Copy;
    /// The primitive with id `id`.
    fn prim(&self, id: u32) -> Self::Prim;
    /// The boxes of the parts of `prim` below and above `plane` on `axis`, within `bounds`
    /// (the reference's box). Either may be empty (`lo > hi` on some axis). Both must be
    /// conservative: together they cover the primitive's part inside `bounds`.
    fn split(&self, prim: &Self::Prim, bounds: &Box4, axis: usize, plane: f32) -> (Box4, Box4);
}

/// No spatial splits (top levels, refittable meshes).
pub(crate) struct NoClip;

impl Clipper for NoClip {
    const ON: bool = false;
    type Prim = ();
    fn prim(&self, _: u32) {}
    fn split(&self, (): &(), bounds: &Box4, axis: usize, plane: f32) -> (Box4, Box4) {
        // The box itself cut at the plane: conservative for any primitive.
        let (m, p) = (axis_mask(axis), Vec4::splat(plane));
        (
            Box4 { lo: bounds.lo, hi: Vec4::select(m, bounds.hi.min(p), bounds.hi) },
            Box4 { lo: Vec4::select(m, bounds.lo.max(p), bounds.lo), hi: bounds.hi },
        )
    }
}

/// Triangles of an indexed mesh, clipped exactly (up to rounding, which is made
/// conservative).
pub(crate) struct TriangleClip<'a> {
    /// Vertex positions.
    pub positions: &'a [Vec3],
    /// Vertex indices per triangle; a reference's id is its index here.
    pub indices: &'a [[u32; 3]],
}

impl Clipper for TriangleClip<'_> {
    const ON: bool = true;
    type Prim = [Vec4; 3];
    #[inline]
    fn prim(&self, id: u32) -> [Vec4; 3] {
        // Ids come from the build's own references, which index `indices`, whose entries
        // were checked against `positions` before the build.
        let t = self.indices[id as usize];
        t.map(|i| self.positions[i as usize].extend(0.0))
    }
    #[inline]
    fn split(&self, v: &[Vec4; 3], bounds: &Box4, axis: usize, plane: f32) -> (Box4, Box4) {
        split_triangle(v, bounds, axis, plane)
    }
}

/// Relative widening of an edge's crossing point with a plane: the point is computed with
/// four roundings, each at most half an ulp of the edge's largest coordinate; 2^-20 covers
/// them with room (the coordinates' scale, never an absolute epsilon).
const CROSS_SLACK: f32 = 1.0 / (1 << 20) as f32;

/// The boxes of triangle `v`'s parts below and above `plane` on `axis`, within `b`: each
/// side's vertices and the edges' crossing points with the plane (widened by
/// [`CROSS_SLACK`] so the boxes stay conservative after rounding), then clamped to `b` and
/// to the plane.
#[inline]
pub(super) fn split_triangle(v: &[Vec4; 3], b: &Box4, axis: usize, plane: f32) -> (Box4, Box4) {
    let mut l = Box4::EMPTY;
    let mut r = Box4::EMPTY;
    for i in 0..3 {
        let a = v[i];
        let c = v[(i + 1) % 3];
        let (pa, pc) = (a[axis], c[axis]);
        if pa <= plane {
            l.grow(a);
        }
        if pa >= plane {
            r.grow(a);
        }
        if (pa < plane && pc > plane) || (pa > plane && pc < plane) {
            let t = (plane - pa) / (pc - pa);
            let x = a + (c - a) * t;
            let e = (a.abs() + c.abs()) * CROSS_SLACK;
            for p in [x - e, x + e] {
                l.grow(p);
                r.grow(p);
            }
        }
    }
    let (m, p) = (axis_mask(axis), Vec4::splat(plane));
    let lhi = Vec4::select(m, b.hi.min(p), b.hi);
    let rlo = Vec4::select(m, b.lo.max(p), b.lo);
    (Box4 { lo: l.lo.max(b.lo), hi: l.hi.min(lhi) }, Box4 { lo: r.lo.max(rlo), hi: r.hi.min(b.hi) })
}

/// A chosen spatial split.
pub(super) struct SpatialSplit {
    pub axis: usize,
    pub plane: f32,
    /// SAH cost (areas times leaf blocks, as [`super::Split::cost`]).
    pub cost: f32,
    /// The sides' boxes and reference counts as binned (for unsplitting).
    pub left: Box4,
    pub right: Box4,
    pub nl: u32,
    pub nr: u32,
}

#[derive(Clone, Copy)]
struct SBins {
    /// One more box than bins: the last takes what must go nowhere (see `fill`).
    b: [[Box4; BINS + 1]; 3],
    enter: [[u32; BINS]; 3],
    exit: [[u32; BINS]; 3],
}

impl SBins {
    fn new() -> Self {
        Self { b: [[Box4::EMPTY; BINS + 1]; 3], enter: [[0; BINS]; 3], exit: [[0; BINS]; 3] }
    }
    fn merge(mut self, o: &Self) -> Self {
        for k in 0..3 {
            for i in 0..BINS {
                self.b[k][i] = self.b[k][i].union(o.b[k][i]);
                self.enter[k][i] += o.enter[k][i];
                self.exit[k][i] += o.exit[k][i];
            }
        }
        self
    }
}

/// The node's box cut into [`BINS`] slabs per axis.
#[derive(Clone, Copy)]
struct Grid {
    origin: Vec4,
    width: Vec4,
    scale: Vec4,
}

impl Grid {
    fn new(bounds: &Box4) -> Self {
        let ext = bounds.hi - bounds.lo;
        let w = ext / BINS as f32;
        let s = |e: f32| if e > 0.0 { BINS as f32 / e } else { 0.0 };
        // PERF: the w lane of the origin is 0. A box's w lanes hold a reference's id bits
        // (tiny normal floats, see `PrimRef`): the difference of two of them is a denormal,
        // and each such subtraction took a microcode assist.
        Self { origin: bounds.lo.truncate().extend(0.0), width: w, scale: Vec4::new(s(ext.x), s(ext.y), s(ext.z), 0.0) }
    }
    /// The slab of `x` on every axis (NaN and out-of-range values clamped).
    #[inline(always)]
    fn bins(&self, x: Vec4) -> [usize; 3] {
        let f = ((x - self.origin) * self.scale).max(Vec4::ZERO).min(Vec4::splat((BINS - 1) as f32));
        let i = f.as_ivec4();
        // In [0, BINS) after the clamp; the `min` lets the compiler drop bounds checks.
        [(i.x as usize).min(BINS - 1), (i.y as usize).min(BINS - 1), (i.z as usize).min(BINS - 1)]
    }
    /// The planes between slabs `i - 1` and `i` on every axis.
    #[inline(always)]
    fn planes(&self, i: usize) -> Vec4 {
        self.origin + self.width * i as f32
    }
}

/// Chopped binning (Stich et al. §4.2) with the references' boxes cut at the bin planes
/// (not the primitives): a reference is an entry in the bin of its box's low end and an
/// exit in that of its high end, and each bin it spans grows by the box's slice in it.
/// The slices are conservative, so a bin's box may be larger than the clipped primitives'
/// would be; [`partition`] clips the primitives themselves at the chosen plane. PERF:
/// clipping every primitive at every plane it crosses, during the search, needed its
/// vertices (scattered loads) and gave the same trees on the shared scenes (Sponza's SAH
/// 44.74 against 44.82) at 5 times the search's cost.
fn fill(prims: &[PrimRef], grid: &Grid) -> SBins {
    // PERF: two sets of bins, alternate references (neighbours often share a bin, and one
    // set made each update wait for the previous one's store); the slices made by lane
    // selects (a single lane written to a box in memory, then the box loaded whole,
    // stalled on store forwarding); no branch on whether a reference spans bins: the
    // slice above its first bin goes to the spare bin `BINS` when there is none.
    let mut sets = [SBins::new(), SBins::new()];
    for (j, p) in prims.iter().enumerate() {
        let bins = &mut sets[j & 1];
        let b = p.box4();
        let (lo, hi) = (grid.bins(b.lo), grid.bins(b.hi));
        for k in 0..3 {
            let (b0, b1) = (lo[k], hi[k].max(lo[k]));
            let m = axis_mask(k);
            bins.enter[k][b0] += 1;
            bins.exit[k][b1] += 1;
            let first = Box4 { lo: b.lo, hi: Vec4::select(m, b.hi.min(grid.planes(b0 + 1)), b.hi) };
            bins.b[k][b0] = bins.b[k][b0].union(first);
            let last = Box4 { lo: Vec4::select(m, b.lo.max(grid.planes(b1)), b.lo), hi: b.hi };
            let at = if b1 > b0 { b1 } else { BINS };
            bins.b[k][at] = bins.b[k][at].union(last);
            for i in b0 + 1..b1 {
                let mid = Box4 { lo: Vec4::select(m, grid.planes(i), b.lo), hi: Vec4::select(m, grid.planes(i + 1), b.hi) };
                bins.b[k][i] = bins.b[k][i].union(mid);
            }
        }
    }
    sets[0].merge(&sets[1])
}

/// The lane of `axis` (0, 1 or 2) as a select mask.
#[inline(always)]
fn axis_mask(axis: usize) -> BVec4A {
    BVec4A::new(axis == 0, axis == 1, axis == 2, false)
}

/// The best spatial split of the references `prims` of a node with box `bounds`, if any
/// plane separates them.
pub(super) fn find(prims: &[PrimRef], bounds: &Box4, cfg: &BuildConfig) -> Option<SpatialSplit> {
    let grid = Grid::new(bounds);
    let bins = if prims.len() > PARALLEL_BIN_MIN {
        use rayon::prelude::*;
        prims.par_chunks(PARALLEL_BIN_MIN / 4).map(|c| fill(c, &grid)).reduce(SBins::new, |a, b| a.merge(&b))
    } else {
        fill(prims, &grid)
    };
    let block = cfg.leaf_block;
    let mut best: Option<(f32, usize, usize)> = None;
    for k in 0..3 {
        if grid.scale[k] == 0.0 {
            continue;
        }
        let mut right_cost = [f32::INFINITY; BINS];
        let mut acc = Box4::EMPTY;
        let mut n = 0usize;
        for i in (1..BINS).rev() {
            acc = acc.union(bins.b[k][i]);
            n += bins.exit[k][i] as usize;
            if n > 0 {
                right_cost[i] = acc.half_area() * blocks(n, block) as f32;
            }
        }
        let mut acc = Box4::EMPTY;
        let mut n = 0usize;
        for (i, &right) in right_cost.iter().enumerate().skip(1) {
            acc = acc.union(bins.b[k][i - 1]);
            n += bins.enter[k][i - 1] as usize;
            if n == 0 {
                continue;
            }
            let cost = acc.half_area() * blocks(n, block) as f32 + right;
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, k, i));
            }
        }
    }
    let (cost, axis, i) = best.filter(|b| b.0.is_finite())?;
    let mut s = SpatialSplit { axis, plane: grid.planes(i)[axis], cost, left: Box4::EMPTY, right: Box4::EMPTY, nl: 0, nr: 0 };
    for j in 0..i {
        s.left = s.left.union(bins.b[axis][j]);
        s.nl += bins.enter[axis][j];
    }
    for j in i..BINS {
        s.right = s.right.union(bins.b[axis][j]);
        s.nr += bins.exit[axis][j];
    }
    Some(s)
}

/// Splits the `n` references at the front of `prims` by `s`: straddling references are
/// split (the part above the plane into the spare room after `n`, while it lasts) or
/// given whole to the cheaper side; then the references are partitioned, left side
/// first. Returns the left count and the total count.
pub(super) fn partition<C: Clipper>(prims: &mut [PrimRef], n: usize, s: &SpatialSplit, clip: &C) -> (usize, usize) {
    const LEFT: f32 = 1.0;
    const RIGHT: f32 = 2.0;
    let (axis, plane) = (s.axis, s.plane);
    let (al, ar) = (s.left.half_area(), s.right.half_area());
    let (nl, nr) = (s.nl as f32, s.nr as f32);
    let whole_cost = |b: &Box4| {
        // Stich et al. §4.3 (counts in references, not blocks): split, all left, all right.
        let split = al * nl + ar * nr;
        let left = s.left.union(*b).half_area() * nl + ar * (nr - 1.0);
        let right = al * (nl - 1.0) + s.right.union(*b).half_area() * nr;
        (split, left, right)
    };
    let mut end = n;
    for i in 0..n {
        let p = prims[i];
        let b = p.box4();
        let (lo, hi) = (b.lo[axis], b.hi[axis]);
        if hi <= plane {
            prims[i].set_side(LEFT);
            continue;
        }
        if lo >= plane {
            prims[i].set_side(RIGHT);
            continue;
        }
        let (c_split, c_left, c_right) = whole_cost(&b);
        if end == prims.len() || c_left.min(c_right) <= c_split {
            prims[i].set_side(if c_left <= c_right { LEFT } else { RIGHT });
            continue;
        }
        let (l, r) = clip.split(&clip.prim(p.id()), &b, axis, plane);
        match (l.is_empty(), r.is_empty()) {
            (false, false) => {
                prims[i] = PrimRef::with_box(&l, p.id(), LEFT);
                prims[end] = PrimRef::with_box(&r, p.id(), RIGHT);
                end += 1;
            }
            (true, false) => prims[i] = PrimRef::with_box(&r, p.id(), RIGHT),
            (false, true) => prims[i] = PrimRef::with_box(&l, p.id(), LEFT),
            // Rounding emptied both (a sliver in the plane): keep it whole.
            (true, true) => prims[i].set_side(LEFT),
        }
    }
    let nl = block_partition(&mut prims[..end], |p| p.side() > 1.5);
    (nl, end)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// `p` (exact enough: f64) inside `b`.
    fn contains(b: &Box4, p: [f64; 3]) -> bool {
        (0..3).all(|k| f64::from(b.lo[k]) <= p[k] && p[k] <= f64::from(b.hi[k]))
    }

    /// Every point of a triangle inside a box lies in the box of its side's part (the
    /// edges' crossings with the plane in both), for
    /// seeded triangles at scales from 1e-4 to 1e4, planes through them and boxes around
    /// parts of them; and neither part reaches past the plane.
    #[test]
    fn triangle_parts_cover_the_triangle() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        for case in 0..20_000 {
            let scale = 10f32.powi(rng.random_range(-4..=4));
            let off = Vec4::new(rng.random(), rng.random(), rng.random(), 0.0) * scale * 100.0;
            let v: [Vec4; 3] = std::array::from_fn(|_| off + Vec4::new(rng.random(), rng.random(), rng.random(), 0.0) * scale);
            let mut tb = Box4::EMPTY;
            v.iter().for_each(|&p| tb.grow(p));
            // A box: the triangle's, or a random sub-box of it (a reference already split).
            let b = if rng.random_bool(0.5) {
                tb
            } else {
                let t = |lo: f32, hi: f32, r: f32| lo + (hi - lo) * r;
                let lo = Vec4::new(
                    t(tb.lo.x, tb.hi.x, rng.random_range(0.0..0.5)),
                    t(tb.lo.y, tb.hi.y, rng.random_range(0.0..0.5)),
                    t(tb.lo.z, tb.hi.z, rng.random_range(0.0..0.5)),
                    0.0,
                );
                let hi = Vec4::new(
                    t(tb.lo.x, tb.hi.x, rng.random_range(0.5..1.0)),
                    t(tb.lo.y, tb.hi.y, rng.random_range(0.5..1.0)),
                    t(tb.lo.z, tb.hi.z, rng.random_range(0.5..1.0)),
                    0.0,
                );
                Box4 { lo, hi }
            };
            let axis = rng.random_range(0..3);
            let plane = b.lo[axis] + (b.hi[axis] - b.lo[axis]) * rng.random::<f32>();
            let (l, r) = split_triangle(&v, &b, axis, plane);
            assert!(l.is_empty() || l.hi[axis] <= plane, "case {case}: left part past the plane");
            assert!(r.is_empty() || r.lo[axis] >= plane, "case {case}: right part past the plane");
            // The edges' crossings with the plane (in f64) are in both parts: the points
            // where rounding in the parts' boxes would show first.
            for i in 0..3 {
                let (a, c) = (v[i], v[(i + 1) % 3]);
                let (pa, pc, pl) = (f64::from(a[axis]), f64::from(c[axis]), f64::from(plane));
                if (pa - pl) * (pc - pl) >= 0.0 {
                    continue;
                }
                let t = (pl - pa) / (pc - pa);
                let mut x: [f64; 3] = std::array::from_fn(|k| f64::from(a[k]) + (f64::from(c[k]) - f64::from(a[k])) * t);
                x[axis] = pl;
                if contains(&b, x) {
                    assert!(contains(&l, x) && contains(&r, x), "case {case}: crossing {x:?} outside a part: {l:?} {r:?}");
                }
            }
            for _ in 0..64 {
                let (mut s, mut t): (f32, f32) = (rng.random(), rng.random());
                if s + t > 1.0 {
                    (s, t) = (1.0 - s, 1.0 - t);
                }
                // The point in f64, so that its rounding is far below the f32 parts'.
                let (s, t) = (f64::from(s), f64::from(t));
                let p: [f64; 3] = std::array::from_fn(|k| {
                    let (a, b, c) = (f64::from(v[0][k]), f64::from(v[1][k]), f64::from(v[2][k]));
                    a + (b - a) * s + (c - a) * t
                });
                if !contains(&b, p) {
                    continue;
                }
                let side = if p[axis] <= f64::from(plane) { &l } else { &r };
                assert!(contains(side, p), "case {case}: {p:?} (plane {plane} on {axis}) outside its part {side:?}");
            }
        }
    }
}
