//! Microfacet distributions, isotropic or anisotropic (α along the frame's x and y, as
//! Mitsuba's `alpha_u`, `alpha_v`), in the local shading frame (z the normal): the
//! Beckmann and GGX (Trowbridge-Reitz) normal distributions and Smith's shadowing after
//! Walter, Marschner, Li and Torrance, "Microfacet Models for Refraction through Rough
//! Surfaces" (EGSR 2007) — including, for Beckmann, their rational approximation of G1
//! (eq. 27), which Mitsuba also uses for its values; normals sampled in proportion to
//! their visible area: GGX's by Heitz, "Sampling the GGX Distribution of Visible Normals"
//! (JCGT 2018), Beckmann's by the stretch-sample-unstretch method of Heitz and d'Eon,
//! "Importance Sampling Microfacet-Based BSDFs using the Distribution of Visible Normals"
//! (EGSR 2014), the visible slope's CDF inverted by safeguarded Newton steps. The densities
//! of those samples use the exact Smith masking (the erf form for Beckmann).

use crate::lanes::{exp, pow_fast, sin_cos};
use glam::Vec3;
use lucent_scene::Distribution;
use std::f32::consts::PI;

/// The least α (Mitsuba clamps there too): below, the lobes are numerically a mirror.
pub const MIN_ALPHA: f32 = 1e-4;

/// A microfacet distribution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    /// Which distribution.
    pub dist: Distribution,
    /// Roughness α (at least [`MIN_ALPHA`]); anisotropic: along the frame's x.
    pub alpha: f32,
    /// Roughness along the frame's y: `alpha` when isotropic.
    pub alpha_y: f32,
}

/// A roughness as the distributions take it: at least [`MIN_ALPHA`], 1 when not finite.
fn clamp_alpha(alpha: f32) -> f32 {
    if alpha.is_finite() {
        alpha.max(MIN_ALPHA)
    } else {
        1.0
    }
}

impl Microfacet {
    /// A distribution of roughness `alpha` (clamped to at least [`MIN_ALPHA`]).
    #[must_use]
    pub fn new(dist: Distribution, alpha: f32) -> Self {
        let alpha = clamp_alpha(alpha);
        Self { dist, alpha, alpha_y: alpha }
    }

    /// A distribution of roughness `ax` along the frame's x (the tangent, ∂p/∂u) and `ay`
    /// along its y (each clamped as in [`Microfacet::new`]).
    #[must_use]
    pub fn anisotropic(dist: Distribution, ax: f32, ay: f32) -> Self {
        Self { dist, alpha: clamp_alpha(ax), alpha_y: clamp_alpha(ay) }
    }

    /// Whether its roughness is the same along x and y.
    #[inline]
    #[must_use]
    pub fn is_isotropic(&self) -> bool {
        self.alpha == self.alpha_y
    }

    /// The larger of its two roughnesses.
    #[inline]
    #[must_use]
    pub fn alpha_max(&self) -> f32 {
        self.alpha.max(self.alpha_y)
    }

    /// α² (x² + y²) for the projected roughness of a direction (x, y, ·): with anisotropy,
    /// αx² x² + αy² y². (Isotropic: the former arithmetic, the same bits.) Branch-free.
    #[inline(always)]
    fn alpha2_xy2(&self, x: f32, y: f32) -> f32 {
        let iso = self.alpha * self.alpha * (x * x + y * y);
        let aniso = self.alpha * self.alpha * (x * x) + self.alpha_y * self.alpha_y * (y * y);
        if self.is_isotropic() {
            iso
        } else {
            aniso
        }
    }

    /// The density of microfacet normals `m` (per unit projected area: ∫ D cos θm = 1).
    #[must_use]
    pub fn d(&self, m: Vec3) -> f32 {
        match self.dist {
            Distribution::Beckmann => self.d_of::<true>(m),
            Distribution::Ggx => self.d_of::<false>(m),
        }
    }

    /// [`Microfacet::d`] of the distribution `BECKMANN` names (the caller knows it: its
    /// lanes were packed by distribution), branch-free: a loop over lanes that calls it
    /// vectorizes, and one call gives the same bits. (So are the other `_of` forms.)
    #[inline(always)]
    #[must_use]
    pub fn d_of<const BECKMANN: bool>(&self, m: Vec3) -> f32 {
        let cos2 = m.z * m.z;
        let (ax, ay) = (self.alpha, self.alpha_y);
        let iso = self.is_isotropic();
        let a2 = ax * ax;
        let xy2 = m.x * m.x + m.y * m.y;
        // (Anisotropic: the slopes scaled by each axis's α, the normalisation π αx αy.)
        let e = (m.x / ax) * (m.x / ax) + (m.y / ay) * (m.y / ay);
        let k = if iso { PI * a2 } else { PI * ax * ay };
        let r = if BECKMANN {
            let arg = if iso { -(xy2 / cos2) / a2 } else { -e / cos2 };
            exp(arg) / (k * cos2 * cos2)
        } else {
            let t = if iso { xy2 / a2 + cos2 } else { e + cos2 };
            1.0 / (k * t * t)
        };
        // (As Mitsuba: values this small only make trouble downstream.)
        if m.z > 0.0 && r * m.z > 1e-20 && r.is_finite() {
            r
        } else {
            0.0
        }
    }

    /// Smith's masking of direction `v` by microfacets of normal `m`: zero when `v` sees
    /// the back of the facet or the facet from the other side of the surface.
    #[must_use]
    pub fn g1(&self, v: Vec3, m: Vec3) -> f32 {
        match self.dist {
            Distribution::Beckmann => self.g1_of::<true>(v, m),
            Distribution::Ggx => self.g1_of::<false>(v, m),
        }
    }

    /// [`Microfacet::g1`], branch-free (see [`Microfacet::d_of`]).
    #[inline(always)]
    #[must_use]
    pub fn g1_of<const BECKMANN: bool>(&self, v: Vec3, m: Vec3) -> f32 {
        let xy2 = v.x * v.x + v.y * v.y;
        let tan2_alpha2 = self.alpha2_xy2(v.x, v.y) / (v.z * v.z);
        let g = if BECKMANN {
            let a = 1.0 / tan2_alpha2.sqrt();
            let r = (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a);
            if a >= 1.6 {
                1.0
            } else {
                r
            }
        } else {
            2.0 / (1.0 + (1.0 + tan2_alpha2).sqrt())
        };
        if v.dot(m) * v.z <= 0.0 {
            0.0
        } else if xy2 == 0.0 {
            1.0
        } else {
            g
        }
    }

    /// [`Microfacet::g`], branch-free (see [`Microfacet::d_of`]).
    #[inline(always)]
    #[must_use]
    pub fn g_of<const BECKMANN: bool>(&self, wo: Vec3, wi: Vec3, m: Vec3) -> f32 {
        self.g1_of::<BECKMANN>(wo, m) * self.g1_of::<BECKMANN>(wi, m)
    }

    /// The separable shadowing-masking of a pair of directions.
    #[must_use]
    pub fn g(&self, wo: Vec3, wi: Vec3, m: Vec3) -> f32 {
        match self.dist {
            Distribution::Beckmann => self.g_of::<true>(wo, wi, m),
            Distribution::Ggx => self.g_of::<false>(wo, wi, m),
        }
    }

    /// A microfacet normal for direction `v` (with `v.z > 0`) from `u` in [0, 1)²: GGX's
    /// visible normals, Beckmann's D(m) cos θm.
    #[must_use]
    pub fn sample(&self, v: Vec3, u: (f32, f32)) -> Vec3 {
        match self.dist {
            Distribution::Ggx => self.ggx_sample(v, u),
            Distribution::Beckmann => {
                let vs = self.stretched(v);
                self.beckmann_from(vs, SlopeSearch::begin::<false>(vs.z, u))
            }
        }
    }

    /// The first part of Beckmann's [`Microfacet::sample`]: the visible slope's search
    /// after its first [`FIRST_STEPS`] steps, branch-free (a loop over lanes that calls it
    /// vectorizes).
    #[inline(always)]
    #[must_use]
    pub fn beckmann_start(&self, v: Vec3, u: (f32, f32)) -> SlopeSearch {
        SlopeSearch::start(self.stretched(v).z, u)
    }

    /// Direction `v` stretched to α = 1, where Beckmann's visible slopes are sampled.
    #[inline(always)]
    #[must_use]
    pub fn stretched(&self, v: Vec3) -> Vec3 {
        Vec3::new(self.alpha * v.x, self.alpha_y * v.y, v.z).normalize()
    }

    /// Beckmann's [`Microfacet::sample`] for the stretched direction `vs`
    /// ([`Microfacet::stretched`]) from its search `s` ([`Microfacet::beckmann_start`] of
    /// the same direction and numbers): the search finished (rarely more steps), then the
    /// slopes rotated to the direction's azimuth and unstretched into the normal.
    #[inline(always)]
    #[must_use]
    pub fn beckmann_from(&self, vs: Vec3, s: SlopeSearch) -> Vec3 {
        let (ax, ay) = (self.alpha, self.alpha_y);
        let sin_t = (1.0 - vs.z * vs.z).max(0.0).sqrt();
        let (cos_p, sin_p) = if sin_t > 1e-7 { (vs.x / sin_t, vs.y / sin_t) } else { (1.0, 0.0) };
        let (sx, sy) = s.finish();
        let (x, y) = ((cos_p * sx - sin_p * sy) * ax, (sin_p * sx + cos_p * sy) * ay);
        Vec3::new(-x, -y, 1.0).normalize()
    }

    /// GGX's visible normal for direction `v` and `u` (see [`Microfacet::sample`]),
    /// branch-free: the hemisphere of a stretched (α = 1) configuration, a disk sample
    /// warped toward the visible half, then unstretched (Heitz 2018, listing 1), the
    /// angle's sine and cosine by [`crate::lanes::sin_cos`].
    #[inline(always)]
    #[must_use]
    pub fn ggx_sample(&self, v: Vec3, u: (f32, f32)) -> Vec3 {
        let (ax, ay) = (self.alpha, self.alpha_y);
        let vh = Vec3::new(ax * v.x, ay * v.y, v.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let inv = 1.0 / len2.sqrt();
        let t1 = if len2 > 0.0 { Vec3::new(-vh.y * inv, vh.x * inv, 0.0) } else { Vec3::X };
        let t2 = vh.cross(t1);
        let r = u.0.sqrt();
        let (s_phi, c_phi) = sin_cos(2.0 * PI * u.1);
        let p1 = r * c_phi;
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * (r * s_phi);
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        Vec3::new(ax * nh.x, ay * nh.y, nh.z.max(1e-6)).normalize()
    }

    /// The density (per solid angle of normals) with which [`Microfacet::sample`] picks `m`
    /// for direction `v` (`v.z > 0`): D(m) G1(v, m) ⟨v, m⟩ / cos θv, with the exact G1.
    #[must_use]
    pub fn pdf(&self, v: Vec3, m: Vec3) -> f32 {
        self.pdf_with_d(v, m, self.d(m))
    }

    /// [`Microfacet::pdf`] with `d` = D(m) already at hand (a BSDF's value and density
    /// computed together, the same bits as apart).
    #[inline]
    #[must_use]
    pub fn pdf_with_d(&self, v: Vec3, m: Vec3, d: f32) -> f32 {
        match self.dist {
            Distribution::Beckmann => self.pdf_with_d_of::<true>(v, m, d),
            Distribution::Ggx => self.pdf_with_d_of::<false>(v, m, d),
        }
    }

    /// [`Microfacet::pdf_with_d`], branch-free (see [`Microfacet::d_of`]).
    #[inline(always)]
    #[must_use]
    pub fn pdf_with_d_of<const BECKMANN: bool>(&self, v: Vec3, m: Vec3, d: f32) -> f32 {
        let g1 = if BECKMANN { self.g1_exact_of::<true>(v, m) } else { self.g1_of::<false>(v, m) };
        let p = d * g1 * v.dot(m).max(0.0) / v.z;
        if v.z <= 0.0 {
            0.0
        } else {
            p
        }
    }

    /// Smith's masking without approximation (for Beckmann, 2 / (1 + erf a + e^(−a²) /
    /// (a √π)) with a = 1 / (α tan θ); GGX's is exact already).
    #[must_use]
    pub fn g1_exact(&self, v: Vec3, m: Vec3) -> f32 {
        match self.dist {
            Distribution::Beckmann => self.g1_exact_of::<true>(v, m),
            Distribution::Ggx => self.g1_of::<false>(v, m),
        }
    }

    /// [`Microfacet::g1_exact`], branch-free (see [`Microfacet::d_of`]).
    #[inline(always)]
    #[must_use]
    pub fn g1_exact_of<const BECKMANN: bool>(&self, v: Vec3, m: Vec3) -> f32 {
        if !BECKMANN {
            return self.g1_of::<false>(v, m);
        }
        let xy2 = v.x * v.x + v.y * v.y;
        let a_iso = v.z.abs() / (self.alpha * xy2.sqrt());
        let a_aniso = v.z.abs() / self.alpha2_xy2(v.x, v.y).sqrt();
        let a = if self.is_isotropic() { a_iso } else { a_aniso };
        let lambda = 0.5 * (exp(-a * a) / (a * std::f32::consts::PI.sqrt()) - erfc(a));
        let g = 1.0 / (1.0 + lambda);
        if v.dot(m) * v.z <= 0.0 {
            0.0
        } else if xy2 == 0.0 {
            1.0
        } else {
            g
        }
    }
}

/// Slopes (x, y) of a Beckmann surface of α = 1 seen from a direction of cosine `cos_t`
/// (azimuth 0), distributed as the visible slopes are: y is independent of x and normal
/// (erf⁻¹), x has the density e^(−x²) (1 − x tan θ) on x < cot θ.
///
/// x is found as Jakob does it ("An Improved Visible Normal Sampling Routine for the
/// Beckmann Distribution", tech. report, ETH Zürich, 2014): in the variable b = erf x,
/// where the CDF is C(b) ∝ 1 + b + (tan θ / √π) e^(−x²) and its derivative is simply
/// ∝ 1 − x tan θ, by Newton steps kept inside a bisection bracket, from the report's
/// fitted first guess b₀ = c − (1 + c)(1 − u)^p(θ), c = erf(cot θ). All in f32: two or
/// three steps where the former f64 search in x took up to 40 with erf and exp each.
///
/// (The search is a [`SlopeSearch`]: [`Microfacet::sample`] takes its steps one by one
/// and stops at the slope; the lane path tracer's Beckmann conductors take the first
/// [`FIRST_STEPS`] on lanes, branch-free ([`SlopeSearch::start`]), then the rest one by
/// one: the same numbers. This whole is for the tests.)
#[cfg(test)]
fn beckmann_visible_slopes(cos_t: f32, u: (f32, f32)) -> (f32, f32) {
    SlopeSearch::begin::<false>(cos_t, u).finish()
}

/// Steps of the slope search taken branch-free, for every lane ([`SlopeSearch::start`]):
/// from the fitted first guess, 90% of searches end after three, the rest after two or
/// four (measured over a 200 × 200 grid of cos θ and u); a search still open takes its
/// further steps one by one ([`SlopeSearch::finish`]).
/// ([`SlopeSearch::start`] writes its steps out.)
pub const FIRST_STEPS: usize = 4;

/// Most steps of the slope search.
pub const MAX_STEPS: usize = 16;

/// The search for Beckmann's visible slope x (see `beckmann_visible_slopes`): its
/// bracket `[lo, hi]` and guess `b` in b = erf x, the CDF's constants, and the slope once
/// found.
#[derive(Clone, Copy, Debug, Default)]
pub struct SlopeSearch {
    lo: f32,
    hi: f32,
    b: f32,
    norm: f32,
    k: f32,
    tan_t: f32,
    u0: f32,
    x: f32,
    found: bool,
    /// The other slope, y = erf⁻¹(2 u₁ − 1).
    y: f32,
    /// Steps taken.
    taken: f32,
}

impl SlopeSearch {
    /// The search for a direction of cosine `cos_t` and the numbers `u`, after its first
    /// [`FIRST_STEPS`] steps, branch-free (for a loop over lanes).
    #[inline(always)]
    #[must_use]
    pub fn start(cos_t: f32, u: (f32, f32)) -> Self {
        let mut s = Self::begin::<true>(cos_t, u);
        // PERF: written out, not as a loop: a loop of four large steps stays a loop, and
        // a loop over lanes around it is then no innermost loop, which LLVM does not
        // vectorize.
        s.step::<true>();
        s.step::<true>();
        s.step::<true>();
        s.step::<true>();
        s
    }

    /// The search before its first step, with `y` (`LANES`: branch-free; either way the
    /// same numbers).
    #[inline(always)]
    #[must_use]
    pub fn begin<const LANES: bool>(cos_t: f32, u: (f32, f32)) -> Self {
        let c = cos_t.clamp(1e-6, 1.0);
        let tan_t = (1.0 - c * c).max(0.0).sqrt() / c;
        let u0 = u.0.clamp(1e-6, 1.0 - 1e-6);
        // The bracket, in b = erf x: the support ends at cot θ (the slope seen edge-on).
        let edge = tan_t > 1e-7;
        let hi = if edge { erf(1.0 / tan_t) } else { 1.0 };
        let k = tan_t * FRAC_1_SQRT_PI;
        let cot2 = if edge { 1.0 / (tan_t * tan_t) } else { f32::INFINITY };
        let norm = 1.0 / (1.0 + hi + k * exp(-cot2));
        // (A first guess only: θ by Abramowitz and Stegun's 4.4.45, within 7e-5, and the
        // power by `pow_fast`'s short series (1 − u in (0, 1), the exponent in [0.44, 1]);
        // Newton's steps correct either.)
        let theta = (1.0 - c).max(0.0).sqrt() * (1.570_728_8 + c * (-0.212_114_4 + c * (0.074_261 - 0.018_729_3 * c)));
        let fit = 1.0 + theta * (-0.876 + theta * (0.4265 - 0.0594 * theta));
        let b = hi - (1.0 + hi) * pow_fast(1.0 - u0, fit);
        let y = erfinv_of::<LANES>(2.0 * u.1.clamp(1e-6, 1.0 - 1e-6) - 1.0);
        Self { lo: -1.0, hi, b, norm, k, tan_t, u0, x: 0.0, found: false, y, taken: 0.0 }
    }

    /// The search as eleven numbers (for rows of lanes; `found` as 0 or 1).
    #[inline(always)]
    #[must_use]
    pub fn to_row(self) -> [f32; 11] {
        [self.lo, self.hi, self.b, self.norm, self.k, self.tan_t, self.u0, self.x, if self.found { 1.0 } else { 0.0 }, self.y, self.taken]
    }

    /// [`SlopeSearch::to_row`] undone.
    #[inline(always)]
    #[must_use]
    pub fn from_row(r: [f32; 11]) -> Self {
        let [lo, hi, b, norm, k, tan_t, u0, x, found, y, taken] = r;
        Self { lo, hi, b, norm, k, tan_t, u0, x, found: found != 0.0, y, taken }
    }

    /// One Newton step kept inside the bracket (bisection where Newton leaves it or gives
    /// NaN), without branches (`LANES`: erf⁻¹'s too; either way the same numbers). A step
    /// after the slope is found changes nothing, so a search that stops there ends as one
    /// that takes them.
    #[inline(always)]
    fn step<const LANES: bool>(&mut self) {
        let Self { lo, hi, b, norm, k, tan_t, u0, .. } = *self;
        // (Written so that a NaN also falls back to bisection.)
        let b = if b >= lo && b <= hi { b } else { 0.5 * (lo + hi) };
        let x = erfinv_of::<LANES>(b);
        let value = norm * (1.0 + b + k * exp(-x * x)) - u0;
        let hit = value.abs() < 1e-6;
        let above = value > 0.0;
        let slope = norm * (1.0 - x * tan_t);
        let next = b - value / slope;
        let go = !self.found & !hit;
        self.x = if !self.found & hit { x } else { self.x };
        self.found |= hit;
        self.hi = if go & above { b } else { self.hi };
        self.lo = if go & !above { b } else { self.lo };
        self.b = if go { next } else { self.b };
        self.taken += 1.0;
    }

    /// The slopes (x, y): the search's further steps while it is open (up to
    /// [`MAX_STEPS`] in all).
    #[inline(always)]
    #[must_use]
    pub fn finish(mut self) -> (f32, f32) {
        while !self.found && self.taken < MAX_STEPS as f32 {
            self.step::<false>();
        }
        (if self.found { self.x } else { erfinv(self.b) }, self.y)
    }
}

/// 1 / √π.
const FRAC_1_SQRT_PI: f32 = 0.564_189_6;

/// erfc in f32 (for the exact Beckmann masking and its sampling), by the Chebyshev fit of
/// Numerical Recipes (§6.2, `erfcc`: fractional error below 1.2 × 10⁻⁷ everywhere).
// (The fit's coefficients as published, past f32's digits.)
#[allow(clippy::excessive_precision)]
#[inline(always)]
fn erfc(x: f32) -> f32 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let mut p = 0.170_872_77f32;
    for c in
        [-0.822_152_23, 1.488_515_87, -1.135_203_98, 0.278_868_07, -0.186_288_06, 0.096_784_18, 0.374_091_96, 1.000_023_68, -1.265_512_23]
    {
        p = c + t * p;
    }
    let r = t * exp(-z * z + p);
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// erf in f32, from [`erfc`].
#[inline(always)]
fn erf(x: f32) -> f32 {
    1.0 - erfc(x)
}

/// erf⁻¹ in f32 by Giles's approximation ("Approximating the erfinv function", GPU
/// Computing Gems, 2011; single-precision accuracy), one by one: the fit its argument
/// needs (the same numbers as [`erfinv_of`]).
#[inline(always)]
fn erfinv(y: f32) -> f32 {
    erfinv_of::<false>(y)
}

/// erf⁻¹ (see [`erfinv`]); with `LANES` branch-free (both fits made, one selected), else
/// only the fit needed: the same numbers either way. The logarithm by
/// [`crate::lanes::ln`].
// (The fit's coefficients as published, past f32's digits.)
#[allow(clippy::excessive_precision)]
#[inline(always)]
fn erfinv_of<const LANES: bool>(y: f32) -> f32 {
    let y = y.clamp(-1.0 + 1e-7, 1.0 - 1e-7);
    let w = -crate::lanes::ln((1.0 - y) * (1.0 + y));
    let near = |w: f32| {
        let w = w - 2.5;
        let mut p = 2.810_226_36e-08f32;
        for c in [
            3.432_739_39e-07,
            -3.523_387_7e-06,
            -4.391_506_54e-06,
            0.000_218_580_87,
            -0.001_253_725_03,
            -0.004_177_681_64,
            0.246_640_727,
            1.501_409_41,
        ] {
            p = c + p * w;
        }
        p
    };
    let far = |w: f32| {
        let w = w.sqrt() - 3.0;
        let mut p = -0.000_200_214_257f32;
        for c in [
            0.000_100_950_558,
            0.001_349_343_22,
            -0.003_673_428_44,
            0.005_739_507_73,
            -0.007_622_461_3,
            0.009_438_870_47,
            1.001_674_06,
            2.832_976_82,
        ] {
            p = c + p * w;
        }
        p
    };
    if LANES {
        let (a, b) = (near(w), far(w));
        (if w < 5.0 { a } else { b }) * y
    } else if w < 5.0 {
        near(w) * y
    } else {
        far(w) * y
    }
}

/// The unpolarised Fresnel reflectance of a dielectric interface for a direction of cosine
/// `cos_i` with the normal (negative: from inside) and relative index `eta` (inside over
/// outside). Returns the reflectance and the cosine of the refracted direction (negative
/// of the incident side's sign; zero under total internal reflection).
#[must_use]
#[inline(always)]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> (f32, f32) {
    // (Branch-free, so that loops over lanes that call it vectorize.)
    let outside = cos_i >= 0.0;
    let eta_it = if outside { eta } else { 1.0 / eta };
    let cos_abs = if outside { cos_i } else { -cos_i }.min(1.0);
    // Snell: sin_t = sin_i / eta_it.
    let sin2_t = (1.0 - cos_abs * cos_abs) / (eta_it * eta_it);
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_abs - eta_it * cos_t) / (cos_abs + eta_it * cos_t);
    let rp = (eta_it * cos_abs - cos_t) / (eta_it * cos_abs + cos_t);
    let f = 0.5 * (rs * rs + rp * rp);
    let signed = if outside { -cos_t } else { cos_t };
    if eta == 1.0 {
        (0.0, -cos_i)
    } else if sin2_t >= 1.0 {
        (1.0, 0.0)
    } else {
        (f, signed)
    }
}

/// The unpolarised Fresnel reflectance of a conductor of complex relative index
/// `eta + i k` for a direction of cosine `cos_i` (clamped to [0, 1]), per channel: the
/// full equations in real arithmetic (the form of Lagarde's "Memo on Fresnel equations",
/// 2013, which pbrt-v3's `FrConductor` and Mitsuba 3's `fresnel_conductor` use: a² + b²,
/// a, then r_s and r_p), two square roots and two divisions a channel where the complex
/// form took nine and twelve. Tested against the complex form.
#[must_use]
#[inline(always)]
pub fn fresnel_conductor(cos_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
    let c = cos_i.clamp(0.0, 1.0);
    let (c2, s2) = (c * c, 1.0 - c * c);
    let s4 = s2 * s2;
    let one = |n: f32, k: f32| {
        let t1 = n * n - k * k - s2;
        let a2_b2 = (t1 * t1 + 4.0 * n * n * k * k).max(0.0).sqrt();
        let a = (0.5 * (a2_b2 + t1)).max(0.0).sqrt();
        let (term1, term2) = (a2_b2 + c2, 2.0 * c * a);
        let r_s = (term1 - term2) / (term1 + term2);
        let (term3, term4) = (a2_b2 * c2 + s4, term2 * s2);
        let r_p = r_s * (term3 - term4) / (term3 + term4);
        let f = 0.5 * (r_s + r_p);
        if f.is_finite() && n * n + k * k > 0.0 {
            f.clamp(0.0, 1.0)
        } else {
            1.0
        }
    };
    Vec3::new(one(eta.x, k.x), one(eta.y, k.y), one(eta.z, k.z))
}

/// Schlick's approximation of the Fresnel reflectance with reflectance `f0` at normal
/// incidence (glTF's BRDF uses it).
#[inline]
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
#[inline(always)]
#[must_use]
pub fn reflect(v: Vec3, m: Vec3) -> Vec3 {
    m * (2.0 * v.dot(m)) - v
}

/// Refraction of `v` through a facet of normal `m` (either side), given the cosine of the
/// refracted direction `cos_t` (from [`fresnel_dielectric`] of `v · m`) and the relative
/// index `eta` (inside over outside).
#[inline(always)]
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
    fn erf_and_its_inverse() {
        for (x, want) in [
            (0.0, 0.0),
            (0.5, 0.520_499_877_813_046_5),
            (1.0, 0.842_700_792_949_714_9),
            (2.0, 0.995_322_265_018_952_7),
            (3.0, 0.999_977_909_503_001_4),
        ] {
            let (x, want) = (x as f32, want as f32);
            assert!((erf(x) - want).abs() < 3e-7, "erf {x}: {}", erf(x));
            assert!((erf(-x) + want).abs() < 3e-7);
        }
        // erfc's fractional error, far into the tail.
        assert!((erfc(4.0) / 1.541_725_8e-8 - 1.0).abs() < 1e-6, "{}", erfc(4.0));
        for y in [-0.999f32, -0.5, 0.0, 0.3, 0.9, 0.99999] {
            assert!((erf(erfinv(y)) - y).abs() < 1e-6, "{y}: {}", erf(erfinv(y)));
        }
    }

    #[test]
    fn beckmann_visible_normals_have_their_density() {
        // The sampled normals' histogram over cos θm against pdf() integrated (the
        // chi-square tests in tests/bsdf.rs cover whole BSDFs).
        let mf = Microfacet::new(Distribution::Beckmann, 0.3);
        let v = Vec3::new(0.8, 0.0, 0.6);
        let n = 200_000;
        let mut mean_vm = 0.0f64;
        for i in 0..n {
            let u = ((i as f32 + 0.5) / n as f32, ((i as u64 * 2_654_435_761) % n as u64) as f32 / n as f32);
            let m = mf.sample(v, u);
            assert!(m.is_finite() && m.z > 0.0);
            mean_vm += f64::from(v.dot(m));
        }
        // The mean of ⟨v, m⟩ over the samples against its integral with pdf() over the
        // hemisphere (quadrature).
        let q = gauss_legendre(200);
        let mut by_pdf = 0.0f64;
        for &(a, wa) in &q {
            for &(b, wb) in &q {
                let ct = 0.5 * (a + 1.0);
                let ph = std::f64::consts::PI * (b + 1.0);
                let st = (1.0 - ct * ct).sqrt();
                let m = Vec3::new((st * ph.cos()) as f32, (st * ph.sin()) as f32, ct as f32);
                by_pdf += wa * wb * 0.5 * std::f64::consts::PI * f64::from(mf.pdf(v, m) * v.dot(m));
            }
        }
        let mean = mean_vm / f64::from(n);
        assert!((mean - by_pdf).abs() < 2e-3, "sampled mean {mean}, by the density {by_pdf}");
    }

    #[test]
    fn beckmann_slopes_invert_their_cdf() {
        // C(x) of the visible slope x (its density e^(−x²)(1 − x tan θ) on x < cot θ, by
        // quadrature in f64) at the sampled x is u, for views from normal to grazing.
        let q = gauss_legendre(64);
        let integral = |lo: f64, hi: f64, tan_t: f64| -> f64 {
            // (Split in pieces: the integrand is smooth, the range up to 16 wide.)
            let pieces = 32;
            let h = (hi - lo) / f64::from(pieces);
            (0..pieces)
                .map(|k| {
                    let (a, b) = (lo + h * f64::from(k), lo + h * f64::from(k + 1));
                    q.iter()
                        .map(|&(x, w)| {
                            let s = 0.5 * (a + b) + 0.5 * (b - a) * x;
                            0.5 * (b - a) * w * (-s * s).exp() * (1.0 - s * tan_t)
                        })
                        .sum::<f64>()
                })
                .sum()
        };
        for cos_t in [1.0f32, 0.9, 0.6, 0.3, 0.1, 0.02] {
            let c = f64::from(cos_t);
            let tan_t = (1.0 - c * c).max(0.0).sqrt() / c;
            let end = if tan_t > 1e-9 { (1.0 / tan_t).min(8.0) } else { 8.0 };
            let total = integral(-8.0, end, tan_t);
            for u in [0.001f32, 0.05, 0.3, 0.5, 0.77, 0.95, 0.999] {
                let (x, y) = beckmann_visible_slopes(cos_t, (u, u));
                let cdf = integral(-8.0, f64::from(x), tan_t) / total;
                assert!((cdf - f64::from(u)).abs() < 2e-5, "cos {cos_t}, u {u}: x {x}, C(x) {cdf}");
                // y is normal: erf(y) = 2u − 1.
                assert!((erf(y) - (2.0 * u - 1.0)).abs() < 2e-6, "y {y}");
            }
        }
    }

    /// The slope search's first steps on lanes (branch-free, both of erf⁻¹'s fits made)
    /// and then the rest give the numbers of the search taken step by step, bit for bit.
    #[test]
    fn slope_search_on_lanes_is_the_search_step_by_step() {
        for i in 0..300 {
            let cos_t = (i as f32 + 0.5) / 300.0;
            for j in 0..300 {
                let u = ((j as f32 + 0.5) / 300.0, ((j * 7 + i) % 300) as f32 / 300.0);
                let started = SlopeSearch::start(cos_t, u);
                assert_eq!(started.taken, FIRST_STEPS as f32);
                let (a, b) = (started.finish(), SlopeSearch::begin::<false>(cos_t, u).finish());
                assert_eq!((a.0.to_bits(), a.1.to_bits()), (b.0.to_bits(), b.1.to_bits()), "cos {cos_t}, u {u:?}");
            }
        }
    }

    #[test]
    fn gauss_legendre_integrates_polynomials() {
        let q = gauss_legendre(16);
        let s: f64 = q.iter().map(|(x, w)| w * x.powi(10)).sum();
        assert!((s - 2.0 / 11.0).abs() < 1e-12, "{s}");
        let s: f64 = q.iter().map(|(_, w)| w).sum();
        assert!((s - 2.0).abs() < 1e-12);
    }

    /// Complex numbers, for the reference form of the conductor's Fresnel term.
    #[derive(Clone, Copy)]
    struct C {
        re: f64,
        im: f64,
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
        fn norm2(self) -> f64 {
            self.re * self.re + self.im * self.im
        }
        fn sqrt(self) -> C {
            let n = self.norm2().sqrt();
            let re = (0.5 * (n + self.re)).max(0.0).sqrt();
            let im = (0.5 * (n - self.re)).max(0.0).sqrt();
            C { re, im: if self.im < 0.0 { -im } else { im } }
        }
    }

    /// The conductor's reflectance from the complex Fresnel equations (Snell's law with a
    /// complex index, r_parallel and r_perpendicular), in f64.
    fn fresnel_complex(c: f64, eta: f64, k: f64) -> f64 {
        let n = C { re: eta, im: k };
        let ci = C { re: c, im: 0.0 };
        let sin2_t = C { re: 1.0 - c * c, im: 0.0 }.div(n.mul(n));
        let cos_t = C { re: 1.0, im: 0.0 }.sub(sin2_t).sqrt();
        let r_parl = n.mul(ci).sub(cos_t).div(n.mul(ci).add(cos_t));
        let r_perp = ci.sub(n.mul(cos_t)).div(ci.add(n.mul(cos_t)));
        0.5 * (r_parl.norm2() + r_perp.norm2())
    }

    #[test]
    fn conductor_fresnel_is_the_complex_equations() {
        for &(eta, k) in &[(0.2f32, 3.9f32), (0.27, 2.78), (1.1, 2.6), (1.5, 0.0), (2.9, 3.1), (0.05, 1.0), (0.9, 7.5), (3.5, 0.2)] {
            for i in 0..=200 {
                let c = i as f32 / 200.0;
                let got = fresnel_conductor(c, Vec3::splat(eta), Vec3::splat(k)).x;
                let want = fresnel_complex(f64::from(c), f64::from(eta), f64::from(k));
                assert!((f64::from(got) - want).abs() < 2e-5, "η {eta}, k {k}, cos {c}: {got} against {want}");
            }
        }
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
    fn anisotropic_distributions_are_normalised_and_reduce_to_isotropic() {
        // ∫ D(m) cos θm dω = 1 over θ and φ (Gauss-Legendre in cos θ and φ).
        let q = gauss_legendre(200);
        for dist in [Distribution::Beckmann, Distribution::Ggx] {
            for (ax, ay) in [(0.05f32, 0.3f32), (0.4, 0.1), (0.2, 0.8)] {
                let mf = Microfacet::anisotropic(dist, ax, ay);
                assert!(!mf.is_isotropic());
                let mut s = 0.0f64;
                for &(a, wa) in &q {
                    for &(b, wb) in &q {
                        let c = 0.5 * (a + 1.0);
                        let ph = std::f64::consts::PI * (b + 1.0);
                        let st = (1.0 - c * c).max(0.0).sqrt();
                        let m = Vec3::new((st * ph.cos()) as f32, (st * ph.sin()) as f32, c as f32);
                        s += wa * wb * 0.5 * std::f64::consts::PI * f64::from(mf.d(m)) * c;
                    }
                }
                assert!((s - 1.0).abs() < 5e-3, "{dist:?} ({ax}, {ay}): {s}");
            }
            // Equal roughnesses are the isotropic distribution, bit for bit.
            let (iso, same) = (Microfacet::new(dist, 0.3), Microfacet::anisotropic(dist, 0.3, 0.3));
            assert_eq!(iso, same);
            let (v, m) = (Vec3::new(0.3, -0.5, 0.81).normalize(), Vec3::new(0.1, 0.2, 0.97).normalize());
            assert_eq!(iso.pdf(v, m).to_bits(), same.pdf(v, m).to_bits());
        }
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
