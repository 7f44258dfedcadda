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
    Per(&'a [f32]),
}

impl Bound1<'_> {
    #[inline(always)]
    fn at(&self, i: usize) -> f32 {
        match self {
            Bound1::Scalar(x) => *x,
            Bound1::Per(s) => s[i],
        }
    }
}

/// The rays of a call as float32 slices in the scene's stored coordinates (sendable to
/// the workers). PERF: float32 input without an offset is read where numpy holds it;
/// anything else is converted once, in parallel, before tracing (reading each value
/// through a per-value conversion was a tenth of a primary-ray query).
#[derive(Clone, Copy)]
struct Rays<'a> {
    o: &'a [f32],
    /// One origin for every ray.
    one_origin: bool,
    d: &'a [f32],
    /// One direction for every ray.
    one_direction: bool,
    n: usize,
    tmin: Bound1<'a>,
    tmax: Bound1<'a>,
}

impl Rays<'_> {
    /// Ray `i`, or `None` when it cannot hit anything (a non-finite origin or direction, a
    /// zero direction, an empty or NaN range).
    #[inline(always)]
    fn ray(&self, i: usize) -> Option<Ray> {
        let k = if self.one_origin { 0 } else { 3 * i };
        let o = Vec3::new(self.o[k], self.o[k + 1], self.o[k + 2]);
        let j = if self.one_direction { 0 } else { 3 * i };
        let d = Vec3::new(self.d[j], self.d[j + 1], self.d[j + 2]);
        let (tmin, tmax) = (self.tmin.at(i), self.tmax.at(i));
        let ok = o.is_finite() && d.is_finite() && d != Vec3::ZERO && tmin < tmax && tmin.is_finite() && !tmax.is_nan();
        ok.then_some(Ray { org: o, dir: d, tmin, tmax })
    }
}

/// `s` as float32, minus `shift` per component (of 3) where given: borrowed when it
/// already is float32 and nothing is taken away, else converted in parallel into `buf`.
fn as_f32<'a>(s: Slice<'a>, shift: Option<DVec3>, buf: &'a mut Vec<f32>) -> &'a [f32] {
    match (s, shift) {
        (Slice::F32(v), None) => v,
        (Slice::F32(v), Some(sh)) => {
            buf.resize(v.len(), 0.0);
            buf.par_chunks_mut(3 * 4096).zip(v.par_chunks(3 * 4096)).for_each(|(o, i)| {
                for (k, (o, i)) in o.iter_mut().zip(i).enumerate() {
                    *o = (f64::from(*i) - sh[k % 3]) as f32;
                }
            });
            buf
        }
        (Slice::F64(v), sh) => {
            let sh = sh.unwrap_or(DVec3::ZERO);
            buf.resize(v.len(), 0.0);
            buf.par_chunks_mut(3 * 4096).zip(v.par_chunks(3 * 4096)).for_each(|(o, i)| {
                for (k, (o, i)) in o.iter_mut().zip(i).enumerate() {
                    *o = (*i - sh[k % 3]) as f32;
                }
            });
            buf
        }
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
    /// [`Input::new`] with the default range [0, inf) where a bound is not given.
    fn with_defaults(
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: Option<&Bound<'py, PyAny>>,
        tmax: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Self> {
        let zero = 0.0f64.into_pyobject(py)?.into_any();
        let inf = f64::INFINITY.into_pyobject(py)?.into_any();
        Self::new(origins, directions, tmin.unwrap_or(&zero), tmax.unwrap_or(&inf))
    }

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

    /// The arrays' values (sendable: converted and traced with the GIL released).
    fn raw(&self) -> PyResult<Raw<'_>> {
        fn opt<'a>(f: &'a Option<Floats<'_>>) -> PyResult<Option<Slice<'a>>> {
            Ok(match f {
                Some(f) => Some(f.slice()?),
                None => None,
            })
        }
        Ok(Raw {
            o: self.o.slice()?,
            d: self.d.slice()?,
            tmin: opt(&self.tmin)?,
            tmax: opt(&self.tmax)?,
            tmin_s: self.tmin_s,
            tmax_s: self.tmax_s,
            one_origin: self.one_origin,
            one_direction: self.one_direction,
            n: self.lead.iter().product(),
        })
    }
}

/// A call's arrays as slices of whatever type they came in.
#[derive(Clone, Copy)]
struct Raw<'a> {
    o: Slice<'a>,
    d: Slice<'a>,
    tmin: Option<Slice<'a>>,
    tmax: Option<Slice<'a>>,
    tmin_s: f32,
    tmax_s: f32,
    one_origin: bool,
    one_direction: bool,
    n: usize,
}

impl<'a> Raw<'a> {
    /// The rays as float32 in the scene's coordinates (`offset` taken from the origins),
    /// converted into `bufs` where needed (call with the GIL released: a float64 batch is
    /// converted here).
    fn rays(self, offset: DVec3, bufs: &'a mut Buffers32) -> Rays<'a> {
        let shift = (offset != DVec3::ZERO).then_some(offset);
        let Buffers32 { o: bo, d: bd, tmin: b0, tmax: b1 } = bufs;
        let bound = |s: Option<Slice<'a>>, x: f32, buf: &'a mut Vec<f32>| match s {
            Some(Slice::F32(v)) => Bound1::Per(v),
            Some(Slice::F64(v)) => {
                buf.extend(v.iter().map(|&x| x as f32));
                Bound1::Per(buf)
            }
            None => Bound1::Scalar(x),
        };
        Rays {
            o: as_f32(self.o, shift, bo),
            one_origin: self.one_origin,
            d: as_f32(self.d, None, bd),
            one_direction: self.one_direction,
            n: self.n,
            tmin: bound(self.tmin, self.tmin_s, b0),
            tmax: bound(self.tmax, self.tmax_s, b1),
        }
    }
}

/// Float32 copies of a call's arrays where they were not float32 already.
#[derive(Default)]
struct Buffers32 {
    o: Vec<f32>,
    d: Vec<f32>,
    tmin: Vec<f32>,
    tmax: Vec<f32>,
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

/// A batch's rays gathered straight into SoA blocks of eight (a ray that cannot hit:
/// an empty lane), which lanes hold a ray, and whether they share a direction octant.
/// PERF: one pass over the arrays per batch (a list of rays first, then the blocks, was
/// a fifth of a primary-ray query).
struct Gathered {
    blocks: [RayBlock; BATCH / 8],
    valid: u64,
    len: usize,
}

impl Gathered {
    fn new() -> Self {
        Self { blocks: [RayBlock::EMPTY; BATCH / 8], valid: 0, len: 0 }
    }

    /// Gathers rays `idx`; returns whether they suit the packet kernels (one direction
    /// octant, at least four rays).
    #[inline(always)]
    fn gather(&mut self, rays: &Rays<'_>, idx: &[usize]) -> bool {
        let sign = |d: Vec3| (d.x < 0.0) as u8 | ((d.y < 0.0) as u8) << 1 | ((d.z < 0.0) as u8) << 2;
        let (mut all, mut any) = (7u8, 0u8);
        self.valid = 0;
        self.len = idx.len();
        for (k, &i) in idx.iter().enumerate() {
            let b = &mut self.blocks[k / 8];
            match rays.ray(i) {
                Some(r) => {
                    b.set(k % 8, &r);
                    self.valid |= 1 << k;
                    let s = sign(r.dir);
                    all &= s;
                    any |= s;
                }
                None => b.set(k % 8, &EMPTY_RAY),
            }
        }
        for k in idx.len()..idx.len().div_ceil(8) * 8 {
            self.blocks[k / 8].set(k % 8, &EMPTY_RAY);
        }
        all == any && self.valid.count_ones() >= 4
    }

    fn blocks(&self) -> &[RayBlock] {
        &self.blocks[..self.len.div_ceil(8)]
    }

    /// Ray `k` of the batch (when it holds one).
    #[inline(always)]
    fn ray(&self, k: usize) -> Option<Ray> {
        if self.valid & (1 << k) == 0 {
            return None;
        }
        let (b, l) = (&self.blocks[k / 8], k % 8);
        Some(Ray {
            org: Vec3::new(b.org[0][l], b.org[1][l], b.org[2][l]),
            dir: Vec3::new(b.dir[0][l], b.dir[1][l], b.dir[2][l]),
            tmin: b.tmin[l],
            tmax: b.tmax[l],
        })
    }
}

/// Traces closest hits of `rays` into `out`.
fn closest(st: &State, w: &World, rays: Rays<'_>, lead: &[usize], mode: Option<bool>, out: Out, forward: Vec3) {
    let tl = w.accel();
    let needs_ray = !out.normal.is_null() || !out.depth.is_null();
    batches(lead, rays.n).par_iter().for_each_init(
        || (Vec::with_capacity(BATCH), Gathered::new(), vec![None; BATCH]),
        |(idx, g, hits), b| {
            b.indices(idx);
            let packets = g.gather(&rays, idx);
            if mode.unwrap_or(packets) {
                let nb = g.blocks().len();
                tl.intersect_blocks(g.blocks(), &mut hits[..nb * 8]);
            } else {
                for (k, h) in hits[..idx.len()].iter_mut().enumerate() {
                    *h = g.ray(k).and_then(|r| tl.intersect(&r));
                }
            }
            for (k, &i) in idx.iter().enumerate() {
                let hit = if g.valid & (1 << k) != 0 { hits[k] } else { None };
                let r = if needs_ray { g.ray(k) } else { None };
                // SAFETY: `i` is a ray of this batch only, below the ray count.
                unsafe { out.put(i, st, w, r.as_ref(), hit, forward) };
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
        let input = Input::with_defaults(py, origins, directions, tmin, tmax)?;
        let names = fields.unwrap_or_else(|| FIELD_NAMES[..7].iter().map(|s| (*s).to_string()).collect());
        let f = Fields::parse(&names, false)?;
        let bufs = Buffers::new(py, f, &input.lead, out)?;
        let offset = self.read().offset;
        let raw = input.raw()?;
        let lead = input.lead.clone();
        let o = bufs.out;
        self.with_world(py, "intersect", move |st, w| {
            crate::threads::run(threads, || {
                let mut conv = Buffers32::default();
                closest(st, w, raw.rays(offset, &mut conv), &lead, coherent, o, Vec3::Z)
            })
        })?;
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
        let input = Input::with_defaults(py, origins, directions, tmin, tmax)?;
        let offset = self.read().offset;
        let raw = input.raw()?;
        let lead = input.lead.clone();
        let n = raw.n;
        let v = self.with_world(py, "occluded", move |_, w| {
            crate::threads::run(threads, || {
                let mut conv = Buffers32::default();
                let rays = raw.rays(offset, &mut conv);
                let tl = w.accel();
                let mut res = vec![false; n];
                let ptr = SendPtr(res.as_mut_ptr());
                batches(&lead, n).par_iter().for_each_init(
                    || (Vec::with_capacity(BATCH), Gathered::new(), vec![false; BATCH]),
                    |(idx, g, occ), b| {
                        b.indices(idx);
                        let packets = g.gather(&rays, idx);
                        if coherent.unwrap_or(packets) {
                            let nb = g.blocks().len();
                            tl.occluded_blocks(g.blocks(), &mut occ[..nb * 8]);
                        } else {
                            for (k, o) in occ[..idx.len()].iter_mut().enumerate() {
                                *o = g.ray(k).is_some_and(|r| tl.occluded(&r));
                            }
                        }
                        for (k, &i) in idx.iter().enumerate() {
                            // SAFETY: `i` is below `n` and belongs to this batch only.
                            unsafe { *ptr.get().add(i) = g.valid & (1 << k) != 0 && occ[k] };
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
        let input = Input::with_defaults(py, origins, directions, tmin, tmax)?;
        let offset = self.read().offset;
        let raw = input.raw()?;
        let n = raw.n;
        let cap = max_hits.unwrap_or(usize::MAX);
        let (counts, hits, gids, iids) = self.with_world(py, "intersect_all", move |st, w| {
            crate::threads::run(threads, || {
                let mut conv = Buffers32::default();
                let rays = raw.rays(offset, &mut conv);
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
        let input = Input::with_defaults(py, origins, directions, tmin, tmax)?;
        let offset = self.read().offset;
        let raw = input.raw()?;
        let n = raw.n;
        let v = self.with_world(py, "count_hits", move |_, w| {
            crate::threads::run(threads, || {
                let mut conv = Buffers32::default();
                let rays = raw.rays(offset, &mut conv);
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
                    || (Vec::with_capacity(BATCH), Vec::with_capacity(BATCH), vec![EMPTY_RAY; BATCH], vec![None; BATCH]),
                    |(idx, pts, rs, hits), b| {
                        b.indices(idx);
                        pts.clear();
                        pts.extend(idx.iter().map(|&i| ((i % wd) as f32 + 0.5, (i / wd) as f32 + 0.5)));
                        // (The camera's rays a component at a time over the tile, vectorized:
                        // ray by ray they were a quarter of the query.)
                        let rs = &mut rs[..idx.len()];
                        cam.rays_at(pts, rs);
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
