//! # lucent_accel
//!
//! Acceleration structures and ray kernels. This crate sees positions, indices and
//! transforms, never materials.
//!
//! - [`MeshBvh`]: a bottom-level BVH over one triangle mesh: binned SAH build ([`build`]),
//!   collapsed into 4- or 8-wide nodes ([`wide`]), traversed by SIMD kernels
//!   ([`Kernel::Simd`], AVX2) or the portable scalar ones, with SaarCOR's unit-triangle
//!   test ([`triangle`]) or the watertight test.
//! - [`Shape`]: analytic primitives in canonical space.
//! - [`TwoLevel`]: the top-level BVH over [`Instance`]s of [`Geometry`].
//! - [`mod@reference`]: brute-force kernels every fast one is checked against.
//!
//! Every query comes in two forms: `intersect` (closest [`Hit`]) and `occluded` (any hit).
//!
//! # Example
//! ```
//! use lucent_accel::{MeshBvh, MeshOptions, Ray};
//! use glam::Vec3;
//! let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
//! let bvh = MeshBvh::build(&p, &[[0, 1, 2]], MeshOptions::default()).unwrap();
//! let hit = bvh.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z)).unwrap();
//! assert_eq!(hit.t, 1.0);
//! ```
#![deny(missing_docs)]

mod all_hits;
pub mod build;
pub mod closed;
mod geom;
mod kernel;
pub mod math;
mod mesh;
pub mod packet;
pub mod reference;
pub mod reinsert;
mod shadow_grid;
mod shape;
pub mod simd;
mod tlas;
pub mod traverse;
pub mod triangle;
pub mod wide;

pub use geom::{Aabb, Hit, Ray, INVALID};
pub use glam;
pub use kernel::Kernel;
pub use mesh::{BuildError, BvhStats, MeshBvh, MeshOptions, Quality, TriangleTest, Width};
pub use packet::{prefetch_blocks, RayBlock, MAX_PACKET};
pub use shape::{gamma, Shape, ShapeHit};
pub use tlas::{Geometry, Instance, TopBuilder, TwoLevel};
pub use traverse::{Counters, Level, TraversalStats};
