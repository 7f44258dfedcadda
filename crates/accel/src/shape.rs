//! Analytic primitives in their canonical space. An instance of a shape is this canonical
//! shape under the instance's `world_from_object` transform (SaarCOR §2.2's idea, applied to
//! quadrics as REND3R does): the ray is carried into object space and meets the unit shape.
//!
//! Canonical forms (axis z, as REND3R's `conics.sv`):
//! - `Sphere`: x²+y²+z² = 1.
//! - `Cylinder`: x²+y² = 1, infinite along z, no caps (REND3R).
//! - `CappedCylinder`: x²+y² ≤ 1 for z in [-1, 1], with caps.
//! - `Tube`: x²+y² = 1 for z in [-1, 1], open (Mitsuba's `cylinder`).
//! - `Cone`: x²+y² = z², infinite double cone, apex at the origin (REND3R).
//! - `CappedCone`: x²+y² = z² for z in [0, 1], closed by a disk at z = 1.
//! - `Box`: [-1, 1]³.
//! - `Disk`: x²+y² ≤ 1 in the plane z = 0.
//!
//! Quadrics are solved in f64 (cheap next to a traversal, and robust for far origins).

use crate::geom::Aabb;
use glam::Vec3;

/// The kind of an analytic primitive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    /// Unit sphere.
    Sphere,
    /// Infinite unit cylinder along z.
    Cylinder,
    /// Unit cylinder, z in [-1, 1], capped.
    CappedCylinder,
    /// Infinite double cone x²+y² = z².
    Cone,
    /// Cone z in [0, 1] with a cap at z = 1.
    CappedCone,
    /// Box [-1, 1]³.
    Box,
    /// Unit disk in z = 0.
    Disk,
    /// Unit cylinder, z in [-1, 1], open at both ends (Mitsuba's `cylinder`).
    Tube,
}

/// A hit on a shape: distance and the part hit (side, cap, face). Surface parameters come
/// from [`Shape::uv_local`] at the hit point, only where they are needed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeHit {
    /// Distance.
    pub t: f32,
    /// Part: 0 = main surface; cylinder 1/2 = bottom/top cap; cone 1 = cap; box 0..6 = face.
    pub part: u32,
}

impl Shape {
    /// Bounds in object space (infinite for the infinite shapes).
    #[must_use]
    pub fn bounds_local(self) -> Aabb {
        let inf = f32::INFINITY;
        match self {
            Shape::Sphere | Shape::CappedCylinder | Shape::Tube | Shape::Box => Aabb { min: Vec3::splat(-1.0), max: Vec3::ONE },
            Shape::Cylinder => Aabb { min: Vec3::new(-1.0, -1.0, -inf), max: Vec3::new(1.0, 1.0, inf) },
            Shape::Cone => Aabb { min: Vec3::splat(-inf), max: Vec3::splat(inf) },
            Shape::CappedCone => Aabb { min: Vec3::new(-1.0, -1.0, 0.0), max: Vec3::ONE },
            Shape::Disk => Aabb { min: Vec3::new(-1.0, -1.0, 0.0), max: Vec3::new(1.0, 1.0, 0.0) },
        }
    }

    /// True for shapes with finite bounds.
    #[must_use]
    pub fn is_bounded(self) -> bool {
        !matches!(self, Shape::Cylinder | Shape::Cone)
    }

    /// Nearest hit of the object-space ray `o + t d` with `t` in `[tmin, tmax)`.
    #[must_use]
    pub fn intersect_local(self, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<ShapeHit> {
        let (o, d) = (o.as_dvec3(), d.as_dvec3());
        let (lo, hi) = (tmin as f64, tmax as f64);
        let mut best: Option<(f64, u32)> = None;
        let mut consider = |t: f64, part: u32, ok: bool| {
            if ok && t >= lo && t < hi && best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, part));
            }
        };
        match self {
            Shape::Sphere => {
                for t in quadric(d.dot(d), d.dot(o), o.dot(o) - 1.0) {
                    consider(t, 0, true);
                }
            }
            Shape::Cylinder | Shape::CappedCylinder | Shape::Tube => {
                let capped = self == Shape::CappedCylinder;
                let finite = self != Shape::Cylinder;
                for t in quadric(d.x * d.x + d.y * d.y, d.x * o.x + d.y * o.y, o.x * o.x + o.y * o.y - 1.0) {
                    let z = o.z + t * d.z;
                    consider(t, 0, !finite || (-1.0..=1.0).contains(&z));
                }
                if capped && d.z != 0.0 {
                    for (part, zc) in [(1, -1.0), (2, 1.0)] {
                        let t = (zc - o.z) / d.z;
                        let p = o + d * t;
                        consider(t, part, p.x * p.x + p.y * p.y <= 1.0);
                    }
                }
            }
            Shape::Cone | Shape::CappedCone => {
                let capped = self == Shape::CappedCone;
                let a = d.x * d.x + d.y * d.y - d.z * d.z;
                let b = d.x * o.x + d.y * o.y - d.z * o.z;
                let c = o.x * o.x + o.y * o.y - o.z * o.z;
                let roots: [f64; 2] = if a.abs() < 1e-12 * d.length_squared() {
                    // Ray parallel to the surface: one crossing.
                    [if b != 0.0 { -c / (2.0 * b) } else { f64::NAN }, f64::NAN]
                } else {
                    quadric(a, b, c)
                };
                for t in roots {
                    let z = o.z + t * d.z;
                    consider(t, 0, !capped || (0.0..=1.0).contains(&z));
                }
                if capped && d.z != 0.0 {
                    let t = (1.0 - o.z) / d.z;
                    let p = o + d * t;
                    consider(t, 1, p.x * p.x + p.y * p.y <= 1.0);
                }
            }
            Shape::Box => {
                // Slabs; remember which face bounds the entry and the exit.
                let mut tn = f64::NEG_INFINITY;
                let mut tf = f64::INFINITY;
                let (mut fn_, mut ff) = (0u32, 0u32);
                for k in 0..3 {
                    if d[k] == 0.0 {
                        if o[k].abs() > 1.0 {
                            return None;
                        }
                        continue;
                    }
                    let inv = 1.0 / d[k];
                    let (mut a, mut b) = ((-1.0 - o[k]) * inv, (1.0 - o[k]) * inv);
                    let (mut fa, mut fb) = (2 * k as u32, 2 * k as u32 + 1);
                    if a > b {
                        std::mem::swap(&mut a, &mut b);
                        std::mem::swap(&mut fa, &mut fb);
                    }
                    if a > tn {
                        tn = a;
                        fn_ = fa;
                    }
                    if b < tf {
                        tf = b;
                        ff = fb;
                    }
                }
                if tn <= tf {
                    consider(tn, fn_, true);
                    consider(tf, ff, true);
                }
            }
            Shape::Disk => {
                if d.z != 0.0 {
                    let t = -o.z / d.z;
                    let p = o + d * t;
                    consider(t, 0, p.x * p.x + p.y * p.y <= 1.0);
                }
            }
        }
        let (t, part) = best?;
        Some(ShapeHit { t: t as f32, part })
    }

    /// Surface parameters (u, v) in [0, 1] of an object-space point on part `part`
    /// (spherical angles, heights, face coordinates; a disk's radius and angle, as
    /// Mitsuba's).
    #[must_use]
    pub fn uv_local(self, p: Vec3, part: u32) -> (f32, f32) {
        use std::f32::consts::{PI, TAU};
        // (f32 with branch-free inverse trigonometry: f64 and the library's calls were
        // 6-8% of a render of three spheres.)
        let phi = crate::math::atan2(p.y, p.x) / TAU;
        let phi = phi - phi.floor();
        match self {
            Shape::Sphere => (phi, crate::math::acos(p.z) / PI),
            Shape::Cylinder | Shape::Cone => (phi, p.z - p.z.floor()),
            Shape::CappedCylinder | Shape::Tube if part == 0 => (phi, (p.z + 1.0) * 0.5),
            Shape::CappedCone if part == 0 => (phi, p.z),
            Shape::Box => {
                let axis = part as usize / 2;
                let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                ((p[a] + 1.0) * 0.5, (p[b] + 1.0) * 0.5)
            }
            // (Polar, as Mitsuba's disk: the radius, then the angle.)
            Shape::Disk => ((p.x * p.x + p.y * p.y).sqrt(), phi),
            _ => ((p.x + 1.0) * 0.5, (p.y + 1.0) * 0.5),
        }
    }

    /// The derivatives ∂p/∂u and ∂p/∂v (object space) of [`Shape::uv_local`]'s
    /// parameters at a point of part `part` (zero where they do not exist: a sphere's
    /// poles).
    #[must_use]
    pub fn uv_tangents_local(self, p: Vec3, part: u32) -> (Vec3, Vec3) {
        use std::f32::consts::{PI, TAU};
        let around = Vec3::new(-p.y, p.x, 0.0) * TAU;
        match self {
            Shape::Sphere => {
                let r = p.x.hypot(p.y);
                let dv = if r > 0.0 { Vec3::new(p.z * p.x / r, p.z * p.y / r, -r) * PI } else { Vec3::ZERO };
                (around, dv)
            }
            Shape::Cylinder | Shape::Cone => (around, Vec3::Z),
            Shape::CappedCylinder | Shape::Tube if part == 0 => (around, Vec3::Z * 2.0),
            Shape::CappedCone if part == 0 => (around, Vec3::Z),
            Shape::Box => {
                let axis = part as usize / 2;
                let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                let (mut du, mut dv) = (Vec3::ZERO, Vec3::ZERO);
                du[a] = 2.0;
                dv[b] = 2.0;
                (du, dv)
            }
            Shape::Disk => {
                let r = p.x.hypot(p.y);
                let du = if r > 0.0 { Vec3::new(p.x / r, p.y / r, 0.0) } else { Vec3::X };
                (du, around)
            }
            _ => (Vec3::X * 2.0, Vec3::Y * 2.0),
        }
    }

    /// Outward surface normal (object space, not normalized) at a point of part `part`.
    #[must_use]
    #[inline]
    pub fn normal_local(self, p: Vec3, part: u32) -> Vec3 {
        match (self, part) {
            (Shape::Sphere, _) => p,
            (Shape::Cylinder | Shape::CappedCylinder | Shape::Tube, 0) => Vec3::new(p.x, p.y, 0.0),
            (Shape::CappedCylinder, 1) => -Vec3::Z,
            (Shape::CappedCylinder, _) => Vec3::Z,
            (Shape::Cone, _) | (Shape::CappedCone, 0) => Vec3::new(p.x, p.y, -p.z),
            (Shape::CappedCone, _) => Vec3::Z,
            (Shape::Box, f) => {
                let mut n = Vec3::ZERO;
                n[(f / 2) as usize] = if f % 2 == 0 { -1.0 } else { 1.0 };
                n
            }
            (Shape::Disk, _) => Vec3::Z,
            (Shape::Cylinder | Shape::Tube, _) => Vec3::new(p.x, p.y, 0.0),
        }
    }
}

/// `γ(n) = n u / (1 − n u)` with `u = 2^-24`, the unit roundoff of `f32`: a bound on the
/// relative error of `n` rounded `f32` operations in sequence (Higham, "Accuracy and
/// Stability of Numerical Algorithms", §3.1; pbrt-v4 §6.8.1).
#[must_use]
pub const fn gamma(n: u32) -> f32 {
    let nu = n as f32 * (f32::EPSILON * 0.5);
    nu / (1.0 - nu)
}

/// Real roots of `a t² + 2 b t + c = 0`, ascending, computed without cancellation
/// (missing roots are NaN, which no range test accepts).
// PERF: a fixed array, not a Vec: this runs for every shape a ray meets.
fn quadric(a: f64, b: f64, c: f64) -> [f64; 2] {
    const NONE: [f64; 2] = [f64::NAN, f64::NAN];
    if a == 0.0 {
        return if b != 0.0 { [-c / (2.0 * b), f64::NAN] } else { NONE };
    }
    let disc = b * b - a * c;
    if disc < 0.0 {
        return NONE;
    }
    let sign = if b >= 0.0 { 1.0 } else { -1.0 };
    let q = -(b + sign * disc.sqrt());
    let (mut t0, mut t1) = if q != 0.0 { (q / a, c / q) } else { (0.0, 0.0) };
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    [t0, t1]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_hits_front() {
        let h = Shape::Sphere.intersect_local(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z, 0.0, f32::INFINITY).expect("hit");
        assert!((h.t - 4.0).abs() < 1e-6);
        let h = Shape::Sphere.intersect_local(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY).expect("inside");
        assert!((h.t - 1.0).abs() < 1e-6);
    }

    #[test]
    fn capped_cylinder_caps_and_side() {
        let s = Shape::CappedCylinder;
        let h = s.intersect_local(Vec3::new(0.2, 0.0, 5.0), -Vec3::Z, 0.0, f32::INFINITY).expect("cap");
        assert_eq!(h.part, 2);
        assert!((h.t - 4.0).abs() < 1e-6);
        let h = s.intersect_local(Vec3::new(5.0, 0.0, 0.5), -Vec3::X, 0.0, f32::INFINITY).expect("side");
        assert_eq!(h.part, 0);
        assert!((h.t - 4.0).abs() < 1e-6);
        assert!(s.intersect_local(Vec3::new(5.0, 0.0, 1.5), -Vec3::X, 0.0, f32::INFINITY).is_none());
        assert!(Shape::Cylinder.intersect_local(Vec3::new(5.0, 0.0, 100.0), -Vec3::X, 0.0, f32::INFINITY).is_some());
    }

    #[test]
    fn cones() {
        // Double cone: a ray along x at height z = 0.5 meets it at x = ±0.5.
        let h = Shape::Cone.intersect_local(Vec3::new(5.0, 0.0, 0.5), -Vec3::X, 0.0, f32::INFINITY).expect("hit");
        assert!((h.t - 4.5).abs() < 1e-6);
        let h = Shape::CappedCone.intersect_local(Vec3::new(0.0, 0.0, 5.0), -Vec3::Z, 0.0, f32::INFINITY).expect("cap");
        assert_eq!(h.part, 1);
        assert!(Shape::CappedCone.intersect_local(Vec3::new(5.0, 0.0, -0.5), -Vec3::X, 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn box_and_disk() {
        let h = Shape::Box.intersect_local(Vec3::new(0.0, 5.0, 0.0), -Vec3::Y, 0.0, f32::INFINITY).expect("box");
        assert!((h.t - 4.0).abs() < 1e-6);
        assert_eq!(Shape::Box.normal_local(Vec3::Y, h.part), Vec3::Y);
        let h = Shape::Disk.intersect_local(Vec3::new(0.5, 0.0, 2.0), -Vec3::Z, 0.0, f32::INFINITY).expect("disk");
        assert!((h.t - 2.0).abs() < 1e-6);
        assert!(Shape::Disk.intersect_local(Vec3::new(1.5, 0.0, 2.0), -Vec3::Z, 0.0, f32::INFINITY).is_none());
    }

    /// ∂p/∂u and ∂p/∂v are the derivatives of `uv_local`'s parameters: a step along
    /// either moves that parameter by the step and the other not (finite differences, away
    /// from seams and poles), on every shape with texture coordinates of its own.
    #[test]
    fn uv_tangents_are_the_derivatives_of_the_texture_coordinates() {
        let points: [(Shape, Vec3, u32); 6] = [
            (Shape::Sphere, Vec3::new(0.48, 0.36, 0.8).normalize(), 0),
            (Shape::Tube, Vec3::new(-0.6, 0.8, 0.3), 0),
            (Shape::CappedCylinder, Vec3::new(0.28, -0.96, -0.4), 0),
            (Shape::Box, Vec3::new(0.3, -0.2, 1.0), 5),
            (Shape::Disk, Vec3::new(-0.3, 0.4, 0.0), 0),
            (Shape::Disk, Vec3::new(0.05, -0.7, 0.0), 0),
        ];
        let h = 1e-3;
        for (shape, p, part) in points {
            let (u0, v0) = shape.uv_local(p, part);
            let (du, dv) = shape.uv_tangents_local(p, part);
            // (A step of h ∂p/∂u moves u by h, to first order.)
            let (uu, uv) = shape.uv_local(p + du * h, part);
            let (vu, vv) = shape.uv_local(p + dv * h, part);
            let tol = 0.02 * h;
            assert!((uu - u0 - h).abs() < tol && (uv - v0).abs() < tol, "{shape:?} along u: {} {}", uu - u0, uv - v0);
            assert!((vv - v0 - h).abs() < tol && (vu - u0).abs() < tol, "{shape:?} along v: {} {}", vu - u0, vv - v0);
        }
    }
}
