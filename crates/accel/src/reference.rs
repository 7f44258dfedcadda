//! Brute-force reference kernels: every fast kernel is tested against these.

use crate::geom::{Hit, Ray, INVALID};
use crate::shape::Shape;
use crate::triangle::{unit_map_possible, unit_triangle_hit, UnitTriangle, WatertightRay};
use glam::{Affine3A, Vec3};

/// Closest hit over all triangles with the unit-triangle test.
#[must_use]
pub fn intersect_triangles(positions: &[Vec3], indices: &[[u32; 3]], ray: &Ray) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    let mut tmax = ray.tmax;
    for (i, t) in indices.iter().enumerate() {
        let Some(u) = UnitTriangle::new(positions[t[0] as usize], positions[t[1] as usize], positions[t[2] as usize]) else {
            continue;
        };
        if let Some((t, u, v)) = unit_triangle_hit(&u, ray.org, ray.dir, ray.tmin, tmax) {
            tmax = t;
            best = Some(Hit { t, u, v, prim: i as u32, inst: INVALID });
        }
    }
    best
}

/// Closest hit over all triangles with the watertight test.
#[must_use]
pub fn intersect_triangles_watertight(positions: &[Vec3], indices: &[[u32; 3]], ray: &Ray) -> Option<Hit> {
    let w = WatertightRay::new(ray.org, ray.dir);
    let mut best: Option<Hit> = None;
    let mut tmax = ray.tmax;
    for (i, t) in indices.iter().enumerate() {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        // The triangles a build keeps (degenerate ones and those out of range are left out).
        if !unit_map_possible(a, b, c) {
            continue;
        }
        if let Some((t, u, v)) = w.hit(a, b, c, ray.tmin, tmax) {
            tmax = t;
            best = Some(Hit { t, u, v, prim: i as u32, inst: INVALID });
        }
    }
    best
}

/// Any hit over all triangles (unit-triangle test).
#[must_use]
pub fn occluded_triangles(positions: &[Vec3], indices: &[[u32; 3]], ray: &Ray) -> bool {
    indices.iter().any(|t| {
        UnitTriangle::new(positions[t[0] as usize], positions[t[1] as usize], positions[t[2] as usize])
            .is_some_and(|u| unit_triangle_hit(&u, ray.org, ray.dir, ray.tmin, ray.tmax).is_some())
    })
}

/// What a reference instance draws.
#[derive(Clone, Copy, Debug)]
pub enum RefGeometry<'a> {
    /// Triangles.
    Mesh(&'a [Vec3], &'a [[u32; 3]]),
    /// A shape.
    Shape(Shape),
}

/// Closest hit over instances, each tested in full.
#[must_use]
pub fn intersect_instances(geoms: &[RefGeometry<'_>], instances: &[(u32, Affine3A)], ray: &Ray) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    let mut tmax = ray.tmax;
    for (id, (g, world_from_object)) in instances.iter().enumerate() {
        let local = Ray { tmax, ..*ray }.transformed(&world_from_object.inverse());
        let h = match geoms[*g as usize] {
            RefGeometry::Mesh(p, i) => intersect_triangles(p, i, &local),
            RefGeometry::Shape(s) => s.intersect_local(local.org, local.dir, local.tmin, local.tmax).map(|h| Hit {
                t: h.t,
                u: 0.0,
                v: 0.0,
                prim: h.part,
                inst: 0,
            }),
        };
        if let Some(mut h) = h {
            h.inst = id as u32;
            tmax = h.t;
            best = Some(h);
        }
    }
    best
}

/// Every hit over instances within the ray's range, each geometry tested in full, sorted
/// by distance (ties by instance, then primitive): the reference of
/// [`crate::TwoLevel::intersect_all`]. `watertight` picks the triangle test.
#[must_use]
pub fn all_hits_instances(geoms: &[RefGeometry<'_>], instances: &[(u32, Affine3A)], ray: &Ray, watertight: bool) -> Vec<Hit> {
    let mut out = Vec::new();
    for (id, (g, world_from_object)) in instances.iter().enumerate() {
        let local = ray.transformed(&world_from_object.inverse());
        match geoms[*g as usize] {
            RefGeometry::Mesh(p, idx) => {
                let w = WatertightRay::new(local.org, local.dir);
                for (i, t) in idx.iter().enumerate() {
                    let [a, b, c] = t.map(|i| p[i as usize]);
                    let h = if watertight {
                        unit_map_possible(a, b, c).then(|| w.hit(a, b, c, local.tmin, local.tmax)).flatten()
                    } else {
                        UnitTriangle::new(a, b, c).and_then(|u| unit_triangle_hit(&u, local.org, local.dir, local.tmin, local.tmax))
                    };
                    if let Some((t, u, v)) = h {
                        out.push(Hit { t, u, v, prim: i as u32, inst: id as u32 });
                    }
                }
            }
            RefGeometry::Shape(s) => {
                let mut tmin = local.tmin;
                while let Some(h) = s.intersect_local(local.org, local.dir, tmin, local.tmax) {
                    out.push(Hit { t: h.t, u: 0.0, v: 0.0, prim: h.part, inst: id as u32 });
                    tmin = h.t.next_up();
                }
            }
        }
    }
    out.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.inst.cmp(&b.inst)).then(a.prim.cmp(&b.prim)));
    out
}
