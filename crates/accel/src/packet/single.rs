//! The single-ray entry points of each kernel set, for the packet walks' fallbacks: one
//! ray traced alone, compiled with its set's CPU features.

use crate::geom::{Hit, Ray};
#[cfg(target_arch = "x86_64")]
use crate::kernel::{Avx512Set, SimdSet};
use crate::kernel::{KernelSet, ScalarSet};
use crate::mesh::MeshBvh;
use crate::tlas::TwoLevel;
use crate::traverse::{Counters, RayPre};

/// A kernel set's single-ray queries, callable from code compiled without its features.
pub(crate) trait SingleRay: KernelSet {
    /// One ray's closest hit in a mesh, compiled with this set's CPU features: for code
    /// that may lack them. PERF: the packet walks' single-ray fallbacks are closures, and a
    /// closure does not take the `target_feature` of the function it is inlined into;
    /// where LLVM kept it out of line, every intrinsic in it became a call (incoherent rays
    /// in 64-ray packets ran 5 times slower than ray by ray).
    ///
    /// # Safety
    /// The CPU must support this set's instructions.
    unsafe fn mesh_intersect<C: Counters>(m: &MeshBvh, ray: &Ray, hit: &mut Hit, c: &mut C) -> bool;
    /// One ray's occlusion in a mesh within `[ray.tmin, tmax)` ([`Self::mesh_intersect`]'s
    /// any-hit twin).
    ///
    /// # Safety
    /// As [`Self::mesh_intersect`].
    unsafe fn mesh_occluded<C: Counters>(m: &MeshBvh, ray: &Ray, tmax: f32, c: &mut C) -> bool;
    /// One ray's closest hit in a two-level scene (as [`Self::mesh_intersect`]).
    ///
    /// # Safety
    /// As [`Self::mesh_intersect`].
    unsafe fn two_level_intersect<C: Counters>(t: &TwoLevel, ray: &Ray, hit: &mut Hit, c: &mut C);
    /// One ray's occlusion in a two-level scene (as [`Self::mesh_occluded`]).
    ///
    /// # Safety
    /// As [`Self::mesh_intersect`].
    unsafe fn two_level_occluded<C: Counters>(t: &TwoLevel, ray: &Ray, tmax: f32, c: &mut C) -> bool;
}

/// The single-ray entry points of one kernel set, compiled with `$feat` (its
/// `target_feature` list; none for the portable set).
macro_rules! single_entries {
    ($set:ty $(, $feat:literal)?) => {
        $(#[target_feature(enable = $feat)])?
        unsafe fn mesh_intersect<C: Counters>(m: &MeshBvh, ray: &Ray, hit: &mut Hit, c: &mut C) -> bool {
            m.intersect_k::<$set, C>(&RayPre::new(ray), hit, c)
        }
        $(#[target_feature(enable = $feat)])?
        unsafe fn mesh_occluded<C: Counters>(m: &MeshBvh, ray: &Ray, tmax: f32, c: &mut C) -> bool {
            m.occluded_k::<$set, C>(&RayPre::new(ray), tmax, c)
        }
        $(#[target_feature(enable = $feat)])?
        unsafe fn two_level_intersect<C: Counters>(t: &TwoLevel, ray: &Ray, hit: &mut Hit, c: &mut C) {
            t.intersect_kc::<$set, C>(&RayPre::new(ray), hit, c)
        }
        $(#[target_feature(enable = $feat)])?
        unsafe fn two_level_occluded<C: Counters>(t: &TwoLevel, ray: &Ray, tmax: f32, c: &mut C) -> bool {
            t.occluded_kc::<$set, C>(&RayPre::new(ray), tmax, c)
        }
    };
}

impl SingleRay for ScalarSet {
    single_entries!(ScalarSet);
}

#[cfg(target_arch = "x86_64")]
impl SingleRay for SimdSet {
    single_entries!(SimdSet, "avx2,fma");
}

#[cfg(target_arch = "x86_64")]
impl SingleRay for Avx512Set {
    single_entries!(Avx512Set, "avx2,fma,avx512f,avx512vl");
}
