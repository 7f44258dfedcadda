//! Mitsuba's `conductor` and `roughconductor`: a metal's mirror reflection with its complex
//! Fresnel term, or a microfacet lobe of it (Walter et al. 2007, sampled by the visible
//! normals).

use super::microfacet::{fresnel_conductor, reflect, Microfacet};
use super::sample::{mirror, reflection_lane, BsdfSample};
use glam::Vec3;
use lucent_scene::Distribution;

/// A smooth (`mf` = None) or rough conductor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conductor {
    /// Real part of the index.
    pub eta: Vec3,
    /// Imaginary part.
    pub k: Vec3,
    /// Factor.
    pub spec: Vec3,
    /// Roughness.
    pub mf: Option<Microfacet>,
}

impl Conductor {
    /// f(wo, wi)·|cos θi| (zero for the mirror).
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// The density of [`Conductor::sample`] (zero for the mirror).
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// [`Conductor::eval`] and [`Conductor::pdf`] at once.
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        match self.mf {
            None => (Vec3::ZERO, 0.0),
            Some(mf) => match mf.dist {
                Distribution::Beckmann => RoughConductor::<true>::of(self, mf).eval_pdf(wo, wi),
                Distribution::Ggx => RoughConductor::<false>::of(self, mf).eval_pdf(wo, wi),
            },
        }
    }

    /// The mirror direction, or a visible facet's reflection for `u2`.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u2: (f32, f32)) -> Option<BsdfSample> {
        let (s, ok) = match self.mf {
            None => {
                let wi = mirror(wo);
                let s = BsdfSample { wi, weight: self.spec * fresnel_conductor(wo.z, self.eta, self.k), pdf: 1.0, delta: true, eta: 1.0 };
                (s, wo.z > 0.0)
            }
            Some(mf) => match mf.dist {
                Distribution::Beckmann => RoughConductor::<true>::of(self, mf).sample(wo, u2),
                Distribution::Ggx => RoughConductor::<false>::of(self, mf).sample(wo, u2),
            },
        };
        ok.then_some(s)
    }
}

/// A rough conductor of a known distribution (Beckmann's when `BECKMANN`, else GGX), as
/// the lane integrator packs it: its value, density and (for GGX) sample are branch-free,
/// so that a loop over lanes of one distribution vectorizes; [`Conductor`] answers through
/// the same code (the same bits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughConductor<const BECKMANN: bool> {
    /// Real part of the index.
    pub eta: Vec3,
    /// Imaginary part.
    pub k: Vec3,
    /// Factor.
    pub spec: Vec3,
    /// Roughness (of the distribution `BECKMANN` names).
    pub mf: Microfacet,
}

impl<const BECKMANN: bool> RoughConductor<BECKMANN> {
    /// `c` with roughness `mf`.
    #[inline(always)]
    #[must_use]
    pub fn of(c: &Conductor, mf: Microfacet) -> Self {
        Self { eta: c.eta, k: c.k, spec: c.spec, mf }
    }

    /// f(wo, wi)·|cos θi| and the density of [`RoughConductor::sample`].
    #[inline(always)]
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let mf = self.mf;
        let h = (wo + wi).normalize();
        let d = mf.d_of::<BECKMANN>(h);
        let pdf = mf.pdf_with_d_of::<BECKMANN>(wo, h, d) / (4.0 * wo.dot(h));
        let f = fresnel_conductor(wo.dot(h), self.eta, self.k) * self.spec * (d * mf.g_of::<BECKMANN>(wo, wi, h) / (4.0 * wo.z));
        let f = if d == 0.0 { Vec3::ZERO } else { f };
        if (wo.z <= 0.0) | (wi.z <= 0.0) {
            (Vec3::ZERO, 0.0)
        } else {
            (f, pdf)
        }
    }

    /// The reflection of `wo` about a visible facet chosen by `u2`.
    #[inline(always)]
    #[must_use]
    pub fn direction(&self, wo: Vec3, u2: (f32, f32)) -> Vec3 {
        let m = if BECKMANN { self.mf.sample(wo, u2) } else { self.mf.ggx_sample(wo, u2) };
        reflect(wo, m)
    }

    /// A visible facet's reflection for `u2`, and whether there is one.
    #[inline(always)]
    #[must_use]
    pub fn sample(&self, wo: Vec3, u2: (f32, f32)) -> (BsdfSample, bool) {
        let wi = self.direction(wo, u2);
        let (f, pdf) = self.eval_pdf(wo, wi);
        reflection_lane(wo, wi, f, pdf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A perfect mirror (k → ∞ makes the Fresnel term 1) reflects everything into the
    /// mirror direction; a rough one's sampled weights average to its albedo, which is at
    /// most one and near one for a nearly smooth surface.
    #[test]
    fn a_perfect_mirror_reflects_everything() {
        let wo = Vec3::new(0.4, -0.2, 0.894_427_2).normalize();
        let smooth = Conductor { eta: Vec3::ZERO, k: Vec3::splat(1e6), spec: Vec3::ONE, mf: None };
        let s = smooth.sample(wo, (0.5, 0.5)).expect("the mirror");
        assert!(s.delta && (s.wi - Vec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-6);
        assert!((s.weight - Vec3::ONE).abs().max_element() < 1e-5, "{}", s.weight);
        let rough = Conductor { mf: Some(Microfacet::new(Distribution::Ggx, 0.05)), ..smooth };
        let n = 64;
        let mut albedo = Vec3::ZERO;
        for i in 0..n {
            for j in 0..n {
                let u = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                if let Some(s) = rough.sample(wo, u) {
                    assert!((s.pdf - rough.pdf(wo, s.wi)).abs() <= 1e-4 * s.pdf);
                    // (Value and density together: the same bits as apart.)
                    let (f, pdf) = rough.eval_pdf(wo, s.wi);
                    assert_eq!((f, pdf), (rough.eval(wo, s.wi), rough.pdf(wo, s.wi)));
                    albedo += s.weight / (n * n) as f32;
                }
            }
        }
        assert!(albedo.max_element() <= 1.0 + 1e-3 && albedo.min_element() > 0.97, "{albedo}");
    }
}
