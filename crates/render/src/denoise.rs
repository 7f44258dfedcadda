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
//! that see no surface or an emitter pass through.
//!
//! Each of the `iterations` passes is a 5 × 5 B3-spline kernel (1/16, 1/4, 3/8, 1/4, 1/16)
//! with holes: pass `i` takes every `2^i`-th pixel, so five passes reach 62 pixels out.

use crate::film::{Aovs, Film};
use glam::Vec3;
use rayon::prelude::*;

/// The denoiser's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DenoiseSettings {
    /// À-trous passes (kernel steps 1, 2, 4, ...).
    pub iterations: u32,
    /// Luminance edge-stopping: differences of `sigma_luminance` standard deviations of
    /// the noise weigh `1/e`.
    pub sigma_luminance: f32,
    /// Normal edge-stopping exponent.
    pub sigma_normal: f32,
    /// Depth edge-stopping: differences of `sigma_depth` times what the depth's slope
    /// predicts weigh `1/e`.
    pub sigma_depth: f32,
}

impl Default for DenoiseSettings {
    fn default() -> Self {
        Self { iterations: 5, sigma_luminance: 4.0, sigma_normal: 128.0, sigma_depth: 1.0 }
    }
}

/// The least albedo the colour is divided by (per channel).
const ALBEDO_MIN: f32 = 1e-3;

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

#[inline]
fn lum(c: Vec3) -> f32 {
    crate::world::luminance(c)
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

/// Denoises `color` guided by `aovs` (the same size). The image's mean is kept (each
/// pass is a normalised weighted mean of the colours around each pixel).
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
            Guide { valid: z.is_finite() && z > 0.0 && nn != Vec3::ZERO && !emits && color.pixels[i].is_finite(), n: nn, z, dz: (0.0, 0.0) }
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
        let next: Vec<(Vec3, f32)> = (0..n)
            .into_par_iter()
            .map(|i| {
                let g = &guide[i];
                if !g.valid {
                    return (c[i], var[i]);
                }
                let (x, y) = ((i % w) as i64, (i / w) as i64);
                let lp = lum(c[i]);
                let sl = s.sigma_luminance * blurred[i].max(0.0).sqrt() + 1e-6;
                let (mut sum, mut wsum, mut vsum) = (Vec3::ZERO, 0.0f32, 0.0f32);
                for (ky, &hy) in B3.iter().enumerate() {
                    let dy = (ky as i64 - 2) * step;
                    let yy = y + dy;
                    if yy < 0 || yy >= h as i64 {
                        continue;
                    }
                    for (kx, &hx) in B3.iter().enumerate() {
                        let dx = (kx as i64 - 2) * step;
                        let xx = x + dx;
                        if xx < 0 || xx >= w as i64 {
                            continue;
                        }
                        let j = yy as usize * w + xx as usize;
                        let q = &guide[j];
                        if !q.valid {
                            continue;
                        }
                        let cos = g.n.dot(q.n).max(0.0);
                        // PERF: an integer exponent by multiplications (powf was most of a pass).
                        let wn = if normal_exp >= 0 { pow_u(cos, normal_exp as u32) } else { cos.powf(s.sigma_normal) };
                        if wn <= 0.0 {
                            continue;
                        }
                        let expect = g.dz.0 * dx.abs() as f32 + g.dz.1 * dy.abs() as f32;
                        let ez = (g.z - q.z).abs() / (s.sigma_depth * expect + 1e-3 * g.z);
                        let el = (lp - lum(c[j])).abs() / sl;
                        let e = ez + el;
                        // (Weights below e^-30 count for nothing.)
                        if e > 30.0 {
                            continue;
                        }
                        let wt = hx * hy * wn * (-e).exp();
                        sum += c[j] * wt;
                        wsum += wt;
                        vsum += wt * wt * var[j];
                    }
                }
                if wsum > 0.0 {
                    (sum / wsum, vsum / (wsum * wsum))
                } else {
                    (c[i], var[i])
                }
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
