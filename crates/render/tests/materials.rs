//! Material features by content, path traced: alpha masks cut surfaces out, normal maps
//! bend the shading normal, emission textures colour emitters.

use glam::{Affine3A, Vec2, Vec3};
use lucent_accel::MeshOptions;
use lucent_render::{render, Camera, Film, Integrator, PathSettings, RenderSettings, World};
use lucent_scene::{Alpha, Attr, CameraDesc, Light, LightKind, Material, Mesh, NormalMap, Scene, Texture, Wrap};

/// A quad in the z = `z` plane over [-1, 1]², facing +z, texture coordinates 0..1 (u along
/// +x, v along +y).
fn quad(z: f32, material: u32) -> Mesh {
    Mesh {
        name: "quad".into(),
        positions: vec![Vec3::new(-1.0, -1.0, z), Vec3::new(1.0, -1.0, z), Vec3::new(1.0, 1.0, z), Vec3::new(-1.0, 1.0, z)],
        indices: vec![[0, 1, 2], [0, 2, 3]],
        uvs: Attr { values: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y], indices: None },
        material: vec![material; 2],
        ..Mesh::default()
    }
}

/// Looking down −z at the origin, the quad filling the middle of the image.
fn image(s: Scene, spp: u32) -> Film {
    let desc = CameraDesc { eye: Vec3::new(0.0, 0.0, 4.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov_deg: 20.0, ortho_height: None };
    let world = World::new(s, MeshOptions::default()).expect("world");
    let st = RenderSettings { spp, integrator: Integrator::Path(PathSettings::default()), ..RenderSettings::new(32, 32) };
    render(&world, &Camera::new(&desc, 32, 32), &st, &|_| {}).0
}

fn at(f: &Film, x: u32, y: u32) -> Vec3 {
    f.pixels[(y * f.width + x) as usize]
}

#[test]
fn an_alpha_mask_cuts_the_surface_out() {
    // A black quad whose left half has alpha 0, in front of a white emitting wall.
    let tex = Texture::new(
        "mask".into(),
        4,
        1,
        vec![[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 255], [0, 0, 0, 255]],
        false,
        Wrap::Clamp,
        Wrap::Clamp,
    );
    let black = Material { diffuse: Vec3::ZERO, alpha: Alpha::Mask { cutoff: 0.5, tex: Some(0), factor: 1.0 }, ..Material::default() };
    let wall = Material { diffuse: Vec3::ZERO, emission: Vec3::ONE, ..Material::default() };
    let mut s = Scene { materials: vec![black, wall], textures: vec![tex], ..Scene::default() };
    s.add_mesh(quad(0.0, 0));
    let mut back = quad(-1.0, 1);
    back.positions.iter_mut().for_each(|p| *p *= Vec3::new(3.0, 3.0, 1.0));
    s.add_mesh(back);
    let f = image(s, 4);
    // Through the cut-out half: the wall; on the solid half: the black quad.
    assert!((at(&f, 12, 16) - Vec3::ONE).abs().max_element() < 1e-3, "{}", at(&f, 12, 16));
    assert!(at(&f, 20, 16).max_element() < 1e-3, "{}", at(&f, 20, 16));
}

#[test]
fn a_normal_map_bends_the_shading_normal() {
    // A white diffuse quad under a directional light 30° off the normal toward +x; the map
    // tilts every normal to (0.6, 0, 0.8): radiance ρ E cos / π with the bent cosine.
    let texel = [204, 128, 230, 255]; // (0.8, 0.5, 0.9) → (0.6, 0.004, 0.804) in tangent space
    let map = Texture::new("normals".into(), 1, 1, vec![texel], false, Wrap::Repeat, Wrap::Repeat);
    let mat = |normal_map| Material { diffuse: Vec3::splat(0.5), normal_map, ..Material::default() };
    let l = Vec3::new(30f32.to_radians().sin(), 0.0, 30f32.to_radians().cos());
    let light = Light { kind: LightKind::Directional { direction: -l }, color: Vec3::splat(2.0), inverse_square: false };
    let radiance = |normal_map: Option<NormalMap>| {
        let mut s = Scene { materials: vec![mat(normal_map)], textures: vec![map.clone()], lights: vec![light], ..Scene::default() };
        s.add_mesh(quad(0.0, 0));
        // (Direct light only: one bounce off the quad.)
        let desc = CameraDesc { eye: Vec3::new(0.0, 0.0, 4.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov_deg: 20.0, ortho_height: None };
        let world = World::new(s, MeshOptions::default()).expect("world");
        let st = RenderSettings {
            spp: 1,
            integrator: Integrator::Path(PathSettings { max_depth: 2, ..PathSettings::default() }),
            ..RenderSettings::new(16, 16)
        };
        at(&render(&world, &Camera::new(&desc, 16, 16), &st, &|_| {}).0, 8, 8).x
    };
    let n = Vec3::new(2.0 * 204.0 / 255.0 - 1.0, 2.0 * 128.0 / 255.0 - 1.0, 2.0 * 230.0 / 255.0 - 1.0).normalize();
    let want = |cos: f32| 0.5 * 2.0 * cos * std::f32::consts::FRAC_1_PI;
    let (flat, bent) = (radiance(None), radiance(Some(NormalMap::gltf(0, 1.0))));
    assert!((flat - want(l.z)).abs() < 1e-4 * want(l.z) + 1e-6, "flat {flat}, want {}", want(l.z));
    assert!((bent - want(n.dot(l))).abs() < 2e-3 * want(n.dot(l)), "bent {bent}, want {}", want(n.dot(l)));
}

#[test]
fn an_emission_texture_colours_the_emitter() {
    let tex = Texture::new("em".into(), 2, 1, vec![[255, 0, 0, 255], [0, 255, 0, 255]], false, Wrap::Clamp, Wrap::Clamp);
    let m = Material { diffuse: Vec3::ZERO, emission: Vec3::splat(2.0), emission_tex: Some(0), ..Material::default() };
    let mut s = Scene { materials: vec![m], textures: vec![tex], ..Scene::default() };
    s.add_mesh(quad(0.0, 0));
    s.instances[0].world_from_object = Affine3A::IDENTITY;
    let f = image(s, 1);
    // (Away from the middle, where the two texels blend.)
    let (left, right) = (at(&f, 2, 16), at(&f, 29, 16));
    assert!(left.x > 1.5 && left.y < 0.5, "{left}");
    assert!(right.y > 1.5 && right.x < 0.5, "{right}");
}
