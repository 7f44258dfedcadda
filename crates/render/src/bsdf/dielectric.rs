//! Mitsuba's `dielectric` and `roughdielectric`: an interface between two dielectrics,
//! smooth (reflection and refraction chosen by the Fresnel term) or rough (Walter et al.
//! 2007, "Microfacet Models for Refraction through Rough Surfaces").

use super::microfacet::{fresnel_dielectric, reflect, refract, Microfacet};
use super::sample::{mirror, same_side, BsdfSample};
use glam::Vec3;
use lucent_scene::Distribution;

/// The relative index `eta` (inside over outside) as a direction leaving `wo`'s side
/// crosses it: η from outside, 1/η from inside.
#[inline(always)]
fn eta_across(eta: f32, wo: Vec3) -> f32 {
    if wo.z > 0.0 {
        eta
    } else {
        1.0 / eta
    }
}

/// A smooth or rough dielectric interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    /// Inside over outside.
    pub eta: f32,
    /// Factor on reflection.
    pub refl: Vec3,
    /// Factor on transmission.
    pub trans: Vec3,
    /// Roughness.
    pub mf: Option<Microfacet>,
}

impl Dielectric {
    /// The relative index a transmitted direction crosses from `wo`'s side.
    #[inline]
    #[must_use]
    pub fn eta_across(&self, wo: Vec3) -> f32 {
        eta_across(self.eta, wo)
    }

    /// f(wo, wi)·|cos θi| (zero for the smooth interface).
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// The density of [`Dielectric::sample`] (zero for the smooth interface).
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// [`Dielectric::eval`] and [`Dielectric::pdf`] at once (the half vector, D and the
    /// facet's Fresnel term once; the same bits as apart).
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        match self.mf {
            None => (Vec3::ZERO, 0.0),
            Some(mf) if mf.dist == Distribution::Beckmann => RoughDielectric::<true>::of(self, mf).eval_pdf(wo, wi),
            Some(mf) => RoughDielectric::<false>::of(self, mf).eval_pdf(wo, wi),
        }
    }

    /// Reflection or refraction, chosen by `u` against the Fresnel term (of a visible
    /// facet chosen by `u2`, when rough).
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        let (s, ok) = match self.mf {
            None => self.smooth_sample(wo, u),
            Some(mf) if mf.dist == Distribution::Beckmann => RoughDielectric::<true>::of(self, mf).sample(wo, u, u2),
            Some(mf) => RoughDielectric::<false>::of(self, mf).sample(wo, u, u2),
        };
        ok.then_some(s)
    }

    /// The smooth interface's sample (its roughness not looked at), branch-free (a loop
    /// over lanes that calls it vectorizes): the sample and whether there is one.
    #[inline(always)]
    #[must_use]
    pub fn smooth_sample(&self, wo: Vec3, u: f32) -> (BsdfSample, bool) {
        let eta = self.eta;
        let (f, cos_t) = fresnel_dielectric(wo.z, eta);
        let refracted = refract(wo, Vec3::Z, cos_t, eta);
        // η on the viewer's side over the far side, squared: radiance crossing into a
        // denser medium is compressed.
        let eta_t = eta_across(eta, wo);
        let trans = self.trans / (eta_t * eta_t);
        let s = if u < f {
            BsdfSample { wi: mirror(wo), weight: self.refl, pdf: f, delta: true, eta: 1.0 }
        } else {
            BsdfSample { wi: refracted, weight: trans, pdf: 1.0 - f, delta: true, eta: eta_t }
        };
        (s, wo.z != 0.0)
    }
}

/// A rough [`Dielectric`] of the distribution `BECKMANN` names, for loops over lanes
/// (value and density branch-free; the direction lane by lane, kept valid or not).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughDielectric<const BECKMANN: bool> {
    /// Inside over outside.
    pub eta: f32,
    /// Factor on reflection.
    pub refl: Vec3,
    /// Factor on transmission.
    pub trans: Vec3,
    /// Roughness (of the distribution `BECKMANN` names).
    pub mf: Microfacet,
    /// Whether the last [`RoughDielectric::direction`] gave a direction.
    pub(crate) valid: bool,
}

impl<const BECKMANN: bool> RoughDielectric<BECKMANN> {
    /// `d` with roughness `mf`.
    #[inline(always)]
    #[must_use]
    pub fn of(d: &Dielectric, mf: Microfacet) -> Self {
        Self { eta: d.eta, refl: d.refl, trans: d.trans, mf, valid: false }
    }

    /// f(wo, wi)·|cos θi| and the density of the sample, branch-free: the half vector
    /// (turned up) of a reflection or of a refraction with the relative index across from
    /// `wo`'s side, D, the facet's Fresnel term and the masking once; zero where either
    /// direction lies in the surface or the half vector is not defined, and for a
    /// refraction lit from the viewer's side of the facet.
    #[inline(always)]
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let mf = self.mf;
        let reflect = same_side(wo, wi);
        let eta_o = eta_across(self.eta, wo);
        let h = if reflect { wo + wi } else { wo + wi * eta_o };
        // (`normalize_or_zero`, its test kept for the end.)
        let rcp = h.length_recip();
        let defined = rcp.is_finite() && rcp > 0.0;
        let h = h * rcp;
        let h = if h.z < 0.0 { -h } else { h };
        let d = mf.d_of::<BECKMANN>(h);
        // The facet was sampled for wo turned to the upper hemisphere (the visible
        // facets seen from below are those seen from the mirrored direction).
        let pm = mf.pdf_with_d_of::<BECKMANN>(if wo.z < 0.0 { -wo } else { wo }, h, d);
        let (f, _) = fresnel_dielectric(wo.dot(h), self.eta);
        let g = mf.g_of::<BECKMANN>(wo, wi, h);
        let (oh, ih) = (wo.dot(h), wi.dot(h));
        let denom = oh + eta_o * ih;
        let r = (self.refl * (f * d * g / (4.0 * wo.z.abs())), f * pm / (4.0 * oh.abs()));
        let t = (
            self.trans * ((1.0 - f) * d * g * (oh * ih).abs() / (wo.z.abs() * denom * denom)).abs(),
            (1.0 - f) * pm * eta_o * eta_o * ih.abs() / (denom * denom),
        );
        // (Light from the other side of the facet than the viewer only.)
        let value = if reflect { r } else { t };
        if (wo.z == 0.0) | (wi.z == 0.0) | !defined | (!reflect & (oh * ih >= 0.0)) {
            (Vec3::ZERO, 0.0)
        } else {
            value
        }
    }

    /// The direction of the sample for `u` and `u2`: a visible facet (facing up: those
    /// seen from below are the ones seen from the mirrored direction), then reflection or
    /// refraction through it chosen against its Fresnel term; its `valid` field
    /// says whether there is one (a facet can turn a direction to the wrong side).
    #[inline(always)]
    #[must_use]
    pub fn direction(&mut self, wo: Vec3, u: f32, u2: (f32, f32)) -> Vec3 {
        let v = if wo.z < 0.0 { -wo } else { wo };
        let m = if BECKMANN { self.mf.sample(v, u2) } else { self.mf.ggx_sample(v, u2) };
        let (f, cos_t) = fresnel_dielectric(wo.dot(m), self.eta);
        let (wi, reflected) = if u < f { (reflect(wo, m), true) } else { (refract(wo, m, cos_t, self.eta), false) };
        self.valid = (wo.z != 0.0) & (same_side(wo, wi) == reflected);
        wi
    }

    /// The sample toward `wi` (from [`RoughDielectric::direction`]) of value `f` and
    /// density `pdf`, and whether there is one.
    #[inline(always)]
    #[must_use]
    pub fn finish(&self, wo: Vec3, wi: Vec3, f: Vec3, pdf: f32) -> (BsdfSample, bool) {
        let ok = self.valid & (pdf > 0.0) & pdf.is_finite();
        let eta = if same_side(wo, wi) { 1.0 } else { eta_across(self.eta, wo) };
        (BsdfSample { wi, weight: f / pdf, pdf, delta: false, eta }, ok)
    }

    /// The sample for `u` and `u2` and whether there is one.
    #[inline(always)]
    #[must_use]
    pub fn sample(mut self, wo: Vec3, u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        if wo.z == 0.0 {
            return (BsdfSample { wi: Vec3::Z, weight: Vec3::ZERO, pdf: 0.0, delta: false, eta: 1.0 }, false);
        }
        let wi = self.direction(wo, u, u2);
        if !self.valid {
            return (BsdfSample { wi, weight: Vec3::ZERO, pdf: 0.0, delta: false, eta: 1.0 }, false);
        }
        let (f, pdf) = self.eval_pdf(wo, wi);
        self.finish(wo, wi, f, pdf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth interface conserves energy: reflection and refraction are chosen in
    /// proportion to F and 1 − F, and carry radiance's (ηi/ηt)² across.
    #[test]
    fn smooth_glass_splits_by_fresnel() {
        let g = Dielectric { eta: 1.5, refl: Vec3::ONE, trans: Vec3::ONE, mf: None };
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let (f, _) = fresnel_dielectric(0.8, 1.5);
        let r = g.sample(wo, f * 0.5, (0.5, 0.5)).expect("reflection");
        assert!(r.delta && r.pdf == f && r.weight == Vec3::ONE && r.wi == Vec3::new(-0.6, 0.0, 0.8));
        let t = g.sample(wo, f + (1.0 - f) * 0.5, (0.5, 0.5)).expect("refraction");
        assert!((t.pdf - (1.0 - f)).abs() < 1e-7 && t.wi.z < 0.0 && t.eta == 1.5);
        // Snell: sin θt = sin θi / η.
        let sin_t = (t.wi.x * t.wi.x + t.wi.y * t.wi.y).sqrt();
        assert!((sin_t - 0.6 / 1.5).abs() < 1e-6);
        assert!((t.weight - Vec3::splat(1.0 / 2.25)).abs().max_element() < 1e-6);
        // From inside beyond the critical angle: all reflected.
        let inside = Vec3::new(0.9, 0.0, -(1.0f32 - 0.81).sqrt());
        let s = g.sample(inside, 0.999, (0.5, 0.5)).expect("total internal reflection");
        assert!(s.wi.z < 0.0 && s.pdf == 1.0);
    }
}
