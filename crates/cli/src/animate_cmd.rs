//! `lucent animate`: renders a glTF animation to numbered PNGs with the scene's animated
//! camera, and reports per-frame update and render times.

use crate::stats::median;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use lucent_accel::MeshOptions;
use lucent_render::{render, Camera, Integrator, RenderSettings, World};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

pub struct AnimateArgs {
    pub scene: Option<PathBuf>,
    pub demo: crate::render_cmd::DemoArg,
    pub from: Option<f32>,
    pub to: Option<f32>,
    pub fps: f32,
    pub size: (u32, u32),
    pub camera: Option<Vec<f32>>,
    pub spp: u32,
    pub integrator: Integrator,
    pub output: PathBuf,
}

pub fn run(a: AnimateArgs) -> Result<()> {
    if !(a.fps.is_finite() && a.fps > 0.0) {
        bail!("--fps must be a positive number (got {})", a.fps);
    }
    let scene = crate::render_cmd::load_scene(a.scene.as_deref(), &a.demo)?;
    let name = a.scene.as_ref().map_or_else(|| format!("the {}", a.demo.label()), |p| p.display().to_string());
    let range = scene.animation.as_ref().map(|an| an.time_range());
    if range.is_none() {
        tracing::warn!("{name} has no animation: every frame is the same");
    }
    let (lo, hi) = range.unwrap_or((0.0, 0.0));
    let from = a.from.unwrap_or(lo);
    let to = a.to.unwrap_or(hi);
    if !(from.is_finite() && to.is_finite()) || to < from {
        bail!("--from {from} --to {to}: the end must not be before the start");
    }
    let fixed = match &a.camera {
        Some(_) => Some(crate::render_cmd::choose_camera(&scene, a.camera.as_deref(), false)?),
        None => None,
    };
    let fallback = crate::render_cmd::choose_camera(&scene, None, false)?;
    let frames = ((to - from) * a.fps).floor() as u64 + 1;
    std::fs::create_dir_all(&a.output).with_context(|| format!("cannot create {}", a.output.display()))?;
    let t0 = Instant::now();
    let mut world = World::new(scene, MeshOptions::default())?;
    world.ensure_light(fallback.eye);
    println!("{name}: built in {:.1} ms; {frames} frames from {from:.3} s to {to:.3} s at {} fps", t0.elapsed().as_secs_f64() * 1e3, a.fps);
    let settings = RenderSettings { spp: a.spp.max(1), integrator: a.integrator, ..RenderSettings::new(a.size.0, a.size.1) };
    let bar = if std::io::stderr().is_terminal() { ProgressBar::new(frames) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{spinner} frames [{bar:40}] {pos}/{len} {per_sec} eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let (mut update_ms, mut render_ms) = (Vec::new(), Vec::new());
    for k in 0..frames {
        let t = from + k as f32 / a.fps;
        let tu = Instant::now();
        let cam = world.set_time(t)?;
        update_ms.push(tu.elapsed().as_secs_f64() * 1e3);
        let desc = fixed.or(cam).unwrap_or(fallback);
        let tr = Instant::now();
        let (film, _) = render(&world, &Camera::new(&desc, a.size.0, a.size.1), &settings, &|_| {});
        render_ms.push(tr.elapsed().as_secs_f64() * 1e3);
        film.save(&a.output.join(format!("frame-{:04}.png", k + 1)))?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let (u, r) = (median(&mut update_ms), median(&mut render_ms));
    println!(
        "{frames} frames at {}x{} -> {}: median update {u:.2} ms, render {r:.1} ms ({:.1} fps update + render), {} threads",
        a.size.0,
        a.size.1,
        a.output.display(),
        1e3 / (u + r).max(1e-9),
        rayon::current_num_threads()
    );
    Ok(())
}
