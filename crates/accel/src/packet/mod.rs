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
//! The code is written on 8-lane arrays ([`crate::simd::F8`], [`crate::simd::M8`]) and compiled twice, once for the
//! baseline CPU and once with AVX2 and FMA enabled, where each array operation becomes one
//! AVX instruction. No multiply-add is fused (Rust never contracts), so both builds give
//! identical answers; tests check both against the single-ray and the reference kernels.

// Group and lane indices address several SoA arrays at once throughout this module.
#![allow(clippy::needless_range_loop)]

mod core;
mod leaves;
mod rays;
mod single;
mod walk;
#[macro_use]
mod mesh;
#[cfg(target_arch = "x86_64")]
mod avx;
mod instances;
#[cfg(test)]
mod tests;

pub use self::core::{RayBlock, MAX_PACKET};
pub use mesh::prefetch_blocks;
