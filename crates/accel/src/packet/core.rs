//! The packet and its hits: up to 64 rays in SoA groups of eight with their box-test
//! constants ([`Packet`]), their closest hits ([`PacketHits`]), the interval bounds that
//! cull nodes for the whole packet ([`Interval`]), and the block of eight rays callers hand
//! in ([`RayBlock`]).

// Group and lane indices address several SoA arrays at once throughout this module.
#![allow(clippy::needless_range_loop)]

pub(crate) use crate::geom::{Hit, Ray, INVALID};
pub(crate) use crate::kernel::{Kernel, KernelSet, ScalarSet};
pub(crate) use crate::simd::{F8, LANES, M8};
pub(crate) use crate::traverse::{Counters, Level, TraversalStats, STACK};
pub(crate) use crate::triangle::Tri4;
pub(crate) use crate::wide::{leaf_range, node_at, WideNode, EMPTY, LEAF};
pub(crate) use glam::{Affine3A, Vec3};
// Lane arithmetic in method form (`a.add(b)`), as the AVX module mirrors it.
pub(crate) use crate::mesh::{MeshBvh, Nodes, TriangleTest};
pub(crate) use crate::shape::Shape;
pub(crate) use crate::tlas::{Geometry, TwoLevel};
pub(crate) use std::ops::{Add, Div, Mul, Neg, Sub};

/// Most rays in one packet.
pub const MAX_PACKET: usize = 64;
/// Groups per packet.
pub(crate) const GROUPS: usize = MAX_PACKET / LANES;
/// Entries of a packet's origin and direction vectors: x, y, z, x, y (see [`Packet::o`]).
pub(crate) const CYCLIC: usize = 5;
/// Groups of a packet that must reach a leaf before its triangles are culled against the
/// whole packet ([`avx::frustum_keep`]).
pub(crate) const CULL_GROUPS: usize = 2;
/// Far-distance scale of the conservative box tests (2γ₃ of Ize 2013 is 3.6e-7).
pub(crate) const FAR_SCALE: f32 = 1.0 + 1.0 / (1u32 << 21) as f32;

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
    pub(crate) near: [usize; 3],
    pub(crate) far: [usize; 3],
    /// Rows of the near and far planes for the interval test.
    pub(crate) inear: [usize; 3],
    pub(crate) ifar: [usize; 3],
    pub(crate) olo: [f32; 3],
    pub(crate) ohi: [f32; 3],
    pub(crate) rlo: [f32; 3],
    pub(crate) rhi: [f32; 3],
    pub(crate) tmin: f32,
    /// The rays' unit directions spread at most [`MAX_DIR_SPREAD`] in every component.
    pub(crate) narrow: bool,
    /// +inf on an axis where some ray runs parallel to the planes ([`PARALLEL_INV`]), else
    /// 0: added to the exit bound, it keeps such a ray's slab open (branch-free).
    pub(crate) pad: [f32; 3],
}

/// Reciprocal directions at least this large (|d| <= 2e-18, near the 1e-18 clamp of
/// [`recip`]) count as parallel to the slab: such a ray lying in the slab never leaves it,
/// but `(b - o)·(1/d)` with its origin at (or within 1e-18·t of) the far plane gives an
/// exit near 0. When some ray of a packet is parallel to an axis, the box tests take every
/// exit on that axis as +inf ([`Interval::pad`]; the single-ray test is saved by its
/// `slack` instead). Only that axis's culling is lost, and only for such packets.
pub(crate) const PARALLEL_INV: f32 = 5e17;

/// Per-group lane masks.
pub(crate) type Masks = [M8; GROUPS];

/// Components `k, k+1, k+2` (mod 3) of a [`CYCLIC`] vector, for a map of axis `k` (not a
/// padding lane's).
#[inline(always)]
pub(crate) fn cyclic(v: &[F8; CYCLIC], k: usize) -> &[F8; 3] {
    debug_assert!(k < 3, "a padding lane");
    // PERF: three consecutive entries from `k` (one address), not indices through
    // `triangle::ROTATION` (callgrind: 4.7% more instructions for primary packets).
    let k = k.min(2);
    v[k..].first_chunk::<3>().expect("k <= 2 leaves three of five entries")
}
