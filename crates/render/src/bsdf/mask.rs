//! A surface that is there with probability α (Mitsuba's `mask`): its BSDF times α, plus a
//! null lobe that carries light straight through with probability 1 − α (a delta
//! transmission of weight one). Sampled paths pass the holes; next-event shadow rays stop
//! at the surface, as in Mitsuba's path tracer (which measures that way: a point light
//! under a half-opaque plane casts a black shadow in Mitsuba 3.9.1).

use super::{Bsdf, BsdfSample};
use crate::materials::PreparedMaterial;
use glam::{Vec2, Vec3};
use lucent_scene::Texture;

/// A mask at one surface point.
#[derive(Clone, Copy, Debug)]
pub struct Mask<'a> {
    /// The opacity α, in [0, 1].
    pub opacity: f32,
    /// The surface's BSDF, prepared.
    pub inner: &'a PreparedMaterial,
    /// The scene's textures and the point's texture coordinates, to resolve it.
    pub textures: &'a [Texture],
    /// Texture coordinates of the point.
    pub uv: Vec2,
}

impl<'a> Mask<'a> {
    fn inner(&self) -> Bsdf<'a> {
        self.inner.bsdf_at(self.textures, self.uv)
    }

    /// α·f(wo, wi)·|cos θi| (the null lobe is a delta: nothing here).
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if self.opacity > 0.0 {
            self.inner().eval(wo, wi) * self.opacity
        } else {
            Vec3::ZERO
        }
    }

    /// α times the inner density.
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.opacity > 0.0 {
            self.inner().pdf(wo, wi) * self.opacity
        } else {
            0.0
        }
    }

    /// Straight through with probability 1 − α, else the inner BSDF's sample (its weight
    /// unchanged: α cancels).
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        let a = self.opacity;
        if u >= a {
            return Some(BsdfSample { wi: -wo, weight: Vec3::ONE, pdf: 1.0 - a, delta: true, eta: 1.0 });
        }
        let s = self.inner().sample(wo, (u / a).clamp(0.0, 1.0 - f32::EPSILON), u2)?;
        Some(BsdfSample { pdf: s.pdf * a, ..s })
    }

    /// Whether the inner BSDF is delta only (then so is the whole).
    #[must_use]
    pub fn is_delta(&self) -> bool {
        self.opacity <= 0.0 || self.inner().is_delta()
    }
}
