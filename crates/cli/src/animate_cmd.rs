//! `lucent animate`: renders a glTF animation to numbered PNGs with the scene's animated
//! camera, and reports per-frame update and render times.

use crate::stats::median;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use lucent_accel::MeshOptions;
use lucent_render::{render, Camera, RenderSettings, World};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

/// Options of `lucent animate`.
#[derive(clap::Args, Debug)]
pub struct AnimateArgs {
    /// Scene (.gltf/.glb with animations). Without it: the built-in demo (static).
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub demo: crate::render_cmd::DemoArg,
    /// Start time in seconds (default: the first key).
    #[arg(long, allow_hyphen_values = true)]
    pub from: Option<f32>,
    /// End time in seconds (default: the last key).
    #[arg(long, allow_hyphen_values = true)]
    pub to: Option<f32>,
    /// Frames per second of animation time.
    #[arg(long, default_value_t = 30.0)]
    pub fps: f32,
    /// Frame size.
    #[arg(long, default_value = "512x384", value_parser = crate::render_cmd::parse_size)]
    pub size: (u32, u32),
    /// Fixed camera EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV instead of the scene's animated one.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1)]
    pub camera: Option<Vec<f32>>,
    /// Samples per pixel.
    #[arg(long, default_value_t = 1)]
    pub spp: u32,
    /// What the rays compute: `whitted`, `path`, `vpl`, `eye-light` or `normals` (as
    /// `lucent render`).
    #[arg(long, default_value = "whitted", value_parser = crate::render_cmd::INTEGRATORS)]
    pub integrator: String,
    /// Whitted: most reflection/refraction generations (0: primary rays, shadows and
    /// shading only; default 6). Path: most path segments (default unlimited).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Turn shadow rays off.
    #[arg(long)]
    pub no_shadows: bool,
    /// Output folder for frame-0001.png, ...
    #[arg(short, long, default_value = "frames")]
    pub output: PathBuf,
    /// Worker threads (per rank with --mpi; default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// With --mpi: `frames` gives each rank whole frames, `tiles` shares each frame's
    /// tiles among the ranks, `auto` takes frames when there are at least twice as many
    /// frames as ranks.
    #[arg(long, default_value = "auto", value_parser = ["auto", "frames", "tiles"])]
    pub mpi_mode: String,
    #[command(flatten)]
    pub mpi: crate::mpi_cmd::MpiArgs,
}

pub fn run(a: AnimateArgs) -> Result<()> {
    let session = crate::mpi_cmd::Session::start(&a.mpi)?;
    if let Some(t) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(t.max(1)).build_global().context("cannot set the thread count")?;
    }
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
    let t0 = Instant::now();
    let mut world = World::new(scene, MeshOptions::default())?;
    world.ensure_light(fallback.eye);
    if let Some(s) = session.as_ref().filter(|s| s.rank() != 0) {
        return s.serve(&mut world, fixed, fallback);
    }
    std::fs::create_dir_all(&a.output).with_context(|| format!("cannot create {}", a.output.display()))?;
    println!("{name}: built in {:.1} ms; {frames} frames from {from:.3} s to {to:.3} s at {} fps", t0.elapsed().as_secs_f64() * 1e3, a.fps);
    let Some(integrator) = lucent_render::setup::integrator_named(&a.integrator, world.scene(), a.max_depth, Some(5), false, a.no_shadows)
    else {
        bail!("--integrator {}: not one of {}", a.integrator, crate::render_cmd::INTEGRATORS.join(", "));
    };
    let settings = RenderSettings { spp: a.spp.max(1), integrator, ..RenderSettings::new(a.size.0, a.size.1) };
    let bar = if std::io::stderr().is_terminal() { ProgressBar::new(frames) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{spinner} frames [{bar:40}] {pos}/{len} {per_sec} eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    if let Some(s) = &session {
        return animate_mpi(s, &a, &mut world, (fixed, fallback), from, frames, &settings, &bar);
    }
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

/// `lucent animate --mpi` on rank 0: the frames over every rank (whole frames to each, or
/// each frame's tiles shared), each written as it completes.
#[allow(clippy::too_many_arguments)]
fn animate_mpi(
    s: &crate::mpi_cmd::Session,
    a: &AnimateArgs,
    world: &mut World,
    (fixed, fallback): (Option<lucent_scene::CameraDesc>, lucent_scene::CameraDesc),
    from: f32,
    frames: u64,
    settings: &RenderSettings,
    bar: &ProgressBar,
) -> Result<()> {
    use crate::mpi_cmd::AnimateMode;
    let mode = match a.mpi_mode.as_str() {
        "frames" => AnimateMode::Frames,
        "tiles" => AnimateMode::Tiles,
        _ if frames >= 2 * s.size() as u64 => AnimateMode::Frames,
        _ => AnimateMode::Tiles,
    };
    let times: Vec<f32> = (0..frames).map(|k| from + k as f32 / a.fps).collect();
    let t = Instant::now();
    let st = s.animate(world, fixed, fallback, &times, settings, mode, &mut |k, film| {
        film.save(&a.output.join(format!("frame-{:04}.png", k + 1)))?;
        bar.inc(1);
        Ok(())
    })?;
    bar.finish_and_clear();
    let all = t.elapsed().as_secs_f64();
    println!(
        "{frames} frames at {}x{} -> {} on {} ranks ({:?}): {:.2} s, {:.2} frames/s",
        settings.width,
        settings.height,
        a.output.display(),
        s.size(),
        mode,
        all,
        frames as f64 / all.max(1e-9),
    );
    println!("{}", crate::render_cmd::cluster_summary(s.size(), &st));
    Ok(())
}
