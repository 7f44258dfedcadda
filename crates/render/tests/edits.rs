//! Editing a world in place (new instance transforms, moved vertices, removed instances)
//! answers every ray as a world built afresh from the edited scene does.

use glam::{Affine3A, Vec3};
use lucent_accel::{MeshOptions, Ray};
use lucent_render::World;
use lucent_scene::{Geom, Instance, Mesh, Scene, ShapeKind};
use rand::{Rng, SeedableRng};

/// A grid of quads, a sphere and a second instance of the grid.
fn scene() -> Scene {
    let n = 8;
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for y in 0..=n {
        for x in 0..=n {
            positions.push(Vec3::new(x as f32 / n as f32 - 0.5, y as f32 / n as f32 - 0.5, 0.1 * ((x * y) % 3) as f32));
        }
    }
    for y in 0..n {
        for x in 0..n {
            let i = (y * (n + 1) + x) as u32;
            indices.push([i, i + 1, i + n as u32 + 2]);
            indices.push([i, i + n as u32 + 2, i + n as u32 + 1]);
        }
    }
    let mesh = Mesh { name: "grid".into(), positions, indices, ..Mesh::default() };
    Scene {
        meshes: vec![mesh],
        instances: vec![
            Instance { geom: Geom::Mesh(0), world_from_object: Affine3A::IDENTITY },
            Instance {
                geom: Geom::Shape { kind: ShapeKind::Sphere, material: 0 },
                world_from_object: Affine3A::from_scale_rotation_translation(
                    Vec3::splat(0.3),
                    glam::Quat::IDENTITY,
                    Vec3::new(0.0, 0.0, 1.0),
                ),
            },
            Instance { geom: Geom::Mesh(0), world_from_object: Affine3A::from_translation(Vec3::new(0.0, 0.0, -1.0)) },
        ],
        materials: vec![lucent_scene::Material::default()],
        ..Scene::default()
    }
}

/// Rays from above and below toward the scene, seeded.
fn rays() -> Vec<Ray> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    (0..4000)
        .map(|i| {
            let z = if i % 2 == 0 { 3.0 } else { -3.0 };
            let o = Vec3::new(rng.random_range(-0.6..0.6), rng.random_range(-0.6..0.6), z);
            let d = Vec3::new(rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1), -z.signum());
            Ray::new(o, d)
        })
        .collect()
}

/// The closest hits of `w` for `rays`, as comparable bits.
fn answers(w: &World, rays: &[Ray]) -> Vec<Option<(u32, u32, u32)>> {
    rays.iter().map(|r| w.intersect(r).map(|h| (h.t.to_bits(), h.prim, h.inst))).collect()
}

#[test]
fn moved_instances_answer_as_a_fresh_world() {
    let mut world = World::new(scene(), MeshOptions::default()).expect("world");
    let m1 = Affine3A::from_scale_rotation_translation(Vec3::splat(0.5), glam::Quat::from_rotation_x(0.3), Vec3::new(0.2, 0.1, 1.2));
    let m2 = Affine3A::from_rotation_z(0.7) * Affine3A::from_translation(Vec3::new(0.1, 0.0, -0.5));
    let before = answers(&world, &rays());
    world.set_instance_transforms(&[(1, m1), (2, m2)]).expect("moved");
    let mut edited = scene();
    edited.instances[1].world_from_object = m1;
    edited.instances[2].world_from_object = m2;
    let fresh = World::new(edited, MeshOptions::default()).expect("world");
    let after = answers(&world, &rays());
    assert_eq!(after, answers(&fresh, &rays()));
    assert_ne!(after, before, "the edit changed nothing");
    assert!(world.set_instance_transforms(&[(3, m1)]).is_err(), "an instance out of range");
    assert!(world.set_instance_transforms(&[(0, Affine3A::from_scale(Vec3::ZERO))]).is_err(), "a singular transform");
}

#[test]
fn moved_vertices_answer_as_a_fresh_world() {
    let mut world = World::new(scene(), MeshOptions::default()).expect("world");
    let mut edited = scene();
    let moved: Vec<Vec3> = edited.meshes[0].positions.iter().map(|p| Vec3::new(p.x * 1.2, p.y, p.z + 0.3 * p.x * p.x)).collect();
    world.set_mesh_positions(0, moved.clone(), None).expect("moved");
    edited.meshes[0].positions = moved;
    let fresh = World::new(edited, MeshOptions::default()).expect("world");
    // (A refit tree, not a fresh one: the same hits, ties apart, which these rays avoid.)
    assert_eq!(answers(&world, &rays()), answers(&fresh, &rays()));
    assert!(world.set_mesh_positions(0, vec![Vec3::ZERO; 3], None).is_err(), "a wrong vertex count");
    assert!(world.set_mesh_positions(1, Vec::new(), None).is_err(), "a mesh out of range");
}

#[test]
fn removed_instances_are_gone() {
    let mut world = World::new(scene(), MeshOptions::default()).expect("world");
    world.retain_instances(&[true, false, true]).expect("removed");
    let mut edited = scene();
    edited.instances.remove(1);
    let fresh = World::new(edited, MeshOptions::default()).expect("world");
    assert_eq!(answers(&world, &rays()), answers(&fresh, &rays()));
    assert_eq!(world.scene().instances.len(), 2);
    assert!(world.retain_instances(&[true]).is_err(), "a flag per instance");
}
