//! Packet traversal of 8-wide BVHs for coherent rays (up to [`MAX_PACKET`] = 64 rays, e.g.
//! an 8×8 pixel tile of primary rays, or the shadow rays of such a tile toward one light).
//!
//! The packet is kept as up to eight groups of eight rays in SoA form. Inner nodes are culled
//! for the whole packet at once by **interval arithmetic** (Wald, Boulos & Shirley, "Ray
//! Tracing Deformable Scenes Using Dynamic Bounding Volume Hierarchies", ACM TOG 2007, §4.2;
//! Boulos et al., "Packet-based Whitted and Distribution Ray Tracing", GI 2007): the origins
//! and reciprocal directions of the live rays are bounded per axis by intervals, which gives
//! a conservative entry and exit distance of the whole packet for all eight child boxes in
//! one SIMD pass, and an order of visit (nearest first). Leaves are where the rays part: each
//! group of eight rays is box-tested against the leaf's box (exactly, one ray per lane), and
//! only the groups with a ray inside test the leaf's triangles, eight rays against one
//! triangle at a time, with the same arithmetic as the single-ray unit-triangle test (so the
//! same `t, u, v`, bit for bit). When all rays start at one point, a leaf's triangles are
//! first culled against the whole packet, in the spirit of the shaft and frustum culling of
//! Dmitriev, Havran & Seidel ("Faster Ray Tracing with SIMD Shaft Culling", MPI-I-2004-4-006)
//! and Reshetov, Soupikov & Hurley ("Multi-Level Ray Tracing Algorithm", SIGGRAPH 2005): in
//! the unit-triangle test the barycentric numerators are linear in the direction once the
//! origin is fixed, so their ranges over the packet's direction box bound every ray's
//! (`avx::frustum_keep`). A packet whose rays do not agree on the direction signs
//! has no interval bound; it falls back to single-ray traversal, as Benthin et al. do
//! ("Combining Single and Packet Ray Tracing for Arbitrary Ray Distributions on the Intel
//! MIC Architecture", IEEE TVCG 2012).
//!
//! The code is written on 8-lane arrays ([`F8`], [`M8`]) and compiled twice, once for the
//! baseline CPU and once with AVX2 and FMA enabled, where each array operation becomes one
//! AVX instruction. No multiply-add is fused (Rust never contracts), so both builds give
//! identical answers; tests check both against the single-ray and the reference kernels.

// Group and lane indices address several SoA arrays at once throughout this module.
#![allow(clippy::needless_range_loop)]

use crate::geom::{Hit, Ray, INVALID};
use crate::kernel::{Kernel, KernelSet, ScalarSet};
use crate::traverse::{Counters, TraversalStats, STACK};
use crate::triangle::Tri4;
use crate::wide::{leaf_range, node_at, WideNode, EMPTY, LEAF};
use glam::{Affine3A, Vec3};

/// Most rays in one packet.
pub const MAX_PACKET: usize = 64;
/// Rays per SIMD group.
pub(crate) const LANES: usize = 8;
/// Groups per packet.
pub(crate) const GROUPS: usize = MAX_PACKET / LANES;
/// Entries of a packet's origin and direction vectors: x, y, z, x, y (see [`Packet::o`]).
pub(crate) const CYCLIC: usize = 5;
/// Groups of a packet that must reach a leaf before its triangles are culled against the
/// whole packet ([`avx::frustum_keep`]).
const CULL_GROUPS: usize = 2;
/// Far-distance scale of the conservative box tests (2γ₃ of Ize 2013 is 3.6e-7).
const FAR_SCALE: f32 = 1.0 + 1.0 / (1u32 << 21) as f32;

/// Eight floats, one per lane.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub(crate) struct F8(pub [f32; LANES]);

/// Eight lane masks (all bits set = true).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(32))]
pub(crate) struct M8(pub [i32; LANES]);

macro_rules! lanewise {
    ($name:ident, $op:tt) => {
        #[inline(always)]
        fn $name(self, o: Self) -> Self {
            let mut r = [0f32; LANES];
            for i in 0..LANES {
                r[i] = self.0[i] $op o.0[i];
            }
            F8(r)
        }
    };
}

macro_rules! compare {
    ($name:ident, $op:tt) => {
        #[inline(always)]
        fn $name(self, o: Self) -> M8 {
            let mut r = [0i32; LANES];
            for i in 0..LANES {
                r[i] = -((self.0[i] $op o.0[i]) as i32);
            }
            M8(r)
        }
    };
}

impl F8 {
    #[inline(always)]
    pub(crate) const fn splat(x: f32) -> Self {
        F8([x; LANES])
    }
    lanewise!(add, +);
    lanewise!(sub, -);
    lanewise!(mul, *);
    lanewise!(div, /);
    compare!(lt, <);
    compare!(le, <=);
    compare!(ge, >=);
    compare!(eq, ==);
    compare!(ne, !=);
    /// `minps`: the second operand when either is NaN.
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = if self.0[i] < o.0[i] { self.0[i] } else { o.0[i] };
        }
        F8(r)
    }
    /// `maxps`: the second operand when either is NaN.
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = if self.0[i] > o.0[i] { self.0[i] } else { o.0[i] };
        }
        F8(r)
    }
    /// `self·a + b` rounded once, lane by lane.
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = self.0[i].mul_add(a.0[i], b.0[i]);
        }
        F8(r)
    }
    /// Flips the sign of the lanes whose `s` has its sign bit set.
    #[inline(always)]
    fn xor_sign(self, s: Self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = f32::from_bits(self.0[i].to_bits() ^ (s.0[i].to_bits() & 0x8000_0000));
        }
        F8(r)
    }
    #[inline(always)]
    fn neg(self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = f32::from_bits(self.0[i].to_bits() ^ 0x8000_0000);
        }
        F8(r)
    }
    /// Lanes of `a` where `m`, else of `self`.
    #[inline(always)]
    fn blend(self, m: M8, a: Self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = f32::from_bits(((m.0[i] as u32) & a.0[i].to_bits()) | (!(m.0[i] as u32) & self.0[i].to_bits()));
        }
        F8(r)
    }
    /// Largest lane.
    #[inline(always)]
    fn hmax(self) -> f32 {
        // PERF: a tree (three steps the compiler keeps in vector registers), not a chain of
        // seven dependent compares; the same maximum for lanes without NaN.
        let m = |a: f32, b: f32| if a > b { a } else { b };
        let v = self.0;
        let a = [m(v[0], v[4]), m(v[1], v[5]), m(v[2], v[6]), m(v[3], v[7])];
        let b = [m(a[0], a[2]), m(a[1], a[3])];
        m(b[0], b[1])
    }
}

impl M8 {
    const NONE: Self = M8([0; LANES]);
    #[inline(always)]
    fn and(self, o: Self) -> Self {
        let mut r = [0i32; LANES];
        for i in 0..LANES {
            r[i] = self.0[i] & o.0[i];
        }
        M8(r)
    }
    #[inline(always)]
    fn or(self, o: Self) -> Self {
        let mut r = [0i32; LANES];
        for i in 0..LANES {
            r[i] = self.0[i] | o.0[i];
        }
        M8(r)
    }
    #[inline(always)]
    fn andnot(self, o: Self) -> Self {
        let mut r = [0i32; LANES];
        for i in 0..LANES {
            r[i] = !self.0[i] & o.0[i];
        }
        M8(r)
    }
    /// One bit per lane (`movmskps`).
    #[inline(always)]
    fn bits(self) -> u32 {
        // PERF: LLVM turns the portable loop into shifts and a horizontal OR; `movmskps`
        // (SSE, part of every x86-64) is one instruction per half.
        #[cfg(target_arch = "x86_64")]
        // SAFETY: SSE is part of x86-64; the loads read the 2 × 16 bytes of `self.0`.
        unsafe {
            use std::arch::x86_64::{_mm_castsi128_ps, _mm_loadu_si128, _mm_movemask_ps};
            let p = self.0.as_ptr().cast::<std::arch::x86_64::__m128i>();
            let lo = _mm_movemask_ps(_mm_castsi128_ps(_mm_loadu_si128(p)));
            let hi = _mm_movemask_ps(_mm_castsi128_ps(_mm_loadu_si128(p.add(1))));
            (lo | (hi << 4)) as u32
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let mut b = 0u32;
            for i in 0..LANES {
                b |= ((self.0[i] < 0) as u32) << i;
            }
            b
        }
    }
    /// Lanes whose bit is set in `b`.
    #[inline(always)]
    fn from_bits(b: u32) -> Self {
        M8(std::array::from_fn(|i| -(((b >> i) & 1) as i32)))
    }
    #[inline(always)]
    fn blend_u32(m: Self, old: [u32; LANES], new: [u32; LANES]) -> [u32; LANES] {
        let mut r = [0u32; LANES];
        for i in 0..LANES {
            r[i] = (m.0[i] as u32 & new[i]) | (!(m.0[i] as u32) & old[i]);
        }
        r
    }
}

/// Eight rays in SoA form (the layout the packet kernels work in, and the benchmark
/// harness's): lane `l` of each row belongs to ray `l`. A lane with an empty range
/// (`tmin >= tmax`, as in [`RayBlock::EMPTY`]) holds no ray.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct RayBlock {
    /// Origins: x, y, z rows.
    pub org: [[f32; LANES]; 3],
    /// Directions: x, y, z rows.
    pub dir: [[f32; LANES]; 3],
    /// Lower ends of the ranges.
    pub tmin: [f32; LANES],
    /// Upper ends of the ranges.
    pub tmax: [f32; LANES],
}

impl RayBlock {
    /// A block with no rays.
    pub const EMPTY: Self = Self { org: [[0.0; LANES]; 3], dir: [[0.0; LANES]; 3], tmin: [0.0; LANES], tmax: [f32::NEG_INFINITY; LANES] };

    /// Puts `r` into lane `l` (< 8).
    #[inline(always)]
    pub fn set(&mut self, l: usize, r: &Ray) {
        for k in 0..3 {
            self.org[k][l] = r.org[k];
            self.dir[k][l] = r.dir[k];
        }
        self.tmin[l] = r.tmin;
        self.tmax[l] = r.tmax;
    }
}

/// Up to 64 rays in SoA groups of eight, with their box-test constants.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Packet {
    /// Groups in use.
    pub groups: usize,
    /// Lanes holding a ray (finite origin and direction, non-empty range).
    pub valid: [M8; GROUPS],
    /// Origins and directions as x, y, z, then x and y again ([`CYCLIC`]): the three
    /// components a unit-triangle map of axis `k` reads, `k, k+1, k+2` (mod 3), are then
    /// the consecutive entries from `k` on.
    pub o: [[F8; CYCLIC]; GROUPS],
    pub d: [[F8; CYCLIC]; GROUPS],
    /// Reciprocal directions (|d| clamped to ≥ 1e-18 as in the single-ray kernel).
    pub inv: [[F8; 3]; GROUPS],
    pub tmin: [F8; GROUPS],
    /// All valid rays start at this one point (primary rays of a pinhole camera): the
    /// origin's part of the triangle test is then computed once per triangle.
    pub common: Option<[f32; 3]>,
    /// With a common origin: bounds of the rays' directions, for culling whole triangles
    /// against the packet ([`Packet::dir_bounds`]).
    pub cull: Option<DirBounds>,
}

/// Per-axis bounds of the directions of a set of rays with a common origin, and whether
/// none of them accepts hits behind the origin (every `tmin >= 0`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct DirBounds {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    pub forward: bool,
}

/// The closest hits (or, for occlusion, the remaining ranges) of a packet's rays. A lane
/// that is not searched any more has `t = -inf`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PacketHits {
    pub t: [F8; GROUPS],
    pub u: [F8; GROUPS],
    pub v: [F8; GROUPS],
    pub prim: [[u32; LANES]; GROUPS],
    pub inst: [[u32; LANES]; GROUPS],
}

/// Interval bounds of a set of rays (all with the same direction signs).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Interval {
    /// Rows of the near and far planes for the rays' own (forward) box tests.
    near: [usize; 3],
    far: [usize; 3],
    /// Rows of the near and far planes for the interval test.
    inear: [usize; 3],
    ifar: [usize; 3],
    olo: [f32; 3],
    ohi: [f32; 3],
    rlo: [f32; 3],
    rhi: [f32; 3],
    tmin: f32,
    /// The rays' unit directions spread at most [`MAX_DIR_SPREAD`] in every component.
    narrow: bool,
    /// +inf on an axis where some ray runs parallel to the planes ([`PARALLEL_INV`]), else
    /// 0: added to the exit bound, it keeps such a ray's slab open (branch-free).
    pad: [f32; 3],
}

/// Reciprocal directions at least this large (|d| <= 2e-18, near the 1e-18 clamp of
/// [`recip`]) count as parallel to the slab: such a ray lying in the slab never leaves it,
/// but `(b - o)·(1/d)` with its origin at (or within 1e-18·t of) the far plane gives an
/// exit near 0. When some ray of a packet is parallel to an axis, the box tests take every
/// exit on that axis as +inf ([`Interval::pad`]; the single-ray test is saved by its
/// `slack` instead). Only that axis's culling is lost, and only for such packets.
const PARALLEL_INV: f32 = 5e17;

/// Per-group lane masks.
pub(crate) type Masks = [M8; GROUPS];

impl Packet {
    /// A packet with no rays, and its hits.
    #[inline(always)]
    pub(crate) fn empty() -> (Self, PacketHits) {
        let z = F8::splat(0.0);
        let p = Packet {
            groups: 0,
            valid: [M8::NONE; GROUPS],
            o: [[z; CYCLIC]; GROUPS],
            d: [[z; CYCLIC]; GROUPS],
            inv: [[z; 3]; GROUPS],
            tmin: [z; GROUPS],
            common: None,
            cull: None,
        };
        let h = PacketHits {
            t: [F8::splat(f32::NEG_INFINITY); GROUPS],
            u: [z; GROUPS],
            v: [z; GROUPS],
            prim: [[INVALID; LANES]; GROUPS],
            inst: [[INVALID; LANES]; GROUPS],
        };
        (p, h)
    }

    /// Loads up to [`GROUPS`] blocks of eight rays into this packet and resets `h` to
    /// "nothing within `tmax`" (invalid lanes at `-inf`). PERF: in place, so the chunk
    /// loops reuse one packet (returning it by value cost four copies of 4 KB per packet).
    #[inline(always)]
    pub(crate) fn load_blocks_into(&mut self, blocks: &[RayBlock], h: &mut PacketHits) {
        let groups = blocks.len().min(GROUPS);
        let z = F8::splat(0.0);
        let p = self;
        p.groups = groups;
        for g in groups..GROUPS {
            p.valid[g] = M8::NONE;
            h.t[g] = F8::splat(f32::NEG_INFINITY);
        }
        for (g, b) in blocks[..groups].iter().enumerate() {
            // PERF: written out, not `array::map`: its closure shim stayed an out-of-line
            // call compiled without AVX2 (a twentieth of a sparse REND3R frame).
            p.o[g] = [F8(b.org[0]), F8(b.org[1]), F8(b.org[2]), F8(b.org[0]), F8(b.org[1])];
            p.d[g] = [F8(b.dir[0]), F8(b.dir[1]), F8(b.dir[2]), F8(b.dir[0]), F8(b.dir[1])];
            p.tmin[g] = F8(b.tmin);
            let tmax = F8(b.tmax);
            p.inv[g] = recip3(&p.d[g]);
            // A ray counts when its origin and direction are finite (x·0 = 0), its direction
            // is not zero and its range is not empty (false for a NaN bound).
            let mut ok = p.tmin[g].lt(tmax);
            let mut nonzero = M8::NONE;
            for k in 0..3 {
                ok = ok.and(p.o[g][k].mul(z).eq(z)).and(p.d[g][k].mul(z).eq(z));
                nonzero = nonzero.or(p.d[g][k].ne(z));
            }
            p.valid[g] = ok.and(nonzero);
            h.t[g] = F8::splat(f32::NEG_INFINITY).blend(p.valid[g], tmax);
            h.u[g] = z;
            h.v[g] = z;
            h.prim[g] = [INVALID; LANES];
            h.inst[g] = [INVALID; LANES];
        }
        p.common = p.find_common_origin();
        p.cull = p.cull_bounds(&p.valid);
    }

    /// [`Packet::cull`] for the rays of `set`: their direction bounds when they share an
    /// origin and the packet is large enough to use them (PERF: the bounds cost 6% of an
    /// 8-ray packet).
    #[inline(always)]
    fn cull_bounds(&self, set: &Masks) -> Option<DirBounds> {
        if self.common.is_some() && self.groups >= CULL_GROUPS {
            self.dir_bounds(set)
        } else {
            None
        }
    }

    /// Bounds of the directions of the rays in `set` (and whether all their `tmin` are at
    /// least 0); `None` when the set is empty.
    #[inline(always)]
    fn dir_bounds(&self, set: &Masks) -> Option<DirBounds> {
        let inf = f32::INFINITY;
        let (mut lo, mut hi) = ([F8::splat(inf); 3], [F8::splat(-inf); 3]);
        let mut tmin = F8::splat(inf);
        let mut any = 0;
        for g in 0..self.groups {
            let m = set[g].and(self.valid[g]);
            if m.bits() == 0 {
                continue;
            }
            any |= m.bits();
            for k in 0..3 {
                lo[k] = lo[k].min(F8::splat(inf).blend(m, self.d[g][k]));
                hi[k] = hi[k].max(F8::splat(-inf).blend(m, self.d[g][k]));
            }
            tmin = tmin.min(F8::splat(inf).blend(m, self.tmin[g]));
        }
        if any == 0 {
            return None;
        }
        let hmin = |v: F8| -(v.neg().hmax());
        Some(DirBounds { lo: lo.map(hmin), hi: hi.map(F8::hmax), forward: hmin(tmin) >= 0.0 })
    }

    /// The origin every valid ray shares, bit for bit, if there is one.
    #[inline(always)]
    fn find_common_origin(&self) -> Option<[f32; 3]> {
        let (g0, l0) = self.first_lane(&self.valid)?;
        let first: [u32; 3] = std::array::from_fn(|k| self.o[g0][k].0[l0].to_bits());
        let mut differ = 0u32;
        for g in g0..self.groups {
            // Lane by lane on the bits (a loop the compiler turns into vector compares).
            let mut d = [0i32; LANES];
            for (l, dl) in d.iter_mut().enumerate() {
                // PERF: `&`, not a short-circuiting `all` (whose early exit kept the loop
                // scalar: 50 instructions a group).
                let o = &self.o[g];
                let same = (o[0].0[l].to_bits() == first[0]) & (o[1].0[l].to_bits() == first[1]) & (o[2].0[l].to_bits() == first[2]);
                *dl = -(!same as i32);
            }
            differ |= M8(d).and(self.valid[g]).bits();
        }
        (differ == 0).then(|| first.map(f32::from_bits))
    }

    /// The first lane of `set` (group, lane), if it has any.
    #[inline(always)]
    fn first_lane(&self, set: &Masks) -> Option<(usize, usize)> {
        let g = (0..self.groups).find(|&g| set[g].bits() != 0)?;
        Some((g, set[g].bits().trailing_zeros() as usize))
    }

    /// The direction of the ray in lane `l` of group `g`.
    #[inline(always)]
    fn dir(&self, g: usize, l: usize) -> Vec3 {
        Vec3::new(self.d[g][0].0[l], self.d[g][1].0[l], self.d[g][2].0[l])
    }

    /// The ray in lane `l` of group `g`, its range ending at `tmax`.
    #[inline(always)]
    pub(crate) fn ray(&self, g: usize, l: usize, tmax: f32) -> Ray {
        Ray { org: Vec3::new(self.o[g][0].0[l], self.o[g][1].0[l], self.o[g][2].0[l]), dir: self.dir(g, l), tmin: self.tmin[g].0[l], tmax }
    }

    /// The rays of `active` in the object space of `inst`, as the single-ray path sees
    /// them: the packet itself for an instance whose transform is the identity (see
    /// [`crate::tlas::Instance::is_identity`]), else [`Packet::transformed`].
    #[inline(always)]
    fn in_object_space(&self, inst: &crate::tlas::Instance, active: &Masks) -> std::borrow::Cow<'_, Self> {
        if inst.is_identity() {
            std::borrow::Cow::Borrowed(self)
        } else {
            std::borrow::Cow::Owned(self.transformed(&inst.object_from_world, active))
        }
    }

    /// The rays of `active` carried by `m` (object space of an instance), computed as
    /// `Ray::transformed` does, so the single-ray kernels see the same rays.
    #[inline(always)]
    pub(crate) fn transformed(&self, m: &Affine3A, active: &Masks) -> Self {
        let mut p = *self;
        let c = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
        let tr = m.translation;
        for g in 0..self.groups {
            if active[g].bits() == 0 {
                continue;
            }
            let [ox, oy, oz, ..] = self.o[g];
            let [dx, dy, dz, ..] = self.d[g];
            for r in 0..3 {
                let (a, b, cc) = (F8::splat(c[0][r]), F8::splat(c[1][r]), F8::splat(c[2][r]));
                p.o[g][r] = a.mul(ox).add(b.mul(oy)).add(cc.mul(oz)).add(F8::splat(tr[r]));
                p.d[g][r] = a.mul(dx).add(b.mul(dy)).add(cc.mul(dz));
            }
            (p.o[g][3], p.o[g][4], p.d[g][3], p.d[g][4]) = (p.o[g][0], p.o[g][1], p.d[g][0], p.d[g][1]);
            p.inv[g] = recip3(&p.d[g]);
        }
        // The same arithmetic on the same origin gives the same point in every lane.
        p.common = self.common.map(|o| {
            let r = |k: usize| c[0][k] * o[0] + c[1][k] * o[1] + c[2][k] * o[2] + tr[k];
            [r(0), r(1), r(2)]
        });
        p.cull = p.cull_bounds(active);
        p
    }

    /// Interval bounds of the rays in `active`; `None` when there are none or their
    /// direction signs disagree on some axis.
    #[inline(always)]
    pub(crate) fn interval(&self, active: &Masks) -> Option<Interval> {
        let inf = f32::INFINITY;
        let (mut olo, mut ohi) = ([F8::splat(inf); 3], [F8::splat(-inf); 3]);
        let (mut rlo, mut rhi) = (olo, ohi);
        let mut tmin = F8::splat(inf);
        let mut any = 0;
        for g in 0..self.groups {
            let m = active[g];
            if m.bits() == 0 {
                continue;
            }
            any |= m.bits();
            let (pinf, ninf) = (F8::splat(inf), F8::splat(-inf));
            for k in 0..3 {
                olo[k] = olo[k].min(pinf.blend(m, self.o[g][k]));
                ohi[k] = ohi[k].max(ninf.blend(m, self.o[g][k]));
                rlo[k] = rlo[k].min(pinf.blend(m, self.inv[g][k]));
                rhi[k] = rhi[k].max(ninf.blend(m, self.inv[g][k]));
            }
            tmin = tmin.min(pinf.blend(m, self.tmin[g]));
        }
        if any == 0 {
            return None;
        }
        let lo = |v: F8| -(v.neg().hmax());
        let mut iv = Interval {
            near: [0; 3],
            far: [0; 3],
            inear: [0; 3],
            ifar: [0; 3],
            olo: [0.0; 3],
            ohi: [0.0; 3],
            rlo: [0.0; 3],
            rhi: [0.0; 3],
            tmin: lo(tmin),
            narrow: true,
            pad: [0.0; 3],
        };
        // The length of one ray's direction, taken for all (PERF: lengths ray by ray, each
        // with a square root and a division, cost more; even so, this check costs 8-ray
        // packets of primary rays 7-10%, and 64-ray packets nothing measurable).
        let q = self.first_lane(active).map_or(f32::NAN, |(g, l)| self.dir(g, l).length());
        for k in 0..3 {
            iv.olo[k] = lo(olo[k]);
            iv.ohi[k] = ohi[k].hmax();
            iv.rlo[k] = lo(rlo[k]);
            iv.rhi[k] = rhi[k].hmax();
            let neg = iv.rhi[k] < 0.0;
            if !neg && iv.rlo[k] < 0.0 {
                return None; // mixed signs
            }
            iv.narrow &= iv.narrow_on(k, q);
            iv.pad[k] = if iv.rlo[k].abs().max(iv.rhi[k].abs()) >= PARALLEL_INV { f32::INFINITY } else { 0.0 };
            iv.near[k] = k + 3 * neg as usize;
            iv.far[k] = k + 3 * (!neg) as usize;
            iv.inear[k] = iv.near[k];
            iv.ifar[k] = iv.far[k];
        }
        Some(iv)
    }
}

impl Packet {
    /// Interval bounds for an any-hit query: those of the rays, or of the same segments
    /// walked backwards from their far ends when those ends are closer together (shadow rays
    /// of a tile start on many surfaces but all end at one light). Both bound every point of
    /// every segment, so culling with either is conservative; the exact per-ray tests stay
    /// on the forward rays.
    #[inline(always)]
    pub(crate) fn occlusion_interval(&self, active: &Masks, h: &PacketHits) -> Option<Interval> {
        let fwd = self.interval(active)?;
        if fwd.tmin < 0.0 {
            return Some(fwd);
        }
        let inf = f32::INFINITY;
        let mut elo = [F8::splat(inf); 3];
        let mut ehi = [F8::splat(-inf); 3];
        for g in 0..self.groups {
            let m = active[g];
            if m.bits() == 0 {
                continue;
            }
            for k in 0..3 {
                let e = self.o[g][k].add(self.d[g][k].mul(h.t[g]));
                elo[k] = elo[k].min(F8::splat(inf).blend(m, e));
                ehi[k] = ehi[k].max(F8::splat(-inf).blend(m, e));
            }
        }
        let mut rev = fwd;
        let (mut ext_f, mut ext_r) = (0.0f32, 0.0f32);
        for k in 0..3 {
            let (lo, hi) = (-(elo[k].neg().hmax()), ehi[k].hmax());
            // Widened by a few ulps of the coordinates: the ends are rounded.
            let pad = lo.abs().max(hi.abs()) * (1.0 / (1u32 << 20) as f32);
            rev.olo[k] = lo - pad;
            rev.ohi[k] = hi + pad;
            // Reversed directions: 1/(−d) = −(1/d) exactly.
            rev.rlo[k] = -fwd.rhi[k];
            rev.rhi[k] = -fwd.rlo[k];
            rev.inear[k] = fwd.far[k];
            rev.ifar[k] = fwd.near[k];
            ext_f += fwd.ohi[k] - fwd.olo[k];
            ext_r += rev.ohi[k] - rev.olo[k];
        }
        // The walk back covers [0, tmax − tmin] ⊂ [0, tmax] (the ends are padded above).
        rev.tmin = 0.0;
        Some(if ext_r.is_finite() && ext_r < ext_f { rev } else { fwd })
    }
}

/// Bounds of a set of ray origins.
#[derive(Clone, Copy)]
pub(crate) struct OriginBounds {
    lo: [f32; 3],
    hi: [f32; 3],
}

impl OriginBounds {
    /// The widest axis and its extent.
    #[inline(always)]
    fn widest(&self) -> (usize, f32) {
        let mut best = (0, self.hi[0] - self.lo[0]);
        for k in 1..3 {
            if self.hi[k] - self.lo[k] > best.1 {
                best = (k, self.hi[k] - self.lo[k]);
            }
        }
        best
    }
}

impl Packet {
    /// Bounds of the origins of the lanes of `set`.
    #[inline(always)]
    fn origin_bounds(&self, set: &Masks) -> OriginBounds {
        let inf = f32::INFINITY;
        let (mut lo, mut hi) = ([F8::splat(inf); 3], [F8::splat(-inf); 3]);
        for g in 0..self.groups {
            if set[g].bits() == 0 {
                continue;
            }
            for k in 0..3 {
                lo[k] = lo[k].min(F8::splat(inf).blend(set[g], self.o[g][k]));
                hi[k] = hi[k].max(F8::splat(-inf).blend(set[g], self.o[g][k]));
            }
        }
        // PERF: written out, not `array::map` (see `load_blocks_into`).
        let low = |v: F8| -(v.neg().hmax());
        OriginBounds { lo: [low(lo[0]), low(lo[1]), low(lo[2])], hi: [hi[0].hmax(), hi[1].hmax(), hi[2].hmax()] }
    }

    /// The lanes of `set` split at the middle of the widest axis of their origins' bounds
    /// `b`: those below it and the rest (both non-empty when the origins differ).
    #[inline(always)]
    fn split_at(&self, set: &Masks, b: OriginBounds) -> (Masks, Masks) {
        let (axis, _) = b.widest();
        let mid = F8::splat(0.5 * b.lo[axis] + 0.5 * b.hi[axis]);
        let mut below = [M8::NONE; GROUPS];
        let mut above = [M8::NONE; GROUPS];
        for g in 0..self.groups {
            let m = self.o[g][axis].lt(mid);
            below[g] = m.and(set[g]);
            above[g] = m.andnot(set[g]);
        }
        (below, above)
    }

    /// The lanes of `set` split by the sign of their direction on the first axis where
    /// it differs (the sign of the reciprocal, which the interval tests go by): `None` when
    /// every lane has the same signs. Rays toward a light straight above a tile, or primary
    /// rays through the image's centre column, mix signs; each half is coherent again.
    #[inline(always)]
    fn sign_split(&self, set: &Masks) -> Option<(Masks, Masks)> {
        let z = F8::splat(0.0);
        for k in 0..3 {
            let mut neg = [M8::NONE; GROUPS];
            let mut pos = [M8::NONE; GROUPS];
            let (mut any_neg, mut any_pos) = (0, 0);
            for g in 0..self.groups {
                let m = self.inv[g][k].lt(z);
                neg[g] = m.and(set[g]);
                pos[g] = m.andnot(set[g]);
                any_neg |= neg[g].bits();
                any_pos |= pos[g].bits();
            }
            if any_neg != 0 && any_pos != 0 {
                return Some((neg, pos));
            }
        }
        None
    }
}

/// [`recip`] of three rows (PERF: not `array::map`, see `load_blocks_into`).
#[inline(always)]
fn recip3(d: &[F8; CYCLIC]) -> [F8; 3] {
    [recip(d[0]), recip(d[1]), recip(d[2])]
}

/// Lane-wise `1/d`, with |d| clamped to ≥ 1e-18 as in the single-ray kernel.
#[inline(always)]
fn recip(d: F8) -> F8 {
    let tiny = 1e-18f32;
    let mut r = [0f32; LANES];
    for i in 0..LANES {
        let x = d.0[i];
        r[i] = 1.0 / if x.abs() < tiny { tiny.copysign(x) } else { x };
    }
    F8(r)
}

impl Interval {
    /// Whether the unit directions' component `k` spreads at most [`MAX_DIR_SPREAD`], for
    /// directions of length about `q` (one ray's; rays here are unit, or scaled alike by an
    /// instance's map). The components lie in `[1/rb, 1/rs]` in magnitude (the
    /// reciprocals' smallest and largest magnitudes `rs` and `rb`, all of one sign), so the
    /// unit components spread about `(1/rs − 1/rb)/q`, compared here without a division.
    /// False on NaN (a zero or overflowing length).
    #[inline(always)]
    fn narrow_on(&self, k: usize, q: f32) -> bool {
        let (r1, r2) = (self.rlo[k].abs(), self.rhi[k].abs());
        let (rs, rb) = (r1.min(r2), r1.max(r2));
        rb - rs <= MAX_DIR_SPREAD * q * rs * rb
    }

    /// True when tracing `lanes` rays together pays: at least three of them, their unit
    /// directions within [`MAX_DIR_SPREAD`] of each other, and their origins within
    /// `extent` of each other on every axis. Scattered origins (the shadow
    /// rays toward a distant light of a tile that spans near and far surfaces) make the
    /// interval bound a large prism that many boxes meet; such rays go alone.
    #[inline(always)]
    pub(crate) fn worth(&self, lanes: u32, extent: f32) -> bool {
        lanes >= 3 && self.narrow && (0..3).all(|k| self.ohi[k] - self.olo[k] <= extent)
    }
}

/// The largest spread of unit directions (the range of one component) a packet may have.
/// Rays scattered over a whole octant (diffuse bounces) bound an interval that meets most
/// of the tree: walked together they were 10 to 80 times slower than one by one. Chosen
/// from `lucent bench rays` on the five presets (64-ray packets, 2 threads): against no
/// limit, 0.1 took Conference's shadow rays from 43 to 61 Mrays/s and Sponza's from 58 to
/// 73, diffuse rays from 0.1–1.5 to 7–8; primary rays stayed within noise. (0.25: shadows
/// 53 and diffuse 7 on Conference; 0.05: no better than 0.1.)
const MAX_DIR_SPREAD: f32 = 0.1;

/// The largest origin spread a packet may have over geometry of bounds `b`: 4% of the
/// diagonal. Chosen from A/B runs with packet splitting on (`lucent bench dynamic`, `bench
/// rend3r`, `bench frame`): against 1%, the sphere field of REND3R's Table IV with a light
/// went from 16.1 to 13.9 ms and the sunflowers from 45.6 to 45.0 ms; the kitchen and the
/// mesh presets moved within noise (±3%).
#[inline(always)]
fn max_spread(b: &crate::geom::Aabb) -> f32 {
    let d = (b.max - b.min).length();
    if d.is_finite() {
        0.04 * d
    } else {
        f32::INFINITY
    }
}

impl PacketHits {
    /// Largest `t` over the lanes of `active` (−inf when none).
    #[inline(always)]
    fn max_t<K: KernelSet>(&self, groups: usize, active: &Masks) -> f32 {
        #[cfg(target_arch = "x86_64")]
        if K::SIMD {
            // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
            return unsafe { avx::max_t(self, groups, active) };
        }
        let mut m = F8::splat(f32::NEG_INFINITY);
        for g in 0..groups {
            m = m.max(F8::splat(f32::NEG_INFINITY).blend(active[g], self.t[g]));
        }
        m.hmax()
    }

    /// The hit of lane `l` of group `g`.
    #[inline(always)]
    pub(crate) fn get(&self, g: usize, l: usize) -> Hit {
        Hit { t: self.t[g].0[l], u: self.u[g].0[l], v: self.v[g].0[l], prim: self.prim[g][l], inst: self.inst[g][l] }
    }

    /// Sets lane `l` of group `g`.
    #[inline(always)]
    pub(crate) fn put(&mut self, g: usize, l: usize, h: &Hit) {
        self.t[g].0[l] = h.t;
        self.u[g].0[l] = h.u;
        self.v[g].0[l] = h.v;
        self.prim[g][l] = h.prim;
        self.inst[g][l] = h.inst;
    }
}

/// All eight children of `node` against the packet's intervals: the mask of children some
/// ray may enter before `tmax`, and lower bounds of their entry distances.
#[inline(always)]
fn interval_test(node: &WideNode<8>, iv: &Interval, tmax: f32, dist: &mut [f32; 8]) -> u32 {
    let mut tn = F8::splat(iv.tmin);
    let mut tf = F8::splat(tmax);
    for k in 0..3 {
        let bn = F8(node.bounds[iv.inear[k]]);
        let bf = F8(node.bounds[iv.ifar[k]]);
        let (olo, ohi) = (F8::splat(iv.olo[k]), F8::splat(iv.ohi[k]));
        let (rlo, rhi) = (F8::splat(iv.rlo[k]), F8::splat(iv.rhi[k]));
        // (b − o)·r is bilinear in (o, r): its extremes over the box of (o, r) are at corners.
        let (n0, n1) = (bn.sub(olo), bn.sub(ohi));
        let lo = n0.mul(rlo).min(n0.mul(rhi)).min(n1.mul(rlo).min(n1.mul(rhi)));
        let (f0, f1) = (bf.sub(olo), bf.sub(ohi));
        let hi = f0.mul(rlo).max(f0.mul(rhi)).max(f1.mul(rlo).max(f1.mul(rhi))).add(F8::splat(iv.pad[k]));
        tn = lo.max(tn);
        tf = hi.min(tf);
    }
    *dist = tn.0;
    tn.le(tf.mul(F8::splat(FAR_SCALE))).bits()
}

/// [`interval_test`] with the kernel of `K`.
#[inline(always)]
fn node_test<K: KernelSet>(node: &WideNode<8>, iv: &Interval, tmax: f32, dist: &mut [f32; 8]) -> u32 {
    if K::SIMD {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
        return unsafe { avx::interval_test(node, iv, tmax, dist) };
    }
    interval_test(node, iv, tmax, dist)
}

/// One group of rays against one box (`rows` as in `WideNode::bounds`): the lanes that
/// enter it within `[tmin, t)`.
#[inline(always)]
fn group_box(rows: &[f32; 6], p: &Packet, iv: &Interval, g: usize, t: F8) -> M8 {
    let mut tn = p.tmin[g];
    let mut tf = t;
    for k in 0..3 {
        let a = F8::splat(rows[iv.near[k]]).sub(p.o[g][k]).mul(p.inv[g][k]);
        let b = F8::splat(rows[iv.far[k]]).sub(p.o[g][k]).mul(p.inv[g][k]).add(F8::splat(iv.pad[k]));
        tn = a.max(tn);
        tf = b.min(tf);
    }
    tn.le(tf.mul(F8::splat(FAR_SCALE)))
}

/// What sits in the leaves, for packets.
pub(crate) trait PacketLeaves {
    /// Closest hits of the lanes in `m` among items `first..first+count`.
    fn intersect(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits);
    /// Occlusion of the lanes in `m`: an occluded lane gets `t = -inf`.
    fn occluded(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits);
    /// Asks for the cache lines of item `first` (a hint).
    #[inline(always)]
    fn prefetch(&self, _first: u32) {}
}

/// A stack entry: a child code, where its box is (its parent's code with the slot in the
/// low three bits) and its entry bound.
#[derive(Clone, Copy)]
struct Entry {
    code: u32,
    at: u32,
    dist: f32,
}

/// The masks of the lanes of `active` whose rays enter the box of slot `at`.
#[inline(always)]
fn leaf_masks<K: KernelSet>(nodes: &[WideNode<8>], at: u32, p: &Packet, iv: &Interval, h: &PacketHits, active: &Masks) -> (Masks, u32) {
    // SAFETY: `at` is a valid inner code (a multiple of `WideNode::<8>::STRIDE`, which is
    // at least 8) with a slot < 8 in its low bits.
    let node = unsafe { node_at(nodes, at & !7) };
    let slot = (at & 7) as usize;
    let rows: [f32; 6] = std::array::from_fn(|r| node.bounds[r][slot]);
    let mut m = [M8::NONE; GROUPS];
    let mut any = 0;
    for g in 0..p.groups {
        if active[g].bits() == 0 {
            continue;
        }
        let b = if K::SIMD {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
            unsafe {
                avx::group_box(&rows, p, iv, g, &h.t[g])
            }
            #[cfg(not(target_arch = "x86_64"))]
            group_box(&rows, p, iv, g, h.t[g])
        } else {
            group_box(&rows, p, iv, g, h.t[g])
        };
        m[g] = b.and(active[g]);
        any |= m[g].bits();
    }
    (m, any)
}

/// Closest-hit traversal of the lanes of `active` (rays with the same direction signs:
/// `iv` is their interval).
#[inline(always)]
pub(crate) fn intersect<K: KernelSet, L: PacketLeaves, C: Counters>(
    nodes: &[WideNode<8>],
    leaves: &L,
    p: &Packet,
    iv: &Interval,
    active: &Masks,
    h: &mut PacketHits,
    c: &mut C,
) {
    traverse::<false, K, L, C>(nodes, leaves, p, iv, active, h, c);
}

/// Any-hit traversal of the lanes of `active`: occluded lanes get `t = -inf`.
#[inline(always)]
pub(crate) fn occluded<K: KernelSet, L: PacketLeaves, C: Counters>(
    nodes: &[WideNode<8>],
    leaves: &L,
    p: &Packet,
    iv: &Interval,
    active: &Masks,
    h: &mut PacketHits,
    c: &mut C,
) {
    traverse::<true, K, L, C>(nodes, leaves, p, iv, active, h, c);
}

/// The one packet traversal: children nearest first (along the interval's rays), leaves
/// handed to `leaves.intersect` or, with `ANY`, to `leaves.occluded`, which ends the walk
/// once every lane is occluded. A closest-hit walk skips popped entries that start beyond
/// every lane's current hit; an any-hit walk visits them all.
#[inline(always)]
fn traverse<const ANY: bool, K: KernelSet, L: PacketLeaves, C: Counters>(
    nodes: &[WideNode<8>],
    leaves: &L,
    p: &Packet,
    iv: &Interval,
    active: &Masks,
    h: &mut PacketHits,
    c: &mut C,
) {
    if nodes.is_empty() {
        return;
    }
    // PERF: left uninitialised (zeroing 6 KB per packet showed in profiles); entries below
    // `sp` are always written before they are read.
    let mut st = [std::mem::MaybeUninit::<Entry>::uninit(); STACK];
    let mut sp = 0usize;
    let mut cur = Entry { code: 0, at: 0, dist: 0.0 };
    let mut tmax = h.max_t::<K>(p.groups, active);
    let mut dist = [0f32; 8];
    loop {
        if cur.code & LEAF == 0 {
            // SAFETY: inner codes come from the collapse and address nodes of `nodes`.
            let node = unsafe { node_at(nodes, cur.code) };
            let mut mask = node_test::<K>(node, iv, tmax, &mut dist);
            c.node();
            // An inner code is a multiple of 32: the slot fits in its low bits.
            let (base, at0) = (sp, cur.code);
            while mask != 0 {
                let k = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                // Insertion: nearest on top.
                let e = Entry { code: node.child[k], at: at0 | k as u32, dist: dist[k] };
                let mut j = sp;
                // SAFETY: entries base..sp were written by earlier pushes.
                while j > base && unsafe { st[j - 1].assume_init() }.dist < e.dist {
                    st[j] = st[j - 1];
                    j -= 1;
                }
                st[j].write(e);
                sp += 1;
                // Start loading what the packet will visit (it visits most of what it pushes):
                // the walk is bound by cache misses more than by its arithmetic.
                if e.code & LEAF == 0 {
                    crate::traverse::prefetch_node(nodes, e.code);
                } else if e.code != EMPTY {
                    leaves.prefetch(leaf_range(e.code).0);
                }
            }
        } else if cur.code != EMPTY {
            let (m, any) = leaf_masks::<K>(nodes, cur.at, p, iv, h, active);
            if any != 0 {
                let (first, count) = leaf_range(cur.code);
                c.items(count);
                if ANY {
                    leaves.occluded(first, count, p, &m, h);
                } else {
                    leaves.intersect(first, count, p, &m, h);
                }
                tmax = h.max_t::<K>(p.groups, active);
                if ANY && tmax == f32::NEG_INFINITY {
                    return;
                }
            }
        }
        loop {
            if sp == 0 {
                return;
            }
            sp -= 1;
            // SAFETY: every entry below the old `sp` was written by a push.
            let e = unsafe { st[sp].assume_init() };
            if ANY || e.dist <= tmax {
                cur = e;
                break;
            }
        }
    }
}

/// The unit-triangle test of one group of rays against lane `lane` of `t4`, exactly as
/// [`crate::triangle::unit_triangle_hit`] computes it: the hit mask and scaled `T, U, V, |D'z|`.
/// The lane must not be padding.
#[inline(always)]
fn tri_eval(t4: &Tri4, lane: usize, p: &Packet, g: usize, tmax: F8) -> (M8, [F8; 4]) {
    let m = |c: usize| F8::splat(t4.m[c][lane]);
    let k = t4.axis(lane) as usize;
    let ([o0, o1, o2], [d0, d1, d2]) = (*cyclic(&p.o[g], k), *cyclic(&p.d[g], k));
    let dir = |i: usize| m(i).mul_add(d1, m(i + 1).mul_add(d2, F8::splat(t4.m[i + 2][lane] * 0.0)));
    let org = |i: usize| m(i).mul_add(o1, m(i + 1).mul_add(o2, m(i + 2)));
    let dzp = m(6).mul_add(d1, m(7).mul_add(d2, m(8).mul_add(F8::splat(0.0), d0)));
    let ozp = m(6).mul_add(o1, m(7).mul_add(o2, m(8).add(o0)));
    let (dxp, oxp, dyp, oyp) = (dir(0), org(0), dir(3), org(3));
    let adz = dzp.xor_sign(dzp);
    let uu = oxp.mul_add(dzp, ozp.mul(dxp).neg()).xor_sign(dzp);
    let vv = oyp.mul_add(dzp, ozp.mul(dyp).neg()).xor_sign(dzp);
    let tt = ozp.neg().xor_sign(dzp);
    let z = F8::splat(0.0);
    let ok = uu.ge(z).and(vv.ge(z)).and(uu.add(vv).le(adz)).and(tt.ge(p.tmin[g].mul(adz))).and(tt.lt(tmax.mul(adz)));
    (ok, [tt, uu, vv, adz])
}

/// Components `k, k+1, k+2` (mod 3) of a [`CYCLIC`] vector, for a map of axis `k` (not a
/// padding lane's).
#[inline(always)]
fn cyclic(v: &[F8; CYCLIC], k: usize) -> &[F8; 3] {
    debug_assert!(k < 3, "a padding lane");
    // PERF: three consecutive entries from `k` (one address), not indices through
    // `triangle::ROTATION` (callgrind: 4.7% more instructions for primary packets).
    let k = k.min(2);
    v[k..].first_chunk::<3>().expect("k <= 2 leaves three of five entries")
}

/// Unit-triangle leaves for packets.
pub(crate) struct UnitPacketLeaves<'a, K> {
    pub tris: &'a [Tri4],
    /// Written into the `inst` of every hit.
    pub inst: u32,
    pub k: std::marker::PhantomData<K>,
    /// Triangles put to the whole-packet cull in this walk, and how many it dropped.
    pub culled: std::cell::Cell<[u32; 2]>,
}

/// Triangles the whole-packet cull is tried on before it must earn its keep.
const CULL_TRIAL: u32 = 4;

impl<K: KernelSet> PacketLeaves for UnitPacketLeaves<'_, K> {
    #[inline(always)]
    fn prefetch(&self, first: u32) {
        if let Some(t4) = self.tris.get(first as usize) {
            crate::traverse::prefetch(t4);
        }
    }

    #[inline(always)]
    fn intersect(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
        // PERF: the whole-packet culling of triangles only where several groups would test
        // them (one group's test costs about what the culling does), and only while it drops
        // at least two fifths of the triangles it is tried on. It drops 83% of those tried in
        // the museum, 54-58% in Conference, the kitchen and Sponza, but 31% of the Stanford
        // bunny's (triangles small next to the packet's footprint), where it cost 5-10%.
        #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
        let [mut tried, mut dropped] = self.culled.get();
        let cull = p
            .cull
            .as_ref()
            .filter(|_| tried < CULL_TRIAL || 5 * dropped >= 2 * tried)
            .filter(|_| m[..p.groups].iter().filter(|mg| mg.bits() != 0).count() >= CULL_GROUPS);
        #[cfg(not(target_arch = "x86_64"))]
        let _ = cull;
        for gi in first..first + count {
            // SAFETY: leaf ranges are in range of `tris` (built so, checked by `validate`).
            let t4 = unsafe { self.tris.get_unchecked(gi as usize) };
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
            let org = if K::SIMD { p.common.map(|o| unsafe { avx::origin_terms(t4, &o) }) } else { None };
            // Triangles that no ray of the packet can hit are dropped for all groups at once.
            #[cfg(target_arch = "x86_64")]
            let keep = match (&org, cull) {
                (Some(o), Some(c)) => {
                    // SAFETY: as above.
                    let keep = unsafe { avx::frustum_keep(t4, o, c) };
                    tried += 4;
                    dropped += 4 - keep.count_ones();
                    keep
                }
                _ => 0xF,
            };
            #[cfg(target_arch = "x86_64")]
            if keep == 0 {
                continue;
            }
            for g in 0..p.groups {
                if m[g].bits() == 0 {
                    continue;
                }
                #[cfg(target_arch = "x86_64")]
                if K::SIMD {
                    // SAFETY: as above.
                    unsafe { avx::tri4_intersect(t4, p, g, &m[g], h, self.inst, org.as_ref(), keep) };
                    continue;
                }
                // As the four-lane single-ray test: all lanes against the same limit, then
                // the nearest, the first lane winning ties.
                let limit = h.t[g];
                let mut found = M8::NONE;
                let mut bt = F8::splat(f32::INFINITY);
                let mut bu = bt;
                let mut bv = bt;
                let mut bp = [INVALID; LANES];
                for lane in 0..4 {
                    // Padding lanes come last and never hit.
                    if t4.is_pad(lane) {
                        break;
                    }
                    let (ok, [tt, uu, vv, adz]) = tri_eval(t4, lane, p, g, limit);
                    let ok = ok.and(m[g]);
                    if ok.bits() == 0 {
                        continue;
                    }
                    let t = tt.div(adz);
                    let take = ok.and(found.andnot(M8([-1; LANES])).or(t.lt(bt)));
                    bt = bt.blend(take, t);
                    bu = bu.blend(take, uu.div(adz));
                    bv = bv.blend(take, vv.div(adz));
                    bp = M8::blend_u32(take, bp, [t4.id(lane); LANES]);
                    found = found.or(take);
                }
                if found.bits() != 0 {
                    h.t[g] = h.t[g].blend(found, bt);
                    h.u[g] = h.u[g].blend(found, bu);
                    h.v[g] = h.v[g].blend(found, bv);
                    h.prim[g] = M8::blend_u32(found, h.prim[g], bp);
                    h.inst[g] = M8::blend_u32(found, h.inst[g], [self.inst; LANES]);
                }
            }
        }
        self.culled.set([tried, dropped]);
    }

    #[inline(always)]
    fn occluded(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
        let mut m = *m;
        for gi in first..first + count {
            // SAFETY: as above.
            let t4 = unsafe { self.tris.get_unchecked(gi as usize) };
            let mut left = 0;
            for g in 0..p.groups {
                if m[g].bits() == 0 {
                    continue;
                }
                let limit = h.t[g];
                let mut hit = M8::NONE;
                #[cfg(target_arch = "x86_64")]
                if K::SIMD {
                    // SAFETY: as above.
                    hit = unsafe { avx::tri4_any(t4, p, g, &limit, &m[g]) };
                }
                if !K::SIMD {
                    for lane in 0..4 {
                        if t4.is_pad(lane) {
                            break;
                        }
                        hit = hit.or(tri_eval(t4, lane, p, g, limit).0);
                    }
                }
                let hit = hit.and(m[g]);
                h.t[g] = h.t[g].blend(hit, F8::splat(f32::NEG_INFINITY));
                m[g] = hit.andnot(m[g]);
                left |= m[g].bits();
            }
            if left == 0 {
                return;
            }
        }
    }
}

/// Lanes of `m` as `(group, lane)` pairs.
#[inline(always)]
pub(crate) fn for_lanes(groups: usize, m: &Masks, mut f: impl FnMut(usize, usize)) {
    for (g, mg) in m.iter().enumerate().take(groups) {
        let mut b = mg.bits();
        while b != 0 {
            let l = b.trailing_zeros() as usize;
            b &= b - 1;
            f(g, l);
        }
    }
}

// ---------------------------------------------------------------------------------------
// Entry points: the bottom level (one mesh) and the two-level index.

use crate::mesh::{MeshBvh, Nodes, TriangleTest};
use crate::shape::Shape;
use crate::tlas::{Geometry, InstLeaves, TwoLevel};
use crate::traverse::RayPre;

/// Runs `body` on every chunk of at most [`MAX_PACKET`] rays, with the packet loaded.
#[inline(always)]
fn chunks(rays: &[Ray], body: impl FnMut(usize, &Packet, &mut PacketHits)) {
    aos_chunks(
        rays,
        |eight, b| {
            for (l, r) in eight.iter().enumerate() {
                b.set(l, r);
            }
        },
        body,
    );
}

/// Runs `body` on every chunk of at most [`MAX_PACKET`] rays, with the packet loaded:
/// `fill(rays, block)` puts up to eight rays into a block, and one packet is reused.
#[inline(always)]
fn aos_chunks(rays: &[Ray], mut fill: impl FnMut(&[Ray], &mut RayBlock), mut body: impl FnMut(usize, &Packet, &mut PacketHits)) {
    with_spare_packet(|p, h| {
        for (c, chunk) in rays.chunks(MAX_PACKET).enumerate() {
            let mut blocks = [RayBlock::EMPTY; GROUPS];
            for (b, eight) in blocks.iter_mut().zip(chunk.chunks(LANES)) {
                fill(eight, b);
            }
            p.load_blocks_into(&blocks[..chunk.len().div_ceil(LANES)], h);
            body(c * MAX_PACKET, p, h);
        }
    });
}

thread_local! {
    /// Each thread's packet between calls (see [`with_spare_packet`]).
    static SPARE_PACKET: std::cell::Cell<Option<Box<(Packet, PacketHits)>>> = const { std::cell::Cell::new(None) };
}

/// Runs `body` with a packet and its hits to load rays into: the thread's spare one (left
/// as the previous call left it), or a new one when a call is already using it. PERF: a
/// fresh packet is 4 KB to zero per call, a fiftieth of a sparse REND3R frame.
/// [`Packet::load_blocks_into`] sets everything a kernel reads, whatever was there before.
#[inline(always)]
fn with_spare_packet(body: impl FnOnce(&mut Packet, &mut PacketHits)) {
    let mut spare = SPARE_PACKET.with(std::cell::Cell::take).unwrap_or_else(|| Box::new(Packet::empty()));
    let (p, h) = &mut *spare;
    body(p, h);
    SPARE_PACKET.with(|s| s.set(Some(spare)));
}

/// Runs `body` on every run of at most [`GROUPS`] blocks, with the packet loaded. The next
/// packet's blocks are asked for before a packet is traced, so a long stream of blocks
/// does not wait on memory at every load. PERF: 64-ray shadow packets in the BART kitchen
/// mostly end at their first leaf; without the hint a quarter of their time went to
/// loading their 2 KB of rays.
#[inline(always)]
fn block_chunks(blocks: &[RayBlock], mut body: impl FnMut(usize, &Packet, &mut PacketHits)) {
    with_spare_packet(|p, h| {
        for (c, chunk) in blocks.chunks(GROUPS).enumerate() {
            p.load_blocks_into(chunk, h);
            let next = (c + 1) * GROUPS;
            prefetch_blocks(blocks.get(next..(next + GROUPS).min(blocks.len())).unwrap_or(&[]));
            body(c * MAX_PACKET, p, h);
        }
    });
}

/// Asks for the cache lines of `blocks` (a hint: nothing changes but how soon they can be
/// read; no effect off x86-64). A caller streaming blocks to [`MeshBvh::intersect_blocks`]
/// or [`MeshBvh::occluded_blocks`] in several calls can hand the next call's first blocks
/// here before the current call: each call already asks for its own later packets.
#[inline(always)]
pub fn prefetch_blocks(blocks: &[RayBlock]) {
    #[cfg(target_arch = "x86_64")]
    {
        // Every line the slice touches (blocks are aligned to 32 bytes, not to lines).
        let base = blocks.as_ptr().cast::<i8>();
        let bytes = std::mem::size_of_val(blocks);
        let mut at = 0;
        while at < bytes + (base as usize & 63) {
            // SAFETY: a prefetch hint (it never faults), at lines that overlap the slice;
            // SSE is part of x86-64.
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(base.wrapping_add(at)) };
            at += 64;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = blocks;
}

/// How many times a packet whose origins spread too far may be halved (up to 16 parts).
const SPLIT_DEPTH: usize = 4;

/// Traces the lanes of `active` as one packet when `interval` bounds them and tracing them
/// together pays ([`Interval::worth`] with origin spread `ext`). A packet whose origins
/// spread too far (the shadow rays of a tile that spans several objects) is halved at the
/// middle of its widest origin axis, up to [`SPLIT_DEPTH`] times, and each half tried again:
/// rays that start on one object stay together. Rays that mix direction signs (no interval
/// bounds them: a light straight above the tile, a view along an axis) are halved by sign
/// instead ([`Packet::sign_split`]), also up to [`SPLIT_DEPTH`] times. What is left (fewer
/// than three rays, or still scattered) goes as groups of eight when a group agrees on
/// direction signs, else ray by ray. `split` false turns the halving by origin off: inside
/// an instance the packet was already formed by the top level (splitting there again cost
/// the sunflowers 8%); sign splits stay on, as a rotation can mix the signs of rays that
/// agreed in world space. PERF: before sign splits, such rays went one by one: the BART
/// kitchen's frame with shadows took 6% longer.
///
/// PERF: a macro, not a function taking closures: closures are not compiled with the
/// caller's target features, so the AVX2 kernels would not inline into them.
macro_rules! coherent_parts {
    ($p:expr, $active:expr, $h:expr, $ext:expr, $split:expr, |$m:ident, $hh:ident| $interval:expr, |$iv:ident, $pm:ident, $ph:ident| $packet:expr, |$g:ident, $l:ident, $sh:ident| $single:expr) => {{
        let p: &Packet = $p;
        let h: &mut PacketHits = $h;
        let ext: f32 = $ext;
        let mut work = [([M8::NONE; GROUPS], 0usize); SPLIT_DEPTH + 1];
        work[0] = (*$active, 0);
        let max_depth = if $split { SPLIT_DEPTH } else { 0 };
        let mut n = 1;
        // Lanes no packet took; they go by groups (and rays) afterwards, each group once.
        let mut rest = [M8::NONE; GROUPS];
        while n > 0 {
            n -= 1;
            let (set, depth) = work[n];
            let lanes = lane_count(&set);
            // The parts of a split are bounded by their origins first (cheap), and only
            // those that are close enough get the full interval.
            let bounds = (depth > 0).then(|| p.origin_bounds(&set));
            let close = bounds.is_none_or(|b| b.widest().1 <= ext && lanes >= 3);
            // Whether halving may still help; rays that mix direction signs (no interval) are
            // split by sign instead.
            let mut by_sign = None;
            let splittable = if close {
                let whole = {
                    let ($m, $hh) = (&set, &*h);
                    $interval
                };
                match whole {
                    Some(iv) if iv.worth(lanes, ext) => {
                        let ($iv, $pm, $ph) = (&iv, &set, &mut *h);
                        $packet;
                        continue;
                    }
                    Some(_) => true,
                    None => {
                        by_sign = p.sign_split(&set);
                        by_sign.is_some()
                    }
                }
            } else {
                true
            };
            // Sign splits are made inside instances too (see above).
            let limit = if by_sign.is_some() { SPLIT_DEPTH } else { max_depth };
            if splittable && depth < limit && lanes >= 6 {
                let (below, above) = match by_sign {
                    Some(halves) => halves,
                    None => p.split_at(&set, bounds.unwrap_or_else(|| p.origin_bounds(&set))),
                };
                work[n] = (below, depth + 1);
                work[n + 1] = (above, depth + 1);
                n += 2;
            } else {
                for g in 0..GROUPS {
                    rest[g] = rest[g].or(set[g]);
                }
            }
        }
        for g in 0..p.groups {
            if rest[g].bits() == 0 {
                continue;
            }
            let mut one = [M8::NONE; GROUPS];
            one[g] = rest[g];
            let part = {
                let ($m, $hh) = (&one, &*h);
                $interval
            };
            match part {
                Some(iv) if iv.worth(lane_count(&one), ext) => {
                    let ($iv, $pm, $ph) = (&iv, &one, &mut *h);
                    $packet;
                }
                _ => {
                    let mut b = rest[g].bits();
                    while b != 0 {
                        let l = b.trailing_zeros() as usize;
                        b &= b - 1;
                        let ($g, $l, $sh) = (g, l, &mut *h);
                        $single;
                    }
                }
            }
        }
    }};
}

/// Number of lanes set in `m`.
#[inline(always)]
fn lane_count(m: &Masks) -> u32 {
    m.iter().map(|x| x.bits().count_ones()).sum()
}

impl MeshBvh {
    /// Closest hits of the lanes of `active` (packet traversal when the mesh has 8-wide
    /// unit-triangle nodes and the rays agree on direction signs; else ray by ray).
    #[inline(always)]
    pub(crate) fn packet_intersect_k<K: KernelSet, C: Counters>(
        &self,
        p: &Packet,
        active: &Masks,
        h: &mut PacketHits,
        inst: u32,
        split: bool,
        c: &mut C,
    ) {
        let single = |g: usize, l: usize, h: &mut PacketHits, c: &mut C| {
            let mut hit = h.get(g, l);
            // SAFETY: the packet entry points run K only where its features were detected.
            if unsafe { K::mesh_intersect(self, &p.ray(g, l, hit.t), &mut hit, c) } {
                hit.inst = inst;
            }
            h.put(g, l, &hit);
        };
        if let (TriangleTest::UnitTriangle, Nodes::W8(n)) = (self.test, &self.nodes) {
            let leaves = UnitPacketLeaves::<K> { tris: &self.tris, inst, k: std::marker::PhantomData, culled: Default::default() };
            let ext = max_spread(&self.bounds());
            coherent_parts!(
                p,
                active,
                h,
                ext,
                split,
                |m, _hh| p.interval(m),
                |iv, m, h| intersect::<K, _, _>(n, &leaves, p, iv, m, h, c),
                |g, l, h| single(g, l, h, c)
            );
        } else {
            for_lanes(p.groups, active, |g, l| single(g, l, h, c));
        }
    }

    /// Occlusion of the lanes of `active` (occluded lanes get `t = -inf`).
    #[inline(always)]
    pub(crate) fn packet_occluded_k<K: KernelSet, C: Counters>(
        &self,
        p: &Packet,
        active: &Masks,
        h: &mut PacketHits,
        split: bool,
        c: &mut C,
    ) {
        let single = |g: usize, l: usize, h: &mut PacketHits, c: &mut C| {
            let t = h.t[g].0[l];
            // SAFETY: as above.
            if unsafe { K::mesh_occluded(self, &p.ray(g, l, t), t, c) } {
                h.t[g].0[l] = f32::NEG_INFINITY;
            }
        };
        if let (TriangleTest::UnitTriangle, Nodes::W8(n)) = (self.test, &self.nodes) {
            let leaves = UnitPacketLeaves::<K> { tris: &self.tris, inst: INVALID, k: std::marker::PhantomData, culled: Default::default() };
            let ext = max_spread(&self.bounds());
            coherent_parts!(
                p,
                active,
                h,
                ext,
                split,
                |m, hh| p.occlusion_interval(m, hh),
                |iv, m, h| occluded::<K, _, _>(n, &leaves, p, iv, m, h, c),
                |g, l, h| single(g, l, h, c)
            );
        } else {
            for_lanes(p.groups, active, |g, l| single(g, l, h, c));
        }
    }

    /// Closest hits of coherent rays, traced together in packets of up to [`MAX_PACKET`]
    /// (for example the 64 primary rays of an 8×8 pixel tile): the same answers as
    /// [`MeshBvh::intersect`] ray by ray, except which of two triangles at exactly the same
    /// distance is reported. `out` must be as long as `rays`.
    pub fn intersect_packet(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.trace_intersect(Rays::Aos(rays), out);
    }

    /// Occlusion of coherent rays within `[tmin, tmax)`, traced in packets (for example the
    /// shadow rays of a tile toward one light): the same answers as [`MeshBvh::occluded`].
    pub fn occluded_packet(&self, rays: &[Ray], out: &mut [bool]) {
        self.trace_occluded(Rays::Aos(rays), out);
    }

    /// [`MeshBvh::intersect_packet`] counting the work into `stats` (scalar kernel: the
    /// same answers and the same nodes visited as the fast ones): a packet's inner node is
    /// one interval test for all its rays, its items the 4-triangle groups of the leaves
    /// some ray entered; rays traced alone (incoherent ones) count as single rays do.
    pub fn intersect_packet_with_stats(&self, rays: &[Ray], out: &mut [Option<Hit>], stats: &mut TraversalStats) {
        chunks(rays, |base, p, h| {
            self.packet_intersect_k::<ScalarSet, _>(p, &p.valid, h, INVALID, true, stats);
            write_hits(base, p, h, out);
        });
    }

    /// [`MeshBvh::occluded_packet`] counting the work into `stats` (scalar kernel), as
    /// [`MeshBvh::intersect_packet_with_stats`] does.
    pub fn occluded_packet_with_stats(&self, rays: &[Ray], out: &mut [bool], stats: &mut TraversalStats) {
        chunks(rays, |base, p, h| {
            self.packet_occluded_k::<ScalarSet, _>(p, &p.valid, h, true, stats);
            write_occluded(base, p, h, out);
        });
    }

    /// [`MeshBvh::intersect_packet`] on rays already in SoA blocks (eight blocks make one
    /// packet); `out` holds eight entries per block.
    pub fn intersect_blocks(&self, blocks: &[RayBlock], out: &mut [Option<Hit>]) {
        self.trace_intersect(Rays::Soa(blocks), out);
    }

    /// [`MeshBvh::occluded_packet`] on rays in SoA blocks; `out` holds eight entries per block.
    pub fn occluded_blocks(&self, blocks: &[RayBlock], out: &mut [bool]) {
        self.trace_occluded(Rays::Soa(blocks), out);
    }

    #[inline(always)]
    fn trace_intersect(&self, rays: Rays, out: &mut [Option<Hit>]) {
        match self.kernel() {
            // SAFETY: the kernel is only Simd/Avx512 when AVX2 and FMA were detected.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd | Kernel::Avx512 => unsafe { avx2_mesh_intersect(self, rays, out) },
            _ => rays.each(|base, p, h| {
                self.packet_intersect_k::<ScalarSet, _>(p, &p.valid, h, INVALID, true, &mut ());
                write_hits(base, p, h, out);
            }),
        }
    }

    #[inline(always)]
    fn trace_occluded(&self, rays: Rays, out: &mut [bool]) {
        match self.kernel() {
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd | Kernel::Avx512 => unsafe { avx2_mesh_occluded(self, rays, out) },
            _ => rays.each(|base, p, h| {
                self.packet_occluded_k::<ScalarSet, _>(p, &p.valid, h, true, &mut ());
                write_occluded(base, p, h, out);
            }),
        }
    }
}

/// Rays handed to a packet entry point, one by one or already in SoA blocks.
#[derive(Clone, Copy)]
enum Rays<'a> {
    Aos(&'a [Ray]),
    Soa(&'a [RayBlock]),
}

impl Rays<'_> {
    /// Runs `body` on every packet of at most [`MAX_PACKET`] rays, loaded, with the index of
    /// its first ray. Inlined into the callers (and their target features): loading a packet
    /// is a good part of the cost of a short shadow packet.
    #[inline(always)]
    fn each(self, body: impl FnMut(usize, &Packet, &mut PacketHits)) {
        match self {
            Rays::Aos(r) => chunks(r, body),
            Rays::Soa(b) => block_chunks(b, body),
        }
    }

    /// [`Rays::each`] for callers compiled with AVX2: rays given one by one are turned into
    /// SoA blocks eight at a time by an 8×8 transpose (PERF: lane-by-lane stores read back
    /// as vectors were a tenth of a sparse REND3R frame).
    ///
    /// # Safety
    /// AVX2 must be available.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn each_avx2(self, body: impl FnMut(usize, &Packet, &mut PacketHits)) {
        match self {
            Rays::Aos(rays) => aos_chunks(
                rays,
                // SAFETY: the caller guarantees AVX2.
                |eight, b| unsafe { avx::transpose_rays(eight, b) },
                body,
            ),
            Rays::Soa(b) => block_chunks(b, body),
        }
    }
}

// The closures below are defined inside the `target_feature` functions, so they are
// compiled with AVX2 and FMA too.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn avx2_mesh_intersect(m: &MeshBvh, rays: Rays, out: &mut [Option<Hit>]) {
    // SAFETY: this function is compiled with AVX2, which its callers checked.
    unsafe {
        rays.each_avx2(|base, p, h| {
            m.packet_intersect_k::<crate::kernel::SimdSet, _>(p, &p.valid, h, INVALID, true, &mut ());
            write_hits(base, p, h, out);
        })
    };
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn avx2_mesh_occluded(m: &MeshBvh, rays: Rays, out: &mut [bool]) {
    // SAFETY: this function is compiled with AVX2, which its callers checked.
    unsafe {
        rays.each_avx2(|base, p, h| {
            m.packet_occluded_k::<crate::kernel::SimdSet, _>(p, &p.valid, h, true, &mut ());
            write_occluded(base, p, h, out);
        })
    };
}

#[inline(always)]
fn write_hits(base: usize, p: &Packet, h: &PacketHits, out: &mut [Option<Hit>]) {
    let out = out.get_mut(base..).unwrap_or_default();
    for (g, chunk) in out.chunks_mut(LANES).take(p.groups).enumerate() {
        for (l, o) in chunk.iter_mut().enumerate() {
            *o = (h.prim[g][l] != INVALID).then(|| h.get(g, l));
        }
    }
}

#[inline(always)]
fn write_occluded(base: usize, p: &Packet, h: &PacketHits, out: &mut [bool]) {
    let out = out.get_mut(base..).unwrap_or_default();
    for (g, chunk) in out.chunks_mut(LANES).take(p.groups).enumerate() {
        for (l, o) in chunk.iter_mut().enumerate() {
            *o = p.valid[g].0[l] != 0 && h.t[g].0[l] == f32::NEG_INFINITY;
        }
    }
}

/// Instance leaves for packets.
struct InstPacketLeaves<'a, K> {
    tl: &'a TwoLevel,
    k: std::marker::PhantomData<K>,
}

impl<K: KernelSet> InstPacketLeaves<'_, K> {
    #[inline(always)]
    fn single(&self) -> InstLeaves<'_, K> {
        InstLeaves { tl: self.tl, k: std::marker::PhantomData }
    }

    /// The lanes `m` against instance `id`, closest hits into `h`.
    #[inline(always)]
    fn hit_instance(&self, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
        #[cfg(target_arch = "x86_64")]
        if K::SIMD {
            // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
            unsafe { avx2_hit_instance(self.tl, id, p, m, h) };
            return;
        }
        self.hit_instance_here(id, p, m, h);
    }

    /// The lanes `m` against instance `id`, occluded lanes to `-inf` in `h`.
    #[inline(always)]
    fn occludes(&self, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
        #[cfg(target_arch = "x86_64")]
        if K::SIMD {
            // SAFETY: as above.
            unsafe { avx2_occludes(self.tl, id, p, m, h) };
            return;
        }
        self.occludes_here(id, p, m, h);
    }

    #[inline(always)]
    fn hit_instance_here(&self, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
        let inst = &self.tl.instances()[id as usize];
        if let Geometry::Mesh(mesh) = &self.tl.geometries()[inst.geometry as usize] {
            // The rays carried into object space exactly as the single-ray path does.
            mesh.packet_intersect_k::<K, _>(&p.in_object_space(inst, m), m, h, id, false, &mut ());
            return;
        }
        if let Geometry::Shape(shape) = &self.tl.geometries()[inst.geometry as usize] {
            #[cfg(target_arch = "x86_64")]
            if K::SIMD && *shape == Shape::Sphere {
                for g in 0..p.groups {
                    if m[g].bits() == 0 {
                        continue;
                    }
                    // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
                    let (hit, t) = unsafe { sphere_group(p, g, inst, m[g], &h.t[g]) };
                    if hit.bits() != 0 {
                        // A sphere has one part (0) and no surface parameters here.
                        h.t[g] = h.t[g].blend(hit, t);
                        h.u[g] = h.u[g].blend(hit, F8::splat(0.0));
                        h.v[g] = h.v[g].blend(hit, F8::splat(0.0));
                        h.prim[g] = M8::blend_u32(hit, h.prim[g], [0; LANES]);
                        h.inst[g] = M8::blend_u32(hit, h.inst[g], [id; LANES]);
                    }
                }
                return;
            }
            // The same object-space rays as the single-ray path, without its box-test
            // constants (a shape needs none).
            let lp = p.transformed(&inst.object_from_world, m);
            for_lanes(p.groups, m, |g, l| {
                let r = lp.ray(g, l, h.t[g].0[l]);
                if let Some(s) = shape.intersect_local(r.org, r.dir, r.tmin, r.tmax) {
                    h.put(g, l, &Hit { t: s.t, u: 0.0, v: 0.0, prim: s.part, inst: id });
                }
            });
            return;
        }
        let single = self.single();
        for_lanes(p.groups, m, |g, l| {
            let mut hit = h.get(g, l);
            single.hit_instance(id, &RayPre::new(&p.ray(g, l, hit.t)), &mut hit, &mut ());
            h.put(g, l, &hit);
        });
    }

    #[inline(always)]
    fn occludes_here(&self, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
        let inst = &self.tl.instances()[id as usize];
        if let Geometry::Mesh(mesh) = &self.tl.geometries()[inst.geometry as usize] {
            mesh.packet_occluded_k::<K, _>(&p.in_object_space(inst, m), m, h, false, &mut ());
            return;
        }
        if let Geometry::Shape(shape) = &self.tl.geometries()[inst.geometry as usize] {
            #[cfg(target_arch = "x86_64")]
            if K::SIMD && *shape == Shape::Sphere {
                for g in 0..p.groups {
                    if m[g].bits() == 0 {
                        continue;
                    }
                    // SAFETY: as above.
                    let (hit, _) = unsafe { sphere_group(p, g, inst, m[g], &h.t[g]) };
                    h.t[g] = h.t[g].blend(hit, F8::splat(f32::NEG_INFINITY));
                }
                return;
            }
            let lp = p.transformed(&inst.object_from_world, m);
            for_lanes(p.groups, m, |g, l| {
                let r = lp.ray(g, l, h.t[g].0[l]);
                if shape.intersect_local(r.org, r.dir, r.tmin, r.tmax).is_some() {
                    h.t[g].0[l] = f32::NEG_INFINITY;
                }
            });
            return;
        }
        let single = self.single();
        for_lanes(p.groups, m, |g, l| {
            let t = h.t[g].0[l];
            if single.occludes(id, &RayPre::new(&p.ray(g, l, t)), t, &mut ()) {
                h.t[g].0[l] = f32::NEG_INFINITY;
            }
        });
    }
}

/// [`InstPacketLeaves::hit_instance`] with AVX2, out of line. Inlined, every kind of
/// instance (mesh walks with their own fallbacks, spheres, other shapes) made the top-level
/// occlusion walk one function of 137 KB of code; now it is 43 KB and this one 24 KB. Frame
/// times did not move either way (BART kitchen, 3 rounds), but profiles tell the two levels
/// apart.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
fn avx2_hit_instance(tl: &TwoLevel, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
    InstPacketLeaves::<crate::kernel::SimdSet> { tl, k: std::marker::PhantomData }.hit_instance_here(id, p, m, h);
}

/// [`InstPacketLeaves::occludes`] with AVX2, out of line (see [`avx2_hit_instance`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
fn avx2_occludes(tl: &TwoLevel, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
    InstPacketLeaves::<crate::kernel::SimdSet> { tl, k: std::marker::PhantomData }.occludes_here(id, p, m, h);
}

/// The unit-sphere test of the lanes `m` of group `g` against instance `inst` within
/// `[tmin, limit)`: the lanes that hit and their distances, the same as
/// [`Shape::intersect_local`] ray by ray. Lanes whose object-space direction is zero (the
/// SIMD code cannot divide by `a = 0`) are tested one by one.
///
/// # Safety
/// AVX2 and FMA must be available.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn sphere_group(p: &Packet, g: usize, inst: &crate::tlas::Instance, m: M8, limit: &F8) -> (M8, F8) {
    // SAFETY: the caller guarantees AVX2 and FMA.
    let (bits, mut t, odd) = unsafe { avx::sphere8(p, g, &inst.object_from_world, limit, m.bits()) };
    let mut hit = bits & m.bits();
    let mut b = odd & m.bits();
    while b != 0 {
        let l = b.trailing_zeros() as usize;
        b &= b - 1;
        let r = p.ray(g, l, limit.0[l]).transformed(&inst.object_from_world);
        if let Some(s) = Shape::Sphere.intersect_local(r.org, r.dir, r.tmin, r.tmax) {
            hit |= 1 << l;
            t.0[l] = s.t;
        }
    }
    (M8::from_bits(hit), t)
}

impl<K: KernelSet> PacketLeaves for InstPacketLeaves<'_, K> {
    #[inline(always)]
    fn intersect(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
        for i in first..first + count {
            self.hit_instance(self.tl.order[i as usize], p, m, h);
        }
    }
    #[inline(always)]
    fn occluded(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
        for i in first..first + count {
            // Only the lanes still unoccluded go on.
            let live: Masks = std::array::from_fn(|g| h.t[g].ge(F8::splat(f32::MIN)).and(m[g]));
            if live.iter().all(|x| x.bits() == 0) {
                return;
            }
            self.occludes(self.tl.order[i as usize], p, &live, h);
        }
    }
}

impl TwoLevel {
    #[inline(always)]
    fn packet_intersect_k<K: KernelSet>(&self, p: &Packet, h: &mut PacketHits) {
        let active = p.valid;
        if let Some(mesh) = self.only_mesh() {
            mesh.packet_intersect_k::<K, _>(p, &active, h, 0, true, &mut ());
            return;
        }
        let leaves = InstPacketLeaves::<K> { tl: self, k: std::marker::PhantomData };
        let ext = max_spread(&self.bounds());
        coherent_parts!(
            p,
            &active,
            h,
            ext,
            true,
            |m, _hh| p.interval(m),
            |iv, m, h| {
                intersect::<K, _, _>(&self.nodes, &leaves, p, iv, m, h, &mut ());
                for &i in &self.unbounded {
                    leaves.hit_instance(i, p, m, h);
                }
            },
            |g, l, h| {
                let mut hit = h.get(g, l);
                // SAFETY: the packet entry points run K only where its features were detected.
                unsafe { K::two_level_intersect(self, &p.ray(g, l, hit.t), &mut hit) };
                h.put(g, l, &hit);
            }
        );
    }

    #[inline(always)]
    fn packet_among_k<K: KernelSet>(&self, ids: &[u32], p: &Packet, h: &mut PacketHits) {
        let leaves = InstPacketLeaves::<K> { tl: self, k: std::marker::PhantomData };
        let n = self.instances().len();
        for &i in ids.iter().filter(|&&i| (i as usize) < n).chain(&self.unbounded) {
            leaves.hit_instance(i, p, &p.valid, h);
        }
    }

    #[inline(always)]
    fn packet_occluded_k<K: KernelSet>(&self, p: &Packet, h: &mut PacketHits) {
        let active = p.valid;
        if let Some(mesh) = self.only_mesh() {
            mesh.packet_occluded_k::<K, _>(p, &active, h, true, &mut ());
            return;
        }
        let leaves = InstPacketLeaves::<K> { tl: self, k: std::marker::PhantomData };
        // Rays toward a directional light: the few instances near their origins, seen
        // from the light, without the walk.
        let mut ids = [0u32; crate::shadow_grid::MAX_CANDIDATES];
        if let Some(n) = self.shadow_candidates(p, &mut ids) {
            for &i in ids[..n].iter().chain(&self.unbounded) {
                leaves.occluded_one(i, p, &active, h);
            }
            return;
        }
        let ext = max_spread(&self.bounds());
        coherent_parts!(
            p,
            &active,
            h,
            ext,
            true,
            |m, hh| p.occlusion_interval(m, hh),
            |iv, m, h| {
                for &i in &self.unbounded {
                    leaves.occluded_one(i, p, m, h);
                }
                occluded::<K, _, _>(&self.nodes, &leaves, p, iv, m, h, &mut ());
            },
            |g, l, h| {
                let t = h.t[g].0[l];
                // SAFETY: as above.
                if unsafe { K::two_level_occluded(self, &p.ray(g, l, t), t) } {
                    h.t[g].0[l] = f32::NEG_INFINITY;
                }
            }
        );
    }

    /// The instances that the valid rays of `p` can meet, besides the unbounded ones, when
    /// they all run along a direction with a shadow grid and there are few (see
    /// [`TwoLevel::set_shadow_directions`]).
    #[inline(always)]
    fn shadow_candidates(&self, p: &Packet, out: &mut [u32; crate::shadow_grid::MAX_CANDIDATES]) -> Option<usize> {
        if self.shadow_grids.is_empty() {
            return None;
        }
        let (g0, l0) = p.first_lane(&p.valid)?;
        let d = p.dir(g0, l0).to_array();
        let grid = self.shadow_grids.iter().find(|gr| gr.dir.to_array().map(f32::to_bits) == d.map(f32::to_bits))?;
        // Every valid ray along exactly that direction.
        for g in 0..p.groups {
            let m = p.valid[g];
            if m.bits() == 0 {
                continue;
            }
            let same = p.d[g][0].eq(F8::splat(d[0])).and(p.d[g][1].eq(F8::splat(d[1]))).and(p.d[g][2].eq(F8::splat(d[2])));
            if same.and(m).bits() != m.bits() {
                return None;
            }
        }
        let b = p.origin_bounds(&p.valid);
        grid.candidates(glam::Vec3::from(b.lo), glam::Vec3::from(b.hi), out)
    }

    /// Closest hits of coherent rays over all instances, traced together in packets of up
    /// to [`MAX_PACKET`] (for example the 64 primary rays of an 8×8 pixel tile). The same
    /// answers as [`TwoLevel::intersect`] ray by ray, except which of two surfaces at exactly
    /// the same distance is reported. `out` must be as long as `rays`.
    pub fn intersect_packet(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.trace_intersect(Rays::Aos(rays), out);
    }

    /// Occlusion of coherent rays within `[tmin, tmax)` (for example the shadow rays of a
    /// tile toward one light), traced in packets: the same answers as [`TwoLevel::occluded`].
    pub fn occluded_packet(&self, rays: &[Ray], out: &mut [bool]) {
        self.trace_occluded(Rays::Aos(rays), out);
    }

    /// [`TwoLevel::intersect_packet`] on rays in SoA blocks; `out` holds eight entries per block.
    pub fn intersect_blocks(&self, blocks: &[RayBlock], out: &mut [Option<Hit>]) {
        self.trace_intersect(Rays::Soa(blocks), out);
    }

    /// [`TwoLevel::intersect_packet`] for rays known to meet no instance but those of
    /// `ids` (and the unbounded ones), for example primary rays of a screen block that only
    /// a few instances cover: those are tested directly, without the top-level walk. The
    /// same answers, except which of two surfaces at exactly the same distance is
    /// reported. Ids out of range are skipped.
    pub fn intersect_packet_among(&self, rays: &[Ray], ids: &[u32], out: &mut [Option<Hit>]) {
        match self.kernel {
            // SAFETY: the kernel is only Simd/Avx512 when AVX2 and FMA were detected.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd | Kernel::Avx512 => unsafe { avx2_tl_intersect_among(self, Rays::Aos(rays), ids, out) },
            _ => Rays::Aos(rays).each(|base, p, h| {
                self.packet_among_k::<ScalarSet>(ids, p, h);
                write_hits(base, p, h, out);
            }),
        }
    }

    /// [`TwoLevel::occluded_packet`] on rays in SoA blocks; `out` holds eight entries per block.
    pub fn occluded_blocks(&self, blocks: &[RayBlock], out: &mut [bool]) {
        self.trace_occluded(Rays::Soa(blocks), out);
    }

    #[inline(always)]
    fn trace_intersect(&self, rays: Rays, out: &mut [Option<Hit>]) {
        match self.kernel {
            // SAFETY: the kernel is only Simd/Avx512 when AVX2 and FMA were detected.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd | Kernel::Avx512 => unsafe { avx2_tl_intersect(self, rays, out) },
            _ => rays.each(|base, p, h| {
                self.packet_intersect_k::<ScalarSet>(p, h);
                write_hits(base, p, h, out);
            }),
        }
    }

    #[inline(always)]
    fn trace_occluded(&self, rays: Rays, out: &mut [bool]) {
        match self.kernel {
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd | Kernel::Avx512 => unsafe { avx2_tl_occluded(self, rays, out) },
            _ => rays.each(|base, p, h| {
                self.packet_occluded_k::<ScalarSet>(p, h);
                write_occluded(base, p, h, out);
            }),
        }
    }
}

impl<K: KernelSet> InstPacketLeaves<'_, K> {
    #[inline(always)]
    fn occluded_one(&self, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits) {
        let live: Masks = std::array::from_fn(|g| h.t[g].ge(F8::splat(f32::MIN)).and(m[g]));
        self.occludes(id, p, &live, h);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn avx2_tl_intersect(t: &TwoLevel, rays: Rays, out: &mut [Option<Hit>]) {
    // SAFETY: this function is compiled with AVX2, which its callers checked.
    unsafe {
        rays.each_avx2(|base, p, h| {
            t.packet_intersect_k::<crate::kernel::SimdSet>(p, h);
            write_hits(base, p, h, out);
        })
    };
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn avx2_tl_intersect_among(t: &TwoLevel, rays: Rays, ids: &[u32], out: &mut [Option<Hit>]) {
    // SAFETY: this function is compiled with AVX2, which its callers checked.
    unsafe {
        rays.each_avx2(|base, p, h| {
            t.packet_among_k::<crate::kernel::SimdSet>(ids, p, h);
            write_hits(base, p, h, out);
        })
    };
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn avx2_tl_occluded(t: &TwoLevel, rays: Rays, out: &mut [bool]) {
    // SAFETY: this function is compiled with AVX2, which its callers checked.
    unsafe {
        rays.each_avx2(|base, p, h| {
            t.packet_occluded_k::<crate::kernel::SimdSet>(p, h);
            write_occluded(base, p, h, out);
        })
    };
}

#[cfg(target_arch = "x86_64")]
mod avx {
    //! AVX2 versions of the hot loops: the same operations in the same order as the
    //! portable ones (so the same answers), one instruction per eight lanes.
    use super::{Interval, Packet, PacketHits, RayBlock, F8, FAR_SCALE, LANES, M8};
    use crate::geom::Ray;

    /// Up to eight rays into the SoA block `b` (lanes past `rays.len()` get
    /// [`RayBlock::EMPTY`]'s empty ray): each ray's eight floats (origin, direction, tmin,
    /// tmax) are one row of an 8×8 matrix, transposed with unpacks, shuffles and lane
    /// permutes.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn transpose_rays(rays: &[Ray], b: &mut RayBlock) {
        let row = |i: usize| {
            let r =
                rays.get(i).copied().unwrap_or(Ray { org: glam::Vec3::ZERO, dir: glam::Vec3::ZERO, tmin: 0.0, tmax: f32::NEG_INFINITY });
            let a = [r.org.x, r.org.y, r.org.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax];
            // SAFETY: `a` holds eight floats.
            unsafe { _mm256_loadu_ps(a.as_ptr()) }
        };
        let r: [__m256; 8] = std::array::from_fn(row);
        let t0 = _mm256_unpacklo_ps(r[0], r[1]);
        let t1 = _mm256_unpackhi_ps(r[0], r[1]);
        let t2 = _mm256_unpacklo_ps(r[2], r[3]);
        let t3 = _mm256_unpackhi_ps(r[2], r[3]);
        let t4 = _mm256_unpacklo_ps(r[4], r[5]);
        let t5 = _mm256_unpackhi_ps(r[4], r[5]);
        let t6 = _mm256_unpacklo_ps(r[6], r[7]);
        let t7 = _mm256_unpackhi_ps(r[6], r[7]);
        let u0 = _mm256_shuffle_ps::<0x44>(t0, t2);
        let u1 = _mm256_shuffle_ps::<0xee>(t0, t2);
        let u2 = _mm256_shuffle_ps::<0x44>(t1, t3);
        let u3 = _mm256_shuffle_ps::<0xee>(t1, t3);
        let u4 = _mm256_shuffle_ps::<0x44>(t4, t6);
        let u5 = _mm256_shuffle_ps::<0xee>(t4, t6);
        let u6 = _mm256_shuffle_ps::<0x44>(t5, t7);
        let u7 = _mm256_shuffle_ps::<0xee>(t5, t7);
        let rows = [
            _mm256_permute2f128_ps::<0x20>(u0, u4),
            _mm256_permute2f128_ps::<0x20>(u1, u5),
            _mm256_permute2f128_ps::<0x20>(u2, u6),
            _mm256_permute2f128_ps::<0x20>(u3, u7),
            _mm256_permute2f128_ps::<0x31>(u0, u4),
            _mm256_permute2f128_ps::<0x31>(u1, u5),
            _mm256_permute2f128_ps::<0x31>(u2, u6),
            _mm256_permute2f128_ps::<0x31>(u3, u7),
        ];
        let mut out = [[0.0f32; LANES]; 8];
        for (o, v) in out.iter_mut().zip(rows) {
            // SAFETY: `o` holds eight floats.
            unsafe { _mm256_storeu_ps(o.as_mut_ptr(), v) };
        }
        *b = RayBlock { org: [out[0], out[1], out[2]], dir: [out[3], out[4], out[5]], tmin: out[6], tmax: out[7] };
    }
    use super::cyclic;
    use crate::triangle::Tri4;
    use crate::wide::WideNode;
    use std::arch::x86_64::*;

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn ld(a: &F8) -> __m256 {
        // SAFETY: `F8` is 32 bytes, 32-byte aligned.
        unsafe { _mm256_load_ps(a.0.as_ptr()) }
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn ldm(a: &M8) -> __m256 {
        // SAFETY: `M8` is 32 bytes, 32-byte aligned.
        unsafe { _mm256_castsi256_ps(_mm256_load_si256(a.0.as_ptr().cast())) }
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn st(v: __m256) -> F8 {
        let mut r = F8([0.0; LANES]);
        // SAFETY: as in `ld`.
        unsafe { _mm256_store_ps(r.0.as_mut_ptr(), v) };
        r
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn stm(v: __m256) -> M8 {
        let mut r = M8([0; LANES]);
        // SAFETY: as in `ldm`.
        unsafe { _mm256_store_si256(r.0.as_mut_ptr().cast(), _mm256_castps_si256(v)) };
        r
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn ldu(a: &[u32; LANES]) -> __m256 {
        // SAFETY: 32 bytes, unaligned load.
        unsafe { _mm256_castsi256_ps(_mm256_loadu_si256(a.as_ptr().cast())) }
    }

    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn stu(v: __m256, a: &mut [u32; LANES]) {
        // SAFETY: 32 bytes, unaligned store.
        unsafe { _mm256_storeu_si256(a.as_mut_ptr().cast(), _mm256_castps_si256(v)) };
    }

    /// `super::interval_test`.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn interval_test(node: &WideNode<8>, iv: &Interval, tmax: f32, dist: &mut [f32; 8]) -> u32 {
        let row = |r: usize| {
            // SAFETY: rows are 32 bytes at 32-byte aligned offsets of a 64-byte aligned node.
            unsafe { _mm256_load_ps(node.bounds[r].as_ptr()) }
        };
        let mut tn = _mm256_set1_ps(iv.tmin);
        let mut tf = _mm256_set1_ps(tmax);
        for k in 0..3 {
            let (bn, bf) = (row(iv.inear[k]), row(iv.ifar[k]));
            let (olo, ohi) = (_mm256_set1_ps(iv.olo[k]), _mm256_set1_ps(iv.ohi[k]));
            let (rlo, rhi) = (_mm256_set1_ps(iv.rlo[k]), _mm256_set1_ps(iv.rhi[k]));
            let (n0, n1) = (_mm256_sub_ps(bn, olo), _mm256_sub_ps(bn, ohi));
            let lo = _mm256_min_ps(
                _mm256_min_ps(_mm256_mul_ps(n0, rlo), _mm256_mul_ps(n0, rhi)),
                _mm256_min_ps(_mm256_mul_ps(n1, rlo), _mm256_mul_ps(n1, rhi)),
            );
            let (f0, f1) = (_mm256_sub_ps(bf, olo), _mm256_sub_ps(bf, ohi));
            let hi = _mm256_add_ps(
                _mm256_max_ps(
                    _mm256_max_ps(_mm256_mul_ps(f0, rlo), _mm256_mul_ps(f0, rhi)),
                    _mm256_max_ps(_mm256_mul_ps(f1, rlo), _mm256_mul_ps(f1, rhi)),
                ),
                _mm256_set1_ps(iv.pad[k]),
            );
            tn = _mm256_max_ps(lo, tn);
            tf = _mm256_min_ps(hi, tf);
        }
        // SAFETY: `dist` is 32 bytes.
        unsafe { _mm256_storeu_ps(dist.as_mut_ptr(), tn) };
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, _mm256_mul_ps(tf, _mm256_set1_ps(FAR_SCALE)))) as u32
    }

    /// `PacketHits::max_t`.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn max_t(h: &PacketHits, groups: usize, active: &super::Masks) -> f32 {
        let ninf = _mm256_set1_ps(f32::NEG_INFINITY);
        let mut m = ninf;
        for g in 0..groups {
            m = _mm256_max_ps(m, _mm256_blendv_ps(ninf, ld(&h.t[g]), ldm(&active[g])));
        }
        let m4 = _mm_max_ps(_mm256_castps256_ps128(m), _mm256_extractf128_ps::<1>(m));
        let m2 = _mm_max_ps(m4, _mm_movehl_ps(m4, m4));
        let m1 = _mm_max_ss(m2, _mm_shuffle_ps::<1>(m2, m2));
        _mm_cvtss_f32(m1)
    }

    /// `super::group_box`.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn group_box(rows: &[f32; 6], p: &Packet, iv: &Interval, g: usize, t: &F8) -> M8 {
        let mut tn = ld(&p.tmin[g]);
        let mut tf = ld(t);
        for k in 0..3 {
            let (o, inv) = (ld(&p.o[g][k]), ld(&p.inv[g][k]));
            let a = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(rows[iv.near[k]]), o), inv);
            let b = _mm256_add_ps(_mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(rows[iv.far[k]]), o), inv), _mm256_set1_ps(iv.pad[k]));
            tn = _mm256_max_ps(a, tn);
            tf = _mm256_min_ps(b, tf);
        }
        stm(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, _mm256_mul_ps(tf, _mm256_set1_ps(FAR_SCALE))))
    }

    /// `super::tri_eval` for all four lanes of `t4`, rays of group `g`.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn eval(t4: &Tri4, lane: usize, p: &Packet, g: usize, tmax: __m256, org: Option<&[[f32; 4]; 3]>) -> (__m256, [__m256; 4]) {
        let m = |c: usize| _mm256_set1_ps(t4.m[c][lane]);
        let k = t4.axis(lane) as usize;
        let d = cyclic(&p.d[g], k);
        let (d0, d1, d2) = (ld(&d[0]), ld(&d[1]), ld(&d[2]));
        let zero = _mm256_setzero_ps();
        let dir = |i: usize| _mm256_fmadd_ps(m(i), d1, _mm256_fmadd_ps(m(i + 1), d2, _mm256_mul_ps(m(i + 2), zero)));
        let dzp = _mm256_fmadd_ps(m(6), d1, _mm256_fmadd_ps(m(7), d2, _mm256_fmadd_ps(m(8), zero, d0)));
        let dxp = dir(0);
        let dyp = dir(3);
        let (oxp, oyp, ozp) = match org {
            // The origin's terms, computed once per triangle (`origin_terms`), broadcast.
            Some(o) => (_mm256_set1_ps(o[0][lane]), _mm256_set1_ps(o[1][lane]), _mm256_set1_ps(o[2][lane])),
            None => {
                let o = cyclic(&p.o[g], k);
                let (o0, o1, o2) = (ld(&o[0]), ld(&o[1]), ld(&o[2]));
                let org = |i: usize| _mm256_fmadd_ps(m(i), o1, _mm256_fmadd_ps(m(i + 1), o2, m(i + 2)));
                let oz = _mm256_fmadd_ps(m(6), o1, _mm256_fmadd_ps(m(7), o2, _mm256_add_ps(m(8), o0)));
                (org(0), org(3), oz)
            }
        };
        let signbit = _mm256_set1_ps(-0.0);
        let s = _mm256_and_ps(dzp, signbit);
        let adz = _mm256_xor_ps(dzp, s);
        let uu = _mm256_xor_ps(_mm256_fmsub_ps(oxp, dzp, _mm256_mul_ps(ozp, dxp)), s);
        let vv = _mm256_xor_ps(_mm256_fmsub_ps(oyp, dzp, _mm256_mul_ps(ozp, dyp)), s);
        let tt = _mm256_xor_ps(_mm256_xor_ps(ozp, signbit), s);
        let zero = _mm256_setzero_ps();
        let ok = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(uu, zero), _mm256_cmp_ps::<_CMP_GE_OQ>(vv, zero)),
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_add_ps(uu, vv), adz),
                _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_GE_OQ>(tt, _mm256_mul_ps(ld(&p.tmin[g]), adz)),
                    _mm256_cmp_ps::<_CMP_LT_OQ>(tt, _mm256_mul_ps(tmax, adz)),
                ),
            ),
        );
        (ok, [tt, uu, vv, adz])
    }

    /// `O'x, O'y, O'z` of the four triangles of `t4` for the common origin `o`, with the
    /// same operations in the same order as the per-lane test (so the same values).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn origin_terms(t4: &Tri4, o: &[f32; 3]) -> [[f32; 4]; 3] {
        // SAFETY: `Tri4` rows are 16-byte aligned `[f32; 4]`s.
        let row = |c: usize| unsafe { _mm_load_ps(t4.m[c].as_ptr()) };
        let [p0, p1, p2] = rotated(t4, _mm_setr_ps(o[0], o[1], o[2], 0.0));
        let ox = _mm_fmadd_ps(row(0), p1, _mm_fmadd_ps(row(1), p2, row(2)));
        let oy = _mm_fmadd_ps(row(3), p1, _mm_fmadd_ps(row(4), p2, row(5)));
        let oz = _mm_fmadd_ps(row(6), p1, _mm_fmadd_ps(row(7), p2, _mm_add_ps(row(8), p0)));
        let mut out = [[0f32; 4]; 3];
        for (slot, v) in out.iter_mut().zip([ox, oy, oz]) {
            // SAFETY: `slot` is 16 bytes.
            unsafe { _mm_storeu_ps(slot.as_mut_ptr(), v) };
        }
        out
    }

    /// Components `k, k+1, k+2` of `v = (x, y, z, 0)` for each lane of `t4`, `k` being the
    /// lane's axis (a lane without one gets the zero).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn rotated(t4: &Tri4, v: __m128) -> [__m128; 3] {
        // SAFETY: `Tri4` is 16-byte aligned, its ids 16 bytes.
        let k = _mm_srli_epi32::<{ crate::triangle::AXIS_SHIFT as i32 }>(unsafe { _mm_load_si128(t4.prim.as_ptr().cast()) });
        let next = _mm_permutevar_ps(_mm_castsi128_ps(_mm_setr_epi32(1, 2, 0, 3)), k);
        let after = _mm_permutevar_ps(_mm_castsi128_ps(_mm_setr_epi32(2, 0, 1, 3)), k);
        [_mm_permutevar_ps(v, k), _mm_permutevar_ps(v, _mm_castps_si128(next)), _mm_permutevar_ps(v, _mm_castps_si128(after))]
    }

    /// The lanes of `t4` that some ray of a packet with common origin and directions within
    /// `c` may hit (bit `i` for lane `i`); `org` holds the lanes' origin terms
    /// ([`origin_terms`]). With the origin fixed, the triangle test's `U = O'x·D'z − O'z·D'x`,
    /// `V` and `U + V − D'z` are linear in the direction, so their ranges over the
    /// direction box bound them for every ray of the packet (interval arithmetic, as the
    /// packet's box culling): a lane is dropped when, for every ray, `D'z` has one sign and
    /// `U`, `V` or `U + V − D'z` has the wrong one, or the plane lies behind the origin. The
    /// ranges must clear zero by a margin ten thousand times the rounding of the exact
    /// test, so no lane that test would hit is dropped.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn frustum_keep(t4: &Tri4, org: &[[f32; 4]; 3], c: &super::DirBounds) -> i32 {
        // SAFETY: `Tri4` rows and `org` rows are 16-byte aligned / 16-byte `[f32; 4]`s.
        let row = |r: usize| unsafe { _mm_load_ps(t4.m[r].as_ptr()) };
        let o = |k: usize| unsafe { _mm_loadu_ps(org[k].as_ptr()) };
        let (ox, oy, oz) = (o(0), o(1), o(2));
        let abs = |v: __m128| _mm_andnot_ps(_mm_set1_ps(-0.0), v);
        // The direction box in each lane's own component order, as its map reads it.
        let lo = rotated(t4, _mm_setr_ps(c.lo[0], c.lo[1], c.lo[2], 0.0));
        let hi = rotated(t4, _mm_setr_ps(c.hi[0], c.hi[1], c.hi[2], 0.0));
        let mag: [__m128; 3] = std::array::from_fn(|k| _mm_max_ps(abs(lo[k]), abs(hi[k])));
        // Range of a·d over the box.
        let range = |a: [__m128; 3]| {
            let (mut l, mut h) = (_mm_setzero_ps(), _mm_setzero_ps());
            for k in 0..3 {
                let (x, y) = (_mm_mul_ps(a[k], lo[k]), _mm_mul_ps(a[k], hi[k]));
                l = _mm_add_ps(l, _mm_min_ps(x, y));
                h = _mm_add_ps(h, _mm_max_ps(x, y));
            }
            (l, h)
        };
        // Σ|a_k|·max|d_k|: the scale a·d's rounding goes with.
        let scale = |a: [__m128; 3]| (0..3).fold(_mm_setzero_ps(), |s, k| _mm_fmadd_ps(abs(a[k]), mag[k], s));
        // The maps' direction rows over those components: the axis' column is (0, 0, 1).
        let (zero, one) = (_mm_setzero_ps(), _mm_set1_ps(1.0));
        let mx = [zero, row(0), row(1)];
        let my = [zero, row(3), row(4)];
        let mz = [one, row(6), row(7)];
        let au: [__m128; 3] = std::array::from_fn(|k| _mm_fmsub_ps(ox, mz[k], _mm_mul_ps(oz, mx[k])));
        let av: [__m128; 3] = std::array::from_fn(|k| _mm_fmsub_ps(oy, mz[k], _mm_mul_ps(oz, my[k])));
        let aw: [__m128; 3] = std::array::from_fn(|k| _mm_sub_ps(_mm_add_ps(au[k], av[k]), mz[k]));
        let (zl, zh) = range(mz);
        let (ul, uh) = range(au);
        let (vl, vh) = range(av);
        let (wl, wh) = range(aw);
        let (xs, ys, zs) = (scale(mx), scale(my), scale(mz));
        // One margin for all four forms: 1e-4 of the magnitudes their terms can reach.
        let e = _mm_mul_ps(
            _mm_set1_ps(1e-4),
            _mm_add_ps(_mm_fmadd_ps(_mm_add_ps(abs(ox), abs(oy)), zs, _mm_mul_ps(abs(oz), _mm_add_ps(xs, ys))), zs),
        );
        let ez = _mm_mul_ps(_mm_set1_ps(1e-4), zs);
        let ne = _mm_sub_ps(_mm_setzero_ps(), e);
        let zero = _mm_setzero_ps();
        let fwd = if c.forward { _mm_castsi128_ps(_mm_set1_epi32(-1)) } else { zero };
        // D'z > 0 for every ray: a hit needs U ≥ 0, V ≥ 0, U + V ≤ D'z and O'z ≤ 0.
        let pos = _mm_cmpgt_ps(zl, ez);
        let pos_out = _mm_or_ps(
            _mm_or_ps(_mm_cmplt_ps(uh, ne), _mm_cmplt_ps(vh, ne)),
            _mm_or_ps(_mm_cmpgt_ps(wl, e), _mm_and_ps(fwd, _mm_cmpgt_ps(oz, zero))),
        );
        // D'z < 0 for every ray: the same with the signs turned.
        let neg = _mm_cmplt_ps(zh, _mm_sub_ps(zero, ez));
        let neg_out = _mm_or_ps(
            _mm_or_ps(_mm_cmpgt_ps(ul, e), _mm_cmpgt_ps(vl, e)),
            _mm_or_ps(_mm_cmplt_ps(wh, ne), _mm_and_ps(fwd, _mm_cmplt_ps(oz, zero))),
        );
        let out = _mm_or_ps(_mm_and_ps(pos, pos_out), _mm_and_ps(neg, neg_out));
        !_mm_movemask_ps(out) & 0xF
    }

    /// The closest-hit leaf step of one group against one `Tri4` (see the portable loop),
    /// for the lanes of `keep` only.
    #[allow(clippy::too_many_arguments)] // the leaf loop's state, passed as it is
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn tri4_intersect(
        t4: &Tri4,
        p: &Packet,
        g: usize,
        m: &M8,
        h: &mut PacketHits,
        inst: u32,
        org: Option<&[[f32; 4]; 3]>,
        keep: i32,
    ) {
        let limit = ld(&h.t[g]);
        let mask = ldm(m);
        let mut found = _mm256_setzero_ps();
        let mut bt = _mm256_set1_ps(f32::INFINITY);
        let (mut bu, mut bv) = (bt, bt);
        let mut bp = _mm256_setzero_ps();
        for lane in 0..4 {
            // Padding lanes come last and never hit.
            if t4.is_pad(lane) {
                break;
            }
            if keep & (1 << lane) == 0 {
                continue;
            }
            let (ok, [tt, uu, vv, adz]) = eval(t4, lane, p, g, limit, org);
            let ok = _mm256_and_ps(ok, mask);
            if _mm256_movemask_ps(ok) == 0 {
                continue;
            }
            let t = _mm256_div_ps(tt, adz);
            let take = _mm256_and_ps(
                ok,
                _mm256_or_ps(_mm256_andnot_ps(found, _mm256_castsi256_ps(_mm256_set1_epi32(-1))), _mm256_cmp_ps::<_CMP_LT_OQ>(t, bt)),
            );
            bt = _mm256_blendv_ps(bt, t, take);
            bu = _mm256_blendv_ps(bu, _mm256_div_ps(uu, adz), take);
            bv = _mm256_blendv_ps(bv, _mm256_div_ps(vv, adz), take);
            bp = _mm256_blendv_ps(bp, _mm256_castsi256_ps(_mm256_set1_epi32(t4.id(lane) as i32)), take);
            found = _mm256_or_ps(found, take);
        }
        if _mm256_movemask_ps(found) != 0 {
            h.t[g] = st(_mm256_blendv_ps(limit, bt, found));
            h.u[g] = st(_mm256_blendv_ps(ld(&h.u[g]), bu, found));
            h.v[g] = st(_mm256_blendv_ps(ld(&h.v[g]), bv, found));
            let prim = _mm256_blendv_ps(ldu(&h.prim[g]), bp, found);
            stu(prim, &mut h.prim[g]);
            let ids = _mm256_blendv_ps(ldu(&h.inst[g]), _mm256_castsi256_ps(_mm256_set1_epi32(inst as i32)), found);
            stu(ids, &mut h.inst[g]);
        }
    }

    /// [`crate::shape::Shape::intersect_local`] of the unit sphere for the eight rays of
    /// group `g` carried by `m` into object space, with the same operations in the same
    /// order (the transform as [`Packet::transformed`], the quadric in f64 as
    /// `shape::quadric`), so the same answers bit for bit. Returns the lanes that hit within
    /// `[tmin, hi)`, their distances, and the lanes whose object-space direction is zero
    /// (`a = 0`: the caller tests those one by one).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn sphere8(p: &Packet, g: usize, m: &glam::Affine3A, hi: &F8, active: u32) -> (u32, F8, u32) {
        let c = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
        let tr = m.translation;
        let (ox, oy, oz) = (ld(&p.o[g][0]), ld(&p.o[g][1]), ld(&p.o[g][2]));
        let (dx, dy, dz) = (ld(&p.d[g][0]), ld(&p.d[g][1]), ld(&p.d[g][2]));
        let mut lo = [_mm256_setzero_ps(); 3];
        let mut ld_ = [_mm256_setzero_ps(); 3];
        for r in 0..3 {
            let (a, b, cc) = (_mm256_set1_ps(c[0][r]), _mm256_set1_ps(c[1][r]), _mm256_set1_ps(c[2][r]));
            lo[r] = _mm256_add_ps(
                _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(a, ox), _mm256_mul_ps(b, oy)), _mm256_mul_ps(cc, oz)),
                _mm256_set1_ps(tr[r]),
            );
            ld_[r] = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(a, dx), _mm256_mul_ps(b, dy)), _mm256_mul_ps(cc, dz));
        }
        let (tmin, tmax) = (ld(&p.tmin[g]), ld(hi));
        // PERF: lanes that start outside the sphere (c > 0) and run away from its centre
        // (b > 0) have both roots negative, so no hit at t >= tmin >= 0: the shadow rays
        // leaving a sphere's lit side, tested against that sphere. Decided in f32 with a
        // margin of four times the dot products' rounding (the f64 code uses the same
        // f32 inputs), so a lane is dropped only where the f64 test would find no hit.
        let away = {
            let abs = |v: __m256| _mm256_andnot_ps(_mm256_set1_ps(-0.0), v);
            let (px, py, pz) = (_mm256_mul_ps(ld_[0], lo[0]), _mm256_mul_ps(ld_[1], lo[1]), _mm256_mul_ps(ld_[2], lo[2]));
            let b = _mm256_add_ps(_mm256_add_ps(px, py), pz);
            let eb = _mm256_mul_ps(_mm256_set1_ps(1e-6), _mm256_add_ps(_mm256_add_ps(abs(px), abs(py)), abs(pz)));
            let oo = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(lo[0], lo[0]), _mm256_mul_ps(lo[1], lo[1])), _mm256_mul_ps(lo[2], lo[2]));
            let one = _mm256_set1_ps(1.0);
            let c = _mm256_sub_ps(oo, one);
            let ec = _mm256_mul_ps(_mm256_set1_ps(1e-6), _mm256_add_ps(oo, one));
            let m = _mm256_and_ps(
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(b, eb), _mm256_cmp_ps::<_CMP_GT_OQ>(c, ec)),
                _mm256_cmp_ps::<_CMP_GE_OQ>(tmin, _mm256_setzero_ps()),
            );
            _mm256_movemask_ps(m) as u32
        };
        let mut hit = 0u32;
        let mut odd = 0u32;
        let mut t = [_mm_setzero_ps(); 2];
        for half in 0..2 {
            // PERF: a half with no active lane, or whose active lanes all run away from the
            // sphere, costs nothing more.
            if ((active & !away) >> (4 * half)) & 15 == 0 {
                continue;
            }
            let wide = |v: __m256| _mm256_cvtps_pd(if half == 0 { _mm256_castps256_ps128(v) } else { _mm256_extractf128_ps::<1>(v) });
            let (ox, oy, oz) = (wide(lo[0]), wide(lo[1]), wide(lo[2]));
            let (dx, dy, dz) = (wide(ld_[0]), wide(ld_[1]), wide(ld_[2]));
            let dot = |ax: __m256d, ay: __m256d, az: __m256d, bx: __m256d, by: __m256d, bz: __m256d| {
                _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(ax, bx), _mm256_mul_pd(ay, by)), _mm256_mul_pd(az, bz))
            };
            let a = dot(dx, dy, dz, dx, dy, dz);
            let b = dot(dx, dy, dz, ox, oy, oz);
            let cq = _mm256_sub_pd(dot(ox, oy, oz, ox, oy, oz), _mm256_set1_pd(1.0));
            let zero = _mm256_setzero_pd();
            odd |= (_mm256_movemask_pd(_mm256_cmp_pd::<_CMP_EQ_OQ>(a, zero)) as u32) << (4 * half);
            // A negative discriminant gives NaN roots, which no range test accepts (the
            // scalar code returns no roots: the same outcome).
            let disc = _mm256_sub_pd(_mm256_mul_pd(b, b), _mm256_mul_pd(a, cq));
            // PERF: four misses (the common case at a sphere's box corners) skip the square
            // root and the divisions. `disc < 0` is exactly the scalar code's "no roots".
            if _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(disc, zero)) == 15 {
                continue;
            }
            let sign = _mm256_blendv_pd(_mm256_set1_pd(-1.0), _mm256_set1_pd(1.0), _mm256_cmp_pd::<_CMP_GE_OQ>(b, zero));
            let q = _mm256_xor_pd(_mm256_add_pd(b, _mm256_mul_pd(sign, _mm256_sqrt_pd(disc))), _mm256_set1_pd(-0.0));
            let qnz = _mm256_cmp_pd::<_CMP_NEQ_UQ>(q, zero);
            let t0 = _mm256_and_pd(_mm256_div_pd(q, a), qnz);
            let t1 = _mm256_and_pd(_mm256_div_pd(cq, q), qnz);
            let swap = _mm256_cmp_pd::<_CMP_GT_OQ>(t0, t1);
            let (t0, t1) = (_mm256_blendv_pd(t0, t1, swap), _mm256_blendv_pd(t1, t0, swap));
            let (lo, hi) = (wide(tmin), wide(tmax));
            let inr = |t| _mm256_and_pd(_mm256_cmp_pd::<_CMP_GE_OQ>(t, lo), _mm256_cmp_pd::<_CMP_LT_OQ>(t, hi));
            let in0 = inr(t0);
            // The second root replaces the first when the first is out of range or farther.
            let all = _mm256_castsi256_pd(_mm256_set1_epi32(-1));
            let in1 = _mm256_and_pd(inr(t1), _mm256_or_pd(_mm256_xor_pd(in0, all), _mm256_cmp_pd::<_CMP_LT_OQ>(t1, t0)));
            hit |= (_mm256_movemask_pd(_mm256_or_pd(in0, in1)) as u32) << (4 * half);
            t[half] = _mm256_cvtpd_ps(_mm256_blendv_pd(t0, t1, in1));
        }
        (hit & !odd, st(_mm256_set_m128(t[1], t[0])), odd)
    }

    /// The lanes of group `g` that hit any triangle of `t4` within `[tmin, limit)`; stops
    /// once every lane of `active` is hit (PERF: shadow rays that start beside their
    /// blocker, most of the kitchen's, are all blocked by a group's first triangle, and
    /// the other three were tested for nothing).
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn tri4_any(t4: &Tri4, p: &Packet, g: usize, limit: &F8, active: &M8) -> M8 {
        let lim = ld(limit);
        let want = ldm(active);
        let mut hit = _mm256_setzero_ps();
        for lane in 0..4 {
            if t4.is_pad(lane) {
                break;
            }
            hit = _mm256_or_ps(hit, eval(t4, lane, p, g, lim, None).0);
            // All wanted lanes hit: `want & !hit` is empty.
            if _mm256_testc_ps(hit, want) != 0 {
                break;
            }
        }
        stm(hit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AVX2 transpose puts every ray of a partial or full group where `RayBlock::set`
    /// does, and empties the other lanes.
    #[test]
    fn transposed_rays_match_lane_by_lane_loads() {
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") {
            let rays: Vec<Ray> = (0..8)
                .map(|i| {
                    let f = i as f32;
                    Ray { org: Vec3::new(f, f + 0.1, f + 0.2), dir: Vec3::new(-f, 1.0 + f, 0.5 * f), tmin: 0.01 * f, tmax: 10.0 + f }
                })
                .collect();
            for n in 1..=8 {
                let mut want = RayBlock::EMPTY;
                for (l, r) in rays[..n].iter().enumerate() {
                    want.set(l, r);
                }
                let mut got = RayBlock::EMPTY;
                // SAFETY: AVX2 was detected above.
                unsafe { avx::transpose_rays(&rays[..n], &mut got) };
                assert_eq!(got, want, "{n} rays");
            }
        }
    }

    /// A packet of eight rays from one tile, with the directions `dir(i)`.
    fn packet_of(dir: impl Fn(usize) -> Vec3) -> Packet {
        let mut b = RayBlock::EMPTY;
        for l in 0..LANES {
            let org = Vec3::new(0.01 * l as f32, 0.0, 0.0);
            b.set(l, &Ray { org, dir: dir(l), tmin: 0.0, tmax: f32::INFINITY });
        }
        let (mut p, mut h) = Packet::empty();
        p.load_blocks_into(&[b], &mut h);
        p
    }

    /// Rays whose unit directions lie close together are worth a packet, however long
    /// their directions; rays scattered over an octant (diffuse bounces) are not; a lane
    /// with a zero direction holds no ray and does not count.
    #[test]
    fn scattered_directions_are_not_worth_a_packet() {
        let worth = |p: &Packet| p.interval(&p.valid).is_some_and(|iv| iv.worth(lane_count(&p.valid), 1.0));
        let near = |l: usize| Vec3::new(0.3 + 0.004 * l as f32, 0.5, 0.8).normalize();
        assert!(worth(&packet_of(near)));
        for scale in [1e-3, 100.0, 1e6] {
            assert!(worth(&packet_of(|l| near(l) * scale)), "scale {scale}");
        }
        // One octant, cosine-like scatter.
        let scattered = |l: usize| Vec3::new(0.1 + 0.12 * l as f32, 1.0 - 0.1 * l as f32, 0.2 + 0.05 * (l % 3) as f32).normalize();
        assert!(!worth(&packet_of(scattered)));
        // A zero direction is no ray (not a valid lane): the others still make a packet.
        let p = packet_of(|l| if l == 3 { Vec3::ZERO } else { near(l) });
        assert_eq!(lane_count(&p.valid), 7);
        assert!(worth(&p));
        // The limit itself: a spread of twice the limit in one component is too much.
        let wide = |l: usize| Vec3::new(0.5 + 2.0 * MAX_DIR_SPREAD * (l as f32 / 7.0), 0.5, 0.7).normalize();
        assert!(!worth(&packet_of(wide)));
    }
}
