//! Closed meshes traced from inside at their vertices and edges (`lucent_accel::closed`):
//! the watertight test loses no ray, at every scale, width and kernel; the unit-triangle
//! test's leaks are counted (SaarCOR's test is not watertight: a ray through a shared edge
//! can fall between the two triangles' rounded maps).

use glam::{Quat, Vec3};
use lucent_accel::closed::ClosedMesh;
use lucent_accel::{Kernel, MeshBvh, MeshOptions, TriangleTest, Width};

fn meshes() -> Vec<ClosedMesh> {
    let turn = Quat::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
    let mut out = Vec::new();
    for scale in [1e-4f32, 1.0, 1e4] {
        let offset = Vec3::new(0.3, -0.2, 0.1) * scale;
        out.push(ClosedMesh::sphere(3).placed(turn, scale, offset));
        out.push(ClosedMesh::torus(48, 24, 1.0, 0.35).placed(turn, scale, offset));
        out.push(ClosedMesh::cube(6).placed(turn, scale, offset));
    }
    out
}

/// Every mesh is closed: each edge is used by exactly two triangles, in opposite
/// directions or not (the generators' own check).
#[test]
fn the_generated_meshes_are_closed() {
    for m in meshes() {
        let mut edges = std::collections::HashMap::<(u32, u32), u32>::new();
        for t in &m.indices {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        assert!(edges.values().all(|&n| n == 2), "{}: an edge not shared by exactly two triangles", m.name);
    }
}

#[test]
fn the_watertight_test_loses_no_ray() {
    let mut unit_leaks = 0;
    for m in meshes() {
        for width in [Width::W4, Width::W8] {
            for kernel in Kernel::available() {
                let scale = (m.positions[0] - m.positions[1]).length();
                for test in [TriangleTest::Watertight, TriangleTest::UnitTriangle] {
                    let mut bvh =
                        MeshBvh::build(&m.positions, &m.indices, MeshOptions { width, test, ..MeshOptions::default() }).expect("build");
                    bvh.set_kernel(kernel);
                    let leaks = m.count_leaks(&bvh, 1, 0..20_000);
                    if test == TriangleTest::Watertight {
                        assert_eq!(leaks, 0, "{} (edge {scale:e}) {width:?} {kernel:?}: {leaks} of 20,000 rays leaked", m.name);
                    } else {
                        unit_leaks += leaks;
                    }
                }
            }
        }
    }
    eprintln!("unit-triangle leaks: {unit_leaks}");
    // The rays do meet the cracks: a test that is not watertight loses some.
    assert!(unit_leaks > 0, "the ray set finds no crack even in the unit-triangle test");
}
