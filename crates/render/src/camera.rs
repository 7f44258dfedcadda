//! Cameras: pinhole (eye, look-at, up, vertical field of view) and orthographic.
//!
//! Ray generation follows the benchmark harness's convention exactly (shared/bench): pixel
//! (x, y) with y = 0 at the top maps to `sx = (2 (x + 0.5) / w - 1) tan(fov/2) w/h` and
//! `sy = (1 - 2 (y + 0.5) / h) tan(fov/2)`, direction `normalize(f + sx r + sy u)`.

use glam::Vec3;
use lucent_accel::Ray;
use lucent_scene::CameraDesc;

/// A camera ready to make rays for a `width` × `height` image.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    half_h: f32,
    aspect: f32,
    ortho: bool,
    width: u32,
    height: u32,
}

impl Camera {
    /// Sets up a camera; `ortho_height` in `desc` makes it orthographic.
    #[must_use]
    pub fn new(desc: &CameraDesc, width: u32, height: u32) -> Self {
        let forward = (desc.look_at - desc.eye).normalize_or(-Vec3::Z);
        let mut right = forward.cross(desc.up).normalize_or_zero();
        if right == Vec3::ZERO {
            right = forward.any_orthonormal_vector();
        }
        let up = right.cross(forward);
        let (half_h, ortho) = match desc.ortho_height {
            Some(h) => (h * 0.5, true),
            None => ((desc.vfov_deg.to_radians() * 0.5).tan(), false),
        };
        Self {
            eye: desc.eye,
            forward,
            right,
            up,
            half_h,
            aspect: width as f32 / height.max(1) as f32,
            ortho,
            width: width.max(1),
            height: height.max(1),
        }
    }

    /// The ray through image position (`x`, `y`) in pixels (pixel centres at +0.5).
    #[must_use]
    pub fn ray(&self, x: f32, y: f32) -> Ray {
        let sx = (2.0 * x / self.width as f32 - 1.0) * self.half_h * self.aspect;
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.half_h;
        if self.ortho {
            Ray::new(self.eye + self.right * sx + self.up * sy, self.forward)
        } else {
            Ray::new(self.eye, (self.forward + self.right * sx + self.up * sy).normalize())
        }
    }

    /// Eye position.
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        self.eye
    }
}

/// A camera that frames `bounds` from the front (+z side), looking at its centre.
#[must_use]
pub fn framing_camera(lo: Vec3, hi: Vec3) -> CameraDesc {
    let c = (lo + hi) * 0.5;
    let r = ((hi - lo).length() * 0.5).max(1e-6);
    let vfov: f32 = 45.0;
    let dist = r / (vfov.to_radians() * 0.5).sin();
    let eye = c + Vec3::new(0.35, 0.3, 1.0).normalize() * dist;
    CameraDesc { eye, look_at: c, up: Vec3::Y, vfov_deg: vfov, ortho_height: None }
}
