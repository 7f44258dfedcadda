//! The glTF 2.0 metallic-roughness BRDF (the specification's Appendix B), with thin-walled
//! `KHR_materials_transmission`: material = mix(dielectric, metal, metallic), dielectric =
//! fresnel_mix(f0, mix(diffuse(base), btdf·base, transmission), brdf), metal = brdf ·
//! schlick(base); the microfacet terms are GGX with the height-correlated Smith
//! visibility; the BTDF, thin-walled, is the BRDF of `wi` mirrored through the surface.

use super::microfacet::{reflect, schlick, Microfacet};
use super::sample::{by_density, lum, BsdfSample};
use crate::sampling::cosine_hemisphere;
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// glTF metallic-roughness.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetallicRoughness {
    /// Base colour.
    pub base: Vec3,
    /// Metallic.
    pub metallic: f32,
    /// α = roughness².
    pub mf: Microfacet,
    /// Transmission (of the dielectric part).
    pub transmission: f32,
    /// Dielectric reflectance at normal incidence, ((η − 1)/(η + 1))².
    pub f0: f32,
}

impl MetallicRoughness {
    /// The height-correlated visibility G2 / (4 |cos o| |cos i|) of GGX, for a
    /// reflection pair.
    #[inline(always)]
    fn visibility(mf: &Microfacet, wo: Vec3, wi: Vec3) -> f32 {
        let a2 = mf.alpha * mf.alpha;
        let (no, ni) = (wo.z.abs(), wi.z.abs());
        let lo = ni * (no * no * (1.0 - a2) + a2).sqrt();
        let li = no * (ni * ni * (1.0 - a2) + a2).sqrt();
        let v = 0.5 / (lo + li);
        if lo + li > 0.0 {
            v
        } else {
            0.0
        }
    }

    /// f(wo, wi)·|cos θi|.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// [`MetallicRoughness::eval`] and [`MetallicRoughness::pdf`] at once, branch-free (a
    /// loop over lanes that calls it vectorizes; the same bits as apart).
    #[inline(always)]
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let (base, metallic, mf, transmission, f0) = (self.base, self.metallic, self.mf, self.transmission, self.f0);
        let reflect = wi.z > 0.0;
        // Thin-walled transmission: the mirrored direction's reflection terms.
        let wl = if reflect { wi } else { Vec3::new(wi.x, wi.y, -wi.z) };
        let h = (wo + wl).normalize();
        let voh = wo.dot(h);
        let d = mf.d_of::<false>(h);
        let spec = d * Self::visibility(&mf, wo, wl);
        let fd = schlick(Vec3::splat(f0), voh).x;
        let cos = wl.z;
        let diffuse = base * FRAC_1_PI;
        let dielectric = diffuse * ((1.0 - fd) * (1.0 - transmission)) + Vec3::splat(fd * spec);
        let metal = schlick(base, voh) * spec;
        let f_reflect = (dielectric * (1.0 - metallic) + metal * metallic) * cos;
        let f_through = base * ((1.0 - metallic) * transmission * (1.0 - fd) * spec * cos);
        let [ps, pd, pt] = self.probs(wo);
        let spec_pdf = mf.pdf_with_d_of::<false>(wo, h, d) / (4.0 * wo.dot(h).abs().max(1e-12));
        let (f, pdf) = if reflect { (f_reflect, ps * spec_pdf + pd * wi.z * FRAC_1_PI) } else { (f_through, pt * spec_pdf) };
        if (wo.z <= 0.0) | (wi.z == 0.0) {
            (Vec3::ZERO, 0.0)
        } else {
            (f, pdf)
        }
    }

    /// Lobe probabilities for `wo`: specular reflection, diffuse, transmission.
    #[inline(always)]
    fn probs(&self, wo: Vec3) -> [f32; 3] {
        let (base, metallic, transmission, f0) = (self.base, self.metallic, self.transmission, self.f0);
        let fd = schlick(Vec3::splat(f0), wo.z).x;
        let spec = (1.0 - metallic) * fd + metallic * lum(schlick(base, wo.z)).max(0.05);
        let rest = (1.0 - metallic) * (1.0 - fd) * lum(base).max(0.05);
        let p = [spec.max(0.02), rest * (1.0 - transmission), rest * transmission];
        let s: f32 = p.iter().sum();
        p.map(|x| x / s)
    }

    /// The density of [`MetallicRoughness::sample`].
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// A direction of one lobe, chosen by `u`.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        let wi = self.direction(wo, u, u2)?;
        let (f, pdf) = self.eval_pdf(wo, wi);
        by_density(wo, wi, pdf, || f, 1.0)
    }

    /// The direction [`MetallicRoughness::sample`] takes (`None`: no sample).
    #[must_use]
    pub fn direction(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<Vec3> {
        if wo.z <= 0.0 {
            return None;
        }
        let [ps, pd, _] = self.probs(wo);
        if u < ps || u >= ps + pd {
            let wi = reflect(wo, self.mf.sample(wo, u2));
            if wi.z <= 0.0 {
                return None;
            }
            Some(if u < ps { wi } else { Vec3::new(wi.x, wi.y, -wi.z) })
        } else {
            Some(cosine_hemisphere(u2))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_scene::Distribution;

    /// A rough dielectric of f0 = 0 is the Lambertian BRDF of its base colour; thin-walled
    /// transmission mirrors the reflection lobe through the surface.
    #[test]
    fn without_fresnel_it_is_lambertian_and_transmission_mirrors() {
        let b = MetallicRoughness {
            base: Vec3::new(0.8, 0.6, 0.4),
            metallic: 0.0,
            mf: Microfacet::new(Distribution::Ggx, 0.25),
            transmission: 0.0,
            f0: 0.0,
        };
        let wo = Vec3::new(0.0, 0.6, 0.8);
        let wi = Vec3::new(0.6, 0.0, 0.8);
        assert!((b.eval(wo, wi) - b.base * (wi.z * FRAC_1_PI)).abs().max_element() < 1e-6);
        // Fully transmissive: reflection is the coating's F·spec, transmission through
        // the mirrored direction base·(1 − F)·spec.
        let t = MetallicRoughness { transmission: 1.0, f0: 0.04, ..b };
        let below = Vec3::new(wi.x, wi.y, -wi.z);
        let f = schlick(Vec3::splat(0.04), wo.dot((wo + wi).normalize())).x;
        let want = t.eval(wo, wi) * t.base * ((1.0 - f) / f);
        assert!((t.eval(wo, below) - want).abs().max_element() < 1e-6 * want.max_element(), "{} against {want}", t.eval(wo, below));
    }
}
