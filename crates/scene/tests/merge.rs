//! `Scene::merge_single_use_meshes`: meshes one instance each draws are baked into world
//! space and merged, with their faces' sides, normals, texture coordinates and materials;
//! shared meshes, shapes and animated scenes are left alone.

use glam::{Affine3A, Quat, Vec2, Vec3};
use lucent_scene::{Attr, Geom, Instance, Mesh, Scene, ShapeKind};

fn triangle(material: u32, normals: bool) -> Mesh {
    Mesh {
        name: format!("tri{material}"),
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        indices: vec![[0, 1, 2]],
        normals: if normals { Attr { values: vec![Vec3::Z], indices: Some(vec![[0, 0, 0]]) } } else { Attr::default() },
        uvs: Attr { values: vec![Vec2::ZERO, Vec2::X, Vec2::Y], indices: None },
        material: vec![material],
    }
}

/// The world-space corners and face normal of every triangle an instance
/// draws, with its material and shading normals, in a canonical order.
/// A triangle as drawn: sorted corners, face normal, material, shading normal (rounded).
type Drawn = (Vec<[i64; 3]>, [i64; 3], u32, Option<[i64; 3]>);

fn world_triangles(s: &Scene) -> Vec<Drawn> {
    let q = |v: Vec3| [(v.x * 1e4).round() as i64, (v.y * 1e4).round() as i64, (v.z * 1e4).round() as i64];
    let mut out = Vec::new();
    for i in &s.instances {
        let Geom::Mesh(m) = i.geom else { continue };
        let mesh = &s.meshes[m as usize];
        let nm = glam::Mat3::from(i.world_from_object.matrix3).inverse().transpose();
        for (t, c) in mesh.indices.iter().enumerate() {
            let p = c.map(|k| i.world_from_object.transform_point3(mesh.positions[k as usize]));
            // (A renderer turns the object's face normal by the inverse transpose.)
            let o = c.map(|k| mesh.positions[k as usize]);
            let face = (nm * (o[1] - o[0]).cross(o[2] - o[0])).normalize();
            let mut corners: Vec<[i64; 3]> = p.iter().map(|&v| q(v)).collect();
            corners.sort_unstable();
            // (Without normals a renderer shades with the face's: what a merged mesh
            // gives such triangles.)
            let ns = mesh.normals.corners(t, c).map_or(face, |n| (nm * n[0]).normalize());
            out.push((corners, q(face), mesh.material[t], Some(q(ns))));
        }
    }
    out.sort();
    out
}

#[test]
fn single_use_meshes_merge_and_keep_what_they_draw() {
    let mut s = Scene::default();
    // Three meshes drawn once each (one mirrored, one turned and scaled), one drawn twice,
    // and a sphere.
    for (k, t) in [
        Affine3A::from_translation(Vec3::new(0.0, 0.0, 1.0)),
        Affine3A::from_scale(Vec3::new(-2.0, 1.0, 1.0)),
        Affine3A::from_scale_rotation_translation(Vec3::new(1.0, 3.0, 0.5), Quat::from_rotation_y(0.7), Vec3::ONE),
    ]
    .into_iter()
    .enumerate()
    {
        s.meshes.push(triangle(k as u32, k == 2));
        s.instances.push(Instance { geom: Geom::Mesh(k as u32), world_from_object: t });
    }
    s.meshes.push(triangle(7, false));
    for x in [5.0, 6.0] {
        s.instances.push(Instance { geom: Geom::Mesh(3), world_from_object: Affine3A::from_translation(Vec3::new(x, 0.0, 0.0)) });
    }
    s.instances.push(Instance { geom: Geom::Shape { kind: ShapeKind::Sphere, material: 0 }, world_from_object: Affine3A::IDENTITY });
    let before = world_triangles(&s);
    // The three single-use meshes merge, with and without normals.
    assert_eq!(s.merge_single_use_meshes(), 2);
    assert_eq!(world_triangles(&s), before);
    assert_eq!(s.meshes.len(), 2, "the merged mesh, the shared one");
    assert_eq!(s.instances.len(), 4);
    let shared: Vec<_> =
        s.instances.iter().filter(|i| matches!(i.geom, Geom::Mesh(m) if s.meshes[m as usize].material == vec![7])).collect();
    assert_eq!(shared.len(), 2, "the shared mesh keeps its two instances");
    assert!(s.instances.iter().any(|i| matches!(i.geom, Geom::Shape { .. })));
    // Texture coordinates follow their triangles.
    let merged = s.meshes.iter().find(|m| m.indices.len() == 3).expect("a merged mesh of three triangles");
    for t in 0..3 {
        let uv = merged.uvs.corners(t, &merged.indices[t]).expect("uvs");
        let mut sorted = uv.map(|v| ((v.x * 10.0) as i32, (v.y * 10.0) as i32));
        sorted.sort_unstable();
        assert_eq!(sorted, [(0, 0), (0, 10), (10, 0)]);
    }
    // Again: nothing left to merge.
    assert_eq!(s.merge_single_use_meshes(), 0);
}

#[test]
fn an_animated_scene_is_left_alone() {
    let mut s = Scene::default();
    for k in 0..3 {
        s.meshes.push(triangle(k, false));
        s.instances.push(Instance { geom: Geom::Mesh(k), world_from_object: Affine3A::IDENTITY });
    }
    s.animation = Some(std::sync::Arc::default());
    assert_eq!(s.merge_single_use_meshes(), 0);
    assert_eq!(s.meshes.len(), 3);
}

#[test]
fn meshes_without_normals_or_uvs_get_their_faces_and_barycentrics() {
    let mut s = Scene::default();
    // A mesh with normals and no uvs beside one with uvs and no normals (a PLY model on a
    // Mitsuba rectangle), the second mirrored.
    let mut a = triangle(0, true);
    a.uvs = Attr::default();
    let mut b = triangle(1, false);
    b.positions = vec![Vec3::new(0.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 2.0), Vec3::new(0.0, 1.0, 2.0)];
    s.add_mesh(a);
    s.meshes.push(b);
    s.instances.push(Instance { geom: Geom::Mesh(1), world_from_object: Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0)) });
    let before = world_triangles(&s);
    assert_eq!(s.merge_single_use_meshes(), 1);
    assert_eq!(world_triangles(&s), before);
    let m = &s.meshes[0];
    for (t, c) in m.indices.iter().enumerate() {
        let p = c.map(|k| m.positions[k as usize]);
        let uv = m.uvs.corners(t, c).expect("uvs everywhere");
        let n = m.normals.corners(t, c).expect("normals everywhere");
        if m.material[t] == 0 {
            // The first: its uvs are the barycentric corners, in its corners' order.
            assert_eq!(uv, [Vec2::ZERO, Vec2::X, Vec2::Y]);
        } else {
            // The second (mirrored): its face normal still points along its turn.
            let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
            assert!(n.iter().all(|&x| (x - face).length() < 1e-6), "{n:?} vs {face}");
        }
    }
}
