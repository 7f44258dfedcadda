//! Light from infinitely far in every direction: a constant, or an equirectangular map
//! (Mitsuba's `envmap`: its lookup, its frame) sampled by its luminance.

use super::sample::LightSample;
use crate::color::luminance;
use crate::lanes::sin_cos;
use crate::sampling::{cosine_hemisphere, uniform_sphere, Distribution2D, ShadingFrame};
use glam::{Affine3A, Vec2, Vec3};
use lucent_accel::math::{acos, atan2};
use lucent_scene::{Environment, HdrImage};
use rayon::prelude::*;
use std::f32::consts::PI;
use std::sync::Arc;

/// An environment light.
#[derive(Clone, Debug)]
pub(crate) struct EnvLight {
    scale: Vec3,
    map: Option<(Arc<HdrImage>, Distribution2D)>,
    /// The density for multiple importance sampling with the BSDF's samples: the cells'
    /// luminance less its mean over the sphere, clamped at zero (Karlík, Šik, Vévoda,
    /// Skřivan, Křivánek 2019, "MIS compensation"). Where the map is dimmer than its mean
    /// the BSDF's samples alone find the light, so its share of the light samples goes to
    /// the bright parts. `None` for a map with nothing above its mean.
    compensated: Option<Distribution2D>,
    to_world: Affine3A,
    to_local: Affine3A,
    /// Mean radiance (power estimate).
    mean: Vec3,
}

impl EnvLight {
    /// The environment light of `e` (`None` when its transform or map is unusable).
    pub(crate) fn new(e: &Environment) -> Option<Self> {
        let to_local = e.to_world.inverse();
        if !to_local.is_finite() {
            return None;
        }
        let Some(img) = e.image.clone() else {
            return Some(Self { scale: e.scale, map: None, compensated: None, to_world: e.to_world, to_local, mean: e.scale });
        };
        let (w, h) = (img.width as usize, img.height as usize);
        if w < 2 || h < 3 || img.texels.len() < w * h {
            return None;
        }
        // The sampling density: a grid of cells over (u, v) in [0, 1)² (twice the map's
        // resolution, at least 256 × 128), each the mean over 4 × 4 points of the
        // luminance the lookup gives there times sin θ, plus a tenth of the largest
        // luminance of the texels the lookup may blend anywhere in the cell: the density
        // follows the radiance closely and is not zero wherever some light comes from.
        let (gw, gh) = ((2 * w).max(256), (2 * h).max(128));
        let unit = Self {
            scale: Vec3::ONE,
            map: None,
            compensated: None,
            to_world: Affine3A::IDENTITY,
            to_local: Affine3A::IDENTITY,
            mean: Vec3::ONE,
        };
        let lookup = |u: f32, v: f32| luminance(unit.lookup(&img, u, v)).max(0.0);
        let lum = |x: usize, y: usize| luminance(img.texels[y.min(h - 1) * w + x % w]).max(0.0);
        let mut f = vec![0f32; gw * gh];
        // (Each cell's mean luminance over its 4 × 4 points, for the compensated density.)
        let mut lum_cell = vec![0f32; gw * gh];
        // (Rows in parallel: a 512 × 256 map's grid took 150 ms on one thread.)
        f.par_chunks_mut(gw).zip(lum_cell.par_chunks_mut(gw)).enumerate().for_each(|(gy, (row, lrow))| {
            let (v0, v1) = (gy as f32 / gh as f32, (gy + 1) as f32 / gh as f32);
            let (r0, r1) = ((v0 * (h - 1) as f32).floor() as usize, ((v1 * (h - 1) as f32).ceil() as usize).min(h - 1));
            let s_mid = (PI * 0.5 * (v0 + v1)).sin();
            for (gx, (cell, lcell)) in row.iter_mut().zip(lrow.iter_mut()).enumerate() {
                let (u0, u1) = (gx as f32 / gw as f32, (gx + 1) as f32 / gw as f32);
                let (mut sum, mut plain) = (0.0, 0.0);
                for j in 0..4 {
                    let v = v0 + (v1 - v0) * (j as f32 + 0.5) / 4.0;
                    let st = (PI * v).sin();
                    for i in 0..4 {
                        let l = lookup(u0 + (u1 - u0) * (i as f32 + 0.5) / 4.0, v);
                        sum += l * st;
                        plain += l;
                    }
                }
                *lcell = plain / 16.0;
                // The texel columns whose bilinear footprint reaches the cell.
                let (c0, c1) = ((u0 * w as f32 - 0.5).floor() as i64, (u1 * w as f32 - 0.5).floor() as i64 + 1);
                let mut m = 0f32;
                for r in r0..=r1 {
                    for c in c0..=c1 {
                        m = m.max(lum(c.rem_euclid(w as i64) as usize, r));
                    }
                }
                *cell = sum / 16.0 + 0.1 * m * s_mid;
            }
        });
        // The compensated density: the mean over the sphere (cells weighed by their solid
        // angle, ∝ sin θ) taken off each cell.
        let sines: Vec<f32> = (0..gh).map(|gy| (PI * (gy as f32 + 0.5) / gh as f32).sin()).collect();
        let (mut lsum, mut ssum) = (0f64, 0f64);
        for (gy, lrow) in lum_cell.chunks(gw).enumerate() {
            lsum += lrow.iter().map(|&l| f64::from(l)).sum::<f64>() * f64::from(sines[gy]);
            ssum += gw as f64 * f64::from(sines[gy]);
        }
        let delta = (lsum / ssum.max(f64::MIN_POSITIVE)) as f32;
        for (gy, lrow) in lum_cell.chunks_mut(gw).enumerate() {
            for l in lrow {
                *l = (*l - delta).max(0.0) * sines[gy];
            }
        }
        let compensated = lum_cell.iter().any(|&c| c > 0.0).then(|| Distribution2D::new(&lum_cell, gw, gh));
        let mut mean = Vec3::ZERO;
        let mut wsum = 0.0;
        for y in 0..h {
            let st = (PI * y as f32 / (h - 1) as f32).sin();
            for x in 0..w {
                mean += img.texels[y * w + x] * st;
                wsum += st;
            }
        }
        let mean = if wsum > 0.0 { mean / wsum * e.scale } else { e.scale };
        Some(Self { scale: e.scale, map: Some((img, Distribution2D::new(&f, gw, gh))), compensated, to_world: e.to_world, to_local, mean })
    }

    /// The luminance of its mean radiance.
    pub(crate) fn mean_luminance(&self) -> f32 {
        luminance(self.mean)
    }

    /// Its power, as light through the scene's bounding sphere of radius `radius` (for the
    /// choice among lights).
    pub(crate) fn power(&self, radius: f32) -> f32 {
        luminance(self.mean) * 4.0 * PI * PI * radius * radius
    }

    /// Radiance arriving from world direction `dir` (unit): Mitsuba's lookup, u =
    /// atan2(x, −z) / 2π and v = acos(y) / π in the map's frame, bilinear with texel
    /// columns centred at (i + ½) / w (wrapping) and rows at j / (h − 1), pole to pole.
    pub(crate) fn eval(&self, dir: Vec3) -> Vec3 {
        let Some((img, _)) = &self.map else { return self.scale };
        let (_, u, v) = self.map_uv(dir);
        self.lookup(img, u, v) * self.scale
    }

    /// World direction `dir` in the map's frame (unit), and its (u, v) there (u not yet
    /// wrapped into [0, 1)).
    #[inline]
    fn map_uv(&self, dir: Vec3) -> (Vec3, f32, f32) {
        let d = self.to_local.transform_vector3(dir).normalize_or_zero();
        (d, atan2(d.x, -d.z) * (0.5 / PI), acos(d.y) / PI)
    }

    /// The density a map is sampled by: the compensated one for multiple importance
    /// sampling with the BSDF (`mis`) when there is one.
    #[inline]
    fn density<'a>(&'a self, dist: &'a Distribution2D, mis: bool) -> &'a Distribution2D {
        match &self.compensated {
            Some(c) if mis => c,
            _ => dist,
        }
    }

    /// [`EnvLight::eval`] of one direction and the density of [`EnvLight::sample`] (with
    /// the same `mis`) for it, the angles found once.
    pub(crate) fn eval_pdf(&self, dir: Vec3, n: Vec3, mis: bool) -> (Vec3, f32) {
        let Some((img, dist)) = &self.map else { return (self.scale, constant_pdf(dir, n)) };
        let dist = self.density(dist, mis);
        let (d, u, v) = self.map_uv(dir);
        let le = self.lookup(img, u, v) * self.scale;
        let st = (1.0 - d.y * d.y).max(0.0).sqrt();
        let pdf = if st <= 0.0 { 0.0 } else { dist.pdf(Vec2::new(u - u.floor(), v)) / (2.0 * PI * PI * st) };
        (le, pdf)
    }

    /// The map's bilinear value at (u, v) (see [`EnvLight::eval`]).
    fn lookup(&self, img: &HdrImage, u: f32, v: f32) -> Vec3 {
        let (w, h) = (img.width as usize, img.height as usize);
        let mut x = u - 0.5 / w as f32;
        x -= x.floor();
        let x = x * w as f32;
        let y = v * (h - 1) as f32;
        let (x0, y0) = ((x as usize).min(w - 1), (y as usize).min(h - 2));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        // (The column after the last is the first: a compare, not a division.)
        let x1 = if x0 + 1 == w { 0 } else { x0 + 1 };
        let t = |xi: usize, yi: usize| img.texels[yi * w + xi];
        let top = t(x0, y0) * (1.0 - fx) + t(x1, y0) * fx;
        let bottom = t(x0, y0 + 1) * (1.0 - fx) + t(x1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// A direction (unit, world) and its density per solid angle, from a point whose
    /// surface has unit normal `n` (zero: none). A constant environment is sampled by the
    /// cosine about `n` (the light it sends to a diffuse surface, exactly; directions
    /// behind the surface are left to the BSDF's samples, whose MIS weight is then 1), or
    /// uniformly without a normal; a map by its luminance, or with `mis` (for multiple
    /// importance sampling with the BSDF's samples, which must then reach every direction
    /// the BSDF scatters light from) by its compensated density, which may be zero where
    /// the map is dim.
    pub(crate) fn sample(&self, u: (f32, f32), n: Vec3, mis: bool) -> Option<LightSample> {
        let (local, pdf, li) = match &self.map {
            None if n != Vec3::ZERO => {
                let l = cosine_hemisphere(u);
                let dir = ShadingFrame::new(n).to_world(l).normalize_or_zero();
                let pdf = constant_pdf(dir, n);
                return (pdf > 0.0).then_some(LightSample { dir, dist: f32::INFINITY, li: self.scale, pdf, delta: false });
            }
            None => (uniform_sphere(u), 1.0 / (4.0 * PI), self.scale),
            Some((img, dist)) => {
                let (uv, p) = self.density(dist, mis).sample(u);
                if p <= 0.0 {
                    return None;
                }
                let (st, ct) = sin_cos(uv.y * PI);
                let (sp, cp) = sin_cos(uv.x * (2.0 * PI));
                if st <= 0.0 {
                    return None;
                }
                // (The radiance where the sample is, read at its (u, v): no way back from
                // the direction.)
                (Vec3::new(sp * st, ct, -cp * st), p / (2.0 * PI * PI * st), self.lookup(img, uv.x, uv.y) * self.scale)
            }
        };
        let dir = self.to_world.transform_vector3(local).normalize_or_zero();
        if dir == Vec3::ZERO {
            return None;
        }
        Some(LightSample { dir, dist: f32::INFINITY, li, pdf, delta: false })
    }
}

/// The density with which a constant environment is sampled toward unit `dir` from a point
/// with unit normal `n` (zero: none), see [`EnvLight::sample`].
#[inline]
fn constant_pdf(dir: Vec3, n: Vec3) -> f32 {
    if n == Vec3::ZERO {
        1.0 / (4.0 * PI)
    } else {
        n.dot(dir).max(0.0) / PI
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::power_heuristic;
    use glam::Affine3A;

    #[test]
    fn a_constant_sky_is_sampled_by_the_cosine_about_the_normal() {
        let sky = EnvLight::new(&Environment { scale: Vec3::splat(0.7), image: None, to_world: Affine3A::IDENTITY }).expect("a sky");
        let n = Vec3::new(0.3, 0.9, -0.2).normalize();
        let mut irradiance = 0.0f64;
        let k = 64;
        for i in 0..k {
            for j in 0..k {
                let u = ((i as f32 + 0.5) / k as f32, (j as f32 + 0.5) / k as f32);
                let s = sky.sample(u, n, false).expect("a direction above the surface");
                assert!(s.dir.dot(n) >= 0.0 && (s.dir.length() - 1.0).abs() < 1e-5);
                // The density it reports is the one a BSDF's direction is weighed with.
                let (le, pdf) = sky.eval_pdf(s.dir, n, false);
                assert!((pdf - s.pdf).abs() <= 1e-4 * s.pdf.max(1.0), "{pdf} vs {}", s.pdf);
                assert_eq!(le, s.li);
                irradiance += f64::from(s.li.x * s.dir.dot(n) / s.pdf);
            }
        }
        // Every sample carries the irradiance of the sky exactly: π L.
        let e = irradiance / f64::from(k * k);
        assert!((e - std::f64::consts::PI * 0.7).abs() < 1e-3, "{e}");
        // Behind the surface: density zero. Without a normal: uniform.
        assert_eq!(sky.eval_pdf(-n, n, false).1, 0.0);
        assert!((sky.eval_pdf(-n, Vec3::ZERO, false).1 - 1.0 / (4.0 * PI)).abs() < 1e-7);
        let s = sky.sample((0.3, 0.8), Vec3::ZERO, false).expect("a direction");
        assert!((s.pdf - 1.0 / (4.0 * PI)).abs() < 1e-7);
    }

    /// A dim sky of 0.2 to 0.8 and a sun of 200 around (u, v) = (0.3, 0.3).
    fn sun_and_sky() -> EnvLight {
        let (w, h) = (64u32, 32u32);
        let texels = (0..h)
            .flat_map(|y| {
                (0..w).map(move |x| {
                    let (u, v) = ((x as f32 + 0.5) / w as f32, y as f32 / (h - 1) as f32);
                    let sun = (u - 0.3).abs() < 0.03 && (v - 0.3).abs() < 0.05;
                    if sun {
                        Vec3::splat(200.0)
                    } else {
                        Vec3::new(0.2, 0.3, 0.5) + Vec3::splat(0.3 * u)
                    }
                })
            })
            .collect();
        let image = Some(Arc::new(HdrImage { width: w, height: h, texels }));
        EnvLight::new(&Environment { scale: Vec3::ONE, image, to_world: Affine3A::IDENTITY }).expect("a sky")
    }

    #[test]
    fn the_compensated_density_leaves_the_dim_sky_to_the_bsdf_and_stays_unbiased() {
        let sky = sun_and_sky();
        let n = Vec3::new(0.2, 0.95, 0.1).normalize();
        // Directions the map is dimmer than its mean toward: no compensated density, but
        // the full density is there (NEE alone still finds them).
        let dim = Vec3::new(0.6, -0.3, 0.74).normalize();
        assert_eq!(sky.eval_pdf(dim, Vec3::ZERO, true).1, 0.0);
        assert!(sky.eval_pdf(dim, Vec3::ZERO, false).1 > 0.0);
        // The irradiance of a surface of normal n by MIS (power heuristic) of the light's
        // samples and cosine-weighted ones, against the cosine samples alone, many more.
        let k = 256;
        let (mut mis, mut brute) = (0.0f64, 0.0f64);
        let frame = ShadingFrame::new(n);
        for i in 0..k {
            for j in 0..k {
                let u = ((i as f32 + 0.37) / k as f32, (j as f32 + 0.61) / k as f32);
                if let Some(s) = sky.sample(u, n, true) {
                    let cos = s.dir.dot(n);
                    if cos > 0.0 {
                        let pb = cos / PI;
                        mis += f64::from(luminance(s.li) * cos / s.pdf * power_heuristic(s.pdf, pb));
                    }
                }
                let dir = frame.to_world(cosine_hemisphere(u));
                let (le, pl) = sky.eval_pdf(dir, n, true);
                let pb = dir.dot(n).max(0.0) / PI;
                if pb > 0.0 {
                    mis += f64::from(luminance(le) * PI * power_heuristic(pb, pl));
                }
            }
        }
        for i in 0..4 * k {
            for j in 0..4 * k {
                let u = ((i as f32 + 0.5) / (4 * k) as f32, (j as f32 + 0.5) / (4 * k) as f32);
                brute += f64::from(luminance(sky.eval(frame.to_world(cosine_hemisphere(u)))) * PI);
            }
        }
        let (mis, brute) = (mis / f64::from(k * k), brute / f64::from(16 * k * k));
        assert!((mis / brute - 1.0).abs() < 0.01, "MIS {mis} against {brute}");
    }
}
