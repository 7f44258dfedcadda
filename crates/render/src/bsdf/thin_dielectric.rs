//! Mitsuba's `thindielectric`: a thin sheet of glass, reflecting and transmitting
//! straight through (no bending), with the light that bounces inside the sheet summed.

use super::microfacet::fresnel_dielectric;
use super::sample::{mirror, BsdfSample};
use glam::Vec3;

/// A thin dielectric sheet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinDielectric {
    /// Index of the sheet.
    pub eta: f32,
    /// Factor on reflection.
    pub refl: Vec3,
    /// Factor on transmission.
    pub trans: Vec3,
}

impl ThinDielectric {
    /// The sheet's reflectance for `wo`: R + T² R / (1 − R²) (light bouncing inside).
    #[inline(always)]
    #[must_use]
    pub fn reflectance(&self, wo: Vec3) -> f32 {
        let (r, _) = fresnel_dielectric(wo.z.abs(), self.eta);
        let t = 1.0 - r;
        let summed = r + t * t * r / (1.0 - r * r);
        if r < 1.0 {
            summed
        } else {
            r
        }
    }

    /// Reflection or straight transmission, chosen by `u` against the reflectance.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32) -> Option<BsdfSample> {
        Some(self.sample_lane(wo, u))
    }

    /// [`ThinDielectric::sample`] branch-free (there always is one).
    #[inline(always)]
    #[must_use]
    pub fn sample_lane(&self, wo: Vec3, u: f32) -> BsdfSample {
        let r = self.reflectance(wo);
        let reflected = BsdfSample { wi: mirror(wo), weight: self.refl, pdf: r, delta: true, eta: 1.0 };
        let through = BsdfSample { wi: -wo, weight: self.trans, pdf: 1.0 - r, delta: true, eta: 1.0 };
        if u < r {
            reflected
        } else {
            through
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reflection and transmission sum to one, transmission goes straight through, and at
    /// normal incidence the reflectance is the closed form 2R / (1 + R) of a lossless slab.
    #[test]
    fn a_sheet_reflects_and_transmits_everything() {
        let s = ThinDielectric { eta: 1.5, refl: Vec3::ONE, trans: Vec3::ONE };
        let r0 = (0.5f32 / 2.5).powi(2);
        assert!((s.reflectance(Vec3::Z) - 2.0 * r0 / (1.0 + r0)).abs() < 1e-6);
        let wo = Vec3::new(0.3, 0.4, (1.0f32 - 0.25).sqrt());
        let r = s.reflectance(wo);
        let a = s.sample(wo, r * 0.5).expect("reflection");
        let b = s.sample(wo, r + (1.0 - r) * 0.5).expect("transmission");
        assert!((a.pdf + b.pdf - 1.0).abs() < 1e-6 && b.wi == -wo && a.wi == Vec3::new(-0.3, -0.4, wo.z));
    }
}
