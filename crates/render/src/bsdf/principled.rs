//! Mitsuba 3's `principled` BSDF: Burley's "Physically Based Shading at Disney" (SIGGRAPH
//! 2012 course) and "Extending the Disney BRDF to a BSDF with Integrated Subsurface
//! Scattering" (2015), in the form Mitsuba 3.9.1 gives them, which is what scenes exported
//! for Mitsuba (Blender's exporter among them) expect:
//! - a diffuse lobe with Burley's retro-reflection, blended toward Hanrahan-Krueger's fake
//!   subsurface by `flatness`, and a sheen lobe;
//! - a main GGX lobe (anisotropic by `anisotropic`) whose Fresnel term mixes the
//!   dielectric's exact one with Schlick's for the metallic and tinted parts, and a rough
//!   dielectric transmission lobe through the same facets (`spec_trans`);
//! - a clearcoat of Burley's GTR1 distribution (Schlick's Fresnel, masking of GGX with
//!   α = 0.25), its weight and masking as Mitsuba writes them.
//!
//! Sampled as Mitsuba samples it: a visible GGX facet, then a lobe chosen with
//! probabilities that depend on its Fresnel term, the sample's weight the whole value over
//! [`Principled::pdf`] (Mitsuba's density: the lobes' probabilities at the half vector).
//! Conventions as the other BSDFs: `wo` toward the viewer, `wi` toward the light, in the
//! shading frame; values are f·|cos θi|.

use super::microfacet::{fresnel_dielectric, reflect, refract, Microfacet};
use super::sample::BsdfSample;
use crate::color::luminance;
use crate::lanes::{exp, sin_cos};
use crate::sampling::cosine_hemisphere;
use glam::Vec3;
use lucent_scene::PrincipledLobes;
use std::f32::consts::{FRAC_1_PI, PI};

/// What a principled BSDF's value and density at a pair of directions share: the half
/// vector, the relative index along the path, whether it is a reflection, the cosines of
/// both directions with the half vector, its dielectric Fresnel term and D.
#[derive(Clone, Copy)]
struct At {
    wh: Vec3,
    eta_path: f32,
    reflect: bool,
    oh: f32,
    ih: f32,
    f: f32,
    d: f32,
}

/// The principled BSDF at one surface point (its textures looked up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Principled {
    /// Base colour.
    pub base: Vec3,
    /// Roughness (for the diffuse lobe's retro-reflection; the GGX lobe's α is in `mf`).
    pub roughness: f32,
    /// Metallic weight (0 when its lobe is off).
    pub metallic: f32,
    /// Transmission weight (0 when off).
    pub spec_trans: f32,
    /// Tint of the dielectric reflection.
    pub spec_tint: f32,
    /// Sheen weight.
    pub sheen: f32,
    /// Tint of the sheen.
    pub sheen_tint: f32,
    /// Fake subsurface blend.
    pub flatness: f32,
    /// Clearcoat weight.
    pub clearcoat: f32,
    /// The clearcoat's GTR1 α.
    pub cc_alpha: f32,
    /// ln α² of the clearcoat's α (GTR1's normalisation; see [`Principled::cc_ln_of`]).
    pub cc_ln: f32,
    /// The main lobes' GGX distribution.
    pub mf: Microfacet,
    /// Relative index.
    pub eta: f32,
    /// Sampling rates: diffuse, main specular, clearcoat.
    pub rates: [f32; 3],
    /// Which lobes are on.
    pub has: PrincipledLobes,
}

/// Schlick's weight (1 − c)⁵, c clamped to [0, 1].
#[inline(always)]
fn schlick_weight(c: f32) -> f32 {
    let m = (1.0 - c).clamp(0.0, 1.0);
    (m * m) * (m * m) * m
}

/// a (1 − t) + b t.
#[inline(always)]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a * (1.0 - t) + b * t
}

/// Schlick's Fresnel term of reflectance `r0` at normal incidence, for a direction of
/// cosine `cos_i` with the facet (negative: from inside), with the refracted angle's
/// weight when the light comes from the denser side, as Mitsuba's `calc_schlick`.
#[inline(always)]
fn schlick(r0: Vec3, cos_i: f32, eta: f32) -> Vec3 {
    let outside = cos_i >= 0.0;
    let (eta_it, eta_ti) = if outside { (eta, 1.0 / eta) } else { (1.0 / eta, eta) };
    let cos_t = (1.0 - (1.0 - cos_i * cos_i) * (eta_ti * eta_ti)).max(0.0).sqrt();
    let w = if eta_it > 1.0 { schlick_weight(cos_i.abs()) } else { schlick_weight(cos_t) };
    Vec3::splat(w) * (Vec3::ONE - r0) + r0
}

/// Whether the facet `m` and the macro surface agree on the sides of `wo` and `wi`
/// (`reflection`: both on the facet's viewer side, else `wi` beyond it).
#[inline(always)]
fn facet_agrees(m: Vec3, wo: Vec3, wi: Vec3, cos_o: f32, reflection: bool) -> bool {
    let m = if cos_o < 0.0 { -m } else { m };
    wo.dot(m) > 0.0 && if reflection { wi.dot(m) > 0.0 } else { wi.dot(m) < 0.0 }
}

/// Smith's masking of GGX of roughness `alpha` (the clearcoat's, isotropic).
#[inline(always)]
fn smith_ggx1(v: Vec3, m: Vec3, alpha: f32) -> f32 {
    let c2 = v.z * v.z;
    let tan2 = (1.0 - c2) / c2;
    let g = 2.0 / (1.0 + (1.0 + alpha * alpha * tan2).sqrt());
    if v.dot(m) * v.z <= 0.0 {
        0.0
    } else if v.z == 1.0 {
        1.0
    } else {
        g
    }
}

/// Burley's GTR1 distribution of roughness `alpha`: D(m); `ln_a2` is ln α² (made once
/// per surface point: the logarithm is a library call, which a loop over lanes cannot
/// vectorize).
#[inline(always)]
fn gtr1(m: Vec3, alpha: f32, ln_a2: f32) -> f32 {
    let a2 = alpha * alpha;
    let r = (a2 - 1.0) / (PI * ln_a2 * (1.0 + (a2 - 1.0) * m.z * m.z));
    if r * m.z > 1e-20 {
        r
    } else {
        0.0
    }
}

/// A GTR1 normal drawn with density D(m) cos θm; `ln_a2` is ln α². (α^(2(1 − u)) as
/// e^((1 − u) ln α²) by [`crate::lanes::exp`], branch-free, where a library `powf` kept a
/// loop over lanes scalar.)
#[inline(always)]
fn gtr1_sample(u: (f32, f32), alpha: f32, ln_a2: f32) -> Vec3 {
    let (sin_phi, cos_phi) = sin_cos(2.0 * PI * u.0);
    let a2 = alpha * alpha;
    let cos2 = (1.0 - exp((1.0 - u.1) * ln_a2)) / (1.0 - a2);
    let sin_t = (1.0 - cos2).max(0.0).sqrt();
    Vec3::new(cos_phi * sin_t, sin_phi * sin_t, cos2.max(0.0).sqrt())
}

impl Principled {
    /// The value of [`Principled::cc_ln`] for a clearcoat of GTR1 α `cc_alpha`.
    #[must_use]
    pub fn cc_ln_of(cc_alpha: f32) -> f32 {
        (cc_alpha * cc_alpha).ln()
    }

    /// The weights of the reflecting (diffuse) and transmitting major lobes.
    #[inline(always)]
    fn weights(&self) -> (f32, f32) {
        let brdf = (1.0 - self.metallic) * (1.0 - self.spec_trans);
        let bsdf = if self.has.spec_trans { (1.0 - self.metallic) * self.spec_trans } else { 0.0 };
        (brdf, bsdf)
    }

    /// The lobes' sampling probabilities (main reflection, transmission, clearcoat,
    /// diffuse) for the dielectric Fresnel term `f`, normalised.
    #[inline(always)]
    fn probabilities(&self, front: bool, f: f32) -> [f32; 4] {
        let (brdf, bsdf) = self.weights();
        let [diff_rate, spec_rate, cc_rate] = self.rates;
        let reflect = if front { spec_rate * (1.0 - bsdf * (1.0 - f)) } else { f };
        let trans = if front { spec_rate * bsdf * (1.0 - f) } else { 1.0 - f };
        let trans = if self.has.spec_trans { trans } else { 0.0 };
        let cc = if self.has.clearcoat && front { 0.25 * self.clearcoat * cc_rate } else { 0.0 };
        let diffuse = if front { brdf * diff_rate } else { 0.0 };
        let rcp = 1.0 / (reflect + trans + cc + diffuse);
        [reflect * rcp, trans * rcp, cc * rcp, diffuse * rcp]
    }

    /// The half vector of `wo` and `wi` (of a refraction when they lie on opposite sides),
    /// turned up, and the relative index along the path.
    #[inline(always)]
    fn half(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32, bool) {
        let front = wo.z > 0.0;
        let eta_path = if front { self.eta } else { 1.0 / self.eta };
        let reflect = wo.z * wi.z > 0.0;
        let h = (wo + wi * if reflect { 1.0 } else { eta_path }).normalize();
        (if h.z < 0.0 { -h } else { h }, eta_path, reflect)
    }

    /// The base colour's hue: the base over its luminance (white for a black base), which
    /// the tinted specular and sheen lobes take.
    #[inline(always)]
    fn tint_colour(&self) -> Vec3 {
        let lum = luminance(self.base);
        if lum > 0.0 {
            self.base / lum
        } else {
            Vec3::ONE
        }
    }

    /// The main lobe's Fresnel term: the dielectric's, mixed with Schlick's for the
    /// metallic and tinted parts on the front side (Mitsuba's `principled_fresnel`).
    /// Branch-free, as the value and density are (see [`Principled::eval_pdf`]).
    #[inline(always)]
    fn fresnel(&self, f_dielectric: f32, cos_i: f32, front: bool, bsdf: f32) -> Vec3 {
        let (m, tint) = (self.metallic, self.spec_tint);
        let fs = Vec3::ZERO;
        let metal = m * schlick(self.base, cos_i, self.eta);
        let fs = if self.has.metallic { fs + metal } else { fs };
        let c_tint = self.tint_colour();
        let eta_it = if cos_i >= 0.0 { self.eta } else { 1.0 / self.eta };
        let r0 = (eta_it - 1.0) / (eta_it + 1.0);
        let tinted = (1.0 - m) * tint * schlick(c_tint * (r0 * r0), cos_i, self.eta);
        let fs = if self.has.spec_tint { fs + tinted } else { fs };
        let front_f = Vec3::splat((1.0 - m) * (1.0 - tint) * f_dielectric) + fs;
        if front {
            front_f
        } else {
            Vec3::splat(bsdf * f_dielectric)
        }
    }

    /// f(wo, wi)·|cos θi|.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_pdf(wo, wi).0
    }

    /// The density of [`Principled::sample`] as Mitsuba states it.
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// [`Principled::eval`] and [`Principled::pdf`] at once: the half vector, its Fresnel
    /// term and D once (the same bits as apart).
    ///
    /// Branch-free: every lobe is computed and kept or not by a select, so that a loop over
    /// lanes that calls it vectorizes (the lane path tracer's), and one call gives the same
    /// bits. (A lobe kept adds its term, one left out adds nothing: the same sums in the
    /// same order as adding only the lobes that are on.)
    ///
    /// (Not inlined: the BSDF dispatch that calls it one lane at a time stays small. The
    /// lane path tracer's loops call [`Principled::eval_pdf_lane`].)
    #[inline(never)]
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        self.eval_pdf_lane(wo, wi)
    }

    /// [`Principled::eval_pdf`], inlined where it is called (in a loop over lanes). PERF:
    /// of a copy (`self` by value), so that every parameter is read unconditionally: a load
    /// that only one arm of a select makes is a conditional load, which keeps a loop over
    /// lanes scalar.
    #[inline(always)]
    #[must_use]
    pub fn eval_pdf_lane(self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let (wh, eta_path, reflect) = self.half(wo, wi);
        let (oh, ih) = (wo.dot(wh), wi.dot(wh));
        let (f, _) = fresnel_dielectric(oh, self.eta);
        let d = self.mf.d_of::<false>(wh);
        let at = At { wh, eta_path, reflect, oh, ih, f, d };
        let (value, pdf) = (self.value(wo, wi, &at), self.density(wo, wi, &at));
        if wo.z == 0.0 {
            (Vec3::ZERO, 0.0)
        } else {
            (value, pdf)
        }
    }

    /// The value at `wi` given what it shares with the density.
    #[inline(always)]
    fn value(&self, wo: Vec3, wi: Vec3, at: &At) -> Vec3 {
        let (ci, co) = (wo.z, wi.z);
        let (brdf, bsdf) = self.weights();
        let front = ci > 0.0;
        let At { wh, eta_path, reflect, oh, ih, f, d } = *at;
        let refract = ci * co < 0.0;
        let g = self.mf.g_of::<false>(wo, wi, wh);
        let agree_r = facet_agrees(wh, wo, wi, ci, true);
        let value = Vec3::ZERO;
        let spec = self.fresnel(f, oh, front, bsdf) * (d * g / (4.0 * ci.abs()));
        let value = if reflect & (f > 0.0) & agree_r { value + spec } else { value };
        // (Radiance is compressed by 1/η² crossing: with it, η² cancels.)
        let inv = 1.0 / eta_path;
        let denom = oh + eta_path * ih;
        let t = (inv * inv * (1.0 - f) * d * g * eta_path * eta_path * oh * ih / (ci * denom * denom)).abs();
        let root = Vec3::new(self.base.x.sqrt(), self.base.y.sqrt(), self.base.z.sqrt());
        let trans = root * (bsdf * t);
        let trans_on = self.has.spec_trans & (bsdf > 0.0) & refract & (f < 1.0) & facet_agrees(wh, wo, wi, ci, false);
        let value = if trans_on { value + trans } else { value };
        let fcc = schlick(Vec3::splat(0.04), oh, self.eta).x;
        let gcc = smith_ggx1(wo, wh, 0.25) * smith_ggx1(wi, wh, 0.25);
        let coat = Vec3::splat(self.clearcoat * 0.25 * fcc * gtr1(wh, self.cc_alpha, self.cc_ln) * gcc * co.abs());
        let coat_on = self.has.clearcoat & (self.clearcoat > 0.0) & reflect & front & agree_r;
        let value = if coat_on { value + coat } else { value };
        let cos_d = wh.dot(wi);
        let (fo, fi) = (schlick_weight(co.abs()), schlick_weight(ci.abs()));
        let f_diff = (1.0 - 0.5 * fi) * (1.0 - 0.5 * fo);
        let rr = 2.0 * self.roughness * cos_d * cos_d;
        let f_retro = rr * (fo + fi + fo * fi * (rr - 1.0));
        let fss90 = rr / 2.0;
        let fss = lerp(1.0, fss90, fo) * lerp(1.0, fss90, fi);
        let f_ss = 1.25 * (fss * (1.0 / (co.abs() + ci.abs()) - 0.5) + 0.5);
        let shape = if self.has.flatness { lerp(f_diff + f_retro, f_ss, self.flatness) } else { f_diff + f_retro };
        let diffuse = self.base * (brdf * co.abs() * FRAC_1_PI * shape);
        let value = if (brdf > 0.0) & reflect & front { value + diffuse } else { value };
        let fd = schlick_weight(cos_d.abs());
        let tinted = Vec3::ONE * (1.0 - self.sheen_tint) + self.tint_colour() * self.sheen_tint;
        let tint = if self.has.sheen_tint { tinted } else { Vec3::ONE };
        let sheen = tint * (self.sheen * (1.0 - self.metallic) * fd * co.abs());
        let sheen_on = self.has.sheen & (self.sheen > 0.0) & reflect & (1.0 - self.metallic > 0.0) & front;
        if sheen_on {
            value + sheen
        } else {
            value
        }
    }

    /// The density at `wi` given what it shares with the value.
    #[inline(always)]
    fn density(&self, wo: Vec3, wi: Vec3, at: &At) -> f32 {
        let (ci, co) = (wo.z, wi.z);
        let front = ci > 0.0;
        let At { wh, eta_path, reflect, oh, ih, f, d } = *at;
        let refract = ci * co < 0.0;
        let [p_reflect, p_trans, p_cc, p_diffuse] = self.probabilities(front, f);
        // |∂ωh/∂ωi| of a reflection or a refraction.
        let refraction = (eta_path * eta_path * ih / ((oh + eta_path * ih) * (oh + eta_path * ih))).abs();
        let jacobian = if self.has.spec_trans & !reflect { refraction } else { (1.0 / (4.0 * ih)).abs() };
        let v = if ci < 0.0 { -wo } else { wo };
        let spec = self.mf.pdf_with_d_of::<false>(v, wh, d) * jacobian;
        let pdf = 0.0;
        let reflect_ok = reflect & facet_agrees(wh, wo, wi, ci, true);
        let pdf = if reflect_ok { pdf + p_reflect * spec } else { pdf };
        let pdf = if reflect { pdf + p_diffuse * FRAC_1_PI * co } else { pdf };
        let trans_ok = self.has.spec_trans & refract & facet_agrees(wh, wo, wi, ci, false);
        let pdf = if trans_ok { pdf + p_trans * spec } else { pdf };
        let gtr = if wh.z < 0.0 { 0.0 } else { wh.z * gtr1(wh, self.cc_alpha, self.cc_ln) };
        if self.has.clearcoat & reflect_ok {
            pdf + p_cc * gtr * jacobian
        } else {
            pdf
        }
    }

    /// A lobe chosen by `u` against the probabilities at a visible GGX facet drawn with
    /// `u2` (which the main reflection and the transmission take; the clearcoat draws its
    /// own facet, the diffuse lobe a cosine-distributed direction, from the same `u2`).
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<BsdfSample> {
        let (wi, eta) = self.direction(wo, u, u2)?;
        let (value, pdf) = self.eval_pdf(wo, wi);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(BsdfSample { wi, weight: value / pdf, pdf, delta: false, eta })
    }

    /// The direction [`Principled::sample`] takes and the relative index it crosses, or
    /// `None` when it has none (its first part: the lane path tracer finds the value and
    /// density of the lanes' directions together, on lanes).
    #[inline(never)]
    #[must_use]
    pub fn direction(&self, wo: Vec3, u: f32, u2: (f32, f32)) -> Option<(Vec3, f32)> {
        let (wi, eta, ok) = self.direction_lane(wo, u, u2);
        ok.then_some((wi, eta))
    }

    /// [`Principled::direction`] branch-free (every lobe's direction made, one selected),
    /// so that a loop over lanes vectorizes; the direction, its relative index and whether
    /// there is one.
    /// (Of a copy, as [`Principled::eval_pdf_lane`].)
    #[inline(always)]
    #[must_use]
    pub fn direction_lane(self, wo: Vec3, u: f32, u2: (f32, f32)) -> (Vec3, f32, bool) {
        let ci = wo.z;
        let (_, bsdf) = self.weights();
        let front = ci > 0.0;
        let none = (ci == 0.0) | !(front | (bsdf > 0.0));
        let v = if ci < 0.0 { -wo } else { wo };
        let m = self.mf.ggx_sample(v, u2);
        let (f, cos_t) = fresnel_dielectric(wo.dot(m), self.eta);
        let [_, p_trans, p_cc, p_diffuse] = self.probabilities(front, f);
        // The lobes in the order they are chosen: diffuse, clearcoat, transmission, the
        // main reflection.
        let wd = cosine_hemisphere(u2);
        let ok_d = ci * wd.z > 0.0;
        let mc = gtr1_sample(u2, self.cc_alpha, self.cc_ln);
        let wc = reflect(wo, mc);
        let ok_c = facet_agrees(mc, wo, wc, ci, true) & (ci * wc.z > 0.0);
        let wt = refract(wo, m, cos_t, self.eta);
        let eta_t = if wo.dot(m) >= 0.0 { self.eta } else { 1.0 / self.eta };
        let ok_t = facet_agrees(m, wo, wt, ci, false) & (ci * wt.z < 0.0);
        let wr = reflect(wo, m);
        let ok_r = facet_agrees(m, wo, wr, ci, true) & (ci * wr.z > 0.0);
        let diffuse = u < p_diffuse;
        let coat = !diffuse & self.has.clearcoat & (u < p_diffuse + p_cc);
        let trans = !diffuse & !coat & self.has.spec_trans & (u < p_diffuse + p_cc + p_trans);
        let (wi, ok) = if diffuse {
            (wd, ok_d)
        } else if coat {
            (wc, ok_c)
        } else if trans {
            (wt, ok_t)
        } else {
            (wr, ok_r)
        };
        let eta = if trans { eta_t } else { 1.0 };
        (wi, eta, ok & !none)
    }

    /// Whether light may pass through (the transmission lobe is on and weighs something).
    #[must_use]
    pub fn transmits(&self) -> bool {
        self.has.spec_trans && (1.0 - self.metallic) * self.spec_trans > 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_scene::Distribution;

    fn plain() -> Principled {
        Principled {
            base: Vec3::new(0.8, 0.5, 0.3),
            roughness: 0.5,
            metallic: 0.0,
            spec_trans: 0.0,
            spec_tint: 0.0,
            sheen: 0.0,
            sheen_tint: 0.0,
            flatness: 0.0,
            clearcoat: 0.0,
            cc_alpha: 0.1,
            cc_ln: Principled::cc_ln_of(0.1),
            mf: Microfacet::new(Distribution::Ggx, 0.25),
            eta: 1.5,
            rates: [1.0, 1.0, 1.0],
            has: PrincipledLobes::default(),
        }
    }

    /// Seen and lit along the normal, Burley's diffuse term is base/π (its Schlick weights
    /// vanish, and with them the retro-reflection), and the GGX lobe adds F₀ D / 4 (no
    /// masking there).
    #[test]
    fn normal_incidence_is_burley_plus_ggx() {
        let p = plain();
        let (wo, wi) = (Vec3::Z, Vec3::Z);
        let f_d = 1.5f32;
        let r0 = ((f_d - 1.0) / (f_d + 1.0)).powi(2);
        let d = p.mf.d(Vec3::Z);
        let want = p.base * FRAC_1_PI + Vec3::splat(r0 * d / 4.0);
        let got = p.eval(wo, wi);
        assert!((got - want).abs().max_element() < 1e-4 * want.max_element(), "{got} against {want}");
    }

    /// Without transmission its back is black, and samples from there fail.
    #[test]
    fn opaque_back_is_black() {
        let p = plain();
        let wo = Vec3::new(0.3, 0.0, -0.954);
        assert_eq!(p.eval(wo, Vec3::new(0.0, 0.3, -0.954)), Vec3::ZERO);
        assert!(p.sample(wo, 0.5, (0.3, 0.6)).is_none());
    }
}
