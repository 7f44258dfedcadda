//! `lucent render` and `lucent info`.

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use lucent_accel::{MeshOptions, TriangleTest};
use lucent_render::progressive::{Passes, Progressive};
use lucent_render::{render, render_region, Camera, Film, Integrator, PathSettings, Region, RenderSettings, VplSettings, World};
use lucent_scene::{AovKind, CameraDesc, Scene};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The least samples per pixel from which `--denoise` measures each pixel's noise from the
/// two halves of its samples. Chosen on the denoiser's tuning scenes (`lucent bench
/// denoise`, 256x192, relMSE against 2048 samples, median of three seeds): at 16 samples
/// the halves' variance beat the neighbourhood's estimate on all three (Cornell box 0.0010
/// -> 0.0009, Sponza 0.0059 -> 0.0052, the kitchen 0.0308 -> 0.0270); at 4 samples (halves
/// of two) it lost on the Cornell box (0.0017 -> 0.0020), tied on Sponza and won on the
/// kitchen.
const HALVES_SPP: u32 = 16;

/// Which denoiser `--denoise` runs.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Denoiser {
    /// The regression denoiser for path tracing from 4 samples per pixel (not for a
    /// crop window or a time budget), else the à-trous filter; a built-in scene shown
    /// by default gets the à-trous filter (its first image in seconds).
    Auto,
    /// First-order regression on the two halves of the samples, after NFOR (Bitterli et
    /// al. 2016): the better image, about a minute per megapixel on two cores.
    Regression,
    /// The edge-avoiding à-trous filter: tens of milliseconds.
    Atrous,
}

/// Options of `lucent render`.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Scene file (.obj, .obj.gz, .ply, .gltf, .glb, or a Mitsuba 3 .xml scene). Without it:
    /// a built-in scene (the path-tracing studio, or the feature demo for the other
    /// integrators).
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub demo: DemoArg,
    /// Camera as EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV: eye, look-at point, up vector, vertical
    /// field of view in degrees. Default: the scene's camera, else one framing the scene.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1)]
    pub camera: Option<Vec<f32>>,
    /// Orthographic projection (same view height as the perspective view at the look-at point).
    #[arg(long)]
    pub ortho: bool,
    /// Image size WIDTHxHEIGHT. Default: the scene file's film (Mitsuba), else 1024x768.
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Samples per pixel (jittered, deterministic per pixel and sample). Default: the scene
    /// file's (Mitsuba), else 16 for path tracing and 1 for the others.
    #[arg(long)]
    pub spp: Option<u32>,
    /// Render for this many seconds instead, adding samples pass by pass (each pass a
    /// region of the film; --spp above 1 still caps the count), and report how many
    /// fit.
    #[arg(long)]
    pub time: Option<f64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output image: .png (8-bit sRGB, tone-mapped by clamping) or .exr (linear float).
    #[arg(short, long, default_value = "out.png")]
    pub output: PathBuf,
    /// With an .exr output: also write the layers a denoiser is guided by, for the first
    /// surface each pixel sees: `albedo.R/G/B`, the shading normal `N.X/Y/Z` and the
    /// distance `Z`.
    #[arg(long)]
    pub aovs: bool,
    /// What the rays compute: `path` (path tracing, the default: area lights, soft
    /// shadows, light bouncing between surfaces, every material's BSDF; converges as --spp
    /// grows), `vpl` (direct light plus indirect light from virtual point lights, as
    /// SaarCOR: a smooth approximation of the path tracer's image in one sample per
    /// pixel; see --vpls), `whitted` (point lights, hard shadows, mirror and glass),
    /// `eye-light` (a light at the eye, no shadows: the fastest preview) or `normals`
    /// (shading normals as colours). `path-scalar` is the path tracer one path after
    /// another (the reference the default, which traces many paths at once on SIMD lanes,
    /// is tested against).
    #[arg(long, value_parser = INTEGRATORS)]
    pub integrator: Option<String>,
    /// Whitted: most reflection/refraction generations (default 6). Path and VPL: most
    /// path segments, as Mitsuba counts them (1: emitters only, 2: direct light; default:
    /// the scene file's, else unlimited).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Path: the depth from which Russian roulette may end paths (default: the scene
    /// file's, else 5).
    #[arg(long)]
    pub rr_depth: Option<u32>,
    /// Path: emitters seen directly from the camera show the background.
    #[arg(long)]
    pub hide_emitters: bool,
    /// Path: the sampler's seed (another seed, another equally good set of samples).
    #[arg(long)]
    pub seed: Option<u32>,
    /// Denoise the image, guided by the albedo, normal and distance of the first surface
    /// each pixel sees (through mirrors and glass): a few samples per pixel look like many
    /// more. Path tracing from 4 samples per pixel: a first-order regression over the two
    /// halves of the samples (each half filtered with weights from the other, the best of
    /// several strengths chosen pixel by pixel); else an edge-avoiding à-trous filter
    /// (see --denoiser). A built-in scene (no scene file) is denoised by default when path
    /// traced or lit by VPLs, at 8 samples per pixel unless --spp says.
    #[arg(long, conflicts_with = "no_denoise")]
    pub denoise: bool,
    /// Do not denoise a built-in scene (see --denoise).
    #[arg(long)]
    pub no_denoise: bool,
    /// Which denoiser --denoise runs (regression needs path tracing, at least 4 samples
    /// per pixel and the whole film; otherwise the à-trous filter runs).
    #[arg(long, value_enum, default_value_t = Denoiser::Auto)]
    pub denoiser: Denoiser,
    /// VPL: virtual point lights per frame (each sample of a pixel is a frame with its own
    /// set).
    #[arg(long, default_value_t = VplSettings::default().count)]
    pub vpls: u32,
    /// VPL: the least distance at which a VPL's light is evaluated, as a fraction of the
    /// scene's diagonal: larger removes more of the bright spots near VPLs and darkens
    /// corners more; 0 turns clamping off (unbiased, noisy).
    #[arg(long, default_value_t = VplSettings::default().clamp)]
    pub vpl_clamp: f32,
    /// VPL: interleaved sampling over M×M pixels (each pixel lit by one of M² sets of the
    /// VPLs; 1: every pixel by all of them).
    #[arg(long, default_value_t = VplSettings::default().interleave)]
    pub interleave: u32,
    /// VPL: leave the interleaving pattern in (no discontinuity buffer).
    #[arg(long)]
    pub no_discontinuity: bool,
    /// Turn shadow rays off (Whitted).
    #[arg(long)]
    pub no_shadows: bool,
    /// Use the watertight triangle test instead of the unit-triangle test.
    #[arg(long)]
    pub watertight: bool,
    /// Trace every ray on its own instead of in 8×8 packets (the same image, slower;
    /// for comparisons).
    #[arg(long)]
    pub single_rays: bool,
    /// The film's reconstruction filter: `box` (each pixel the mean of the samples in its
    /// square), `tent[:RADIUS]` (radius 1 pixel unless given), `gaussian[:STDDEV]`
    /// (σ 0.5 pixel, out to 4σ: Mitsuba's default), or the sharper filters with negative
    /// lobes, `mitchell` (B = C = 1/3), `catmullrom` and `lanczos[:LOBES]` (3 unless given),
    /// whose samples carry signed weights (the VPL integrator takes box for these).
    /// Default: the scene file's (Mitsuba XML's film), else box.
    #[arg(long, value_parser = parse_filter)]
    pub filter: Option<lucent_scene::PixelFilter>,
    /// BVH quality: `high` (binned SAH, then insertion-based optimization: the
    /// default), `sah` (binned SAH only: the shortest build, rays 5-15% slower) or
    /// `spatial` (binned SAH with spatial splits: triangles cut between leaves; much
    /// faster on scenes of large, overlapping triangles such as Sponza, slower on
    /// others, up to 2× the build).
    #[arg(long, default_value = "high", value_parser = ["high", "sah", "spatial"])]
    pub quality: String,
    #[command(flatten)]
    pub mpi: crate::mpi_cmd::MpiArgs,
}

/// The integrators `--integrator` names.
pub use lucent_render::setup::INTEGRATORS;

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
    /// The path tracer's studio: an area light's soft shadows, glossy and polished metal,
    /// glass, plastic and coloured walls bleeding onto the floor.
    Studio,
    /// 5,622 instanced sunflowers of 32k triangles each, swaying.
    Sunflowers,
}

impl Demo {
    /// The name `--demo` takes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Demo::Default => "default",
            Demo::Studio => "studio",
            Demo::Sunflowers => "sunflowers",
        }
    }
}

/// `--demo`, shared by every command that loads a scene.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct DemoArg {
    /// A built-in scene instead of a file.
    #[arg(long, value_enum)]
    pub demo: Option<Demo>,
    /// Refuse a glTF file that breaks any rule of the glTF 2.0 specification, naming the
    /// JSON pointer of the first one. By default lucent warns and renders what it can read.
    #[arg(long)]
    pub strict: bool,
    /// Mitsuba scenes: set a parameter of the file (NAME=VALUE, in place of its
    /// `<default name=... value=...>`), as Mitsuba's -D does. Repeatable.
    #[arg(short = 'D', long = "define", value_parser = parse_define)]
    pub define: Vec<(String, String)>,
}

/// Parses "NAME=VALUE".
fn parse_define(s: &str) -> Result<(String, String), String> {
    let (k, v) = s.split_once('=').ok_or_else(|| format!("'{s}' is not NAME=VALUE"))?;
    if k.is_empty() || !k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(format!("'{k}' is not a parameter name (letters, digits and _)"));
    }
    Ok((k.to_string(), v.to_string()))
}

impl DemoArg {
    /// How a scene loaded without a file is named in messages.
    #[must_use]
    pub fn label(&self) -> String {
        format!("built-in {} demo", self.demo.unwrap_or(Demo::Default).name())
    }
}

/// Loads a scene file, or a built-in scene (`--demo`), else the default demo when there is
/// no file.
pub fn load_scene(path: Option<&Path>, demo: &DemoArg) -> Result<Scene> {
    match (path, demo.demo) {
        (Some(_), Some(_)) => bail!("give a scene file or --demo, not both"),
        (None, Some(Demo::Sunflowers)) => Ok(lucent_scene::sunflower_scene()),
        (None, Some(Demo::Studio)) => Ok(lucent_scene::studio_scene()),
        (None, _) => Ok(lucent_scene::demo_scene()),
        (Some(p), None) if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("xml")) => {
            lucent_scene::load_mitsuba_with(p, &demo.define).map_err(anyhow::Error::from)
        }
        (Some(p), None) => lucent_scene::load_with(p, &lucent_scene::LoadOptions { strict: demo.strict }).map_err(anyhow::Error::from),
    }
}

/// The camera to use: `--camera`, else the scene's, else one framing the bounds.
pub fn choose_camera(scene: &Scene, camera: Option<&[f32]>, ortho: bool) -> Result<CameraDesc> {
    let view = match camera {
        Some(c) => match <&[f32; 10]>::try_from(c) {
            Ok(v) => Some(v),
            _ => bail!("--camera needs 10 finite numbers EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV (got {})", c.len()),
        },
        None => None,
    };
    lucent_render::setup::camera_desc(scene, view, ortho).map_err(|e| match e {
        lucent_render::setup::SetupError::Camera => anyhow::anyhow!("--camera needs 10 finite numbers EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV"),
        e => e.into(),
    })
}

/// `--filter`'s value: `box`, `tent[:RADIUS]`, `gaussian[:STDDEV]`, `mitchell`,
/// `catmullrom` or `lanczos[:LOBES]`.
fn parse_filter(s: &str) -> Result<lucent_scene::PixelFilter, String> {
    let (name, size) = match s.split_once(':') {
        Some((n, v)) => (n, Some(v.parse::<f32>().map_err(|_| format!("'{v}' is not a number"))?)),
        None => (s, None),
    };
    if let Some(v) = size.filter(|v| !(*v > 0.0 && *v < 64.0)) {
        return Err(format!("the filter's size must be positive and below 64 (got {v})"));
    }
    match name {
        "box" if size.is_none() => Ok(lucent_scene::PixelFilter::Box),
        "tent" => Ok(lucent_scene::PixelFilter::Tent { radius: size.unwrap_or(1.0) }),
        "gaussian" => Ok(lucent_scene::PixelFilter::Gaussian { stddev: size.unwrap_or(0.5) }),
        "mitchell" if size.is_none() => Ok(lucent_scene::PixelFilter::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 }),
        "catmullrom" if size.is_none() => Ok(lucent_scene::PixelFilter::Mitchell { b: 0.0, c: 0.5 }),
        "lanczos" => match size.unwrap_or(3.0) {
            l if l.fract() == 0.0 && l <= 16.0 => Ok(lucent_scene::PixelFilter::Lanczos { lobes: l }),
            l => Err(format!("lanczos needs a whole number of lobes, 1 to 16 (got {l})")),
        },
        _ => Err(format!("'{s}' is not box, tent[:RADIUS], gaussian[:STDDEV], mitchell, catmullrom or lanczos[:LOBES]")),
    }
}

pub fn run(a: RenderArgs) -> Result<()> {
    // (MPI starts first: a rank of `mpirun` renders the same image as the others.)
    let session = crate::mpi_cmd::Session::start(&a.mpi)?;
    if let Some(t) = a.threads {
        rayon::ThreadPoolBuilder::new().num_threads(t.max(1)).build_global().context("cannot set the thread count")?;
    }
    // (Refused before any work.)
    if a.aovs && !a.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        bail!("--aovs needs an .exr output (got {})", a.output.display());
    }
    let t0 = Instant::now();
    let name = a.integrator.clone().unwrap_or_else(|| "path".into());
    // Without a scene, the path tracer shows its studio and the others the feature demo.
    let demo = match (a.scene.as_ref(), a.demo.demo, name.as_str()) {
        (None, None, "path" | "path-scalar" | "vpl") => DemoArg { demo: Some(Demo::Studio), ..a.demo },
        _ => a.demo,
    };
    // A built-in scene is denoised unless told not to (issue 55: the first image a newcomer
    // sees is a clean one), at 8 samples per pixel (the studio at 640 × 480 in about five
    // seconds on two cores) unless --spp says.
    let built_in_denoise = a.scene.is_none() && !a.no_denoise && !a.denoise && matches!(name.as_str(), "path" | "path-scalar" | "vpl");
    let denoise = a.denoise || built_in_denoise;
    let spp = a.spp.or((built_in_denoise && name != "vpl" && a.time.is_none()).then_some(8));
    let scene = load_scene(a.scene.as_deref(), &demo)?;
    let load_s = t0.elapsed().as_secs_f64();
    let Some(integrator) = lucent_render::setup::integrator_named(&name, &scene, a.max_depth, a.rr_depth, a.hide_emitters, a.no_shadows)
    else {
        bail!("--integrator {name}: not one of {}", INTEGRATORS.join(", "));
    };
    let integrator = match (integrator, a.seed) {
        (Integrator::Path(p), Some(seed)) => Integrator::Path(PathSettings { seed, ..p }),
        (Integrator::Vpl(v), seed) => {
            if !(a.vpl_clamp >= 0.0 && a.vpl_clamp.is_finite()) {
                bail!("--vpl-clamp must be a fraction of the scene's diagonal, 0 or more (got {})", a.vpl_clamp);
            }
            if !(1..=64).contains(&a.interleave) {
                bail!("--interleave must be 1..=64 (got {})", a.interleave);
            }
            Integrator::Vpl(VplSettings {
                count: a.vpls,
                clamp: a.vpl_clamp,
                interleave: a.interleave,
                discontinuity: !a.no_discontinuity,
                seed: seed.unwrap_or(v.seed),
                ..v
            })
        }
        (i, _) => i,
    };
    let view = match a.camera.as_deref() {
        Some(c) => match <[f32; 10]>::try_from(c) {
            Ok(v) if v.iter().all(|x| x.is_finite()) => Some(v),
            _ => bail!("--camera needs 10 finite numbers EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV (got {})", c.len()),
        },
        None => None,
    };
    let st = scene.stats();
    let t1 = Instant::now();
    let recipe = lucent_render::setup::Recipe {
        integrator,
        size: a.size,
        spp,
        view,
        ortho: a.ortho,
        mesh: MeshOptions {
            test: if a.watertight { TriangleTest::Watertight } else { TriangleTest::UnitTriangle },
            quality: quality_of(&a.quality),
            ..MeshOptions::default()
        },
        packets: !a.single_rays,
        filter: a.filter,
    };
    let prepared = lucent_render::setup::prepare(scene, &recipe)?;
    if prepared.sky {
        tracing::warn!("the scene has no lights: lit by a white sky (a constant environment of radiance 1)");
    }
    if prepared.headlight {
        tracing::info!("the scene has no lights: using a headlight at the camera");
    }
    let lucent_render::setup::Prepared { mut world, desc, camera: cam, settings, crop, .. } = prepared;
    let (w, h) = (settings.width, settings.height);
    let build_s = t1.elapsed().as_secs_f64();
    if let Some(s) = session.as_ref().filter(|s| s.rank() != 0) {
        return s.serve(&mut world, None, desc);
    }
    let t2 = Instant::now();
    let mut cluster = None;
    // Denoised path tracing renders its samples in two halves: for the regression
    // denoiser (from its MIN_SPP), else from HALVES_SPP for the à-trous filter to follow
    // each pixel's noise as the halves measure it (render_halves).
    let path = matches!(settings.integrator, lucent_render::Integrator::Path(_));
    let regression = denoise
        && crop.is_none()
        && path
        && settings.spp >= lucent_render::denoise::regression::MIN_SPP
        && match a.denoiser {
            Denoiser::Auto => !built_in_denoise,
            Denoiser::Regression => true,
            Denoiser::Atrous => false,
        };
    if denoise && a.denoiser == Denoiser::Regression && !regression {
        let min = lucent_render::denoise::regression::MIN_SPP;
        tracing::warn!(
            "--denoiser regression needs path tracing, at least {min} samples per pixel and the whole film: the à-trous filter runs"
        );
    }
    let halves = denoise && crop.is_none() && path && (regression || settings.spp >= HALVES_SPP);
    let mut variance = None;
    let mut two = None;
    let (film, rays, spp) = match (&session, a.time) {
        (Some(s), budget) => {
            // Every rank's samples, as they come back.
            let bar = if std::io::stderr().is_terminal() {
                match budget {
                    None => ProgressBar::new(u64::from(w) * u64::from(h) * u64::from(settings.spp)),
                    Some(_) => ProgressBar::no_length(),
                }
            } else {
                ProgressBar::hidden()
            };
            bar.set_style(
                ProgressStyle::with_template(&format!(
                    "{{spinner}} rendering on {} ranks [{{bar:40}}] {{pos}} samples {{elapsed}}",
                    s.size()
                ))
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            let (acc, rays, spp, st) = s.render(&mut world, &cam, &settings, budget, a.spp.unwrap_or(1), &bar)?;
            bar.finish_and_clear();
            cluster = Some((s.size(), st));
            (acc.resolve(), rays, spp)
        }
        (None, None) => {
            // (Two passes over the tiles when the samples are rendered in halves.)
            let tiles = (w.div_ceil(lucent_render::TILE) * h.div_ceil(lucent_render::TILE)) as u64 * if halves { 2 } else { 1 };
            let bar = if std::io::stderr().is_terminal() { ProgressBar::new(tiles) } else { ProgressBar::hidden() };
            bar.set_style(
                ProgressStyle::with_template("{spinner} rendering [{bar:40}] {pos}/{len} tiles {elapsed}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            let (film, rays) = match crop {
                // Only the window's pixels are traced (each pixel's samples are its own:
                // the same values as in the whole image).
                Some([x, y, cw, ch]) => {
                    let region = Region { x0: x, y0: y, x1: x + cw, y1: y + ch, s0: 0, s1: settings.spp.max(1) };
                    let (part, rays) = render_region(&world, &cam, &settings, region, &|n| bar.inc(n));
                    let mut acc = lucent_render::FilmAccumulator::new(w, h);
                    acc.merge(part)?;
                    (acc.resolve(world.scene().background), rays)
                }
                None if regression => match lucent_render::render_two_halves(&world, &cam, &settings, &|n| bar.inc(n)) {
                    Ok(h) => {
                        let (film, rays) = (h.whole.clone(), h.rays);
                        two = Some(h);
                        (film, rays)
                    }
                    Err(whole) => whole,
                },
                None if halves => {
                    let (film, var, rays) = lucent_render::render_halves(&world, &cam, &settings, &|n| bar.inc(n));
                    variance = var;
                    (film, rays)
                }
                None => render(&world, &cam, &settings, &|n| bar.inc(n)),
            };
            bar.finish_and_clear();
            (film, rays, settings.spp)
        }
        (None, Some(budget)) => render_for(&world, &cam, &settings, budget, a.spp.unwrap_or(1))?,
    };
    // Over MPI: the runs' time (the wait for the other ranks to load their scene apart).
    let render_s = cluster.as_ref().map_or_else(|| t2.elapsed().as_secs_f64(), |(_, st)| st.seconds);
    if cluster.is_some() {
        println!("mpi: every rank ready after {:.1} ms (loading and building their scenes)", (t2.elapsed().as_secs_f64() - render_s) * 1e3);
    }
    // The scene file's crop window: the camera saw the whole film; the image is the window.
    let film = match crop {
        Some(c) => film.crop(c),
        None => film,
    };
    let t3 = Instant::now();
    let aovs = (a.aovs || denoise).then(|| {
        let g = lucent_render::render_aovs(&world, &cam, w, h);
        match crop {
            Some(c) => g.crop(c),
            None => g,
        }
    });
    let film = match &aovs {
        Some(aovs) if denoise => {
            let t = Instant::now();
            let (f, how) = match (&two, &variance) {
                (Some(hv), _) => (
                    lucent_render::denoise::regression::denoise_render(&world, &cam, &hv.a, &hv.b, aovs),
                    "regression over the samples' halves",
                ),
                (None, Some(v)) => (
                    lucent_render::denoise_with_variance(&film, aovs, &lucent_render::DenoiseSettings::default(), v),
                    "à-trous, the halves' noise",
                ),
                (None, None) => (lucent_render::denoise(&film, aovs, &lucent_render::DenoiseSettings::default()), "à-trous"),
            };
            let ms = t.elapsed().as_secs_f64() * 1e3;
            println!("denoised ({how}) in {ms:.1} ms (guides included: {:.1} ms)", t3.elapsed().as_secs_f64() * 1e3);
            if built_in_denoise {
                println!("(a built-in scene is denoised by default; --no-denoise shows the raw samples)");
            }
            f
        }
        _ => film,
    };
    let exr = a.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    let outputs = world.scene().outputs.clone().filter(|_| exr && !a.aovs && !denoise);
    if let (true, Some(aovs)) = (a.aovs, &aovs) {
        film.save_exr_with_aovs(&a.output, aovs)?;
    } else if let Some(outputs) = outputs.clone().filter(|_| cluster.is_none() && a.time.is_none()) {
        // The scene's film writes more channels (Mitsuba's `aov` integrator, an alpha):
        // each layer is one more pass of the same samples.
        let t = Instant::now();
        let layer = |kind: AovKind| -> Result<Film> {
            let st = RenderSettings { integrator: Integrator::Aov(kind), ..settings };
            Ok(match crop {
                Some([x, y, cw, ch]) => {
                    let region = Region { x0: x, y0: y, x1: x + cw, y1: y + ch, s0: 0, s1: st.spp.max(1) };
                    let mut acc = lucent_render::FilmAccumulator::new(w, h);
                    acc.merge(render_region(&world, &cam, &st, region, &|_| {}).0)?;
                    acc.resolve(glam::Vec3::ZERO).crop([x, y, cw, ch])
                }
                None => render(&world, &cam, &st, &|_| {}).0,
            })
        };
        let mut channels = Vec::new();
        let comp = |f: &Film, k: usize| f.pixels.iter().map(|p| p[k]).collect::<Vec<f32>>();
        let alpha = (outputs.alpha || outputs.inner.is_some()).then(|| layer(AovKind::Alpha)).transpose()?;
        let rgb = |prefix: &str, channels: &mut Vec<(String, Vec<f32>)>, with_alpha: bool| {
            for (k, c) in ["R", "G", "B"].iter().enumerate() {
                channels.push((format!("{prefix}{c}"), comp(&film, k)));
            }
            if let (true, Some(a)) = (with_alpha, &alpha) {
                channels.push((format!("{prefix}A"), comp(a, 0)));
            }
        };
        rgb("", &mut channels, outputs.alpha);
        if let Some(inner) = &outputs.inner {
            rgb(&format!("{inner}."), &mut channels, true);
        }
        for (name, kind) in &outputs.aovs {
            let f = layer(*kind)?;
            for (k, c) in kind.channels().iter().enumerate() {
                channels.push((format!("{name}.{c}"), comp(&f, k)));
            }
        }
        Film::save_exr_channels(&a.output, film.width, film.height, channels)?;
        println!(
            "the film's other channels ({} layers) in {:.1} ms",
            outputs.aovs.len() + usize::from(alpha.is_some()),
            t.elapsed().as_secs_f64() * 1e3
        );
    } else {
        if outputs.is_some() {
            tracing::warn!("the scene's film has more channels (aov, alpha); they are written for a single-process render of a whole sample count only");
        }
        film.save(&a.output)?;
    }
    if let Some([x, y, cw, ch]) = crop {
        println!("crop: the scene's film window {cw}x{ch} at ({x}, {y})");
    }
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
    if let Some((ranks, st)) = cluster {
        println!("{}", cluster_summary(ranks, &st));
    }
    println!("wrote {}", a.output.display());
    Ok(())
}

/// One line on what a distributed run cost.
pub fn cluster_summary(ranks: usize, st: &lucent_cluster::RunStats) -> String {
    let per: Vec<String> = st.jobs_per_rank.iter().map(usize::to_string).collect();
    let n = st.jobs.max(1) as f64;
    format!(
        "mpi: {ranks} ranks, {} regions (per rank {}), {:.1} kB sent and {:.1} kB received by rank 0; per region: render {:.2} ms, \
         round-trip overhead {:.2} ms, merge {:.3} ms",
        st.jobs,
        per.join("/"),
        st.bytes_out as f64 / 1e3,
        st.bytes_in as f64 / 1e3,
        st.render_seconds / n * 1e3,
        (st.turnaround_seconds - st.render_seconds).max(0.0) / n * 1e3,
        st.merge_seconds / n * 1e3
    )
}

/// Renders for `budget` seconds: passes of whole-image regions of the next samples
/// ([`Passes::timed`]: one sample, doubling while a pass takes under a sixteenth of the
/// budget), merged into the progressive image, until the time is spent or `cap` samples
/// (when above 1) are in. Returns the image, the rays traced and the samples per pixel.
fn render_for(world: &World, cam: &Camera, settings: &RenderSettings, budget: f64, cap: u32) -> Result<(lucent_render::Film, u64, u32)> {
    let mut passes = Passes::timed(budget, cap).map_err(|e| anyhow::anyhow!("--time: {e}"))?;
    let st = RenderSettings { spp: passes.image_spp(), ..*settings };
    let (w, h) = (st.width, st.height);
    let mut image = Progressive::new(w, h, world.scene().background);
    let bar = if std::io::stderr().is_terminal() { ProgressBar::new((budget * 1e3) as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{spinner} rendering [{bar:40}] {elapsed} {msg}").unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut rays = 0u64;
    while let Some(samples) = passes.next() {
        let t = Instant::now();
        let (part, r) = render_region(world, cam, &st, Region::full(w, h, samples.start, samples.end), &|_| {});
        image.merge(part)?;
        rays += r;
        passes.took(samples, t.elapsed().as_secs_f64());
        let elapsed = passes.elapsed();
        bar.set_position(((elapsed.min(budget)) * 1e3) as u64);
        bar.set_message(format!(
            "{} spp, {:.2} M samples/s",
            passes.samples(),
            f64::from(w) * f64::from(h) * f64::from(passes.samples()) / elapsed.max(1e-9) * 1e-6
        ));
    }
    bar.finish_and_clear();
    Ok((image.resolve(), rays, passes.samples()))
}

pub fn info(path: Option<&Path>, demo: DemoArg) -> Result<()> {
    let scene = load_scene(path, &demo)?;
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

/// The build quality named on the command line (clap allows only these names).
pub fn quality_of(name: &str) -> lucent_accel::Quality {
    match name {
        "sah" => lucent_accel::Quality::Sah,
        "spatial" => lucent_accel::Quality::Spatial,
        _ => lucent_accel::Quality::High,
    }
}
