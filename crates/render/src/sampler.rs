//! The sampler: sample values as a pure function of (pixel, sample index, dimension), so an
//! image does not depend on the thread count, the tile order, or how its samples were
//! split into passes or regions.
//!
//! The sequence is the Sobol' (0,2)-sequence in padded pairs of dimensions, Owen-scrambled
//! by hashing, with each pixel's samples taken in a shuffled order: Brent Burley,
//! "Practical Hash-based Owen Scrambling", JCGT 9(4), 2020. Its first two dimensions are the
//! van der Corput sequence and the second Sobol' dimension (primitive polynomial x + 1,
//! direction numbers m_k = 2 m_(k-1) XOR m_(k-1)); scrambling uses the Laine-Karras
//! hash-based nested uniform permutation (Laine and Karras, "Stratified sampling for
//! stochastic transparency", 2011, as refined by Burley). Dimensions 2k and 2k + 1 form
//! pair k, each pair with its own seeds, so any pair is a (0, m, 2)-net of the first 2^m
//! samples: every elementary interval of area 2^-m holds exactly one sample.
//!
//! Beside it, the hashes the other integrators jitter with ([`jitter`]: Whitted's
//! supersampling, the debug views' lens), so that every random number of every
//! integrator is made here.

use crate::sampling::Distribution1D;
use lucent_scene::PixelFilter;

/// The second Sobol' dimension's digits before they are read as a fraction: digit `r` of
/// point `i` is the XOR of the bits `c` of `i` whose position contains `r`'s bits (its
/// generator matrix is Pascal's triangle mod 2, and C(c, r) is odd exactly when `r ⊆ c`,
/// Lucas's theorem), summed over supersets one bit of the position at a time. PERF:
/// fifteen shifts, masks and XORs, which vectorize, instead of four table lookups (gathers
/// on lanes); the same bits (tested against the generator matrix).
#[inline]
fn superset_xor(mut z: u32) -> u32 {
    z ^= (z >> 1) & 0x5555_5555;
    z ^= (z >> 2) & 0x3333_3333;
    z ^= (z >> 4) & 0x0f0f_0f0f;
    z ^= (z >> 8) & 0x00ff_00ff;
    z ^= (z >> 16) & 0x0000_ffff;
    z
}

/// The unscrambled pair `(dim 0, dim 1)` of Sobol' point `i`, as 32-bit fractions.
#[inline]
#[must_use]
pub fn sobol2(i: u32) -> (u32, u32) {
    (i.reverse_bits(), superset_xor(i).reverse_bits())
}

/// Burley's Laine-Karras-style permutation: a hash in which each bit depends only on the
/// bits below it, so applied to bit-reversed values it is a nested uniform (Owen) scramble.
#[inline]
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Owen scrambling of a 32-bit fraction (its high bits are the coarse ones).
#[inline]
#[must_use]
pub fn owen_scramble(x: u32, seed: u32) -> u32 {
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

/// A 32-bit mixing hash (the "lowbias32" finalizer of Chris Wellons's hash prospector).
#[inline]
#[must_use]
pub fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// A 32-bit fraction as a float in [0, 1): its top 24 bits, so 1.0 is never returned.
#[inline]
#[must_use]
pub fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// A 32-bit hash (Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 2020: PCG).
#[must_use]
pub fn pcg_hash(x: u32) -> u32 {
    let s = x.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let w = ((s >> ((s >> 28) + 4)) ^ s).wrapping_mul(277_803_737);
    (w >> 22) ^ w
}

/// The jitter of sample `s` of pixel (x, y): a pure function, so images do not depend on
/// thread count or tile order.
#[must_use]
pub fn jitter(x: u32, y: u32, s: u32) -> (f32, f32) {
    let h = pcg_hash(x ^ pcg_hash(y ^ pcg_hash(s)));
    let h2 = pcg_hash(h);
    ((h >> 8) as f32 / (1u32 << 24) as f32, (h2 >> 8) as f32 / (1u32 << 24) as f32)
}

/// An offset from a pixel's centre (in pixels) distributed as `f` along one axis, from a
/// uniform `u` in [0, 1): the tent's inverse CDF in closed form, the Gaussian's from a
/// table of its cumulative integral (one table for σ = 1, scaled), a filter with negative
/// lobes as |f| (see [`signed_sample`] for the weight that goes with it).
#[must_use]
pub fn filter_offset(f: PixelFilter, u: f32) -> f32 {
    match f {
        PixelFilter::Box => u - 0.5,
        PixelFilter::Tent { radius } => {
            if u < 0.5 {
                radius * ((2.0 * u).sqrt() - 1.0)
            } else {
                radius * (1.0 - (2.0 - 2.0 * u).max(0.0).sqrt())
            }
        }
        PixelFilter::Gaussian { stddev } => stddev * (8.0 * gaussian_table().sample(u).0 - 4.0),
        PixelFilter::Mitchell { .. } | PixelFilter::Lanczos { .. } => signed_sample(f, u).0,
    }
}

/// A filter with negative lobes as a table: |f| over [−r, r] in bins (each weighted by
/// its integral, Simpson's rule) to sample offsets from, and ∫f to normalise the weights.
struct SignedTable {
    dist: Distribution1D,
    radius: f32,
    integral: f32,
}

/// Bins of a signed filter's table.
const SIGNED_BINS: usize = 4096;

impl SignedTable {
    fn new(f: PixelFilter) -> Self {
        let r = f64::from(f.radius());
        let h = 2.0 * r / SIGNED_BINS as f64;
        let g = |x: f64| f64::from(f.eval(x as f32));
        let mut integral = 0.0;
        let bins: Vec<f32> = (0..SIGNED_BINS)
            .map(|i| {
                let (a, b) = (-r + i as f64 * h, -r + (i + 1) as f64 * h);
                integral += h / 6.0 * (g(a) + 4.0 * g(0.5 * (a + b)) + g(b));
                (h / 6.0 * (g(a).abs() + 4.0 * g(0.5 * (a + b)).abs() + g(b).abs())) as f32
            })
            .collect();
        Self { dist: Distribution1D::new(&bins), radius: r as f32, integral: integral as f32 }
    }
}

/// The table of signed filter `f` (built once per filter and kept: a process sees few).
fn signed_table(f: PixelFilter) -> &'static SignedTable {
    thread_local! {
        static LAST: std::cell::Cell<Option<(PixelFilter, &'static SignedTable)>> = const { std::cell::Cell::new(None) };
    }
    if let Some((g, t)) = LAST.with(std::cell::Cell::get) {
        if g == f {
            return t;
        }
    }
    static ALL: std::sync::Mutex<Vec<(PixelFilter, &'static SignedTable)>> = std::sync::Mutex::new(Vec::new());
    let mut all = ALL.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let t = match all.iter().find(|(g, _)| *g == f) {
        Some(&(_, t)) => t,
        None => {
            let t: &'static SignedTable = Box::leak(Box::new(SignedTable::new(f)));
            all.push((f, t));
            t
        }
    };
    LAST.with(|c| c.set(Some((f, t))));
    t
}

/// For a filter with negative lobes: an offset from the pixel's centre distributed as |f|
/// for `u`, and the sample's weight along this axis, f / (p ∫f) (about ±∫|f| / ∫f): the
/// pixel is the mean of its samples' weighted values, an unbiased estimate of the
/// filtered image (filter importance sampling with signed weights, as pbrt-v4's
/// `FilterSampler`).
#[must_use]
pub fn signed_sample(f: PixelFilter, u: f32) -> (f32, f32) {
    let t = signed_table(f);
    let (s, pdf, _) = t.dist.sample(u);
    let x = (2.0 * s - 1.0) * t.radius;
    let p = pdf / (2.0 * t.radius);
    let w = if p > 0.0 && t.integral != 0.0 { f.eval(x) / (p * t.integral) } else { 0.0 };
    (x, w)
}

/// Bins of the Gaussian's tabulated integral over [−4, 4].
const GAUSS_BINS: usize = 4096;

/// `exp(−x²/2) − exp(−8)` over [−4, 4] (σ = 1) as a piecewise-constant distribution, each
/// bin weighted by its integral (Simpson's rule): sampled by inverting its cumulative
/// integral, linearly within a bin.
fn gaussian_table() -> &'static Distribution1D {
    static T: std::sync::OnceLock<Distribution1D> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        let f = |x: f64| ((-0.5 * x * x).exp() - (-8.0f64).exp()).max(0.0);
        let h = 8.0 / GAUSS_BINS as f64;
        let bins: Vec<f32> = (0..GAUSS_BINS)
            .map(|i| {
                let (a, b) = (-4.0 + i as f64 * h, -4.0 + (i + 1) as f64 * h);
                (h / 6.0 * (f(a) + 4.0 * f(0.5 * (a + b)) + f(b))) as f32
            })
            .collect();
        Distribution1D::new(&bins)
    })
}

/// The default seed of the path tracer's and the VPL integrator's samplers.
pub const DEFAULT_SEED: u32 = 0x1ce7_0001;

/// The sampler pair of the lens position (thin-lens cameras), far from the bounces'.
pub const LENS_PAIR: u32 = 0x4000_0000;

/// Where an integrator's camera samples lie in their pixel and on the lens: the sampler's
/// first pair and its [`LENS_PAIR`] (the path tracer and VPLs), or hashes of pixel and
/// sample ([`jitter`]: Whitted and the debug views); every sample at its pixel's centre
/// when `centred` (one-sample images of all but the path tracer).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSamples {
    /// The low-discrepancy sampler, or `None` for hashes.
    pub sobol: Option<Sampler>,
    /// Every sample at its pixel's centre.
    pub centred: bool,
    /// The film's reconstruction filter, for the renderers that keep each pixel to its
    /// own samples ([`crate::render_pixel`], VPL frames): samples are placed around the
    /// pixel's centre in proportion to it (filter importance sampling, as pbrt-v4's
    /// `FilterSampler`: for a positive filter every sample then weighs the same, so a
    /// pixel is still the mean of its own samples; a filter with negative lobes places them
    /// by |f| and gives each a signed weight, [`CameraSamples::weight`], a pure function
    /// of pixel and sample). The tile renderer splats instead (see
    /// `crate::tiles::render_blocks`): its pixels then average their neighbours' samples
    /// too, about a third of the variance for Mitsuba's Gaussian (measured: relMSE 4.3×
    /// lower on the Cornell box at 64 samples a pixel).
    pub filter: PixelFilter,
}

impl CameraSamples {
    /// Where in pixel (x, y) sample `k` lies, as an offset in [0, 1)².
    #[inline]
    #[must_use]
    pub fn pixel(&self, x: u32, y: u32, k: u32) -> (f32, f32) {
        let (u, v) = match self.sobol {
            _ if self.centred => return (0.5, 0.5),
            Some(s) => s.get2(x, y, k, 0),
            None => jitter(x, y, k),
        };
        match self.filter {
            PixelFilter::Box => (u, v),
            f => (0.5 + filter_offset(f, u), 0.5 + filter_offset(f, v)),
        }
    }

    /// The weight of sample `k` of pixel (x, y) in its pixel's mean: one, but for a
    /// filter with negative lobes (see [`signed_sample`]), whose samples carry signed
    /// weights.
    #[inline]
    #[must_use]
    pub fn weight(&self, x: u32, y: u32, k: u32) -> f32 {
        if !self.filter.signed() || self.centred {
            return 1.0;
        }
        let (u, v) = match self.sobol {
            Some(s) => s.get2(x, y, k, 0),
            None => jitter(x, y, k),
        };
        signed_sample(self.filter, u).1 * signed_sample(self.filter, v).1
    }

    /// Where on the lens sample `k` of pixel (x, y) passes, in [0, 1)².
    #[inline]
    #[must_use]
    pub fn lens(&self, x: u32, y: u32, k: u32) -> (f32, f32) {
        match self.sobol {
            Some(s) => s.get2(x, y, k, LENS_PAIR),
            None => jitter(x ^ 0x5bd1_e995, y, k),
        }
    }
}

/// Owen-scrambled Sobol' samples; `seed` tells apart independent images (another seed is
/// another, equally good, set of samples).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sampler {
    /// The image's seed.
    pub seed: u32,
}

impl Sampler {
    /// A sampler of seed `seed`.
    #[must_use]
    pub const fn new(seed: u32) -> Self {
        Self { seed }
    }

    /// The samples of pixel `(x, y)` (its seed hashed once, for many draws).
    #[inline]
    #[must_use]
    pub fn pixel(&self, x: u32, y: u32) -> PixelSampler {
        PixelSampler { key: hash32(hash32(hash32(self.seed) ^ x) ^ y) }
    }

    /// Dimensions `2 pair` and `2 pair + 1` of sample `index` of pixel `(x, y)`, in [0, 1)².
    #[inline]
    #[must_use]
    pub fn get2(&self, x: u32, y: u32, index: u32, pair: u32) -> (f32, f32) {
        self.pixel(x, y).get2(index, pair)
    }

    /// [`Sampler::get2`] as 32-bit fractions.
    #[inline]
    #[must_use]
    pub fn get2_bits(&self, x: u32, y: u32, index: u32, pair: u32) -> (u32, u32) {
        self.pixel(x, y).get2_bits(index, pair)
    }

    /// Dimension `dim` of sample `index` of pixel `(x, y)`, in [0, 1).
    #[inline]
    #[must_use]
    pub fn get1(&self, x: u32, y: u32, index: u32, dim: u32) -> f32 {
        let (a, b) = self.get2(x, y, index, dim / 2);
        if dim.is_multiple_of(2) {
            a
        } else {
            b
        }
    }
}

/// One pixel's samples (see [`Sampler::pixel`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PixelSampler {
    key: u32,
}

impl PixelSampler {
    /// Dimensions `2 pair` and `2 pair + 1` of sample `index`, in [0, 1)².
    #[inline]
    #[must_use]
    pub fn get2(&self, index: u32, pair: u32) -> (f32, f32) {
        let (a, b) = self.get2_bits(index, pair);
        (to_unit(a), to_unit(b))
    }

    /// A uniform number in [0, 1) for sample `index` and dimension `dim`, by hashing
    /// alone: independent (not low-discrepancy) samples, at a fraction of a scrambled
    /// pair's cost, for roulette (stratified, it changed no reference scene's error) and
    /// the VPL integrator's lobe choices and shadow-ray roulette. The dimensions are their
    /// own space, apart from [`PixelSampler::get2`]'s pairs and [`PixelSampler::get1`]'s.
    #[inline]
    #[must_use]
    pub fn get1_hashed(&self, index: u32, dim: u32) -> f32 {
        hashed_at(self.hashed_seed(index), dim)
    }

    /// What [`PixelSampler::get1_hashed`] draws sample `index`'s dimensions from (with
    /// [`hashed_at`]): one hash per sample, where many dimensions are drawn.
    #[inline]
    #[must_use]
    pub fn hashed_seed(&self, index: u32) -> u32 {
        hash32(self.key ^ 0x68a5_4e1d ^ index)
    }
}

/// Dimension `dim` of [`PixelSampler::get1_hashed`] from the sample's
/// [`PixelSampler::hashed_seed`] (integer operations only: a loop over lanes of it
/// vectorizes).
#[inline(always)]
#[must_use]
pub fn hashed_at(seed: u32, dim: u32) -> f32 {
    to_unit(hash32(seed ^ dim.wrapping_mul(0x9e37_79b9)))
}

impl PixelSampler {
    /// Dimension `dim` of sample `index`, stratified on its own: the van der Corput
    /// sequence (a Sobol' point's first dimension) over its own shuffle of the pixel's
    /// samples, Owen-scrambled, so that the first 2^m samples of a pixel put one number
    /// in each of 2^m equal intervals (the padding of pbrt-v4's `PaddedSobolSampler`,
    /// with Burley's hashed scrambles). The dimensions are their own space, apart from
    /// [`PixelSampler::get2`]'s pairs and from each other.
    #[inline]
    #[must_use]
    pub fn get1(&self, index: u32, dim: u32) -> f32 {
        let k = hash32(self.key ^ 0x1b87_3593 ^ dim.wrapping_mul(0x9e37_79b9));
        let shuffled = owen_scramble(index, hash32(k ^ 0x5eed_0001));
        to_unit(laine_karras(shuffled, hash32(k ^ 0x5eed_0002)).reverse_bits())
    }

    /// [`PixelSampler::get2`] as 32-bit fractions.
    #[inline]
    #[must_use]
    pub fn get2_bits(&self, index: u32, pair: u32) -> (u32, u32) {
        // The pair's seed; from it, one salt per use: the pixel's own order of the samples
        // (a nested uniform scramble of the index, so that pixels do not share one
        // sequence), then each dimension scrambled on its own.
        let k = hash32(self.key ^ pair.wrapping_mul(0x9e37_79b9));
        let shuffled = owen_scramble(index, hash32(k ^ 0x5eed_0001));
        // (`owen_scramble` of `sobol2(shuffled)`'s two fractions, whose bit reversals
        // cancel the scramble's own.)
        (
            laine_karras(shuffled, hash32(k ^ 0x5eed_0002)).reverse_bits(),
            laine_karras(superset_xor(shuffled), hash32(k ^ 0x5eed_0003)).reverse_bits(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The second dimension from its generator matrix (m_k = 2 m_(k-1) XOR m_(k-1)), column
    /// by column.
    fn sobol1_by_matrix(i: u32) -> u32 {
        let (mut m, mut y) = (1u32, 0u32);
        for k in 0..32 {
            if i >> k & 1 != 0 {
                y ^= m << (31 - k);
            }
            m = (m << 1) ^ m;
        }
        y
    }

    #[test]
    fn the_superset_sum_is_the_generator_matrix() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for i in (0..1u32 << 16).chain((0..200_000).map(|_| rng.random::<u32>())).chain([u32::MAX, 1 << 31]) {
            assert_eq!(sobol2(i).1, sobol1_by_matrix(i), "{i:#x}");
        }
        // And the pair as scrambled: the reversals folded away give the same numbers.
        let px = PixelSampler { key: 0x1234_5678 };
        for index in 0..4096 {
            for pair in 0..6u32 {
                let k = hash32(px.key ^ pair.wrapping_mul(0x9e37_79b9));
                let (a, b) = sobol2(owen_scramble(index, hash32(k ^ 0x5eed_0001)));
                let want = (owen_scramble(a, hash32(k ^ 0x5eed_0002)), owen_scramble(b, hash32(k ^ 0x5eed_0003)));
                assert_eq!(px.get2_bits(index, pair), want);
            }
        }
    }

    /// The unscrambled sequence starts as the Sobol' sequence does.
    #[test]
    fn sobol_points_are_the_known_ones() {
        let pts: Vec<(f64, f64)> = (0..8).map(sobol2).map(|(a, b)| (f64::from(a) / 2f64.powi(32), f64::from(b) / 2f64.powi(32))).collect();
        let want = [(0.0, 0.0), (0.5, 0.5), (0.25, 0.75), (0.75, 0.25), (0.125, 0.625), (0.625, 0.125), (0.375, 0.375), (0.875, 0.875)];
        assert_eq!(pts, want);
    }

    /// Whether `pts` (2^m 32-bit pairs) form a (0, m, 2)-net: for every split of m into
    /// i + j, each of the 2^i × 2^j boxes holds exactly one point.
    fn is_net(pts: &[(u32, u32)]) -> bool {
        let m = pts.len().trailing_zeros();
        (0..=m).all(|i| {
            let j = m - i;
            let mut seen = vec![false; pts.len()];
            pts.iter().all(|&(a, b)| {
                // (u64 shifts, so a shift by 32 gives 0.)
                let cell = ((u64::from(a) >> (32 - i)) << j | (u64::from(b) >> (32 - j))) as usize;
                !std::mem::replace(&mut seen[cell], true)
            })
        })
    }

    /// Scrambling keeps the net property, in every pixel and dimension pair, for the first
    /// 2^m samples (m up to 10), and for any aligned block of 2^m samples.
    #[test]
    fn single_dimensions_are_stratified_and_apart() {
        // The first 2^m samples of a pixel put one number of each single dimension in each
        // of 2^m intervals, and the dimensions do not repeat each other or the pairs.
        let s = Sampler::new(7);
        for (x, y) in [(0, 0), (3, 9), (640, 480)] {
            let px = s.pixel(x, y);
            for dim in [0, 1, 5, 33] {
                for m in [2u32, 4, 6] {
                    let n = 1u32 << m;
                    let mut seen = vec![false; n as usize];
                    for k in 0..n {
                        let u = px.get1(k, dim);
                        assert!((0.0..1.0).contains(&u));
                        let cell = (u * n as f32) as usize;
                        assert!(!seen[cell], "pixel ({x}, {y}), dim {dim}, {n} samples: interval {cell} twice");
                        seen[cell] = true;
                    }
                }
                // Not another dimension, nor a pair's first dimension, over again.
                let a: Vec<f32> = (0..64).map(|k| px.get1(k, dim)).collect();
                let b: Vec<f32> = (0..64).map(|k| px.get1(k, dim + 1)).collect();
                let c: Vec<f32> = (0..64).map(|k| px.get2(k, dim).0).collect();
                assert_ne!(a, b);
                assert_ne!(a, c);
            }
        }
    }

    #[test]
    fn every_pixel_and_pair_is_a_net() {
        let s = Sampler::new(7);
        assert!(is_net(&(0..256).map(sobol2).collect::<Vec<_>>()));
        for (x, y, pair) in [(0, 0, 0), (13, 7, 0), (13, 7, 1), (1023, 511, 5), (4, 9, 31)] {
            for m in [2u32, 4, 6, 8, 10] {
                let pts: Vec<(u32, u32)> = (0..1 << m).map(|i| s.get2_bits(x, y, i, pair)).collect();
                assert!(is_net(&pts), "pixel ({x}, {y}) pair {pair}: the first 2^{m} samples are not a net");
                let pts: Vec<(u32, u32)> = (3 << m..4 << m).map(|i| s.get2_bits(x, y, i, pair)).collect();
                assert!(is_net(&pts), "pixel ({x}, {y}) pair {pair}: samples 3·2^{m}.. are not a net");
            }
        }
    }

    /// Pixels, pairs and seeds get different samples (no two share a sequence), and the
    /// values are uniform: the mean of many pixels' first samples is ½.
    #[test]
    fn pixels_pairs_and_seeds_are_decorrelated() {
        let s = Sampler::new(1);
        let a: Vec<(u32, u32)> = (0..64).map(|i| s.get2_bits(5, 5, i, 0)).collect();
        for other in [(6, 5, 0, 1), (5, 6, 0, 1), (5, 5, 1, 1), (5, 5, 0, 2)] {
            let t = Sampler::new(other.3);
            let b: Vec<(u32, u32)> = (0..64).map(|i| t.get2_bits(other.0, other.1, i, other.2)).collect();
            assert_ne!(a, b, "{other:?} repeats pixel (5, 5)'s samples");
        }
        let n = 200 * 200;
        let (mut sx, mut sy, mut sxy) = (0.0f64, 0.0f64, 0.0f64);
        for p in 0..n {
            let (u, v) = s.get2(p % 200, p / 200, 0, 0);
            assert!((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v));
            sx += f64::from(u);
            sy += f64::from(v);
            sxy += f64::from(u) * f64::from(v);
        }
        let n = f64::from(n);
        assert!((sx / n - 0.5).abs() < 0.005 && (sy / n - 0.5).abs() < 0.005, "means {} {}", sx / n, sy / n);
        // Uncorrelated dimensions: E[uv] = ¼.
        assert!((sxy / n - 0.25).abs() < 0.005, "E[uv] = {}", sxy / n);
    }

    /// Sobol' points beat independent ones: integrating a smooth function over the pixel
    /// with 256 samples errs far less than with 256 hashed random points.
    #[test]
    fn low_discrepancy_beats_random_on_a_smooth_integral() {
        let f = |u: f32, v: f32| (u * 3.0).sin() * (v * 2.0).cos() + u * v;
        // ∫∫ sin(3u) cos(2v) + uv = (1 - cos 3)/3 · sin 2 / 2 + 1/4.
        let exact = (1.0 - 3f64.cos()) / 3.0 * 2f64.sin() / 2.0 + 0.25;
        let s = Sampler::new(3);
        let (mut e_sobol, mut e_rand) = (0.0, 0.0);
        for p in 0..64u32 {
            let sob: f64 = (0..256).map(|i| s.get2(p, 0, i, 0)).map(|(u, v)| f64::from(f(u, v))).sum::<f64>() / 256.0;
            let rnd: f64 = (0..256u32)
                .map(|i| (to_unit(hash32(p * 7919 + i * 2)), to_unit(hash32(p * 7919 + i * 2 + 1))))
                .map(|(u, v)| f64::from(f(u, v)))
                .sum::<f64>()
                / 256.0;
            e_sobol += (sob - exact).powi(2);
            e_rand += (rnd - exact).powi(2);
        }
        assert!(e_sobol * 20.0 < e_rand, "squared errors: Sobol {e_sobol:e}, random {e_rand:e}");
    }
}
