//! BSDFs: how a surface scatters light, each with `eval`, `sample` and `pdf`, one file per
//! model as Mitsuba's `bsdfs/`.
//!
//! Conventions (those of pbrt-v4 for the names, Mitsuba 3 for the values): directions are
//! unit vectors in the local shading frame (z along the shading normal), both pointing
//! away from the surface; `wo` goes toward the viewer (the way the path came), `wi` toward
//! the light (the way it goes on). [`Bsdf::eval`] returns f(wo, wi)·|cos θi| (the BSDF
//! with the cosine of the light's direction, as Mitsuba's `eval` does), for radiance
//! (transmission carries the (ηo/ηi)² factor of radiance crossing an interface, Veach's
//! thesis §5.2). [`Bsdf::sample`] returns a direction, eval/pdf as its weight (for a delta
//! lobe, the lobe's value over its discrete probability), and the pdf per solid angle.
//!
//! The models (see `lucent_scene::bsdf` for their parameters and where each importer's
//! materials land) follow Mitsuba 3's plugins of the same names, formula for formula, so
//! that images agree: [`diffuse`], [`conductor`] (complex Fresnel) smooth or rough,
//! [`dielectric`] smooth or rough (Walter et al. 2007), [`thin_dielectric`], [`plastic`]
//! and [`rough_plastic`] (Weidlich and Wilkie 2007's layering), the glTF 2.0
//! [`metallic_roughness`] BRDF, MTL's [`diffuse_glossy`], and, here beside [`Bsdf`] since
//! they hold BSDFs themselves, the mix of two ([`Blend`]) and a surface with holes
//! ([`Mask`]).
//! Users add their own through
//! [`BsdfModel`].
//!
//! Adding a built-in BSDF: a file here with its struct, `eval`, `pdf`, `sample` and its
//! closed-form tests; a variant of [`Bsdf`] and one arm in each of its matches; the
//! material's description in `lucent_scene::bsdf` and its preparation in
//! `crate::materials`.

pub mod conductor;
pub mod dielectric;
pub mod diffuse;
pub mod diffuse_glossy;
pub mod metallic_roughness;
pub mod microfacet;
pub mod plastic;
pub mod principled;
pub mod rough_plastic;
pub(crate) mod sample;
pub mod thin_dielectric;

pub use conductor::{Conductor, RoughConductor};
pub use dielectric::{Dielectric, RoughDielectric};
pub use diffuse::Diffuse;
pub use diffuse_glossy::DiffuseGlossy;
pub use metallic_roughness::MetallicRoughness;
pub use microfacet::{fresnel_conductor, fresnel_dielectric, Microfacet};
pub use plastic::{plastic_spec_weight, Plastic};
pub use principled::Principled;
pub use rough_plastic::{RoughPlastic, RoughPlasticLane, RoughPlasticTables};
pub use sample::BsdfSample;
pub use thin_dielectric::ThinDielectric;

/// Cosine-weighted hemisphere sampling (see [`crate::sampling::cosine_hemisphere`]), for
/// the user's BSDFs.
pub use crate::sampling::cosine_hemisphere;

use glam::{Vec2, Vec3};
use lucent_scene::Texture;

/// A BSDF of the library user's own, at the coarse seam the path tracer offers: it sees
/// local directions and the hit's texture coordinates and answers as the built-in ones
/// do (see the module's conventions). Give it to [`crate::World::set_bsdf`]; an example is
/// `examples/custom_bsdf.rs`.
pub trait BsdfModel: Send + Sync + std::fmt::Debug {
    /// f(wo, wi)·|cos θi| (zero for delta lobes).
    fn eval(&self, wo: Vec3, wi: Vec3, uv: Vec2) -> Vec3;
    /// The density with which [`BsdfModel::sample`] returns `wi` (zero for delta lobes).
    fn pdf(&self, wo: Vec3, wi: Vec3, uv: Vec2) -> f32;
    /// A direction for `u` (one number for a discrete choice, two for the direction).
    fn sample(&self, wo: Vec3, uv: Vec2, u: f32, u2: (f32, f32)) -> Option<BsdfSample>;
    /// Whether every lobe is a delta (next-event estimation is then skipped).
    fn is_delta(&self) -> bool {
        false
    }
}

/// A BSDF at one surface point: a material's model with its textures looked up.
#[derive(Clone, Copy, Debug)]
pub enum Bsdf<'a> {
    /// Lambertian.
    Diffuse(Diffuse),
    /// Smooth or rough conductor.
    Conductor(Conductor),
    /// Smooth or rough dielectric interface.
    Dielectric(Dielectric),
    /// Thin dielectric sheet.
    Thin(ThinDielectric),
    /// Smooth plastic.
    Plastic(Plastic),
    /// Rough plastic.
    RoughPlastic(RoughPlastic<'a>),
    /// glTF metallic-roughness.
    MetallicRoughness(MetallicRoughness),
    /// MTL's Kd + Ks/Ns.
    DiffuseGlossy(DiffuseGlossy),
    /// Mitsuba's principled BSDF.
    Principled(Principled),
    /// A mix of two (Mitsuba's `blendbsdf`).
    Blend(Blend<'a>),
    /// A surface with holes (Mitsuba's `mask`).
    Mask(Mask<'a>),
    /// The user's own.
    Custom(&'a dyn BsdfModel, Vec2),
}

impl Bsdf<'_> {
    /// Whether every lobe is a delta: next-event estimation cannot help.
    #[must_use]
    pub fn is_delta(&self) -> bool {
        match self {
            Self::Conductor(b) => b.mf.is_none(),
            Self::Dielectric(b) => b.mf.is_none(),
            Self::Thin(_) => true,
            Self::Blend(b) => b.is_delta(),
            Self::Mask(b) => b.is_delta(),
            Self::Custom(m, _) => m.is_delta(),
            _ => false,
        }
    }

    /// Whether the BSDF scatters the same from either side (it is evaluated with `wo`
    /// turned to the upper hemisphere): the thin sheet and glTF's BRDF (thin-walled).
    /// Dielectrics tell the sides apart by the index, the others by Mitsuba's one-sided
    /// convention (see `lucent_scene::Sides`).
    #[must_use]
    pub fn symmetric(&self) -> bool {
        matches!(self, Self::Thin(_) | Self::MetallicRoughness(_))
    }

    /// Whether the BSDF transmits (a shading point of it may send light through).
    #[must_use]
    pub fn transmits(&self) -> bool {
        match self {
            Self::Dielectric(_) | Self::Thin(_) | Self::Mask(_) | Self::Custom(..) => true,
            Self::Blend(b) => b.transmits(),
            Self::MetallicRoughness(b) => b.transmission > 0.0 && b.metallic < 1.0,
            Self::Principled(b) => b.transmits(),
            _ => false,
        }
    }

    /// f(wo, wi)·|cos θi|.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self {
            Self::Diffuse(b) => b.eval(wo, wi),
            Self::Conductor(b) => b.eval(wo, wi),
            Self::Dielectric(b) => b.eval(wo, wi),
            Self::Thin(_) => Vec3::ZERO,
            Self::Plastic(b) => b.eval(wo, wi),
            Self::RoughPlastic(b) => b.eval(wo, wi),
            Self::MetallicRoughness(b) => b.eval(wo, wi),
            Self::Principled(b) => b.eval(wo, wi),
            Self::DiffuseGlossy(b) => b.eval(wo, wi),
            Self::Blend(b) => b.eval(wo, wi),
            Self::Mask(b) => b.eval(wo, wi),
            Self::Custom(m, uv) => m.eval(wo, wi, *uv),
        }
    }

    /// [`Bsdf::eval`] and [`Bsdf::pdf`] at once: what next-event estimation asks for,
    /// computed together where they share work (the microfacet models' half vector and
    /// D), the same bits as apart.
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        match self {
            Self::Conductor(b) => b.eval_pdf(wo, wi),
            Self::Dielectric(b) => b.eval_pdf(wo, wi),
            Self::RoughPlastic(b) => b.eval_pdf(wo, wi),
            Self::Plastic(b) => b.eval_pdf(wo, wi),
            Self::DiffuseGlossy(b) => b.eval_pdf(wo, wi),
            Self::Blend(b) => b.eval_pdf(wo, wi),
            Self::Mask(b) => b.eval_pdf(wo, wi),
            Self::Principled(b) => b.eval_pdf(wo, wi),
            _ => (self.eval(wo, wi), self.pdf(wo, wi)),
        }
    }

    /// The density with which [`Bsdf::sample`] returns `wi` (its non-delta lobes).
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Self::Diffuse(b) => b.pdf(wo, wi),
            Self::Conductor(b) => b.pdf(wo, wi),
            Self::Dielectric(b) => b.pdf(wo, wi),
            Self::Thin(_) => 0.0,
            Self::Plastic(b) => b.pdf(wo, wi),
            Self::RoughPlastic(b) => b.pdf(wo, wi),
            Self::MetallicRoughness(b) => b.pdf(wo, wi),
            Self::Principled(b) => b.pdf(wo, wi),
            Self::DiffuseGlossy(b) => b.pdf(wo, wi),
            Self::Blend(b) => b.pdf(wo, wi),
            Self::Mask(b) => b.pdf(wo, wi),
            Self::Custom(m, uv) => m.pdf(wo, wi, *uv),
        }
    }

    /// A direction for `wo`: `u` chooses among lobes, `u2` places the direction.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        match self {
            Self::Diffuse(b) => b.sample(wo, u2),
            Self::Conductor(b) => b.sample(wo, u2),
            Self::Dielectric(b) => b.sample(wo, u, u2),
            Self::Thin(b) => b.sample(wo, u),
            Self::Plastic(b) => b.sample(wo, u, u2),
            Self::RoughPlastic(b) => b.sample(wo, u, u2),
            Self::MetallicRoughness(b) => b.sample(wo, u, u2),
            Self::Principled(b) => b.sample(wo, u, u2),
            Self::DiffuseGlossy(b) => b.sample(wo, u, u2),
            Self::Blend(b) => b.sample(wo, u, u2),
            Self::Mask(b) => b.sample(wo, u, u2),
            Self::Custom(m, uv) => m.sample(wo, *uv, u, u2),
        }
    }
}

/// A BSDF that a composite one ([`Blend`], [`Mask`]) holds, resolved at a surface point
/// (the prepared materials are).
pub trait Nested: Send + Sync + std::fmt::Debug {
    /// The BSDF at texture coordinates `uv` (`textures`: the scene's).
    fn bsdf_at<'a>(&'a self, textures: &'a [Texture], uv: Vec2) -> Bsdf<'a>;
}

/// A mix of two BSDFs at one surface point, `(1 − w)·f₀ + w·f₁` (Mitsuba's `blendbsdf`): evaluated as the mix,
/// sampled by choosing the first with probability 1 − w, then weighed by the mixed
/// density of both (one-sample MIS with the balance heuristic over the two, as Mitsuba's
/// `sample` does), so that the estimate is the mix whichever BSDF drew the direction. A
/// delta direction is weighed the same way, its probability mixed with the other's
/// density, as Mitsuba's does (measured: keeping the delta sample's own weight instead
/// left a blend of rough plastic and glass 0.3% brighter than Mitsuba's at 4,096
/// samples).
///
/// The two BSDFs are the material's prepared ones, resolved at the surface point when
/// used (their textures looked up per call).
#[derive(Clone, Copy, Debug)]
pub struct Blend<'a> {
    /// The second BSDF's share, in [0, 1].
    pub weight: f32,
    /// The two BSDFs.
    pub parts: [&'a dyn Nested; 2],
    /// The scene's textures and the point's texture coordinates, to resolve them.
    pub textures: &'a [Texture],
    /// Texture coordinates of the point.
    pub uv: Vec2,
}

impl<'a> Blend<'a> {
    pub(crate) fn first(&self) -> Bsdf<'a> {
        self.parts[0].bsdf_at(self.textures, self.uv)
    }

    pub(crate) fn second(&self) -> Bsdf<'a> {
        self.parts[1].bsdf_at(self.textures, self.uv)
    }

    /// f(wo, wi)·|cos θi|.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let w = self.weight;
        let a = if w < 1.0 { self.first().eval(wo, wi) * (1.0 - w) } else { Vec3::ZERO };
        let b = if w > 0.0 { self.second().eval(wo, wi) * w } else { Vec3::ZERO };
        a + b
    }

    /// The mixed density of the two BSDFs' non-delta lobes.
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let w = self.weight;
        let a = if w < 1.0 { self.first().pdf(wo, wi) * (1.0 - w) } else { 0.0 };
        let b = if w > 0.0 { self.second().pdf(wo, wi) * w } else { 0.0 };
        a + b
    }

    /// [`Blend::eval`] and [`Blend::pdf`] at once (each BSDF resolved once; the same bits
    /// as apart).
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        Self::mix(self.weight, || self.first().eval_pdf(wo, wi), || self.second().eval_pdf(wo, wi))
    }

    /// `(1 − w)·first + w·second` of two parts' (value, density) pairs, each part's asked
    /// for only where its share is positive: [`Blend::eval_pdf`], and the lane
    /// integrator's blends (their parts' values from their packs).
    #[inline]
    pub(crate) fn mix(w: f32, first: impl FnOnce() -> (Vec3, f32), second: impl FnOnce() -> (Vec3, f32)) -> (Vec3, f32) {
        let (fa, pa) = if w < 1.0 {
            let (f, p) = first();
            (f * (1.0 - w), p * (1.0 - w))
        } else {
            (Vec3::ZERO, 0.0)
        };
        let (fb, pb) = if w > 0.0 {
            let (f, p) = second();
            (f * w, p * w)
        } else {
            (Vec3::ZERO, 0.0)
        };
        (fa + fb, pa + pb)
    }

    /// A direction: the second BSDF's with probability w (`u` reused, rescaled).
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        let (chosen, other, p, u) = self.choose(u);
        let s = chosen.sample(wo, u, u2)?;
        let (of, op) = other.eval_pdf(wo, s.wi);
        Self::mixed(s, p, of, op)
    }

    /// The part `u` chooses (the second with probability w), the other part, the chosen
    /// one's probability, and `u` rescaled within its share for the chosen one's sample.
    #[inline]
    pub(crate) fn choose(&self, u: f32) -> (Bsdf<'a>, Bsdf<'a>, f32, f32) {
        let w = self.weight;
        let (chosen, other, p, u) =
            if u < w { (self.second(), self.first(), w, u / w) } else { (self.first(), self.second(), 1.0 - w, (u - w) / (1.0 - w)) };
        (chosen, other, p, u.clamp(0.0, 1.0 - f32::EPSILON))
    }

    /// The sample `s` of the part chosen with probability `p`, weighed by the mixed
    /// density with the other part's value `of` and density `op` toward it; `None` where
    /// that density is not a positive number.
    #[inline]
    pub(crate) fn mixed(s: BsdfSample, p: f32, of: Vec3, op: f32) -> Option<BsdfSample> {
        // (The chosen one's value from its weight and density; the other's evaluated. A
        // delta sample's probability is mixed with the other's density as well, as
        // Mitsuba 3.9.1's blendbsdf does: not the mix's estimate where a delta and a
        // glossy lobe overlap, but Mitsuba's image.)
        let f = s.weight * s.pdf * p + of * (1.0 - p);
        let pdf = s.pdf * p + op * (1.0 - p);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(BsdfSample { weight: f / pdf, pdf, ..s })
    }

    /// Whether both BSDFs are delta only.
    #[must_use]
    pub fn is_delta(&self) -> bool {
        self.first().is_delta() && self.second().is_delta()
    }

    /// Whether either transmits.
    #[must_use]
    pub fn transmits(&self) -> bool {
        self.first().transmits() || self.second().transmits()
    }
}

/// A surface with holes at one surface point: there with probability α (Mitsuba's
/// `mask`), its BSDF times α, plus a null lobe that carries light straight through with
/// probability 1 − α (a delta transmission of weight one). Sampled paths pass the holes; next-event shadow rays stop
/// at the surface, as in Mitsuba's path tracer (which measures that way: a point light
/// under a half-opaque plane casts a black shadow in Mitsuba 3.9.1).
#[derive(Clone, Copy, Debug)]
pub struct Mask<'a> {
    /// The opacity α, in [0, 1].
    pub opacity: f32,
    /// The surface's BSDF.
    pub inner: &'a dyn Nested,
    /// The scene's textures and the point's texture coordinates, to resolve it.
    pub textures: &'a [Texture],
    /// Texture coordinates of the point.
    pub uv: Vec2,
}

impl<'a> Mask<'a> {
    pub(crate) fn inner(&self) -> Bsdf<'a> {
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

    /// [`Mask::eval`] and [`Mask::pdf`] at once (the inner BSDF resolved once).
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        Self::scaled(self.opacity, || self.inner().eval_pdf(wo, wi))
    }

    /// The inner BSDF's (value, density) times the opacity `a`, asked for only where `a`
    /// is positive: [`Mask::eval_pdf`], and the lane integrator's masks.
    #[inline]
    pub(crate) fn scaled(a: f32, inner: impl FnOnce() -> (Vec3, f32)) -> (Vec3, f32) {
        if a > 0.0 {
            let (f, p) = inner();
            (f * a, p * a)
        } else {
            (Vec3::ZERO, 0.0)
        }
    }

    /// Straight through with probability 1 − α, else the inner BSDF's sample (its weight
    /// unchanged: α cancels).
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        let a = self.opacity;
        match Self::choose(a, wo, u) {
            Err(null) => Some(null),
            Ok(u) => Some(Self::through(self.inner().sample(wo, u, u2)?, a)),
        }
    }

    /// What `u` chooses at opacity `a`: the null lobe's sample (straight through), or the
    /// inner BSDF, with `u` rescaled within its share for the inner one's sample.
    #[inline]
    pub(crate) fn choose(a: f32, wo: Vec3, u: f32) -> Result<f32, BsdfSample> {
        if u >= a {
            Err(Self::null(a, wo))
        } else {
            Ok((u / a).clamp(0.0, 1.0 - f32::EPSILON))
        }
    }

    /// The null lobe's sample at opacity `a`: straight through, with probability 1 − `a`.
    #[inline]
    pub(crate) fn null(a: f32, wo: Vec3) -> BsdfSample {
        BsdfSample { wi: -wo, weight: Vec3::ONE, pdf: 1.0 - a, delta: true, eta: 1.0 }
    }

    /// The inner BSDF's sample `s` as the mask's at opacity `a` (its density times `a`).
    #[inline]
    pub(crate) fn through(s: BsdfSample, a: f32) -> BsdfSample {
        BsdfSample { pdf: s.pdf * a, ..s }
    }

    /// Whether the inner BSDF is delta only (then so is the whole).
    #[must_use]
    pub fn is_delta(&self) -> bool {
        self.opacity <= 0.0 || self.inner().is_delta()
    }
}
