//! `lucent render` and `lucent info`.

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use lucent_accel::{MeshOptions, TriangleTest};
use lucent_render::{
    framing_camera, render, render_region, Camera, FilmAccumulator, Integrator, PathSettings, Region, RenderSettings, Traversal,
    WhittedSettings, World,
};
use lucent_scene::{CameraDesc, Scene};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `lucent render`.
pub struct RenderArgs {
    pub scene: Option<PathBuf>,
    pub demo: DemoArg,
    pub camera: Option<Vec<f32>>,
    pub ortho: bool,
    pub size: (u32, u32),
    pub spp: u32,
    pub time: Option<f64>,
    pub threads: Option<usize>,
    pub output: PathBuf,
    pub integrator: Integrator,
    pub watertight: bool,
    pub single_rays: bool,
    pub quality: lucent_accel::Quality,
}

/// The integrators `--integrator` names.
pub const INTEGRATORS: [&str; 4] = ["whitted", "path", "eye-light", "normals"];

/// The integrator `--integrator NAME` (one of [`INTEGRATORS`]) names, with the settings of
/// `--max-depth` and `--no-shadows` (Whitted) or `--max-depth`, `--rr-depth` and
/// `--hide-emitters` (path).
pub fn integrator_of(name: &str, max_depth: Option<u32>, no_shadows: bool, rr_depth: u32, hide_emitters: bool) -> Integrator {
    match name {
        "eye-light" => Integrator::EyeLight,
        "normals" => Integrator::Normals,
        "path" => {
            Integrator::Path(PathSettings { max_depth: max_depth.unwrap_or(u32::MAX), rr_depth, hide_emitters, ..PathSettings::default() })
        }
        _ => Integrator::Whitted(WhittedSettings {
            max_depth: max_depth.unwrap_or(WhittedSettings::default().max_depth),
            shadows: !no_shadows,
        }),
    }
}

/// Parses "WxH".
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT (e.g. 1024x768)"))?;
    let w: u32 = w.trim().parse().map_err(|_| format!("'{w}' is not a width"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("'{h}' is not a height"))?;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(format!("{w}x{h}: each side must be 1..=16384"));
    }
    Ok((w, h))
}

/// The built-in scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Demo {
    /// The feature demo (textured floor, mirror and glass spheres, cylinder, cone, mesh).
    Default,
    /// 5,622 instanced sunflowers of 32k triangles each, swaying.
    Sunflowers,
}

impl Demo {
    /// The name `--demo` takes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Demo::Default => "default",
            Demo::Sunflowers => "sunflowers",
        }
    }
}

/// `--demo`, shared by every command that loads a scene.
#[derive(clap::Args, Clone, Copy, Debug, Default)]
pub struct DemoArg {
    /// A built-in scene instead of a file.
    #[arg(long, value_enum)]
    pub demo: Option<Demo>,
    /// Refuse a glTF file that breaks any rule of the glTF 2.0 specification, naming the
    /// JSON pointer of the first one. By default lucent warns and renders what it can read.
    #[arg(long)]
    pub strict: bool,
}

impl DemoArg {
    /// How a scene loaded without a file is named in messages.
    #[must_use]
    pub fn label(self) -> String {
        format!("built-in {} demo", self.demo.unwrap_or(Demo::Default).name())
    }
}

/// Loads a scene file, or a built-in scene (`--demo`), else the default demo when there is
/// no file.
pub fn load_scene(path: Option<&Path>, demo: DemoArg) -> Result<Scene> {
    match (path, demo.demo) {
        (Some(_), Some(_)) => bail!("give a scene file or --demo, not both"),
        (None, Some(Demo::Sunflowers)) => Ok(lucent_scene::sunflower_scene()),
        (None, _) => Ok(lucent_scene::demo_scene()),
        (Some(p), None) => lucent_scene::load_with(p, &lucent_scene::LoadOptions { strict: demo.strict }).map_err(anyhow::Error::from),
    }
}

/// The camera to use: `--camera`, else the scene's, else one framing the bounds.
pub fn choose_camera(scene: &Scene, camera: Option<&[f32]>, ortho: bool) -> Result<CameraDesc> {
    let mut desc = match camera {
        Some(c) => match <&[f32; 10]>::try_from(c) {
            Ok(v) if v.iter().all(|x| x.is_finite()) => CameraDesc::from_view(v),
            _ => bail!("--camera needs 10 finite numbers EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV (got {})", c.len()),
        },
        None => match (scene.camera, scene.bounds()) {
            (Some(c), _) => c,
            (None, Some((lo, hi))) => framing_camera(lo, hi),
            (None, None) => bail!("the scene is empty: nothing to frame"),
        },
    };
    if ortho {
        let dist = (desc.look_at - desc.eye).length();
        desc.ortho_height = Some(2.0 * dist * (desc.vfov_deg.to_radians() * 0.5).tan());
    }
    Ok(desc)
}

pub fn run(a: RenderArgs) -> Result<()> {
    if let Some(t) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(t.max(1)).build_global().context("cannot set the thread count")?;
    }
    let t0 = Instant::now();
    let scene = load_scene(a.scene.as_deref(), a.demo)?;
    let load_s = t0.elapsed().as_secs_f64();
    let desc = choose_camera(&scene, a.camera.as_deref(), a.ortho)?;
    let st = scene.stats();
    let t1 = Instant::now();
    let opts = MeshOptions {
        test: if a.watertight { TriangleTest::Watertight } else { TriangleTest::UnitTriangle },
        quality: a.quality,
        ..MeshOptions::default()
    };
    let mut world = World::new(scene, opts)?;
    if world.ensure_light(desc.eye) {
        tracing::info!("the scene has no lights: using a headlight at the camera");
    }
    let build_s = t1.elapsed().as_secs_f64();
    let (w, h) = a.size;
    let settings = RenderSettings {
        spp: a.spp.max(1),
        integrator: a.integrator,
        traversal: Traversal { packets: !a.single_rays },
        ..RenderSettings::new(w, h)
    };
    let cam = Camera::new(&desc, w, h);
    let t2 = Instant::now();
    let (film, rays, spp) = match a.time {
        None => {
            let tiles = (w.div_ceil(lucent_render::TILE) * h.div_ceil(lucent_render::TILE)) as u64;
            let bar = if std::io::stderr().is_terminal() { ProgressBar::new(tiles) } else { ProgressBar::hidden() };
            bar.set_style(
                ProgressStyle::with_template("{spinner} rendering [{bar:40}] {pos}/{len} tiles {elapsed}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            let (film, rays) = render(&world, &cam, &settings, &|n| bar.inc(n));
            bar.finish_and_clear();
            (film, rays, settings.spp)
        }
        Some(budget) => render_for(&world, &cam, &settings, budget, a.spp)?,
    };
    let render_s = t2.elapsed().as_secs_f64();
    film.save(&a.output)?;
    println!("scene: {} triangles, {} instances, {} lights", st.triangles, st.instances, world.lights().len());
    println!(
        "load {:.1} ms, build {:.1} ms, render {:.1} ms ({}x{}, {} spp, {} threads)",
        load_s * 1e3,
        build_s * 1e3,
        render_s * 1e3,
        w,
        h,
        spp,
        rayon::current_num_threads()
    );
    let samples = f64::from(w) * f64::from(h) * f64::from(spp);
    println!("{:.3} M samples/s", samples / render_s.max(1e-9) * 1e-6);
    println!("{rays} rays, {:.2} Mrays/s", rays as f64 / render_s.max(1e-9) * 1e-6);
    println!("wrote {}", a.output.display());
    Ok(())
}

/// Renders for `budget` seconds: passes of whole-image regions of the next samples (one
/// sample, doubling while a pass takes under a sixteenth of the budget), merged into a
/// film accumulator, until the time is spent or `cap` samples (when above 1) are in.
/// Returns the image, the rays traced and the samples per pixel.
fn render_for(world: &World, cam: &Camera, settings: &RenderSettings, budget: f64, cap: u32) -> Result<(lucent_render::Film, u64, u32)> {
    if !(budget.is_finite() && budget > 0.0) {
        bail!("--time must be a positive number of seconds (got {budget})");
    }
    let cap = if cap > 1 { cap } else { u32::MAX };
    // The image has as many samples as the cap (jittered from the first).
    let st = RenderSettings { spp: cap.max(2), ..*settings };
    let (w, h) = (st.width, st.height);
    let mut acc = FilmAccumulator::new(w, h);
    let bar = if std::io::stderr().is_terminal() { ProgressBar::new((budget * 1e3) as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{spinner} rendering [{bar:40}] {elapsed} {msg}").unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    let (mut s0, mut chunk, mut rays) = (0u32, 1u32, 0u64);
    while s0 < cap && (s0 == 0 || start.elapsed().as_secs_f64() < budget) {
        let s1 = s0.saturating_add(chunk).min(cap);
        let t = Instant::now();
        let (part, r) = render_region(world, cam, &st, Region::full(w, h, s0, s1), &|_| {});
        acc.merge(part)?;
        rays += r;
        s0 = s1;
        if t.elapsed().as_secs_f64() < budget / 16.0 {
            chunk = chunk.saturating_mul(2);
        }
        let elapsed = start.elapsed().as_secs_f64();
        bar.set_position(((elapsed.min(budget)) * 1e3) as u64);
        bar.set_message(format!("{s0} spp, {:.2} M samples/s", f64::from(w) * f64::from(h) * f64::from(s0) / elapsed.max(1e-9) * 1e-6));
    }
    bar.finish_and_clear();
    Ok((acc.resolve(world.scene().background), rays, s0))
}

pub fn info(path: Option<&Path>, demo: DemoArg) -> Result<()> {
    let scene = load_scene(path, demo)?;
    let st = scene.stats();
    println!("scene:      {}", path.map_or_else(|| format!("({})", demo.label()), |p| p.display().to_string()));
    println!("triangles:  {} ({} instanced)", st.triangles, st.instanced_triangles);
    println!("vertices:   {}", st.vertices);
    println!("meshes:     {}", st.meshes);
    println!("instances:  {}", st.instances);
    println!("materials:  {}", st.materials);
    println!("textures:   {}", st.textures);
    println!("lights:     {}", st.lights);
    match scene.bounds() {
        Some((lo, hi)) => println!("bounds:     [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}]", lo.x, lo.y, lo.z, hi.x, hi.y, hi.z),
        None => println!("bounds:     empty"),
    }
    if let Some(c) = scene.camera {
        println!(
            "camera:     eye {:?} look-at {:?} up {:?} vfov {:.1}",
            c.eye.to_array(),
            c.look_at.to_array(),
            c.up.to_array(),
            c.vfov_deg
        );
    }
    let t = Instant::now();
    let world = World::new(scene, MeshOptions::default())?;
    let (top, bottom) = world.accel().stats();
    println!(
        "accel:      {} bytes ({:.1} per triangle): BLAS {} nodes, {} bytes; TLAS {} nodes, {} bytes; built in {:.1} ms",
        top.bytes + bottom.bytes,
        (top.bytes + bottom.bytes) as f64 / st.triangles.max(1) as f64,
        bottom.nodes,
        bottom.bytes,
        top.nodes,
        top.bytes,
        t.elapsed().as_secs_f64() * 1e3
    );
    Ok(())
}
