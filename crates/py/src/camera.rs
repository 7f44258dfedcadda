//! `Camera`: look-at, calibrated (intrinsics and extrinsics as OpenCV and Open3D define
//! them), orthographic, with an optional thin lens. Kept in the caller's coordinates (f64)
//! and made into lucent's camera for a scene's offset when used.

use crate::arrays::{to_numpy, Floats};
use glam::{DMat3, DVec3, Vec3};
use lucent_render::Camera as RCamera;
use lucent_scene::CameraDesc;
use numpy::PyArrayDyn;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// Origins and directions, each (height, width, 3).
type RayArrays<'py> = (Bound<'py, PyArrayDyn<f32>>, Bound<'py, PyArrayDyn<f32>>);

#[derive(Clone, Copy, Debug)]
enum Kind {
    /// Look-at with a vertical field of view, or an orthographic view of a height.
    LookAt { eye: DVec3, target: DVec3, up: Vec3, vfov: f32, ortho_height: Option<f32> },
    /// A calibrated pinhole: axes in the world, focal lengths and principal point in pixels.
    Intrinsics { eye: DVec3, right: Vec3, down: Vec3, forward: Vec3, f: (f32, f32), c: (f32, f32) },
}

/// A camera: where it is, what it sees, the image size. Make one with
/// ``Camera.look_at``, ``Camera.from_intrinsics`` or ``Camera.orthographic``.
#[pyclass(frozen, module = "lucent._lucent", name = "Camera")]
#[derive(Clone, Debug)]
pub struct Camera {
    kind: Kind,
    /// Image size in pixels.
    #[pyo3(get)]
    pub width: u32,
    /// Image height in pixels.
    #[pyo3(get)]
    pub height: u32,
    lens: Option<(f32, f32)>,
    clip: Option<(f32, f32)>,
}

fn size(width: u32, height: u32) -> PyResult<(u32, u32)> {
    if width == 0 || height == 0 || width > 16384 || height > 16384 {
        return Err(PyValueError::new_err(format!("width, height: {width} x {height} is not an image size (1..=16384 each)")));
    }
    Ok((width, height))
}

fn finite3(v: [f64; 3], name: &str) -> PyResult<DVec3> {
    let d = DVec3::from(v);
    if d.is_finite() {
        Ok(d)
    } else {
        Err(PyValueError::new_err(format!("{name}: not finite ({d})")))
    }
}

impl Camera {
    /// A camera from a scene file's description (stored coordinates plus `offset`).
    pub fn from_desc(d: &CameraDesc, width: u32, height: u32, offset: DVec3) -> Self {
        Self {
            kind: Kind::LookAt {
                eye: d.eye.as_dvec3() + offset,
                target: d.look_at.as_dvec3() + offset,
                up: d.up,
                vfov: d.vfov_deg,
                ortho_height: d.ortho_height,
            },
            width,
            height,
            lens: None,
            clip: None,
        }
    }

    /// The same camera with a scene file's clip range and lens.
    pub fn with_hints(mut self, clip: (f32, f32), lens: Option<(f32, f32)>) -> Self {
        if clip.0 >= 0.0 && clip.1 > clip.0 && clip != (0.0, f32::INFINITY) {
            self.clip = Some(clip);
        }
        self.lens = lens;
        self
    }

    /// lucent's camera for a scene stored minus `offset`.
    pub fn build(&self, offset: DVec3) -> RCamera {
        let mut c = match self.kind {
            Kind::LookAt { .. } => match self.desc(offset) {
                Some(d) => RCamera::new(&d, self.width, self.height),
                None => {
                    RCamera::new(&CameraDesc::from_view(&[0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0, 45.0]), self.width, self.height)
                }
            },
            Kind::Intrinsics { eye, right, down, forward, f, c } => {
                RCamera::from_intrinsics((eye - offset).as_vec3(), right, down, forward, f, c, self.width, self.height)
            }
        };
        if let Some((near, far)) = self.clip {
            c = c.with_clip(near, far);
        }
        if let Some((r, f)) = self.lens {
            c = c.with_lens(r, f);
        }
        c
    }

    /// The look-at description (for a camera made by `look_at` or `orthographic`).
    pub fn desc(&self, offset: DVec3) -> Option<CameraDesc> {
        match self.kind {
            Kind::LookAt { eye, target, up, vfov, ortho_height } => {
                Some(CameraDesc { eye: (eye - offset).as_vec3(), look_at: (target - offset).as_vec3(), up, vfov_deg: vfov, ortho_height })
            }
            Kind::Intrinsics { .. } => None,
        }
    }

    /// [`Camera::with_size`] for Rust callers.
    pub fn with_size_checked(&self, width: u32, height: u32) -> PyResult<Self> {
        self.with_size(width, height)
    }

    /// Whether the camera is exactly what `lucent render --camera` describes (look-at,
    /// perspective, no lens or clip of its own).
    pub fn is_plain_view(&self) -> bool {
        matches!(self.kind, Kind::LookAt { ortho_height: None, .. }) && self.lens.is_none() && self.clip.is_none()
    }
}

#[pymethods]
impl Camera {
    /// A perspective camera at ``eye`` looking at ``target`` with ``up`` pointing up,
    /// ``fov`` degrees across the image's ``fov_axis`` (``'x'``, as Mitsuba, or ``'y'``).
    #[staticmethod]
    #[pyo3(signature = (eye, target, up = [0.0, 1.0, 0.0], *, fov = 45.0, fov_axis = "x", width = 640, height = 480))]
    fn look_at(eye: [f64; 3], target: [f64; 3], up: [f64; 3], fov: f64, fov_axis: &str, width: u32, height: u32) -> PyResult<Self> {
        let (width, height) = size(width, height)?;
        let (eye, target, up) = (finite3(eye, "eye")?, finite3(target, "target")?, finite3(up, "up")?);
        if eye == target {
            return Err(PyValueError::new_err("eye and target are the same point"));
        }
        if !(fov > 0.0 && fov < 180.0) {
            return Err(PyValueError::new_err(format!("fov: {fov} degrees is not between 0 and 180")));
        }
        let vfov = match fov_axis {
            "y" => fov,
            "x" => 2.0 * ((fov.to_radians() * 0.5).tan() * f64::from(height) / f64::from(width)).atan().to_degrees(),
            a => return Err(PyValueError::new_err(format!("fov_axis: {a:?} is not 'x' or 'y'"))),
        };
        Ok(Self {
            kind: Kind::LookAt { eye, target, up: up.as_vec3(), vfov: vfov as f32, ortho_height: None },
            width,
            height,
            lens: None,
            clip: None,
        })
    }

    /// An orthographic camera at ``eye`` looking at ``target``, seeing ``view_height``
    /// world units from the bottom of the image to the top.
    #[staticmethod]
    #[pyo3(signature = (eye, target, up = [0.0, 1.0, 0.0], *, view_height = 1.0, width = 640, height = 480))]
    fn orthographic(eye: [f64; 3], target: [f64; 3], up: [f64; 3], view_height: f64, width: u32, height: u32) -> PyResult<Self> {
        let (width, height) = size(width, height)?;
        let (eye, target, up) = (finite3(eye, "eye")?, finite3(target, "target")?, finite3(up, "up")?);
        if eye == target {
            return Err(PyValueError::new_err("eye and target are the same point"));
        }
        if !(view_height > 0.0 && view_height.is_finite()) {
            return Err(PyValueError::new_err(format!("view_height: {view_height} is not a positive size")));
        }
        Ok(Self {
            kind: Kind::LookAt { eye, target, up: up.as_vec3(), vfov: 45.0, ortho_height: Some(view_height as f32) },
            width,
            height,
            lens: None,
            clip: None,
        })
    }

    /// A calibrated pinhole camera as OpenCV and Open3D describe it: ``intrinsic`` K
    /// (3, 3) with focal lengths and principal point in pixels, and either
    /// ``extrinsic`` (4, 4), world to camera (x right, y down, z forward), or ``pose``
    /// (4, 4), camera to world. Pixel (x, y) has its centre at (x + 0.5, y + 0.5).
    #[staticmethod]
    #[pyo3(signature = (intrinsic, *, extrinsic = None, pose = None, width, height))]
    fn from_intrinsics(
        intrinsic: &Bound<'_, PyAny>,
        extrinsic: Option<&Bound<'_, PyAny>>,
        pose: Option<&Bound<'_, PyAny>>,
        width: u32,
        height: u32,
    ) -> PyResult<Self> {
        let (width, height) = size(width, height)?;
        let k = Floats::extract(intrinsic, "intrinsic")?;
        if k.shape() != [3, 3] {
            return Err(PyValueError::new_err(format!("intrinsic: shape {} where (3, 3) was needed", crate::arrays::shape_str(k.shape()))));
        }
        let ks = k.slice()?;
        let (fx, fy, cx, cy) = (ks.get(0), ks.get(4), ks.get(2), ks.get(5));
        if !(fx > 0.0 && fy > 0.0 && fx.is_finite() && fy.is_finite() && cx.is_finite() && cy.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "intrinsic: focal lengths {fx}, {fy} (positive) and principal point {cx}, {cy} (finite) were needed"
            )));
        }
        if ks.get(1) != 0.0 {
            return Err(PyValueError::new_err("intrinsic: a skewed camera (K[0, 1] not 0) is not supported"));
        }
        // Camera to world.
        let (r, eye) = match (extrinsic, pose) {
            (Some(e), None) => {
                let inv = crate::arrays::one_affine(Some(e), "extrinsic")?.inverse();
                (inv.matrix3, inv.translation)
            }
            (None, Some(p)) => {
                let a = crate::arrays::one_affine(Some(p), "pose")?;
                (a.matrix3, a.translation)
            }
            (None, None) => (DMat3::IDENTITY, DVec3::ZERO),
            (Some(_), Some(_)) => return Err(PyValueError::new_err("give extrinsic or pose, not both")),
        };
        if !eye.is_finite() || r.determinant().abs() < 1e-12 {
            return Err(PyValueError::new_err("extrinsic/pose: not an invertible rigid map"));
        }
        let axis = |v: DVec3, name: &str| -> PyResult<Vec3> {
            v.try_normalize()
                .map(|v| v.as_vec3())
                .ok_or_else(|| PyValueError::new_err(format!("extrinsic/pose: the camera's {name} axis is zero")))
        };
        Ok(Self {
            kind: Kind::Intrinsics {
                eye,
                right: axis(r.x_axis, "x")?,
                down: axis(r.y_axis, "y")?,
                forward: axis(r.z_axis, "z")?,
                f: (fx as f32, fy as f32),
                c: (cx as f32, cy as f32),
            },
            width,
            height,
            lens: None,
            clip: None,
        })
    }

    /// The same camera with a thin lens: ``aperture`` radius and the distance in focus.
    fn with_lens(&self, aperture: f32, focus_distance: f32) -> PyResult<Self> {
        if !(aperture >= 0.0 && aperture.is_finite() && focus_distance > 0.0 && focus_distance.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "aperture {aperture} (0 or more) and focus_distance {focus_distance} (positive) were needed"
            )));
        }
        Ok(Self { lens: Some((aperture, focus_distance)), ..self.clone() })
    }

    /// The same camera seeing only depths in [``near``, ``far``).
    fn with_clip(&self, near: f32, far: f32) -> PyResult<Self> {
        if !(near >= 0.0 && far > near) {
            return Err(PyValueError::new_err(format!("near {near} and far {far}: 0 <= near < far was needed")));
        }
        Ok(Self { clip: Some((near, far)), ..self.clone() })
    }

    /// The same camera with another image size (the field of view kept).
    fn with_size(&self, width: u32, height: u32) -> PyResult<Self> {
        let (width, height) = size(width, height)?;
        let kind = match self.kind {
            Kind::Intrinsics { eye, right, down, forward, f, c } => {
                // Pixels scale with the image.
                let (sx, sy) = (width as f32 / self.width as f32, height as f32 / self.height as f32);
                Kind::Intrinsics { eye, right, down, forward, f: (f.0 * sx, f.1 * sy), c: (c.0 * sx, c.1 * sy) }
            }
            k => k,
        };
        Ok(Self { kind, width, height, ..self.clone() })
    }

    /// The unit view axis in the world.
    #[getter]
    fn forward(&self) -> [f32; 3] {
        self.build(DVec3::ZERO).forward().to_array()
    }

    /// The eye (the lens centre).
    #[getter]
    fn eye(&self) -> [f64; 3] {
        match self.kind {
            Kind::LookAt { eye, .. } | Kind::Intrinsics { eye, .. } => eye.to_array(),
        }
    }

    /// The pixel-centre rays: origins and unit directions, each (height, width, 3)
    /// float32 (a thin lens's rays from the lens centre).
    fn rays<'py>(&self, py: Python<'py>) -> PyResult<RayArrays<'py>> {
        let cam = self.build(DVec3::ZERO);
        let (w, h) = (self.width as usize, self.height as usize);
        let (o, d) = py.detach(|| {
            let mut o = Vec::with_capacity(w * h * 3);
            let mut d = Vec::with_capacity(w * h * 3);
            for y in 0..h {
                for x in 0..w {
                    let r = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
                    o.extend(r.org.to_array());
                    d.extend(r.dir.to_array());
                }
            }
            (o, d)
        });
        Ok((to_numpy(py, o, &[h, w, 3])?, to_numpy(py, d, &[h, w, 3])?))
    }

    fn __repr__(&self) -> String {
        match self.kind {
            Kind::LookAt { eye, target, vfov, ortho_height: None, .. } => {
                format!("Camera.look_at(eye={eye}, target={target}, vertical fov {vfov:.3} deg, {}x{})", self.width, self.height)
            }
            Kind::LookAt { eye, target, ortho_height: Some(hh), .. } => {
                format!("Camera.orthographic(eye={eye}, target={target}, view_height={hh}, {}x{})", self.width, self.height)
            }
            Kind::Intrinsics { eye, f, c, .. } => {
                format!("Camera.from_intrinsics(eye={eye}, f={f:?}, c={c:?}, {}x{})", self.width, self.height)
            }
        }
    }
}
