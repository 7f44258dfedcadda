//! # lucent_study
//!
//! The hardware study behind `lucent report`: lucent's kernels count what they do through
//! the [`lucent_accel::Counters`] seam, and models of the seed papers' machines turn the
//! counts into their tables.
//!
//! - [`cache`]: direct-mapped caches of fixed-size items (SaarCOR's three caches).
//! - [`saarcor`]: SaarCOR's DynRTP prototype (units, caches, bandwidth) fed with primary
//!   rays through lucent's BVH or the kd index of [`lucent_accel::kd`]: its Table 3 (fps
//!   at 512×384) and Table 4 (fps, unit usage, hit rates, MB/s at 1024×768).
//! - [`precision`]: traversal and intersection in SaarCOR's 24-bit floats, IEEE half and
//!   fixed point: changed hits and PSNR against f32.
//! - [`report`]: the tables as terminal text, Markdown, JSON lines and an HTML page with
//!   plots; REND3R's cycle model is `lucent_device::cycles`.
#![warn(missing_docs)]

pub mod cache;
pub mod precision;
pub mod report;
pub mod saarcor;

use lucent_accel::kd::{KdGeometry, KdMesh, KdOptions, KdTwoLevel};
use lucent_accel::{BuildError, Geometry};
use lucent_render::World;

/// The two-level kd index of `world`'s geometry: a kd-tree per mesh (the world's meshes,
/// in its geometry order), its shapes as they are, the same instances; hits carry the
/// same instance and primitive ids as the world's own index.
///
/// # Errors
/// When a tree cannot be built.
pub fn kd_of_world(world: &World) -> Result<KdTwoLevel, BuildError> {
    let meshes = &world.scene().meshes;
    let geoms = world
        .accel()
        .geometries()
        .iter()
        .enumerate()
        .map(|(i, g)| match g {
            Geometry::Mesh(_) => {
                let m = meshes.get(i).ok_or(BuildError::TooLarge(i))?;
                KdMesh::build(&m.positions, &m.indices, KdOptions::default()).map(KdGeometry::Mesh)
            }
            Geometry::Shape(s) => Ok(KdGeometry::Shape(*s)),
        })
        .collect::<Result<Vec<_>, _>>()?;
    KdTwoLevel::new(geoms, world.accel().instances().to_vec(), KdOptions::default())
}
