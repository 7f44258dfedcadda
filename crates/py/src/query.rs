//! Ray queries on numpy arrays: closest hit, any hit, all hits, hit counts, and a camera's
//! rays traced without arrays. Rays are read where numpy holds them, cut into batches of
//! up to 64 (8 × 8 tiles for a 2-D leading shape) that the thread pool shares; a batch
//! whose rays are coherent (one direction octant, directions within a narrow cone) goes
//! through the packet kernels, the rest ray by ray.

use crate::arrays::{shape_str, to_numpy, with_last, Floats, Slice};
use crate::scene::{Scene, State};
use glam::{DVec3, Vec3};
use lucent_accel::{Hit, Ray, RayBlock};
use lucent_render::World;
use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use rayon::prelude::*;

/// Rays in a batch.
const BATCH: usize = 64;

/// Per-ray or shared range bounds.
#[derive(Clone, Copy)]
enum Bound1<'a> {
    Scalar(f32),
    Per(Slice<'a>),
}

impl Bound1<'_> {
    #[inline]
    fn at(&self, i: usize) -> f32 {
        match self {
            Bound1::Scalar(x) => *x,
            Bound1::Per(s) => s.get(i) as f32,
        }
    }
}

/// The rays of a call, as slices (sendable to the workers).
#[derive(Clone, Copy)]
struct Rays<'a> {
    o: Slice<'a>,
    /// One origin for every ray.
    one_origin: bool,
    d: Slice<'a>,
    /// One direction for every ray.
    one_direction: bool,
    n: usize,
    tmin: Bound1<'a>,
    tmax: Bound1<'a>,
    offset: DVec3,
}

impl Rays<'_> {
    /// Ray `i` in the scene's stored coordinates, or `None` when it cannot hit anything
    /// (a non-finite origin or direction, a zero direction, an empty or NaN range).
    #[inline]
    fn ray(&self, i: usize) -> Option<Ray> {
        let k = if self.one_origin { 0 } else { 3 * i };
        let o = if self.offset == DVec3::ZERO {
            Vec3::new(self.o.get(k) as f32, self.o.get(k + 1) as f32, self.o.get(k + 2) as f32)
        } else {
            (DVec3::new(self.o.get(k), self.o.get(k + 1), self.o.get(k + 2)) - self.offset).as_vec3()
        };
        let j = if self.one_direction { 0 } else { 3 * i };
        let d = Vec3::new(self.d.get(j) as f32, self.d.get(j + 1) as f32, self.d.get(j + 2) as f32);
        let (tmin, tmax) = (self.tmin.at(i), self.tmax.at(i));
        // (`!(a < b)` also refuses NaN.)
        let ok = o.is_finite() && d.is_finite() && d != Vec3::ZERO && tmin < tmax && tmin.is_finite() && !tmax.is_nan();
        ok.then_some(Ray { org: o, dir: d, tmin, tmax })
    }
}

/// Keeps the numpy arrays of a call borrowed while their slices are used.
struct Input<'py> {
    o: Floats<'py>,
    d: Floats<'py>,
    tmin: Option<Floats<'py>>,
    tmax: Option<Floats<'py>>,
    tmin_s: f32,
    tmax_s: f32,
    lead: Vec<usize>,
    one_origin: bool,
    one_direction: bool,
}

/// A range bound: a number or an array of the rays' leading shape.
fn range_arg<'py>(v: &Bound<'py, PyAny>, name: &str, lead: &[usize]) -> PyResult<(Option<Floats<'py>>, f32)> {
    if let Ok(x) = v.extract::<f64>() {
        if x.is_nan() {
            return Err(PyValueError::new_err(format!("{name}: NaN")));
        }
        return Ok((None, x as f32));
    }
    let f = Floats::extract(v, name)?;
    if f.shape() != lead {
        return Err(PyValueError::new_err(format!(
            "{name}: shape {} where a number or {} (the rays' shape) was needed",
            shape_str(f.shape()),
            shape_str(lead)
        )));
    }
    Ok((Some(f), 0.0))
}

impl<'py> Input<'py> {
    fn new(
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: &Bound<'py, PyAny>,
        tmax: &Bound<'py, PyAny>,
    ) -> PyResult<Self> {
        let d = Floats::extract(directions, "directions")?;
        let dlead = d.vectors("directions", 3)?;
        let o = Floats::extract(origins, "origins")?;
        let olead = o.vectors("origins", 3)?;
        // One origin for many directions (a camera, a LiDAR), one direction for many
        // origins (toward a directional light), or one of each per ray.
        let (lead, one_origin, one_direction) = match (olead.is_empty(), dlead.is_empty()) {
            (true, _) => (dlead, true, false),
            (false, true) => (olead, false, true),
            (false, false) if olead == dlead => (dlead, false, false),
            _ => {
                return Err(PyValueError::new_err(format!(
                    "origins: shape {} does not match directions {} (give one of either as (3,), or one per ray)",
                    shape_str(o.shape()),
                    shape_str(d.shape())
                )))
            }
        };
        let (tmin, tmin_s) = range_arg(tmin, "tmin", &lead)?;
        let (tmax, tmax_s) = range_arg(tmax, "tmax", &lead)?;
        Ok(Self { o, d, tmin, tmax, tmin_s, tmax_s, lead, one_origin, one_direction })
    }

    fn rays(&self, offset: DVec3) -> PyResult<Rays<'_>> {
        fn bound<'a>(f: &'a Option<Floats<'_>>, s: f32) -> PyResult<Bound1<'a>> {
            Ok(match f {
                Some(f) => Bound1::Per(f.slice()?),
                None => Bound1::Scalar(s),
            })
        }
        Ok(Rays {
            o: self.o.slice()?,
            one_origin: self.one_origin,
            d: self.d.slice()?,
            one_direction: self.one_direction,
            n: self.lead.iter().product(),
            tmin: bound(&self.tmin, self.tmin_s)?,
            tmax: bound(&self.tmax, self.tmax_s)?,
            offset,
        })
    }
}

/// A batch of ray indices: a run, or an 8 × 8 tile of a 2-D leading shape.
#[derive(Clone, Copy)]
enum Batch {
    Run(usize, usize),
    Tile { x0: usize, y0: usize, w: usize, h: usize, width: usize },
}

impl Batch {
    fn indices(&self, out: &mut Vec<usize>) {
        out.clear();
        match *self {
            Batch::Run(a, b) => out.extend(a..b),
            Batch::Tile { x0, y0, w, h, width } => {
                for y in y0..y0 + h {
                    out.extend((y * width + x0)..(y * width + x0 + w));
                }
            }
        }
    }
}

/// The batches of `n` rays of leading shape `lead`.
fn batches(lead: &[usize], n: usize) -> Vec<Batch> {
    match lead {
        [h, w] if *h >= 8 && *w >= 8 => {
            let mut v = Vec::with_capacity(h.div_ceil(8) * w.div_ceil(8));
            for y0 in (0..*h).step_by(8) {
                for x0 in (0..*w).step_by(8) {
                    v.push(Batch::Tile { x0, y0, w: 8.min(w - x0), h: 8.min(h - y0), width: *w });
                }
            }
            v
        }
        _ => (0..n).step_by(BATCH).map(|a| Batch::Run(a, (a + BATCH).min(n))).collect(),
    }
}

/// Whether rays are coherent enough for the packet kernels: all in one direction octant
/// (a camera's or a light's rays in a tile are; bounce rays mostly are not). Measured on
/// the bunny's dumped rays: a test of the directions' spread as well cost more than it
/// saved.
fn coherent(rays: &[Option<Ray>]) -> bool {
    let sign = |d: Vec3| (d.x < 0.0) as u8 | ((d.y < 0.0) as u8) << 1 | ((d.z < 0.0) as u8) << 2;
    let mut s0 = None;
    let mut n = 0;
    for r in rays.iter().flatten() {
        let s = sign(r.dir);
        if *s0.get_or_insert(s) != s {
            return false;
        }
        n += 1;
    }
    n >= 4
}

/// Puts a batch's rays into SoA blocks of eight (a missing ray: an empty lane).
fn fill_blocks(rays: &[Option<Ray>], blocks: &mut [RayBlock; BATCH / 8]) -> usize {
    let nb = rays.len().div_ceil(8);
    for (k, r) in rays.iter().enumerate() {
        match r {
            Some(r) => blocks[k / 8].set(k % 8, r),
            None => blocks[k / 8].set(k % 8, &EMPTY_RAY),
        }
    }
    for k in rays.len()..nb * 8 {
        blocks[k / 8].set(k % 8, &EMPTY_RAY);
    }
    nb
}

/// A lane that holds no ray (its range is empty).
const EMPTY_RAY: Ray = Ray { org: Vec3::ZERO, dir: Vec3::Z, tmin: 0.0, tmax: f32::NEG_INFINITY };

/// Output fields of a closest-hit query.
#[derive(Clone, Copy, Default)]
struct Fields {
    t: bool,
    hit: bool,
    prim: bool,
    geom: bool,
    inst: bool,
    uv: bool,
    normal: bool,
    depth: bool,
}

const FIELD_NAMES: [&str; 8] = ["t", "hit", "prim_id", "geom_id", "inst_id", "uv", "normal", "depth"];

impl Fields {
    fn parse(names: &[String], depth_ok: bool) -> PyResult<Self> {
        let mut f = Self::default();
        for n in names {
            match n.as_str() {
                "t" => f.t = true,
                "hit" => f.hit = true,
                "prim_id" => f.prim = true,
                "geom_id" => f.geom = true,
                "inst_id" => f.inst = true,
                "uv" => f.uv = true,
                "normal" => f.normal = true,
                "depth" if depth_ok => f.depth = true,
                other => {
                    let known = if depth_ok { &FIELD_NAMES[..] } else { &FIELD_NAMES[..7] };
                    return Err(PyValueError::new_err(format!("fields: unknown field {other:?} (known: {})", known.join(", "))));
                }
            }
        }
        Ok(f)
    }
}

/// Raw pointers to the output buffers; each ray's entries are written by one task.
#[derive(Clone, Copy)]
struct Out {
    t: *mut f32,
    hit: *mut bool,
    prim: *mut i32,
    geom: *mut i32,
    inst: *mut i32,
    uv: *mut f32,
    normal: *mut f32,
    depth: *mut f32,
}

// SAFETY: the pointers address buffers that outlive the parallel loop, and no two tasks
// write the same entry (each ray index belongs to one batch).
unsafe impl Send for Out {}
// SAFETY: as above.
unsafe impl Sync for Out {}

impl Out {
    /// Writes ray `i`'s answer. SAFETY (caller): `i` is below the buffers' ray count and
    /// written by this task only.
    #[inline]
    unsafe fn put(&self, i: usize, st: &State, w: &World, r: Option<&Ray>, h: Option<Hit>, forward: Vec3) {
        // SAFETY: (all writes) the caller's contract; a null pointer is a field not asked for.
        unsafe {
            if !self.t.is_null() {
                *self.t.add(i) = h.map_or(f32::INFINITY, |h| h.t);
            }
            if !self.hit.is_null() {
                *self.hit.add(i) = h.is_some();
            }
            if !self.prim.is_null() {
                *self.prim.add(i) = h.map_or(-1, |h| h.prim as i32);
            }
            if !self.geom.is_null() {
                *self.geom.add(i) = h.map_or(-1, |h| st.inst_geom.get(h.inst as usize).map_or(-1, |&g| g as i32));
            }
            if !self.inst.is_null() {
                *self.inst.add(i) = h.map_or(-1, |h| st.ids.get(h.inst as usize).map_or(-1, |&g| g as i32));
            }
            if !self.uv.is_null() {
                let (u, v) = h.map_or((0.0, 0.0), |h| (h.u, h.v));
                *self.uv.add(2 * i) = u;
                *self.uv.add(2 * i + 1) = v;
            }
            if !self.normal.is_null() {
                let n = match (r, h) {
                    (Some(r), Some(h)) => w.geometric_normal(r, &h),
                    _ => Vec3::ZERO,
                };
                *self.normal.add(3 * i) = n.x;
                *self.normal.add(3 * i + 1) = n.y;
                *self.normal.add(3 * i + 2) = n.z;
            }
            if !self.depth.is_null() {
                *self.depth.add(i) = match (r, h) {
                    (Some(r), Some(h)) => h.t * r.dir.dot(forward),
                    _ => f32::INFINITY,
                };
            }
        }
    }
}

/// Output buffers: the caller's (``out=``) or new ones.
struct Buffers<'py> {
    arrays: Vec<(&'static str, Bound<'py, PyAny>)>,
    out: Out,
}

/// A writable C-contiguous array of dtype `T` and shape `shape` from `out`, or a new one.
fn buffer<'py, T: numpy::Element + Copy>(
    py: Python<'py>,
    out: Option<&Bound<'py, PyDict>>,
    name: &'static str,
    shape: &[usize],
    fill: T,
) -> PyResult<(Bound<'py, PyAny>, *mut T)> {
    if let Some(a) = out.and_then(|o| o.get_item(name).ok().flatten()) {
        let arr = a
            .cast::<PyArrayDyn<T>>()
            .map_err(|_| PyTypeError::new_err(format!("out[{name:?}]: not an array of {}", std::any::type_name::<T>())))?;
        if arr.shape() != shape {
            return Err(PyValueError::new_err(format!(
                "out[{name:?}]: shape {} where {} was needed",
                shape_str(arr.shape()),
                shape_str(shape)
            )));
        }
        if !arr.is_c_contiguous() {
            return Err(PyValueError::new_err(format!("out[{name:?}]: not C-contiguous")));
        }
        let mut rw = arr.try_readwrite().map_err(|e| PyValueError::new_err(format!("out[{name:?}]: {e}")))?;
        let p = rw.as_slice_mut().map_err(|e| PyValueError::new_err(format!("out[{name:?}]: {e}")))?.as_mut_ptr();
        drop(rw);
        return Ok((arr.clone().into_any(), p));
    }
    let n = shape.iter().product();
    let arr = to_numpy(py, vec![fill; n], shape)?;
    // SAFETY: the array was just made here, is C-contiguous, and nothing else holds it.
    let p = unsafe { arr.as_slice_mut() }.map_err(|e| PyValueError::new_err(e.to_string()))?.as_mut_ptr();
    Ok((arr.into_any(), p))
}

impl<'py> Buffers<'py> {
    fn new(py: Python<'py>, f: Fields, lead: &[usize], out: Option<&Bound<'py, PyDict>>) -> PyResult<Self> {
        let mut arrays = Vec::new();
        let mut o = Out {
            t: std::ptr::null_mut(),
            hit: std::ptr::null_mut(),
            prim: std::ptr::null_mut(),
            geom: std::ptr::null_mut(),
            inst: std::ptr::null_mut(),
            uv: std::ptr::null_mut(),
            normal: std::ptr::null_mut(),
            depth: std::ptr::null_mut(),
        };
        macro_rules! field {
            ($on:expr, $name:literal, $ptr:ident, $k:expr, $fill:expr) => {
                if $on {
                    let (a, p) = buffer(py, out, $name, &with_last(lead, $k), $fill)?;
                    arrays.push(($name, a));
                    o.$ptr = p;
                }
            };
        }
        field!(f.t, "t", t, 0, f32::INFINITY);
        field!(f.hit, "hit", hit, 0, false);
        field!(f.prim, "prim_id", prim, 0, -1i32);
        field!(f.geom, "geom_id", geom, 0, -1i32);
        field!(f.inst, "inst_id", inst, 0, -1i32);
        field!(f.uv, "uv", uv, 2, 0f32);
        field!(f.normal, "normal", normal, 3, 0f32);
        field!(f.depth, "depth", depth, 0, f32::INFINITY);
        Ok(Self { arrays, out: o })
    }

    fn into_dict(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in self.arrays {
            d.set_item(k, v)?;
        }
        Ok(d)
    }
}

/// The packet mode asked for.
fn packet_mode(coherent: Option<bool>) -> Option<bool> {
    coherent
}

/// Traces closest hits of `rays` into `out`.
fn closest(st: &State, w: &World, rays: Rays<'_>, lead: &[usize], mode: Option<bool>, out: Out, forward: Vec3) {
    let tl = w.accel();
    batches(lead, rays.n).par_iter().for_each_init(
        || (Vec::with_capacity(BATCH), Vec::with_capacity(BATCH), [RayBlock::EMPTY; BATCH / 8], vec![None; BATCH]),
        |(idx, rs, blocks, hits), b| {
            b.indices(idx);
            rs.clear();
            rs.extend(idx.iter().map(|&i| rays.ray(i)));
            if mode.unwrap_or_else(|| coherent(rs)) {
                let nb = fill_blocks(rs, blocks);
                tl.intersect_blocks(&blocks[..nb], &mut hits[..nb * 8]);
            } else {
                for (h, r) in hits.iter_mut().zip(rs.iter()) {
                    *h = r.as_ref().and_then(|r| tl.intersect(r));
                }
            }
            for (k, &i) in idx.iter().enumerate() {
                // SAFETY: `i` is a ray of this batch only, below the ray count.
                unsafe { out.put(i, st, w, rs[k].as_ref(), if rs[k].is_some() { hits[k] } else { None }, forward) };
            }
        },
    );
}

/// Answers of [`Scene`]'s queries.
#[pymethods]
impl Scene {
    /// Closest hits of rays ``origins`` (..., 3) or one origin (3,) and ``directions``
    /// (..., 3), within [``tmin``, ``tmax``) (numbers or arrays of the rays' shape), in
    /// units of each direction's length. Returns a dict of the ``fields`` asked for:
    /// ``t`` (inf on a miss), ``hit``, ``prim_id``, ``geom_id``, ``inst_id`` (-1 on a
    /// miss), ``uv`` (..., 2) (barycentric weights of vertices 1 and 2), ``normal``
    /// (..., 3) (unit geometric normal, by the triangle's winding). ``coherent``: True
    /// traces batches as packets, False ray by ray, None decides per batch. ``out``: a
    /// dict of arrays to write into.
    #[pyo3(signature = (origins, directions, *, tmin = None, tmax = None, fields = None, coherent = None, out = None, threads = None))]
    #[allow(clippy::too_many_arguments)]
    fn _intersect<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        fields: Option<Vec<String>>,
        coherent: Option<bool>,
        out: Option<&Bound<'py, PyDict>>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let zero = 0.0f64.into_pyobject(py)?.into_any();
        let inf = f64::INFINITY.into_pyobject(py)?.into_any();
        let input = Input::new(origins, directions, tmin.unwrap_or(&zero), tmax.unwrap_or(&inf))?;
        let names = fields.unwrap_or_else(|| FIELD_NAMES[..7].iter().map(|s| (*s).to_string()).collect());
        let f = Fields::parse(&names, false)?;
        let bufs = Buffers::new(py, f, &input.lead, out)?;
        let offset = self.read().offset;
        let rays = input.rays(offset)?;
        let lead = input.lead.clone();
        let o = bufs.out;
        let mode = packet_mode(coherent);
        self.with_world(py, "intersect", move |st, w| crate::threads::run(threads, || closest(st, w, rays, &lead, mode, o, Vec3::Z)))?;
        bufs.into_dict(py)
    }

    /// Whether anything blocks each ray within [``tmin``, ``tmax``): a bool array of the
    /// rays' leading shape (an any-hit query, cheaper than ``intersect``).
    #[pyo3(signature = (origins, directions, *, tmin = None, tmax = None, coherent = None, threads = None))]
    #[allow(clippy::too_many_arguments)]
    fn occluded<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        coherent: Option<bool>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArrayDyn<bool>>> {
        let zero = 0.0f64.into_pyobject(py)?.into_any();
        let inf = f64::INFINITY.into_pyobject(py)?.into_any();
        let input = Input::new(origins, directions, tmin.unwrap_or(&zero), tmax.unwrap_or(&inf))?;
        let offset = self.read().offset;
        let rays = input.rays(offset)?;
        let lead = input.lead.clone();
        let n = rays.n;
        let v = self.with_world(py, "occluded", move |_, w| {
            crate::threads::run(threads, || {
                let tl = w.accel();
                let mut res = vec![false; n];
                let ptr = SendPtr(res.as_mut_ptr());
                batches(&lead, n).par_iter().for_each_init(
                    || (Vec::with_capacity(BATCH), Vec::with_capacity(BATCH), [RayBlock::EMPTY; BATCH / 8], vec![false; BATCH]),
                    |(idx, rs, blocks, occ), b| {
                        b.indices(idx);
                        rs.clear();
                        rs.extend(idx.iter().map(|&i| rays.ray(i)));
                        if coherent.unwrap_or_else(|| crate::query::coherent(rs)) {
                            let nb = fill_blocks(rs, blocks);
                            tl.occluded_blocks(&blocks[..nb], &mut occ[..nb * 8]);
                        } else {
                            for (o, r) in occ.iter_mut().zip(rs.iter()) {
                                *o = r.as_ref().is_some_and(|r| tl.occluded(r));
                            }
                        }
                        for (k, &i) in idx.iter().enumerate() {
                            // SAFETY: `i` is below `n` and belongs to this batch only.
                            unsafe { *ptr.get().add(i) = rs[k].is_some() && occ[k] };
                        }
                    },
                );
                res
            })
        })?;
        to_numpy(py, v, &input.lead)
    }

    /// Every surface each ray meets within [``tmin``, ``tmax``), sorted by ``t`` per ray
    /// (each triangle once, a shape at each crossing), at most ``max_hits`` per ray.
    /// Returns a dict of flat arrays: ``ray_index``, ``t``, ``prim_id``, ``geom_id``,
    /// ``inst_id``, ``uv`` (M, 2), and ``splits`` (N + 1,): ray i's hits are
    /// ``splits[i]:splits[i + 1]`` (rays in row-major order of their leading shape).
    #[pyo3(signature = (origins, directions, *, tmin = None, tmax = None, max_hits = None, threads = None))]
    #[allow(clippy::too_many_arguments)]
    fn _intersect_all<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        max_hits: Option<usize>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let zero = 0.0f64.into_pyobject(py)?.into_any();
        let inf = f64::INFINITY.into_pyobject(py)?.into_any();
        let input = Input::new(origins, directions, tmin.unwrap_or(&zero), tmax.unwrap_or(&inf))?;
        let offset = self.read().offset;
        let rays = input.rays(offset)?;
        let n = rays.n;
        let cap = max_hits.unwrap_or(usize::MAX);
        let (counts, hits, gids, iids) = self.with_world(py, "intersect_all", move |st, w| {
            crate::threads::run(threads, || {
                let tl = w.accel();
                let parts: Vec<(Vec<u32>, Vec<Hit>)> = (0..n)
                    .into_par_iter()
                    .chunks(256)
                    .map(|chunk| {
                        let mut counts = Vec::with_capacity(chunk.len());
                        let mut hits = Vec::new();
                        for i in chunk {
                            let before = hits.len();
                            if let Some(r) = rays.ray(i) {
                                tl.intersect_all(&r, &mut hits);
                                hits.truncate(before + (hits.len() - before).min(cap));
                            }
                            counts.push((hits.len() - before) as u32);
                        }
                        (counts, hits)
                    })
                    .collect();
                let mut counts = Vec::with_capacity(n);
                let mut hits = Vec::new();
                for (c, h) in parts {
                    counts.extend(c);
                    hits.extend(h);
                }
                let gids: Vec<i32> = hits.iter().map(|h| st.inst_geom.get(h.inst as usize).map_or(-1, |&g| g as i32)).collect();
                let iids: Vec<i32> = hits.iter().map(|h| st.ids.get(h.inst as usize).map_or(-1, |&g| g as i32)).collect();
                (counts, hits, gids, iids)
            })
        })?;
        let m = hits.len();
        let mut splits = Vec::with_capacity(n + 1);
        let mut ray_index = Vec::with_capacity(m);
        let mut acc = 0i64;
        splits.push(0);
        for (i, &c) in counts.iter().enumerate() {
            acc += i64::from(c);
            splits.push(acc);
            ray_index.extend(std::iter::repeat_n(i as i64, c as usize));
        }
        let d = PyDict::new(py);
        d.set_item("ray_index", to_numpy(py, ray_index, &[m])?)?;
        d.set_item("splits", to_numpy(py, splits, &[n + 1])?)?;
        d.set_item("t", to_numpy(py, hits.iter().map(|h| h.t).collect::<Vec<_>>(), &[m])?)?;
        d.set_item("prim_id", to_numpy(py, hits.iter().map(|h| h.prim as i32).collect::<Vec<_>>(), &[m])?)?;
        d.set_item("geom_id", to_numpy(py, gids, &[m])?)?;
        d.set_item("inst_id", to_numpy(py, iids, &[m])?)?;
        d.set_item("uv", to_numpy(py, hits.iter().flat_map(|h| [h.u, h.v]).collect::<Vec<_>>(), &[m, 2])?)?;
        d.set_item("shape", PyTuple::new(py, &input.lead)?)?;
        Ok(d)
    }

    /// How many surfaces each ray meets within [``tmin``, ``tmax``) (each triangle once):
    /// an int32 array of the rays' leading shape.
    #[pyo3(signature = (origins, directions, *, tmin = None, tmax = None, threads = None))]
    fn count_hits<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArrayDyn<i32>>> {
        let zero = 0.0f64.into_pyobject(py)?.into_any();
        let inf = f64::INFINITY.into_pyobject(py)?.into_any();
        let input = Input::new(origins, directions, tmin.unwrap_or(&zero), tmax.unwrap_or(&inf))?;
        let offset = self.read().offset;
        let rays = input.rays(offset)?;
        let n = rays.n;
        let v = self.with_world(py, "count_hits", move |_, w| {
            crate::threads::run(threads, || {
                let tl = w.accel();
                (0..n)
                    .into_par_iter()
                    .map_init(Vec::new, |scratch, i| rays.ray(i).map_or(0, |r| tl.count_hits(&r, scratch) as i32))
                    .collect::<Vec<i32>>()
            })
        })?;
        to_numpy(py, v, &input.lead)
    }

    /// A camera's pixel-centre rays traced as 8 × 8 packets, without ray arrays: a dict of
    /// (height, width) fields as ``intersect`` gives, plus ``depth`` (distance along the
    /// view axis, inf on a miss).
    #[pyo3(signature = (camera, *, fields = None, threads = None))]
    fn _trace_camera<'py>(
        &self,
        py: Python<'py>,
        camera: &crate::camera::Camera,
        fields: Option<Vec<String>>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let names = fields
            .unwrap_or_else(|| ["t", "hit", "prim_id", "geom_id", "inst_id", "normal", "depth"].iter().map(|s| (*s).to_string()).collect());
        let f = Fields::parse(&names, true)?;
        let (wd, ht) = (camera.width as usize, camera.height as usize);
        let lead = [ht, wd];
        let bufs = Buffers::new(py, f, &lead, None)?;
        let offset = self.read().offset;
        let cam = camera.build(offset);
        let o = bufs.out;
        self.with_world(py, "trace_camera", move |st, w| {
            crate::threads::run(threads, || {
                let tl = w.accel();
                let forward = cam.forward();
                batches(&lead, wd * ht).par_iter().for_each_init(
                    || (Vec::with_capacity(BATCH), Vec::with_capacity(BATCH), vec![None; BATCH]),
                    |(idx, rs, hits), b| {
                        b.indices(idx);
                        rs.clear();
                        rs.extend(idx.iter().map(|&i| cam.ray((i % wd) as f32 + 0.5, (i / wd) as f32 + 0.5)));
                        tl.intersect_packet(rs, &mut hits[..rs.len()]);
                        for (k, &i) in idx.iter().enumerate() {
                            // SAFETY: `i` is a pixel of this tile only, below width × height.
                            unsafe { o.put(i, st, w, Some(&rs[k]), hits[k], forward) };
                        }
                    },
                );
            })
        })?;
        bufs.into_dict(py)
    }
}

/// A raw pointer that may cross to the workers (each writes its own entries).
#[derive(Clone, Copy)]
struct SendPtr<T>(*mut T);
impl<T> SendPtr<T> {
    fn get(self) -> *mut T {
        self.0
    }
}
// SAFETY: used only for disjoint writes into a buffer that outlives the loop.
unsafe impl<T> Send for SendPtr<T> {}
// SAFETY: as above.
unsafe impl<T> Sync for SendPtr<T> {}
