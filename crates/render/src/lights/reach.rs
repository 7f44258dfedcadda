//! How much light each light object may send to a shading point, bounded from its shape:
//! the weights of the choice among lights (Conty Estevez and Kulla 2018, "Importance
//! sampling of many lights with adaptive tree splitting", their importance measure for a
//! cluster of lights, applied to every light object of a scene with few of them).
//!
//! Every weight is an irradiance at the point, in the same units for every kind of light:
//! an area light's radiance times its area over the squared distance (its intensity over
//! d²), a point or spot light's intensity over d², a directional light's irradiance, and
//! the environment's mean radiance times π (a plane's irradiance under a uniform sky).
//! Each is scaled by two cosines bounded over the light's extent: at the light (the angle
//! between its emission cone and the point, less the angle its bounds subtend) and at the
//! point (between its normal and the light, less the same angle). Visibility is not known:
//! an occluded light keeps its weight.
//!
//! The weight is zero only where the light sends nothing: behind a one-sided emitter, or
//! outside a spot light's cone. Everywhere else it is at least a thousandth of its
//! unbounded value (both cosines are floored), so the choice stays unbiased wherever the
//! bounds are loose.

// Lane loops index several arrays by the lane number; written so, they vectorize.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;

/// The least factor a cosine contributes where the light is not ruled out.
const FLOOR: f32 = 1e-3;
/// Slack on the angle past which a light sends nothing (radians): rounding in the bounds
/// never rules out a light that reaches the point.
const SLACK: f32 = 1e-3;

/// What bounds a light object's contribution (see the module's documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Reach {
    /// Light from a bounded place: a sphere (centre, radius) holding the emitter, the axis
    /// of its emission, the half-angle θo of the cone of normals about it (cos, sin; π
    /// for every direction), the cosine of θe, the angle past θo at which emission stops
    /// (π/2 for a one-sided surface, the falloff's width for a spot light, −1 for never),
    /// and its intensity along the cone (luminance).
    Local { centre: Vec3, radius: f32, axis: Vec3, cos_o: f32, sin_o: f32, cos_e: f32, intensity: f32 },
    /// Parallel light toward unit `toward`, of irradiance `irradiance` (luminance).
    Directional { toward: Vec3, irradiance: f32 },
    /// Light from every direction: a plane's irradiance under it (luminance).
    Everywhere { irradiance: f32 },
}

impl Reach {
    /// A light whose emission stops θe past a cone of normals of half-angle θo (`theta_e`
    /// of π or more: never).
    pub(crate) fn local(centre: Vec3, radius: f32, axis: Vec3, theta_o: f32, theta_e: f32, intensity: f32) -> Self {
        let theta_o = theta_o.clamp(0.0, std::f32::consts::PI);
        let cos_e = if theta_e + SLACK >= std::f32::consts::PI { -2.0 } else { (theta_e + SLACK).cos() };
        let axis = axis.normalize_or_zero();
        // (No axis: light in every direction.)
        let (cos_o, sin_o) = if axis == Vec3::ZERO { (-1.0, 0.0) } else { (theta_o.cos(), theta_o.sin()) };
        Self::Local { centre, radius: radius.max(0.0), axis, cos_o, sin_o, cos_e, intensity: intensity.max(0.0) }
    }

    /// The weight of this light at point `p` whose surface has unit normal `n` (zero: no
    /// surface, light from every side counts): [`Lanes::weights`] for one light.
    #[cfg(test)]
    pub(crate) fn weight(&self, p: Vec3, n: Vec3) -> f32 {
        lane_weight(&Lane::of(self), p, n, n != Vec3::ZERO)
    }
}

/// One light's bounds as the weight's arithmetic takes them: every kind in one form.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Lane {
    /// The centre (`m` = 1) or the unit direction toward the light (`m` = 0: parallel).
    c: Vec3,
    m: f32,
    radius: f32,
    /// 1 / max(radius², 10⁻¹²).
    inv_r2: f32,
    axis: Vec3,
    cos_o: f32,
    sin_o: f32,
    cos_e: f32,
    intensity: f32,
    /// 1: the weight is `intensity` alone, no cosine (the environment).
    everywhere: f32,
}

impl Lane {
    /// The weight of this light at `p` (unit normal `n`, or zero).
    #[cfg(test)]
    #[inline]
    pub(crate) fn weight(&self, p: Vec3, n: Vec3) -> f32 {
        lane_weight(self, p, n, n != Vec3::ZERO)
    }

    pub(crate) fn of(r: &Reach) -> Self {
        let mut l = match *r {
            Reach::Local { centre, radius, axis, cos_o, sin_o, cos_e, intensity } => {
                Lane { c: centre, m: 1.0, radius, inv_r2: 0.0, axis, cos_o, sin_o, cos_e, intensity, everywhere: 0.0 }
            }
            Reach::Directional { toward, irradiance } => {
                Lane { c: toward, m: 0.0, cos_o: -1.0, cos_e: -2.0, intensity: irradiance, ..Lane::default() }
            }
            Reach::Everywhere { irradiance } => {
                Lane { cos_o: -1.0, cos_e: -2.0, intensity: irradiance, everywhere: 1.0, ..Lane::default() }
            }
        };
        l.inv_r2 = 1.0 / (l.radius * l.radius).max(1e-12);
        l
    }
}

/// The weight of one light (see the module's documentation), branch-free: selects only,
/// no fused multiply-add, so a loop of it vectorizes and gives the same bits at every
/// width.
#[inline(always)]
fn lane_weight(l: &Lane, p: Vec3, n: Vec3, has_n: bool) -> f32 {
    let to = l.c - p * l.m;
    let d2 = to.length_squared();
    let r2 = l.radius * l.radius;
    let inside = d2 <= r2 || d2.is_nan();
    let inv_d = 1.0 / d2.sqrt();
    let w = to * inv_d;
    let sin_b = (l.radius * inv_d).min(1.0);
    let cos_b = (1.0 - sin_b * sin_b).max(0.0).sqrt();
    // At the light: θw (between its axis and the way to p) less θo, less θb.
    let cos_w = l.axis.dot(-w).clamp(-1.0, 1.0);
    let sin_w = (1.0 - cos_w * cos_w).max(0.0).sqrt();
    let full = cos_w >= l.cos_o;
    let c1 = if full { 1.0 } else { cos_w * l.cos_o + sin_w * l.sin_o };
    let s1 = if full { 0.0 } else { sin_w * l.cos_o - cos_w * l.sin_o };
    let c2 = if c1 >= cos_b { 1.0 } else { c1 * cos_b + s1 * sin_b };
    // At the point: its normal toward the light, less θb (either side: transmission
    // counts).
    let cos_i = n.dot(w).abs().min(1.0);
    let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
    let ci = if cos_i >= cos_b { 1.0 } else { cos_i * cos_b + sin_i * sin_b };
    let recv = if has_n { ci.max(FLOOR) } else { 1.0 };
    let v = l.intensity * c2.max(FLOOR) * recv * (inv_d * inv_d);
    let v = if c2 < l.cos_e { 0.0 } else { v };
    // Inside the light's bounds no angle bounds it.
    let v = if inside { l.intensity * l.inv_r2 } else { v };
    if l.everywhere > 0.0 {
        l.intensity
    } else {
        v
    }
}

/// The one of `w` (weights summing to `total`, which is positive) that `u` in [0, 1)
/// picks, each in proportion to its weight: its index, its probability and `u` rescaled
/// to within its share (not clamped). Rounding that leaves `u · total` past the last sum
/// gives the last one with any weight.
#[inline(always)]
pub(crate) fn pick(w: &[f32], total: f32, u: f32) -> (usize, f32, f32) {
    let target = u * total;
    let (mut k, mut acc, mut last) = (usize::MAX, 0.0, (0, 0.0));
    for (j, &wj) in w.iter().enumerate() {
        if wj > 0.0 {
            if target < acc + wj {
                k = j;
                break;
            }
            last = (j, acc);
            acc += wj;
        }
    }
    if k == usize::MAX {
        (k, acc) = last;
    }
    (k, w[k] / total, (target - acc) / w[k])
}

/// The most lights weighed at once.
pub(crate) const WIDTH: usize = 16;

/// Up to [`WIDTH`] lights' bounds as a structure of arrays, weighed all at once on lanes.
#[derive(Clone, Debug)]
pub(crate) struct Lanes {
    count: usize,
    cx: [f32; WIDTH],
    cy: [f32; WIDTH],
    cz: [f32; WIDTH],
    m: [f32; WIDTH],
    radius: [f32; WIDTH],
    inv_r2: [f32; WIDTH],
    ax: [f32; WIDTH],
    ay: [f32; WIDTH],
    az: [f32; WIDTH],
    cos_o: [f32; WIDTH],
    sin_o: [f32; WIDTH],
    cos_e: [f32; WIDTH],
    intensity: [f32; WIDTH],
    everywhere: [f32; WIDTH],
}

impl Default for Lanes {
    fn default() -> Self {
        Self::new(&[])
    }
}

impl Lanes {
    /// The first [`WIDTH`] of `reaches` (the rest are left out).
    pub(crate) fn new(reaches: &[Reach]) -> Self {
        let z = [0.0; WIDTH];
        let mut s = Self {
            count: reaches.len().min(WIDTH),
            cx: z,
            cy: z,
            cz: z,
            m: z,
            radius: z,
            inv_r2: z,
            ax: z,
            ay: z,
            az: z,
            cos_o: z,
            sin_o: z,
            cos_e: z,
            intensity: z,
            everywhere: z,
        };
        for (i, r) in reaches.iter().take(WIDTH).enumerate() {
            let l = Lane::of(r);
            (s.cx[i], s.cy[i], s.cz[i], s.m[i], s.radius[i], s.inv_r2[i]) = (l.c.x, l.c.y, l.c.z, l.m, l.radius, l.inv_r2);
            (s.ax[i], s.ay[i], s.az[i], s.cos_o[i], s.sin_o[i], s.cos_e[i]) = (l.axis.x, l.axis.y, l.axis.z, l.cos_o, l.sin_o, l.cos_e);
            (s.intensity[i], s.everywhere[i]) = (l.intensity, l.everywhere);
        }
        s
    }

    /// Each light's weight at `p` (unit normal `n`, or zero) into `out` (zero past the
    /// lights), and their sum in order.
    #[inline]
    pub(crate) fn weights(&self, p: Vec3, n: Vec3, out: &mut [f32; WIDTH]) -> f32 {
        /// Lanes `0..N` of `s`.
        #[inline(always)]
        fn run<const N: usize>(s: &Lanes, p: Vec3, n: Vec3, out: &mut [f32; WIDTH]) {
            let has_n = n != Vec3::ZERO;
            for i in 0..N {
                let l = Lane {
                    c: Vec3::new(s.cx[i], s.cy[i], s.cz[i]),
                    m: s.m[i],
                    radius: s.radius[i],
                    inv_r2: s.inv_r2[i],
                    axis: Vec3::new(s.ax[i], s.ay[i], s.az[i]),
                    cos_o: s.cos_o[i],
                    sin_o: s.sin_o[i],
                    cos_e: s.cos_e[i],
                    intensity: s.intensity[i],
                    everywhere: s.everywhere[i],
                };
                out[i] = lane_weight(&l, p, n, has_n);
            }
        }
        // (Eight lanes where they hold every light: half the divisions and roots.)
        if self.count <= WIDTH / 2 {
            crate::lanes::on_lanes!(|s: &Lanes, p: Vec3, n: Vec3, out: &mut [f32; WIDTH]| run::<{ WIDTH / 2 }>(s, p, n, out))(
                self, p, n, out,
            );
            out[WIDTH / 2..].fill(0.0);
        } else {
            crate::lanes::on_lanes!(|s: &Lanes, p: Vec3, n: Vec3, out: &mut [f32; WIDTH]| run::<WIDTH>(s, p, n, out))(self, p, n, out);
        }
        out[..self.count].iter().sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    #[test]
    fn a_point_light_falls_off_with_the_square_of_distance_and_the_cosine() {
        let l = Reach::local(Vec3::new(0.0, 2.0, 0.0), 0.0, Vec3::ZERO, PI, PI, 3.0);
        let up = l.weight(Vec3::ZERO, Vec3::Y);
        assert!((up - 3.0 / 4.0).abs() < 1e-6, "{up}");
        let tilted = l.weight(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0).normalize());
        assert!((tilted - 0.75 * 0.5f32.sqrt()).abs() < 1e-6, "{tilted}");
        // Edge on: floored, not zero (the surface's BSDF decides).
        assert!(l.weight(Vec3::ZERO, Vec3::X) > 0.0);
        assert!((l.weight(Vec3::ZERO, Vec3::ZERO) - 0.75).abs() < 1e-6);
    }

    #[test]
    fn a_spot_light_sends_nothing_outside_its_cone_only() {
        // Down the −y axis, full to 10°, nothing past 30°.
        let (inner, outer) = (10f32.to_radians(), 30f32.to_radians());
        let l = Reach::local(Vec3::new(0.0, 1.0, 0.0), 0.0, -Vec3::Y, inner, outer - inner, 1.0);
        for deg in [0.0f32, 5.0, 10.0, 20.0, 29.9] {
            let x = deg.to_radians().tan();
            assert!(l.weight(Vec3::new(x, 0.0, 0.0), Vec3::Y) > 0.0, "{deg}°");
        }
        for deg in [30.2f32, 45.0, 90.0, 135.0] {
            let a = deg.to_radians();
            let p = Vec3::new(0.0, 1.0, 0.0) + Vec3::new(a.sin(), -a.cos(), 0.0);
            assert_eq!(l.weight(p, Vec3::Y), 0.0, "{deg}°");
        }
        // Full inside the inner cone, less between.
        let at = |deg: f32| l.weight(Vec3::new(deg.to_radians().tan(), 0.0, 0.0), Vec3::ZERO) * (1.0 + deg.to_radians().tan().powi(2));
        assert!((at(5.0) - 1.0).abs() < 1e-5 && at(20.0) < 1.0);
    }

    #[test]
    fn a_one_sided_emitter_lights_its_front_only_and_its_extent_loosens_the_bounds() {
        // A unit disk-like emitter at the origin facing +y.
        let l = Reach::local(Vec3::ZERO, 1.0, Vec3::Y, 0.0, 0.5 * PI, 2.0);
        assert!(l.weight(Vec3::new(0.0, 3.0, 0.0), Vec3::ZERO) > 0.0);
        assert_eq!(l.weight(Vec3::new(0.0, -3.0, 0.0), Vec3::ZERO), 0.0);
        // Beside its plane, within the angle its bounds subtend: still lit.
        assert!(l.weight(Vec3::new(3.0, 0.0, 0.0), Vec3::ZERO) > 0.0);
        // Far away and head on, the bounds are tight: intensity over d².
        let far = l.weight(Vec3::new(0.0, 1000.0, 0.0), Vec3::Y);
        assert!((far / (2.0 / 1e6) - 1.0).abs() < 1e-3, "{far}");
        // Inside the bounds: finite and positive.
        let inside = l.weight(Vec3::new(0.1, 0.1, 0.0), Vec3::Y);
        assert!(inside > 0.0 && inside.is_finite());
    }

    #[test]
    fn lanes_weigh_as_one_light_at_a_time() {
        let reaches = [
            Reach::local(Vec3::new(0.0, 2.0, 0.0), 0.0, Vec3::ZERO, PI, PI, 3.0),
            Reach::local(Vec3::new(1.0, 1.0, 0.0), 0.0, -Vec3::Y, 0.2, 0.3, 1.0),
            Reach::local(Vec3::new(-1.0, 1.5, 0.5), 0.4, Vec3::new(0.0, -1.0, 0.2), 0.0, 0.5 * PI, 2.0),
            Reach::local(Vec3::new(0.0, 0.5, -1.0), 0.3, Vec3::ZERO, PI, PI, 5.0),
            Reach::Directional { toward: Vec3::new(0.3, 1.0, 0.1).normalize(), irradiance: 1.5 },
            Reach::Everywhere { irradiance: 0.7 },
        ];
        let lanes = Lanes::new(&reaches);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32 * 4.0 - 2.0
        };
        for k in 0..2000 {
            let p = Vec3::new(next(), next(), next());
            let n = if k % 7 == 0 { Vec3::ZERO } else { Vec3::new(next(), next(), next()).normalize_or_zero() };
            let mut out = [f32::NAN; WIDTH];
            let total = lanes.weights(p, n, &mut out);
            let mut sum = 0.0;
            for (i, r) in reaches.iter().enumerate() {
                assert_eq!(out[i].to_bits(), r.weight(p, n).to_bits(), "light {i} at {p} {n}");
                assert!(out[i] >= 0.0 && out[i].is_finite());
                sum += out[i];
            }
            assert_eq!(total.to_bits(), sum.to_bits());
            assert!(out[reaches.len()..].iter().all(|&w| w == 0.0));
        }
    }

    #[test]
    fn directional_and_environment_weights_are_irradiances() {
        let sun = Reach::Directional { toward: Vec3::Y, irradiance: 2.0 };
        assert!((sun.weight(Vec3::ZERO, Vec3::Y) - 2.0).abs() < 1e-6);
        assert!((sun.weight(Vec3::ZERO, -Vec3::Y) - 2.0).abs() < 1e-6, "either side");
        let sky = Reach::Everywhere { irradiance: 0.5 };
        assert_eq!(sky.weight(Vec3::splat(7.0), Vec3::X), 0.5);
    }
}
