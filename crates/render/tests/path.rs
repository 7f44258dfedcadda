//! The path tracer against closed-form answers (as pbrt-v4's integrator tests): inside a
//! closed diffuse sphere of albedo ρ that emits Le everywhere, every ray sees
//! L = Le / (1 − ρ); lit instead by a point light of intensity I at its centre, every ray
//! sees L = ρ I / (π R² (1 − ρ)). The strategies (next-event estimation only, BSDF
//! sampling only, both by MIS) converge to the same image; images do not depend on the
//! thread count.

mod common;
use common::scene;
use glam::{Affine3A, Vec3};
use lucent_accel::{closed::ClosedMesh, MeshOptions};
use lucent_render::{render, Camera, Film, Integrator, LightSampling, PathSettings, RenderSettings, World};
use lucent_scene::{CameraDesc, Geom, Instance, Light, LightKind, Material, Mesh, Scene};

/// A closed sphere of radius 1 around the origin (an icosphere of 5,120 triangles), wound
/// so its normals point inward (the emitting side faces the centre).
fn inside_sphere(albedo: f32, emission: f32) -> Scene {
    let s = ClosedMesh::sphere(4);
    let mesh = Mesh {
        name: "sphere".into(),
        indices: s.indices.iter().map(|&[a, b, c]| [a, c, b]).collect(),
        material: vec![0; s.indices.len()],
        positions: s.positions,
        ..Mesh::default()
    };
    Scene {
        meshes: vec![mesh],
        instances: vec![Instance { geom: Geom::Mesh(0), world_from_object: Affine3A::IDENTITY }],
        materials: vec![Material { diffuse: Vec3::splat(albedo), emission: Vec3::splat(emission), ..Material::default() }],
        ..Scene::default()
    }
}

fn path(sampling: LightSampling) -> Integrator {
    Integrator::Path(PathSettings { sampling, ..PathSettings::default() })
}

fn image(s: Scene, cam: &CameraDesc, (w, h): (u32, u32), spp: u32, integrator: Integrator) -> Film {
    let world = World::new(s, MeshOptions::default()).expect("world");
    render(&world, &Camera::new(cam, w, h), &RenderSettings { spp, integrator, ..RenderSettings::new(w, h) }, &|_| {}).0
}

fn mean(f: &Film) -> Vec3 {
    f.pixels.iter().copied().sum::<Vec3>() / f.pixels.len() as f32
}

const CENTRE: CameraDesc = CameraDesc { eye: Vec3::ZERO, look_at: Vec3::Z, up: Vec3::Y, vfov_deg: 90.0, ortho_height: None };

#[test]
fn emitting_sphere_seen_from_inside_has_radiance_le_over_one_minus_albedo() {
    for sampling in [LightSampling::Mis, LightSampling::Nee, LightSampling::Bsdf] {
        let f = image(inside_sphere(0.5, 0.5), &CENTRE, (24, 24), 64, path(sampling));
        let m = mean(&f);
        assert!((m - Vec3::ONE).abs().max_element() < 0.025, "{sampling:?}: mean radiance {m}, want 1");
    }
    // Direct emission only (one segment), then one bounce more.
    let one = Integrator::Path(PathSettings { max_depth: 1, ..PathSettings::default() });
    assert!((mean(&image(inside_sphere(0.5, 0.5), &CENTRE, (16, 16), 4, one)) - Vec3::splat(0.5)).abs().max_element() < 1e-4);
    let two = Integrator::Path(PathSettings { max_depth: 2, ..PathSettings::default() });
    let m2 = mean(&image(inside_sphere(0.5, 0.5), &CENTRE, (24, 24), 64, two));
    assert!((m2 - Vec3::splat(0.75)).abs().max_element() < 0.02, "two segments: {m2}, want 0.75");
}

#[test]
fn point_light_at_the_centre_gives_the_closed_form() {
    let (rho, r) = (0.5f32, 1.0f32);
    // I such that L = ρ I / (π R² (1 − ρ)) = 1 (the facets' distance from the centre is
    // within 0.2% of R).
    let intensity = std::f32::consts::PI * r * r * (1.0 - rho) / rho;
    let mut s = inside_sphere(rho, 0.0);
    s.lights.push(Light { kind: LightKind::Point { position: Vec3::ZERO }, color: Vec3::splat(intensity), inverse_square: true });
    let m = mean(&image(s, &CENTRE, (24, 24), 64, path(LightSampling::Mis)));
    assert!((m - Vec3::ONE).abs().max_element() < 0.025, "mean radiance {m}, want 1");
}

/// The rays a render sends are recorded whole (rays alone, packets and blocks: the path
/// tracer's, Whitted's and the VPL tiles' kinds) and traced again with the same answers:
/// inside the closed sphere every closest-hit ray hits and no shadow ray toward the light
/// at its centre (or between two points of the sphere) is blocked; with a light outside
/// the sphere every shadow ray is.
#[test]
fn recorded_rays_are_the_rays_traced() {
    let whitted = Integrator::Whitted(lucent_render::WhittedSettings::default());
    // (One set, so that a VPL's rays from a tile fill packets.)
    let vpl = Integrator::Vpl(lucent_render::VplSettings { interleave: 1, ..lucent_render::VplSettings::default() });
    let outside = Vec3::new(0.0, 3.0, 0.0);
    let mut kinds = [0usize; 5];
    for (light, integrator) in [
        (Vec3::ZERO, path(LightSampling::Mis)),
        (Vec3::ZERO, whitted),
        (Vec3::ZERO, vpl),
        (outside, path(LightSampling::Mis)),
        (outside, whitted),
    ] {
        let mut s = inside_sphere(0.5, 0.0);
        s.lights.push(Light { kind: LightKind::Point { position: light }, color: Vec3::ONE, inverse_square: true });
        let world = World::new(s, MeshOptions::default()).expect("world");
        let cam = Camera::new(&CENTRE, 16, 16);
        let settings = RenderSettings { spp: 4, integrator, ..RenderSettings::new(16, 16) };
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
        let ((_, traced), rays) = one.install(|| lucent_render::record_rays(|| render(&world, &cam, &settings, &|_| {})));
        assert_eq!(rays.rays(), traced, "{integrator:?}: every ray recorded");
        for (k, n) in kinds.iter_mut().zip([
            rays.closest.len(),
            rays.shadow.len(),
            rays.closest_packets.len(),
            rays.shadow_packets.len(),
            rays.shadow_blocks.len(),
        ]) {
            *k += n;
        }
        let closest = (rays.closest.len() + rays.closest_packets.iter().map(|p| p.0.len()).sum::<usize>()) as u64;
        let shadow = traced - closest;
        assert!(closest >= 256 && shadow >= 256, "{integrator:?}: {closest} closest-hit and {shadow} shadow rays");
        let blocked = if light == outside { shadow } else { 0 };
        assert_eq!(rays.trace(&world), closest + blocked, "{integrator:?}, light at {light}");
    }
    assert!(kinds.iter().all(|&n| n > 0), "every kind of query recorded: {kinds:?}");
}

/// On the Cornell box (an area light, diffuse walls), next-event estimation alone, BSDF
/// sampling alone and their MIS combination agree: the same mean, and the same radiance in
/// each 16×16 block of the image within the noise of 256 samples (1,024 for BSDF sampling
/// alone, which finds the small light rarely: its noise sets the tolerance).
#[test]
fn strategies_agree_on_the_cornell_box() {
    let cam = CameraDesc::from_view(&[278.0, 273.0, -800.0, 278.0, 273.0, 0.0, 0.0, 1.0, 0.0, 39.3]);
    let load = || lucent_scene::load(&scene("cornell_box/cornell_box.obj")).expect("cornell");
    let (w, h) = (32, 32);
    // (BSDF sampling alone meets the small light rarely: four times the samples.)
    let imgs: Vec<Film> = [(LightSampling::Mis, 256), (LightSampling::Nee, 256), (LightSampling::Bsdf, 1024)]
        .into_iter()
        .map(|(s, spp)| image(load(), &cam, (w, h), spp, path(s)))
        .collect();
    let blocks = |f: &Film| -> Vec<Vec3> {
        (0..4)
            .map(|b| {
                let (bx, by) = (b % 2 * 16, b / 2 * 16);
                (0..256).map(|i| f.get(bx + i % 16, by + i / 16)).sum::<Vec3>() / 256.0
            })
            .collect()
    };
    let reference = blocks(&imgs[0]);
    let m0 = mean(&imgs[0]);
    assert!(m0.min_element() > 0.05, "the box is lit: {m0}");
    for (name, img) in [("nee", &imgs[1]), ("bsdf", &imgs[2])] {
        let m = mean(img);
        assert!(((m - m0) / m0).abs().max_element() < 0.03, "{name}: mean {m} against MIS {m0}");
        for (k, (a, b)) in blocks(img).iter().zip(&reference).enumerate() {
            let rel = ((*a - *b).abs() / (b.max(Vec3::splat(0.05)))).max_element();
            eprintln!("{name}: block {k}: {rel:.3}");
            assert!(rel < 0.1, "{name}: block {k}: {a} against MIS {b}");
        }
    }
}

#[test]
fn path_traced_images_do_not_depend_on_thread_count_or_packets() {
    let cam = CameraDesc::from_view(&[278.0, 273.0, -800.0, 278.0, 273.0, 0.0, 0.0, 1.0, 0.0, 39.3]);
    let world =
        World::new(lucent_scene::load(&scene("cornell_box/cornell_box.obj")).expect("cornell"), MeshOptions::default()).expect("world");
    let st = RenderSettings { spp: 4, integrator: path(LightSampling::Mis), ..RenderSettings::new(40, 30) };
    let c = Camera::new(&cam, 40, 30);
    let run = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().expect("pool").install(|| render(&world, &c, &st, &|_| {}).0);
    let (one, two) = (run(1), run(2));
    assert!(one.pixels.iter().zip(&two.pixels).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)));
    // Camera rays traced as packets (the default) or one by one: the same image.
    let single = render(&world, &c, &RenderSettings { traversal: lucent_render::Traversal { packets: false }, ..st }, &|_| {}).0;
    assert!(one.pixels.iter().zip(&single.pixels).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)));
    // And every pixel is the single-ray reference's.
    for (x, y) in [(0, 0), (20, 15), (39, 29), (7, 22)] {
        assert_eq!(one.get(x, y), lucent_render::render_pixel(&world, &c, &st, x, y));
    }
}
