//! `lucent view`.

use anyhow::{Context, Result};
use lucent_accel::MeshOptions;
use lucent_render::World;
use lucent_viewer::{Content, ViewOptions};
use rend3r_machine::{FrameSettings, Mode, Processor, SetKind};
use std::path::{Path, PathBuf};

/// Options of `lucent view`.
#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    /// Scene (.obj, .obj.gz, .ply, .gltf, .glb) or REND3R program (.rdr, .mem, .bin).
    /// Without it: the built-in demo scene.
    pub input: Option<PathBuf>,
    #[command(flatten)]
    pub demo: crate::render_cmd::DemoArg,
    /// Start camera as EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV (default: the scene's).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1)]
    pub camera: Option<Vec<f32>>,
    /// Window size.
    #[arg(long, default_value = "1024x768", value_parser = crate::render_cmd::parse_size)]
    pub size: (u32, u32),
    /// Frame rate to hold while moving (the moving resolution adapts to it).
    #[arg(long, default_value_t = 30.0)]
    pub target_fps: f64,
    /// Samples per pixel of a converged still image.
    #[arg(long, default_value_t = 64)]
    pub samples: u32,
    /// Linear resolution scale when movement starts (0.5 = a quarter of the pixels).
    #[arg(long, default_value_t = 0.5)]
    pub moving_scale: f64,
    /// REND3R programs: raytrace or raster.
    #[arg(long, default_value = "raytrace", value_parser = ["raytrace", "raster"])]
    pub mode: String,
    /// Folder for screenshots (lucent-view-0001.png, ...).
    #[arg(long, default_value = ".")]
    pub screenshots: PathBuf,
    /// Print frame rates once a second, and the time to converge when still.
    #[arg(long)]
    pub report: bool,
    /// Close after this many seconds.
    #[arg(long)]
    pub quit_after: Option<f64>,
    /// The integrator shown first (key 4 cycles them).
    #[arg(long, default_value = "whitted", value_parser = crate::render_cmd::INTEGRATORS)]
    pub integrator: String,
    /// Worker threads (per rank with --mpi; default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    #[command(flatten)]
    pub mpi: crate::mpi_cmd::MpiArgs,
}

fn is_program(p: &Path) -> bool {
    let ext = p.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
    matches!(ext.as_str(), "rdr" | "mem" | "bin" | "hex")
}

pub fn run(a: ViewArgs) -> Result<()> {
    let session = crate::mpi_cmd::Session::start(&a.mpi)?;
    if let Some(t) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(t.max(1)).build_global().context("cannot set the thread count")?;
    }
    let opts = ViewOptions {
        size: a.size,
        target_fps: a.target_fps,
        max_samples: a.samples.max(1),
        moving_scale: a.moving_scale,
        screenshot_dir: a.screenshots.clone(),
        report: a.report,
        quit_after: a.quit_after,
        view: match a.integrator.as_str() {
            "path" => 1,
            "vpl" => 2,
            "eye-light" => 3,
            "normals" => 4,
            _ => 0,
        },
    };
    let mut passes = None;
    let content = match a.input.as_deref() {
        Some(p) if is_program(p) && session.is_some() => anyhow::bail!("--mpi renders scenes; REND3R programs run on one process"),
        Some(p) if is_program(p) => {
            let (words, sets) = crate::run_cmd::load_program(p, rend3r_isa::CameraTable::Final)?;
            let processor = Processor::new(words, rend3r_isa::CameraTable::Final).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?;
            let mode = if a.mode == "raster" { Mode::Raster } else { Mode::Raytrace };
            let sets = sets.unwrap_or(SetKind::for_mode(mode));
            let settings = FrameSettings { width: a.size.0, height: a.size.1, mode, sets, painter: false, spp: 1 };
            Content::Program { processor: Box::new(processor), settings, name: p.display().to_string() }
        }
        input => {
            let scene = crate::render_cmd::load_scene(input, &a.demo)?;
            let home = crate::render_cmd::choose_camera(&scene, a.camera.as_deref(), false)?;
            let st = scene.stats();
            let stats = format!("{} tris, {} instances, {} lights", st.triangles, st.instances, scene.lights.len());
            let mut world = World::new(scene, MeshOptions::default()).context("cannot build the scene")?;
            world.ensure_light(home.eye);
            if let Some(s) = &session {
                // Every rank renders the passes the window on rank 0 shows.
                if s.rank() != 0 {
                    return s.serve(&mut world, None, home);
                }
                passes = Some(s.passes(&world)?);
            }
            let name = input.map_or_else(|| a.demo.label(), |p| p.display().to_string());
            Content::Scene { world: Box::new(world), home, stats, name }
        }
    };
    lucent_viewer::run_with(content, opts, passes)?;
    Ok(())
}
