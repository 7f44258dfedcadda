//! Inverse trigonometry in `f32`, branch-free (selects only): a loop over lanes that calls
//! these vectorizes, and every width gives the same bits. The library's `atan2f` and
//! `acosf` are calls the compiler cannot inline; these are a few multiply-adds. Used where
//! directions become angles in the hot paths: spherical texture coordinates, environment
//! map lookups, spot light falloff.
//!
//! Both follow Cephes (Moshier, *Methods and Programs for Mathematical Functions*, 1989):
//! `atanf`'s minimax polynomial on [0, tan π/8] after reducing the ratio of the smaller to
//! the larger coordinate by the π/4 identity; `asinf`'s polynomial on [0, ½] with the
//! half-angle identity above ½. Within 4 ulp of the exact values (or 2e-7 absolute near
//! zeros), tested against `f64`.

use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// `atan(x)` for `x` in [0, 1].
#[inline(always)]
fn atan_unit(x: f32) -> f32 {
    const TAN_PI_8: f32 = 0.414_213_57;
    let big = x > TAN_PI_8;
    // (x − 1)/(x + 1) is in [−0.4143, 0] when x is in (tan π/8, 1].
    let r = if big { (x - 1.0) / (x + 1.0) } else { x };
    let z = r * r;
    let p = (((8.053_744_5e-2 * z - 1.387_768_5e-1) * z + 1.997_771_1e-1) * z - 3.333_295e-1) * z * r + r;
    if big {
        p + FRAC_PI_4
    } else {
        p
    }
}

/// `atan2(y, x)`: the angle of (x, y) in [−π, π] (as the library's, also for zeros of
/// either sign; NaN in, NaN out).
#[inline(always)]
#[must_use]
pub fn atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    // (0/0 → the angle 0: both zero.)
    let t = if hi > 0.0 { lo / hi } else { 0.0 };
    let a = atan_unit(t);
    let a = if ay > ax { FRAC_PI_2 - a } else { a };
    let a = if x.is_sign_negative() { PI - a } else { a };
    let a = if x.is_nan() || y.is_nan() { f32::NAN } else { a };
    f32::from_bits(a.to_bits() | (y.to_bits() & 0x8000_0000))
}

/// Cephes' `asinf` polynomial: asin s for s in [0, ½], with z = s².
#[inline(always)]
fn asin_poly(s: f32, z: f32) -> f32 {
    ((((4.216_32e-2 * z + 2.418_131e-2) * z + 4.547_002_6e-2) * z + 7.495_300_3e-2) * z + 1.666_675_2e-1) * z * s + s
}

/// `acos(x)` for `x` in [−1, 1] (clamped there; NaN in, NaN out).
#[inline(always)]
#[must_use]
pub fn acos(x: f32) -> f32 {
    let c = x.clamp(-1.0, 1.0);
    let a = c.abs();
    // acos a = π/2 − asin a up to ½; above, the half-angle form, exact to the end:
    // acos a = 2 asin √((1 − a)/2).
    let big = a > 0.5;
    let z = if big { 0.5 * (1.0 - a) } else { a * a };
    let s = if big { z.sqrt() } else { a };
    let p = asin_poly(s, z);
    let r = if big { 2.0 * p } else { FRAC_PI_2 - p };
    if c.is_sign_negative() {
        PI - r
    } else {
        r
    }
}

/// Units in the last place between `a` and `b`: how many floats lie between them (0 for
/// equal values, and for +0 and −0), the measure the approximations here are tested in.
#[must_use]
pub fn ulps(a: f32, b: f32) -> u32 {
    let key = |v: f32| {
        let b = v.to_bits() as i32;
        if b < 0 {
            i32::MIN - b
        } else {
            b
        }
    };
    key(a).abs_diff(key(b))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(got: f32, want: f64) -> bool {
        ulps(got, want as f32) <= 4 || (f64::from(got) - want).abs() <= 2e-7
    }

    #[test]
    fn atan2_matches_f64_around_the_circle() {
        let mut worst = 0u32;
        for i in 0..=400_000 {
            let t = (i as f64 / 400_000.0) * 2.0 * std::f64::consts::PI - std::f64::consts::PI;
            for r in [1e-3f64, 0.7, 1.0, 123.0] {
                let (y, x) = ((t.sin() * r) as f32, (t.cos() * r) as f32);
                let want = f64::from(y).atan2(f64::from(x));
                let got = atan2(y, x);
                assert!(close(got, want), "atan2({y}, {x}) = {got}, want {want}");
                worst = worst.max(ulps(got, want as f32));
            }
        }
        assert!(worst > 0, "not the library's function");
    }

    #[test]
    fn atan2_at_zeros_axes_and_nan() {
        for (y, x) in
            [(0.0f32, 0.0f32), (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0), (-0.0, -1.0)]
        {
            assert_eq!(atan2(y, x).to_bits(), y.atan2(x).to_bits(), "atan2({y}, {x})");
        }
        for (y, x) in [(f32::INFINITY, 1.0f32), (1.0, f32::INFINITY), (1.0, f32::NEG_INFINITY)] {
            assert!(close(atan2(y, x), f64::from(y).atan2(f64::from(x))), "atan2({y}, {x})");
        }
        assert!(atan2(f32::NAN, 1.0).is_nan() && atan2(1.0, f32::NAN).is_nan());
    }

    #[test]
    fn acos_matches_f64_over_its_domain() {
        let mut worst = 0u32;
        for i in -1_000_000..=1_000_000 {
            let x = i as f32 / 1_000_000.0;
            let want = f64::from(x).acos();
            let got = acos(x);
            assert!(close(got, want), "acos({x}) = {got}, want {want}");
            worst = worst.max(ulps(got, want as f32));
        }
        assert!(worst > 0, "not the library's function");
        assert_eq!(acos(1.0), 0.0);
        assert_eq!(acos(1.5), 0.0);
        assert!((acos(-1.0) - PI).abs() <= 2e-7);
        assert!(acos(f32::NAN).is_nan());
    }
}
