//! A camera description: where it is, where it looks, its field of view or orthographic
//! height (what scene files and animations give; `lucent_render::Camera` makes rays).

use glam::Vec3;

/// A camera description.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraDesc {
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub look_at: Vec3,
    /// Up hint.
    pub up: Vec3,
    /// Vertical field of view in degrees (perspective).
    pub vfov_deg: f32,
    /// Orthographic: full height of the view in world units.
    pub ortho_height: Option<f32>,
}

impl CameraDesc {
    /// A perspective camera from the ten numbers `--camera` and the scene README use:
    /// eye (3), look-at point (3), up vector (3), vertical field of view in degrees.
    #[must_use]
    pub fn from_view(c: &[f32; 10]) -> Self {
        Self {
            eye: Vec3::new(c[0], c[1], c[2]),
            look_at: Vec3::new(c[3], c[4], c[5]),
            up: Vec3::new(c[6], c[7], c[8]),
            vfov_deg: c[9],
            ortho_height: None,
        }
    }
}
