//! Mitsuba's `diffuse`: the Lambertian BRDF, sampled by the cosine.

use super::sample::BsdfSample;
use crate::sampling::cosine_hemisphere;
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// Lambertian reflection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diffuse {
    /// Albedo.
    pub r: Vec3,
}

impl Diffuse {
    /// f(wo, wi)·|cos θi|.
    #[inline]
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z > 0.0 && wi.z > 0.0 {
            self.r * (FRAC_1_PI * wi.z)
        } else {
            Vec3::ZERO
        }
    }

    /// The density of [`Diffuse::sample`].
    #[inline]
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z > 0.0 && wi.z > 0.0 {
            wi.z * FRAC_1_PI
        } else {
            0.0
        }
    }

    /// A cosine-distributed direction for `u2`.
    #[inline]
    #[must_use]
    pub fn sample(&self, wo: Vec3, u2: (f32, f32)) -> Option<BsdfSample> {
        let (s, ok) = self.sample_lane(wo, u2);
        ok.then_some(s)
    }

    /// [`Diffuse::sample`] without a branch (for loops over lanes): the sample, and
    /// whether there is one (when not, the sample's fields mean nothing).
    #[inline(always)]
    #[must_use]
    pub fn sample_lane(&self, wo: Vec3, u2: (f32, f32)) -> (BsdfSample, bool) {
        let wi = cosine_hemisphere(u2);
        let ok = (wo.z > 0.0) & (wi.z > 0.0);
        (BsdfSample { wi, weight: self.r, pdf: wi.z * FRAC_1_PI, delta: false, eta: 1.0 }, ok)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The white furnace: the albedo is `r`, by sampling (every weight is `r`) and by
    /// integrating `eval` over the hemisphere (midpoint rule in cos θ and φ).
    #[test]
    fn reflects_its_albedo() {
        let b = Diffuse { r: Vec3::new(0.2, 0.5, 0.9) };
        let wo = Vec3::new(0.3, 0.1, 0.948_683_3).normalize();
        let s = b.sample(wo, (0.3, 0.7)).expect("a sample");
        assert_eq!(s.weight, b.r);
        assert!((s.pdf - b.pdf(wo, s.wi)).abs() < 1e-6);
        let n = 200;
        let mut albedo = Vec3::ZERO;
        for i in 0..n {
            let mu = (i as f32 + 0.5) / n as f32;
            for j in 0..n {
                let phi = 2.0 * std::f32::consts::PI * (j as f32 + 0.5) / n as f32;
                let st = (1.0 - mu * mu).sqrt();
                let wi = Vec3::new(st * phi.cos(), st * phi.sin(), mu);
                // dω = dμ dφ; eval carries the cosine.
                albedo += b.eval(wo, wi) * (2.0 * std::f32::consts::PI / (n * n) as f32);
            }
        }
        assert!((albedo - b.r).abs().max_element() < 1e-3, "{albedo}");
        assert_eq!(b.eval(wo, -wo), Vec3::ZERO, "no light through");
    }
}
