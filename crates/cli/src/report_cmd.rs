//! `lucent report`: the hardware study (saarcor) as SaarCOR's and REND3R's tables.

use crate::render_cmd::{choose_camera, load_scene, DemoArg};
use anyhow::{bail, Context, Result};
use lucent_accel::MeshOptions;
use lucent_render::{Camera, World};
use saarcor::dynrtp::{model_frame, Machine, Traced};
use saarcor::precision::{precision_study, Format};
use saarcor::report::{Rend3rReport, SaarcorReport, Tables};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
pub struct ReportArgs {
    /// A scene file (SaarCOR model) or a REND3R program (.rdr/.mem/.bin: REND3R's cycle
    /// model). Without it: the built-in demo scene (or --demo).
    pub input: Option<PathBuf>,
    #[command(flatten)]
    pub demo: DemoArg,
    /// The machine to model: saarcor (scenes) or rend3r (programs). Default: from the input.
    #[arg(long, value_parser = ["saarcor", "rend3r"])]
    pub machine: Option<String>,
    /// Index the rays traverse: bvh (lucent's), kd (SaarCOR's kd-trees, packets of 4), or
    /// both (side by side).
    #[arg(long, default_value = "both", value_parser = ["bvh", "kd", "both"])]
    pub index: String,
    /// Image size for Table 4 (Table 3 is always 512x384). Default: 1024x768, as the paper.
    #[arg(long, value_parser = crate::render_cmd::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Reduced precisions to emulate (comma separated: f24, f16, fixed; "none" for none).
    #[arg(long, default_value = "f24,f16,fixed")]
    pub precision: String,
    /// Size of the precision images.
    #[arg(long, default_value = "256x192", value_parser = crate::render_cmd::parse_size)]
    pub precision_size: (u32, u32),
    /// Cache sizes in bytes: traversal, list, transformation.
    #[arg(long, value_delimiter = ',', default_value = "4096,2048,6144")]
    pub cache_bytes: Vec<u64>,
    /// Items per cache (one number for all three).
    #[arg(long, default_value_t = 512)]
    pub cache_items: u64,
    /// Print one JSON line per table row instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// Also write an HTML page with plots (and its PNG images beside it).
    #[arg(long)]
    pub html: Option<PathBuf>,
    /// Camera as EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV (default: the scene's).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub camera: Option<Vec<f32>>,
    /// REND3R programs: frames to report.
    #[arg(long, default_value_t = 4)]
    pub frames: u64,
}

fn is_program(p: &Path) -> bool {
    p.extension().is_some_and(|e| ["rdr", "mem", "bin", "hex"].iter().any(|x| e.eq_ignore_ascii_case(x)))
}

pub fn run(a: ReportArgs) -> Result<()> {
    let program = a.input.as_deref().is_some_and(is_program);
    match (a.machine.as_deref(), program) {
        (Some("rend3r"), false) => bail!("--machine rend3r models REND3R programs (.rdr, .mem, .bin); give one"),
        (Some("saarcor"), true) => bail!(
            "--machine saarcor models scenes; {} is a REND3R program",
            a.input.as_deref().map_or(String::new(), |p| p.display().to_string())
        ),
        _ => {}
    }
    if program {
        rend3r(&a)
    } else {
        saarcor(&a)
    }
}

fn formats(s: &str) -> Result<Vec<Format>> {
    if s == "none" {
        return Ok(Vec::new());
    }
    s.split(',')
        .map(|f| Format::parse(f.trim()).with_context(|| format!("--precision: unknown format '{f}' (f24, f16, fixed or none)")))
        .collect()
}

fn saarcor(a: &ReportArgs) -> Result<()> {
    if a.cache_bytes.len() != 3 || a.cache_bytes.contains(&0) || a.cache_items == 0 {
        bail!("--cache-bytes needs three sizes above 0 (traversal, list, transformation) and --cache-items a count above 0");
    }
    let formats = formats(&a.precision)?;
    let scene = load_scene(a.input.as_deref(), &a.demo)?;
    let name = a.input.as_deref().map_or_else(|| a.demo.label(), |p| p.display().to_string());
    // The harness presets' cameras (shared/scenes/README.md) for their files.
    let preset = a.input.as_deref().and_then(|p| crate::frame_bench::PRESETS.iter().find(|q| p.ends_with(q.file)));
    let desc = match (preset, a.camera.as_deref()) {
        (Some(q), None) => choose_camera(&scene, Some(&q.cam), false)?,
        (_, cam) => choose_camera(&scene, cam, false)?,
    };
    let triangles = scene.meshes.iter().map(|m| m.indices.len()).sum();
    let world = World::new(scene, MeshOptions::default())?;
    let t = Instant::now();
    let kd = saarcor::kd_of_world(&world)?;
    tracing::info!("kd index built in {:.2} s", t.elapsed().as_secs_f64());
    let machine = Machine {
        cache_bytes: [a.cache_bytes[0], a.cache_bytes[1], a.cache_bytes[2]],
        cache_items: [a.cache_items; 3],
        ..Machine::default()
    };
    let indices: Vec<Traced<'_>> = match a.index.as_str() {
        "bvh" => vec![Traced::Bvh(world.accel())],
        "kd" => vec![Traced::Kd(&kd)],
        _ => vec![Traced::Bvh(world.accel()), Traced::Kd(&kd)],
    };
    let size4 = a.size.unwrap_or((1024, 768));
    let cam4 = Camera::new(&desc, size4.0, size4.1);
    let cam3 = Camera::new(&desc, 512, 384);
    let (top, bottom) = world.accel().stats();
    let mut rep = SaarcorReport {
        scene: name,
        triangles,
        instances: world.accel().instances().len(),
        index_bytes: vec![("bvh", top.bytes + bottom.bytes), ("kd", kd.bytes())],
        precision_size: a.precision_size,
        ..SaarcorReport::default()
    };
    for ix in &indices {
        rep.table4.push(model_frame(ix, &cam4, &machine));
        rep.table3.push(if size4 == (512, 384) { rep.table4[rep.table4.len() - 1].clone() } else { model_frame(ix, &cam3, &machine) });
    }
    // lucent's own time for the same rays (the fast single-ray kernels, this machine).
    let t = Instant::now();
    let hits = rend3r_machine::cycles::hit_pixels(&world, &cam4, size4.0, size4.1);
    rep.lucent_ms = Some(t.elapsed().as_secs_f64() * 1e3);
    tracing::debug!("{hits} primary hits");
    if !formats.is_empty() {
        let camp = Camera::new(&desc, a.precision_size.0, a.precision_size.1);
        rep.precision = precision_study(&world, &kd, &camp, &formats);
    }
    print_tables(a.json, &rep);
    if let Some(path) = &a.html {
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let stem = path.file_stem().map_or("report".into(), |s| s.to_string_lossy().into_owned());
        let html = rep.html(dir, &stem)?;
        std::fs::write(path, html).with_context(|| format!("cannot write {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// The tables on standard output: JSON lines with `--json`, else Markdown.
fn print_tables(json: bool, rep: &impl Tables) {
    if json {
        for l in rep.json_lines() {
            println!("{l}");
        }
    } else {
        print!("{}", rep.markdown());
    }
}

fn rend3r(a: &ReportArgs) -> Result<()> {
    use rend3r_machine::{render_frame, FrameSettings, Mode, Processor, SetKind, Step};
    let Some(path) = a.input.as_deref() else { bail!("give a REND3R program") };
    let (words, kind) = crate::run_cmd::load_program(path, rend3r_isa::CameraTable::Final)?;
    let sets = kind.unwrap_or(SetKind::Shapes);
    let mode = if sets == SetKind::Triangles { Mode::Raster } else { Mode::Raytrace };
    let size = a.size.unwrap_or((512, 384));
    let fs = FrameSettings { width: size.0, height: size.1, mode, sets, painter: false, spp: 1 };
    let mut p = Processor::new(words, rend3r_isa::CameraTable::Final).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let mut rep = Rend3rReport {
        program: path.display().to_string(),
        mode: if mode == Mode::Raster { "raster" } else { "raytrace" },
        size,
        ..Rend3rReport::default()
    };
    for frame in 1..=a.frames {
        if p.run_to_frame(50_000_000) != Step::Frame {
            break;
        }
        let t = Instant::now();
        render_frame(&p.state, &fs)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let (c, hits) = rend3r_machine::cycles::frame_cycles(&p.state, &fs)?;
        rep.frames.push((frame, p.state.used_sets() as u64, p.state.used_lights() as u64, c.worst, c.board, hits, ms));
    }
    print_tables(a.json, &rep);
    if let Some(path) = &a.html {
        std::fs::write(path, rep.html()).with_context(|| format!("cannot write {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}
