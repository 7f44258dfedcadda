//! Run-time kernel selection.

use crate::geom::{Hit, Ray};
use crate::mesh::MeshBvh;
use crate::tlas::TwoLevel;
use crate::traverse::{BoxTest, Counters, RayPre, ScalarBox};

/// Which code the ray queries run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Portable scalar code (same answers as `Simd`).
    Scalar,
    /// SSE/AVX2/FMA code; chosen only when the CPU has AVX2 and FMA.
    Simd,
    /// The same kernels compiled for AVX-512VL (32 vector registers: no spills), with the
    /// single-ray walks' 8-wide box test taking its first two hit children from a mask
    /// register (`Avx512Set`); same answers as `Simd`. Chosen only when the CPU has
    /// AVX-512F and AVX-512VL.
    Avx512,
}

impl Kernel {
    /// The fastest kernel this CPU supports.
    #[must_use]
    pub fn detect() -> Self {
        if Self::avx512_available() {
            Kernel::Avx512
        } else if Self::simd_available() {
            Kernel::Simd
        } else {
            Kernel::Scalar
        }
    }

    /// True when the AVX-512VL build of the kernels can run here.
    #[must_use]
    pub fn avx512_available() -> bool {
        crate::simd::avx512()
    }

    /// Every kernel this CPU can run (for tests and benchmarks).
    #[must_use]
    pub fn available() -> Vec<Self> {
        let mut v = vec![Kernel::Scalar];
        if Self::simd_available() {
            v.push(Kernel::Simd);
        }
        if Self::avx512_available() {
            v.push(Kernel::Avx512);
        }
        v
    }

    /// True when the SIMD kernel can run here.
    #[must_use]
    pub fn simd_available() -> bool {
        crate::simd::avx2_fma()
    }

    /// `self` if the CPU supports it, else the best lesser kernel.
    #[must_use]
    pub fn supported(self) -> Self {
        match self {
            Kernel::Avx512 if !Self::avx512_available() => Kernel::Simd.supported(),
            Kernel::Simd if !Self::simd_available() => Kernel::Scalar,
            k => k,
        }
    }

    /// Short name for reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Kernel::Scalar => "scalar",
            Kernel::Simd => "avx2",
            Kernel::Avx512 => "avx512",
        }
    }
}

/// A set of kernels used together in one traversal.
pub(crate) trait KernelSet {
    type B4: BoxTest<4>;
    type B8: BoxTest<8>;
    /// Use the SSE leaf tests.
    const SIMD: bool;

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

pub(crate) struct ScalarSet;
impl KernelSet for ScalarSet {
    type B4 = ScalarBox;
    type B8 = ScalarBox;
    const SIMD: bool = false;
    single_entries!(ScalarSet);
}

#[cfg(target_arch = "x86_64")]
pub(crate) struct SimdSet;
#[cfg(target_arch = "x86_64")]
impl KernelSet for SimdSet {
    type B4 = crate::traverse::SseBox;
    type B8 = crate::traverse::Avx2Box;
    const SIMD: bool = true;
    single_entries!(SimdSet, "avx2,fma");
}

/// The SIMD kernels with the AVX-512VL 8-wide box test (run only where AVX-512F/VL were
/// detected).
#[cfg(target_arch = "x86_64")]
pub(crate) struct Avx512Set;
#[cfg(target_arch = "x86_64")]
impl KernelSet for Avx512Set {
    type B4 = crate::traverse::SseBox;
    type B8 = crate::traverse::Avx512Box;
    const SIMD: bool = true;
    single_entries!(Avx512Set, "avx2,fma,avx512f,avx512vl");
}
