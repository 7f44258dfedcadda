//! Mitsuba's `plastic`: a diffuse base under a smooth dielectric coating (Weidlich and
//! Wilkie 2007's layering: the base's light enters and leaves through the coating's
//! Fresnel transmittance, with internal reflection summed), the coating's mirror
//! reflection a delta lobe.

use super::microfacet::fresnel_dielectric;
use super::sample::{mean, mirror, reflection_lane, BsdfSample};
use crate::sampling::cosine_hemisphere;
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// Smooth plastic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plastic {
    /// Base albedo.
    pub diffuse: Vec3,
    /// Factor on the coating's reflection.
    pub spec: Vec3,
    /// Coating index.
    pub eta: f32,
    /// Mitsuba's `nonlinear`.
    pub nonlinear: bool,
    /// Probability weight of the specular lobe (Mitsuba's `specular_sampling_weight`).
    pub spec_weight: f32,
    /// The coating's diffuse Fresnel reflectance from inside.
    pub fdr_int: f32,
}

impl Plastic {
    /// f(wo, wi)·|cos θi| of the diffuse part (the coating's reflection is a delta lobe).
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// The density of [`Plastic::sample`]'s diffuse lobe.
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// [`Plastic::eval`] and [`Plastic::pdf`] at once, branch-free (a loop over lanes
    /// that calls it vectorizes; the same bits as apart).
    #[inline(always)]
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let (diffuse, eta, fdr_int) = (self.diffuse, self.eta, self.fdr_int);
        let (fo, pd_share) = self.spec_prob(wo);
        let (fi, _) = fresnel_dielectric(wi.z, eta);
        let nonlinear = diffuse / (Vec3::ONE - diffuse * fdr_int);
        let linear = diffuse / (1.0 - fdr_int);
        let base = if self.nonlinear { nonlinear } else { linear };
        let f = base * (FRAC_1_PI * wi.z / (eta * eta) * (1.0 - fo) * (1.0 - fi));
        let pdf = pd_share * wi.z * FRAC_1_PI;
        if (wo.z <= 0.0) | (wi.z <= 0.0) {
            (Vec3::ZERO, 0.0)
        } else {
            (f, pdf)
        }
    }

    /// The Fresnel reflectance for `wo` and the diffuse lobe's share of the samples (the
    /// specular lobe's probability is its Fresnel reflectance times its weight, over the
    /// diffuse lobe's).
    #[inline(always)]
    fn spec_prob(&self, wo: Vec3) -> (f32, f32) {
        let (fo, _) = fresnel_dielectric(wo.z, self.eta);
        let ps = fo * self.spec_weight;
        let pd = (1.0 - fo) * (1.0 - self.spec_weight);
        (fo, pd / (ps + pd))
    }

    /// The coating's mirror reflection or the base's cosine lobe, chosen by `u`.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        let (s, ok) = self.sample_lane(wo, u, u2);
        ok.then_some(s)
    }

    /// [`Plastic::sample`] branch-free: the sample and whether there is one.
    #[inline(always)]
    #[must_use]
    pub fn sample_lane(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        let (fo, _) = fresnel_dielectric(wo.z, self.eta);
        let ps = fo * self.spec_weight;
        let pd = (1.0 - fo) * (1.0 - self.spec_weight);
        let ps = ps / (ps + pd);
        let spec = BsdfSample { wi: mirror(wo), weight: self.spec * (fo / ps), pdf: ps, delta: true, eta: 1.0 };
        let wi = cosine_hemisphere(u2);
        let (f, pdf) = self.eval_pdf(wo, wi);
        let (diffuse, ok) = reflection_lane(wo, wi, f, pdf);
        if u < ps {
            (spec, wo.z > 0.0)
        } else {
            (diffuse, ok)
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::microfacet::fresnel_diffuse_reflectance;

    /// With a white base and no absorption, the coating keeps the energy it lets in: the
    /// albedo (sampled) is one at every angle in the nonlinear model, which sums the base's
    /// internal bounces exactly.
    #[test]
    fn white_plastic_reflects_everything() {
        let eta = 1.5;
        let p = Plastic {
            diffuse: Vec3::ONE,
            spec: Vec3::ONE,
            eta,
            nonlinear: true,
            spec_weight: plastic_spec_weight(Vec3::ONE, Vec3::ONE),
            fdr_int: fresnel_diffuse_reflectance(1.0 / eta),
        };
        for cos in [0.2f32, 0.6, 0.95] {
            let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
            let n = 256;
            let mut albedo = Vec3::ZERO;
            for i in 0..n {
                for j in 0..n {
                    let u = (i as f32 + 0.5) / n as f32;
                    let u2 = ((j as f32 + 0.5) / n as f32, ((i * 7 + j * 13) % n) as f32 / n as f32 + 0.5 / n as f32);
                    if let Some(s) = p.sample(wo, u, u2) {
                        albedo += s.weight / (n * n) as f32;
                    }
                }
            }
            assert!((albedo - Vec3::ONE).abs().max_element() < 0.02, "cos {cos}: {albedo}");
        }
    }
}
