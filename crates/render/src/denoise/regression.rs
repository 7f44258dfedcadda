//! A regression denoiser for offline renders, after NFOR (Bitterli, Rousselle, Moon,
//! Iglesias-Guitián, Adler, Mitchell, Jarosz and Novák, "Nonlinearly Weighted First-order
//! Regression for Denoising Monte Carlo Renderings", EGSR 2016), on the two halves of a
//! render's samples ([`crate::render::Halves`]):
//!
//! - **Cross-filtering.** Half `A` is filtered with weights computed from half `B` and
//!   `B` with weights from `A`, so the weights do not follow the very noise they average
//!   (a pixel's own noise cannot pick its neighbours).
//! - **Weights**: non-local means over patches (Buades, Coll and Morel 2005), with the
//!   distance normalised by the noise's variance as Rousselle, Knaus and Zwicker ("Adaptive
//!   rendering with non-local means filtering", 2012) do: for two pixels `p`, `q`,
//!   `((u_p − u_q)² − (v_p + v_q)) / (ε + k² (v_p + v_q))` per channel, averaged over the
//!   `(2f+1)²` pixel pairs of their patches, weight `exp(−max(0, d))`; the variance `v` of
//!   a half's pixel from the two halves' difference, `(a − b)² / 2`, smoothed. `k`, the
//!   bandwidth, sets the filter's strength.
//! - **First-order regression** in each pixel's window (`(2r+1)²` pixels): the colour is
//!   fitted as a linear function of the guides (shading normal, log distance, screen
//!   position) by weighted least squares (a small ridge on each slope, in units of that
//!   guide's spread in the window), so a gradient of light across a surface, or along
//!   a normal's turn, is followed instead of flattened, as a weighted mean would.
//!   **Collaboratively** (NFOR's §4): every window's fit predicts every pixel of the
//!   window, and each pixel averages the predictions of the windows that contain it,
//!   with the same weights.
//! - **Selection per pixel** among candidates (the raw halves and one filter per
//!   bandwidth): by the error each makes against the *other* half, `(f_A − B)² + (f_B −
//!   A)²`, which, `B` being independent of `A`'s noise, has the mean `MSE(f_A) + Var(B)`
//!   and so orders the candidates as their error does (NFOR selects by a SURE estimate;
//!   this cross-validation needs no variance). The errors are smoothed over a window
//!   before the choice, the choices over a smaller one before they blend.
//!
//! As [`super::denoise`], the colour of a surface is divided by its albedo first (and
//! dark surfaces are filtered in radiance among themselves; emitters and the background
//! pass through), so textures stay sharp.
//!
//! Afterwards one factor per channel keeps the image's sum (see `keep_energy`).
//!
//! Settings were swept on the tuning scenes of `lucent bench denoise` (Cornell box, Sponza,
//! the kitchen) and frozen before the held-out scenes were measured: at 4 samples
//! denoised against 64 raw, relMSE ratios 0.50 / 0.66 / 1.09 (the à-trous filter: 0.80 /
//! 1.06 / 5.11). Speed: 11.6 s at 512 × 384 on two threads (the à-trous filter: 61 ms),
//! about a minute per megapixel: an offline denoiser.
//!
//! Every stage runs over bands of rows (`BAND`), offset by offset within a band: each
//! pixel's sums for its regression stay in the cache, and the loops over a row are plain
//! loops over planes that the compiler vectorizes (built twice, for the baseline CPU and
//! for AVX2 with FMA: the same answers, as no sum is reordered).

// Plane loops index several arrays at once.
#![allow(clippy::needless_range_loop)]

use crate::aov::demodulating;
use crate::color::luminance;
use crate::film::{Aovs, Film};
pub use crate::integrator::guides::Features;
use glam::Vec3;
use rayon::prelude::*;

/// The regression denoiser's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct RegressionSettings {
    /// Window radius `r` (the window is `(2r+1)²` pixels).
    pub radius: u32,
    /// Patch radius `f` of the non-local means weights.
    pub patch: u32,
    /// The bandwidths `k` of the candidate filters (each filters both halves).
    pub bandwidths: Vec<f32>,
    /// Ridge on each slope, in units of its guide's weighted variance in the window.
    pub ridge: f32,
    /// Radius of the window the candidates' errors are averaged over before the choice.
    pub select_radius: u32,
    /// Radius of the window the choices are blended over.
    pub blend_radius: u32,
    /// Spread each half's outliers over their surfaces first (see
    /// [`super::DenoiseSettings::outlier_sigmas`]).
    pub outliers: bool,
}

impl Default for RegressionSettings {
    fn default() -> Self {
        Self {
            radius: 9,
            patch: 2,
            bandwidths: vec![0.25, 0.5, 1.0, 2.0, 4.0],
            ridge: 1e-3,
            select_radius: 3,
            blend_radius: 2,
            outliers: true,
        }
    }
}

/// Points per pixel along each axis of the guides [`denoise_halves`] is measured with
/// ([`crate::integrator::guides::render_features`]'s `grid`).
pub const FEATURE_GRID: u32 = 4;

/// The least samples per pixel from which `lucent render --denoise` (and Python's
/// `render(denoise=True)`) use this denoiser on path-traced images: two halves of two
/// samples each. On the tuning scenes (`lucent bench denoise`, 256x192, median of three
/// seeds) it beat the à-trous filter at 4 samples on all three (relMSE Cornell box 0.0017
/// -> 0.0011, Sponza 0.0096 -> 0.0061, the kitchen 0.058 -> 0.013).
pub const MIN_SPP: u32 = 4;

/// [`denoise_halves`] with the default settings and its guides traced here
/// ([`crate::integrator::guides::render_features`] at [`FEATURE_GRID`]): what `lucent
/// render --denoise` and Python's `render(denoise=True)` run on the halves `a`, `b` of a
/// render of `world` through `cam`.
#[must_use]
pub fn denoise_render(world: &crate::World, cam: &crate::Camera, a: &Film, b: &Film, aovs: &Aovs) -> Film {
    let feats = crate::integrator::guides::render_features(world, cam, a.width, a.height, FEATURE_GRID);
    denoise_halves(a, b, aovs, &feats, &RegressionSettings::default())
}

/// Guides of the regression: shading normal (3), log distance, albedo (3), screen x and y.
const NF: usize = 9;
/// With the intercept.
const D: usize = NF + 1;
/// Sums of a pixel's regression: the upper triangle of XᵀWX, then XᵀWy per channel.
const NM: usize = D * (D + 1) / 2;
const NA: usize = NM + 3 * D;
/// Rows per band.
const BAND: usize = 8;
/// ε of the weights' normalisation.
const EPS: f32 = 1e-10;
/// The log distance's scale as a guide (a relative change of 1% is 0.01 × this).
const DEPTH_SCALE: f32 = 4.0;

/// Index of (i, j), i ≤ j, in the upper triangle.
const fn tri(i: usize, j: usize) -> usize {
    i * D - i * (i + 1) / 2 + j
}

/// Red, green and blue planes.
type Planes = [Vec<f32>; 3];

/// Everything the filters read.
struct Input {
    w: usize,
    h: usize,
    /// 0: passes through; 1: filtered over its albedo; 2: dark, filtered in radiance.
    kind: Vec<u8>,
    /// The halves' colours (demodulated), channel planes.
    a: Planes,
    b: Planes,
    /// The variance of one half's pixel (mean over channels), smoothed.
    var: Vec<f32>,
    /// Guide planes.
    f: [Vec<f32>; NF],
}

/// `exp(-x)` for `x ≥ 0` (0 past 80), branch-free so that loops of it vectorize: 2^(−x
/// log2 e) as an integer power of two times a degree-7 polynomial of the fraction
/// (relative error below 1e-5 to x = 80; a weight needs far less).
#[inline(always)]
fn exp_neg(x: f32) -> f32 {
    let y = x.clamp(0.0, 80.0) * std::f32::consts::LOG2_E;
    let i = y as i32; // (y ≥ 0: truncation is the floor)
    let f = i as f32 - y; // in (−1, 0]
                          // 2^f on [−1, 0]: Taylor of e^(f ln 2) to degree 7.
    let t = f * std::f32::consts::LN_2;
    let p = 1.0 + t * (1.0 + t * (0.5 + t * (1.0 / 6.0 + t * (1.0 / 24.0 + t * (1.0 / 120.0 + t * (1.0 / 720.0 + t * (1.0 / 5040.0)))))));
    f32::from_bits(((127 - i) as u32) << 23) * p
}

/// Denoises the render whose halves are `a` and `b` (each the mean of half its samples:
/// [`crate::render::render_two_halves`]), guided by `aovs`. Returns the denoised whole.
/// Sizes that do not match are returned as the halves' mean.
#[must_use]
pub fn denoise_halves(a: &Film, b: &Film, aovs: &Aovs, feats: &Features, s: &RegressionSettings) -> Film {
    let simd = lucent_accel::simd::avx2_fma();
    denoise_halves_with(a, b, aovs, feats, s, simd)
}

/// [`denoise_halves`] with the AVX2 build of its loops (`simd`, where the CPU has it) or
/// the portable one: the same image.
#[must_use]
pub(crate) fn denoise_halves_with(a: &Film, b: &Film, aovs: &Aovs, feats: &Features, s: &RegressionSettings, simd: bool) -> Film {
    let simd = simd && lucent_accel::simd::avx2_fma();
    let (w, h) = (a.width as usize, a.height as usize);
    let n = w * h;
    let mean_of =
        || Film { width: a.width, height: a.height, pixels: a.pixels.iter().zip(&b.pixels).map(|(&x, &y)| (x + y) * 0.5).collect() };
    if n == 0
        || b.width != a.width
        || b.height != a.height
        || a.pixels.len() != n
        || b.pixels.len() != n
        || aovs.albedo.pixels.len() != n
        || aovs.normal.pixels.len() != n
        || aovs.depth.len() != n
        || aovs.emission.pixels.len() != n
        || feats.albedo.len() != n
        || feats.normal.len() != n
        || feats.depth.len() != n
    {
        return mean_of();
    }
    let alb: Vec<Vec3> = aovs.albedo.pixels.iter().map(|&x| demodulating(x)).collect();
    // (The à-trous filter's kinds of pixel, from the same guides.)
    let g = super::aov_guides(w, h, aovs, |i| a.pixels[i].is_finite() && b.pixels[i].is_finite());
    let kind: Vec<u8> = g.kind.iter().map(|&k| k as u8).collect();
    let demod =
        |f: &Film| -> Planes { [0, 1, 2].map(|c| (0..n).map(|i| if kind[i] != 0 { f.pixels[i][c] / alb[i][c] } else { 0.0 }).collect()) };
    let (mut ca, mut cb) = (demod(a), demod(b));
    // Outliers of each half spread over their surfaces first (as `super::denoise` does):
    // a firefly would otherwise pull the fits of every window around it.
    if s.outliers {
        let albedo = super::planes(&alb);
        let ds = super::DenoiseSettings::default();
        super::spread_outliers(&mut ca, &albedo, &g, &ds, simd);
        super::spread_outliers(&mut cb, &albedo, &g, &ds, simd);
    }
    // A half's variance per pixel, (a − b)² / 2 over the channels, averaged over its 7 × 7
    // neighbours of its kind (alone it is one squared difference: too noisy to normalise by).
    let raw: Vec<f32> = (0..n).map(|i| (0..3).map(|c| (ca[c][i] - cb[c][i]).powi(2)).sum::<f32>() / 6.0).collect();
    let var = box_mean_same_kind(&raw, &kind, w, h, 3);
    let r = s.radius.max(1) as f32;
    let dep =
        |i: usize| if kind[i] != 0 && feats.depth[i].is_finite() && feats.depth[i] > 0.0 { feats.depth[i].ln() * DEPTH_SCALE } else { 0.0 };
    let f: [Vec<f32>; NF] = [
        (0..n).map(|i| feats.normal[i].x).collect(),
        (0..n).map(|i| feats.normal[i].y).collect(),
        (0..n).map(|i| feats.normal[i].z).collect(),
        (0..n).map(dep).collect(),
        (0..n).map(|i| feats.albedo[i].x).collect(),
        (0..n).map(|i| feats.albedo[i].y).collect(),
        (0..n).map(|i| feats.albedo[i].z).collect(),
        (0..n).map(|i| (i % w) as f32 / r).collect(),
        (0..n).map(|i| (i / w) as f32 / r).collect(),
    ];
    let input = Input { w, h, kind, a: ca, b: cb, var, f };
    // Candidates: the raw halves, then one filter per bandwidth.
    let mut cands: Vec<(Planes, Planes)> = vec![(input.a.clone(), input.b.clone())];
    for &k in &s.bandwidths {
        let fa = filter(&input, &input.a, &input.b, k, s, simd);
        let fb = filter(&input, &input.b, &input.a, k, s, simd);
        cands.push((fa, fb));
    }
    // Each candidate's error against the other half, relative to the light's size there
    // (as relMSE weighs it), in radiance.
    let strongest = cands.last().map(|c| [0, 1, 2].map(|k| (0..n).map(|i| 0.5 * (c.0[k][i] + c.1[k][i])).collect::<Vec<f32>>()));
    let scale: Vec<f32> = (0..n)
        .map(|i| {
            let m = strongest.as_ref().map_or(Vec3::ZERO, |p| Vec3::new(p[0][i], p[1][i], p[2][i]) * alb[i]);
            1.0 / (luminance(m).powi(2) + 1e-2)
        })
        .collect();
    let errs: Vec<Vec<f32>> = cands
        .iter()
        .map(|(fa, fb)| {
            let e: Vec<f32> = (0..n)
                .map(|i| {
                    (0..3)
                        .map(|c| {
                            let cross = 0.5 * ((fa[c][i] - input.b[c][i]).powi(2) + (fb[c][i] - input.a[c][i]).powi(2));
                            alb[i][c].powi(2) * (cross - 0.25 * (fa[c][i] - fb[c][i]).powi(2))
                        })
                        .sum::<f32>()
                        * scale[i]
                })
                .collect();
            box_mean_same_kind(&e, &input.kind, w, h, s.select_radius as usize)
        })
        .collect();
    // One-hot choices, blended over a small window.
    let chosen: Vec<usize> = (0..n)
        .map(|i| {
            let mut best = 0;
            for c in 1..errs.len() {
                if errs[c][i] < errs[best][i] {
                    best = c;
                }
            }
            best
        })
        .collect();
    let blends: Vec<Vec<f32>> = (0..cands.len())
        .map(|c| {
            let one: Vec<f32> = chosen.iter().map(|&k| if k == c { 1.0 } else { 0.0 }).collect();
            box_mean_same_kind(&one, &input.kind, w, h, s.blend_radius as usize)
        })
        .collect();
    let pixels = (0..n)
        .map(|i| {
            if input.kind[i] == 0 {
                return (a.pixels[i] + b.pixels[i]) * 0.5;
            }
            let (mut v, mut wsum) = (Vec3::ZERO, 0.0);
            for (c, (fa, fb)) in cands.iter().enumerate() {
                let wt = blends[c][i];
                if wt > 0.0 {
                    v += wt * 0.5 * Vec3::new(fa[0][i] + fb[0][i], fa[1][i] + fb[1][i], fa[2][i] + fb[2][i]);
                    wsum += wt;
                }
            }
            let v = if wsum > 0.0 {
                v / wsum
            } else {
                0.5 * Vec3::new(input.a[0][i] + input.b[0][i], input.a[1][i] + input.b[1][i], input.a[2][i] + input.b[2][i])
            };
            (v * alb[i]).max(Vec3::ZERO)
        })
        .collect();
    let mut out = Film { width: a.width, height: a.height, pixels };
    keep_energy(&mut out, a, b, &input.kind);
    out
}

/// Scales the filtered pixels (kind ≠ 0), channel by channel, so that their sum is the
/// halves' mean's: the fits and the choice between candidates are not conservative (a
/// window's fit is normalised by its own weights; on the envmap scene at 4 samples the
/// image's mean drifted up to 1.2%), while the input's sum is an unbiased estimate of the
/// light. (One factor per channel over the whole image: the sum of tens of thousands of
/// pixels is nearly noise-free, where a local sum would bring back the noise.)
fn keep_energy(out: &mut Film, a: &Film, b: &Film, kind: &[u8]) {
    let (mut sum_in, mut sum_out) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    for (i, p) in out.pixels.iter().enumerate() {
        if kind[i] != 0 {
            sum_in += ((a.pixels[i] + b.pixels[i]) * 0.5).as_dvec3();
            sum_out += p.as_dvec3();
        }
    }
    let scale = Vec3::from_array(std::array::from_fn(|c| if sum_out[c] > 0.0 { (sum_in[c] / sum_out[c]) as f32 } else { 1.0 }));
    for (i, p) in out.pixels.iter_mut().enumerate() {
        if kind[i] != 0 {
            *p *= scale;
        }
    }
}

/// The mean of `v` over each pixel's `(2r+1)²` neighbours of its kind (kind 0: 0).
fn box_mean_same_kind(v: &[f32], kind: &[u8], w: usize, h: usize, r: usize) -> Vec<f32> {
    let n = w * h;
    (0..n)
        .into_par_iter()
        .map(|i| {
            let k = kind[i];
            if k == 0 {
                return 0.0;
            }
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            let r = r as isize;
            let (mut s, mut m) = (0.0f32, 0.0f32);
            for yy in (y - r).max(0)..(y + r + 1).min(h as isize) {
                for xx in (x - r).max(0)..(x + r + 1).min(w as isize) {
                    let j = yy as usize * w + xx as usize;
                    if kind[j] == k {
                        s += v[j];
                        m += 1.0;
                    }
                }
            }
            s / m
        })
        .collect()
}

/// One candidate: `data` filtered with the weights of `guide` (the other half) at
/// bandwidth `k`, by collaborative first-order regression. Channel planes.
fn filter(inp: &Input, data: &Planes, guide: &Planes, k: f32, s: &RegressionSettings, simd: bool) -> Planes {
    let (w, h) = (inp.w, inp.h);
    let n = w * h;
    let ctx = Ctx { inp, data, guide, k2: k * k, r: s.radius as isize, f: s.patch as isize };
    // Pass 1: each pixel's regression sums, band by band; then its fit (D × 3
    // coefficients), kept as planes `[(c * D + i) * n + pixel]`.
    let fits: Vec<Vec<f32>> = (0..h.div_ceil(BAND))
        .into_par_iter()
        .map(|band| {
            let y0 = band * BAND;
            let y1 = (y0 + BAND).min(h);
            let m = (y1 - y0) * w;
            let mut scratch = Scratch::new(w, y1 - y0, s.patch as usize);
            let mut acc = vec![0.0f32; NA * m];
            run(simd, &ctx, y0, y1, &mut scratch, Pass::Sums(&mut acc));
            let mut out = vec![0.0f32; m * D * 3];
            for p in 0..m {
                let sums: [f32; NA] = std::array::from_fn(|j| acc[j * m + p]);
                out[p * D * 3..(p + 1) * D * 3].copy_from_slice(&solve(&sums, s.ridge));
            }
            out
        })
        .collect();
    let mut beta = vec![0.0f32; n * D * 3];
    for (band, fit) in fits.iter().enumerate() {
        let p0 = band * BAND * w;
        for (p, f) in fit.chunks_exact(D * 3).enumerate() {
            for (k, v) in f.iter().enumerate() {
                beta[k * n + p0 + p] = *v;
            }
        }
    }
    // Pass 2: each pixel averages the predictions of the windows that hold it (the
    // weights are symmetric: the window of `p` holds `q` with the weight `q`'s holds `p`).
    let mut out = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
    let bands: Vec<Vec<f32>> = (0..h.div_ceil(BAND))
        .into_par_iter()
        .map(|band| {
            let y0 = band * BAND;
            let y1 = (y0 + BAND).min(h);
            let mut scratch = Scratch::new(w, y1 - y0, s.patch as usize);
            let mut acc = vec![0.0f32; 4 * (y1 - y0) * w];
            run(simd, &ctx, y0, y1, &mut scratch, Pass::Predict(&beta, &mut acc));
            acc
        })
        .collect();
    for (band, acc) in bands.iter().enumerate() {
        let y0 = band * BAND;
        let m = acc.len() / 4;
        for p in 0..m {
            let i = y0 * w + p;
            let wt = acc[3 * m + p];
            for c in 0..3 {
                out[c][i] = if wt > 0.0 { acc[c * m + p] / wt } else { data[c][i] };
            }
        }
    }
    out
}

/// What a filter reads.
struct Ctx<'a> {
    inp: &'a Input,
    data: &'a Planes,
    guide: &'a Planes,
    k2: f32,
    r: isize,
    f: isize,
}

/// A band's working rows: the per-pair distances of the band's rows and the patch's
/// margin, summed along rows, then the weights of the band's rows.
struct Scratch {
    /// (rows + 2f) × w: distance terms summed over the patch's row.
    hsum: Vec<f32>,
    /// One row of distance terms.
    t: Vec<f32>,
    /// rows × w: the weights of one offset.
    wt: Vec<f32>,
    /// NF × w: one row's guide differences, partner minus pixel.
    diff: Vec<f32>,
    /// w: one row's prediction of one channel.
    pred: Vec<f32>,
}

impl Scratch {
    fn new(w: usize, rows: usize, f: usize) -> Self {
        Self {
            hsum: vec![0.0; (rows + 2 * f) * w],
            t: vec![0.0; w + 2 * f],
            wt: vec![0.0; rows * w],
            diff: vec![0.0; NF * w],
            pred: vec![0.0; w],
        }
    }
}

/// What a band does with each offset's weights.
enum Pass<'a> {
    /// Pass 1: the regression sums ([`accumulate`]).
    Sums(&'a mut [f32]),
    /// Pass 2: the predictions of these fits ([`predict`]).
    Predict(&'a [f32], &'a mut [f32]),
}

/// For every offset of the window: the band's weights, then `pass` for each of the
/// band's rows.
fn run(simd: bool, ctx: &Ctx, y0: usize, y1: usize, sc: &mut Scratch, pass: Pass) {
    #[cfg(target_arch = "x86_64")]
    if simd {
        // SAFETY: `simd` is only true when AVX2 and FMA were detected.
        unsafe { run_avx2(ctx, y0, y1, sc, pass) };
        return;
    }
    let _ = simd;
    run_portable(ctx, y0, y1, sc, pass);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn run_avx2(ctx: &Ctx, y0: usize, y1: usize, sc: &mut Scratch, pass: Pass) {
    run_portable(ctx, y0, y1, sc, pass);
}

#[inline(always)]
fn run_portable(ctx: &Ctx, y0: usize, y1: usize, sc: &mut Scratch, mut pass: Pass) {
    let inp = ctx.inp;
    let (w, h) = (inp.w, inp.h);
    let (r, f) = (ctx.r, ctx.f);
    let rows = y1 - y0;
    let side = (2 * f + 1) as f32;
    let norm = 1.0 / (3.0 * side * side);
    for dy in -r..=r {
        for dx in -r..=r {
            // Distance terms of the pairs (x, y), (x + dx, y + dy) for the band's rows and
            // the patch's margin, summed along rows over the patch.
            for (m, yy) in (y0 as isize - f..y1 as isize + f).enumerate() {
                let hrow = &mut sc.hsum[m * w..(m + 1) * w];
                let qy = yy + dy;
                if yy < 0 || yy >= h as isize || qy < 0 || qy >= h as isize {
                    hrow.fill(0.0);
                    continue;
                }
                let (py, qy) = (yy as usize, qy as usize);
                // Columns whose partner is inside.
                let x0 = (-dx).max(0) as usize;
                let x1 = (w as isize - dx.max(0)) as usize;
                // (`t` holds the row's terms at `f..f + w`, zeros around.)
                let fu = f as usize;
                let t = &mut sc.t;
                t.fill(0.0);
                if x0 < x1 {
                    let vp = &inp.var[py * w + x0..py * w + x1];
                    let vq = &inp.var[qy * w + (x0 as isize + dx) as usize..qy * w + (x1 as isize + dx) as usize];
                    let g = ctx.guide;
                    let (p0, p1, p2) = (&g[0][py * w + x0..py * w + x1], &g[1][py * w + x0..py * w + x1], &g[2][py * w + x0..py * w + x1]);
                    let qo = (qy * w) as isize + dx;
                    let qs = |c: usize| &g[c][(qo + x0 as isize) as usize..(qo + x1 as isize) as usize];
                    let (q0, q1, q2) = (qs(0), qs(1), qs(2));
                    let tt = &mut t[fu + x0..fu + x1];
                    for j in 0..tt.len() {
                        let v = vp[j] + vq[j];
                        let d = (p0[j] - q0[j]) * (p0[j] - q0[j]) + (p1[j] - q1[j]) * (p1[j] - q1[j]) + (p2[j] - q2[j]) * (p2[j] - q2[j]);
                        tt[j] = (d - 3.0 * v) / (EPS + ctx.k2 * v);
                    }
                }
                // Summed over the patch's row: 2f + 1 shifted rows added.
                hrow.copy_from_slice(&t[..w]);
                for sh in 1..=2 * fu {
                    let src = &t[sh..sh + w];
                    for x in 0..w {
                        hrow[x] += src[x];
                    }
                }
            }
            // Sum over the patch's rows, then the weights; zero where the partner is
            // outside or of another kind.
            for yr in 0..rows {
                let y = y0 + yr;
                let wrow = &mut sc.wt[yr * w..(yr + 1) * w];
                wrow.fill(0.0);
                let qy = y as isize + dy;
                if qy < 0 || qy >= h as isize {
                    continue;
                }
                let x0 = (-dx).max(0) as usize;
                let x1 = (w as isize - dx.max(0)) as usize;
                if x0 >= x1 {
                    continue;
                }
                wrow[x0..x1].copy_from_slice(&sc.hsum[yr * w + x0..yr * w + x1]);
                for m in 1..(2 * f + 1) as usize {
                    let src = &sc.hsum[(yr + m) * w + x0..(yr + m) * w + x1];
                    for (o, v) in wrow[x0..x1].iter_mut().zip(src) {
                        *o += v;
                    }
                }
                let kp = &inp.kind[y * w + x0..y * w + x1];
                let qo = (qy as usize * w) as isize + dx;
                let kq = &inp.kind[(qo + x0 as isize) as usize..(qo + x1 as isize) as usize];
                let wr = &mut wrow[x0..x1];
                for j in 0..wr.len() {
                    let same = kp[j] == kq[j] && kp[j] != 0;
                    let e = exp_neg(wr[j] * norm);
                    wr[j] = if same { e } else { 0.0 };
                }
            }
            for yr in 0..rows {
                diffs(ctx, sc, dy, dx, y0 + yr);
                match &mut pass {
                    Pass::Sums(acc) => accumulate(ctx, sc, dy, dx, y0 + yr, y0, acc),
                    Pass::Predict(beta, acc) => predict(ctx, sc, beta, dy, dx, y0 + yr, y0, acc),
                }
            }
        }
    }
}

/// The columns `x0..x1` of a row whose partners at offset `dx` are inside.
#[inline(always)]
fn cols(w: usize, dx: isize) -> (usize, usize) {
    ((-dx).max(0) as usize, (w as isize - dx.max(0)).max(0) as usize)
}

/// The columns `x0..x1` of row `y` whose partners at offset (dx, dy) are inside, with the
/// index of the first one's pixel and of its partner; `None`: there are none.
#[inline(always)]
fn span(inp: &Input, dy: isize, dx: isize, y: usize) -> Option<(usize, usize, usize, usize)> {
    let w = inp.w;
    let qy = y as isize + dy;
    let (x0, x1) = cols(w, dx);
    if qy < 0 || qy >= inp.h as isize || x0 >= x1 {
        return None;
    }
    Some((x0, x1, ((qy as usize * w) as isize + dx) as usize + x0, y * w + x0))
}

/// Row `y`'s guide differences at offset (dx, dy), partner minus pixel, into `sc.diff`
/// (columns `x0..x1` of [`cols`]; nothing when the partners' row is outside).
#[inline(always)]
fn diffs(ctx: &Ctx, sc: &mut Scratch, dy: isize, dx: isize, y: usize) {
    let inp = ctx.inp;
    let w = inp.w;
    let Some((x0, x1, qo, po)) = span(inp, dy, dx, y) else { return };
    let len = x1 - x0;
    for i in 0..NF {
        let (q, p) = (&inp.f[i][qo..qo + len], &inp.f[i][po..po + len]);
        let o = &mut sc.diff[i * w + x0..i * w + x1];
        for x in 0..len {
            o[x] = q[x] - p[x];
        }
    }
}

/// Pass 1 for row `y` at offset (dx, dy): the weighted sums of each pixel's regression
/// over its partner (its guides' differences from the pixel's, the partner's colour).
#[inline(always)]
fn accumulate(ctx: &Ctx, sc: &Scratch, dy: isize, dx: isize, y: usize, y0: usize, acc: &mut [f32]) {
    let inp = ctx.inp;
    let w = inp.w;
    let Some((x0, x1, qo, _)) = span(inp, dy, dx, y) else { return };
    let len = x1 - x0;
    let yr = y - y0;
    let plane = acc.len() / NA;
    let wt = &sc.wt[yr * w + x0..yr * w + x1];
    let d: [&[f32]; NF] = std::array::from_fn(|i| &sc.diff[i * w + x0..i * w + x1]);
    let at = yr * w + x0;
    for i in 0..D {
        for j in i..D {
            let o = &mut acc[tri(i, j) * plane + at..tri(i, j) * plane + at + len];
            match (i, j) {
                (0, 0) => {
                    for x in 0..len {
                        o[x] += wt[x];
                    }
                }
                (0, j) => {
                    let a = d[j - 1];
                    for x in 0..len {
                        o[x] += wt[x] * a[x];
                    }
                }
                (i, j) => {
                    let (a, b) = (d[i - 1], d[j - 1]);
                    for x in 0..len {
                        o[x] += wt[x] * a[x] * b[x];
                    }
                }
            }
        }
    }
    for c in 0..3 {
        let yc = &ctx.data[c][qo..qo + len];
        for i in 0..D {
            let o = &mut acc[(NM + c * D + i) * plane + at..(NM + c * D + i) * plane + at + len];
            if i == 0 {
                for x in 0..len {
                    o[x] += wt[x] * yc[x];
                }
            } else {
                let a = d[i - 1];
                for x in 0..len {
                    o[x] += wt[x] * a[x] * yc[x];
                }
            }
        }
    }
}

/// A pixel's fit from its sums: the coefficients (intercept, then one slope per guide)
/// for each channel, `[c * D + i]`. Solved in f64 by Cholesky with the ridge; a window
/// whose system is singular falls back to the weighted mean.
fn solve(sums: &[f32; NA], ridge: f32) -> [f32; D * 3] {
    let mut out = [0.0f32; D * 3];
    let w0 = f64::from(sums[tri(0, 0)]);
    if w0 <= 0.0 {
        return out;
    }
    let mut m = [[0.0f64; D]; D];
    for i in 0..D {
        for j in i..D {
            let v = f64::from(sums[tri(i, j)]) / w0;
            m[i][j] = v;
            m[j][i] = v;
        }
    }
    // The ridge, in units of each guide's weighted variance in the window (plus a floor
    // for a guide that does not vary).
    for i in 1..D {
        let var = (m[i][i] - m[0][i] * m[0][i]).max(0.0);
        m[i][i] += f64::from(ridge) * var + 1e-9;
    }
    let mut l = [[0.0f64; D]; D];
    let mut ok = true;
    'chol: for i in 0..D {
        for j in 0..=i {
            let mut s = m[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if s <= 1e-12 {
                    ok = false;
                    break 'chol;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    for c in 0..3 {
        let rhs: [f64; D] = std::array::from_fn(|i| f64::from(sums[NM + c * D + i]) / w0);
        if !ok {
            out[c * D] = rhs[0] as f32;
            continue;
        }
        let mut z = [0.0f64; D];
        for i in 0..D {
            let mut s = rhs[i];
            for k in 0..i {
                s -= l[i][k] * z[k];
            }
            z[i] = s / l[i][i];
        }
        let mut x = [0.0f64; D];
        for i in (0..D).rev() {
            let mut s = z[i];
            for k in i + 1..D {
                s -= l[k][i] * x[k];
            }
            x[i] = s / l[i][i];
        }
        for i in 0..D {
            out[c * D + i] = x[i] as f32;
        }
    }
    out
}

/// Pass 2 for row `y` at offset (dx, dy): the partner's fit predicts the pixel (at the
/// pixel's guides), weighed as in pass 1; sums of the three channels and of the weights.
/// `beta`: the fits as planes, `[(c * D + i) * n + pixel]`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn predict(ctx: &Ctx, sc: &mut Scratch, beta: &[f32], dy: isize, dx: isize, y: usize, y0: usize, acc: &mut [f32]) {
    let inp = ctx.inp;
    let (w, n) = (inp.w, inp.w * inp.h);
    let Some((x0, x1, qo, _)) = span(inp, dy, dx, y) else { return };
    let len = x1 - x0;
    let yr = y - y0;
    let plane = acc.len() / 4;
    let at = yr * w + x0;
    let Scratch { wt, diff, pred, .. } = sc;
    let wt = &wt[yr * w + x0..yr * w + x1];
    let pred = &mut pred[..len];
    for c in 0..3 {
        // The partner's fit at the pixel: its guides differ from the partner's by −diff.
        pred.copy_from_slice(&beta[c * D * n + qo..c * D * n + qo + len]);
        for i in 1..D {
            let b = &beta[(c * D + i) * n + qo..(c * D + i) * n + qo + len];
            let d = &diff[(i - 1) * w + x0..(i - 1) * w + x1];
            for x in 0..len {
                pred[x] -= b[x] * d[x];
            }
        }
        let o = &mut acc[c * plane + at..c * plane + at + len];
        for x in 0..len {
            o[x] += wt[x] * pred[x];
        }
    }
    let o = &mut acc[3 * plane + at..3 * plane + at + len];
    for x in 0..len {
        o[x] += wt[x];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform numbers in [0, 1) from a seed.
    fn uniform(mut state: u32) -> impl FnMut() -> f32 {
        move || {
            state = crate::sampler::pcg_hash(state);
            (state >> 8) as f32 / (1u32 << 24) as f32
        }
    }

    /// Two noisy halves of a 48 × 32 picture: a plane (albedo 0.5) lit by a ramp along x,
    /// and from column 32 a farther, brighter surface; a background column at x = 0 and
    /// an emitter at (5, 5). Returns the halves, the guides, the features and the clean
    /// picture.
    fn picture() -> (Film, Film, Aovs, Features, Film) {
        let (w, h) = (48u32, 32u32);
        let mut rnd = uniform(99);
        let (mut a, mut b, mut clean) = (Vec::new(), Vec::new(), Vec::new());
        let (mut albedo, mut normal, mut depth, mut emission) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for y in 0..h {
            for x in 0..w {
                let far = x >= 32;
                let light = if far { 8.0 } else { 0.5 + x as f32 / 16.0 };
                let c = Vec3::splat(0.5 * light);
                clean.push(c);
                let mut noisy = || c * (0.4 + 1.2 * rnd());
                let (na, nb) = (noisy(), noisy());
                a.push(na);
                b.push(nb);
                albedo.push(Vec3::splat(0.5));
                normal.push(Vec3::Z);
                depth.push(if x == 0 {
                    f32::INFINITY
                } else if far {
                    6.0
                } else {
                    3.0
                });
                emission.push(if (x, y) == (5, 5) { Vec3::ONE } else { Vec3::ZERO });
            }
        }
        let film = |p: Vec<Vec3>| Film { width: w, height: h, pixels: p };
        let feats = Features { albedo: albedo.clone(), normal: normal.clone(), depth: depth.clone() };
        let aovs = Aovs { albedo: film(albedo), normal: film(normal), depth, emission: film(emission) };
        (film(a), film(b), aovs, feats, film(clean))
    }

    /// The AVX2 build of the loops and the portable one give the same image, bit for bit.
    #[test]
    fn avx2_and_portable_agree() {
        let (a, b, aovs, feats, _) = picture();
        let s = RegressionSettings::default();
        let x = denoise_halves_with(&a, &b, &aovs, &feats, &s, true);
        let y = denoise_halves_with(&a, &b, &aovs, &feats, &s, false);
        assert_eq!(x.pixels, y.pixels);
    }

    /// On the picture: much closer to the clean picture than the halves' mean, the ramp
    /// followed (the plane's left and right quarters keep their light), nothing carried
    /// across the depth edge, the background and the emitter passed through, the mean
    /// kept within 1%.
    #[test]
    fn follows_a_ramp_and_keeps_edges() {
        let (a, b, aovs, feats, clean) = picture();
        let out = denoise_halves(&a, &b, &aovs, &feats, &RegressionSettings::default());
        let mean: Vec<Vec3> = a.pixels.iter().zip(&b.pixels).map(|(&x, &y)| (x + y) * 0.5).collect();
        let err = |p: &[Vec3]| -> f64 {
            p.iter().zip(&clean.pixels).map(|(x, c)| f64::from(((*x - *c) / *c).length_squared())).sum::<f64>() / p.len() as f64
        };
        let (e_raw, e_out) = (err(&mean), err(&out.pixels));
        assert!(e_out * 8.0 < e_raw, "relative error {e_out} denoised against {e_raw}");
        let w = a.width as usize;
        let band = |x0: usize, x1: usize| -> f32 {
            let v: Vec<f32> = (0..a.height as usize)
                .flat_map(|y| (x0..x1).map(move |x| y * w + x))
                .map(|i| out.pixels[i].x / clean.pixels[i].x)
                .collect();
            v.iter().sum::<f32>() / v.len() as f32
        };
        for (x0, x1) in [(1, 8), (24, 31), (28, 32), (32, 36)] {
            let r = band(x0, x1);
            assert!((r - 1.0).abs() < 0.06, "columns {x0}..{x1}: {r} of the clean light");
        }
        for y in 0..a.height as usize {
            for i in [y * w, 5 * w + 5] {
                assert_eq!(out.pixels[i], mean[i]);
            }
        }
        let sum = |p: &[Vec3]| p.iter().map(|v| f64::from(v.x)).sum::<f64>();
        assert!((sum(&out.pixels) / sum(&mean) - 1.0).abs() < 1e-5, "{} against {}", sum(&out.pixels), sum(&mean));
    }

    /// Guides or halves of another size: the halves' mean.
    #[test]
    fn mismatched_sizes_give_the_mean() {
        let (a, b, aovs, mut feats, _) = picture();
        feats.depth.pop();
        let out = denoise_halves(&a, &b, &aovs, &feats, &RegressionSettings::default());
        assert_eq!(out.pixels[7], (a.pixels[7] + b.pixels[7]) * 0.5);
    }

    #[test]
    fn exp_neg_is_close_to_exp() {
        let mut worst = 0.0f32;
        for k in 0..=200_000 {
            let x = k as f32 * 4e-4;
            let (got, want) = (exp_neg(x), (-x).exp());
            worst = worst.max((got / want - 1.0).abs());
        }
        assert!(worst < 1e-5, "relative error {worst}");
        assert_eq!(exp_neg(1e9), exp_neg(80.0));
    }

    /// The fit of an exact linear function of the guides is that function.
    #[test]
    fn solve_recovers_a_linear_function() {
        let mut sums = [0.0f32; NA];
        let coef: [f32; D] = std::array::from_fn(|i| [0.5f32, 0.2, -0.1, 0.3, 0.05, -0.2, 0.1, 0.15, -0.25, 0.35][i]);
        let mut s = 12345u32;
        let mut rnd = || {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        for _ in 0..400 {
            let x: [f32; D] = std::array::from_fn(|i| if i == 0 { 1.0 } else { rnd() });
            let y: f32 = (0..D).map(|i| coef[i] * x[i]).sum();
            for i in 0..D {
                for j in i..D {
                    sums[tri(i, j)] += x[i] * x[j];
                }
                for c in 0..3 {
                    sums[NM + c * D + i] += x[i] * y;
                }
            }
        }
        let fit = solve(&sums, 0.0);
        for c in 0..3 {
            for i in 0..D {
                assert!((fit[c * D + i] - coef[i]).abs() < 2e-3, "{c} {i}: {} vs {}", fit[c * D + i], coef[i]);
            }
        }
    }
}
