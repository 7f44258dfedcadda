//! Light from infinitely far in every direction: a constant, or an equirectangular map
//! (Mitsuba's `envmap`: its lookup, its frame) sampled by its luminance.

use super::sample::LightSample;
use crate::color::luminance;
use crate::lanes::sin_cos;
use crate::sampling::{cosine_hemisphere, uniform_sphere, Distribution2D, ShadingFrame};
use glam::{Affine3A, Vec2, Vec3};
use lucent_accel::math::{acos, atan2};
use lucent_accel::traverse::prefetch;
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
    /// Half a texel column: the densities' cells start at the first column's centre, so
    /// a cell's u is the map's less this.
    shift: f32,
}

impl EnvLight {
    /// The environment light of `e` (`None` when its transform or map is unusable).
    pub(crate) fn new(e: &Environment) -> Option<Self> {
        let to_local = e.to_world.inverse();
        if !to_local.is_finite() {
            return None;
        }
        let Some(img) = e.image.clone() else {
            return Some(Self { scale: e.scale, map: None, compensated: None, to_world: e.to_world, to_local, mean: e.scale, shift: 0.0 });
        };
        let (w, h) = (img.width as usize, img.height as usize);
        if w < 2 || h < 3 || img.texels.len() < w * h {
            return None;
        }
        // The sampling density: a grid of cells on the lookup's own lattice (cell corners
        // at texel centres: columns at (i + ½) / w, rows at j / (h − 1)), each lattice
        // cell split into kx × ky cells so that small maps still get at least 256 × 128.
        // Within a lattice cell the lookup is bilinear, and a bilinear function's mean
        // over a rectangle is its value at the rectangle's centre: each cell's mean
        // luminance is one lookup, exactly. The density is that times sin θ at the centre,
        // plus a tenth of the largest luminance of the cell's four texels (the largest
        // the lookup reaches in it), so it follows the radiance closely and is not zero
        // wherever some light comes from. (Was 16 lookups a cell on a grid of twice the
        // map's resolution, unaligned: a 512 × 256 map took 186 ms to prepare and its
        // 12 MB of tables missed the caches on every sample.)
        let (kx, ky) = (256usize.div_ceil(w).max(1), 128usize.div_ceil(h - 1).max(1));
        let (gw, gh) = (w * kx, (h - 1) * ky);
        let shift = 0.5 / w as f32;
        let lum = |x: usize, y: usize| luminance(img.texels[y.min(h - 1) * w + x % w]).max(0.0);
        let mut f = vec![0f32; gw * gh];
        // (Each cell's mean luminance, for the compensated density.)
        let mut lum_cell = vec![0f32; gw * gh];
        f.par_chunks_mut(gw).zip(lum_cell.par_chunks_mut(gw)).enumerate().for_each(|(gy, (row, lrow))| {
            let v = (gy as f32 + 0.5) / gh as f32;
            let st = (PI * v).sin();
            let r0 = gy / ky;
            for (gx, (cell, lcell)) in row.iter_mut().zip(lrow.iter_mut()).enumerate() {
                let l = luminance(Self::lookup(&img, (gx as f32 + 0.5) / gw as f32 + shift, v)).max(0.0);
                let c0 = gx / kx;
                let m = lum(c0, r0).max(lum(c0 + 1, r0)).max(lum(c0, r0 + 1)).max(lum(c0 + 1, r0 + 1));
                *lcell = l;
                *cell = (l + 0.1 * m) * st;
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
        Some(Self {
            scale: e.scale,
            map: Some((img, Distribution2D::new(&f, gw, gh))),
            compensated,
            to_world: e.to_world,
            to_local,
            mean,
            shift,
        })
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
        Self::lookup(img, u, v) * self.scale
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
        let (d, u, v) = self.map_uv(dir);
        self.eval_pdf_at(img, self.density(dist, mis), d.y, u, v)
    }

    /// [`EnvLight::eval_pdf`] of many directions (`dirs`, world, unit; `normals` as its
    /// `n`) into `out`: first every direction's (u, v), asking for the texels and density
    /// cells they read; then the values. (The map and its densities outgrow the caches;
    /// one direction after another, each waited for its own lines.)
    pub(crate) fn eval_pdf_batch(&self, dirs: &[Vec3], normals: &[Vec3], mis: bool, out: &mut [(Vec3, f32)]) {
        let Some((img, dist)) = &self.map else {
            for ((o, &d), &n) in out.iter_mut().zip(dirs).zip(normals) {
                *o = self.eval_pdf(d, n, mis);
            }
            return;
        };
        let dist = self.density(dist, mis);
        let mut at = [(0.0f32, 0.0f32, 0.0f32); 64];
        for (dirs, out) in dirs.chunks(64).zip(out.chunks_mut(64)) {
            for (a, &dir) in at.iter_mut().zip(dirs) {
                let (d, u, v) = self.map_uv(dir);
                self.prefetch_texels(img, u, v);
                dist.prefetch(Vec2::new(self.density_u(u), v));
                *a = (d.y, u, v);
            }
            for (o, &(cos, u, v)) in out.iter_mut().zip(&at) {
                *o = self.eval_pdf_at(img, dist, cos, u, v);
            }
        }
    }

    /// The radiance and density at (u, v) of the map (`cos`: the direction's y in the
    /// map's frame, cos θ).
    #[inline]
    fn eval_pdf_at(&self, img: &HdrImage, dist: &Distribution2D, cos: f32, u: f32, v: f32) -> (Vec3, f32) {
        let le = Self::lookup(img, u, v) * self.scale;
        let st = (1.0 - cos * cos).max(0.0).sqrt();
        let pdf = if st <= 0.0 { 0.0 } else { dist.pdf(Vec2::new(self.density_u(u), v)) / (2.0 * PI * PI * st) };
        (le, pdf)
    }

    /// The map's `u` (not yet wrapped) as the densities' cells take it, in [0, 1).
    #[inline]
    fn density_u(&self, u: f32) -> f32 {
        let x = u - self.shift;
        x - x.floor()
    }

    /// The texel lattice's cell of (u, v): its top-left texel's column and row, and the
    /// weights of the next column and row.
    #[inline]
    fn texel_cell(img: &HdrImage, u: f32, v: f32) -> (usize, usize, f32, f32) {
        let (w, h) = (img.width as usize, img.height as usize);
        let mut x = u - 0.5 / w as f32;
        x -= x.floor();
        let x = x * w as f32;
        let y = v * (h - 1) as f32;
        let (x0, y0) = ((x as usize).min(w - 1), (y as usize).min(h - 2));
        (x0, y0, x - x0 as f32, y - y0 as f32)
    }

    /// Asks for the lines [`EnvLight::lookup`] at (u, v) reads.
    #[inline]
    fn prefetch_texels(&self, img: &HdrImage, u: f32, v: f32) {
        let (x0, y0, _, _) = Self::texel_cell(img, u, v);
        let w = img.width as usize;
        for t in [img.texels.get(y0 * w + x0), img.texels.get((y0 + 1) * w + x0)].into_iter().flatten() {
            prefetch(t);
        }
    }

    /// The map's bilinear value at (u, v) (see [`EnvLight::eval`]).
    fn lookup(img: &HdrImage, u: f32, v: f32) -> Vec3 {
        let w = img.width as usize;
        let (x0, y0, fx, fy) = Self::texel_cell(img, u, v);
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
                return self.map_sample(img, uv, p);
            }
        };
        let dir = self.to_world.transform_vector3(local).normalize_or_zero();
        if dir == Vec3::ZERO {
            return None;
        }
        Some(LightSample { dir, dist: f32::INFINITY, li, pdf, delta: false })
    }
}

impl EnvLight {
    /// The light sample of a map's density at `uv` (density `p` over the unit square).
    #[inline]
    fn map_sample(&self, img: &HdrImage, uv: Vec2, p: f32) -> Option<LightSample> {
        if p <= 0.0 {
            return None;
        }
        let (st, ct) = sin_cos(uv.y * PI);
        let u = uv.x + self.shift;
        let (sp, cp) = sin_cos(u * (2.0 * PI));
        if st <= 0.0 {
            return None;
        }
        // (The radiance where the sample is, read at its (u, v): no way back from the
        // direction.)
        let li = Self::lookup(img, u, uv.y) * self.scale;
        let dir = self.to_world.transform_vector3(Vec3::new(sp * st, ct, -cp * st)).normalize_or_zero();
        if dir == Vec3::ZERO {
            return None;
        }
        Some(LightSample { dir, dist: f32::INFINITY, li, pdf: p / (2.0 * PI * PI * st), delta: false })
    }

    /// [`EnvLight::sample`] of the first `b.n` lanes of `b` (the same bits), in four passes
    /// over them: the rows (the marginal density is small and stays cached), the guide
    /// table's cells, the columns, then the directions and radiances; each pass first asks
    /// for the lines the next reads, so the lanes' cache misses overlap. (A map's density
    /// and texels outgrow the caches: one lane after another, each waited for its own
    /// three or four lines.)
    pub(crate) fn sample_batch(&self, b: &mut EnvBatch, mis: bool) {
        let n = b.n.min(ENV_BATCH);
        let Some((img, dist)) = &self.map else {
            for j in 0..n {
                b.out[j] = self.sample(b.u[j], b.normal[j], mis);
            }
            return;
        };
        let d = self.density(dist, mis);
        for j in 0..n {
            let (v, pv, r) = d.sample_row(b.u[j].1);
            (b.v[j], b.pv[j], b.row[j]) = (v, pv, r as u32);
            d.row(r).prefetch_start(b.u[j].0);
        }
        for j in 0..n {
            let row = d.row(b.row[j] as usize);
            let s = row.start(b.u[j].0);
            b.start[j] = s as u32;
            row.prefetch_cell(s);
        }
        for j in 0..n {
            let (x, pu, _) = d.row(b.row[j] as usize).sample_from(b.start[j] as usize, b.u[j].0);
            (b.x[j], b.pv[j]) = (x, b.pv[j] * pu);
            self.prefetch_texels(img, x + self.shift, b.v[j]);
        }
        for j in 0..n {
            b.out[j] = self.map_sample(img, Vec2::new(b.x[j], b.v[j]), b.pv[j]);
        }
    }
}

/// Lanes' environment samples taken together ([`EnvLight::sample_batch`]): their numbers
/// and normals in, their samples out.
pub(crate) struct EnvBatch {
    pub n: usize,
    /// In: each lane's (the integrator's) index, numbers and surface normal (see
    /// [`EnvLight::sample`]), and the environment's choice probability.
    pub lane: [u8; ENV_BATCH],
    pub u: [(f32, f32); ENV_BATCH],
    pub normal: [Vec3; ENV_BATCH],
    pub pmf: [f32; ENV_BATCH],
    /// Between the passes.
    row: [u32; ENV_BATCH],
    start: [u32; ENV_BATCH],
    v: [f32; ENV_BATCH],
    pv: [f32; ENV_BATCH],
    x: [f32; ENV_BATCH],
    /// Out.
    pub out: [Option<LightSample>; ENV_BATCH],
}

/// The most lanes an [`EnvBatch`] holds.
pub(crate) const ENV_BATCH: usize = 128;

impl EnvBatch {
    pub(crate) fn new() -> Box<Self> {
        Box::new(Self {
            n: 0,
            lane: [0; ENV_BATCH],
            u: [(0.0, 0.0); ENV_BATCH],
            normal: [Vec3::ZERO; ENV_BATCH],
            pmf: [0.0; ENV_BATCH],
            row: [0; ENV_BATCH],
            start: [0; ENV_BATCH],
            v: [0.0; ENV_BATCH],
            pv: [0.0; ENV_BATCH],
            x: [0.0; ENV_BATCH],
            out: [None; ENV_BATCH],
        })
    }

    /// Adds a lane (ignored when full).
    #[inline]
    pub(crate) fn push(&mut self, lane: u8, u: (f32, f32), normal: Vec3, pmf: f32) {
        if self.n < ENV_BATCH {
            let j = self.n;
            (self.lane[j], self.u[j], self.normal[j], self.pmf[j]) = (lane, u, normal, pmf);
            self.n += 1;
        }
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

    /// A map's samples report the radiance and density `eval_pdf` gives for their
    /// direction (both densities, on a rotated map whose lattice is not the grid's), and
    /// each density integrates to one over the sphere.
    #[test]
    fn a_maps_samples_agree_with_eval_pdf_and_its_density_is_normalised() {
        let mut sky = sun_and_sky();
        sky.to_world = Affine3A::from_rotation_y(0.7) * Affine3A::from_rotation_x(0.3);
        sky.to_local = sky.to_world.inverse();
        for mis in [false, true] {
            let k = 128;
            let mut worst = 0f32;
            for i in 0..k {
                for j in 0..k {
                    let u = ((i as f32 + 0.31) / k as f32, (j as f32 + 0.77) / k as f32);
                    let Some(s) = sky.sample(u, Vec3::ZERO, mis) else { continue };
                    let (le, pdf) = sky.eval_pdf(s.dir, Vec3::ZERO, mis);
                    worst = worst.max((pdf / s.pdf - 1.0).abs());
                    assert!((le - s.li).abs().max_element() <= 1e-3 * s.li.max_element().max(1.0), "{le} vs {}", s.li);
                }
            }
            // (A direction a rounding away from a cell's edge finds its neighbour.)
            assert!(worst < 0.02, "density off by {worst}");
            // ∫ pdf dω over the sphere, by the midpoint rule in (cos θ, φ).
            let n = 1024;
            let mut total = 0f64;
            for a in 0..n {
                let ct = 1.0 - 2.0 * (a as f32 + 0.5) / n as f32;
                let st = (1.0 - ct * ct).sqrt();
                for b in 0..2 * n {
                    let phi = PI * (b as f32 + 0.5) / n as f32;
                    total += f64::from(sky.eval_pdf(Vec3::new(st * phi.cos(), ct, st * phi.sin()), Vec3::ZERO, mis).1);
                }
            }
            let total = total * 4.0 * std::f64::consts::PI / f64::from(2 * n * n);
            assert!((total - 1.0).abs() < 5e-3, "mis {mis}: ∫ pdf = {total}");
        }
    }

    /// The batches give the one-by-one answers' bits: samples (both densities, a rotated
    /// map, numbers at the edges) and values with densities.
    #[test]
    fn batches_are_one_by_one() {
        let mut sky = sun_and_sky();
        sky.to_world = Affine3A::from_rotation_y(-1.1) * Affine3A::from_rotation_z(0.4);
        sky.to_local = sky.to_world.inverse();
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 40) as f32 / (1u64 << 24) as f32
        };
        for mis in [false, true] {
            for round in 0..20 {
                let mut b = EnvBatch::new();
                for j in 0..ENV_BATCH {
                    let u = match (round, j) {
                        (0, 0) => (0.0, 0.0),
                        (0, 1) => (1.0 - f32::EPSILON, 1.0 - f32::EPSILON),
                        (0, 2) => (0.5, 0.0),
                        _ => (next(), next()),
                    };
                    b.push(j as u8, u, Vec3::new(next() - 0.5, next(), next() - 0.5).normalize(), 1.0);
                }
                sky.sample_batch(&mut b, mis);
                let (mut dirs, mut normals) = ([Vec3::ZERO; ENV_BATCH], [Vec3::ZERO; ENV_BATCH]);
                for j in 0..ENV_BATCH {
                    assert_eq!(b.out[j], sky.sample(b.u[j], b.normal[j], mis), "lane {j}");
                    dirs[j] = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5).normalize();
                    normals[j] = b.normal[j];
                }
                let mut out = [(Vec3::ZERO, 0.0); ENV_BATCH];
                sky.eval_pdf_batch(&dirs, &normals, mis, &mut out);
                for j in 0..ENV_BATCH {
                    assert_eq!(out[j], sky.eval_pdf(dirs[j], normals[j], mis));
                }
            }
        }
    }
}
