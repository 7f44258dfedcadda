//! Rendering to numpy: `render` (one image, as `lucent render` makes it), `Renderer`
//! (progressive: samples added step by step), the denoiser on arrays, image files.
//!
//! Both render in bands of rows ([`BAND`]), each a region of the image that lucent's
//! regions merge into the same pixels as one whole render (`render_region`); between bands
//! Python's signals are checked, so Ctrl-C stops a long render within a band.

use crate::arrays::{shape_str, to_numpy, Floats};
use crate::camera::Camera;
use crate::errors::{guard, LucentError};
use crate::scene::Scene;
use glam::Vec3;
use lucent_render::setup::{integrator_named, prepare, Prepared, Recipe};
use lucent_render::{Aovs, Film, FilmAccumulator, Integrator, PathSettings, Region, RenderSettings, VplSettings, World};
use numpy::PyArrayDyn;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Mutex;

/// Rows per band (a multiple of the tile size).
const BAND: u32 = 4 * lucent_render::TILE;

/// AOV names `render` knows.
const AOVS: [&str; 6] = ["albedo", "normal", "depth", "prim_id", "inst_id", "geom_id"];

/// What a render needs, prepared from a scene.
struct Job {
    prepared: Prepared,
    ids: Vec<i64>,
    inst_geom: Vec<i64>,
}

#[allow(clippy::too_many_arguments)]
fn prepare_job(
    py: Python<'_>,
    scene: &Scene,
    camera: Option<&Camera>,
    width: Option<u32>,
    height: Option<u32>,
    spp: Option<u32>,
    integrator: &str,
    max_depth: Option<u32>,
    seed: Option<u32>,
) -> PyResult<Job> {
    let (sc, offset, ids, inst_geom) = {
        let s = scene.read();
        (s.scene().clone(), s.offset, s.ids.clone(), s.inst_geom.clone())
    };
    let Some(integ) = integrator_named(integrator, &sc, max_depth, None, false, false) else {
        return Err(PyValueError::new_err(format!(
            "integrator: {integrator:?} is not one of {}",
            lucent_render::setup::INTEGRATORS.map(|s| format!("'{s}'")).join(", ")
        )));
    };
    let integ = match (integ, seed) {
        (Integrator::Path(p), Some(seed)) => Integrator::Path(PathSettings { seed, ..p }),
        (Integrator::Vpl(v), Some(seed)) => Integrator::Vpl(VplSettings { seed, ..v }),
        (i, _) => i,
    };
    if width.is_some() != height.is_some() {
        return Err(PyValueError::new_err("give both width and height, or neither"));
    }
    let cam = match (camera, width, height) {
        (Some(c), Some(w), Some(h)) => Some(c.with_size_checked(w, h)?),
        (Some(c), _, _) => Some(c.clone()),
        (None, ..) => None,
    };
    let size = match &cam {
        Some(c) => Some((c.width, c.height)),
        None => width.zip(height),
    };
    // A plain look-at camera is what `lucent render --camera` takes: the same set-up.
    let view = cam
        .as_ref()
        .filter(|c| c.is_plain_view())
        .and_then(|c| c.desc(offset))
        .map(|d| [d.eye.x, d.eye.y, d.eye.z, d.look_at.x, d.look_at.y, d.look_at.z, d.up.x, d.up.y, d.up.z, d.vfov_deg]);
    let recipe = Recipe { integrator: integ, size, spp, view, ortho: false, mesh: scene.read().opts, packets: true, filter: None };
    let mut prepared = py.detach(|| guard("render", || prepare(sc, &recipe)))?.map_err(|e| LucentError::new_err(format!("render: {e}")))?;
    if let Some(c) = cam.filter(|c| !c.is_plain_view()) {
        prepared.camera = c.build(offset);
    }
    Ok(Job { prepared, ids, inst_geom })
}

/// Renders samples `s0..s1` of every pixel of `window` (x, y, width, height) band by band
/// into `acc`, checking Python's signals between bands.
#[allow(clippy::too_many_arguments)]
fn render_bands(
    py: Python<'_>,
    world: &World,
    cam: &lucent_render::Camera,
    settings: &RenderSettings,
    [x0, wy, ww, wh]: [u32; 4],
    s0: u32,
    s1: u32,
    acc: &mut FilmAccumulator,
    mut half: Option<&mut FilmAccumulator>,
    threads: Option<usize>,
) -> PyResult<()> {
    let (x1, h) = (x0 + ww, wy + wh);
    let mut y0 = wy;
    while y0 < h {
        let region = Region { x0, y0, x1, y1: (y0 + BAND).min(h), s0, s1 };
        let part = py.detach(|| {
            guard("render", || crate::threads::run(threads, || lucent_render::render_region(world, cam, settings, region, &|_| {}).0))
        })?;
        if let Some(h) = half.as_deref_mut() {
            // (The half's own image counts its samples from 0.)
            let mut own = part.clone();
            own.region.s0 -= s0;
            own.region.s1 -= s0;
            h.merge(own).map_err(|e| LucentError::new_err(format!("render: {e}")))?;
        }
        acc.merge(part).map_err(|e| LucentError::new_err(format!("render: {e}")))?;
        py.check_signals()?;
        y0 += BAND;
    }
    Ok(())
}

/// The pixels rendered: the scene file's crop window, else the whole image (x, y, width,
/// height).
fn rendered(p: &lucent_render::setup::Prepared) -> [u32; 4] {
    p.crop.unwrap_or([0, 0, p.settings.width, p.settings.height])
}

/// `film` cut to the scene file's crop window, if it has one (as `lucent render` writes).
fn window(p: &lucent_render::setup::Prepared, film: Film) -> Film {
    match p.crop {
        Some(c) => film.crop(c),
        None => film,
    }
}

/// A film as an (H, W, 3) float32 array.
fn film_array<'py>(py: Python<'py>, f: &Film) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    to_numpy(py, f.pixels.iter().flat_map(|p| p.to_array()).collect(), &[f.height as usize, f.width as usize, 3])
}

/// The AOV images asked for.
fn aov_dict<'py>(py: Python<'py>, job: &Job, names: &[String], aovs: &Aovs, threads: Option<usize>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let [x0, y0, w, h] = rendered(&job.prepared);
    let (w, h) = (w as usize, h as usize);
    let ids = names.iter().any(|n| n.ends_with("_id"));
    let hits = if ids {
        let (world, cam) = (&job.prepared.world, &job.prepared.camera);
        py.detach(|| {
            crate::threads::run(threads, || {
                use rayon::prelude::*;
                (0..h)
                    .into_par_iter()
                    .flat_map_iter(|y| {
                        let y = (y + y0 as usize) as f32 + 0.5;
                        (0..w).map(move |x| {
                            world.accel().intersect(&cam.ray((x + x0 as usize) as f32 + 0.5, y)).map(|hit| (hit.prim, hit.inst))
                        })
                    })
                    .collect::<Vec<_>>()
            })
        })
    } else {
        Vec::new()
    };
    for n in names {
        match n.as_str() {
            "albedo" => d.set_item(n, film_array(py, &aovs.albedo)?)?,
            "normal" => d.set_item(n, film_array(py, &aovs.normal)?)?,
            "depth" => d.set_item(n, to_numpy(py, aovs.depth.clone(), &[h, w])?)?,
            "prim_id" => d.set_item(n, to_numpy(py, hits.iter().map(|x| x.map_or(-1, |(p, _)| p as i32)).collect(), &[h, w])?)?,
            "inst_id" => d.set_item(
                n,
                to_numpy(
                    py,
                    hits.iter().map(|x| x.and_then(|(_, i)| job.ids.get(i as usize)).map_or(-1, |&v| v as i32)).collect(),
                    &[h, w],
                )?,
            )?,
            "geom_id" => d.set_item(
                n,
                to_numpy(
                    py,
                    hits.iter().map(|x| x.and_then(|(_, i)| job.inst_geom.get(i as usize)).map_or(-1, |&v| v as i32)).collect(),
                    &[h, w],
                )?,
            )?,
            _ => {}
        }
    }
    Ok(d)
}

fn check_aovs(aovs: &[String]) -> PyResult<()> {
    for a in aovs {
        if !AOVS.contains(&a.as_str()) {
            return Err(PyValueError::new_err(format!("aovs: unknown AOV {a:?} (known: {})", AOVS.join(", "))));
        }
    }
    Ok(())
}

/// Renders ``scene`` to a float32 (H, W, 3) linear RGB image, as ``lucent render`` does
/// for the same scene and settings (bit for bit). ``camera``: a ``Camera``, else the
/// file's, else one framing the scene. ``integrator``: ``'path'`` (default),
/// ``'whitted'``, ``'vpl'``, ``'eye-light'``, ``'normals'``, ``'path-scalar'``.
/// ``aovs``: names of extra images (``albedo``, ``normal``, ``depth``, ``prim_id``,
/// ``inst_id``, ``geom_id``): then ``(image, {name: array})`` is returned. ``denoise``:
/// the image is denoised with its albedo, normal and depth guides (path tracing from 4
/// samples per pixel on the whole film: the regression over the two halves of the
/// samples, as ``lucent render --denoise``, seconds per frame; else the à-trous filter).
#[pyfunction]
#[pyo3(signature = (scene, camera = None, *, width = None, height = None, spp = None, integrator = "path", max_depth = None, seed = None, aovs = None, denoise = false, threads = None))]
#[allow(clippy::too_many_arguments)]
pub fn render<'py>(
    py: Python<'py>,
    scene: &Scene,
    camera: Option<&Camera>,
    width: Option<u32>,
    height: Option<u32>,
    spp: Option<u32>,
    integrator: &str,
    max_depth: Option<u32>,
    seed: Option<u32>,
    aovs: Option<Vec<String>>,
    denoise: bool,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    let aov_names = aovs.unwrap_or_default();
    check_aovs(&aov_names)?;
    if spp == Some(0) {
        return Err(PyValueError::new_err("spp: at least 1 sample per pixel"));
    }
    let job = prepare_job(py, scene, camera, width, height, spp, integrator, max_depth, seed)?;
    let p = &job.prepared;
    let (w, h) = (p.settings.width, p.settings.height);
    let mut acc = FilmAccumulator::new(w, h);
    // Denoised path tracing from MIN_SPP samples per pixel on the whole film: the regression
    // denoiser over the two halves of the samples, as `lucent render --denoise` (the same
    // image, bit for bit); the halves' own images are kept as they are rendered.
    let spp = p.settings.spp.max(1);
    let regression = denoise
        && p.crop.is_none()
        && spp >= lucent_render::denoise::regression::MIN_SPP
        && matches!(p.settings.integrator, lucent_render::Integrator::Path(_));
    let mut halves = None;
    if regression {
        let half = spp / 2;
        let (mut a, mut b) = (FilmAccumulator::new(w, h), FilmAccumulator::new(w, h));
        render_bands(py, &p.world, &p.camera, &p.settings, rendered(p), 0, half, &mut acc, Some(&mut a), threads)?;
        render_bands(py, &p.world, &p.camera, &p.settings, rendered(p), half, spp, &mut acc, Some(&mut b), threads)?;
        let bg = p.world.scene().background;
        halves = Some((a.resolve(bg), b.resolve(bg)));
    } else {
        render_bands(py, &p.world, &p.camera, &p.settings, rendered(p), 0, p.settings.spp, &mut acc, None, threads)?;
    }
    let mut film = window(p, acc.resolve(p.world.scene().background));
    let guides = (!aov_names.is_empty() || denoise).then(|| {
        let g = py.detach(|| crate::threads::run(threads, || lucent_render::render_aovs(&p.world, &p.camera, w, h)));
        match p.crop {
            Some(c) => g.crop(c),
            None => g,
        }
    });
    match (denoise, &guides, &halves) {
        (true, Some(g), Some((a, b))) => {
            film = py.detach(|| {
                crate::threads::run(threads, || lucent_render::denoise::regression::denoise_render(&p.world, &p.camera, a, b, g))
            });
        }
        (true, Some(g), None) => {
            film =
                py.detach(|| crate::threads::run(threads, || lucent_render::denoise(&film, g, &lucent_render::DenoiseSettings::default())));
        }
        _ => {}
    }
    let img = film_array(py, &film)?.into_any();
    match guides {
        Some(g) if !aov_names.is_empty() => {
            let d = aov_dict(py, &job, &aov_names, &g, threads)?;
            Ok(pyo3::types::PyTuple::new(py, [img, d.into_any()])?.into_any())
        }
        _ => Ok(img),
    }
}

struct Progress {
    job: Job,
    acc: FilmAccumulator,
    spp: u32,
}

/// A progressive render: each ``step(spp)`` adds samples to every pixel (for the path
/// tracer, after n samples the image ``render`` makes with ``spp=n``, up to the rounding
/// of the sums). Ctrl-C during a step leaves the
/// image as it was before the step.
#[pyclass(frozen, module = "lucent._lucent", name = "Renderer")]
pub struct Renderer {
    inner: Mutex<Progress>,
    threads: Option<usize>,
}

#[pymethods]
impl Renderer {
    #[new]
    #[pyo3(signature = (scene, camera = None, *, width = None, height = None, integrator = "path", max_depth = None, seed = None, threads = None))]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        py: Python<'_>,
        scene: &Scene,
        camera: Option<&Camera>,
        width: Option<u32>,
        height: Option<u32>,
        integrator: &str,
        max_depth: Option<u32>,
        seed: Option<u32>,
        threads: Option<usize>,
    ) -> PyResult<Self> {
        let job = prepare_job(py, scene, camera, width, height, Some(1), integrator, max_depth, seed)?;
        let (w, h) = (job.prepared.settings.width, job.prepared.settings.height);
        Ok(Self { inner: Mutex::new(Progress { job, acc: FilmAccumulator::new(w, h), spp: 0 }), threads })
    }

    /// Adds ``spp`` samples to every pixel (GIL released; Ctrl-C checked between bands).
    #[pyo3(signature = (spp = 1))]
    fn step(&self, py: Python<'_>, spp: u32) -> PyResult<()> {
        if spp == 0 {
            return Ok(());
        }
        let mut g = self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let p = &mut *g;
        let (s0, s1) = (p.spp, p.spp.saturating_add(spp));
        // The samples of an image of s1 samples per pixel: the settings' count matters to
        // the samplers (stratification over the whole count).
        let settings = RenderSettings { spp: s1, ..p.job.prepared.settings };
        let before = p.acc.clone();
        let prep = &p.job.prepared;
        let r = render_bands(py, &prep.world, &prep.camera, &settings, rendered(prep), s0, s1, &mut p.acc, None, self.threads);
        match r {
            Ok(()) => {
                p.spp = s1;
                Ok(())
            }
            Err(e) => {
                p.acc = before;
                Err(e)
            }
        }
    }

    /// The image so far, (H, W, 3) float32.
    #[getter]
    fn image<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let g = self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        film_array(py, &window(&g.job.prepared, g.acc.resolve(g.job.prepared.world.scene().background)))
    }

    /// Samples per pixel so far.
    #[getter]
    fn spp(&self) -> u32 {
        self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner).spp
    }

    /// Starts over (no samples).
    fn reset(&self) {
        let mut g = self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let (w, h) = (g.job.prepared.settings.width, g.job.prepared.settings.height);
        g.acc = FilmAccumulator::new(w, h);
        g.spp = 0;
    }
}

/// An (H, W, 3) array as a film.
fn film_of(a: &Bound<'_, PyAny>, name: &str, want: Option<(usize, usize)>) -> PyResult<Film> {
    let f = Floats::extract(a, name)?;
    let s = f.shape().to_vec();
    if s.len() != 3 || s[2] != 3 || want.is_some_and(|(h, w)| (s[0], s[1]) != (h, w)) {
        let need = want.map_or("(H, W, 3)".to_string(), |(h, w)| format!("({h}, {w}, 3)"));
        return Err(PyValueError::new_err(format!("{name}: shape {} where {need} was needed", shape_str(&s))));
    }
    let v = f.slice()?;
    let pixels = (0..s[0] * s[1]).map(|i| Vec3::new(v.get(3 * i) as f32, v.get(3 * i + 1) as f32, v.get(3 * i + 2) as f32)).collect();
    Ok(Film { width: s[1] as u32, height: s[0] as u32, pixels })
}

/// Denoises a rendered ``color`` image (H, W, 3) guided by its ``albedo`` and ``normal``
/// (H, W, 3) and ``depth`` (H, W) (lucent's edge-aware à-trous filter, as ``render(...,
/// denoise=True)`` applies it).
#[pyfunction]
#[pyo3(signature = (color, *, albedo, normal, depth, iterations = None))]
pub fn denoise<'py>(
    py: Python<'py>,
    color: &Bound<'py, PyAny>,
    albedo: &Bound<'py, PyAny>,
    normal: &Bound<'py, PyAny>,
    depth: &Bound<'py, PyAny>,
    iterations: Option<u32>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let c = film_of(color, "color", None)?;
    let hw = (c.height as usize, c.width as usize);
    let albedo = film_of(albedo, "albedo", Some(hw))?;
    let normal = film_of(normal, "normal", Some(hw))?;
    let d = Floats::extract(depth, "depth")?;
    if d.shape() != [hw.0, hw.1] {
        return Err(PyValueError::new_err(format!("depth: shape {} where ({}, {}) was needed", shape_str(d.shape()), hw.0, hw.1)));
    }
    let ds = d.slice()?;
    let depth: Vec<f32> = (0..ds.len()).map(|i| ds.get(i) as f32).collect();
    let mut settings = lucent_render::DenoiseSettings::default();
    if let Some(n) = iterations {
        if !(1..=10).contains(&n) {
            return Err(PyValueError::new_err(format!("iterations: {n} is not 1..=10")));
        }
        settings.iterations = n;
    }
    let emission = Film::new(c.width, c.height);
    let aovs = Aovs { albedo, normal, depth, emission };
    let out = py.detach(|| guard("denoise", || lucent_render::denoise(&c, &aovs, &settings)))?;
    film_array(py, &out)
}

/// Writes an (H, W, 3) linear image: ``.exr`` (float), ``.png`` (sRGB, 8 bits) or
/// ``.ppm``.
#[pyfunction]
pub fn write_image(py: Python<'_>, path: PathBuf, image: &Bound<'_, PyAny>) -> PyResult<()> {
    let f = film_of(image, "image", None)?;
    py.detach(|| f.save(&path)).map_err(|e| LucentError::new_err(format!("{}: {e}", path.display())))
}

/// Reads an image file (``.exr``, ``.png``, ...) as an (H, W, 3) linear float32 array.
#[pyfunction]
pub fn read_image(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArrayDyn<f32>>> {
    if !path.exists() {
        return Err(pyo3::exceptions::PyFileNotFoundError::new_err(format!("{}: no such file", path.display())));
    }
    let f = py.detach(|| Film::load(&path)).map_err(|e| LucentError::new_err(format!("{}: {e}", path.display())))?;
    film_array(py, &f)
}
