//! `lucent bench dynamic`: the figures of dynamic scenes: top-level rebuilds for many
//! instances, bottom-level refits of deforming meshes, and whole animated frames.

use crate::stats::median;
use anyhow::{Context, Result};
use lucent_accel::glam::{Affine3A, Quat, Vec3};
use lucent_accel::{Geometry, Instance, MeshBvh, MeshOptions, TopBuilder, TwoLevel};
use lucent_render::{render, Camera, Integrator, RenderSettings, WhittedSettings, World};
use std::path::Path;
use std::time::Instant;

fn time_ms(reps: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut v: Vec<f64> = (0..reps.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    median(&mut v)
}

/// A simple pseudo-random sequence (a hash of the index): deterministic placements.
fn rand01(i: u64) -> f32 {
    let h = lucent_render::pcg_hash(i as u32 ^ lucent_render::pcg_hash((i >> 32) as u32));
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// A wavy grid of `n` triangles (a 100k-triangle deforming mesh).
fn grid(n: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let side = ((n / 2) as f64).sqrt().ceil() as u32;
    let mut p = Vec::new();
    for y in 0..=side {
        for x in 0..=side {
            p.push(Vec3::new(x as f32 / side as f32, 0.0, y as f32 / side as f32));
        }
    }
    let mut idx = Vec::new();
    for y in 0..side {
        for x in 0..side {
            let a = y * (side + 1) + x;
            idx.push([a, a + 1, a + side + 1]);
            idx.push([a + 1, a + side + 2, a + side + 1]);
        }
    }
    idx.truncate(n);
    (p, idx)
}

fn wave(p: &[Vec3], t: f32) -> Vec<Vec3> {
    p.iter().map(|v| Vec3::new(v.x, 0.05 * ((v.x * 12.0 + t).sin() + (v.z * 9.0 - 0.7 * t).cos()), v.z)).collect()
}

fn line(kind: &str, fields: serde_json::Value) {
    let mut m = serde_json::Map::new();
    m.insert("kind".into(), kind.into());
    m.insert("threads".into(), rayon::current_num_threads().into());
    if let serde_json::Value::Object(f) = fields {
        m.extend(f);
    }
    println!("{}", serde_json::Value::Object(m));
}

pub fn run(scenes: &Path, frames: usize, size: (u32, u32)) -> Result<()> {
    let table = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let mut rows: Vec<String> = Vec::new();
    // 1. Top level over 1k, 10k, 100k instances of one small mesh.
    let (gp, gi) = grid(200);
    let blas = MeshBvh::build(&gp, &gi, MeshOptions::default())?;
    for n in [1_000usize, 10_000, 100_000] {
        let side = (n as f32).cbrt();
        let insts: Vec<Instance> = (0..n as u64)
            .map(|i| {
                let pos = Vec3::new(rand01(3 * i), rand01(3 * i + 1), rand01(3 * i + 2)) * side * 2.0;
                let rot = Quat::from_rotation_y(rand01(i + 7_000_000) * std::f32::consts::TAU);
                Instance::new(0, Affine3A::from_scale_rotation_translation(Vec3::splat(0.5 + rand01(i + 9_000_000)), rot, pos))
            })
            .collect();
        for (builder, name) in [(TopBuilder::Sah, "sah"), (TopBuilder::Linear, "linear")] {
            let mut tl = TwoLevel::new(vec![Geometry::Mesh(blas.clone())], insts.clone())?;
            tl.set_top_builder(builder);
            let ms = time_ms(15, || {
                // What a frame of rigid motion costs: new transforms in, top level rebuilt.
                let _ = tl.update_instances(|i| i.copy_from_slice(&insts));
            });
            line("tlas_build", serde_json::json!({"instances": n, "builder": name, "median_ms": ms}));
            rows.push(format!("TLAS rebuild ({name}), {n} instances: {ms:.3} ms"));
        }
    }
    // 2. Bottom-level refit: 100k-triangle wavy grid, and the museum's animated mesh.
    let (p, idx) = grid(100_000);
    let opts = MeshOptions { refittable: true, ..MeshOptions::default() };
    let mut bvh = MeshBvh::build(&p, &idx, opts)?;
    let mut k = 0.0f32;
    let frames_pos: Vec<Vec<Vec3>> = (0..8).map(|i| wave(&p, i as f32 * 0.5)).collect();
    let refit = time_ms(15, || {
        k += 1.0;
        let _ = bvh.refit(&frames_pos[k as usize % 8], &idx);
    });
    let rebuild = time_ms(7, || {
        let _ = MeshBvh::build(&frames_pos[3], &idx, opts);
    });
    line("blas_refit", serde_json::json!({"mesh": "grid", "triangles": idx.len(), "median_ms": refit, "rebuild_median_ms": rebuild}));
    rows.push(format!("BLAS refit, {} triangles (wavy grid): {refit:.2} ms (rebuild {rebuild:.2} ms)", idx.len()));
    let museum = scenes.join("bart/museum/museum5.gltf");
    let kitchen = scenes.join("bart/kitchen/kitchen.gltf");
    if museum.exists() {
        let s = lucent_scene::load(&museum)?;
        let anim = s.animation.clone().context("the museum is not animated")?;
        let m = anim.morphs.first().context("the museum has no morphing mesh")?;
        let mesh = &s.meshes[m.mesh as usize];
        let mut bvh = MeshBvh::build(&mesh.positions, &mesh.indices, opts)?;
        let (t0, t1) = anim.time_range();
        let poses: Vec<Vec<Vec3>> = (0..=30)
            .map(|i| anim.pose(t0 + (t1 - t0) * i as f32 / 30.0))
            .filter_map(|p| p.meshes.into_iter().next().map(|x| x.1))
            .collect();
        let mut i = 0;
        let refit = time_ms(31, || {
            i += 1;
            let _ = bvh.refit(&poses[i % poses.len()], &mesh.indices);
        });
        // How the refitted tree's quality decays over the animation (no rebuilds).
        let mut fresh = MeshBvh::build(&mesh.positions, &mesh.indices, opts)?;
        let ratios: Vec<f32> = poses.iter().map(|p| fresh.refit(p, &mesh.indices).unwrap_or(f32::NAN)).collect();
        let worst = ratios.iter().copied().fold(0.0f32, f32::max);
        // The data behind the rebuild threshold: how much slower rays get through a
        // refitted tree than through a fresh one, against the SAH cost ratio.
        let (lo, hi) = poses.iter().flatten().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
        let rays: Vec<lucent_accel::Ray> = (0..20_000u64)
            .map(|i| {
                let o = lo + (hi - lo) * Vec3::new(rand01(5 * i), rand01(5 * i + 1), rand01(5 * i + 2)) * 1.2 - (hi - lo) * 0.1;
                let d = Vec3::new(rand01(5 * i + 3) - 0.5, rand01(5 * i + 4) - 0.5, rand01(7 * i + 11) - 0.5).normalize_or(Vec3::X);
                lucent_accel::Ray::new(o, d)
            })
            .collect();
        let trace = |b: &MeshBvh| {
            time_ms(5, || {
                let mut n = 0u32;
                for r in &rays {
                    n += u32::from(b.intersect(r).is_some());
                }
                std::hint::black_box(n);
            })
        };
        let mut refitted = MeshBvh::build(&mesh.positions, &mesh.indices, opts)?;
        let mut samples = Vec::new();
        for (k, p) in poses.iter().enumerate().step_by(5) {
            let ratio = refitted.refit(p, &mesh.indices)?;
            let fresh = MeshBvh::build(p, &mesh.indices, opts)?;
            let slow = trace(&refitted) / trace(&fresh).max(1e-9);
            samples.push(serde_json::json!({"pose": k, "sah_ratio": ratio, "trace_time_ratio": slow}));
            rows.push(format!("  museum pose {k:2}: refitted tree SAH ratio {ratio:6.2}, rays {slow:5.2}x the time of a fresh tree"));
        }
        line("refit_decay", serde_json::json!({"mesh": "museum animated", "samples": samples}));
        line(
            "blas_refit",
            serde_json::json!({"mesh": "museum animated", "triangles": mesh.indices.len(), "median_ms": refit, "sah_ratio_max": worst, "sah_ratio_end": ratios.last()}),
        );
        rows.push(format!(
            "BLAS refit, museum's {} animated triangles: {refit:.3} ms; SAH cost ratio up to {worst:.2} over the animation",
            mesh.indices.len()
        ));
    }
    // 3. Whole animated frames (update + render): full Whitted with shadows (reflections and
    // refractions up to depth 6), then primary rays with shadows and shading only, and the
    // sunflowers with primary rays and shading alone.
    let full = WhittedSettings::default();
    let direct = WhittedSettings { max_depth: 0, ..full };
    // The sunflower goal's "primary rays and shading" (SaarCOR's SunCOR figure): no shadow rays.
    let primary = WhittedSettings { shadows: false, ..direct };
    for (name, path, builder, whitted) in [
        ("kitchen", Some(&kitchen), TopBuilder::Sah, full),
        ("museum", Some(&museum), TopBuilder::Sah, full),
        ("sunflowers", None, TopBuilder::Sah, full),
        ("sunflowers, linear TLAS", None, TopBuilder::Linear, full),
        ("kitchen, no reflections", Some(&kitchen), TopBuilder::Sah, direct),
        ("museum, no reflections", Some(&museum), TopBuilder::Sah, direct),
        ("sunflowers, primary rays and shading", None, TopBuilder::Sah, primary),
    ] {
        let scene = match path {
            Some(p) if !p.exists() => continue,
            Some(p) => lucent_scene::load(p)?,
            None => lucent_scene::sunflower_scene(),
        };
        let (t0, t1) = scene.animation.as_ref().map_or((0.0, 0.0), |a| a.time_range());
        let fallback = crate::render_cmd::choose_camera(&scene, None, false)?;
        let mut world = World::new(scene, MeshOptions::default())?;
        world.ensure_light(fallback.eye);
        world.set_top_builder(builder);
        let rs = RenderSettings { integrator: Integrator::Whitted(whitted), ..RenderSettings::new(size.0, size.1) };
        let (mut upd, mut ren, mut tot) = (Vec::new(), Vec::new(), Vec::new());
        for f in 0..frames.max(1) {
            let t = t0 + (t1 - t0) * f as f32 / frames.max(1) as f32;
            let a = Instant::now();
            let cam = world.set_time(t)?.unwrap_or(fallback);
            let b = Instant::now();
            let _ = render(&world, &Camera::new(&cam, size.0, size.1), &rs, &|_| {});
            let c = Instant::now();
            upd.push((b - a).as_secs_f64() * 1e3);
            ren.push((c - b).as_secs_f64() * 1e3);
            tot.push((c - a).as_secs_f64() * 1e3);
        }
        let (u, r, t) = (median(&mut upd), median(&mut ren), median(&mut tot));
        line(
            "animation_frame",
            serde_json::json!({"scene": name, "width": size.0, "height": size.1, "frames": frames, "update_median_ms": u, "render_median_ms": r, "frame_median_ms": t, "fps": 1e3 / t}),
        );
        rows.push(format!("{name} animation at {}x{}: update {u:.2} ms + render {r:.1} ms = {:.1} fps", size.0, size.1, 1e3 / t));
    }
    if let Some(kib) = crate::stats::proc_status_kib("VmHWM:") {
        line("peak_memory", serde_json::json!({"mb": kib as f64 / 1024.0, "note": "whole process, all scenes above"}));
        rows.push(format!("peak resident memory of the whole run: {:.0} MB", kib as f64 / 1024.0));
    }
    if table {
        eprintln!();
        for r in rows {
            eprintln!("{r}");
        }
    }
    Ok(())
}
