//! Mitsuba's `roughplastic`: a diffuse base under a rough dielectric coating, the
//! coating's reflection a microfacet lobe, the base's light through the coating's
//! transmittance. The coating's tables (as Mitsuba precomputes them): the fraction of
//! light the rough coating transmits for 64 directions (cosines evenly spaced over
//! [0, 1]), and its internal reflectance (twice the mean over the same cosines of the
//! reflectance from inside, each times its cosine), both integrals over the visible
//! microfacet normals, here by Gauss-Legendre quadrature.

use super::microfacet::{fresnel_dielectric, gauss_legendre, reflect, refract, Microfacet};
use super::sample::{reflection_lane, BsdfSample};
use crate::sampling::cosine_hemisphere;
use glam::Vec3;
use lucent_scene::Distribution;
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

impl<'a> RoughPlastic<'a> {
    /// f(wo, wi)·|cos θi|: the coating's lobe plus the base's light through it.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// The density of [`RoughPlastic::sample`].
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// [`RoughPlastic::eval`] and [`RoughPlastic::pdf`] at once.
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        match self.mf.dist {
            Distribution::Beckmann => RoughPlasticLane::<true>::new(self, wo, wi).eval_pdf(wo, wi),
            Distribution::Ggx => RoughPlasticLane::<false>::new(self, wo, wi).eval_pdf(wo, wi),
        }
    }

    /// The coating's lobe or the base's cosine lobe, chosen by `u`.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        let (s, ok) = match self.mf.dist {
            Distribution::Beckmann => RoughPlasticLane::<true>::new(self, wo, Vec3::Z).sample(wo, u, u2),
            Distribution::Ggx => RoughPlasticLane::<false>::new(self, wo, Vec3::Z).sample(wo, u, u2),
        };
        ok.then_some(s)
    }
}

/// A rough plastic of a known distribution (Beckmann's when `BECKMANN`, else GGX) as the
/// lane integrator packs it: the coating's transmittance toward `wo` and `wi` read from
/// its table ahead (lane by lane), the rest branch-free, so that a loop over lanes of one
/// distribution vectorizes; [`RoughPlastic`] answers through the same code (the same bits).
#[derive(Clone, Copy, Debug)]
pub struct RoughPlasticLane<'a, const BECKMANN: bool> {
    diffuse: Vec3,
    spec: Vec3,
    nonlinear: bool,
    spec_weight: f32,
    mf: Microfacet,
    eta: f32,
    internal: f32,
    /// The transmittance toward `wo` and toward `wi`.
    to: f32,
    ti: f32,
    tables: &'a RoughPlasticTables,
}

impl<'a, const BECKMANN: bool> RoughPlasticLane<'a, BECKMANN> {
    /// `b` seen from `wo`, toward `wi` (for a sample, any: [`RoughPlasticLane::prepare`]
    /// reads its transmittance once the direction is known).
    #[inline(always)]
    #[must_use]
    pub fn new(b: &RoughPlastic<'a>, wo: Vec3, wi: Vec3) -> Self {
        let t = b.tables;
        Self {
            diffuse: b.diffuse,
            spec: b.spec,
            nonlinear: b.nonlinear,
            spec_weight: b.spec_weight,
            mf: b.mf,
            eta: t.eta,
            internal: t.internal,
            to: t.external(wo.z),
            ti: t.external(wi.z),
            tables: t,
        }
    }

    /// f(wo, wi)·|cos θi| and the density of the sample, with the transmittances read
    /// for these `wo` and `wi`.
    #[inline(always)]
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let (mf, diffuse) = (self.mf, self.diffuse);
        let h = (wo + wi).normalize();
        let d = mf.d_of::<BECKMANN>(h);
        let (f, _) = fresnel_dielectric(wo.dot(h), self.eta);
        let specular = self.spec * (f * d * mf.g_of::<BECKMANN>(wo, wi, h) / (4.0 * wo.z));
        let (to, ti) = (self.to, self.ti);
        let ri = self.internal;
        let linear = diffuse / (1.0 - ri);
        let nonlinear = diffuse / (Vec3::ONE - diffuse * ri);
        let base = Vec3::select(glam::BVec3::splat(self.nonlinear), nonlinear, linear);
        let value = specular + base * (FRAC_1_PI / (self.eta * self.eta) * wi.z * to * ti);
        let (ps, pd) = probs(to, self.spec_weight);
        let pdf = ps * mf.pdf_with_d_of::<BECKMANN>(wo, h, d) / (4.0 * wo.dot(h)) + pd * wi.z * FRAC_1_PI;
        if (wo.z <= 0.0) | (wi.z <= 0.0) {
            (Vec3::ZERO, 0.0)
        } else {
            (value, pdf)
        }
    }

    /// The sample's direction (the coating's lobe or the base's, chosen by `u`), its
    /// transmittance read into `self`: what does not vectorize.
    #[inline(always)]
    pub fn prepare(&mut self, wo: Vec3, u: f32, u2: (f32, f32)) -> Vec3 {
        let (ps, _) = probs(self.to, self.spec_weight);
        let wi = if u < ps { reflect(wo, self.mf.sample(wo, u2)) } else { cosine_hemisphere(u2) };
        self.ti = self.tables.external(wi.z);
        wi
    }

    /// The sample toward `wi` (of [`RoughPlasticLane::prepare`]), and whether there is one.
    #[inline(always)]
    #[must_use]
    pub fn sample_of(&self, wo: Vec3, wi: Vec3) -> (BsdfSample, bool) {
        let (f, pdf) = self.eval_pdf(wo, wi);
        reflection_lane(wo, wi, f, pdf)
    }

    /// The coating's lobe or the base's cosine lobe, chosen by `u`.
    #[inline(always)]
    #[must_use]
    pub fn sample(mut self, wo: Vec3, u: f32, u2: (f32, f32)) -> (BsdfSample, bool) {
        let wi = self.prepare(wo, u, u2);
        self.sample_of(wo, wi)
    }
}

/// Mitsuba's lobe probabilities for rough plastic: (specular, diffuse) from the coating's
/// transmittance toward the viewer.
#[inline(always)]
fn probs(t_o: f32, spec_weight: f32) -> (f32, f32) {
    let ps = (1.0 - t_o) * spec_weight;
    let pd = t_o * (1.0 - spec_weight);
    let s = ps + pd;
    let (a, b) = (ps / s, pd / s);
    if s > 0.0 {
        (a, b)
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
        match mf.dist {
            Distribution::Beckmann => Self::compute_of::<true>(mf, eta),
            Distribution::Ggx => Self::compute_of::<false>(mf, eta),
        }
    }

    fn compute_of<const BECKMANN: bool>(mf: &Microfacet, eta: f32) -> Self {
        use rayon::prelude::*;
        let q = gauss_legendre(128);
        // (Each cosine's two integrals apart, in parallel: 2 × 128² evaluations each,
        // 60 ms a coating on one thread; summed after, in order: the same bits.)
        let rows: Vec<(f32, f64)> = (0..RES)
            .into_par_iter()
            .map(|i| {
                let mu = (i as f32 / (RES - 1) as f32).max(1e-6);
                let wi = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
                let t = visible_integral::<BECKMANN>(mf, wi, &q, |m| {
                    let (f, cos_t) = fresnel_dielectric(wi.dot(m), eta);
                    let wt = refract(wi, m, cos_t, eta);
                    if wt.z * wi.z >= 0.0 {
                        0.0
                    } else {
                        (1.0 - f) * mf.g1_of::<BECKMANN>(wt, m)
                    }
                }) as f32;
                let r = visible_integral::<BECKMANN>(mf, wi, &q, |m| {
                    let (f, _) = fresnel_dielectric(wi.dot(m), 1.0 / eta);
                    let wr = reflect(wi, m);
                    if wr.z <= 0.0 {
                        0.0
                    } else {
                        f * mf.g1_of::<BECKMANN>(wr, m)
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
    #[inline(always)]
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
///
/// PERF: each row of nodes' values in one loop over the row (branch-free, it vectorizes),
/// then summed in order in f64 (the same bits as one node after another).
#[inline(always)]
fn visible_integral<const BECKMANN: bool>(mf: &Microfacet, wi: Vec3, q: &[(f64, f64)], g: impl Fn(Vec3) -> f32) -> f64 {
    let mut sum = 0.0f64;
    let a2 = f64::from(mf.alpha * mf.alpha);
    // (Each column's azimuth, for Beckmann's map.)
    let azimuths: Vec<(f64, f64)> = q.iter().map(|&(y, _)| (2.0 * std::f64::consts::PI * (0.5 * (y + 1.0))).sin_cos()).collect();
    let mut row = vec![0f32; q.len()];
    for &(x, wx) in q {
        let u = 0.5 * (x + 1.0);
        // tan² θm of D cos θm at u (Beckmann).
        let tan2 = -a2 * (1.0 - u).max(1e-300).ln();
        let cos = 1.0 / (1.0 + tan2).sqrt();
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        for ((value, &(y, _)), &(sp, cp)) in row.iter_mut().zip(q).zip(&azimuths) {
            *value = if BECKMANN {
                let m = Vec3::new((sin * cp) as f32, (sin * sp) as f32, cos as f32);
                let d = mf.d_of::<true>(m);
                let sample_pdf = d * m.z;
                let visible = d * mf.g1_exact_of::<true>(wi, m) * wi.dot(m).max(0.0) / wi.z;
                let v = g(m) * visible / sample_pdf;
                if sample_pdf.is_nan() || sample_pdf <= 0.0 {
                    0.0
                } else {
                    v
                }
            } else {
                g(mf.ggx_sample(wi, (u as f32, (0.5 * (y + 1.0)) as f32)))
            };
        }
        for (&value, &(_, wy)) in row.iter().zip(q) {
            let weight = 0.25 * wx * wy;
            sum += weight * f64::from(value);
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
