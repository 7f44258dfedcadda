//! Microfacet distributions, isotropic, in the local shading frame (z the normal): the
//! Beckmann and GGX (Trowbridge-Reitz) normal distributions and Smith's shadowing after
//! Walter, Marschner, Li and Torrance, "Microfacet Models for Refraction through Rough
//! Surfaces" (EGSR 2007) — including, for Beckmann, their rational approximation of G1
//! (eq. 27), which Mitsuba also uses; GGX normals sampled in proportion to their visible
//! area (Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 2018), Beckmann
//! normals in proportion to D(m) cos θm (Walter et al., eq. 28).

use glam::Vec3;
use lucent_scene::Distribution;
use std::f32::consts::PI;

/// The least α (Mitsuba clamps there too): below, the lobes are numerically a mirror.
pub const MIN_ALPHA: f32 = 1e-4;

/// An isotropic microfacet distribution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    /// Which distribution.
    pub dist: Distribution,
    /// Roughness α (at least [`MIN_ALPHA`]).
    pub alpha: f32,
}

impl Microfacet {
    /// A distribution of roughness `alpha` (clamped to at least [`MIN_ALPHA`]).
    #[must_use]
    pub fn new(dist: Distribution, alpha: f32) -> Self {
        let alpha = if alpha.is_finite() { alpha.max(MIN_ALPHA) } else { 1.0 };
        Self { dist, alpha }
    }

    /// The density of microfacet normals `m` (per unit projected area: ∫ D cos θm = 1).
    #[must_use]
    pub fn d(&self, m: Vec3) -> f32 {
        let cos2 = m.z * m.z;
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let r = match self.dist {
            Distribution::Beckmann => {
                let tan2 = (m.x * m.x + m.y * m.y) / cos2;
                (-tan2 / a2).exp() / (PI * a2 * cos2 * cos2)
            }
            Distribution::Ggx => {
                let t = (m.x * m.x + m.y * m.y) / a2 + cos2;
                1.0 / (PI * a2 * t * t)
            }
        };
        // (As Mitsuba: values this small only make trouble downstream.)
        if r * m.z > 1e-20 && r.is_finite() {
            r
        } else {
            0.0
        }
    }

    /// Smith's masking of direction `v` by microfacets of normal `m`: zero when `v` sees
    /// the back of the facet or the facet from the other side of the surface.
    #[must_use]
    pub fn g1(&self, v: Vec3, m: Vec3) -> f32 {
        if v.dot(m) * v.z <= 0.0 {
            return 0.0;
        }
        let xy2 = v.x * v.x + v.y * v.y;
        if xy2 == 0.0 {
            return 1.0;
        }
        let tan2_alpha2 = self.alpha * self.alpha * xy2 / (v.z * v.z);
        match self.dist {
            Distribution::Beckmann => {
                let a = 1.0 / tan2_alpha2.sqrt();
                if a >= 1.6 {
                    1.0
                } else {
                    (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
                }
            }
            Distribution::Ggx => 2.0 / (1.0 + (1.0 + tan2_alpha2).sqrt()),
        }
    }

    /// The separable shadowing-masking of a pair of directions.
    #[must_use]
    pub fn g(&self, wo: Vec3, wi: Vec3, m: Vec3) -> f32 {
        self.g1(wo, m) * self.g1(wi, m)
    }

    /// A microfacet normal for direction `v` (with `v.z > 0`) from `u` in [0, 1)²: GGX's
    /// visible normals, Beckmann's D(m) cos θm.
    #[must_use]
    pub fn sample(&self, v: Vec3, u: (f32, f32)) -> Vec3 {
        let a = self.alpha;
        match self.dist {
            Distribution::Ggx => {
                // The hemisphere of a stretched (α = 1) configuration, a disk sample warped
                // toward the visible half, then unstretched (Heitz 2018, listing 1).
                let vh = Vec3::new(a * v.x, a * v.y, v.z).normalize();
                let len2 = vh.x * vh.x + vh.y * vh.y;
                let t1 = if len2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3::X };
                let t2 = vh.cross(t1);
                let r = u.0.sqrt();
                let phi = 2.0 * PI * u.1;
                let (s_phi, c_phi) = phi.sin_cos();
                let p1 = r * c_phi;
                let s = 0.5 * (1.0 + vh.z);
                let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * (r * s_phi);
                let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
                Vec3::new(a * nh.x, a * nh.y, nh.z.max(1e-6)).normalize()
            }
            Distribution::Beckmann => {
                let tan2 = -a * a * (1.0 - u.0).max(f32::MIN_POSITIVE).ln();
                let cos = 1.0 / (1.0 + tan2).sqrt();
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let (s_phi, c_phi) = (2.0 * PI * u.1).sin_cos();
                Vec3::new(sin * c_phi, sin * s_phi, cos)
            }
        }
    }

    /// The density (per solid angle of normals) with which [`Microfacet::sample`] picks `m`
    /// for direction `v` (`v.z > 0`).
    #[must_use]
    pub fn pdf(&self, v: Vec3, m: Vec3) -> f32 {
        match self.dist {
            Distribution::Ggx => {
                if v.z <= 0.0 {
                    return 0.0;
                }
                self.d(m) * self.g1(v, m) * v.dot(m).max(0.0) / v.z
            }
            Distribution::Beckmann => self.d(m) * m.z.max(0.0),
        }
    }
}

/// The unpolarised Fresnel reflectance of a dielectric interface for a direction of cosine
/// `cos_i` with the normal (negative: from inside) and relative index `eta` (inside over
/// outside). Returns the reflectance and the cosine of the refracted direction (negative
/// of the incident side's sign; zero under total internal reflection).
#[must_use]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> (f32, f32) {
    if eta == 1.0 {
        return (0.0, -cos_i);
    }
    let (eta_it, cos_abs) = if cos_i >= 0.0 { (eta, cos_i) } else { (1.0 / eta, -cos_i) };
    let cos_abs = cos_abs.min(1.0);
    // Snell: sin_t = sin_i / eta_it.
    let sin2_t = (1.0 - cos_abs * cos_abs) / (eta_it * eta_it);
    if sin2_t >= 1.0 {
        return (1.0, 0.0);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_abs - eta_it * cos_t) / (cos_abs + eta_it * cos_t);
    let rp = (eta_it * cos_abs - cos_t) / (eta_it * cos_abs + cos_t);
    let f = 0.5 * (rs * rs + rp * rp);
    (f, if cos_i >= 0.0 { -cos_t } else { cos_t })
}

/// A complex number, for conductors' Fresnel equations.
#[derive(Clone, Copy, Debug)]
struct C {
    re: f32,
    im: f32,
}

impl C {
    fn add(self, o: C) -> C {
        C { re: self.re + o.re, im: self.im + o.im }
    }
    fn sub(self, o: C) -> C {
        C { re: self.re - o.re, im: self.im - o.im }
    }
    fn mul(self, o: C) -> C {
        C { re: self.re * o.re - self.im * o.im, im: self.re * o.im + self.im * o.re }
    }
    fn div(self, o: C) -> C {
        let d = o.re * o.re + o.im * o.im;
        C { re: (self.re * o.re + self.im * o.im) / d, im: (self.im * o.re - self.re * o.im) / d }
    }
    fn norm2(self) -> f32 {
        self.re * self.re + self.im * self.im
    }
    fn sqrt(self) -> C {
        let n = self.norm2().sqrt();
        if n == 0.0 {
            return C { re: 0.0, im: 0.0 };
        }
        let re = (0.5 * (n + self.re)).max(0.0).sqrt();
        let im = (0.5 * (n - self.re)).max(0.0).sqrt();
        C { re, im: if self.im < 0.0 { -im } else { im } }
    }
}

/// The unpolarised Fresnel reflectance of a conductor of complex relative index
/// `eta + i k` for a direction of cosine `cos_i` (clamped to [0, 1]), per channel (the
/// full equations, e.g. pbrt-v4 §9.3.6).
#[must_use]
pub fn fresnel_conductor(cos_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
    let c = cos_i.clamp(0.0, 1.0);
    let one = |ch: usize| {
        let n = C { re: eta[ch], im: k[ch] };
        if n.norm2() == 0.0 {
            return 1.0;
        }
        let ci = C { re: c, im: 0.0 };
        let sin2_i = C { re: 1.0 - c * c, im: 0.0 };
        let sin2_t = sin2_i.div(n.mul(n));
        let cos_t = C { re: 1.0, im: 0.0 }.sub(sin2_t).sqrt();
        let r_parl = n.mul(ci).sub(cos_t).div(n.mul(ci).add(cos_t));
        let r_perp = ci.sub(n.mul(cos_t)).div(ci.add(n.mul(cos_t)));
        let f = 0.5 * (r_parl.norm2() + r_perp.norm2());
        if f.is_finite() {
            f.clamp(0.0, 1.0)
        } else {
            1.0
        }
    };
    Vec3::new(one(0), one(1), one(2))
}

/// Schlick's approximation of the Fresnel reflectance with reflectance `f0` at normal
/// incidence (glTF's BRDF uses it).
#[must_use]
pub fn schlick(f0: Vec3, cos: f32) -> Vec3 {
    let m = (1.0 - cos.abs()).clamp(0.0, 1.0);
    let m5 = m * m * m * m * m;
    f0 + (Vec3::ONE - f0) * m5
}

/// The diffuse Fresnel reflectance (the reflectance of a dielectric interface of relative
/// index `eta` averaged over a cosine-weighted hemisphere of directions), by the fits
/// Mitsuba uses: Egan and Hilgeman (1979) for η < 1, d'Eon and Irving ("A Quantized-
/// Diffusion Model for Rendering Translucent Materials", 2011) otherwise.
#[must_use]
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    if eta < 1.0 {
        -1.4399 * eta * eta + 0.7099 * eta + 0.6681 + 0.0636 / eta
    } else {
        let i = 1.0 / eta;
        let (i2, i3, i4, i5) = (i * i, i * i * i, i * i * i * i, i * i * i * i * i);
        0.919317 - 3.4793 * i + 6.75335 * i2 - 7.80989 * i3 + 4.98554 * i4 - 1.36881 * i5
    }
}

/// Mirror reflection of `v` about `m`.
#[inline]
#[must_use]
pub fn reflect(v: Vec3, m: Vec3) -> Vec3 {
    m * (2.0 * v.dot(m)) - v
}

/// Refraction of `v` through a facet of normal `m` (either side), given the cosine of the
/// refracted direction `cos_t` (from [`fresnel_dielectric`] of `v · m`) and the relative
/// index `eta` (inside over outside).
#[inline]
#[must_use]
pub fn refract(v: Vec3, m: Vec3, cos_t: f32, eta: f32) -> Vec3 {
    let eta_ti = if cos_t < 0.0 { 1.0 / eta } else { eta };
    m * (v.dot(m) * eta_ti + cos_t) - v * eta_ti
}

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton's method on the Legendre
/// polynomial, from the usual initial guesses).
#[must_use]
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(x) and its derivative by the three-term recurrence.
            let (mut p0, mut p1) = (1.0f64, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let p = if n == 0 {
                1.0
            } else if n == 1 {
                x
            } else {
                p1
            };
            let pm1 = if n == 1 { 1.0 } else { p0 };
            dp = n as f64 * (x * p - pm1) / (x * x - 1.0);
            let dx = p / dp;
            x -= dx;
            if dx.abs() < 1e-15 {
                break;
            }
        }
        out.push((x, 2.0 / ((1.0 - x * x) * dp * dp)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials() {
        let q = gauss_legendre(16);
        let s: f64 = q.iter().map(|(x, w)| w * x.powi(10)).sum();
        assert!((s - 2.0 / 11.0).abs() < 1e-12, "{s}");
        let s: f64 = q.iter().map(|(_, w)| w).sum();
        assert!((s - 2.0).abs() < 1e-12);
    }

    #[test]
    fn fresnel_limits() {
        // Normal incidence: ((η − 1) / (η + 1))².
        let (f, c) = fresnel_dielectric(1.0, 1.5);
        assert!((f - 0.04).abs() < 1e-6 && (c + 1.0).abs() < 1e-6);
        // Total internal reflection from inside past the critical angle.
        assert_eq!(fresnel_dielectric(-0.2, 1.5).0, 1.0);
        // A conductor of zero absorption is a dielectric.
        let fc = fresnel_conductor(0.6, Vec3::splat(1.5), Vec3::ZERO);
        assert!((fc.x - fresnel_dielectric(0.6, 1.5).0).abs() < 1e-5, "{fc}");
        // Mitsuba's "none": a perfect mirror.
        assert!((fresnel_conductor(0.3, Vec3::ZERO, Vec3::ONE) - Vec3::ONE).abs().max_element() < 1e-6);
    }

    #[test]
    fn distributions_are_normalised() {
        // ∫ D(m) cos θm dω = 1, by quadrature over θ (φ-symmetric).
        for dist in [Distribution::Beckmann, Distribution::Ggx] {
            for alpha in [0.05f32, 0.3, 1.0] {
                let mf = Microfacet::new(dist, alpha);
                let q = gauss_legendre(400);
                let s: f64 = q
                    .iter()
                    .map(|&(x, w)| {
                        // θ in [0, π/2): cos θ = (x + 1)/2 spacing in cos.
                        let c = 0.5 * (x + 1.0);
                        let s = (1.0 - c * c).max(0.0).sqrt();
                        let m = Vec3::new(s as f32, 0.0, c as f32);
                        w * 0.5 * f64::from(mf.d(m)) * c * 2.0 * std::f64::consts::PI
                    })
                    .sum();
                assert!((s - 1.0).abs() < 2e-3, "{dist:?} {alpha}: {s}");
            }
        }
    }
}
