//! Mitsuba's `dielectric` and `roughdielectric`: an interface between two dielectrics,
//! smooth (reflection and refraction chosen by the Fresnel term) or rough (Walter et al.
//! 2007, "Microfacet Models for Refraction through Rough Surfaces").

use super::microfacet::{fresnel_dielectric, reflect, refract, Microfacet};
use super::sample::{by_density, mirror, same_side, BsdfSample};
use glam::Vec3;

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
        if wo.z > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        }
    }

    /// What `eval` and `pdf` share, for a rough interface and directions off the surface:
    /// the microfacets, whether `wi` is a reflection, the relative index across from
    /// `wo`'s side (η on the far side over η on the viewer's) and the half vector, turned
    /// up; `None` where both are zero.
    #[inline]
    fn half(&self, wo: Vec3, wi: Vec3) -> Option<(Microfacet, bool, f32, Vec3)> {
        let mf = self.mf?;
        if wo.z == 0.0 || wi.z == 0.0 {
            return None;
        }
        let reflect = same_side(wo, wi);
        let eta_o = self.eta_across(wo);
        let h = if reflect { wo + wi } else { wo + wi * eta_o };
        let h = h.normalize_or_zero();
        let h = if h.z < 0.0 { -h } else { h };
        (h != Vec3::ZERO).then_some((mf, reflect, eta_o, h))
    }

    /// f(wo, wi)·|cos θi| (zero for the smooth interface).
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let Some((mf, reflect, eta_o, h)) = self.half(wo, wi) else { return Vec3::ZERO };
        let d = mf.d(h);
        let (f, _) = fresnel_dielectric(wo.dot(h), self.eta);
        let g = mf.g(wo, wi, h);
        if reflect {
            self.refl * (f * d * g / (4.0 * wo.z.abs()))
        } else {
            let (oh, ih) = (wo.dot(h), wi.dot(h));
            let denom = oh + eta_o * ih;
            // (Light from the other side of the facet than the viewer only.)
            if oh * ih >= 0.0 {
                return Vec3::ZERO;
            }
            self.trans * ((1.0 - f) * d * g * (oh * ih).abs() / (wo.z.abs() * denom * denom)).abs()
        }
    }

    /// The density of [`Dielectric::sample`] (zero for the smooth interface).
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let Some((mf, reflect, eta_o, h)) = self.half(wo, wi) else { return 0.0 };
        // The facet was sampled for wo turned to the upper hemisphere (the visible
        // facets seen from below are those seen from the mirrored direction).
        let pm = mf.pdf(if wo.z < 0.0 { -wo } else { wo }, h);
        let (f, _) = fresnel_dielectric(wo.dot(h), self.eta);
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

    /// [`Dielectric::eval`] and [`Dielectric::pdf`] at once (the half vector, D and the
    /// facet's Fresnel term once; the same bits as apart).
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let Some((mf, reflect, eta_o, h)) = self.half(wo, wi) else { return (Vec3::ZERO, 0.0) };
        let d = mf.d(h);
        let pm = mf.pdf_with_d(if wo.z < 0.0 { -wo } else { wo }, h, d);
        let (f, _) = fresnel_dielectric(wo.dot(h), self.eta);
        let g = mf.g(wo, wi, h);
        let (oh, ih) = (wo.dot(h), wi.dot(h));
        if reflect {
            (self.refl * (f * d * g / (4.0 * wo.z.abs())), f * pm / (4.0 * oh.abs()))
        } else {
            if oh * ih >= 0.0 {
                return (Vec3::ZERO, 0.0);
            }
            let denom = oh + eta_o * ih;
            (
                self.trans * ((1.0 - f) * d * g * (oh * ih).abs() / (wo.z.abs() * denom * denom)).abs(),
                (1.0 - f) * pm * eta_o * eta_o * ih.abs() / (denom * denom),
            )
        }
    }

    /// Reflection or refraction, chosen by `u` against the Fresnel term (of a visible
    /// facet chosen by `u2`, when rough).
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let eta = self.eta;
        match self.mf {
            None => {
                let (f, cos_t) = fresnel_dielectric(wo.z, eta);
                if u < f {
                    Some(BsdfSample { wi: mirror(wo), weight: self.refl, pdf: f, delta: true, eta: 1.0 })
                } else {
                    let wi = refract(wo, Vec3::Z, cos_t, eta);
                    // η on the viewer's side over the far side, squared: radiance
                    // crossing into a denser medium is compressed.
                    let eta_t = if wo.z > 0.0 { eta } else { 1.0 / eta };
                    Some(BsdfSample { wi, weight: self.trans / (eta_t * eta_t), pdf: 1.0 - f, delta: true, eta: eta_t })
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
                let (value, pdf) = self.eval_pdf(wo, wi);
                by_density(wo, wi, pdf, || value, self.eta_across(wo))
            }
        }
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
