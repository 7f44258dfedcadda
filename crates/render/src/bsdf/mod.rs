//! BSDFs: how a surface scatters light, each with `eval`, `sample` and `pdf`.
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
//! that images agree: Lambertian `diffuse`; `conductor` (complex Fresnel) smooth or rough;
//! `dielectric` smooth or rough (Walter et al. 2007); `thindielectric`; `plastic` and
//! `roughplastic` (Weidlich and Wilkie 2007's layering: the base's light enters and leaves
//! through the coating's Fresnel transmittance, internal reflection summed); and the glTF
//! 2.0 metallic-roughness BRDF (Appendix B, with thin-walled `KHR_materials_transmission`).
//! Users add their own through [`BsdfModel`].

pub mod microfacet;
mod plastic;

use glam::{Vec2, Vec3};
pub use microfacet::{fresnel_conductor, fresnel_dielectric, Microfacet};
use microfacet::{reflect, refract, schlick};
pub use plastic::RoughPlasticTables;
use std::f32::consts::FRAC_1_PI;

/// A sampled direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Direction toward the light (local frame).
    pub wi: Vec3,
    /// f·|cos θi| / pdf (for a delta lobe: its value over the probability of choosing it).
    pub weight: Vec3,
    /// Density per solid angle (for a delta lobe: the probability of choosing it).
    pub pdf: f32,
    /// A delta lobe (mirror, smooth refraction): no other strategy can sample it.
    pub delta: bool,
    /// The relative index of refraction crossed (ηt/ηi; 1 for reflection), for roulette.
    pub eta: f32,
}

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
    Diffuse {
        /// Albedo.
        r: Vec3,
    },
    /// Smooth (`mf` = None) or rough conductor.
    Conductor {
        /// Real part of the index.
        eta: Vec3,
        /// Imaginary part.
        k: Vec3,
        /// Factor.
        spec: Vec3,
        /// Roughness.
        mf: Option<Microfacet>,
    },
    /// Smooth or rough dielectric interface.
    Dielectric {
        /// Inside over outside.
        eta: f32,
        /// Factor on reflection.
        refl: Vec3,
        /// Factor on transmission.
        trans: Vec3,
        /// Roughness.
        mf: Option<Microfacet>,
    },
    /// Thin dielectric sheet.
    Thin {
        /// Index of the sheet.
        eta: f32,
        /// Factor on reflection.
        refl: Vec3,
        /// Factor on transmission.
        trans: Vec3,
    },
    /// Smooth plastic.
    Plastic {
        /// Base albedo.
        diffuse: Vec3,
        /// Factor on the coating's reflection.
        spec: Vec3,
        /// Coating index.
        eta: f32,
        /// Mitsuba's `nonlinear`.
        nonlinear: bool,
        /// Probability weight of the specular lobe (Mitsuba's `specular_sampling_weight`).
        spec_weight: f32,
        /// The coating's diffuse Fresnel reflectance from inside.
        fdr_int: f32,
    },
    /// Rough plastic.
    RoughPlastic {
        /// Base albedo.
        diffuse: Vec3,
        /// Factor on the coating's reflection.
        spec: Vec3,
        /// Mitsuba's `nonlinear`.
        nonlinear: bool,
        /// Probability weight of the specular lobe.
        spec_weight: f32,
        /// Coating roughness.
        mf: Microfacet,
        /// The coating's transmittance and internal reflectance.
        tables: &'a RoughPlasticTables,
    },
    /// glTF metallic-roughness.
    MetallicRoughness {
        /// Base colour.
        base: Vec3,
        /// Metallic.
        metallic: f32,
        /// α = roughness².
        mf: Microfacet,
        /// Transmission (of the dielectric part).
        transmission: f32,
        /// Dielectric reflectance at normal incidence, ((η − 1)/(η + 1))².
        f0: f32,
    },
    /// MTL's Kd + Ks/Ns.
    DiffuseGlossy {
        /// Lambertian albedo.
        kd: Vec3,
        /// Glossy reflectance.
        ks: Vec3,
        /// Beckmann lobe.
        mf: Microfacet,
    },
    /// The user's own.
    Custom(&'a dyn BsdfModel, Vec2),
}

/// Cosine-weighted hemisphere sampling (Malley's method over Shirley and Chiu's concentric
/// disk), local frame.
#[inline]
#[must_use]
pub fn cosine_hemisphere(u: (f32, f32)) -> Vec3 {
    let (a, b) = (2.0 * u.0 - 1.0, 2.0 * u.1 - 1.0);
    let (r, phi) = if a == 0.0 && b == 0.0 {
        (0.0, 0.0)
    } else if a.abs() > b.abs() {
        (a, std::f32::consts::FRAC_PI_4 * (b / a))
    } else {
        (b, std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a / b))
    };
    let (x, y) = (r * phi.cos(), r * phi.sin());
    Vec3::new(x, y, (1.0 - x * x - y * y).max(0.0).sqrt())
}

#[inline]
fn same_side(wo: Vec3, wi: Vec3) -> bool {
    wo.z * wi.z > 0.0
}

/// Mitsuba's mean of a colour, for lobe-sampling weights.
#[inline]
fn mean(c: Vec3) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

#[inline]
fn lum(c: Vec3) -> f32 {
    crate::world::luminance(c).max(0.0)
}

impl Bsdf<'_> {
    /// Whether every lobe is a delta: next-event estimation cannot help.
    #[must_use]
    pub fn is_delta(&self) -> bool {
        match self {
            Self::Conductor { mf, .. } | Self::Dielectric { mf, .. } => mf.is_none(),
            Self::Thin { .. } => true,
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
        matches!(self, Self::Thin { .. } | Self::MetallicRoughness { .. })
    }

    /// Whether the BSDF transmits (a shading point of it may send light through).
    #[must_use]
    pub fn transmits(&self) -> bool {
        match self {
            Self::Dielectric { .. } | Self::Thin { .. } | Self::Custom(..) => true,
            Self::MetallicRoughness { transmission, metallic, .. } => *transmission > 0.0 && *metallic < 1.0,
            _ => false,
        }
    }

    /// f(wo, wi)·|cos θi|.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match *self {
            Self::Diffuse { r } => {
                if wo.z > 0.0 && wi.z > 0.0 {
                    r * (FRAC_1_PI * wi.z)
                } else {
                    Vec3::ZERO
                }
            }
            Self::Conductor { eta, k, spec, mf } => {
                let Some(mf) = mf else { return Vec3::ZERO };
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return Vec3::ZERO;
                }
                let h = (wo + wi).normalize();
                let d = mf.d(h);
                if d == 0.0 {
                    return Vec3::ZERO;
                }
                fresnel_conductor(wo.dot(h), eta, k) * spec * (d * mf.g(wo, wi, h) / (4.0 * wo.z))
            }
            Self::Dielectric { eta, refl, trans, mf } => {
                let Some(mf) = mf else { return Vec3::ZERO };
                if wo.z == 0.0 || wi.z == 0.0 {
                    return Vec3::ZERO;
                }
                let reflect = same_side(wo, wi);
                // η on the far side over η on the viewer's side.
                let eta_o = if wo.z > 0.0 { eta } else { 1.0 / eta };
                let h = if reflect { wo + wi } else { wo + wi * eta_o };
                let h = h.normalize_or_zero();
                let h = if h.z < 0.0 { -h } else { h };
                if h == Vec3::ZERO {
                    return Vec3::ZERO;
                }
                let d = mf.d(h);
                let (f, _) = fresnel_dielectric(wo.dot(h), eta);
                let g = mf.g(wo, wi, h);
                if reflect {
                    refl * (f * d * g / (4.0 * wo.z.abs()))
                } else {
                    let (oh, ih) = (wo.dot(h), wi.dot(h));
                    let denom = oh + eta_o * ih;
                    // (Light from the other side of the facet than the viewer only.)
                    if oh * ih >= 0.0 {
                        return Vec3::ZERO;
                    }
                    trans * ((1.0 - f) * d * g * (oh * ih).abs() / (wo.z.abs() * denom * denom)).abs()
                }
            }
            Self::Thin { .. } => Vec3::ZERO,
            Self::Plastic { diffuse, eta, nonlinear, fdr_int, .. } => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return Vec3::ZERO;
                }
                let (fo, _) = fresnel_dielectric(wo.z, eta);
                let (fi, _) = fresnel_dielectric(wi.z, eta);
                let base = if nonlinear { diffuse / (Vec3::ONE - diffuse * fdr_int) } else { diffuse / (1.0 - fdr_int) };
                base * (FRAC_1_PI * wi.z / (eta * eta) * (1.0 - fo) * (1.0 - fi))
            }
            Self::RoughPlastic { diffuse, spec, nonlinear, mf, tables, .. } => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return Vec3::ZERO;
                }
                let h = (wo + wi).normalize();
                let (f, _) = fresnel_dielectric(wo.dot(h), tables.eta);
                let specular = spec * (f * mf.d(h) * mf.g(wo, wi, h) / (4.0 * wo.z));
                let (to, ti) = (tables.external(wo.z), tables.external(wi.z));
                let ri = tables.internal;
                let base = if nonlinear { diffuse / (Vec3::ONE - diffuse * ri) } else { diffuse / (1.0 - ri) };
                specular + base * (FRAC_1_PI / (tables.eta * tables.eta) * wi.z * to * ti)
            }
            Self::MetallicRoughness { .. } => self.mr_eval(wo, wi),
            Self::DiffuseGlossy { kd, ks, mf } => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return Vec3::ZERO;
                }
                let h = (wo + wi).normalize();
                kd * (FRAC_1_PI * wi.z) + ks * (mf.d(h) * mf.g(wo, wi, h) / (4.0 * wo.z))
            }
            Self::Custom(m, uv) => m.eval(wo, wi, uv),
        }
    }

    /// The density with which [`Bsdf::sample`] returns `wi` (its non-delta lobes).
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match *self {
            Self::Diffuse { .. } => {
                if wo.z > 0.0 && wi.z > 0.0 {
                    wi.z * FRAC_1_PI
                } else {
                    0.0
                }
            }
            Self::Conductor { mf, .. } => {
                let Some(mf) = mf else { return 0.0 };
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return 0.0;
                }
                let h = (wo + wi).normalize();
                mf.pdf(wo, h) / (4.0 * wo.dot(h))
            }
            Self::Dielectric { eta, mf, .. } => {
                let Some(mf) = mf else { return 0.0 };
                if wo.z == 0.0 || wi.z == 0.0 {
                    return 0.0;
                }
                let reflect = same_side(wo, wi);
                let eta_o = if wo.z > 0.0 { eta } else { 1.0 / eta };
                let h = if reflect { wo + wi } else { wo + wi * eta_o };
                let h = h.normalize_or_zero();
                let h = if h.z < 0.0 { -h } else { h };
                if h == Vec3::ZERO {
                    return 0.0;
                }
                // The facet was sampled for wo turned to the upper hemisphere (the visible
                // facets seen from below are those seen from the mirrored direction).
                let pm = mf.pdf(if wo.z < 0.0 { -wo } else { wo }, h);
                let (f, _) = fresnel_dielectric(wo.dot(h), eta);
                let (oh, ih) = (wo.dot(h), wi.dot(h));
                if reflect {
                    f * pm / (4.0 * oh.abs())
                } else {
                    if oh * ih >= 0.0 {
                        return 0.0;
                    }
                    let denom = oh + eta_o * ih;
                    (1.0 - f) * pm * eta_o * eta_o * ih.abs() / (denom * denom)
                }
            }
            Self::Thin { .. } => 0.0,
            Self::Plastic { eta, spec_weight, .. } => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return 0.0;
                }
                let (fo, _) = fresnel_dielectric(wo.z, eta);
                let ps = fo * spec_weight;
                let pd = (1.0 - fo) * (1.0 - spec_weight);
                pd / (ps + pd) * wi.z * FRAC_1_PI
            }
            Self::RoughPlastic { spec_weight, mf, tables, .. } => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return 0.0;
                }
                let (ps, pd) = rough_plastic_probs(tables.external(wo.z), spec_weight);
                let h = (wo + wi).normalize();
                ps * mf.pdf(wo, h) / (4.0 * wo.dot(h)) + pd * wi.z * FRAC_1_PI
            }
            Self::MetallicRoughness { .. } => self.mr_pdf(wo, wi),
            Self::DiffuseGlossy { kd, ks, mf } => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return 0.0;
                }
                let pg = glossy_prob(kd, ks);
                let h = (wo + wi).normalize();
                pg * mf.pdf(wo, h) / (4.0 * wo.dot(h)) + (1.0 - pg) * wi.z * FRAC_1_PI
            }
            Self::Custom(m, uv) => m.pdf(wo, wi, uv),
        }
    }

    /// A direction for `wo`: `u` chooses among lobes, `u2` places the direction.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        let from_eval = |wi: Vec3| -> Option<BsdfSample> {
            let pdf = self.pdf(wo, wi);
            if !(pdf > 0.0 && pdf.is_finite()) {
                return None;
            }
            let weight = self.eval(wo, wi) / pdf;
            let eta = if same_side(wo, wi) { 1.0 } else { self.eta_across(wo) };
            Some(BsdfSample { wi, weight, pdf, delta: false, eta })
        };
        match *self {
            Self::Diffuse { r } => {
                if wo.z <= 0.0 {
                    return None;
                }
                let wi = cosine_hemisphere(u2);
                if wi.z <= 0.0 {
                    return None;
                }
                Some(BsdfSample { wi, weight: r, pdf: wi.z * FRAC_1_PI, delta: false, eta: 1.0 })
            }
            Self::Conductor { eta, k, spec, mf } => {
                if wo.z <= 0.0 {
                    return None;
                }
                match mf {
                    None => {
                        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                        Some(BsdfSample { wi, weight: spec * fresnel_conductor(wo.z, eta, k), pdf: 1.0, delta: true, eta: 1.0 })
                    }
                    Some(mf) => {
                        let m = mf.sample(wo, u2);
                        let wi = reflect(wo, m);
                        if wi.z <= 0.0 {
                            return None;
                        }
                        from_eval(wi)
                    }
                }
            }
            Self::Dielectric { eta, refl, trans, mf } => {
                if wo.z == 0.0 {
                    return None;
                }
                match mf {
                    None => {
                        let (f, cos_t) = fresnel_dielectric(wo.z, eta);
                        if u < f {
                            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                            Some(BsdfSample { wi, weight: refl, pdf: f, delta: true, eta: 1.0 })
                        } else {
                            let wi = refract(wo, Vec3::Z, cos_t, eta);
                            // η on the viewer's side over the far side, squared: radiance
                            // crossing into a denser medium is compressed.
                            let eta_t = if wo.z > 0.0 { eta } else { 1.0 / eta };
                            Some(BsdfSample { wi, weight: trans / (eta_t * eta_t), pdf: 1.0 - f, delta: true, eta: eta_t })
                        }
                    }
                    Some(mf) => {
                        // A facet (facing up) visible from wo: those seen from below are
                        // the ones seen from the mirrored direction.
                        let m = mf.sample(if wo.z < 0.0 { -wo } else { wo }, u2);
                        let (f, cos_t) = fresnel_dielectric(wo.dot(m), eta);
                        let (wi, reflected) = if u < f { (reflect(wo, m), true) } else { (refract(wo, m, cos_t, eta), false) };
                        // (A facet can turn a direction to the wrong side: no sample.)
                        if same_side(wo, wi) != reflected {
                            return None;
                        }
                        from_eval(wi)
                    }
                }
            }
            Self::Thin { eta, refl, trans } => {
                let (mut r, _) = fresnel_dielectric(wo.z.abs(), eta);
                // Light bouncing inside the sheet: R + T² R / (1 − R²).
                if r < 1.0 {
                    let t = 1.0 - r;
                    r += t * t * r / (1.0 - r * r);
                }
                if u < r {
                    Some(BsdfSample { wi: Vec3::new(-wo.x, -wo.y, wo.z), weight: refl, pdf: r, delta: true, eta: 1.0 })
                } else {
                    Some(BsdfSample { wi: -wo, weight: trans, pdf: 1.0 - r, delta: true, eta: 1.0 })
                }
            }
            Self::Plastic { spec, eta, spec_weight, .. } => {
                if wo.z <= 0.0 {
                    return None;
                }
                let (fo, _) = fresnel_dielectric(wo.z, eta);
                let ps = fo * spec_weight;
                let pd = (1.0 - fo) * (1.0 - spec_weight);
                let ps = ps / (ps + pd);
                if u < ps {
                    let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                    Some(BsdfSample { wi, weight: spec * (fo / ps), pdf: ps, delta: true, eta: 1.0 })
                } else {
                    let wi = cosine_hemisphere(u2);
                    from_eval(wi)
                }
            }
            Self::RoughPlastic { spec_weight, mf, tables, .. } => {
                if wo.z <= 0.0 {
                    return None;
                }
                let (ps, _) = rough_plastic_probs(tables.external(wo.z), spec_weight);
                let wi = if u < ps { reflect(wo, mf.sample(wo, u2)) } else { cosine_hemisphere(u2) };
                if wi.z <= 0.0 {
                    return None;
                }
                from_eval(wi)
            }
            Self::MetallicRoughness { .. } => {
                let wi = self.mr_sample(wo, u, u2)?;
                from_eval(wi)
            }
            Self::DiffuseGlossy { kd, ks, mf } => {
                if wo.z <= 0.0 {
                    return None;
                }
                let pg = glossy_prob(kd, ks);
                let wi = if u < pg { reflect(wo, mf.sample(wo, u2)) } else { cosine_hemisphere(u2) };
                if wi.z <= 0.0 {
                    return None;
                }
                from_eval(wi)
            }
            Self::Custom(m, uv) => m.sample(wo, uv, u, u2),
        }
    }

    /// The relative index a transmitted direction crosses from `wo`'s side.
    fn eta_across(&self, wo: Vec3) -> f32 {
        match *self {
            Self::Dielectric { eta, .. } => {
                if wo.z > 0.0 {
                    eta
                } else {
                    1.0 / eta
                }
            }
            _ => 1.0,
        }
    }

    // glTF metallic-roughness (Appendix B): material = mix(dielectric, metal, metallic),
    // dielectric = fresnel_mix(f0, mix(diffuse(base), btdf·base, transmission), brdf),
    // metal = brdf · schlick(base); the microfacet terms are GGX with the height-correlated
    // Smith visibility; the BTDF, thin-walled, is the BRDF of `wi` mirrored through the
    // surface.

    fn mr_parts(&self) -> (Vec3, f32, Microfacet, f32, f32) {
        match *self {
            Self::MetallicRoughness { base, metallic, mf, transmission, f0 } => (base, metallic, mf, transmission, f0),
            _ => (Vec3::ZERO, 0.0, Microfacet::new(lucent_scene::Distribution::Ggx, 1.0), 0.0, 0.04),
        }
    }

    /// GGX D times the height-correlated visibility G2 / (4 |cos o| |cos i|), for a
    /// reflection pair with half vector `h`.
    fn mr_specular(mf: &Microfacet, wo: Vec3, wi: Vec3, h: Vec3) -> f32 {
        let a2 = mf.alpha * mf.alpha;
        let (no, ni) = (wo.z.abs(), wi.z.abs());
        let lo = ni * (no * no * (1.0 - a2) + a2).sqrt();
        let li = no * (ni * ni * (1.0 - a2) + a2).sqrt();
        let v = if lo + li > 0.0 { 0.5 / (lo + li) } else { 0.0 };
        mf.d(h) * v
    }

    fn mr_eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let (base, metallic, mf, transmission, f0) = self.mr_parts();
        if wo.z <= 0.0 || wi.z == 0.0 {
            return Vec3::ZERO;
        }
        let reflect = wi.z > 0.0;
        // Thin-walled transmission: the mirrored direction's reflection terms.
        let wl = if reflect { wi } else { Vec3::new(wi.x, wi.y, -wi.z) };
        let h = (wo + wl).normalize();
        let voh = wo.dot(h);
        let spec = Self::mr_specular(&mf, wo, wl, h);
        let fd = schlick(Vec3::splat(f0), voh).x;
        let cos = wl.z;
        if reflect {
            let diffuse = base * FRAC_1_PI;
            let dielectric = diffuse * ((1.0 - fd) * (1.0 - transmission)) + Vec3::splat(fd * spec);
            let metal = schlick(base, voh) * spec;
            (dielectric * (1.0 - metallic) + metal * metallic) * cos
        } else {
            base * ((1.0 - metallic) * transmission * (1.0 - fd) * spec * cos)
        }
    }

    /// Lobe probabilities of glTF's BRDF for `wo`: specular reflection, diffuse,
    /// transmission.
    fn mr_probs(&self, wo: Vec3) -> [f32; 3] {
        let (base, metallic, _, transmission, f0) = self.mr_parts();
        let fd = schlick(Vec3::splat(f0), wo.z).x;
        let spec = (1.0 - metallic) * fd + metallic * lum(schlick(base, wo.z)).max(0.05);
        let rest = (1.0 - metallic) * (1.0 - fd) * lum(base).max(0.05);
        let p = [spec.max(0.02), rest * (1.0 - transmission), rest * transmission];
        let s: f32 = p.iter().sum();
        p.map(|x| x / s)
    }

    fn mr_pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (_, _, mf, _, _) = self.mr_parts();
        if wo.z <= 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        let [ps, pd, pt] = self.mr_probs(wo);
        let wl = if wi.z > 0.0 { wi } else { Vec3::new(wi.x, wi.y, -wi.z) };
        let h = (wo + wl).normalize();
        let spec = mf.pdf(wo, h) / (4.0 * wo.dot(h).abs().max(1e-12));
        if wi.z > 0.0 {
            ps * spec + pd * wi.z * FRAC_1_PI
        } else {
            pt * spec
        }
    }

    fn mr_sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<Vec3> {
        let (_, _, mf, _, _) = self.mr_parts();
        if wo.z <= 0.0 {
            return None;
        }
        let [ps, pd, _] = self.mr_probs(wo);
        if u < ps || u >= ps + pd {
            let wi = reflect(wo, mf.sample(wo, u2));
            if wi.z <= 0.0 {
                return None;
            }
            Some(if u < ps { wi } else { Vec3::new(wi.x, wi.y, -wi.z) })
        } else {
            Some(cosine_hemisphere(u2))
        }
    }
}

/// Mitsuba's lobe probabilities for rough plastic: (specular, diffuse) from the coating's
/// transmittance toward the viewer.
#[inline]
fn rough_plastic_probs(t_o: f32, spec_weight: f32) -> (f32, f32) {
    let ps = (1.0 - t_o) * spec_weight;
    let pd = t_o * (1.0 - spec_weight);
    let s = ps + pd;
    if s > 0.0 {
        (ps / s, pd / s)
    } else {
        (0.0, 1.0)
    }
}

/// The probability of sampling MTL's glossy lobe: its share of the reflectance.
#[inline]
fn glossy_prob(kd: Vec3, ks: Vec3) -> f32 {
    let (d, s) = (lum(kd), lum(ks));
    if d + s > 0.0 {
        s / (d + s)
    } else {
        0.5
    }
}

/// Mitsuba's specular sampling weight for plastics: the specular factor's mean over the
/// diffuse one's plus it.
#[must_use]
pub fn plastic_spec_weight(diffuse_mean: Vec3, spec_mean: Vec3) -> f32 {
    let (d, s) = (mean(diffuse_mean), mean(spec_mean));
    if d + s > 0.0 {
        s / (d + s)
    } else {
        0.5
    }
}
