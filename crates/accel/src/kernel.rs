//! Run-time kernel selection.

use crate::traverse::{BoxTest, ScalarBox};

/// Which code the ray queries run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Portable scalar code (same answers as `Simd`).
    Scalar,
    /// SSE/AVX2/FMA code; chosen only when the CPU has AVX2 and FMA.
    Simd,
}

impl Kernel {
    /// The fastest kernel this CPU supports.
    #[must_use]
    pub fn detect() -> Self {
        if Self::simd_available() {
            Kernel::Simd
        } else {
            Kernel::Scalar
        }
    }

    /// True when the SIMD kernel can run here.
    #[must_use]
    pub fn simd_available() -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }

    /// `self` if the CPU supports it, else `Scalar`.
    #[must_use]
    pub fn supported(self) -> Self {
        if self == Kernel::Simd && !Self::simd_available() {
            Kernel::Scalar
        } else {
            self
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
