//! The screen coverage of primary rays ([`lucent_render::Coverage`]) is conservative: no
//! ray through an uncovered pixel (at its centre or anywhere in its square) hits anything,
//! for spheres under any affine map, boxes, capped shapes, disks and meshes, in front of,
//! around and behind the eye, under pinhole, viewport and orthographic cameras. It is
//! also tight for spheres in front of the eye.

use glam::{Affine3A, Quat, Vec3};
use lucent_accel::MeshOptions;
use lucent_render::{Camera, Coverage, World};
use lucent_scene::{CameraDesc, Geom, Instance, Material, Mesh, Scene, ShapeKind};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

fn random_map(rng: &mut Pcg64, spread: f32) -> Affine3A {
    let t = Vec3::new(rng.random_range(-spread..spread), rng.random_range(-spread..spread), rng.random_range(-spread..spread));
    let q = Quat::from_euler(glam::EulerRot::XYZ, rng.random_range(0.0..6.3), rng.random_range(0.0..6.3), rng.random_range(0.0..6.3));
    let s = Vec3::new(rng.random_range(0.05..1.5), rng.random_range(0.05..1.5), rng.random_range(0.05..1.5));
    // A shear now and then: any affine map, not only translate·rotate·scale.
    let shear = if rng.random_bool(0.3) {
        Affine3A::from_cols_array(&[1.0, 0.4, 0.0, 0.0, 1.0, 0.3, 0.2, 0.0, 1.0, 0.0, 0.0, 0.0])
    } else {
        Affine3A::IDENTITY
    };
    Affine3A::from_scale_rotation_translation(s, q, t) * shear
}

fn cube_mesh() -> Mesh {
    let positions: Vec<Vec3> = (0..8).map(|i| Vec3::new((i & 1) as f32, (i >> 1 & 1) as f32, (i >> 2 & 1) as f32) - 0.5).collect();
    let quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
    let indices = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect::<Vec<_>>();
    let n = indices.len();
    Mesh { name: "cube".into(), positions, indices, material: vec![0; n], ..Mesh::default() }
}

fn random_scene(rng: &mut Pcg64, n: usize, spheres_only: bool) -> Scene {
    let kinds = [ShapeKind::Sphere, ShapeKind::Box, ShapeKind::CappedCylinder, ShapeKind::CappedCone, ShapeKind::Disk];
    let mut s = Scene { materials: vec![Material::default()], meshes: vec![cube_mesh()], ..Scene::default() };
    for _ in 0..n {
        let geom = if spheres_only {
            Geom::Shape { kind: ShapeKind::Sphere, material: 0 }
        } else if rng.random_bool(0.2) {
            Geom::Mesh(0)
        } else {
            Geom::Shape { kind: kinds[rng.random_range(0..kinds.len())], material: 0 }
        };
        s.instances.push(Instance { geom, world_from_object: random_map(rng, 6.0) });
    }
    s
}

fn random_camera(rng: &mut Pcg64, w: u32, h: u32, kind: u32, among: bool) -> Camera {
    // Outside the objects, or among them (shapes then reach around the eye).
    let eye = if among {
        Vec3::new(rng.random_range(-4.0..4.0), rng.random_range(-4.0..4.0), rng.random_range(-4.0..4.0))
    } else {
        Vec3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), rng.random_range(4.0..12.0))
    };
    let look = Vec3::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
    match kind {
        0 => {
            Camera::new(&CameraDesc { eye, look_at: look, up: Vec3::Y, vfov_deg: rng.random_range(20.0..120.0), ortho_height: None }, w, h)
        }
        1 => Camera::new(
            &CameraDesc { eye, look_at: look, up: Vec3::Y, vfov_deg: 45.0, ortho_height: Some(rng.random_range(4.0..14.0)) },
            w,
            h,
        ),
        // REND3R's kind: an unnormalized frame with a near clip (and, here, axes that are
        // neither unit nor orthogonal).
        _ => {
            let f = (look - eye).normalize();
            let r = f.cross(Vec3::Y).normalize() * rng.random_range(0.8..1.2);
            let u = r.cross(f).normalize() + 0.2 * r;
            Camera::viewport(
                eye,
                r,
                u,
                f,
                rng.random_range(0.5..5.0),
                rng.random_range(0.4..3.75),
                rng.random_range(0.0..1.0),
                f32::INFINITY,
                w,
                h,
            )
        }
    }
}

/// Checks that every ray through an uncovered pixel misses, and that a covered pixel's
/// rays hit only instances its block lists (when it lists them); returns (covered, hit,
/// listed) pixel counts, hits at the pixel centres.
fn check(world: &World, cam: &Camera, w: u32, h: u32, what: &str) -> (u64, u64, u64) {
    check_centres(world, cam, w, h, what);
    let Some(cover) = Coverage::of(world, cam) else { return (u64::from(w * h), 0, 0) };
    let (mut hits, mut listed) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let centre = world.intersect(&cam.ray(x as f32 + 0.5, y as f32 + 0.5)).is_some();
            hits += centre as u64;
            if cover.covered(x, y) {
                if let Some(ids) = cover.candidates(x / 8, y / 8) {
                    listed += 1;
                    for (jx, jy) in [(0.5, 0.5), (0.0, 0.0), (0.999, 0.999), (0.0, 0.999), (0.999, 0.0)] {
                        if let Some(hit) = world.intersect(&cam.ray(x as f32 + jx, y as f32 + jy)) {
                            assert!(ids.contains(&hit.inst), "{what}: pixel {x},{y} hits instance {} not in {ids:?}", hit.inst);
                        }
                    }
                }
                continue;
            }
            for (jx, jy) in
                [(0.5, 0.5), (0.0, 0.0), (0.999, 0.0), (0.0, 0.999), (0.999, 0.999), (0.5, 0.0), (0.0, 0.5), (0.999, 0.5), (0.5, 0.999)]
            {
                let r = cam.ray(x as f32 + jx, y as f32 + jy);
                assert!(world.intersect(&r).is_none(), "{what}: pixel {x},{y} (+{jx},{jy}) is not covered but its ray hits");
            }
        }
    }
    (cover.count(), hits, listed)
}

/// [`Coverage::of_centres`]: the ray through an uncovered pixel's centre misses, a listed
/// block's centre rays hit only listed instances, and no more pixels are covered than by
/// [`Coverage::of`]. Returns the covered pixels.
fn check_centres(world: &World, cam: &Camera, w: u32, h: u32, what: &str) -> u64 {
    let Some(cover) = Coverage::of_centres(world, cam) else { return u64::from(w * h) };
    let squares = Coverage::of(world, cam).expect("the centres' coverage exists, so the squares' does");
    for y in 0..h {
        for x in 0..w {
            let hit = world.intersect(&cam.ray(x as f32 + 0.5, y as f32 + 0.5));
            if !cover.covered(x, y) {
                assert!(hit.is_none(), "{what}: pixel {x},{y}'s centre is not covered but its ray hits");
                continue;
            }
            assert!(squares.covered(x, y), "{what}: pixel {x},{y}: the centre is covered, the square not");
            if let (Some(ids), Some(hit)) = (cover.candidates(x / 8, y / 8), hit) {
                assert!(ids.contains(&hit.inst), "{what}: pixel {x},{y}'s centre hits instance {} not in {ids:?}", hit.inst);
            }
        }
    }
    cover.count()
}

#[test]
fn uncovered_pixels_never_hit() {
    let mut rng = Pcg64::seed_from_u64(7);
    let (w, h) = (64, 48);
    let (mut culled, mut listed) = (0, 0);
    for round in 0..80 {
        let n = rng.random_range(1..6);
        let scene = random_scene(&mut rng, n, false);
        let world = World::new(scene, MeshOptions::default()).expect("world");
        for kind in 0..6 {
            let cam = random_camera(&mut rng, w, h, kind % 3, kind >= 3);
            let (covered, _, l) = check(&world, &cam, w, h, &format!("round {round}, camera {kind}"));
            culled += u64::from(w * h) - covered;
            listed += l;
        }
    }
    assert!(culled > 80 * 6 * u64::from(w * h) / 4, "coverage culls little: {culled}");
    assert!(listed > 80 * 6 * u64::from(w * h) / 20, "few blocks list their instances: {listed} pixels");
}

#[test]
fn spheres_are_covered_tightly_and_safely() {
    let mut rng = Pcg64::seed_from_u64(11);
    let (w, h) = (96, 72);
    let (mut covered, mut hit, mut centres) = (0, 0, 0);
    for round in 0..40 {
        let scene = random_scene(&mut rng, 8, true);
        let world = World::new(scene, MeshOptions::default()).expect("world");
        for kind in [0, 2] {
            let cam = random_camera(&mut rng, w, h, kind, false);
            let (c, hh, _) = check(&world, &cam, w, h, &format!("round {round}, camera {kind}"));
            if Coverage::of(&world, &cam).is_some() {
                covered += c;
                hit += hh;
                centres += check_centres(&world, &cam, w, h, &format!("round {round}, camera {kind}, centres"));
            }
        }
    }
    // Ellipses filled row by row: a rim of about a pixel over the pixels that hit; for
    // centres, a rim of about a quarter pixel.
    assert!(hit > 10_000, "{hit}");
    assert!(covered < hit * 3 / 2, "covered {covered} for {hit} hits");
    assert!(centres < hit * 23 / 20, "centres covered {centres} for {hit} hits");
}

#[test]
fn unbounded_shapes_and_the_eye_inside_cover_everything() {
    let mut s = Scene { materials: vec![Material::default()], ..Scene::default() };
    s.instances.push(Instance { geom: Geom::Shape { kind: ShapeKind::Cylinder, material: 0 }, world_from_object: Affine3A::IDENTITY });
    let world = World::new(s, MeshOptions::default()).expect("world");
    let cam = Camera::new(
        &CameraDesc { eye: Vec3::new(0.0, 0.0, 9.0), look_at: Vec3::ZERO, up: Vec3::Y, vfov_deg: 40.0, ortho_height: None },
        32,
        32,
    );
    assert!(Coverage::of(&world, &cam).is_none());
    // The eye inside a large sphere: every direction meets it.
    let mut s = Scene { materials: vec![Material::default()], ..Scene::default() };
    s.instances.push(Instance {
        geom: Geom::Shape { kind: ShapeKind::Sphere, material: 0 },
        world_from_object: Affine3A::from_scale(Vec3::splat(50.0)),
    });
    let world = World::new(s, MeshOptions::default()).expect("world");
    assert!(Coverage::of(&world, &cam).is_none());
    // Everything behind the eye: nothing is covered.
    let mut s = Scene { materials: vec![Material::default()], ..Scene::default() };
    s.instances.push(Instance {
        geom: Geom::Shape { kind: ShapeKind::Box, material: 0 },
        world_from_object: Affine3A::from_translation(Vec3::new(0.0, 0.0, 20.0)),
    });
    let world = World::new(s, MeshOptions::default()).expect("world");
    assert_eq!(Coverage::of(&world, &cam).map(|c| c.count()), Some(0));
}
