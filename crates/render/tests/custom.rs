//! The user's seam: a BSDF given to `World::set_bsdf` and a light given to
//! `World::add_light` take part in path tracing as the built-in ones do. A Lambertian
//! BSDF written by hand gives the built-in diffuse material's image; a sun of tiny angular
//! size gives the built-in directional light's.

use glam::{Affine3A, Vec2, Vec3};
use lucent_accel::MeshOptions;
use lucent_render::{
    render, BsdfModel, BsdfSample, Camera, Film, Integrator, LightModel, LightSample, PathSettings, RenderSettings, World,
};
use lucent_scene::{CameraDesc, Geom, Instance, Light, LightKind, Material, Mesh, Scene, ShapeKind};
use std::f32::consts::{FRAC_1_PI, PI};
use std::sync::Arc;

#[derive(Debug)]
struct Lambert(Vec3);

impl BsdfModel for Lambert {
    fn eval(&self, wo: Vec3, wi: Vec3, _uv: Vec2) -> Vec3 {
        if wo.z > 0.0 && wi.z > 0.0 {
            self.0 * (wi.z * FRAC_1_PI)
        } else {
            Vec3::ZERO
        }
    }
    fn pdf(&self, wo: Vec3, wi: Vec3, _uv: Vec2) -> f32 {
        if wo.z > 0.0 && wi.z > 0.0 {
            wi.z * FRAC_1_PI
        } else {
            0.0
        }
    }
    fn sample(&self, wo: Vec3, uv: Vec2, _u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        let wi = lucent_render::bsdf::cosine_hemisphere(u2);
        let pdf = self.pdf(wo, wi, uv);
        (pdf > 0.0).then(|| BsdfSample { wi, weight: self.eval(wo, wi, uv) / pdf, pdf, delta: false, eta: 1.0 })
    }
}

#[derive(Debug)]
struct Sun {
    toward: Vec3,
    half_angle: f32,
    radiance: Vec3,
}

impl LightModel for Sun {
    fn sample(&self, _p: Vec3, u: (f32, f32)) -> Option<LightSample> {
        let cos_max = self.half_angle.cos();
        let dir = lucent_render::sampling::uniform_cone(self.toward, cos_max, u);
        Some(LightSample { dir, dist: f32::INFINITY, li: self.radiance, pdf: 1.0 / (2.0 * PI * (1.0 - cos_max)), delta: false })
    }
    fn power(&self) -> f32 {
        1.0
    }
}

/// A floor and a sphere on it, grey diffuse.
fn scene(lights: Vec<Light>) -> Scene {
    let floor = Mesh {
        name: "floor".into(),
        positions: vec![Vec3::new(-5.0, 0.0, -5.0), Vec3::new(5.0, 0.0, -5.0), Vec3::new(5.0, 0.0, 5.0), Vec3::new(-5.0, 0.0, 5.0)],
        indices: vec![[0, 2, 1], [0, 3, 2]],
        material: vec![0, 0],
        ..Mesh::default()
    };
    let mut s =
        Scene { materials: vec![Material { diffuse: Vec3::new(0.6, 0.5, 0.4), ..Material::default() }], lights, ..Scene::default() };
    s.add_mesh(floor);
    s.instances.push(Instance {
        geom: Geom::Shape { kind: ShapeKind::Sphere, material: 0 },
        world_from_object: Affine3A::from_translation(Vec3::Y),
    });
    s
}

fn image(w: &World) -> Film {
    let desc =
        CameraDesc { eye: Vec3::new(0.0, 3.0, 6.0), look_at: Vec3::new(0.0, 0.8, 0.0), up: Vec3::Y, vfov_deg: 45.0, ortho_height: None };
    let st = RenderSettings { spp: 64, integrator: Integrator::Path(PathSettings::default()), ..RenderSettings::new(48, 36) };
    render(w, &Camera::new(&desc, 48, 36), &st, &|_| {}).0
}

fn mean(f: &Film) -> Vec3 {
    f.pixels.iter().copied().sum::<Vec3>() / f.pixels.len() as f32
}

const TO_SUN: Vec3 = Vec3::new(0.3, 0.8, 0.5);

fn directional() -> Vec<Light> {
    vec![Light { kind: LightKind::Directional { direction: -TO_SUN.normalize() }, color: Vec3::splat(2.0), inverse_square: false }]
}

#[test]
fn a_hand_written_lambertian_bsdf_renders_as_the_built_in_one() {
    let built_in = image(&World::new(scene(directional()), MeshOptions::default()).expect("world"));
    let mut w = World::new(scene(directional()), MeshOptions::default()).expect("world");
    assert!(w.set_bsdf(0, Arc::new(Lambert(Vec3::new(0.6, 0.5, 0.4)))));
    assert!(!w.set_bsdf(7, Arc::new(Lambert(Vec3::ONE))), "an index out of range is refused");
    let custom = image(&w);
    // The same samples, the same arithmetic up to rounding.
    let e = custom.rel_mse(&built_in).expect("same size");
    assert!(e < 1e-8, "relMSE {e}");
}

#[test]
fn a_small_sun_of_the_users_own_renders_as_a_directional_light() {
    let built_in = image(&World::new(scene(directional()), MeshOptions::default()).expect("world"));
    let mut w = World::new(scene(Vec::new()), MeshOptions::default()).expect("world");
    let half_angle = 0.01f32;
    // Radiance over the cone's solid angle giving the directional light's irradiance.
    let solid = 2.0 * PI * (1.0 - half_angle.cos());
    w.add_light(Arc::new(Sun { toward: TO_SUN.normalize(), half_angle, radiance: Vec3::splat(2.0 / solid) }));
    let custom = image(&w);
    let (a, b) = (mean(&custom), mean(&built_in));
    assert!(b.min_element() > 0.05, "{b}");
    assert!(((a - b).abs() / b).max_element() < 0.01, "user sun {a}, directional light {b}");
}
