//! Mitsuba's `roughplastic`: a diffuse base under a rough dielectric coating, the
//! coating's reflection a microfacet lobe, the base's light through the coating's
//! transmittance. The coating's tables (as Mitsuba precomputes them): the fraction of
//! light the rough coating transmits for 64 directions (cosines evenly spaced over
//! [0, 1]), and its internal reflectance (twice the mean over the same cosines of the
//! reflectance from inside, each times its cosine), both integrals over the visible
//! microfacet normals, here by Gauss-Legendre quadrature.

use super::microfacet::{fresnel_dielectric, gauss_legendre, reflect, refract, Microfacet};
use super::sample::{by_density, BsdfSample};
use crate::sampling::cosine_hemisphere;
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// Rough plastic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughPlastic<'a> {
    /// Base albedo.
    pub diffuse: Vec3,
    /// Factor on the coating's reflection.
    pub spec: Vec3,
    /// Mitsuba's `nonlinear`.
    pub nonlinear: bool,
    /// Probability weight of the specular lobe.
    pub spec_weight: f32,
    /// Coating roughness.
    pub mf: Microfacet,
    /// The coating's transmittance and internal reflectance.
    pub tables: &'a RoughPlasticTables,
}

impl RoughPlastic<'_> {
    /// f(wo, wi)·|cos θi|: the coating's lobe plus the base's light through it.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let (mf, tables, diffuse) = (self.mf, self.tables, self.diffuse);
        let h = (wo + wi).normalize();
        let (f, _) = fresnel_dielectric(wo.dot(h), tables.eta);
        let specular = self.spec * (f * mf.d(h) * mf.g(wo, wi, h) / (4.0 * wo.z));
        let (to, ti) = (tables.external(wo.z), tables.external(wi.z));
        let ri = tables.internal;
        let base = if self.nonlinear { diffuse / (Vec3::ONE - diffuse * ri) } else { diffuse / (1.0 - ri) };
        specular + base * (FRAC_1_PI / (tables.eta * tables.eta) * wi.z * to * ti)
    }

    /// The density of [`RoughPlastic::sample`].
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let (ps, pd) = probs(self.tables.external(wo.z), self.spec_weight);
        let h = (wo + wi).normalize();
        ps * self.mf.pdf(wo, h) / (4.0 * wo.dot(h)) + pd * wi.z * FRAC_1_PI
    }

    /// [`RoughPlastic::eval`] and [`RoughPlastic::pdf`] at once (the half vector, D and
    /// the coating's transmittance once; the same bits as apart).
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let (mf, tables, diffuse) = (self.mf, self.tables, self.diffuse);
        let h = (wo + wi).normalize();
        let d = mf.d(h);
        let (f, _) = fresnel_dielectric(wo.dot(h), tables.eta);
        let specular = self.spec * (f * d * mf.g(wo, wi, h) / (4.0 * wo.z));
        let (to, ti) = (tables.external(wo.z), tables.external(wi.z));
        let ri = tables.internal;
        let base = if self.nonlinear { diffuse / (Vec3::ONE - diffuse * ri) } else { diffuse / (1.0 - ri) };
        let value = specular + base * (FRAC_1_PI / (tables.eta * tables.eta) * wi.z * to * ti);
        let (ps, pd) = probs(to, self.spec_weight);
        (value, ps * mf.pdf_with_d(wo, h, d) / (4.0 * wo.dot(h)) + pd * wi.z * FRAC_1_PI)
    }

    /// The coating's lobe or the base's cosine lobe, chosen by `u`.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let (ps, _) = probs(self.tables.external(wo.z), self.spec_weight);
        let wi = if u < ps { reflect(wo, self.mf.sample(wo, u2)) } else { cosine_hemisphere(u2) };
        if wi.z <= 0.0 {
            return None;
        }
        let (f, pdf) = self.eval_pdf(wo, wi);
        by_density(wo, wi, pdf, || f, 1.0)
    }
}

/// Mitsuba's lobe probabilities for rough plastic: (specular, diffuse) from the coating's
/// transmittance toward the viewer.
#[inline]
fn probs(t_o: f32, spec_weight: f32) -> (f32, f32) {
    let ps = (1.0 - t_o) * spec_weight;
    let pd = t_o * (1.0 - spec_weight);
    let s = ps + pd;
    if s > 0.0 {
        (ps / s, pd / s)
    } else {
        (0.0, 1.0)
    }
}

/// Cosines in the transmittance table.
pub const RES: usize = 64;

/// A rough coating's transmittance table and internal reflectance.
#[derive(Clone, Debug, PartialEq)]
pub struct RoughPlasticTables {
    /// Relative index of the coating.
    pub eta: f32,
    /// Transmittance from outside, at cosines `i / (RES − 1)` (the first at 10⁻⁶).
    pub transmittance: [f32; RES],
    /// Reflectance from inside, averaged over the cosine-weighted hemisphere.
    pub internal: f32,
}

impl RoughPlasticTables {
    /// The tables of a coating of relative index `eta` and roughness `mf` (made once per
    /// distinct coating in a process, then shared).
    #[must_use]
    pub fn new(mf: &Microfacet, eta: f32) -> std::sync::Arc<Self> {
        type Cache = std::sync::Mutex<std::collections::HashMap<(bool, u32, u32), std::sync::Arc<RoughPlasticTables>>>;
        static CACHE: std::sync::OnceLock<Cache> = std::sync::OnceLock::new();
        let key = (mf.dist == lucent_scene::Distribution::Ggx, mf.alpha.to_bits(), eta.to_bits());
        let cache = CACHE.get_or_init(Default::default);
        if let Some(t) = cache.lock().ok().and_then(|c| c.get(&key).cloned()) {
            return t;
        }
        let t = std::sync::Arc::new(Self::compute(mf, eta));
        if let Ok(mut c) = cache.lock() {
            c.insert(key, t.clone());
        }
        t
    }

    fn compute(mf: &Microfacet, eta: f32) -> Self {
        use rayon::prelude::*;
        let q = gauss_legendre(128);
        // (Each cosine's two integrals apart, in parallel: 2 × 128² evaluations each,
        // 60 ms a coating on one thread; summed after, in order: the same bits.)
        let rows: Vec<(f32, f64)> = (0..RES)
            .into_par_iter()
            .map(|i| {
                let mu = (i as f32 / (RES - 1) as f32).max(1e-6);
                let wi = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
                let t = visible_integral(mf, wi, &q, |m| {
                    let (f, cos_t) = fresnel_dielectric(wi.dot(m), eta);
                    let wt = refract(wi, m, cos_t, eta);
                    if wt.z * wi.z >= 0.0 {
                        0.0
                    } else {
                        (1.0 - f) * mf.g1(wt, m)
                    }
                }) as f32;
                let r = visible_integral(mf, wi, &q, |m| {
                    let (f, _) = fresnel_dielectric(wi.dot(m), 1.0 / eta);
                    let wr = reflect(wi, m);
                    if wr.z <= 0.0 {
                        0.0
                    } else {
                        f * mf.g1(wr, m)
                    }
                });
                (t, r * f64::from(mu))
            })
            .collect();
        let mut transmittance = [0.0f32; RES];
        let mut internal = 0.0f64;
        for (t, &(ti, ri)) in transmittance.iter_mut().zip(&rows) {
            *t = ti;
            internal += ri;
        }
        Self { eta, transmittance, internal: (2.0 * internal / RES as f64) as f32 }
    }

    /// The transmittance for a direction of cosine `cos` (linear between the table's).
    #[must_use]
    pub fn external(&self, cos: f32) -> f32 {
        let x = cos.clamp(0.0, 1.0) * (RES - 1) as f32;
        let i = (x as usize).min(RES - 2);
        let f = x - i as f32;
        self.transmittance[i] * (1.0 - f) + self.transmittance[i + 1] * f
    }
}

/// ∫ g(m) over the normals visible from `wi`, weighted by their visible density
/// (D(m) G1(wi, m) ⟨wi, m⟩ / cos θi, the exact masking, as Mitsuba's visible-normal samples
/// follow it), by a product Gauss-Legendre rule over a map of [0, 1]² onto normals: for
/// GGX the visible normals' own (exact and smooth: each node weighs one), for Beckmann
/// the map onto D(m) cos θm (Walter et al. 2007, eq. 28: its visible map inverts a CDF
/// numerically, too slow for a million nodes), each node weighed by visible / D cos.
fn visible_integral(mf: &Microfacet, wi: Vec3, q: &[(f64, f64)], g: impl Fn(Vec3) -> f32) -> f64 {
    let mut sum = 0.0f64;
    let a2 = f64::from(mf.alpha * mf.alpha);
    for &(x, wx) in q {
        let u = 0.5 * (x + 1.0);
        // tan² θm of D cos θm at u (Beckmann).
        let tan2 = -a2 * (1.0 - u).max(1e-300).ln();
        let cos = 1.0 / (1.0 + tan2).sqrt();
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        for &(y, wy) in q {
            let v = 0.5 * (y + 1.0);
            let weight = 0.25 * wx * wy;
            if mf.dist == lucent_scene::Distribution::Ggx {
                let m = mf.sample(wi, (u as f32, v as f32));
                sum += weight * f64::from(g(m));
                continue;
            }
            let phi = 2.0 * std::f64::consts::PI * v;
            let m = Vec3::new((sin * phi.cos()) as f32, (sin * phi.sin()) as f32, cos as f32);
            let sample_pdf = mf.d(m) * m.z;
            if sample_pdf.is_nan() || sample_pdf <= 0.0 {
                continue;
            }
            let visible = mf.d(m) * mf.g1_exact(wi, m) * wi.dot(m).max(0.0) / wi.z;
            sum += weight * f64::from(g(m) * visible / sample_pdf);
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_scene::Distribution;

    /// Value and density together are the same bits as apart (next-event estimation takes
    /// them together, MIS of an emitter met takes the density alone), for the rough
    /// plastic, conductor and dielectric, either distribution.
    #[test]
    fn eval_pdf_is_eval_and_pdf() {
        for dist in [Distribution::Beckmann, Distribution::Ggx] {
            let mf = Microfacet::new(dist, 0.25);
            let tables = RoughPlasticTables::new(&mf, 1.5);
            let b = RoughPlastic {
                diffuse: Vec3::new(0.6, 0.4, 0.2),
                spec: Vec3::ONE,
                nonlinear: false,
                spec_weight: 0.3,
                mf,
                tables: &tables,
            };
            let c = crate::bsdf::Conductor { eta: Vec3::new(0.2, 0.9, 1.1), k: Vec3::new(3.9, 2.4, 2.2), spec: Vec3::ONE, mf: Some(mf) };
            for i in 0..400 {
                let a = i as f32 * 0.7;
                let wo = Vec3::new(a.cos() * 0.6, a.sin() * 0.5, 0.3 + 0.002 * i as f32 - 0.4).normalize();
                let wi = Vec3::new((a * 1.3).sin(), (a * 0.4).cos(), 0.9 - 0.004 * i as f32).normalize();
                assert_eq!(b.eval_pdf(wo, wi), (b.eval(wo, wi), b.pdf(wo, wi)), "{dist:?} {wo} {wi}");
                assert_eq!(c.eval_pdf(wo, wi), (c.eval(wo, wi), c.pdf(wo, wi)), "{dist:?} {wo} {wi}");
                for eta in [1.5, 1.0 / 1.33] {
                    let g = crate::bsdf::Dielectric { eta, refl: Vec3::ONE, trans: Vec3::new(0.9, 1.0, 0.8), mf: Some(mf) };
                    // (Transmission too: wi below the surface.)
                    for wi in [wi, Vec3::new(wi.x, wi.y, -wi.z)] {
                        assert_eq!(g.eval_pdf(wo, wi), (g.eval(wo, wi), g.pdf(wo, wi)), "{dist:?} η {eta} {wo} {wi}");
                    }
                }
            }
        }
    }

    /// The coating's tables: a smooth-looking coating (small α) transmits what the smooth
    /// Fresnel term lets through at every tabulated angle, and its internal reflectance is
    /// the smooth coating's diffuse Fresnel reflectance from inside.
    #[test]
    fn nearly_smooth_coating_tables_are_fresnel() {
        let eta = 1.5;
        let t = RoughPlasticTables::compute(&Microfacet::new(Distribution::Ggx, 0.001), eta);
        for i in [8usize, 32, 63] {
            let mu = i as f32 / (RES - 1) as f32;
            let (f, _) = fresnel_dielectric(mu, eta);
            assert!((t.transmittance[i] - (1.0 - f)).abs() < 2e-3, "cos {mu}: {} against {}", t.transmittance[i], 1.0 - f);
        }
        let fdr = super::super::microfacet::fresnel_diffuse_reflectance(1.0 / eta);
        assert!((t.internal - fdr).abs() < 0.02, "{} against {fdr}", t.internal);
    }
}
