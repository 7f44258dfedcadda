//! Colour: luminance and the sRGB encoding of linear values (the film's PNG output, the
//! viewer's window).

use glam::Vec3;

/// The luminance of linear sRGB's primaries (Rec. 709 weights).
pub const LUMINANCE: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// Luminance of linear sRGB (Rec. 709 weights).
#[inline]
#[must_use]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::from_array(LUMINANCE))
}

/// Linear to sRGB transfer.
#[must_use]
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// The 8-bit sRGB code of a linear value as [`crate::film::Film::to_srgb8`] defines it: clamped to
/// [0, 1] (non-finite values give 0), encoded, scaled to 255 and rounded half up.
#[must_use]
pub fn srgb8_exact(c: f32) -> u8 {
    (linear_to_srgb(if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.0 }) * 255.0 + 0.5) as u8
}

/// [`srgb8_exact`] by table: for each code `k ≥ 1`, the least `f32` in [0, 1] whose code is
/// at least `k` (found once by bisection over the ordered bit patterns of non-negative
/// floats), and a coarse index into those thresholds. The code of `c` is the number of
/// thresholds at or below it, which is exactly `srgb8_exact(c)` because that function
/// never decreases as `c` grows.
pub struct Srgb8Table {
    /// `first[k]`: least value with code ≥ k (`first[0] = 0`).
    first: [f32; 256],
    /// `start[i]`: the code of `i / STEPS` (a lower bound for values in that step).
    start: [u8; STEPS + 1],
}

/// Steps of the coarse index over [0, 1].
const STEPS: usize = 4096;

impl Srgb8Table {
    fn new() -> Self {
        let mut first = [0f32; 256];
        for (k, slot) in first.iter_mut().enumerate().skip(1) {
            // Bisection on bit patterns: codes are monotone in the value.
            let (mut lo, mut hi) = (0u32, 1f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if usize::from(srgb8_exact(f32::from_bits(mid))) >= k {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            *slot = f32::from_bits(lo);
        }
        let start = std::array::from_fn(|i| srgb8_exact(i as f32 / STEPS as f32));
        Self { first, start }
    }

    /// The code of `c` (as [`srgb8_exact`]).
    #[inline]
    #[must_use]
    pub fn encode(&self, c: f32) -> u8 {
        // NaN fails both tests and lands on 0, as do ±inf via the finiteness check.
        let c = if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.0 };
        // The step's own code, then up over the (at most a few) thresholds inside the step.
        let mut k = self.start[(c * STEPS as f32) as usize];
        while k < 255 && c >= self.first[usize::from(k) + 1] {
            k += 1;
        }
        k
    }
}

/// The shared table of [`Srgb8Table`] (built on first use, about 8,000 evaluations).
#[must_use]
pub fn srgb8_table() -> &'static Srgb8Table {
    static T: std::sync::OnceLock<Srgb8Table> = std::sync::OnceLock::new();
    T.get_or_init(Srgb8Table::new)
}

#[cfg(test)]
mod tests {
    use super::{srgb8_exact, srgb8_table};

    /// The table gives the exact codes: on every value around every threshold, on a dense
    /// sweep of [0, 1] and beyond, and on the odd inputs.
    #[test]
    fn table_codes_match_the_exact_encoding() {
        let t = srgb8_table();
        for k in 1..256 {
            let x = t.first[k];
            for b in x.to_bits().saturating_sub(3)..=x.to_bits() + 3 {
                let c = f32::from_bits(b);
                assert_eq!(t.encode(c), srgb8_exact(c), "{c:e} near code {k}");
            }
        }
        let mut b = 0u32;
        while b <= 1.2f32.to_bits() {
            let c = f32::from_bits(b);
            assert_eq!(t.encode(c), srgb8_exact(c), "{c:e}");
            b += 997;
        }
        for c in [-1.0, -0.0, 0.0, 1.0, 2.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MIN_POSITIVE, 1e-40] {
            assert_eq!(t.encode(c), srgb8_exact(c), "{c:e}");
        }
        // Every code is reached.
        assert!((0..=255u8).all(|k| t.encode(t.first[usize::from(k)]) == k));
    }
}
