//! The eight-lane types every SIMD-shaped loop in lucent is written on, and the one place
//! that asks the CPU what it has.
//!
//! [`F8`] and [`M8`] are plain arrays of eight floats and eight lane masks (all bits set =
//! true) with lane-wise operations written as loops. Code written on them is compiled
//! twice, once for the baseline CPU and once inside a `#[target_feature(enable =
//! "avx2,fma")]` function, where each operation becomes one AVX instruction; no product is
//! fused unless [`F8::mul_add`] says so (Rust never contracts), so both builds give the
//! same answers. The packet kernels (`lucent_accel::packet`) and the lane shading of
//! `lucent_render` use them.

// Lane loops index several arrays at once.
#![allow(clippy::needless_range_loop)]

/// Lanes of [`F8`] and [`M8`].
pub const LANES: usize = 8;

/// Whether the CPU runs AVX (unit-triangle maps of four triangles at once).
#[must_use]
pub fn avx() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether the CPU runs AVX2 (the coverage rows' integer and f64 kernels).
#[must_use]
pub fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether the CPU runs AVX2 with FMA (the SIMD kernels and the lane loops' fast builds).
/// `std`'s detection caches its answer.
#[must_use]
pub fn avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether the CPU also runs AVX-512F and AVX-512VL (and [`avx2_fma`]).
#[must_use]
pub fn avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        avx2_fma() && std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx512vl")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Eight floats, one per lane.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct F8(pub [f32; LANES]);

/// Eight lane masks (all bits set = true).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(32))]
pub struct M8(pub [i32; LANES]);

/// A lane-wise binary operator `$op` as the std trait `$tr` on `$ty` (of `$elem`s).
macro_rules! lanewise {
    ($ty:ident, $elem:ty, $tr:ident, $name:ident, $op:tt) => {
        impl std::ops::$tr for $ty {
            type Output = $ty;
            #[inline(always)]
            fn $name(self, o: Self) -> Self {
                let mut r = [<$elem>::default(); LANES];
                for i in 0..LANES {
                    r[i] = self.0[i] $op o.0[i];
                }
                $ty(r)
            }
        }
    };
}
lanewise!(F8, f32, Add, add, +);
lanewise!(F8, f32, Sub, sub, -);
lanewise!(F8, f32, Mul, mul, *);
lanewise!(F8, f32, Div, div, /);
lanewise!(M8, i32, BitAnd, bitand, &);
lanewise!(M8, i32, BitOr, bitor, |);

impl std::ops::Not for M8 {
    type Output = M8;
    #[inline(always)]
    fn not(self) -> Self {
        M8(self.0.map(|m| !m))
    }
}

impl std::ops::Neg for F8 {
    type Output = F8;
    #[inline(always)]
    fn neg(self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = f32::from_bits(self.0[i].to_bits() ^ 0x8000_0000);
        }
        F8(r)
    }
}

macro_rules! compare {
    ($name:ident, $op:tt) => {
        /// The lanes where `self` compares so with `o`.
        #[inline(always)]
        pub fn $name(self, o: Self) -> M8 {
            let mut r = [0i32; LANES];
            for i in 0..LANES {
                r[i] = -((self.0[i] $op o.0[i]) as i32);
            }
            M8(r)
        }
    };
}

impl F8 {
    /// Every lane `x`.
    #[inline(always)]
    pub const fn splat(x: f32) -> Self {
        F8([x; LANES])
    }
    compare!(lt, <);
    compare!(le, <=);
    compare!(gt, >);
    compare!(ge, >=);
    compare!(eq, ==);
    compare!(ne, !=);
    /// `minps`: the second operand when either is NaN.
    #[inline(always)]
    pub fn min(self, o: Self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = if self.0[i] < o.0[i] { self.0[i] } else { o.0[i] };
        }
        F8(r)
    }
    /// `maxps`: the second operand when either is NaN.
    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = if self.0[i] > o.0[i] { self.0[i] } else { o.0[i] };
        }
        F8(r)
    }
    /// `self·a + b` rounded once, lane by lane.
    #[inline(always)]
    pub fn mul_add(self, a: Self, b: Self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = self.0[i].mul_add(a.0[i], b.0[i]);
        }
        F8(r)
    }
    /// Flips the sign of the lanes whose `s` has its sign bit set.
    #[inline(always)]
    pub fn xor_sign(self, s: Self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = f32::from_bits(self.0[i].to_bits() ^ (s.0[i].to_bits() & 0x8000_0000));
        }
        F8(r)
    }
    /// Lanes of `a` where `m`, else of `self`.
    #[inline(always)]
    pub fn blend(self, m: M8, a: Self) -> Self {
        let mut r = [0f32; LANES];
        for i in 0..LANES {
            r[i] = f32::from_bits(((m.0[i] as u32) & a.0[i].to_bits()) | (!(m.0[i] as u32) & self.0[i].to_bits()));
        }
        F8(r)
    }
    /// Largest lane.
    #[inline(always)]
    pub fn hmax(self) -> f32 {
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
    /// No lane set.
    pub const NONE: Self = M8([0; LANES]);
    /// Lane-wise and.
    #[inline(always)]
    pub fn and(self, o: Self) -> Self {
        let mut r = [0i32; LANES];
        for i in 0..LANES {
            r[i] = self.0[i] & o.0[i];
        }
        M8(r)
    }
    /// Lane-wise or.
    #[inline(always)]
    pub fn or(self, o: Self) -> Self {
        let mut r = [0i32; LANES];
        for i in 0..LANES {
            r[i] = self.0[i] | o.0[i];
        }
        M8(r)
    }
    /// Lanes of `o` where `self` is not set.
    #[inline(always)]
    pub fn andnot(self, o: Self) -> Self {
        let mut r = [0i32; LANES];
        for i in 0..LANES {
            r[i] = !self.0[i] & o.0[i];
        }
        M8(r)
    }
    /// One bit per lane (`movmskps`).
    #[inline(always)]
    pub fn bits(self) -> u32 {
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
    pub fn from_bits(b: u32) -> Self {
        M8(std::array::from_fn(|i| -(((b >> i) & 1) as i32)))
    }
    /// Lanes of `new` where `m`, else of `old`.
    #[inline(always)]
    pub fn blend_u32(m: Self, old: [u32; LANES], new: [u32; LANES]) -> [u32; LANES] {
        let mut r = [0u32; LANES];
        for i in 0..LANES {
            r[i] = (m.0[i] as u32 & new[i]) | (!(m.0[i] as u32) & old[i]);
        }
        r
    }
}

impl F8 {
    /// The eight floats of `row` from `j` on.
    #[inline(always)]
    #[must_use]
    pub fn load(row: &[f32], j: usize) -> Self {
        let mut r = [0f32; LANES];
        r.copy_from_slice(&row[j..j + LANES]);
        F8(r)
    }
    /// Stores the lanes into `row` from `j` on.
    #[inline(always)]
    pub fn store(self, row: &mut [f32], j: usize) {
        row[j..j + LANES].copy_from_slice(&self.0);
    }
}
