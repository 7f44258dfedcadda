//! Animated scenes: sampling against the glTF's own keyframes, instances that move, morph
//! targets, and frames that do not depend on the thread count.

mod common;
use common::scene;
use glam::{Affine3A, Quat, Vec3};
use lucent_accel::{MeshOptions, Ray};
use lucent_render::{render, Camera, RenderSettings, Traversal, World};
use lucent_scene::anim::{sample, Channel, Interp, Node, SceneAnimation, Target};
use lucent_scene::{load, CameraDesc, Geom, Instance, Material, Scene, ShapeKind};
use std::sync::Arc;

#[test]
fn every_key_of_every_channel_is_hit_exactly() {
    for rel in ["bart/kitchen/kitchen.gltf", "bart/museum/museum5.gltf", "gltf_animated/BoxAnimated.glb", "gltf_animated/CesiumMan.glb"] {
        let s = load(&scene(rel)).expect("load");
        let anim = s.animation.as_ref().unwrap_or_else(|| panic!("{rel} is animated"));
        assert!(!anim.channels.is_empty());
        let mut keys = 0;
        for c in &anim.channels {
            let stride = if c.interp == Interp::CubicSpline { 3 * c.width } else { c.width };
            let off = if c.interp == Interp::CubicSpline { c.width } else { 0 };
            for (k, &t) in c.times.iter().enumerate() {
                let want = &c.values[k * stride + off..k * stride + off + c.width];
                let got = sample(c, t).expect("a value");
                if c.target == Target::Rotation {
                    // Slerp at s = 0 returns the key up to rounding and sign.
                    let (a, b) = (Quat::from_slice(want), Quat::from_slice(&got));
                    assert!(a.dot(b).abs() > 1.0 - 1e-6, "{rel}: rotation key {k} at {t}");
                } else {
                    assert_eq!(got, want, "{rel}: node {} {:?} key {k} at t = {t}", c.node, c.target);
                }
                keys += 1;
            }
        }
        assert!(keys > 0);
    }
}

#[test]
fn an_animated_node_sits_at_its_key() {
    // BoxAnimated: node 2 ("inner box") has translation keys; at a key time its
    // instance's origin is its parent's transform applied to the key translation.
    let s = load(&scene("gltf_animated/BoxAnimated.glb")).expect("load");
    let anim = s.animation.clone().expect("animated");
    let tr = anim.channels.iter().find(|c| c.target == Target::Translation).expect("a translation channel");
    let node = tr.node as usize;
    let k = tr.times.len() / 2;
    let t = tr.times[k];
    let key = Vec3::from_slice(&tr.values[3 * k..3 * k + 3]);
    let world = anim.world_matrices(t);
    let parent = anim.nodes[node].parent.map_or(glam::Mat4::IDENTITY, |p| world[p as usize]);
    let expect = parent.transform_point3(key);
    assert!((world[node].transform_point3(Vec3::ZERO) - expect).length() < 1e-5);
    let pose = anim.pose(t);
    if let Some(i) = anim.instance_nodes.iter().position(|&n| n as usize == node) {
        assert!((pose.instances[i].transform_point3(Vec3::ZERO) - expect).length() < 1e-5);
    }
}

/// A unit sphere that slides from x = 0 to x = 5 over one second.
fn sliding_sphere() -> Scene {
    let mut s = Scene { materials: vec![Material::default()], ..Scene::default() };
    s.instances.push(Instance { geom: Geom::Shape { kind: ShapeKind::Sphere, material: 0 }, world_from_object: Affine3A::IDENTITY });
    s.animation = Some(Arc::new(SceneAnimation {
        nodes: vec![Node { parent: None, t: Vec3::ZERO, r: Quat::IDENTITY, s: Vec3::ONE }],
        channels: vec![Channel {
            node: 0,
            target: Target::Translation,
            interp: Interp::Linear,
            times: vec![0.0, 1.0],
            values: vec![0., 0., 0., 5., 0., 0.],
            width: 3,
        }],
        instance_nodes: vec![0],
        ..SceneAnimation::default()
    }));
    s
}

#[test]
fn a_moved_instance_is_hit_where_it_is_now() {
    let mut w = World::new(sliding_sphere(), MeshOptions::default()).expect("world");
    let down = |x: f32| Ray::new(Vec3::new(x, 10.0, 0.0), -Vec3::Y);
    w.set_time(0.0).expect("pose");
    assert!(w.intersect(&down(0.0)).is_some());
    assert!(w.intersect(&down(5.0)).is_none());
    w.set_time(1.0).expect("pose");
    assert!(w.intersect(&down(0.0)).is_none(), "not where it was");
    let h = w.intersect(&down(5.0)).expect("where it is now");
    assert!((h.t - 9.0).abs() < 1e-4, "top of the sphere at y = 1: t = {}", h.t);
    w.set_time(0.5).expect("pose");
    assert!(w.intersect(&down(2.5)).is_some() && !w.occluded(&Ray::new(Vec3::new(5.0, 10.0, 0.0), -Vec3::Y)));
}

#[test]
fn museum_morph_targets_move_the_animated_triangles() {
    let s = load(&scene("bart/museum/museum5.gltf")).expect("load");
    let anim = s.animation.clone().expect("animated");
    assert_eq!(anim.morphs.len(), 1);
    let m = &anim.morphs[0];
    assert_eq!(s.meshes[m.mesh as usize].indices.len(), 1024, "BART's 1,024 animated triangles");
    let mut w = World::new(s, MeshOptions::default()).expect("world");
    let (t0, t1) = anim.time_range();
    w.set_time(t0).expect("pose");
    let a = w.scene().meshes[m.mesh as usize].positions.clone();
    w.set_time(0.5 * (t0 + t1)).expect("pose");
    let b = w.scene().meshes[m.mesh as usize].positions.clone();
    let moved = a.iter().zip(&b).filter(|(p, q)| (**p - **q).length() > 1e-4).count();
    assert!(moved > a.len() / 2, "{moved} of {} vertices moved", a.len());
    // The rebuilt bottom level finds the triangles where they now are: a ray at a moved
    // triangle's new centroid, along its normal, hits it.
    let geom = m.mesh;
    let inst = w.scene().instances.iter().position(|i| i.geom == Geom::Mesh(geom)).expect("instanced");
    let xf = w.scene().instances[inst].world_from_object;
    let mesh = &w.scene().meshes[m.mesh as usize];
    let mut hits = 0;
    for (ti, tri) in mesh.indices.iter().enumerate().step_by(37) {
        let [p, q, r] = tri.map(|i| xf.transform_point3(mesh.positions[i as usize]));
        let n = (q - p).cross(r - p);
        if n.length() < 1e-8 {
            continue;
        }
        let c = (p + q + r) / 3.0;
        let n = n.normalize();
        let ray = Ray::new(c + n * 0.01, -n).with_range(0.0, 0.02);
        if let Some(h) = w.intersect(&ray) {
            hits += usize::from(h.inst as usize == inst && h.prim as usize == ti);
        }
    }
    assert!(hits > 10, "{hits} triangles found at their new places");
}

#[test]
fn animation_frames_do_not_depend_on_thread_count() {
    let s = load(&scene("bart/kitchen/kitchen.gltf")).expect("load");
    let mut w = World::new(s, MeshOptions::default()).expect("world");
    let cam: CameraDesc = w.set_time(7.5).expect("pose").expect("animated camera");
    let c = Camera::new(&cam, 64, 48);
    // Whitted, and the VPL integrator (its VPLs made anew for the posed frame).
    for integrator in [lucent_render::Integrator::default(), lucent_render::Integrator::Vpl(lucent_render::VplSettings::default())] {
        let st = RenderSettings { integrator, ..RenderSettings::new(64, 48) };
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool").install(|| render(&w, &c, &st, &|_| {}).0);
        let two = rayon::ThreadPoolBuilder::new().num_threads(3).build().expect("pool").install(|| render(&w, &c, &st, &|_| {}).0);
        assert_eq!(one.pixels, two.pixels, "{}", integrator.name());
    }
    // And the camera moves: another time, another view.
    let cam2 = w.set_time(12.0).expect("pose").expect("camera");
    assert!((cam2.eye - cam.eye).length() > 0.1);
}

#[test]
fn cesium_man_is_skinned_and_walks() {
    let s = load(&scene("gltf_animated/CesiumMan.glb")).expect("load");
    let anim = s.animation.clone().expect("animated");
    assert_eq!(anim.skins.len(), 1);
    let sk = &anim.skins[0];
    assert!(sk.joints.len() > 10 && sk.vertex_weights.len() == sk.base.len());
    let mut w = World::new(s, MeshOptions::default()).expect("world");
    let (t0, t1) = anim.time_range();
    let shape = |w: &World| -> (Vec<Vec3>, Vec3, Vec3) {
        let p = w.scene().meshes[sk.mesh as usize].positions.clone();
        let lo = p.iter().fold(Vec3::INFINITY, |a, b| a.min(*b));
        let hi = p.iter().fold(Vec3::NEG_INFINITY, |a, b| a.max(*b));
        (p, lo, hi)
    };
    w.set_time(t0).expect("pose");
    let (a, lo, hi) = shape(&w);
    // Upright and man-sized in world space (its instance transform is now the identity).
    assert!((hi.y - lo.y) > 1.0 && (hi.y - lo.y) < 2.5, "height {}", hi.y - lo.y);
    assert_eq!(w.scene().instances[sk.instance as usize].world_from_object, Affine3A::IDENTITY);
    w.set_time(0.5 * (t0 + t1)).expect("pose");
    let (b, _, _) = shape(&w);
    let moved = a.iter().zip(&b).filter(|(p, q)| (**p - **q).length() > 1e-3).count();
    assert!(moved > a.len() / 4, "{moved} of {} vertices moved as he walks", a.len());
    // His normals follow the pose: unit length, on the side of the posed triangles as
    // often as the file's own normals are on the side of the triangles at rest.
    let agreement = |m: &lucent_scene::Mesh| -> f64 {
        let (mut agree, mut faces) = (0, 0);
        for idx in &m.indices {
            let [p0, p1, p2] = idx.map(|i| m.positions[i as usize]);
            let f = (p1 - p0).cross(p2 - p0);
            if f.length() < 1e-9 {
                continue;
            }
            faces += 1;
            let Some([n0, n1, n2]) = m.normals.corners(0, idx) else { continue };
            if (n0 + n1 + n2).dot(f) > 0.0 {
                agree += 1;
            }
        }
        f64::from(agree) / f64::from(faces.max(1))
    };
    let rest_mesh = load(&scene("gltf_animated/CesiumMan.glb")).expect("load").meshes[sk.mesh as usize].clone();
    let rest = agreement(&rest_mesh);
    let mesh = &w.scene().meshes[sk.mesh as usize];
    let normals = &mesh.normals.values;
    assert_eq!(normals.len(), mesh.positions.len(), "a normal per vertex");
    assert!(normals.iter().all(|n| n.length() < 1e-6 || (n.length() - 1.0).abs() < 1e-4), "normals of unit length");
    let posed = agreement(mesh);
    eprintln!("normals on the side of their triangles: {posed:.4} posed (mid-walk), {rest:.4} at rest");
    // Linear blend skinning folds a few triangles at the joints (2.6% mid-walk when
    // written); the rest keep their normals on their side.
    assert!(rest > 0.99 && posed > 0.95, "posed normals agree with {posed:.4} of the triangles, the file's with {rest:.4} at rest");
    // And they turned with the body: the normals are not the rest normals (rest pose to
    // world: the skin's instance transform is the identity now, so compare directions
    // after the walk moved them).
    let turned = normals.iter().zip(&rest_mesh.normals.values).filter(|(a, b)| a.dot(**b) < 0.99).count();
    assert!(turned > normals.len() / 4, "{turned} of {} normals turned", normals.len());
    // The refitted or rebuilt bottom level follows: a ray down onto the head finds him.
    // It aims at the centre of the highest triangle that faces up, not at the top vertex:
    // the unit-triangle test is not watertight, and a ray through a vertex may pass
    // between the triangles that share it.
    let centre = |idx: &[u32; 3]| idx.iter().map(|&i| b[i as usize]).sum::<Vec3>() / 3.0;
    let up = |idx: &[u32; 3]| {
        let [p0, p1, p2] = idx.map(|i| b[i as usize]);
        (p1 - p0).cross(p2 - p0).normalize_or_zero().y.abs() > 0.3
    };
    let top = mesh.indices.iter().filter(|i| up(i)).map(centre).fold(Vec3::NEG_INFINITY, |m, p| if p.y > m.y { p } else { m });
    let ray = Ray::new(top + Vec3::Y, -Vec3::Y);
    let h = w.intersect(&ray).expect("the head");
    assert!((h.t - 1.0).abs() < 0.05, "t = {}", h.t);
    // Its geometric normal is the posed triangle's (the world keeps the triangles' normal
    // vectors, and they must follow the pose).
    let [p0, p1, p2] = mesh.indices[h.prim as usize].map(|i| b[i as usize]);
    let posed_normal = (p1 - p0).cross(p2 - p0).normalize_or_zero();
    let ng = w.surface(&ray, &h).ng;
    assert!(ng.dot(posed_normal) > 0.9999, "surface normal {ng} against the posed triangle's {posed_normal}");
}

/// The BART kitchen at t = 16.67 s: coplanar parts of different instances meet some
/// reflection rays at equal distances. A tie once paired one mesh's triangle with another
/// instance and the shader indexed out of bounds (both with packets and ray by ray). The
/// frame must render, and packets must give the ray-by-ray picture.
#[test]
fn kitchen_frame_with_coplanar_ties_renders() {
    let s = load(&scene("bart/kitchen/kitchen.gltf")).expect("load");
    let mut w = World::new(s, MeshOptions::default()).expect("world");
    w.ensure_light(Vec3::ZERO);
    let cam = w.set_time(16.6f32 + 2.0 / 30.0).expect("pose").expect("animated camera");
    let c = Camera::new(&cam, 512, 384);
    let mut frames = Vec::new();
    for packets in [true, false] {
        let st = RenderSettings { traversal: Traversal { packets }, ..RenderSettings::new(512, 384) };
        frames.push(render(&w, &c, &st, &|_| {}).0);
    }
    let differ = frames[0].pixels.iter().zip(&frames[1].pixels).filter(|(a, b)| (**a - **b).abs().max_element() > 1e-3).count();
    // Packets and single rays may differ only where two surfaces tie exactly.
    assert!(differ * 1000 < frames[0].pixels.len(), "{differ} pixels differ");
}

#[test]
fn vertex_normals_average_the_faces_around_a_vertex() {
    // A tent: two slopes meeting at a ridge along x; the ridge's normals point straight up,
    // the eaves' are their slope's. An unused vertex and a triangle out of range are left out.
    let p =
        [Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0), Vec3::new(5.0, 5.0, 5.0)];
    let tris = [[0u32, 2, 1], [0, 1, 3], [0, 1, 9]];
    let n = lucent_render::vertex_normals(&p, &tris);
    let up = |v: Vec3| (v - Vec3::Y).length() < 1e-6;
    assert!(up(n[0]) && up(n[1]), "ridge normals {:?} {:?}", n[0], n[1]);
    let slope = Vec3::new(0.0, 1.0, 1.0).normalize();
    assert!((n[2] - slope).length() < 1e-6, "eave {:?}", n[2]);
    assert!((n[3] - Vec3::new(0.0, 1.0, -1.0).normalize()).length() < 1e-6, "eave {:?}", n[3]);
    assert_eq!(n[4], Vec3::ZERO);
}

/// A floor lit by an emitting quad (a mesh instance) and, in `moving`, the quad slides from
/// x = 0 to x = 3 over one second while a grey sphere stays put. `lit_at`: the quad placed
/// there without animation.
fn lamp_scene(moving: bool, lit_at: f32) -> Scene {
    let quad = |y: f32, s: f32, material: u32, name: &str| lucent_scene::Mesh {
        name: name.into(),
        positions: vec![Vec3::new(-s, y, -s), Vec3::new(s, y, -s), Vec3::new(s, y, s), Vec3::new(-s, y, s)],
        // (The lamp faces down, the floor up.)
        indices: if y > 0.0 { vec![[0, 1, 2], [0, 2, 3]] } else { vec![[0, 2, 1], [0, 3, 2]] },
        material: vec![material; 2],
        ..lucent_scene::Mesh::default()
    };
    let lamp = Material { emission: Vec3::splat(8.0), ..Material::default() };
    let mut s = Scene { materials: vec![Material::default(), lamp], ..Scene::default() };
    s.meshes = vec![quad(0.0, 10.0, 0, "floor"), quad(2.0, 0.5, 1, "lamp")];
    let at = |x: f32| Affine3A::from_translation(Vec3::new(x, 0.0, 0.0));
    s.instances.push(Instance { geom: Geom::Mesh(0), world_from_object: Affine3A::IDENTITY });
    s.instances.push(Instance { geom: Geom::Mesh(1), world_from_object: at(lit_at) });
    s.instances.push(Instance { geom: Geom::Shape { kind: ShapeKind::Sphere, material: 0 }, world_from_object: at(-2.0) });
    s.camera = Some(CameraDesc::from_view(&[0.0, 6.0, -8.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 60.0]));
    if moving {
        let still = |t: Vec3| Node { parent: None, t, r: Quat::IDENTITY, s: Vec3::ONE };
        s.animation = Some(Arc::new(SceneAnimation {
            nodes: vec![still(Vec3::ZERO), still(Vec3::ZERO), still(Vec3::new(-2.0, 0.0, 0.0))],
            channels: vec![Channel {
                node: 1,
                target: Target::Translation,
                interp: Interp::Linear,
                times: vec![0.0, 1.0],
                values: vec![0., 0., 0., 3., 0., 0.],
                width: 3,
            }],
            instance_nodes: vec![0, 1, 2],
            ..SceneAnimation::default()
        }));
    }
    s
}

/// Posing a frame makes the light set again only when an emitter moved, and the images
/// are those of the scene built with the emitter where it is now (next-event estimation
/// samples it there).
#[test]
fn a_moved_emitter_lights_from_where_it_is_now() {
    let path = |w: &World| {
        let c = Camera::new(&w.scene().camera.expect("camera"), 48, 32);
        let ps = lucent_render::PathSettings { max_depth: 3, ..lucent_render::PathSettings::default() };
        let st = RenderSettings { spp: 4, integrator: lucent_render::Integrator::Path(ps), ..RenderSettings::new(48, 32) };
        render(w, &c, &st, &|_| {}).0
    };
    let mut w = World::new(lamp_scene(true, 0.0), MeshOptions::default()).expect("world");
    for t in [0.0, 0.5, 1.0] {
        w.set_time(t).expect("pose");
        let still = World::new(lamp_scene(false, 3.0 * t), MeshOptions::default()).expect("world");
        assert_eq!(path(&w).pixels, path(&still).pixels, "t = {t}");
    }
}
