//! Lanes: arithmetic written once over [`Real`], a number that is one `f32` or eight
//! ([`F8`], `lucent_accel::simd`'s eight lanes, whose operations are loops the compiler
//! turns into one AVX2 instruction each in functions compiled with AVX2, chosen at run
//! time; the baseline build of the same loops is the fallback), and [`V3`], a 3-vector of
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

/// [`pow_unit`]'s series, branch-free; meaningful only where [`pow_needs_slow`] is false.
#[inline(always)]
pub(crate) fn pow_fast<T: Real>(x: T, y: T) -> T {
    // log2 x = e + log2 m with m in [√½, √2): log2 m = 2/ln 2 · atanh((m − 1)/(m + 1)),
    // an odd series in s = (m − 1)/(m + 1), |s| ≤ 0.172 (next term below 2e-8).
    let one = T::splat(1.0);
    let (e, m) = x.exponent_mantissa();
    let big = m.gt(T::splat(std::f32::consts::SQRT_2));
    let m = T::select(big, m * T::splat(0.5), m);
    let e = T::select(big, e + one, e);
    let s = (m - one) / (m + one);
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

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
}
