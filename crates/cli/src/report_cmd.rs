//! `lucent report`: the hardware study (saarcor) as SaarCOR's and REND3R's tables.

use crate::render_cmd::{choose_camera, load_scene, DemoArg};
use anyhow::{bail, Context, Result};
use lucent_accel::MeshOptions;
use lucent_render::{Camera, World};
use saarcor::dynrtp::{simulate, FrameModel, FrameTrace, Machine, Traced};
use saarcor::precision::{precision_study, Format};
use saarcor::report::{Rend3rReport, SaarcorReport, Tables};
use std::io::IsTerminal as _;
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
    /// Threads of the modelled pipeline (packets in flight; the prototype has 64).
    #[arg(long, default_value_t = 64)]
    pub pipeline_threads: u32,
    /// Cycles from a unit finishing a step to the thread having its result (not printed
    /// in the paper; the default reproduces its thread scaling, see the report).
    #[arg(long, default_value_t = saarcor::dynrtp::UNIT_LATENCY)]
    pub unit_latency: u32,
    /// Cycles from a cache miss's bytes leaving memory to their arrival (not printed in
    /// the paper).
    #[arg(long, default_value_t = saarcor::dynrtp::MEMORY_LATENCY)]
    pub memory_latency: u32,
    /// The kd-trees' surface area heuristic: the cost of a traversal step and of a
    /// triangle test (Wald and Havran's 15,20 by default; only the ratio matters: a
    /// cheaper step makes deeper trees with shorter leaves).
    #[arg(long, value_delimiter = ',', default_value = "15,20")]
    pub kd_cost: Vec<f32>,
    /// The kd-trees' depth limit (0: Havran's 8 + 1.3 log2 N, 32 levels for Conference;
    /// at most 60).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=60))]
    pub kd_max_depth: u32,
    /// For a scene of the paper's (Conference, the sunflowers) at the paper's 1024x768:
    /// measure the kd frame under other modelling choices, each changed alone, to explain
    /// where the model and the paper differ (a few more frames of work).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub gaps: bool,
    /// Split the scene's mesh into at most this many objects first (SaarCOR's Conference
    /// is 54 objects: pieces that touch are one object, the room's walls another, the
    /// nearest merged until this many remain; equal objects become instances of one
    /// geometry). 0: the scene as read.
    #[arg(long, default_value_t = 0)]
    pub objects: usize,
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
    let scene = if a.objects > 0 {
        let (split, st) = saarcor::objects::split_objects(&scene, a.objects);
        eprintln!("split into {} objects ({} distinct geometries) from {} connected pieces", st.objects, st.geometries, st.pieces);
        split
    } else {
        scene
    };
    let triangles = scene
        .instances
        .iter()
        .filter_map(|i| match i.geom {
            lucent_scene::Geom::Mesh(m) => scene.meshes.get(m as usize).map(|m| m.indices.len()),
            _ => None,
        })
        .sum();
    let world = World::new(scene, MeshOptions::default())?;
    let t = Instant::now();
    let [ct, ci] = a.kd_cost[..] else { bail!("--kd-cost needs two costs: a traversal step's and a triangle test's") };
    if !(ct > 0.0 && ci > 0.0 && ct.is_finite() && ci.is_finite()) {
        bail!("--kd-cost: both costs must be positive numbers");
    }
    let kd_opts =
        saarcor::kd::KdOptions { cost_traverse: ct, cost_intersect: ci, max_depth: a.kd_max_depth, ..saarcor::kd::KdOptions::default() };
    let kd = saarcor::kd::kd_of_world_with(&world, kd_opts)?;
    tracing::info!("kd index built in {:.2} s", t.elapsed().as_secs_f64());
    for (i, g) in kd.geometries().iter().enumerate() {
        if let saarcor::kd::KdGeometry::Mesh(m) = g {
            let st = m.tree().stats();
            tracing::info!(
                "kd mesh {i}: {} triangles, {} leaves ({} empty), {:.2} entries a full leaf, depth {}",
                m.triangles(),
                st.leaves,
                st.empty_leaves,
                st.list_entries as f64 / (st.leaves - st.empty_leaves).max(1) as f64,
                st.depth
            );
        }
    }
    let machine = Machine {
        cache_bytes: [a.cache_bytes[0], a.cache_bytes[1], a.cache_bytes[2]],
        cache_items: [a.cache_items; 3],
        threads: a.pipeline_threads.max(1),
        unit_latency: a.unit_latency,
        memory_latency: a.memory_latency,
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
    // Progress: each index's frames (Table 4, Table 3, the threads, the gaps' choices).
    let bar = if std::io::stderr().is_terminal() { indicatif::ProgressBar::new_spinner() } else { indicatif::ProgressBar::hidden() };
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    for ix in &indices {
        let name = ix.name();
        bar.set_message(format!("{name}: Table 4's frame at {}x{}", size4.0, size4.1));
        let trace4 = FrameTrace::new(ix, &cam4);
        rep.table4.push(simulate(&trace4, &machine));
        if matches!(ix, Traced::Kd(_)) && saarcor::paper::table4_of(&rep.scene).is_some() && a.gaps && size4 == (1024, 768) {
            bar.set_message(format!("{name}: the frame under other modelling choices (the gaps table)"));
            rep.variants = variants(&world, &trace4, &cam4, &machine)?;
        }
        bar.set_message(format!("{name}: Table 3's frame and 1 to 64 threads at 512x384"));
        let trace3 = FrameTrace::new(ix, &cam3);
        rep.table3.push(simulate(&trace3, &machine));
        // The paper's scaling statement: fps and usage against threads, at 512x384.
        for t in saarcor::dynrtp::THREAD_SWEEP {
            rep.threads.push(simulate(&trace3, &Machine { threads: t, ..machine }));
        }
    }
    bar.finish_and_clear();
    // lucent's own time for the same rays (the fast single-ray kernels, this machine).
    let t = Instant::now();
    let hits = rend3r_machine::cycles::hit_pixels(&world, &cam4, size4.0, size4.1);
    rep.lucent_ms = Some(t.elapsed().as_secs_f64() * 1e3);
    tracing::debug!("{hits} primary hits");
    if !formats.is_empty() {
        let camp = Camera::new(&desc, a.precision_size.0, a.precision_size.1);
        rep.precision = precision_study(&world, &kd, &camp, &formats);
        rep.pp5 = saarcor::pp5::study();
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

/// The kd frame at the Table 4 size under other modelling choices, each changed alone:
/// the gaps table's measurements.
fn variants(world: &World, trace: &FrameTrace, cam: &Camera, m: &Machine) -> Result<Vec<(String, FrameModel)>> {
    use saarcor::dynrtp::{simulate_in_rows, simulate_in_strips};
    use saarcor::kd::KdOptions;
    let machines = [
        ("the caches see each packet's reads in turn (one thread; fps and usage of one thread)", Machine { threads: 1, ..*m }),
        ("primary rays not made on the transformation unit", Machine { generate_rays: false, ..*m }),
        ("no shading steps on the transformation unit (2 a hit ray)", Machine { shade_steps: 0, ..*m }),
        ("each intersection's result back through the traversal unit (path f)", Machine { results_via_traversal: true, ..*m }),
        (
            "shading reads 60 B a hit ray (three vertices' normals and texture coordinates), not the paper's 28",
            Machine { shade_bytes: 60, ..*m },
        ),
    ];
    let mut out: Vec<(String, FrameModel)> = machines.iter().map(|(what, mc)| ((*what).to_string(), simulate(trace, mc))).collect();
    out.push(("packets handed out in scanline order (rows of 2x2 quads), not 8x8 tiles".into(), simulate_in_rows(trace, m)));
    out.push(("the threads' packets dealt from 64 places of the image at once, not side by side".into(), simulate_in_strips(trace, m, 64)));
    let slow = Machine { unit_latency: 4 * m.unit_latency, memory_latency: 4 * m.memory_latency, ..*m };
    out.push(("memory and unit latencies 4x (64 threads no longer hide them)".into(), simulate(trace, &slow)));
    // Other trees: each rebuilt, its frame traced and simulated (one trace held at a time).
    let trees = [
        (
            "kd-trees with a 3x cheaper traversal step and 40 levels (smaller leaves)",
            KdOptions { cost_traverse: 5.0, max_depth: 40, ..KdOptions::default() },
        ),
        (
            "kd-trees split down to 2 triangles a leaf where a split divides them (40 levels)",
            KdOptions { max_depth: 40, max_leaf: 2, ..KdOptions::default() },
        ),
        (
            "kd-trees split by the triangles' boxes cut at the nodes' faces, not by the clipped triangles",
            KdOptions { perfect_splits: false, ..KdOptions::default() },
        ),
    ];
    for (what, opts) in trees {
        let kd = saarcor::kd::kd_of_world_with(world, opts)?;
        out.push((what.to_string(), simulate(&FrameTrace::new(&Traced::Kd(&kd), cam), m)));
    }
    Ok(out)
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
