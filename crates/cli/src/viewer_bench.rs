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
use lucent_render::{
    denoise, render, render_aovs, render_region, Camera, DenoiseSettings, FilmAccumulator, Integrator, PathSettings, Region,
    RenderSettings, Temporal, World,
};
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

/// What the viewer shows while moving, against the converged image (issue 55).
struct Moving {
    /// Frames per second of the whole moving frame: the samples, the guides, the blend
    /// with the frames before and the denoiser.
    fps: f64,
    /// Of the blend alone, milliseconds per frame.
    blend_ms: f64,
    /// relMSE of the last frame against the converged image: raw, denoised, blended and
    /// denoised; and the frames its pixels held on average.
    raw: f64,
    denoised: f64,
    blended: f64,
    frames_held: f64,
}

/// The viewer's moving frames along the orbit at half the window's size, one sample per
/// pixel each, shown as the viewer shows them (denoised, after the blend), and the last
/// one against a converged image of its camera (`reference_spp` samples per pixel).
fn moving(world: &World, home: &CameraDesc, o: &ViewerOptions, reference_spp: u32) -> Moving {
    let integrator = Integrator::Path(PathSettings::default());
    let (w, h) = (o.size.0 / 2, o.size.1 / 2);
    let frames = o.frames.max(2);
    let mut temporal = Temporal::new(8.0);
    let (mut times, mut blend) = (Vec::new(), Vec::new());
    let mut last = None;
    for f in 0..frames {
        let desc = orbit(home, 0.01 * f as f32);
        let camera = Camera::new(&desc, w, h);
        // (Each frame its own sample of the image of `frames` samples, as the viewer's
        // passes.)
        let rs = RenderSettings { spp: frames as u32, integrator, ..RenderSettings::new(w, h) };
        let t = Instant::now();
        let r = render_region(world, &camera, &rs, Region::full(w, h, f as u32, f as u32 + 1), &|_| {}).0;
        let mut acc = FilmAccumulator::new(w, h);
        // (A region of the whole image of this size: it merges, as a later pass's samples.)
        if acc.merge(r).is_err() {
            continue;
        }
        let raw = acc.resolve(world.scene().background);
        let aovs = render_aovs(world, &camera, w, h);
        let tb = Instant::now();
        let (blended, stats) = temporal.add(&camera, &raw, &aovs);
        blend.push(tb.elapsed().as_secs_f64() * 1e3);
        let shown = denoise(&blended, &aovs, &DenoiseSettings::default());
        times.push(t.elapsed().as_secs_f64());
        last = Some((desc, raw, aovs, shown, stats.mean_frames));
    }
    let Some((desc, raw, aovs, shown, frames_held)) = last else { unreachable!("at least two frames") };
    let camera = Camera::new(&desc, w, h);
    let rs = RenderSettings {
        spp: reference_spp,
        integrator: Integrator::Path(PathSettings { seed: 0x7e5e_ed02, ..PathSettings::default() }),
        ..RenderSettings::new(w, h)
    };
    let reference = render(world, &camera, &rs, &|_| {}).0;
    let denoised = denoise(&raw, &aovs, &DenoiseSettings::default());
    let half = times.len() / 2;
    Moving {
        fps: 1.0 / median(&mut times[half..].to_vec()).max(1e-9),
        blend_ms: median(&mut blend),
        raw: raw.rel_mse(&reference).unwrap_or(f64::NAN),
        denoised: denoised.rel_mse(&reference).unwrap_or(f64::NAN),
        blended: shown.rel_mse(&reference).unwrap_or(f64::NAN),
        frames_held,
    }
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
    let mut quality = Vec::new();
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
        quality.push((name, moving(&prepared.world, &prepared.desc, o, 256)));
    }
    println!();
    println!(
        "While moving, at {}x{}, one sample per pixel a frame, {} frames along the orbit; the last frame's relMSE against 256 samples per pixel of its camera:",
        o.size.0 / 2,
        o.size.1 / 2,
        o.frames.max(2)
    );
    println!("| scene | fps (samples, guides, blend, denoiser) | blend ms | raw | denoised | blended with the frames before, denoised | frames held |");
    println!("|---|---|---|---|---|---|---|");
    for (name, m) in quality {
        println!(
            "| {name} | {:.1} | {:.2} | {:.4} | {:.4} | {:.4} | {:.1} |",
            m.fps, m.blend_ms, m.raw, m.denoised, m.blended, m.frames_held
        );
        println!(
            "{}",
            serde_json::json!({"kind": "viewer_moving", "scene": name, "fps": m.fps, "blend_ms": m.blend_ms, "rel_mse_raw": m.raw, "rel_mse_denoised": m.denoised, "rel_mse_blended_denoised": m.blended, "frames_held": m.frames_held})
        );
    }
    Ok(())
}
