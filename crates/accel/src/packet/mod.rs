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
use crate::simd::{F8, LANES, M8};
use crate::traverse::{Counters, Level, TraversalStats, STACK};
use crate::triangle::Tri4;
use crate::wide::{leaf_range, node_at, WideNode, EMPTY, LEAF};
use glam::{Affine3A, Vec3};
// Lane arithmetic in method form (`a.add(b)`), as the AVX module mirrors it.
use crate::mesh::{MeshBvh, Nodes, TriangleTest};
use crate::shape::Shape;
use crate::tlas::{Geometry, TwoLevel};
use std::ops::{Add, Div, Mul, Neg, Sub};

mod leaves;
mod rays;
mod walk;
#[macro_use]
mod mesh;
#[cfg(target_arch = "x86_64")]
mod avx;
mod instances;
#[cfg(test)]
mod tests;

use leaves::*;
pub use mesh::prefetch_blocks;
use mesh::*;
use rays::*;
use walk::*;

/// Most rays in one packet.
pub const MAX_PACKET: usize = 64;
/// Groups per packet.
pub(crate) const GROUPS: usize = MAX_PACKET / LANES;
/// Entries of a packet's origin and direction vectors: x, y, z, x, y (see [`Packet::o`]).
pub(crate) const CYCLIC: usize = 5;
/// Groups of a packet that must reach a leaf before its triangles are culled against the
/// whole packet ([`avx::frustum_keep`]).
const CULL_GROUPS: usize = 2;
/// Far-distance scale of the conservative box tests (2γ₃ of Ize 2013 is 3.6e-7).
const FAR_SCALE: f32 = 1.0 + 1.0 / (1u32 << 21) as f32;

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
