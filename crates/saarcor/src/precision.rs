//! Reduced-precision arithmetic for the kd kernels (`crate::kd::Precision`):
//! SaarCOR's 24-bit floats, IEEE half (REND3R's values) and Pixel-Planes-style fixed point.

use crate::kd::Precision;

/// SaarCOR's 24-bit float: sign, 7-bit exponent (bias 63), 16-bit mantissa. Values are
/// rounded to nearest (ties to even) in the mantissa; magnitudes beyond the largest
/// become infinite and below the least normal become zero (no subnormals).
#[derive(Clone, Copy, Debug, Default)]
pub struct F24;

/// The largest finite [`F24`]: (2 - 2^-16) × 2^64.
pub const F24_MAX: f32 = (2.0 - 1.0 / 65536.0) * 18_446_744_073_709_551_616.0;
/// The least normal [`F24`]: 2^-62.
pub const F24_MIN: f32 = 1.0 / 4_611_686_018_427_387_904.0;

impl Precision for F24 {
    #[inline]
    fn r(x: f32) -> f32 {
        if !x.is_finite() {
            return x;
        }
        // Round the 23-bit mantissa to 16 bits, to nearest even.
        let b = x.to_bits();
        let drop = 7;
        let half = 1u32 << (drop - 1);
        let lsb = (b >> drop) & 1;
        let r = f32::from_bits((b + half - 1 + lsb) & !((1 << drop) - 1));
        if r.abs() > F24_MAX {
            f32::INFINITY.copysign(x)
        } else if r.abs() < F24_MIN {
            0.0f32.copysign(x)
        } else {
            r
        }
    }
}

/// IEEE binary16 (REND3R stores every value as one).
#[derive(Clone, Copy, Debug, Default)]
pub struct F16;

impl Precision for F16 {
    #[inline]
    fn r(x: f32) -> f32 {
        half::f16::from_f32(x).to_f32()
    }
}

/// Pixel-Planes-style fixed point: 32-bit two's complement with 16 fraction bits
/// (rounded to nearest; saturating at ±32768; infinities saturate too, NaN stays NaN).
#[derive(Clone, Copy, Debug, Default)]
pub struct Fixed;

/// The fraction bits of [`Fixed`].
pub const FIXED_FRACTION_BITS: i32 = 16;

impl Precision for Fixed {
    #[inline]
    fn r(x: f32) -> f32 {
        if x.is_nan() {
            return x;
        }
        let s = (1i64 << FIXED_FRACTION_BITS) as f64;
        let q = (f64::from(x) * s).round().clamp(i32::MIN as f64, i32::MAX as f64);
        (q / s) as f32
    }
}

/// A precision by name, for the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// f32 (the reference).
    F32,
    /// [`F24`].
    F24,
    /// [`F16`].
    F16,
    /// [`Fixed`].
    Fixed,
}

impl Format {
    /// The name used on the command line and in reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::F32 => "f32",
            Self::F24 => "f24",
            Self::F16 => "f16",
            Self::Fixed => "fixed",
        }
    }
    /// The format named `s`.
    #[must_use]
    pub fn parse(s: &str) -> Option<Self> {
        [Self::F32, Self::F24, Self::F16, Self::Fixed].into_iter().find(|f| f.name() == s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact rounding of chosen values.
    #[test]
    fn rounding_of_chosen_values() {
        // 1 + 2^-16 is an F24; 1 + 2^-17 is a tie and goes to even (1); 1 + 3·2^-17 goes up.
        assert_eq!(F24::r(1.0 + 1.0 / 65536.0), 1.0 + 1.0 / 65536.0);
        assert_eq!(F24::r(1.0 + 1.0 / 131_072.0), 1.0);
        assert_eq!(F24::r(1.0 + 3.0 / 131_072.0), 1.0 + 2.0 / 65536.0);
        assert_eq!(F24::r(-3.0), -3.0);
        assert_eq!(F24::r(1e30), f32::INFINITY);
        assert_eq!(F24::r(1e-30), 0.0);
        // 0.1 = 0x3DCCCCCD: the dropped bits 0x4D are above half, so it rounds up.
        assert_eq!(F24::r(0.1).to_bits(), 0x3DCC_CD00);
        // Half: 1/3 -> 0.33325195; 65520 overflows; 2049 rounds to 2048 (11-bit significand).
        assert_eq!(F16::r(1.0 / 3.0), 0.333_251_95);
        assert_eq!(F16::r(65520.0), f32::INFINITY);
        assert_eq!(F16::r(2049.0), 2048.0);
        // Fixed 16.16: 2^-17 is a tie (rounds away from zero), 1e-6 vanishes, 1e6 saturates.
        assert_eq!(Fixed::r(1.0 / 131_072.0), 1.0 / 65536.0);
        assert_eq!(Fixed::r(1e-6), 0.0);
        assert_eq!(Fixed::r(1e6), 32768.0 - 1.0 / 65536.0);
        assert_eq!(Fixed::r(-1e6), -32768.0);
        assert_eq!(Fixed::r(0.5), 0.5);
    }
}

/// What reduced precision does to one view of a scene.
#[derive(Clone, Debug)]
pub struct PrecisionRow {
    /// The format.
    pub format: Format,
    /// Pixels whose hit (instance and primitive, or a hit at all) differs from f32's, percent.
    pub changed_pct: f64,
    /// PSNR of the eye-light image against f32's, dB (infinite when identical).
    pub psnr: f64,
    /// The eye-light image (grey, 0..1).
    pub image: Vec<f32>,
}

/// Eye-light shading of the kd index's primary hits with precision `P`: 0.1 + 0.9 |n·d|,
/// 0 for a miss; and the hit ids.
fn eye_light<P: Precision + Sync>(
    world: &lucent_render::World,
    kd: &crate::kd::KdTwoLevel,
    cam: &lucent_render::Camera,
) -> (Vec<f32>, Vec<(u32, u32)>) {
    use rayon::prelude::*;
    let (w, h) = cam.size();
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let r = cam.ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            match kd.intersect_with::<P, ()>(&r, &mut ()) {
                Some(hit) => {
                    let s = world.surface(&r, &hit);
                    (0.1 + 0.9 * s.ng.dot(r.dir.normalize_or_zero()).abs(), (hit.inst, hit.prim))
                }
                None => (0.0, (u32::MAX, u32::MAX)),
            }
        })
        .unzip()
}

/// The precision table of one view: f32 first, then each of `formats`.
#[must_use]
pub fn precision_study(
    world: &lucent_render::World,
    kd: &crate::kd::KdTwoLevel,
    cam: &lucent_render::Camera,
    formats: &[Format],
) -> Vec<PrecisionRow> {
    use crate::kd::Exact;
    let (ref_img, ref_ids) = eye_light::<Exact>(world, kd, cam);
    let mut rows = vec![PrecisionRow { format: Format::F32, changed_pct: 0.0, psnr: f64::INFINITY, image: ref_img.clone() }];
    for &f in formats.iter().filter(|&&f| f != Format::F32) {
        let (img, ids) = match f {
            Format::F24 => eye_light::<F24>(world, kd, cam),
            Format::F16 => eye_light::<F16>(world, kd, cam),
            Format::Fixed => eye_light::<Fixed>(world, kd, cam),
            Format::F32 => eye_light::<Exact>(world, kd, cam),
        };
        let changed = ids.iter().zip(&ref_ids).filter(|(a, b)| a != b).count();
        rows.push(PrecisionRow {
            format: f,
            changed_pct: 100.0 * changed as f64 / ids.len().max(1) as f64,
            psnr: psnr(&img, &ref_img),
            image: img,
        });
    }
    rows
}

/// PSNR of `a` against `b` (values 0..1), dB; infinite when equal.
#[must_use]
pub fn psnr(a: &[f32], b: &[f32]) -> f64 {
    let n = a.len().min(b.len()).max(1);
    let mse: f64 = a.iter().zip(b).map(|(x, y)| f64::from(x - y).powi(2)).sum::<f64>() / n as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (1.0 / mse).log10()
    }
}
