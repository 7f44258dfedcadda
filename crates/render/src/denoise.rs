//! A denoiser for path-traced and VPL images: the edge-avoiding à-trous wavelet filter of
//! Dammertz, Sewtz, Hanika and Lensch ("Edge-Avoiding À-Trous Wavelet Transform for fast
//! Global Illumination Filtering", HPG 2010), with the edge-stopping functions of SVGF's
//! spatial filter (Schied et al., "Spatiotemporal Variance-Guided Filtering", HPG 2017):
//! luminance differences measured against the local standard deviation of the noise
//! (estimated from the image itself: the variance over each pixel's 5 × 5 neighbourhood
//! of the same surface, then filtered along with the colour), depth differences against
//! the depth's own slope, and normals by `max(0, n·n')^σn`.
//!
//! The colour is demodulated first: what reflects at the first surface is divided by its
//! albedo (and its own emission kept apart), filtered, and multiplied back, so textures
//! stay sharp ([`crate::film::Aovs`] gives albedo, normal, distance and emission). Pixels
//! that see no surface, an emitter, or a surface darker than
//! [`crate::integrator::vpl::FILTER_ALBEDO_MIN`] (whose light is not proportional to its
//! albedo) pass through.
//!
//! Each of the `iterations` passes is a 5 × 5 B3-spline kernel (1/16, 1/4, 3/8, 1/4, 1/16)
//! with holes: pass `i` takes every `2^i`-th pixel, so five passes reach 62 pixels out.

use crate::film::{Aovs, Film};
use crate::integrator::vpl::{ALBEDO_MIN, FILTER_ALBEDO_MIN};
use crate::world::luminance as lum;
use glam::Vec3;
use rayon::prelude::*;

/// The denoiser's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DenoiseSettings {
    /// À-trous passes (kernel steps 1, 2, 4, ...).
    pub iterations: u32,
    /// Luminance edge-stopping: differences of `sigma_luminance` standard deviations of
    /// the noise weigh `1/e` (8: on the Cornell box at 512 × 384, 4 samples denoised, the
    /// relMSE against 256-sample path tracing was 0.0022 at 4, 0.0017 at 8 and 0.0019 at
    /// 16; six passes instead of five did not help).
    pub sigma_luminance: f32,
    /// Normal edge-stopping exponent.
    pub sigma_normal: f32,
    /// Depth edge-stopping: differences of `sigma_depth` times what the depth's slope
    /// predicts weigh `1/e`.
    pub sigma_depth: f32,
}

impl Default for DenoiseSettings {
    fn default() -> Self {
        Self { iterations: 5, sigma_luminance: 8.0, sigma_normal: 128.0, sigma_depth: 1.0 }
    }
}

/// The B3 spline's weights at offsets -2..=2.
const B3: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// `x^n` by squaring, inline (`powi` is a library call).
#[inline]
fn pow_u(mut x: f32, mut n: u32) -> f32 {
    let mut r = 1.0;
    while n > 0 {
        if n & 1 == 1 {
            r *= x;
        }
        x *= x;
        n >>= 1;
    }
    r
}

/// A guide pixel: whether it sees a surface, and that surface's normal and distance.
#[derive(Clone, Copy)]
struct Guide {
    valid: bool,
    n: Vec3,
    z: f32,
    /// The distance's slope per pixel, along x and y.
    dz: (f32, f32),
}

/// Whether two guide pixels lie on one smooth surface (for the variance estimate and the
/// depth slope).
#[inline]
fn same_surface(a: &Guide, b: &Guide) -> bool {
    b.valid && a.n.dot(b.n) > 0.9 && (a.z - b.z).abs() < 0.1 * a.z
}

/// Denoises `color` guided by `aovs` (the same size). Energy is kept: each pass moves
/// light between pairs of pixels by an amount that is the same both ways (a conservative
/// diffusion step), so the image's sum does not change, where a normalised weighted mean
/// loses the light of outliers its neighbours refuse (measured: −3% on a 4-sample
/// Sponza), and demodulated values traded as they are change it where the albedo varies
/// (+8% on the kitchen).
#[must_use]
pub fn denoise(color: &Film, aovs: &Aovs, s: &DenoiseSettings) -> Film {
    let (w, h) = (color.width as usize, color.height as usize);
    let n = w * h;
    if n == 0 || aovs.albedo.pixels.len() != n || aovs.normal.pixels.len() != n || aovs.depth.len() != n || aovs.emission.pixels.len() != n
    {
        return color.clone();
    }
    let albedo: Vec<Vec3> = aovs.albedo.pixels.iter().map(|a| a.max(Vec3::splat(ALBEDO_MIN))).collect();
    let mut guide: Vec<Guide> = (0..n)
        .map(|i| {
            let (nn, z) = (aovs.normal.pixels[i], aovs.depth[i]);
            // (Emitters pass through: their light is not the albedo's to scale.)
            let emits = aovs.emission.pixels[i].max_element() > 0.0;
            // (Nor dark surfaces: see `FILTER_ALBEDO_MIN`.)
            let dark = aovs.albedo.pixels[i].max_element() < FILTER_ALBEDO_MIN;
            Guide {
                valid: z.is_finite() && z > 0.0 && nn != Vec3::ZERO && !emits && !dark && color.pixels[i].is_finite(),
                n: nn,
                z,
                dz: (0.0, 0.0),
            }
        })
        .collect();
    // The depth's slope: the smaller one-sided difference toward the same surface.
    let slopes: Vec<(f32, f32)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let g = &guide[i];
            if !g.valid {
                return (0.0, 0.0);
            }
            let (x, y) = (i % w, i / w);
            let slope = |a: Option<usize>, b: Option<usize>| {
                let d = |j: Option<usize>| j.filter(|&j| same_surface(g, &guide[j])).map(|j| (guide[j].z - g.z).abs());
                match (d(a), d(b)) {
                    (Some(p), Some(q)) => p.min(q),
                    (Some(p), None) | (None, Some(p)) => p,
                    (None, None) => 0.0,
                }
            };
            (slope((x > 0).then(|| i - 1), (x + 1 < w).then_some(i + 1)), slope((y > 0).then(|| i - w), (y + 1 < h).then_some(i + w)))
        })
        .collect();
    for (g, d) in guide.iter_mut().zip(slopes) {
        g.dz = d;
    }
    // Demodulated colour.
    let mut c: Vec<Vec3> = (0..n).map(|i| if guide[i].valid { color.pixels[i] / albedo[i] } else { Vec3::ZERO }).collect();
    // The noise's variance (of luminance): over each pixel's 5 × 5 neighbourhood on its
    // surface.
    let mut var: Vec<f32> = (0..n)
        .into_par_iter()
        .map(|i| {
            let g = &guide[i];
            if !g.valid {
                return 0.0;
            }
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            let (mut m1, mut m2, mut k) = (0f64, 0f64, 0f64);
            for dy in -2..=2i64 {
                for dx in -2..=2i64 {
                    let (xx, yy) = (x + dx, y + dy);
                    if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                        continue;
                    }
                    let j = yy as usize * w + xx as usize;
                    if !same_surface(g, &guide[j]) {
                        continue;
                    }
                    let l = f64::from(lum(c[j]));
                    m1 += l;
                    m2 += l * l;
                    k += 1.0;
                }
            }
            if k < 2.0 {
                return 0.0;
            }
            let mean = m1 / k;
            ((m2 / k - mean * mean).max(0.0) * k / (k - 1.0)) as f32
        })
        .collect();
    let normal_exp = if s.sigma_normal.fract() == 0.0 && (0.0..=1024.0).contains(&s.sigma_normal) { s.sigma_normal as i32 } else { -1 };
    for it in 0..s.iterations.min(12) {
        let step = 1i64 << it;
        // The variance at each pixel, blurred over 3 × 3 (SVGF: a steadier estimate).
        let blurred: Vec<f32> = (0..n)
            .into_par_iter()
            .map(|i| {
                let (x, y) = ((i % w) as i64, (i / w) as i64);
                let (mut sum, mut ws) = (0.0f32, 0.0f32);
                for dy in -1..=1i64 {
                    for dx in -1..=1i64 {
                        let (xx, yy) = (x + dx, y + dy);
                        if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                            continue;
                        }
                        let k = [0.25, 0.5, 0.25][(dx + 1) as usize] * [0.25, 0.5, 0.25][(dy + 1) as usize];
                        sum += var[yy as usize * w + xx as usize] * k;
                        ws += k;
                    }
                }
                sum / ws
            })
            .collect();
        // Each pair's weight, the same both ways (B3 taps, normals, depth against the larger
        // of the two slopes, luminance against the larger of the two noise levels), and
        // each pixel's sum of them (its own tap included).
        let weight = |i: usize, j: usize, dx: i64, dy: i64, hxy: f32| -> f32 {
            let (g, q) = (&guide[i], &guide[j]);
            if !q.valid {
                return 0.0;
            }
            let cos = g.n.dot(q.n).max(0.0);
            // PERF: an integer exponent by multiplications (powf was most of a pass).
            let wn = if normal_exp >= 0 { pow_u(cos, normal_exp as u32) } else { cos.powf(s.sigma_normal) };
            if wn <= 0.0 {
                return 0.0;
            }
            let (ax, ay) = (dx.unsigned_abs() as f32, dy.unsigned_abs() as f32);
            let expect = (g.dz.0 * ax + g.dz.1 * ay).max(q.dz.0 * ax + q.dz.1 * ay);
            let ez = (g.z - q.z).abs() / (s.sigma_depth * expect + 1e-3 * g.z.max(q.z));
            let sl = s.sigma_luminance * blurred[i].max(blurred[j]).max(0.0).sqrt() + 1e-6;
            let e = ez + (lum(c[i]) - lum(c[j])).abs() / sl;
            // (Weights below e^-30 count for nothing.)
            if e > 30.0 {
                return 0.0;
            }
            hxy * wn * (-e).exp()
        };
        let taps = |i: usize| {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            B3.iter().enumerate().flat_map(move |(ky, &hy)| {
                B3.iter().enumerate().filter_map(move |(kx, &hx)| {
                    let (dx, dy) = ((kx as i64 - 2) * step, (ky as i64 - 2) * step);
                    let (xx, yy) = (x + dx, y + dy);
                    (xx >= 0 && yy >= 0 && xx < w as i64 && yy < h as i64).then(|| (yy as usize * w + xx as usize, dx, dy, hx * hy))
                })
            })
        };
        // PERF: each pixel's 25 weights kept for the trading pass (made twice, they were
        // half of the denoiser's time).
        let weights: Vec<[f32; 25]> = (0..n)
            .into_par_iter()
            .map(|i| {
                let mut ws = [0.0f32; 25];
                if guide[i].valid {
                    for (k, (j, dx, dy, hxy)) in taps(i).enumerate() {
                        ws[k] = weight(i, j, dx, dy, hxy);
                    }
                }
                ws
            })
            .collect();
        let sums: Vec<f32> = weights.par_iter().map(|ws| ws.iter().sum()).collect();
        // Every pair trades light by its weight over the larger of the two sums: what one
        // gives the other takes, so the image's sum is kept exactly (up to rounding), and
        // each pixel's new value is a convex mix of its neighbourhood.
        let next: Vec<(Vec3, f32)> = (0..n)
            .into_par_iter()
            .map(|i| {
                if !guide[i].valid || sums[i] <= 0.0 {
                    return (c[i], var[i]);
                }
                let (mut delta, mut kept, mut v) = (Vec3::ZERO, 1.0f32, 0.0f32);
                for (k, (j, _, _, _)) in taps(i).enumerate() {
                    if j == i {
                        continue;
                    }
                    let wt = weights[i][k];
                    if wt <= 0.0 {
                        continue;
                    }
                    let a = wt / sums[i].max(sums[j]);
                    // In radiance, the pair trades `a · min(albedos)` of the difference:
                    // the same both ways, so the image's light is kept where the albedo
                    // varies too (per channel); the darker side moves at the full rate.
                    delta += (c[j] - c[i]) * (albedo[i].min(albedo[j]) * a) / albedo[i];
                    kept -= a;
                    v += a * a * var[j];
                }
                (c[i] + delta, v + kept * kept * var[i])
            })
            .collect();
        for (i, (cc, vv)) in next.into_iter().enumerate() {
            c[i] = cc;
            var[i] = vv;
        }
    }
    let pixels = (0..n).map(|i| if guide[i].valid { albedo[i] * c[i] } else { color.pixels[i] }).collect();
    Film { width: color.width, height: color.height, pixels }
}
