//! Rough plastic's coating tables (as Mitsuba's `roughplastic` precomputes them): the
//! fraction of light the rough coating transmits for 64 directions (cosines evenly spaced
//! over [0, 1]), and its internal reflectance (twice the mean over the same cosines of
//! the reflectance from inside, each times its cosine), both integrals over the visible
//! microfacet normals, here by Gauss-Legendre quadrature.

use super::microfacet::{fresnel_dielectric, gauss_legendre, reflect, refract, Microfacet};
use glam::Vec3;

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
        let q = gauss_legendre(128);
        let mut transmittance = [0.0f32; RES];
        let mut internal = 0.0f64;
        for (i, t) in transmittance.iter_mut().enumerate() {
            let mu = (i as f32 / (RES - 1) as f32).max(1e-6);
            let wi = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
            *t = visible_integral(mf, wi, &q, |m| {
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
            internal += r * f64::from(mu);
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
