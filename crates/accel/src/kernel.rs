//! Run-time kernel selection.

use crate::traverse::{BoxTest, ScalarBox};

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
}

pub(crate) struct ScalarSet;
impl KernelSet for ScalarSet {
    type B4 = ScalarBox;
    type B8 = ScalarBox;
    const SIMD: bool = false;
}

#[cfg(target_arch = "x86_64")]
pub(crate) struct SimdSet;
#[cfg(target_arch = "x86_64")]
impl KernelSet for SimdSet {
    type B4 = crate::traverse::SseBox;
    type B8 = crate::traverse::Avx2Box;
    const SIMD: bool = true;
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
}
