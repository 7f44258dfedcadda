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
//! [`metallic_roughness`] BRDF, MTL's [`diffuse_glossy`], the mix of two, [`blend`], and
//! a surface with holes, [`mask`].
//! Users add their own through
//! [`BsdfModel`].
//!
//! Adding a built-in BSDF: a file here with its struct, `eval`, `pdf`, `sample` and its
//! closed-form tests; a variant of [`Bsdf`] and one arm in each of its matches; the
//! material's description in `lucent_scene::bsdf` and its preparation in
//! `crate::materials`.

pub mod blend;
pub mod conductor;
pub mod dielectric;
pub mod diffuse;
pub mod diffuse_glossy;
pub mod mask;
pub mod metallic_roughness;
pub mod microfacet;
pub mod plastic;
pub mod rough_plastic;
mod sample;
pub mod thin_dielectric;

pub use blend::Blend;
pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use diffuse_glossy::DiffuseGlossy;
pub use mask::Mask;
pub use metallic_roughness::MetallicRoughness;
pub use microfacet::{fresnel_conductor, fresnel_dielectric, Microfacet};
pub use plastic::{plastic_spec_weight, Plastic};
pub use rough_plastic::{RoughPlastic, RoughPlasticTables};
pub use sample::BsdfSample;
pub use thin_dielectric::ThinDielectric;

/// Cosine-weighted hemisphere sampling (see [`crate::sampling::cosine_hemisphere`]), for
/// the user's BSDFs.
pub use crate::sampling::cosine_hemisphere;

use glam::{Vec2, Vec3};

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
            Self::DiffuseGlossy(b) => b.eval(wo, wi),
            Self::Blend(b) => b.eval(wo, wi),
            Self::Mask(b) => b.eval(wo, wi),
            Self::Custom(m, uv) => m.eval(wo, wi, *uv),
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
            Self::DiffuseGlossy(b) => b.sample(wo, u, u2),
            Self::Blend(b) => b.sample(wo, u, u2),
            Self::Mask(b) => b.sample(wo, u, u2),
            Self::Custom(m, uv) => m.sample(wo, *uv, u, u2),
        }
    }
}
