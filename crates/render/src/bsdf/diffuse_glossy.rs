//! MTL's `Kd` + `Ks`/`Ns` (and BART's materials): a Lambertian lobe plus a Beckmann
//! glossy lobe of α from the Phong exponent, each sampled in proportion to its share of
//! the reflectance.

use super::microfacet::{reflect, Microfacet};
use super::sample::{by_density, lum, BsdfSample};
use crate::sampling::cosine_hemisphere;
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// MTL's Kd + Ks/Ns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseGlossy {
    /// Lambertian albedo.
    pub kd: Vec3,
    /// Glossy reflectance.
    pub ks: Vec3,
    /// Beckmann lobe.
    pub mf: Microfacet,
}

impl DiffuseGlossy {
    /// f(wo, wi)·|cos θi|.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// f(wo, wi)·|cos θi| and the density of [`DiffuseGlossy::sample`], branch-free (a loop
    /// over lanes that calls it vectorizes; one call gives the same bits as apart).
    #[inline(always)]
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let mf = self.mf;
        let h = (wo + wi).normalize();
        let d = mf.d_of::<true>(h);
        let f = self.kd * (FRAC_1_PI * wi.z) + self.ks * (d * mf.g_of::<true>(wo, wi, h) / (4.0 * wo.z));
        let pg = self.glossy_prob();
        let pdf = pg * mf.pdf_with_d_of::<true>(wo, h, d) / (4.0 * wo.dot(h)) + (1.0 - pg) * wi.z * FRAC_1_PI;
        if (wo.z <= 0.0) | (wi.z <= 0.0) {
            (Vec3::ZERO, 0.0)
        } else {
            (f, pdf)
        }
    }

    /// The probability of sampling the glossy lobe: its share of the reflectance.
    #[inline(always)]
    fn glossy_prob(&self) -> f32 {
        let (d, s) = (lum(self.kd), lum(self.ks));
        let p = s / (d + s);
        if d + s > 0.0 {
            p
        } else {
            0.5
        }
    }

    /// The density of [`DiffuseGlossy::sample`].
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// The glossy or the diffuse lobe, chosen by `u`.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = self.direction(wo, u, u2);
        if wi.z <= 0.0 {
            return None;
        }
        let (f, pdf) = self.eval_pdf(wo, wi);
        by_density(wo, wi, pdf, || f, 1.0)
    }

    /// The direction [`DiffuseGlossy::sample`] takes (`wo` above the surface): a Beckmann
    /// facet's reflection or a cosine-distributed one, chosen by `u`.
    #[must_use]
    pub fn direction(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Vec3 {
        if u < self.glossy_prob() {
            reflect(wo, self.mf.sample(wo, u2))
        } else {
            cosine_hemisphere(u2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_scene::Distribution;

    /// Without a glossy part it is the Lambertian BRDF, sampled by the cosine alone.
    #[test]
    fn without_gloss_it_is_lambertian() {
        let b = DiffuseGlossy { kd: Vec3::new(0.5, 0.4, 0.3), ks: Vec3::ZERO, mf: Microfacet::new(Distribution::Beckmann, 0.2) };
        let wo = Vec3::new(0.0, 0.6, 0.8);
        let wi = Vec3::new(0.48, 0.0, 0.877_496_4);
        assert!((b.eval(wo, wi) - b.kd * (wi.z * FRAC_1_PI)).abs().max_element() < 1e-7);
        assert!((b.pdf(wo, wi) - wi.z * FRAC_1_PI).abs() < 1e-7);
        let s = b.sample(wo, 0.3, (0.2, 0.9)).expect("a sample");
        assert!((s.weight - b.kd).abs().max_element() < 1e-5);
    }
}
