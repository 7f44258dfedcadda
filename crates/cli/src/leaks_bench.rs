//! `lucent bench leaks`: rays through the shared vertices and edges of closed meshes, per
//! triangle test (see `lucent_accel::closed`).

use anyhow::Result;
use glam::{Quat, Vec3};
use lucent_accel::closed::ClosedMesh;
use lucent_accel::{MeshBvh, MeshOptions, TriangleTest};
use rayon::prelude::*;

/// Rays per parallel task.
const CHUNK: u64 = 1 << 16;

pub fn run(rays: u64, seed: u64) -> Result<()> {
    let turn = Quat::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
    let mut meshes = Vec::new();
    for scale in [1e-4f32, 1.0, 1e4] {
        let offset = Vec3::new(0.3, -0.2, 0.1) * scale;
        meshes.push((scale, ClosedMesh::sphere(4).placed(turn, scale, offset)));
        meshes.push((scale, ClosedMesh::torus(96, 48, 1.0, 0.35).placed(turn, scale, offset)));
        meshes.push((scale, ClosedMesh::cube(16).placed(turn, scale, offset)));
    }
    let per_mesh = rays.div_ceil(meshes.len() as u64);
    let bar = indicatif::ProgressBar::new(2 * per_mesh * meshes.len() as u64);
    bar.set_style(indicatif::ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} rays ({eta})")?);
    bar.set_message("bench leaks");
    println!("{:<7} {:>6} {:>9} {:>13} {:>16} {:>12}", "mesh", "scale", "triangles", "rays", "unit-triangle", "watertight");
    let (mut total_unit, mut total_wt) = (0u64, 0u64);
    for (scale, m) in &meshes {
        let mut leaks = [0u64; 2];
        for (k, test) in [TriangleTest::UnitTriangle, TriangleTest::Watertight].into_iter().enumerate() {
            let bvh = MeshBvh::build(&m.positions, &m.indices, MeshOptions { test, ..MeshOptions::default() })?;
            leaks[k] = (0..per_mesh.div_ceil(CHUNK))
                .into_par_iter()
                .map(|c| {
                    let r = c * CHUNK..((c + 1) * CHUNK).min(per_mesh);
                    let n = r.end - r.start;
                    let l = m.count_leaks(&bvh, seed, r);
                    bar.inc(n);
                    l
                })
                .sum();
        }
        total_unit += leaks[0];
        total_wt += leaks[1];
        bar.suspend(|| {
            println!("{:<7} {:>6.0e} {:>9} {:>13} {:>16} {:>12}", m.name, scale, m.indices.len(), per_mesh, leaks[0], leaks[1]);
        });
    }
    bar.finish_and_clear();
    let all = per_mesh * meshes.len() as u64;
    println!(
        "{:<7} {:>6} {:>9} {:>13} {:>16} {:>12}",
        "all",
        "",
        "",
        all,
        format!("{total_unit} ({:.2}%)", 100.0 * total_unit as f64 / all as f64),
        format!("{total_wt} ({:.2}%)", 100.0 * total_wt as f64 / all as f64)
    );
    Ok(())
}
