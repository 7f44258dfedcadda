//! Lanes: arithmetic written once over `Real`, a number that is one `f32` or eight
//! ([`F8`], `lucent_accel::simd`'s eight lanes, whose operations are loops the compiler
//! turns into one AVX2 instruction each in functions compiled with AVX2, chosen at run
//! time; the baseline build of the same loops is the fallback), and `V3`, a 3-vector of
//! them. Code on them is branch-free (selects only) and uses no fused multiply-adds, so
//! every width gives bit for bit the same answers: IEEE add, multiply, divide and square
//! root are correctly rounded whatever the width. The Whitted integrator's blocks, the
//! denoiser and the lane integrator are written on them.

// Lane loops index several arrays by the lane number; written so, they vectorize.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;
use lucent_accel::simd::{F8, LANES as W, M8};
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// A number the shading arithmetic runs on: one `f32`, or eight ([`F8`]).
pub(crate) trait Real:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
{
    /// Lane-wise truth values.
    type Mask: Copy + BitAnd<Output = Self::Mask> + BitOr<Output = Self::Mask> + Not<Output = Self::Mask>;
    fn splat(v: f32) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    /// `a` where `m`, else `b`.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// The unbiased exponent field (as a float) and the significand with a zero exponent
    /// (in `[1, 2)`) of positive normal numbers.
    fn exponent_mantissa(self) -> (Self, Self);
    /// `2^n` for integral `n` in `[-126, 127]`.
    fn exp2i(self) -> Self;
    /// `x^y` for `x` in `(0, 1]` (the Phong term): [`pow_unit`] on `f32`, [`pow_fast`] on
    /// lanes (whose out-of-range lanes the caller redoes one by one).
    fn powu(x: Self, y: Self) -> Self;
}

/// `self > o ? self : o` (`maxps`: `o` when either is NaN).
#[inline(always)]
pub(crate) fn max<T: Real>(a: T, b: T) -> T {
    T::select(a.gt(b), a, b)
}

/// Neither infinite nor NaN.
#[inline(always)]
pub(crate) fn finite<T: Real>(a: T) -> T::Mask {
    a.abs().lt(T::splat(f32::INFINITY))
}

/// `1.5·2^23`: adding and taking it away rounds to an integer; `2^23 + 127` biases one.
pub(crate) const ROUND: f32 = 12_582_912.0;
const BIAS: f32 = 8_388_735.0;

impl Real for f32 {
    type Mask = bool;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> bool {
        self < o
    }
    #[inline(always)]
    fn le(self, o: Self) -> bool {
        self <= o
    }
    #[inline(always)]
    fn gt(self, o: Self) -> bool {
        self > o
    }
    #[inline(always)]
    fn ge(self, o: Self) -> bool {
        self >= o
    }
    #[inline(always)]
    fn select(m: bool, a: Self, b: Self) -> Self {
        if m {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn exponent_mantissa(self) -> (Self, Self) {
        let bits = self.to_bits();
        (((bits >> 23) & 0xff) as i32 as f32 - 127.0, f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000))
    }
    #[inline(always)]
    fn powu(x: Self, y: Self) -> Self {
        pow_unit(x, y)
    }
    #[inline(always)]
    fn exp2i(self) -> Self {
        // 2^23 + 127 + n holds n + 127 in its low significand bits; shifting them into the
        // exponent field drops the rest.
        f32::from_bits((self + BIAS).to_bits() << 23)
    }
}

macro_rules! compare {
    ($name:ident, $op:tt) => {
        #[inline(always)]
        fn $name(self, o: Self) -> M8 {
            let mut r = [0i32; W];
            for i in 0..W {
                r[i] = -((self.0[i] $op o.0[i]) as i32);
            }
            M8(r)
        }
    };
}

impl Real for F8 {
    type Mask = M8;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        F8([v; W])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        F8(self.0.map(f32::sqrt))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        F8(self.0.map(|x| f32::from_bits(x.to_bits() & 0x7fff_ffff)))
    }
    compare!(lt, <);
    compare!(le, <=);
    compare!(gt, >);
    compare!(ge, >=);
    #[inline(always)]
    fn select(m: M8, a: Self, b: Self) -> Self {
        let mut r = [0f32; W];
        for i in 0..W {
            let k = m.0[i] as u32;
            r[i] = f32::from_bits((a.0[i].to_bits() & k) | (b.0[i].to_bits() & !k));
        }
        F8(r)
    }
    #[inline(always)]
    fn exponent_mantissa(self) -> (Self, Self) {
        let mut e = [0f32; W];
        let mut m = [0f32; W];
        for i in 0..W {
            let bits = self.0[i].to_bits();
            e[i] = ((bits >> 23) & 0xff) as i32 as f32 - 127.0;
            m[i] = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
        }
        (F8(e), F8(m))
    }
    #[inline(always)]
    fn powu(x: Self, y: Self) -> Self {
        pow_fast(x, y)
    }
    #[inline(always)]
    fn exp2i(self) -> Self {
        F8(self.0.map(|n| f32::from_bits((n + BIAS).to_bits() << 23)))
    }
}

/// A 3-vector of [`Real`]s (glam's `Vec3` arithmetic, in the same order of operations).
#[derive(Clone, Copy, Debug)]
pub(crate) struct V3<T> {
    pub x: T,
    pub y: T,
    pub z: T,
}

impl<T: Real> V3<T> {
    #[inline(always)]
    pub(crate) fn splat3(v: Vec3) -> Self {
        V3 { x: T::splat(v.x), y: T::splat(v.y), z: T::splat(v.z) }
    }
    #[inline(always)]
    pub(crate) fn zero() -> Self {
        Self::splat3(Vec3::ZERO)
    }
    #[inline(always)]
    pub(crate) fn add(self, o: Self) -> Self {
        V3 { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
    #[inline(always)]
    pub(crate) fn sub(self, o: Self) -> Self {
        V3 { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
    #[inline(always)]
    pub(crate) fn mul(self, o: Self) -> Self {
        V3 { x: self.x * o.x, y: self.y * o.y, z: self.z * o.z }
    }
    #[inline(always)]
    pub(crate) fn scale(self, k: T) -> Self {
        V3 { x: self.x * k, y: self.y * k, z: self.z * k }
    }
    #[inline(always)]
    pub(crate) fn div(self, k: T) -> Self {
        V3 { x: self.x / k, y: self.y / k, z: self.z / k }
    }
    #[inline(always)]
    pub(crate) fn neg(self) -> Self {
        V3 { x: -self.x, y: -self.y, z: -self.z }
    }
    #[inline(always)]
    pub(crate) fn dot(self, o: Self) -> T {
        (self.x * o.x) + (self.y * o.y) + (self.z * o.z)
    }
    #[inline(always)]
    pub(crate) fn length(self) -> T {
        self.dot(self).sqrt()
    }
    #[inline(always)]
    pub(crate) fn normalize(self) -> Self {
        self.scale(T::splat(1.0) / self.length())
    }
    #[inline(always)]
    pub(crate) fn max_element(self) -> T {
        max(self.x, max(self.y, self.z))
    }
    #[inline(always)]
    pub(crate) fn select(m: T::Mask, a: Self, b: Self) -> Self {
        V3 { x: T::select(m, a.x, b.x), y: T::select(m, a.y, b.y), z: T::select(m, a.z, b.z) }
    }
}

impl From<Vec3> for V3<f32> {
    #[inline(always)]
    fn from(v: Vec3) -> Self {
        V3 { x: v.x, y: v.y, z: v.z }
    }
}

impl From<V3<f32>> for Vec3 {
    #[inline(always)]
    fn from(v: V3<f32>) -> Self {
        Vec3::new(v.x, v.y, v.z)
    }
}

impl V3<F8> {
    #[inline(always)]
    pub(crate) fn load<const K: usize>(rows: &[[f32; K]; 3], j: usize) -> Self {
        V3 { x: F8::load(&rows[0], j), y: F8::load(&rows[1], j), z: F8::load(&rows[2], j) }
    }
    #[inline(always)]
    pub(crate) fn store<const K: usize>(self, rows: &mut [[f32; K]; 3], j: usize) {
        self.x.store(&mut rows[0], j);
        self.y.store(&mut rows[1], j);
        self.z.store(&mut rows[2], j);
    }
}

/// Lane `i` of three rows (x, y, z) of `K` lanes.
#[inline(always)]
pub(crate) fn get3<const K: usize>(r: &[[f32; K]; 3], i: usize) -> Vec3 {
    Vec3::new(r[0][i], r[1][i], r[2][i])
}

/// Sets lane `i` of three rows.
#[inline(always)]
pub(crate) fn put3<const K: usize>(r: &mut [[f32; K]; 3], i: usize, v: Vec3) {
    r[0][i] = v.x;
    r[1][i] = v.y;
    r[2][i] = v.z;
}

/// Which build of a lane loop runs: the instruction sets a loop's function is compiled for
/// by `on_lanes!`, best first. Every build gives the same bits (IEEE operations, no fused
/// products: Rust never contracts).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// AVX-512 (F, VL, DQ, BW) with AVX2 and FMA: sixteen lanes per register.
    Avx512,
    /// AVX2 and FMA: eight lanes per register.
    Avx2,
    /// The baseline build (SSE2 on x86-64).
    Portable,
}

/// The level lane loops run at, when set (tests force each in turn); 0: the CPU's best.
static FORCED: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(0);

impl Level {
    /// The level lane loops run at: AVX2 where the CPU has it (else the baseline), unless
    /// one is forced ([`Level::force`]) or named by the environment variable
    /// `LUCENT_LANES`.
    #[inline]
    #[must_use]
    pub fn current() -> Self {
        let want = match FORCED.load(std::sync::atomic::Ordering::Relaxed) {
            1 => Self::Portable,
            2 => Self::Avx2,
            3 => Self::Avx512,
            // (AVX2 by default, on AVX-512 machines too: the lane integrator ran 4-6%
            // faster in its AVX2 build than in its AVX-512 one on the Cornell box, envmap,
            // bunny and materials scenes, whole renders on a Sapphire Rapids Xeon.)
            _ => Self::from_env().unwrap_or(Self::Avx2),
        };
        Self::cpu_best_at_most(want)
    }

    /// The level `LUCENT_LANES` names (`avx512`, `avx2` or `portable`), read once: to
    /// compare the builds' speed (every build gives the same bits).
    fn from_env() -> Option<Self> {
        static ENV: std::sync::OnceLock<Option<Level>> = std::sync::OnceLock::new();
        *ENV.get_or_init(|| {
            let v = std::env::var("LUCENT_LANES").ok()?;
            let level = match v.to_ascii_lowercase().as_str() {
                "avx512" => Self::Avx512,
                "avx2" => Self::Avx2,
                "portable" => Self::Portable,
                _ => {
                    tracing::warn!("LUCENT_LANES={v}: not avx512, avx2 or portable; ignored");
                    return None;
                }
            };
            Some(level)
        })
    }

    /// `level`, or the best below it this CPU runs.
    fn cpu_best_at_most(level: Self) -> Self {
        match level {
            Self::Avx512 if Self::avx512() => Self::Avx512,
            Self::Avx512 | Self::Avx2 if lucent_accel::simd::avx2_fma() => Self::Avx2,
            _ => Self::Portable,
        }
    }

    fn avx512() -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            lucent_accel::simd::avx512() && std::is_x86_feature_detected!("avx512dq") && std::is_x86_feature_detected!("avx512bw")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }

    /// Runs lane loops at `level` (where the CPU has it; else at its best) until
    /// [`Level::unforce`]: for tests that compare the builds. Process-wide.
    pub fn force(level: Self) {
        let v = match level {
            Self::Portable => 1,
            Self::Avx2 => 2,
            Self::Avx512 => 3,
        };
        FORCED.store(v, std::sync::atomic::Ordering::Relaxed);
    }

    /// Back to the CPU's best level.
    pub fn unforce() {
        FORCED.store(0, std::sync::atomic::Ordering::Relaxed);
    }
}

/// A lane loop compiled three times, for AVX-512, for AVX2+FMA and for the baseline, and a
/// closure that runs the build of [`Level::current`]. The loop is written as plain scalar
/// code over the lanes' arrays (`for i in 0..n { ... }`, branch-free where it can be):
/// LLVM vectorizes it in each build.
///
/// ```ignore
/// on_lanes!(|a: &mut [f32; 64], n: usize| for i in 0..n { a[i] *= 2.0 })(&mut a, n);
/// ```
macro_rules! on_lanes {
    (|$($a:ident: $t:ty),*| $body:expr) => {{
        #[inline(always)]
        #[allow(clippy::too_many_arguments)]
        fn portable($($a: $t),*) {
            $body
        }
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2,fma")]
        #[allow(clippy::too_many_arguments)]
        fn avx512($($a: $t),*) {
            portable($($a),*)
        }
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        #[allow(clippy::too_many_arguments)]
        fn avx2($($a: $t),*) {
            portable($($a),*)
        }
        #[allow(clippy::too_many_arguments)]
        |$($a: $t),*| match $crate::lanes::Level::current() {
            // SAFETY: `Level::current` says AVX-512 (F, VL, DQ, BW), AVX2 and FMA were detected.
            #[cfg(target_arch = "x86_64")]
            $crate::lanes::Level::Avx512 => unsafe { avx512($($a),*) },
            // SAFETY: `Level::current` says AVX2 and FMA were detected.
            #[cfg(target_arch = "x86_64")]
            $crate::lanes::Level::Avx2 => unsafe { avx2($($a),*) },
            _ => portable($($a),*),
        }
    }};
}
pub(crate) use on_lanes;

/// `x^y` needs `powf`: outside `x` in `(0, 1]`, `y` in `(0, 4096]`, or `x` subnormal.
#[inline(always)]
pub(crate) fn pow_needs_slow<T: Real>(x: T, y: T) -> T::Mask {
    !(x.gt(T::splat(0.0)) & x.le(T::splat(1.0)) & y.gt(T::splat(0.0)) & y.le(T::splat(4096.0))) | x.lt(T::splat(f32::MIN_POSITIVE))
}

/// `x^y` for the Phong term: `x` in `(0, 1]` and `y` in `(0, 4096]` by `exp2(y·log2 x)`
/// with short series (relative error below 2e-5 for these arguments, against `powf`'s
/// exactly rounded result; PERF: `powf` was 5–7% of a shaded frame of the BART kitchen and
/// of the sunflowers); anything else goes to `powf`.
#[inline]
pub(crate) fn pow_unit(x: f32, y: f32) -> f32 {
    if pow_needs_slow(x, y) {
        x.powf(y)
    } else {
        pow_fast(x, y)
    }
}

/// The reduction of a logarithm ([`pow_fast`], [`ln`]): x = 2^e m with m in [√½, √2),
/// and s = (m − 1)/(m + 1), so that ln m = 2 atanh s (|s| ≤ 0.172).
#[inline(always)]
fn log_reduced<T: Real>(x: T) -> (T, T) {
    let one = T::splat(1.0);
    let (e, m) = x.exponent_mantissa();
    let big = m.gt(T::splat(std::f32::consts::SQRT_2));
    let m = T::select(big, m * T::splat(0.5), m);
    let e = T::select(big, e + one, e);
    (e, (m - one) / (m + one))
}

/// [`pow_unit`]'s series, branch-free; meaningful only where [`pow_needs_slow`] is false.
#[inline(always)]
pub(crate) fn pow_fast<T: Real>(x: T, y: T) -> T {
    // log2 x = e + log2 m with m in [√½, √2): log2 m = 2/ln 2 · atanh((m − 1)/(m + 1)),
    // an odd series in s = (m − 1)/(m + 1), |s| ≤ 0.172 (next term below 2e-8).
    let one = T::splat(1.0);
    let (e, s) = log_reduced(x);
    let s2 = s * s;
    // PERF: the series in Estrin's form (two short chains rather than one long one).
    let atanh = s * ((one + s2 * T::splat(1.0 / 3.0)) + (s2 * s2) * (T::splat(1.0 / 5.0) + s2 * T::splat(1.0 / 7.0)));
    let z = y * (e + T::splat(2.0 * std::f32::consts::LOG2_E) * atanh);
    // 2^z = 2^n · 2^f with n = z rounded to nearest, so f is in [−½, ½]: e^(f ln 2) by its
    // Taylor series to the 5th power (next term below 2.5e-6), in Estrin's form. x ≤ 1 and
    // y > 0 make z ≤ 0; below 2^-126 the answer is 0.
    let r = (z + T::splat(ROUND)) - T::splat(ROUND);
    let g = (z - r) * T::splat(std::f32::consts::LN_2);
    let g2 = g * g;
    let p = (one + g) + g2 * ((T::splat(0.5) + g * T::splat(1.0 / 6.0)) + g2 * (T::splat(1.0 / 24.0) + g * T::splat(1.0 / 120.0)));
    T::select(z.lt(T::splat(-126.0)), T::splat(0.0), p * r.exp2i())
}

/// `sin x` and `cos x` (f32, |x| below 2^22), branch-free, so that a loop over lanes that
/// calls it vectorizes and every width gives the same bits: the argument reduced to
/// [−π/4, π/4] by quadrant (Cody and Waite's three-part π/2), then Cephes' minimax
/// polynomials (`sinf`, `cosf`: relative error about 1e-7 there), swapped and signed by
/// the quadrant. Within 4 ulp of the exact values over [−2π, 2π] (tested).
#[inline(always)]
#[must_use]
pub fn sin_cos(x: f32) -> (f32, f32) {
    const TWO_OVER_PI: f32 = std::f32::consts::FRAC_2_PI;
    const P1: f32 = 1.570_312_5;
    const P2: f32 = 4.837_513e-4;
    const P3: f32 = 7.549_79e-8;
    let q = (x * TWO_OVER_PI + ROUND) - ROUND;
    let r = ((x - q * P1) - q * P2) - q * P3;
    let z = r * r;
    let s = r + r * z * (-1.666_665_5e-1 + z * (8.332_161e-3 + z * -1.951_529_6e-4));
    let c = (1.0 - 0.5 * z) + z * z * (4.166_664_6e-2 + z * (-1.388_731_6e-3 + z * 2.443_315_7e-5));
    let qi = q as i32;
    let swap = qi & 1 != 0;
    let (sv, cv) = if swap { (c, s) } else { (s, c) };
    let s_neg = (qi as u32 & 2) << 30;
    let c_neg = ((qi.wrapping_add(1)) as u32 & 2) << 30;
    (f32::from_bits(sv.to_bits() ^ s_neg), f32::from_bits(cv.to_bits() ^ c_neg))
}

/// `e^x` (f32), branch-free as [`sin_cos`]: x = n ln 2 + r with |r| ≤ ½ ln 2 (ln 2 in two
/// parts), Cephes' `expf` polynomial for e^r, times 2^n built in the exponent field; 0
/// below −87.3 (where f32 leaves normal numbers), +∞ above 88.7. Within 2 ulp (tested).
#[inline(always)]
#[must_use]
pub fn exp(x: f32) -> f32 {
    let xc = x.clamp(-87.3, 88.7);
    let n = (xc * std::f32::consts::LOG2_E + ROUND) - ROUND;
    let r = (xc - n * 0.693_359_4) - n * -2.121_944_4e-4;
    let z = r * r;
    let p = ((((((1.987_569_1e-4 * r + 1.398_199_9e-3) * r + 8.333_452e-3) * r + 4.166_579_6e-2) * r + 1.666_666_5e-1) * r + 5e-1) * z + r)
        + 1.0;
    // (2^n with n up to 128: the last doubling apart, exact.)
    let m = n.min(127.0);
    let v = (p * (1.0 + (n - m))) * m.exp2i();
    if x < -87.3 {
        0.0
    } else if x > 88.7 {
        f32::INFINITY
    } else {
        v
    }
}

/// `ln x` (f32) of a positive normal `x`, branch-free as [`exp`]: x = 2^e m with m in
/// [√½, √2), ln m = 2 atanh((m − 1)/(m + 1)) by its odd series to the 9th power (|s| ≤
/// 0.172: the next term is below 3e-9 of the result), plus e ln 2 (ln 2 in two parts).
/// Within 3e-7 of the exact value, relative, or 1e-7 absolute near 1 (tested).
#[inline(always)]
#[must_use]
pub fn ln(x: f32) -> f32 {
    let (e, s) = log_reduced(x);
    let s2 = s * s;
    let series = s * ((1.0 + s2 * (1.0 / 3.0)) + (s2 * s2) * ((1.0 / 5.0 + s2 * (1.0 / 7.0)) + (s2 * s2) * (1.0 / 9.0)));
    (e * 0.693_359_4 + 2.0 * series) + e * -2.121_944_4e-4
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_accel::math::ulps;
    use rand::{Rng, SeedableRng};

    /// [`ln`] against the exactly rounded logarithm over positive normal numbers.
    #[test]
    fn ln_matches_std() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for k in 0..200_000 {
            let x = if k < 1000 { 1.0 + (k as f32 - 500.0) * 1e-4 } else { f32::from_bits(rng.random_range(0x0080_0000u32..0x7f80_0000)) };
            let (got, want) = (f64::from(ln(x)), f64::from(x).ln());
            assert!((got - want).abs() <= 3e-7 * want.abs() + 1e-7, "ln {x}: {got} against {want}");
        }
    }

    /// The Phong power against `powf` over the range it serves (relative error, with an
    /// absolute floor far below one 8-bit step), and `powf`'s answers outside it.
    #[test]
    fn pow_unit_matches_powf() {
        let mut worst = 0.0f64;
        for i in 1..=2000 {
            let x = i as f32 / 2000.0;
            for y in [0.01f32, 0.5, 1.0, 2.0, 5.0, 10.0, 32.0, 64.0, 96.078, 128.0, 500.0, 1000.0, 4096.0] {
                let (got, want) = (pow_unit(x, y) as f64, (x as f64).powf(y as f64));
                let err = (got - want).abs() / want.max(1e-30);
                if want > 1e-30 {
                    worst = worst.max(err);
                }
                assert!(err < 2e-5 || (got - want).abs() < 1e-12, "{x}^{y}: {got} against {want}");
            }
        }
        assert!(worst > 0.0, "the series is not exact");
        for (x, y) in [(0.0f32, 2.0f32), (0.5, 0.0), (0.5, -1.0), (1.5, 2.0), (0.5, 1e5), (1e-40, 0.5), (f32::NAN, 2.0)] {
            let (got, want) = (pow_unit(x, y), x.powf(y));
            assert!(got == want || (got.is_nan() && want.is_nan()), "{x}^{y}: {got} against {want}");
        }
    }

    /// The power's lane form is the scalar one, lane for lane.
    #[test]
    fn pow_lanes_match_scalar() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for _ in 0..2000 {
            let x: [f32; W] = std::array::from_fn(|_| rng.random_range(1e-6f32..1.0));
            let y: [f32; W] = std::array::from_fn(|_| rng.random_range(0.01f32..2000.0));
            let got = pow_fast(F8(x), F8(y));
            for i in 0..W {
                assert_eq!(got.0[i].to_bits(), pow_unit(x[i], y[i]).to_bits(), "{}^{}", x[i], y[i]);
            }
        }
    }

    /// `sin_cos` against the library's over [−2π, 2π] (4 ulp, or an absolute 1e-7 near
    /// zeros, where ulps shrink without bound), and its quadrants' signs.
    #[test]
    fn sin_cos_matches_the_library() {
        let mut worst = 0u32;
        for i in -200_000..=200_000 {
            let x = i as f32 * (2.0 * std::f32::consts::PI / 200_000.0);
            let (s, c) = sin_cos(x);
            let (ws, wc) = x.sin_cos();
            for (got, want) in [(s, ws), (c, wc)] {
                let u = ulps(got, want);
                assert!(u <= 4 || (got - want).abs() < 1e-7, "{x}: {got} against {want} ({u} ulp)");
                if want.abs() > 1e-3 {
                    worst = worst.max(u);
                }
            }
        }
        assert!(worst <= 4, "{worst} ulp");
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
    }

    /// `exp` against the library's over its range (2 ulp), 0 and ∞ beyond it.
    #[test]
    fn exp_matches_the_library() {
        for i in -174_000..=177_000 {
            let x = i as f32 * 5e-4;
            let (got, want) = (exp(x), x.exp());
            assert!(ulps(got, want) <= 2 || want < f32::MIN_POSITIVE, "{x}: {got} against {want}");
        }
        assert_eq!((exp(-100.0), exp(100.0), exp(0.0)), (0.0, f32::INFINITY, 1.0));
    }
}
