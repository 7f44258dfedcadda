//! Delta lights: the scene's point, spot and directional lights (Mitsuba's `point`,
//! `spot` with its falloff, `directional`). No ray meets them; next-event estimation alone
//! finds their light.

use super::sample::{EmissionSample, LightSample};
use crate::color::luminance;
use crate::sampling::{uniform_cone, uniform_sphere};
use glam::{Vec3, Vec3A};
use lucent_scene::{Light, LightKind};
use std::f32::consts::PI;

/// The unit direction toward a directional light that shines along `direction`: the
/// direction of its shadow rays, bit for bit (the top level's shadow grids match on it).
pub(crate) fn toward_directional(direction: Vec3) -> Vec3 {
    -direction.normalize()
}

/// Its power, for the choice among lights (a directional light's through the scene's
/// bounding sphere of radius `radius`).
pub(crate) fn power(l: &Light, radius: f32) -> f32 {
    luminance(l.color)
        * match l.kind {
            LightKind::Point { .. } => 4.0 * PI,
            LightKind::Spot { inner, outer, .. } => 2.0 * PI * (1.0 - (0.5 * (inner + outer)).cos()),
            LightKind::Directional { .. } => PI * radius * radius,
        }
}

/// A ray of light leaving `l`: point lights emit uniformly in all directions, spot lights
/// uniformly within their outer cone (times the falloff), directional light from the
/// point `disk_start` gives for its direction on a disk of area `disk_area` across the
/// scene; its flux not yet over the light's choice.
pub(crate) fn emit(l: &Light, u_dir: (f32, f32), disk_start: impl Fn(Vec3) -> Vec3, disk_area: f32) -> Option<EmissionSample> {
    Some(match l.kind {
        LightKind::Point { position } => EmissionSample { p: position, dir: uniform_sphere(u_dir), n: None, flux: l.color * (4.0 * PI) },
        LightKind::Spot { position, direction, outer, .. } => {
            let axis = direction.normalize_or_zero();
            let cos_max = outer.cos();
            let dir = uniform_cone(axis, cos_max, u_dir);
            // (The falloff is what a shading point on this direction receives.)
            let falloff = sample(l, position + dir)?.li;
            EmissionSample { p: position, dir, n: None, flux: falloff * (2.0 * PI * (1.0 - cos_max)) }
        }
        LightKind::Directional { direction } => {
            let dir = direction.normalize_or_zero();
            EmissionSample { p: disk_start(dir), dir, n: None, flux: l.color * disk_area }
        }
    })
}

/// A point, spot or directional light seen from `p`.
pub(crate) fn sample(l: &Light, p: Vec3) -> Option<LightSample> {
    match l.kind {
        LightKind::Directional { direction } => {
            let dir = -direction.normalize_or_zero();
            (dir != Vec3::ZERO).then_some(LightSample { dir, dist: f32::INFINITY, li: l.color, pdf: 1.0, delta: true })
        }
        LightKind::Point { position } | LightKind::Spot { position, .. } => {
            // PERF: in four lanes (Vec3A), length and division included: as Vec3 the
            // square root and the divisions of x, y and of z ran one after another (perf put
            // 5-6% of a Sponza render on them); Sponza at 64 spp 0.94 -> 0.87 s (medians of
            // five, interleaved, 2 threads).
            let to = Vec3A::from(position) - Vec3A::from(p);
            let dist = to.length();
            if !(dist > 0.0 && dist.is_finite()) {
                return None;
            }
            let dir = Vec3::from(to / dist);
            let falloff = match l.kind {
                LightKind::Spot { direction, inner, outer, .. } => {
                    // Mitsuba's spot falloff: full inside `inner`, then linear in the angle
                    // down to zero at `outer`.
                    let angle = lucent_accel::math::acos((-dir).dot(direction.normalize_or_zero()));
                    if angle <= inner {
                        1.0
                    } else if angle >= outer || outer <= inner {
                        0.0
                    } else {
                        (outer - angle) / (outer - inner)
                    }
                }
                _ => 1.0,
            };
            (falloff > 0.0).then(|| LightSample { dir, dist, li: l.color * falloff / (dist * dist), pdf: 1.0, delta: true })
        }
    }
}

/// A point, spot or directional light as a loop over lanes takes it ([`sample_lane`]).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct DeltaLane {
    /// Position (point and spot lights).
    pub(crate) position: Vec3,
    /// A spot light's unit axis; a directional light's unit direction toward it; zero for
    /// a point light, which has no falloff.
    pub(crate) axis: Vec3,
    /// A spot light's inner and outer angles (radians).
    pub(crate) inner: f32,
    pub(crate) outer: f32,
    /// Whether it is a spot light, a directional light.
    pub(crate) spot: bool,
    pub(crate) directional: bool,
    pub(crate) color: Vec3,
}

impl DeltaLane {
    /// `l` as a lane takes it.
    pub(crate) fn of(l: &Light) -> Self {
        match l.kind {
            LightKind::Point { position } => Self { position, color: l.color, ..Self::default() },
            LightKind::Spot { position, direction, inner, outer } => {
                Self { position, axis: direction.normalize_or_zero(), inner, outer, spot: true, color: l.color, ..Self::default() }
            }
            LightKind::Directional { direction } => {
                Self { axis: -direction.normalize_or_zero(), directional: true, color: l.color, ..Self::default() }
            }
        }
    }
}

/// [`sample`], branch-free for loops over lanes (the same bits): the sample and whether
/// there is one.
#[inline(always)]
pub(crate) fn sample_lane(l: &DeltaLane, p: Vec3) -> (LightSample, bool) {
    let to = l.position - p;
    let dist = to.length();
    let dir = to / dist;
    let angle = lucent_accel::math::acos((-dir).dot(l.axis));
    let ramp = (l.outer - angle) / (l.outer - l.inner);
    let cone = if angle <= l.inner {
        1.0
    } else if (angle >= l.outer) | (l.outer <= l.inner) {
        0.0
    } else {
        ramp
    };
    let falloff = if l.spot { cone } else { 1.0 };
    let ok = (dist > 0.0) & dist.is_finite() & (falloff > 0.0);
    let local = LightSample { dir, dist, li: l.color * falloff / (dist * dist), pdf: 1.0, delta: true };
    // (A directional light: its direction, from every point.)
    let parallel = LightSample { dir: l.axis, dist: f32::INFINITY, li: l.color, pdf: 1.0, delta: true };
    if l.directional {
        (parallel, l.axis != Vec3::ZERO)
    } else {
        (local, ok)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lane form gives [`sample`]'s numbers bit for bit (point, spot and directional
    /// lights; points inside, on the edge of and outside the cone, at the light itself; a
    /// directional light without a direction), and no sample where it gives none.
    #[test]
    fn the_lane_sample_is_the_scalar_one() {
        let v = Vec3::new;
        let lights = [
            Light { kind: LightKind::Point { position: v(0.3, 2.0, -1.0) }, color: v(5.0, 4.0, 3.0), inverse_square: true },
            Light {
                kind: LightKind::Spot { position: v(1.0, 3.0, 0.5), direction: v(-0.2, -1.0, 0.1), inner: 0.3, outer: 0.6 },
                color: v(9.0, 9.0, 8.0),
                inverse_square: true,
            },
            Light {
                kind: LightKind::Spot { position: v(0.0, 1.0, 0.0), direction: v(0.0, -2.0, 0.0), inner: 0.5, outer: 0.5 },
                color: v(1.0, 2.0, 3.0),
                inverse_square: true,
            },
            Light { kind: LightKind::Directional { direction: v(0.3, -1.0, 0.2) }, color: v(2.0, 2.0, 1.5), inverse_square: false },
            Light { kind: LightKind::Directional { direction: Vec3::ZERO }, color: v(1.0, 1.0, 1.0), inverse_square: false },
        ];
        let mut state = 0x1234_5678u32;
        let mut next = || {
            state = state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
            (state >> 8) as f32 / (1u32 << 24) as f32 * 8.0 - 4.0
        };
        let (mut some, mut none) = (0, 0);
        for l in &lights {
            let lane = DeltaLane::of(l);
            let mut points: Vec<Vec3> = (0..4000).map(|_| v(next(), next(), next())).collect();
            if let LightKind::Point { position } | LightKind::Spot { position, .. } = l.kind {
                points.push(position);
            }
            for p in points {
                let (s, ok) = sample_lane(&lane, p);
                match sample(l, p) {
                    Some(t) => {
                        some += 1;
                        assert!(ok, "{p}: the scalar form samples, the lane form does not");
                        assert_eq!(s.dir.to_array().map(f32::to_bits), t.dir.to_array().map(f32::to_bits), "{p}");
                        assert_eq!(s.li.to_array().map(f32::to_bits), t.li.to_array().map(f32::to_bits), "{p}");
                        assert_eq!((s.dist.to_bits(), s.pdf, s.delta), (t.dist.to_bits(), t.pdf, t.delta), "{p}");
                    }
                    None => {
                        none += 1;
                        assert!(!ok, "{p}: the lane form samples where the scalar one does not");
                    }
                }
            }
        }
        assert!(some > 1000 && none > 4000, "{some} samples, {none} without");
    }
}
