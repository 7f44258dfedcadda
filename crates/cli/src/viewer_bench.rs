//! `lucent bench viewer`: the viewer's path mode without a window. What `lucent view` does
//! frame by frame (`lucent_viewer::control::Adaptive`, the same planner): while the camera
//! moves (here: an orbit about the look-at point), one sample per pixel at the resolution
//! that holds the target frame rate, the planner told each frame's time; when it stops, the
//! full image refined one sample per pixel per pass until it has its samples. Printed per
//! scene and per path tracer (on lanes, the default, and one path after another, the
//! scalar reference): frames per second while moving, the fraction of the pixels the
//! planner settled on, and the seconds to the converged still image. Display and events are
//! not counted (the window adds its blit to each frame).

use crate::stats::median;
use anyhow::{Context, Result};
use lucent_accel::glam::Vec3;
use lucent_accel::MeshOptions;
use lucent_render::setup::{prepare, Recipe};
use lucent_render::{render_region, Camera, Integrator, PathSettings, Region, RenderSettings, World};
use lucent_scene::CameraDesc;
use lucent_viewer::control::Adaptive;
use std::path::Path;
use std::time::Instant;

/// What to measure.
pub struct ViewerOptions<'a> {
    /// The reference scenes' folder (Sponza's Mitsuba scene).
    pub data: &'a Path,
    /// The shared scenes folder (Sponza's mesh).
    pub dir: &'a Path,
    /// Window size.
    pub size: (u32, u32),
    /// Frames while moving.
    pub frames: usize,
    /// The frame rate the planner holds while moving.
    pub target_fps: f64,
    /// Samples per pixel of the still image.
    pub spp: u32,
}

/// The figures of one scene and one path tracer.
struct Figures {
    fps: f64,
    pixels: f64,
    converged_s: f64,
}

/// `desc` turned by `angle` (radians) about the vertical through its look-at point.
fn orbit(desc: &CameraDesc, angle: f32) -> CameraDesc {
    let (s, c) = angle.sin_cos();
    let d = desc.eye - desc.look_at;
    let eye = desc.look_at + Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
    CameraDesc { eye, ..*desc }
}

/// The viewer's frames on `world` from `home` with path tracer `lanes`.
fn measure(world: &World, home: &CameraDesc, o: &ViewerOptions, lanes: bool) -> Figures {
    let integrator = Integrator::Path(PathSettings { lanes, ..PathSettings::default() });
    let full = o.size;
    let mut planner = Adaptive::new(o.target_fps, o.spp, 0.5);
    let (mut fps, mut pixels) = (Vec::new(), Vec::new());
    for f in 0..o.frames {
        let Some(plan) = planner.plan(true, full) else { break };
        let desc = orbit(home, 0.01 * f as f32);
        let camera = Camera::new(&desc, plan.width, plan.height);
        let rs = RenderSettings { spp: 1, integrator, ..RenderSettings::new(plan.width, plan.height) };
        let t = Instant::now();
        let _ = render_region(world, &camera, &rs, Region::full(plan.width, plan.height, 0, 1), &|_| {});
        let s = t.elapsed().as_secs_f64();
        planner.finished(&plan, s, true);
        // (The planner's first frames find the resolution: the second half is reported.)
        if f >= o.frames / 2 {
            fps.push(1.0 / s.max(1e-9));
            pixels.push(f64::from(plan.width * plan.height) / f64::from(full.0 * full.1));
        }
    }
    let camera = Camera::new(home, full.0, full.1);
    let t = Instant::now();
    while let Some(plan) = planner.plan(false, full) {
        // (As the viewer: the first pass is the one-sample image, the others add the
        // jittered samples of the image of `spp` samples.)
        let spp = if plan.sample == 0 { 1 } else { o.spp };
        let rs = RenderSettings { spp, integrator, ..RenderSettings::new(full.0, full.1) };
        let _ = render_region(world, &camera, &rs, Region::full(full.0, full.1, plan.sample, plan.sample + 1), &|_| {});
        planner.finished(&plan, 0.0, false);
    }
    Figures { fps: median(&mut fps), pixels: median(&mut pixels), converged_s: t.elapsed().as_secs_f64() }
}

/// Runs the benchmark on the feature demo and Sponza (the Mitsuba reference scene's: its
/// point and spot lights, depth 6).
pub fn run(o: &ViewerOptions) -> Result<()> {
    let sponza = o.data.join("sponza/scene.xml");
    // (The scene file names its mesh by `$scenes`, resolved beside the file: absolute.)
    let shared = o.dir.canonicalize().with_context(|| format!("{}", o.dir.display()))?;
    let scenes: Vec<(&str, lucent_scene::Scene)> = vec![
        ("demo", lucent_scene::demo_scene()),
        (
            "sponza",
            lucent_scene::load_mitsuba_with(&sponza, &[("scenes".into(), shared.display().to_string())])
                .with_context(|| format!("{}", sponza.display()))?,
        ),
    ];
    println!(
        "viewer, path mode: {}x{}, {} moving frames at a target of {} fps, then {} samples per pixel, {} threads",
        o.size.0,
        o.size.1,
        o.frames,
        o.target_fps,
        o.spp,
        rayon::current_num_threads()
    );
    println!("| scene | path tracer | fps moving | pixels moving | s to {} spp |", o.spp);
    println!("|---|---|---|---|---|");
    for (name, scene) in scenes {
        let recipe = Recipe {
            integrator: Integrator::Path(PathSettings::default()),
            size: Some(o.size),
            spp: Some(o.spp),
            view: None,
            ortho: false,
            mesh: MeshOptions::default(),
            packets: true,
            filter: None,
        };
        let prepared = prepare(scene, &recipe).with_context(|| name.to_string())?;
        for lanes in [true, false] {
            let f = measure(&prepared.world, &prepared.desc, o, lanes);
            let kind = if lanes { "lanes" } else { "scalar" };
            println!("| {name} | {kind} | {:.1} | {:.3} | {:.2} |", f.fps, f.pixels, f.converged_s);
            println!(
                "{}",
                serde_json::json!({"kind": "viewer", "scene": name, "lanes": lanes, "fps_moving": f.fps, "pixels_moving": f.pixels, "seconds_to_spp": f.converged_s, "spp": o.spp, "width": o.size.0, "height": o.size.1})
            );
        }
    }
    Ok(())
}
