//! The denoiser as it was written first, pixel by pixel and tap by tap (until stop 48):
//! the reference the lane kernels of [`super`] are tested against. Same filter, same
//! settings; it differs from the fast one only in rounding (the library's `exp` where the
//! lanes use a polynomial, sums taken in another order).

use super::{DenoiseSettings, B3};
use crate::aov::{dark as is_dark, demodulating};
use crate::color::luminance as lum;
use crate::film::{Aovs, Film};
use glam::Vec3;
use rayon::prelude::*;

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
    /// A surface darker than [`FILTER_ALBEDO_MIN`]: filtered in radiance (its light is
    /// not proportional to its albedo), with its own kind only.
    dark: bool,
}

/// Whether two guide pixels lie on one smooth surface (for the variance estimate and the
/// depth slope).
#[inline]
fn same_surface(a: &Guide, b: &Guide) -> bool {
    b.valid && a.dark == b.dark && a.n.dot(b.n) > 0.9 && (a.z - b.z).abs() < 0.1 * a.z
}

/// Spreads the light of outliers (fireflies: rare paths of high contribution) over their
/// surface, keeping it: a pixel whose demodulated luminance exceeds the mean of its 5 × 5
/// neighbours on the same surface (its brightest neighbour left out) by more than
/// `outlier_sigmas` of their standard deviation keeps that bound, and the rest of its light,
/// in radiance, goes to the pixels of the same surface within `outlier_radius`, in
/// proportion to their albedo (so each gains the same demodulated amount).
fn spread_outliers(c: &mut [Vec3], albedo: &[Vec3], guide: &[Guide], w: usize, h: usize, s: &DenoiseSettings) {
    if s.outlier_sigmas <= 0.0 || s.outlier_radius == 0 {
        return;
    }
    let n = c.len();
    let excess: Vec<Option<Vec3>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let g = &guide[i];
            if !g.valid {
                return None;
            }
            let li = lum(c[i]);
            let (x, y) = (i % w, i / w);
            let (mut m1, mut m2, mut k, mut top) = (0f64, 0f64, 0f64, f64::NEG_INFINITY);
            for yy in y.saturating_sub(2)..(y + 3).min(h) {
                for xx in x.saturating_sub(2)..(x + 3).min(w) {
                    let j = yy * w + xx;
                    if j == i || !same_surface(g, &guide[j]) {
                        continue;
                    }
                    let l = f64::from(lum(c[j]));
                    m1 += l;
                    m2 += l * l;
                    k += 1.0;
                    top = top.max(l);
                }
            }
            if k < 4.0 {
                return None;
            }
            let (m1, m2, k) = (m1 - top, m2 - top * top, k - 1.0);
            let mean = m1 / k;
            let sd = (m2 / k - mean * mean).max(0.0).sqrt();
            let bound = (mean + f64::from(s.outlier_sigmas) * sd) as f32;
            (li > bound && bound >= 0.0).then(|| c[i] * (1.0 - bound / li))
        })
        .collect();
    // Each outlier's excess, per unit of albedo of the pixels that share it (they must lie
    // on its surface: the test is the outlier's, so gathering below finds the same ones).
    // PERF: rows and columns as ranges (no division per tap).
    let r = s.outlier_radius as usize;
    let span = |v: usize, len: usize| v.saturating_sub(r)..(v + r + 1).min(len);
    let outliers: Vec<(usize, Vec3)> = excess
        .par_iter()
        .enumerate()
        .filter_map(|(i, e)| {
            let e = (*e)?;
            let (x, y) = (i % w, i / w);
            let mut total = Vec3::ZERO;
            for yy in span(y, h) {
                for j in span(x, w).map(|xx| yy * w + xx) {
                    if j == i || same_surface(&guide[i], &guide[j]) {
                        total += albedo[j];
                    }
                }
            }
            Some((i, albedo[i] * e / total))
        })
        .collect();
    if outliers.is_empty() {
        return;
    }
    // Gathered per row (in parallel): what each pixel receives from the outliers near it.
    let mut by_row: Vec<Vec<(usize, usize, Vec3)>> = vec![Vec::new(); h];
    for &(i, per) in &outliers {
        by_row[i / w].push((i % w, i, per));
    }
    let mut gained = vec![Vec3::ZERO; n];
    gained.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for yy in span(y, h) {
            // (Each row's outliers are in order of x.)
            let list = &by_row[yy];
            let mut lo = 0;
            for (x, g) in row.iter_mut().enumerate() {
                while lo < list.len() && list[lo].0 + r < x {
                    lo += 1;
                }
                let j = y * w + x;
                for &(_, i, per) in list[lo..].iter().take_while(|o| o.0 <= x + r) {
                    if j == i || same_surface(&guide[i], &guide[j]) {
                        *g += per;
                    }
                }
            }
        }
    });
    for (i, e) in excess.iter().enumerate() {
        if let Some(e) = e {
            c[i] -= *e;
        }
    }
    for (c, g) in c.iter_mut().zip(gained) {
        *c += g;
    }
}

/// Denoises `color` guided by `aovs` (the same size). Energy is kept: each pass moves
/// light between pairs of pixels by an amount that is the same both ways (a conservative
/// diffusion step), so the image's sum does not change, where a normalised weighted mean
/// loses the light of outliers its neighbours refuse (measured: −3% on a 4-sample
/// Sponza), and demodulated values traded as they are change it where the albedo varies
/// (+8% on the kitchen).
#[must_use]
pub(super) fn denoise(color: &Film, aovs: &Aovs, s: &DenoiseSettings) -> Film {
    let (w, h) = (color.width as usize, color.height as usize);
    let n = w * h;
    if n == 0 || aovs.albedo.pixels.len() != n || aovs.normal.pixels.len() != n || aovs.depth.len() != n || aovs.emission.pixels.len() != n
    {
        return color.clone();
    }
    let albedo: Vec<Vec3> = aovs.albedo.pixels.iter().map(|&a| demodulating(a)).collect();
    let mut guide: Vec<Guide> = (0..n)
        .map(|i| {
            let (nn, z) = (aovs.normal.pixels[i], aovs.depth[i]);
            // (Emitters pass through: their light is not the albedo's to scale.)
            let emits = aovs.emission.pixels[i].max_element() > 0.0;
            // (Dark surfaces are filtered among themselves: see `FILTER_ALBEDO_MIN`.)
            let dark = is_dark(aovs.albedo.pixels[i]);
            Guide {
                valid: z.is_finite() && z > 0.0 && nn != Vec3::ZERO && !emits && color.pixels[i].is_finite(),
                n: nn,
                z,
                dz: (0.0, 0.0),
                dark,
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
    spread_outliers(&mut c, &albedo, &guide, w, h, s);
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
    // PERF: plain loops over rows, the luminance and noise level of each pixel computed
    // once per pass, and the buffers kept across passes (the iterator-and-closure version
    // took 1.2-1.9 s at 512 × 384 on 2 threads).
    // The least cosine between normals whose weight reaches e^-30.
    let cos_min = if s.sigma_normal > 0.0 { (-30.0 / s.sigma_normal).exp() } else { -1.0 };
    let mut weights = vec![[0.0f32; 25]; n];
    let mut sums = vec![0.0f32; n];
    let mut next = vec![(Vec3::ZERO, 0.0f32); n];
    let mut l = vec![0.0f32; n];
    let mut sd = vec![0.0f32; n];
    for it in 0..s.iterations.min(12) {
        let step = 1usize << it;
        // The noise's standard deviation at each pixel: the variance blurred over 3 × 3
        // (SVGF: a steadier estimate).
        sd.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let (mut sum, mut ws) = (0.0f32, 0.0f32);
                for (ky, hy) in [0.25f32, 0.5, 0.25].into_iter().enumerate() {
                    let Some(yy) = (y + ky).checked_sub(1).filter(|&yy| yy < h) else { continue };
                    for (kx, hx) in [0.25f32, 0.5, 0.25].into_iter().enumerate() {
                        let Some(xx) = (x + kx).checked_sub(1).filter(|&xx| xx < w) else { continue };
                        sum += var[yy * w + xx] * (hx * hy);
                        ws += hx * hy;
                    }
                }
                *out = (sum / ws).max(0.0).sqrt();
            }
        });
        l.par_iter_mut().zip(&c).for_each(|(l, c)| *l = lum(*c));
        // Each pair's weight, the same both ways (B3 taps, normals, depth against the larger
        // of the two slopes, luminance against the larger of the two noise levels), and
        // each pixel's sum of them (its own tap included). Taps outside the image weigh 0.
        let (guide, l, sd) = (&guide, &l, &sd);
        weights.par_chunks_mut(w).zip(sums.par_chunks_mut(w)).enumerate().for_each(|(y, (wrow, srow))| {
            for x in 0..w {
                let i = y * w + x;
                let ws = &mut wrow[x];
                *ws = [0.0; 25];
                let g = &guide[i];
                if !g.valid {
                    srow[x] = 0.0;
                    continue;
                }
                for ky in 0..5 {
                    let Some(yy) = (y + ky * step).checked_sub(2 * step).filter(|&yy| yy < h) else { continue };
                    let ay = (ky.abs_diff(2) * step) as f32;
                    for kx in 0..5 {
                        let Some(xx) = (x + kx * step).checked_sub(2 * step).filter(|&xx| xx < w) else { continue };
                        let j = yy * w + xx;
                        let q = &guide[j];
                        if !q.valid || q.dark != g.dark {
                            continue;
                        }
                        let cos = g.n.dot(q.n);
                        // (Weights below e^-30 count for nothing: normals apart by more
                        // than that, first, as it is the cheapest test.)
                        if cos < cos_min {
                            continue;
                        }
                        let ax = (kx.abs_diff(2) * step) as f32;
                        let expect = (g.dz.0 * ax + g.dz.1 * ay).max(q.dz.0 * ax + q.dz.1 * ay);
                        let ez = (g.z - q.z).abs() / (s.sigma_depth * expect + 1e-3 * g.z.max(q.z));
                        let sl = s.sigma_luminance * sd[i].max(sd[j]) + 1e-6;
                        let e = ez + (l[i] - l[j]).abs() / sl;
                        if e > 30.0 {
                            continue;
                        }
                        // PERF: an integer exponent by multiplications (powf was most of a pass).
                        let cos = cos.max(0.0);
                        let wn = if normal_exp >= 0 { pow_u(cos, normal_exp as u32) } else { cos.powf(s.sigma_normal) };
                        ws[ky * 5 + kx] = B3[kx] * B3[ky] * wn * (-e).exp();
                    }
                }
                srow[x] = ws.iter().sum();
            }
        });
        // Every pair trades light by its weight over the larger of the two sums: what one
        // gives the other takes, so the image's sum is kept exactly (up to rounding), and
        // each pixel's new value is a convex mix of its neighbourhood.
        let (weights, sums, cc, vv) = (&weights, &sums, &c, &var);
        next.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let i = y * w + x;
                if !guide[i].valid || sums[i] <= 0.0 {
                    *out = (cc[i], vv[i]);
                    continue;
                }
                let (mut delta, mut kept, mut v) = (Vec3::ZERO, 1.0f32, 0.0f32);
                for ky in 0..5 {
                    let Some(yy) = (y + ky * step).checked_sub(2 * step).filter(|&yy| yy < h) else { continue };
                    for kx in 0..5 {
                        let wt = weights[i][ky * 5 + kx];
                        if wt <= 0.0 || (kx == 2 && ky == 2) {
                            continue;
                        }
                        // (A tap of positive weight lies inside the image.)
                        let j = yy * w + (x + kx * step - 2 * step);
                        let a = wt / sums[i].max(sums[j]);
                        // In radiance, the pair trades `a · min(albedos)` of the difference:
                        // the same both ways, so the image's light is kept where the albedo
                        // varies too (per channel); the darker side moves at the full rate.
                        delta += (cc[j] - cc[i]) * (albedo[i].min(albedo[j]) * a) / albedo[i];
                        kept -= a;
                        v += a * a * vv[j];
                    }
                }
                *out = (cc[i] + delta, v + kept * kept * vv[i]);
            }
        });
        for (i, &(cn, vn)) in next.iter().enumerate() {
            c[i] = cn;
            var[i] = vn;
        }
    }
    let pixels = (0..n).map(|i| if guide[i].valid { albedo[i] * c[i] } else { color.pixels[i] }).collect();
    Film { width: color.width, height: color.height, pixels }
}
