//! The built-in instancing scene of SaarCOR's SunCOR demo: a field of 5,622 sunflowers,
//! one procedurally generated plant of about 32,000 triangles instanced 5,622 times (about
//! 180 million triangles), swaying in the wind. Memory follows the unique geometry: one
//! mesh, one bottom-level BVH, and a transform per flower.
//!
//! The flower head's seeds follow Vogel's model of the sunflower spiral (H. Vogel, "A
//! better way to construct the sunflower head", Mathematical Biosciences 44, 1979): seed
//! `i` at radius `c·√i` and angle `i·137.508°`.

use crate::anim::{Channel, Interp, Node, SceneAnimation, Target};
use crate::camera::CameraDesc;
use crate::model::{Geom, Instance, Light, LightKind, Material, Mesh, Scene};
use glam::{Affine3A, Quat, Vec3};
use std::sync::Arc;

/// Flowers in the field (SunCOR's count).
pub const FLOWERS: usize = 5_622;

/// Seeds in a flower head.
const SEEDS: usize = 3_200;

struct Builder {
    mesh: Mesh,
}

impl Builder {
    fn tri(&mut self, a: Vec3, b: Vec3, c: Vec3, mat: u32) {
        let i = self.mesh.positions.len() as u32;
        self.mesh.positions.extend([a, b, c]);
        self.mesh.indices.push([i, i + 1, i + 2]);
        self.mesh.material.push(mat);
    }

    /// A grid of `nu` × `nv` quads over `f(u, v)`, u and v in [0, 1].
    fn sheet(&mut self, nu: usize, nv: usize, mat: u32, f: impl Fn(f32, f32) -> Vec3) {
        let base = self.mesh.positions.len() as u32;
        for j in 0..=nv {
            for i in 0..=nu {
                self.mesh.positions.push(f(i as f32 / nu as f32, j as f32 / nv as f32));
            }
        }
        let w = nu as u32 + 1;
        for j in 0..nv as u32 {
            for i in 0..nu as u32 {
                let a = base + j * w + i;
                self.mesh.indices.push([a, a + 1, a + w]);
                self.mesh.indices.push([a + 1, a + w + 1, a + w]);
                self.mesh.material.extend([mat, mat]);
            }
        }
    }
}

/// One sunflower plant, base at the origin, y up, head facing +z.
#[must_use]
pub fn sunflower_mesh() -> Mesh {
    let mut b = Builder { mesh: Mesh { name: "sunflower".into(), ..Mesh::default() } };
    let (stem, leaf, petal, seed, back) = (1, 2, 3, 4, 5);
    let tau = std::f32::consts::TAU;
    // Stem: a slightly bending tube.
    let height = 2.2f32;
    let bend = |y: f32| Vec3::new(0.0, y, 0.12 * (y / height).powi(2));
    b.sheet(24, 40, stem, |u, v| {
        let a = u * tau;
        let r = 0.045 * (1.0 - 0.3 * v);
        bend(v * height) + Vec3::new(r * a.cos(), 0.0, r * a.sin())
    });
    // Leaves: eight along the stem, each a cupped ellipse.
    for k in 0..8 {
        let y = 0.4 + 0.2 * k as f32;
        let dir = k as f32 * 2.4;
        let (s, c) = dir.sin_cos();
        let out = Vec3::new(c, 0.0, s);
        let side = Vec3::new(-s, 0.0, c);
        let base = bend(y);
        let len = 0.55 - 0.03 * k as f32;
        b.sheet(12, 6, leaf, |u, v| {
            let w = 0.22 * len * (std::f32::consts::PI * u).sin() * (2.0 * v - 1.0);
            let droop = -0.35 * len * u * u + 0.12 * len * u;
            base + out * (u * len) + side * w + Vec3::new(0.0, droop + 0.05 * w.abs(), 0.0)
        });
    }
    // Head: a frame facing +z, tilted a little up.
    let centre = bend(height) + Vec3::new(0.0, 0.12, 0.1);
    let n = Vec3::new(0.0, 0.25, 1.0).normalize();
    let e1 = Vec3::X;
    let e2 = n.cross(e1).normalize();
    let radius = 0.34f32;
    // Back of the head: a shallow cone.
    b.sheet(64, 4, back, |u, v| {
        let a = u * tau;
        let r = radius * (0.15 + 0.85 * v) * 1.02;
        centre + (e1 * a.cos() + e2 * a.sin()) * r - n * (0.08 * (1.0 - v) + 0.01)
    });
    // Seeds: Vogel's spiral, each an octagonal cap on a slight dome.
    let c = radius / (SEEDS as f32).sqrt();
    let golden = 137.507_76f32.to_radians();
    for i in 0..SEEDS {
        let r = c * (i as f32 + 0.5).sqrt();
        let a = i as f32 * golden;
        let dome = 0.04 * (1.0 - (r / radius).powi(2));
        let p = centre + (e1 * a.cos() + e2 * a.sin()) * r + n * dome;
        let top = p + n * 0.012;
        let rs = c * 0.8;
        for k in 0..8 {
            let (a0, a1) = (k as f32 / 8.0 * tau, (k + 1) as f32 / 8.0 * tau);
            let q0 = p + (e1 * a0.cos() + e2 * a0.sin()) * rs;
            let q1 = p + (e1 * a1.cos() + e2 * a1.sin()) * rs;
            b.tri(top, q0, q1, seed);
        }
    }
    // Petals: 34 around the rim, curving back.
    for k in 0..34 {
        let a = k as f32 / 34.0 * tau + if k % 2 == 0 { 0.0 } else { 0.05 };
        let dir = e1 * a.cos() + e2 * a.sin();
        let side = n.cross(dir);
        let len = 0.42 + 0.05 * ((k * 7) % 5) as f32 / 5.0;
        b.sheet(10, 4, petal, |u, v| {
            let w = 0.075 * (std::f32::consts::PI * (0.15 + 0.85 * u)).sin() * (2.0 * v - 1.0);
            centre + dir * (radius * 0.95 + u * len) + side * w - n * (0.12 * u * u + 0.02 * (k % 2) as f32)
        });
    }
    b.mesh
}

/// The field: `FLOWERS` flowers on a jittered grid, facing the sun, swaying over a
/// 4-second loop.
#[must_use]
pub fn sunflower_scene() -> Scene {
    let plant = sunflower_mesh();
    let ground = Mesh {
        name: "ground".into(),
        positions: vec![
            Vec3::new(-500.0, 0.0, -500.0),
            Vec3::new(500.0, 0.0, -500.0),
            Vec3::new(500.0, 0.0, 500.0),
            Vec3::new(-500.0, 0.0, 500.0),
        ],
        indices: vec![[0, 2, 1], [0, 3, 2]],
        material: vec![6, 6],
        ..Mesh::default()
    };
    let mat = |name: &str, d: Vec3, spec: f32| Material {
        name: name.into(),
        diffuse: d,
        specular: Vec3::splat(spec),
        shininess: 24.0,
        ..Material::default()
    };
    let materials = vec![
        Material::default(),
        mat("stem", Vec3::new(0.18, 0.42, 0.10), 0.05),
        mat("leaf", Vec3::new(0.16, 0.45, 0.12), 0.1),
        mat("petal", Vec3::new(0.95, 0.72, 0.08), 0.05),
        mat("seed", Vec3::new(0.22, 0.12, 0.05), 0.15),
        mat("head back", Vec3::new(0.25, 0.35, 0.10), 0.0),
        mat("ground", Vec3::new(0.30, 0.24, 0.14), 0.0),
    ];
    let side = (FLOWERS as f32).sqrt().ceil() as usize;
    let hash = |i: u32| {
        let mut x = i.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
        x = ((x >> ((x >> 28) + 4)) ^ x).wrapping_mul(277_803_737);
        ((x >> 22) ^ x) as f32 / u32::MAX as f32
    };
    let mut instances = vec![Instance { geom: Geom::Mesh(1), world_from_object: Affine3A::IDENTITY }];
    let mut nodes = vec![Node { parent: None, t: Vec3::ZERO, r: Quat::IDENTITY, s: Vec3::ONE }];
    let mut channels = Vec::new();
    let times: Vec<f32> = (0..=8).map(|k| k as f32 * 0.5).collect();
    for i in 0..FLOWERS {
        let (gx, gz) = ((i % side) as f32, (i / side) as f32);
        let x = (gx - side as f32 / 2.0) * 1.1 + (hash(3 * i as u32) - 0.5) * 0.6;
        let z = -(gz * 1.1) + (hash(3 * i as u32 + 1) - 0.5) * 0.6;
        let scale = 0.85 + 0.3 * hash(3 * i as u32 + 2);
        let yaw = (hash(7 * i as u32 + 5) - 0.5) * 0.5;
        let t = Vec3::new(x, 0.0, z);
        let r = Quat::from_rotation_y(yaw);
        let s = Vec3::splat(scale);
        instances.push(Instance { geom: Geom::Mesh(0), world_from_object: Affine3A::from_scale_rotation_translation(s, r, t) });
        let node = nodes.len() as u32;
        nodes.push(Node { parent: None, t, r, s });
        // Sway: a gust travelling across the field; the stem leans about its base.
        let phase = 0.35 * x + 0.2 * z;
        let mut values = Vec::with_capacity(4 * times.len());
        for &tk in &times {
            let lean = 0.06 * (tk * std::f32::consts::TAU / 4.0 + phase).sin();
            let q = Quat::from_rotation_x(lean) * Quat::from_rotation_z(0.4 * lean) * r;
            values.extend([q.x, q.y, q.z, q.w]);
        }
        channels.push(Channel { node, target: Target::Rotation, interp: Interp::Linear, times: times.clone(), values, width: 4 });
    }
    let instance_nodes: Vec<u32> = (0..instances.len() as u32).collect();
    let animation = SceneAnimation { nodes, channels, instance_nodes, ..SceneAnimation::default() };
    Scene {
        meshes: vec![plant, ground],
        instances,
        materials,
        lights: vec![Light {
            kind: LightKind::Directional { direction: Vec3::new(-0.3, -0.6, -0.75).normalize() },
            color: Vec3::splat(1.0),
            inverse_square: false,
        }],
        camera: Some(CameraDesc {
            eye: Vec3::new(-6.0, 5.0, 9.0),
            look_at: Vec3::new(3.0, 1.5, -12.0),
            up: Vec3::Y,
            vfov_deg: 50.0,
            ortho_height: None,
        }),
        ambient: Vec3::splat(0.25),
        background: Vec3::new(0.45, 0.65, 0.95),
        animation: Some(Arc::new(animation)),
        textures: Vec::new(),
        environment: None,
        hints: None,
        outputs: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_field_has_suncor_s_counts() {
        let m = sunflower_mesh();
        assert!(m.indices.len() >= 30_000, "{} triangles", m.indices.len());
        let s = sunflower_scene();
        assert_eq!(s.instances.len(), FLOWERS + 1);
        let st = s.stats();
        assert!(st.instanced_triangles >= 150_000_000, "{}", st.instanced_triangles);
        assert_eq!(st.meshes, 2, "one plant mesh, one ground");
        assert!(m.positions.iter().all(|p| p.is_finite()));
    }
}
