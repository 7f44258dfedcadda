//! What every BSDF answers with ([`BsdfSample`]) and the small helpers they share.

use glam::Vec3;

/// A sampled direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Direction toward the light (local frame).
    pub wi: Vec3,
    /// f·|cos θi| / pdf (for a delta lobe: its value over the probability of choosing it).
    pub weight: Vec3,
    /// Density per solid angle (for a delta lobe: the probability of choosing it).
    pub pdf: f32,
    /// A delta lobe (mirror, smooth refraction): no other strategy can sample it.
    pub delta: bool,
    /// The relative index of refraction crossed (ηt/ηi; 1 for reflection), for roulette.
    pub eta: f32,
}

/// Whether two local directions lie on the same side of the surface.
#[inline]
pub(crate) fn same_side(wo: Vec3, wi: Vec3) -> bool {
    wo.z * wi.z > 0.0
}

/// Mitsuba's mean of a colour, for lobe-sampling weights.
#[inline]
pub(crate) fn mean(c: Vec3) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

/// Luminance, at least zero (for lobe-sampling weights).
#[inline]
pub(crate) fn lum(c: Vec3) -> f32 {
    crate::color::luminance(c).max(0.0)
}

/// A non-delta sample toward `wi`: its weight `eval() / pdf` (`None` where the density is
/// not positive and finite), crossing `eta_across` when `wi` lies on the other side.
#[inline]
pub(crate) fn by_density(wo: Vec3, wi: Vec3, pdf: f32, eval: impl FnOnce() -> Vec3, eta_across: f32) -> Option<BsdfSample> {
    if !(pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    let weight = eval() / pdf;
    let eta = if same_side(wo, wi) { 1.0 } else { eta_across };
    Some(BsdfSample { wi, weight, pdf, delta: false, eta })
}

/// [`by_density`] for a reflection toward `wi` of value `f` and density `pdf`, without a
/// branch (for loops over lanes): the sample and whether there is one (both directions
/// above the surface, the density positive and finite).
#[inline(always)]
pub(crate) fn reflection_lane(wo: Vec3, wi: Vec3, f: Vec3, pdf: f32) -> (BsdfSample, bool) {
    let ok = (wo.z > 0.0) & (wi.z > 0.0) & (pdf > 0.0) & pdf.is_finite();
    (BsdfSample { wi, weight: f / pdf, pdf, delta: false, eta: 1.0 }, ok)
}

/// The mirror direction of `wo` about the normal (local frame).
#[inline]
pub(crate) fn mirror(wo: Vec3) -> Vec3 {
    Vec3::new(-wo.x, -wo.y, wo.z)
}
