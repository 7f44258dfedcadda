//! A BSDF and a light of your own, at the path tracer's coarse seam.
//!
//!     cargo run --release -p lucent_render --example custom_bsdf -- out.png
//!
//! The BSDF is Oren and Nayar's rough diffuse model ("Generalization of Lambert's
//! Reflectance Model", SIGGRAPH 1994, the qualitative form): clay and plaster look flatter
//! than Lambertian surfaces under grazing light. The light is a sun of finite angular size
//! (a disk of directions, sampled uniformly within its cone), giving soft-edged shadows a
//! directional light cannot. Both go into a `World` built from the built-in studio scene:
//! `World::set_bsdf` replaces one material's BSDF, `World::add_light` adds a light to those
//! next-event estimation samples. The built-in BSDFs and lights stay a closed enum; a user
//! one is one more variant, reached through a virtual call.

use glam::{Vec2, Vec3};
use lucent_accel::MeshOptions;
use lucent_render::{render, BsdfModel, BsdfSample, Camera, Integrator, LightModel, LightSample, PathSettings, RenderSettings, World};
use std::f32::consts::{FRAC_1_PI, PI};
use std::sync::Arc;

/// Oren-Nayar rough diffuse reflection of albedo `albedo` and roughness `sigma` (radians).
#[derive(Debug)]
struct OrenNayar {
    albedo: Vec3,
    a: f32,
    b: f32,
}

// The same shape as a built-in BSDF's file (`crates/render/src/bsdf/diffuse.rs`): the
// struct, its `eval`, `pdf` and `sample` in the local shading frame (z along the normal,
// `wo` toward the viewer, `wi` toward the light, `eval` with the cosine), and its
// closed-form tests; the seam (`BsdfModel`) only hands them on.
impl OrenNayar {
    fn new(albedo: Vec3, sigma: f32) -> Self {
        let s2 = sigma * sigma;
        Self { albedo, a: 1.0 - s2 / (2.0 * (s2 + 0.33)), b: 0.45 * s2 / (s2 + 0.09) }
    }

    /// f(wo, wi)·cos θi.
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let sin_o = (1.0 - wo.z * wo.z).max(0.0).sqrt();
        let sin_i = (1.0 - wi.z * wi.z).max(0.0).sqrt();
        // cos(φi − φo) from the projections on the tangent plane.
        let cos_dphi = if sin_o > 1e-4 && sin_i > 1e-4 { ((wo.x * wi.x + wo.y * wi.y) / (sin_o * sin_i)).max(0.0) } else { 0.0 };
        let (sin_a, tan_b) = if wi.z < wo.z { (sin_i, sin_o / wo.z) } else { (sin_o, sin_i / wi.z) };
        self.albedo * (FRAC_1_PI * (self.a + self.b * cos_dphi * sin_a * tan_b) * wi.z)
    }

    /// The density of [`OrenNayar::sample`]: the cosine.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z > 0.0 && wi.z > 0.0 {
            wi.z * FRAC_1_PI
        } else {
            0.0
        }
    }

    /// A cosine-distributed direction for `u2`, weighed by eval / pdf.
    fn sample(&self, wo: Vec3, u2: (f32, f32)) -> Option<BsdfSample> {
        let wi = lucent_render::sampling::cosine_hemisphere(u2);
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then(|| BsdfSample { wi, weight: self.eval(wo, wi) / pdf, pdf, delta: false, eta: 1.0 })
    }
}

impl BsdfModel for OrenNayar {
    fn eval(&self, wo: Vec3, wi: Vec3, _uv: Vec2) -> Vec3 {
        OrenNayar::eval(self, wo, wi)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3, _uv: Vec2) -> f32 {
        OrenNayar::pdf(self, wo, wi)
    }

    fn sample(&self, wo: Vec3, _uv: Vec2, _u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        OrenNayar::sample(self, wo, u2)
    }
}

/// A sun: radiance `radiance` from a cone of half-angle `half_angle` about `toward` (unit,
/// pointing to the sun).
#[derive(Debug)]
struct DiskSun {
    toward: Vec3,
    half_angle: f32,
    radiance: Vec3,
}

impl LightModel for DiskSun {
    fn sample(&self, _p: Vec3, u: (f32, f32)) -> Option<LightSample> {
        let cos_max = self.half_angle.cos();
        let dir = lucent_render::sampling::uniform_cone(self.toward, cos_max, u);
        Some(LightSample { dir, dist: f32::INFINITY, li: self.radiance, pdf: 1.0 / (2.0 * PI * (1.0 - cos_max)), delta: false })
    }

    fn power(&self) -> f32 {
        // Its irradiance at normal incidence (a light's power only steers the choice among
        // lights within one emitter; the choice among lights is uniform).
        let solid = 2.0 * PI * (1.0 - self.half_angle.cos());
        lucent_render::color::luminance(self.radiance) * solid
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "custom_bsdf.png".into());
    let scene = lucent_scene::studio_scene();
    let desc = scene.camera.ok_or("the studio has a camera")?;
    // The walls' material (a white diffuse one) becomes rough clay.
    let walls = scene.materials.iter().position(|m| m.name == "white").ok_or("the studio has white walls")? as u32;
    let mut world = World::new(scene, MeshOptions::default())?;
    world.set_bsdf(walls, Arc::new(OrenNayar::new(Vec3::new(0.8, 0.7, 0.6), 0.5)));
    world.add_light(Arc::new(DiskSun { toward: Vec3::new(0.3, 0.8, 0.5).normalize(), half_angle: 0.05, radiance: Vec3::splat(40.0) }));
    let (w, h) = (320, 240);
    let settings = RenderSettings { spp: 32, integrator: Integrator::Path(PathSettings::default()), ..RenderSettings::new(w, h) };
    let (film, _) = render(&world, &Camera::new(&desc, w, h), &settings, &|_| {});
    film.save(std::path::Path::new(&out))?;
    let mean = film.pixels.iter().copied().sum::<Vec3>() / film.pixels.len() as f32;
    println!("wrote {out} ({w}x{h}, 32 spp): mean radiance {mean:.3}");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Smooth (σ = 0), Oren-Nayar is Lambert's law: A = 1, B = 0.
    #[test]
    fn without_roughness_it_is_lambertian() {
        let b = OrenNayar::new(Vec3::new(0.5, 0.6, 0.7), 0.0);
        let (wo, wi) = (Vec3::new(0.6, 0.0, 0.8), Vec3::new(0.0, 0.28, 0.96));
        assert!((b.eval(wo, wi) - b.albedo * (wi.z * FRAC_1_PI)).abs().max_element() < 1e-7);
    }

    /// Rough, it still loses energy, never gains it: the albedo by sampling (weights over
    /// a stratified grid) is below the albedo's own, and above Lambert's at grazing light
    /// and view (its retro-reflection), as Oren and Nayar's figure 11 shows.
    #[test]
    fn rough_it_conserves_energy() {
        let b = OrenNayar::new(Vec3::ONE, 0.5);
        for cos in [0.2f32, 0.7, 1.0] {
            let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
            let n = 128;
            let mut albedo = 0.0;
            for i in 0..n {
                for j in 0..n {
                    let u = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    if let Some(s) = b.sample(wo, u) {
                        assert!((s.pdf - b.pdf(wo, s.wi)).abs() < 1e-5);
                        albedo += s.weight.x / (n * n) as f32;
                    }
                }
            }
            assert!(albedo > 0.7 && albedo <= 1.0, "cos {cos}: albedo {albedo}");
        }
    }
}
