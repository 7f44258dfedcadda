//! The built-in demo scene (compiled in): a checkered floor texture, a mirror sphere, a
//! glass sphere, a capped cylinder and cone, a triangle mesh (a torus) and two lights.

use crate::camera::CameraDesc;
use crate::model::{Attr, Geom, Instance, Light, LightKind, Material, Mesh, Scene, ShapeKind};
use crate::texture::Texture;
use crate::texture::Wrap;
use glam::{Affine3A, Quat, Vec2, Vec3};

/// Builds the demo scene.
#[must_use]
pub fn demo_scene() -> Scene {
    let mut s = Scene { ambient: Vec3::splat(0.08), background: Vec3::new(0.25, 0.35, 0.55), ..Scene::default() };
    // Texture: 8x8 checker, 64 texels a square.
    let n = 512u32;
    let texels = (0..n * n)
        .map(|i| {
            let (x, y) = (i % n / 64, i / n / 64);
            // Linear codes: 0.85, 0.85, 0.80 and 0.12, 0.12, 0.14 to within 1/510.
            if (x + y) % 2 == 0 {
                [217, 217, 204, 255]
            } else {
                [31, 31, 36, 255]
            }
        })
        .collect();
    s.textures.push(Texture::new("checker".into(), n, n, texels, false, Wrap::Repeat, Wrap::Repeat));
    let mat = |s: &mut Scene, m: Material| {
        s.materials.push(m);
        (s.materials.len() - 1) as u32
    };
    let floor = mat(
        &mut s,
        Material {
            name: "floor".into(),
            diffuse: Vec3::ONE,
            diffuse_tex: Some(0),
            specular: Vec3::splat(0.1),
            shininess: 20.0,
            ..Material::default()
        },
    );
    let mirror = mat(
        &mut s,
        Material {
            name: "mirror".into(),
            diffuse: Vec3::splat(0.05),
            specular: Vec3::splat(0.8),
            shininess: 200.0,
            reflect: Vec3::splat(0.9),
            ..Material::default()
        },
    );
    let glass = mat(
        &mut s,
        Material {
            name: "glass".into(),
            diffuse: Vec3::ZERO,
            specular: Vec3::splat(0.8),
            shininess: 300.0,
            transmit: Vec3::ONE,
            ior: 1.5,
            fresnel: true,
            ..Material::default()
        },
    );
    let red = mat(
        &mut s,
        Material {
            name: "red".into(),
            diffuse: Vec3::new(0.8, 0.1, 0.08),
            specular: Vec3::splat(0.3),
            shininess: 40.0,
            ..Material::default()
        },
    );
    let blue = mat(
        &mut s,
        Material {
            name: "blue".into(),
            diffuse: Vec3::new(0.1, 0.2, 0.8),
            specular: Vec3::splat(0.3),
            shininess: 40.0,
            ..Material::default()
        },
    );
    let gold = mat(
        &mut s,
        Material {
            name: "gold".into(),
            diffuse: Vec3::new(0.8, 0.6, 0.15),
            specular: Vec3::splat(0.5),
            shininess: 60.0,
            reflect: Vec3::new(0.25, 0.2, 0.05),
            ..Material::default()
        },
    );

    // Floor: two triangles, 20 x 20, uv repeating 4 times.
    let h = 10.0;
    let floor_mesh = Mesh {
        name: "floor".into(),
        positions: vec![Vec3::new(-h, 0.0, -h), Vec3::new(h, 0.0, -h), Vec3::new(h, 0.0, h), Vec3::new(-h, 0.0, h)],
        indices: vec![[0, 2, 1], [0, 3, 2]],
        normals: Attr::default(),
        uvs: Attr { values: vec![Vec2::new(0.0, 0.0), Vec2::new(4.0, 0.0), Vec2::new(4.0, 4.0), Vec2::new(0.0, 4.0)], indices: None },
        material: vec![floor, floor],
    };
    s.add_mesh(floor_mesh);
    s.add_mesh(torus(Vec3::new(2.6, 0.45, 1.2), 0.8, 0.3, 48, 24, gold));
    let place = |t: Vec3, r: Quat, sc: Vec3| Affine3A::from_scale_rotation_translation(sc, r, t);
    let upright = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2); // z axis -> y axis
    let shapes = [
        (ShapeKind::Sphere, mirror, place(Vec3::new(-1.2, 1.0, 0.0), Quat::IDENTITY, Vec3::ONE)),
        (ShapeKind::Sphere, glass, place(Vec3::new(0.9, 0.8, 1.8), Quat::IDENTITY, Vec3::splat(0.8))),
        (ShapeKind::CappedCylinder, red, place(Vec3::new(-3.4, 0.9, -1.0), upright, Vec3::new(0.6, 0.6, 0.9))),
        // Cone with its apex up: flip z before standing it up; base on the floor.
        (
            ShapeKind::CappedCone,
            blue,
            place(Vec3::new(1.6, 1.6, -1.6), Quat::from_rotation_x(std::f32::consts::FRAC_PI_2), Vec3::new(0.8, 0.8, 1.6)),
        ),
    ];
    for (kind, material, m) in shapes {
        s.instances.push(Instance { geom: Geom::Shape { kind, material }, world_from_object: m });
    }
    s.lights.push(Light {
        kind: LightKind::Point { position: Vec3::new(-4.0, 7.0, 5.0) },
        color: Vec3::new(0.75, 0.72, 0.65),
        inverse_square: false,
    });
    s.lights.push(Light {
        kind: LightKind::Point { position: Vec3::new(5.0, 5.0, 3.0) },
        color: Vec3::new(0.3, 0.32, 0.4),
        inverse_square: false,
    });
    s.camera = Some(CameraDesc {
        eye: Vec3::new(0.0, 3.2, 8.5),
        look_at: Vec3::new(0.0, 0.8, 0.0),
        up: Vec3::Y,
        vfov_deg: 45.0,
        ortho_height: None,
    });
    s
}

/// A torus around the y axis with smooth normals.
#[must_use]
pub fn torus(center: Vec3, major: f32, minor: f32, nu: u32, nv: u32, material: u32) -> Mesh {
    let mut m = Mesh { name: "torus".into(), ..Mesh::default() };
    let mut normals = Vec::new();
    for i in 0..nu {
        let a = i as f32 / nu as f32 * std::f32::consts::TAU;
        let dir = Vec3::new(a.cos(), 0.0, a.sin());
        for j in 0..nv {
            let b = j as f32 / nv as f32 * std::f32::consts::TAU;
            let n = dir * b.cos() + Vec3::Y * b.sin();
            m.positions.push(center + dir * major + n * minor);
            normals.push(n);
        }
    }
    for i in 0..nu {
        for j in 0..nv {
            let id = |i: u32, j: u32| (i % nu) * nv + (j % nv);
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            m.indices.push([a, c, b]);
            m.indices.push([a, d, c]);
        }
    }
    m.material = vec![material; m.indices.len()];
    m.normals = Attr { values: normals, indices: None };
    m
}

/// The path tracer's studio: a room of diffuse walls (red left, green right: their colour
/// bleeds onto the floor and the objects) lit by a rectangular area light in the ceiling
/// (soft shadows), holding a glass sphere, a polished gold sphere, a rough copper torus,
/// a blue rough-plastic sphere and a yellow plastic block on a checkered floor.
#[must_use]
pub fn studio_scene() -> Scene {
    use crate::bsdf::{named_conductor, Bsdf, ColorTex, Distribution, FloatTex, Rough, Sides};
    let mut s = Scene { materials: vec![Material::default()], ..Scene::default() };
    let mut mat = |m: Material| {
        s.materials.push(m);
        (s.materials.len() - 1) as u32
    };
    let diffuse = |name: &str, c: Vec3| Material::physical(name, Bsdf::Diffuse { reflectance: ColorTex::Const(c) });
    let white = mat(diffuse("white", Vec3::splat(0.75)));
    let red = mat(diffuse("red", Vec3::new(0.63, 0.065, 0.05)));
    let green = mat(diffuse("green", Vec3::new(0.14, 0.45, 0.09)));
    let floor = mat(Material::physical(
        "floor",
        Bsdf::Diffuse {
            reflectance: ColorTex::Checker {
                a: Vec3::splat(0.7),
                b: Vec3::splat(0.25),
                to_uv: glam::Affine2::from_scale(Vec2::splat(4.0)),
            },
        },
    ));
    let light = mat(Material { emission: Vec3::new(17.0, 12.0, 4.0), ..diffuse("light", Vec3::splat(0.78)) });
    let glass = mat(Material::physical(
        "glass",
        Bsdf::Dielectric { eta: 1.5, reflectance: ColorTex::grey(1.0), transmittance: ColorTex::grey(1.0), rough: None },
    ));
    let (au_eta, au_k) = named_conductor("Au").unwrap_or((Vec3::ONE, Vec3::ONE));
    let gold = mat(Material::physical(
        "gold",
        Bsdf::Conductor {
            eta: au_eta,
            k: au_k,
            specular: ColorTex::grey(1.0),
            rough: Some(Rough::isotropic(Distribution::Ggx, FloatTex::Const(0.05))),
        },
    ));
    let (cu_eta, cu_k) = named_conductor("Cu").unwrap_or((Vec3::ONE, Vec3::ONE));
    let copper = mat(Material::physical(
        "copper",
        Bsdf::Conductor {
            eta: cu_eta,
            k: cu_k,
            specular: ColorTex::grey(1.0),
            rough: Some(Rough::isotropic(Distribution::Ggx, FloatTex::Const(0.3))),
        },
    ));
    let blue = mat(Material::physical(
        "blue plastic",
        Bsdf::Plastic {
            diffuse: ColorTex::Const(Vec3::new(0.1, 0.2, 0.6)),
            specular: ColorTex::grey(1.0),
            eta: 1.49,
            nonlinear: false,
            rough: Some((Distribution::Ggx, 0.15)),
        },
    ));
    let block = mat(Material::physical(
        "yellow plastic",
        Bsdf::Plastic {
            diffuse: ColorTex::Const(Vec3::new(0.8, 0.6, 0.15)),
            specular: ColorTex::grey(1.0),
            eta: 1.49,
            nonlinear: false,
            rough: None,
        },
    ));
    for m in [white, red, green, floor] {
        s.materials[m as usize].sides = Sides::Both;
    }
    // The room: x in [-2, 2], y in [0, 3], z in [-2, 2], open toward +z.
    let quad = |name: &str, p: [Vec3; 4], material: u32| Mesh {
        name: name.into(),
        positions: p.to_vec(),
        indices: vec![[0, 1, 2], [0, 2, 3]],
        uvs: Attr { values: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y], indices: None },
        material: vec![material; 2],
        ..Mesh::default()
    };
    let v = Vec3::new;
    s.add_mesh(quad("floor", [v(-2.0, 0.0, 2.0), v(2.0, 0.0, 2.0), v(2.0, 0.0, -2.0), v(-2.0, 0.0, -2.0)], floor));
    s.add_mesh(quad("ceiling", [v(-2.0, 3.0, -2.0), v(2.0, 3.0, -2.0), v(2.0, 3.0, 2.0), v(-2.0, 3.0, 2.0)], white));
    s.add_mesh(quad("back", [v(-2.0, 0.0, -2.0), v(2.0, 0.0, -2.0), v(2.0, 3.0, -2.0), v(-2.0, 3.0, -2.0)], white));
    s.add_mesh(quad("left", [v(-2.0, 0.0, 2.0), v(-2.0, 0.0, -2.0), v(-2.0, 3.0, -2.0), v(-2.0, 3.0, 2.0)], red));
    s.add_mesh(quad("right", [v(2.0, 0.0, -2.0), v(2.0, 0.0, 2.0), v(2.0, 3.0, 2.0), v(2.0, 3.0, -2.0)], green));
    // The light faces down, just below the ceiling.
    s.add_mesh(quad("light", [v(-0.6, 2.99, -0.6), v(0.6, 2.99, -0.6), v(0.6, 2.99, 0.6), v(-0.6, 2.99, 0.6)], light));
    s.add_mesh(torus(Vec3::new(0.9, 0.2, 0.9), 0.45, 0.2, 48, 24, copper));
    let place = |t: Vec3, sc: Vec3| Affine3A::from_scale_rotation_translation(sc, Quat::IDENTITY, t);
    let shapes = [
        (ShapeKind::Sphere, glass, place(v(-0.2, 0.55, 0.8), Vec3::splat(0.55))),
        (ShapeKind::Sphere, gold, place(v(-1.1, 0.6, -0.6), Vec3::splat(0.6))),
        (ShapeKind::Sphere, blue, place(v(1.2, 0.45, -0.9), Vec3::splat(0.45))),
        (
            ShapeKind::Box,
            block,
            Affine3A::from_scale_rotation_translation(Vec3::new(0.35, 0.7, 0.35), Quat::from_rotation_y(0.5), v(0.1, 0.7, -1.3)),
        ),
    ];
    for (kind, material, m) in shapes {
        s.instances.push(Instance { geom: Geom::Shape { kind, material }, world_from_object: m });
    }
    s.camera = Some(CameraDesc { eye: v(0.0, 1.5, 6.2), look_at: v(0.0, 1.2, 0.0), up: Vec3::Y, vfov_deg: 36.0, ortho_height: None });
    // A few seconds on two cores (flags override it).
    s.hints = Some(crate::model::RenderHints {
        width: 640,
        height: 480,
        spp: 16,
        max_depth: None,
        rr_depth: 5,
        hide_emitters: false,
        lens: None,
        clip: (0.0, f32::INFINITY),
        filter: crate::model::PixelFilter::Box,
        crop: None,
        strategies: crate::model::Strategies::Both,
    });
    s
}
