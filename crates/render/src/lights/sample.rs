//! What a light answers: a direction toward it from a shading point ([`LightSample`]),
//! or a ray of light leaving it ([`EmissionSample`]).

use glam::Vec3;

/// A light's answer for one shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point toward the light.
    pub dir: Vec3,
    /// Distance to the light's point (infinite for directional and environment lights).
    pub dist: f32,
    /// Radiance arriving along `dir` (for a delta light: its intensity over the squared
    /// distance, the irradiance it gives at normal incidence).
    pub li: Vec3,
    /// Density per solid angle of this direction (for a delta light: its probability).
    pub pdf: f32,
    /// A delta light (point, spot, directional, or the user's): no BSDF ray can meet it.
    pub delta: bool,
}

/// A ray of light leaving a light, for light paths (virtual point lights).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissionSample {
    /// Where it starts.
    pub p: Vec3,
    /// Unit direction it travels.
    pub dir: Vec3,
    /// The emitting surface's normal (area lights), for offsetting the start.
    pub n: Option<Vec3>,
    /// Power it carries: the emitted radiance times the cosine over the densities of
    /// its choice, point and direction.
    pub flux: Vec3,
}
