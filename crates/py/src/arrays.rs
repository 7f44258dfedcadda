//! numpy arrays in and out: any array-like becomes a C-contiguous float32 or float64 array
//! (float32 C-contiguous input is read in place), shapes are checked with the argument's
//! name in the message, and results go back as arrays that own their Rust buffers.

use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{Element, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// A float array as numpy holds it, borrowed for the call.
pub enum Floats<'py> {
    /// float32, read in place.
    F32(PyReadonlyArrayDyn<'py, f32>),
    /// float64 (and integer input, converted once).
    F64(PyReadonlyArrayDyn<'py, f64>),
}

/// The data of [`Floats`] as plain slices (sendable to worker threads).
#[derive(Clone, Copy)]
pub enum Slice<'a> {
    /// float32 values.
    F32(&'a [f32]),
    /// float64 values.
    F64(&'a [f64]),
}

impl Slice<'_> {
    /// Value `i` as f64.
    #[inline]
    pub fn get(&self, i: usize) -> f64 {
        match self {
            Slice::F32(s) => f64::from(s[i]),
            Slice::F64(s) => s[i],
        }
    }

    /// Whether the values are float64.
    pub fn is_f64(&self) -> bool {
        matches!(self, Slice::F64(_))
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            Slice::F32(s) => s.len(),
            Slice::F64(s) => s.len(),
        }
    }
}

impl<'py> Floats<'py> {
    /// `obj` as a C-contiguous float array: float32 and float64 kept, integers and bools
    /// converted to float64; anything else is a `TypeError` naming `name`.
    pub fn extract(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Self> {
        let py = obj.py();
        if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
            if a.is_c_contiguous() {
                return Ok(Floats::F32(a.try_readonly().map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?));
            }
        }
        let np = py.import("numpy")?;
        let arr =
            np.call_method1("asarray", (obj,)).map_err(|e| PyValueError::new_err(format!("{name}: not an array of numbers ({e})")))?;
        let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
        let itemsize: usize = arr.getattr("dtype")?.getattr("itemsize")?.extract()?;
        let dtype_name: String = arr.getattr("dtype")?.str()?.extract()?;
        let want = match (kind.as_str(), itemsize) {
            ("f", 4) => "float32",
            ("f", _) | ("i", _) | ("u", _) | ("b", _) => "float64",
            _ => {
                return Err(PyTypeError::new_err(format!(
                    "{name}: an array of {dtype_name} where numbers (float32 or float64) were needed"
                )))
            }
        };
        let c = np.call_method1("ascontiguousarray", (arr, want))?;
        if want == "float32" {
            let a = c.cast_into::<PyArrayDyn<f32>>().map_err(|e| PyTypeError::new_err(format!("{name}: {e}")))?;
            Ok(Floats::F32(a.try_readonly().map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?))
        } else {
            let a = c.cast_into::<PyArrayDyn<f64>>().map_err(|e| PyTypeError::new_err(format!("{name}: {e}")))?;
            Ok(Floats::F64(a.try_readonly().map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?))
        }
    }

    /// The shape.
    pub fn shape(&self) -> &[usize] {
        match self {
            Floats::F32(a) => a.shape(),
            Floats::F64(a) => a.shape(),
        }
    }

    /// The values (row-major).
    pub fn slice(&self) -> PyResult<Slice<'_>> {
        match self {
            Floats::F32(a) => Ok(Slice::F32(a.as_slice().map_err(|e| PyValueError::new_err(e.to_string()))?)),
            Floats::F64(a) => Ok(Slice::F64(a.as_slice().map_err(|e| PyValueError::new_err(e.to_string()))?)),
        }
    }

    /// Checks the shape is `(N, k)` and returns `N`.
    pub fn rows(&self, name: &str, k: usize) -> PyResult<usize> {
        match self.vectors(name, k)?.as_slice() {
            [n] => Ok(*n),
            _ => Err(PyValueError::new_err(format!("{name}: shape {} where (N, {k}) was needed", shape_str(self.shape())))),
        }
    }

    /// Checks the shape is `(..., k)` and returns the leading shape.
    pub fn vectors(&self, name: &str, k: usize) -> PyResult<Vec<usize>> {
        let s = self.shape();
        match s.split_last() {
            Some((&last, lead)) if last == k => Ok(lead.to_vec()),
            _ => Err(PyValueError::new_err(format!("{name}: shape {} where (..., {k}) was needed", shape_str(s)))),
        }
    }
}

/// `(a, b, c)` as Python prints a shape.
pub fn shape_str(s: &[usize]) -> String {
    match s {
        [one] => format!("({one},)"),
        _ => format!("({})", s.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")),
    }
}

/// An integer array (any integer dtype) as i64 values, with its shape.
pub fn ints(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<(Vec<i64>, Vec<usize>)> {
    let np = obj.py().import("numpy")?;
    let arr = np.call_method1("asarray", (obj,)).map_err(|e| PyValueError::new_err(format!("{name}: not an array of integers ({e})")))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    // (An empty list reads as float64: no integers in it to refuse.)
    let empty = kind == "f" && arr.call_method0("__len__").is_ok_and(|n| n.extract::<usize>().is_ok_and(|n| n == 0));
    if !(matches!(kind.as_str(), "i" | "u") || empty) {
        let dtype_name: String = arr.getattr("dtype")?.str()?.extract()?;
        return Err(PyTypeError::new_err(format!("{name}: an array of {dtype_name} where integers were needed")));
    }
    let c = np.call_method1("ascontiguousarray", (arr, "int64"))?;
    let a = c.cast_into::<PyArrayDyn<i64>>().map_err(|e| PyTypeError::new_err(format!("{name}: {e}")))?;
    let r = a.readonly();
    let v = r.as_slice().map_err(|e| PyValueError::new_err(e.to_string()))?.to_vec();
    Ok((v, r.shape().to_vec()))
}

/// A numpy array of shape `shape` owning `v` (no copy).
pub fn to_numpy<'py, T: Element>(py: Python<'py>, v: Vec<T>, shape: &[usize]) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let a =
        ArrayD::from_shape_vec(IxDyn(shape), v).map_err(|e| PyValueError::new_err(format!("result shape {}: {e}", shape_str(shape))))?;
    Ok(PyArrayDyn::from_owned_array(py, a))
}

/// `shape` with `k` appended (when `k` is not zero).
pub fn with_last(shape: &[usize], k: usize) -> Vec<usize> {
    let mut s = shape.to_vec();
    if k > 0 {
        s.push(k);
    }
    s
}

/// One `(4, 4)` world-from-object matrix, or the identity when none is given.
pub fn one_affine(obj: Option<&Bound<'_, PyAny>>, name: &str) -> PyResult<glam::DAffine3> {
    let Some(obj) = obj else { return Ok(glam::DAffine3::IDENTITY) };
    match affines(obj, name)? {
        (a, lead) if lead.is_empty() => Ok(a[0]),
        (_, lead) => Err(PyValueError::new_err(format!(
            "{name}: one (4, 4) matrix was needed, not {}",
            shape_str(&with_last(&with_last(&lead, 4), 4))
        ))),
    }
}

/// A `(4, 4)` matrix (or `(K, 4, 4)` matrices) as affine maps in f64, the bottom row
/// checked to be `0 0 0 1`.
pub fn affines(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<(Vec<glam::DAffine3>, Vec<usize>)> {
    let f = Floats::extract(obj, name)?;
    let s = f.shape().to_vec();
    if s.len() < 2 || s[s.len() - 1] != 4 || s[s.len() - 2] != 4 {
        return Err(PyValueError::new_err(format!("{name}: shape {} where (4, 4) or (K, 4, 4) was needed", shape_str(&s))));
    }
    let v = f.slice()?;
    let n = v.len() / 16;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let m = |r: usize, c: usize| v.get(k * 16 + r * 4 + c);
        let bottom = [m(3, 0), m(3, 1), m(3, 2), m(3, 3)];
        if bottom != [0.0, 0.0, 0.0, 1.0] {
            return Err(PyValueError::new_err(format!(
                "{name}[{k}]: the bottom row is {bottom:?}, not [0, 0, 0, 1] (an affine map is needed)"
            )));
        }
        let a = glam::DAffine3::from_cols_array(&[
            m(0, 0),
            m(1, 0),
            m(2, 0),
            m(0, 1),
            m(1, 1),
            m(2, 1),
            m(0, 2),
            m(1, 2),
            m(2, 2),
            m(0, 3),
            m(1, 3),
            m(2, 3),
        ]);
        if !a.is_finite() {
            return Err(PyValueError::new_err(format!("{name}[{k}]: not finite")));
        }
        out.push(a);
    }
    Ok((out, s[..s.len() - 2].to_vec()))
}
