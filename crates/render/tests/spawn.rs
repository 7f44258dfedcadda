//! Secondary rays leave their surfaces: a ray spawned from a hit ([`Surface::spawn`], its
//! origin moved off by the hit's floating-point error bound) never meets the surface it
//! left. Checked on real scenes (the demo's shapes and meshes, the Cornell box, Sponza) and
//! on the same scenes moved far from the origin, turned and scaled (instances with large
//! translations, where coordinates carry few fraction bits), for rays leaving at every
//! angle, grazing ones included. Without the offset, the same rays do meet their own
//! surfaces: the test can fail.

mod common;
use common::scene;
use glam::{Affine3A, Quat, Vec3};
use lucent_accel::{MeshOptions, Ray};
use lucent_render::{Camera, World};
use lucent_scene::{CameraDesc, Geom, Scene};

/// A small seeded generator (SplitMix64).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// The scene moved by `m` (every instance), with the camera moved along.
fn moved(mut s: Scene, m: Affine3A) -> Scene {
    for i in &mut s.instances {
        i.world_from_object = m * i.world_from_object;
    }
    s.camera = s.camera.map(|c| CameraDesc {
        eye: m.transform_point3(c.eye),
        look_at: m.transform_point3(c.look_at),
        up: m.transform_vector3(c.up),
        ..c
    });
    s
}

/// (rays spawned, rays that met the primitive they left) over camera hits of `s`, leaving
/// each hit in directions from grazing to straight out, on the side the camera ray came
/// from (and, for triangles, through to the other side too); `spawn` makes the rays.
fn self_hits(s: Scene, cam: CameraDesc, spawn: &dyn Fn(&lucent_render::Surface, Vec3) -> Ray) -> (u64, u64) {
    let w = World::new(s, MeshOptions::default()).expect("world");
    let c = Camera::new(&cam, 64, 48);
    let mut rng = Rng(7);
    let (mut n, mut bad) = (0, 0);
    for y in 0..48 {
        for x in 0..64 {
            let r = c.ray(x as f32 + 0.5, y as f32 + 0.5);
            let Some(h) = w.intersect(&r) else { continue };
            let surf = w.surface(&r, &h);
            if !surf.p_err.is_finite() || surf.ng == Vec3::ZERO {
                continue;
            }
            let facing = if r.dir.dot(surf.ng) < 0.0 { surf.ng } else { -surf.ng };
            // An orthonormal frame around the normal.
            let t = facing.any_orthonormal_vector();
            let b = facing.cross(t);
            let is_mesh = matches!(w.scene().instances[h.inst as usize].geom, Geom::Mesh(_));
            for k in 0..16 {
                // Elevation from 1e-4 (grazing) to straight out, any azimuth.
                let cos = [1e-4, 1e-3, 1e-2, 0.1, 0.5, 1.0][k % 6] * (0.5 + 0.5 * rng.next());
                let phi = std::f32::consts::TAU * rng.next();
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let side = if is_mesh && k % 2 == 1 { -facing } else { facing };
                let dir = (t * (sin * phi.cos()) + b * (sin * phi.sin()) + side * cos).normalize();
                let ray = spawn(&surf, dir);
                n += 1;
                if let Some(h2) = w.intersect(&ray) {
                    if h2.inst == h.inst && h2.prim == h.prim && (is_mesh || side == facing) {
                        bad += 1;
                    }
                }
            }
        }
    }
    (n, bad)
}

#[test]
fn spawned_rays_never_meet_their_own_surface() {
    let far = Affine3A::from_scale_rotation_translation(
        Vec3::splat(3.0),
        Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 0.7),
        Vec3::new(1.0e5, -3.0e4, 2.0e4),
    );
    let demo = lucent_scene::demo_scene();
    let dcam = demo.camera.expect("demo camera");
    let cornell = || lucent_scene::load(&scene("cornell_box/cornell_box.obj")).expect("cornell");
    let ccam = CameraDesc::from_view(&[278.0, 273.0, -800.0, 278.0, 273.0, 0.0, 0.0, 1.0, 0.0, 39.3]);
    let sponza = lucent_scene::load(&scene("sponza_dabrovic/sponza.obj.gz")).expect("sponza");
    let scam = CameraDesc::from_view(&[-10.0, 2.5, 0.0, 0.0, 4.5, 0.0, 0.0, 1.0, 0.0, 70.0]);
    let moved_cam = |c: CameraDesc| CameraDesc {
        eye: far.transform_point3(c.eye),
        look_at: far.transform_point3(c.look_at),
        up: far.transform_vector3(c.up),
        ..c
    };
    let cases = [
        ("demo", demo.clone(), dcam),
        ("demo, far away", moved(demo, far), moved_cam(dcam)),
        ("cornell", cornell(), ccam),
        ("cornell, far away", moved(cornell(), far), moved_cam(ccam)),
        ("sponza", sponza, scam),
    ];
    let mut unguarded = 0;
    for (name, s, cam) in cases {
        let (n, bad) = self_hits(s.clone(), cam, &|surf, dir| surf.spawn(dir));
        assert!(n > 10_000, "{name}: only {n} rays");
        assert_eq!(bad, 0, "{name}: {bad} of {n} spawned rays met their own surface");
        // The same rays from the hit point itself.
        let from_p = self_hits(s, cam, &|surf, dir| Ray::new(surf.p, dir)).1;
        eprintln!("{name}: {n} rays spawned, none met its own surface; from the hit point, {from_p} did");
        unguarded += from_p;
    }
    assert!(unguarded > 100, "without the offset only {unguarded} rays met their own surface: the test proves nothing");
}
