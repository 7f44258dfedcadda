//! Surface points rebuilt from hits: position, normals, texture coordinates, material and
//! a bound on the position's floating-point error, from which secondary rays start.

use super::{face_normal, shape_of, World};
use glam::{Vec2, Vec3};
use lucent_accel::{Hit, Ray};
use lucent_scene::Geom;

/// A surface point rebuilt from a hit.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    /// World position.
    pub p: Vec3,
    /// Geometric normal (world, unit, as the geometry is wound).
    pub ng: Vec3,
    /// Shading normal (world, unit, same side as `ng`).
    pub ns: Vec3,
    /// Texture coordinates (left at zero on analytic shapes whose material has no texture).
    pub uv: Vec2,
    /// Material index.
    pub material: u32,
    /// A bound on the floating-point error of each coordinate of `p`, and on how far from
    /// the surface the intersection tests may still meet a ray starting there: see
    /// [`Surface::offset`].
    pub p_err: Vec3,
}

impl Surface {
    /// How far along the geometric normal a ray leaving the surface starts: the error
    /// bound projected on the normal, `|ng| · p_err` (pbrt-v4 §6.8.6, "Robust Spawned Ray
    /// Origins"), so that every point within `p_err` of `p` lies behind the plane through
    /// the new origin parallel to the surface, and the new ray cannot meet the surface it
    /// leaves. Two margins for the addition `p + offset · ng` itself, which is rounded: a
    /// whole ulp of each coordinate (`ε |ng| · |p|`; rounding costs at most half of one
    /// along the normal), and the least normal float, so that a zero bound (a point
    /// computed exactly, on a plane the tests evaluate exactly, such as x = 0) still
    /// leaves the plane. (pbrt rounds each coordinate on to the next float instead; per
    /// lane that took 6% of a shaded frame.)
    #[inline]
    #[must_use]
    pub fn offset(&self) -> f32 {
        self.ng.abs().dot(self.p_err + self.p.abs() * f32::EPSILON) + f32::MIN_POSITIVE
    }

    /// A ray leaving the surface along `dir`: its origin moved off `p` by
    /// [`Surface::offset`] to the side `dir` goes. The one way secondary rays start (the
    /// Whitted shader's lanes do the same arithmetic).
    #[inline]
    #[must_use]
    pub fn spawn(&self, dir: Vec3) -> Ray {
        let n = if dir.dot(self.ng) < 0.0 { -self.ng } else { self.ng };
        Ray::new(self.p + n * self.offset(), dir)
    }
}

impl World {
    /// Asks for the cache lines [`World::surface`] reads first for hit `h` (a mesh
    /// triangle's face normal, material and corners), so that the misses of many hits
    /// overlap when their surfaces are made after all of them are found.
    #[inline]
    pub(crate) fn prefetch_surface(&self, h: &Hit) {
        let Some(inst) = self.info.get(h.inst as usize) else { return };
        if let Geom::Mesh(m) = inst.geom {
            let tri = h.prim as usize;
            if let Some(f) = self.faces.get(m as usize).and_then(|f| f.get(tri)) {
                lucent_accel::traverse::prefetch(f);
            }
            if let Some(mesh) = self.scene.meshes.get(m as usize) {
                if let Some(t) = mesh.material.get(tri) {
                    lucent_accel::traverse::prefetch(t);
                }
                if let Some(idx) = mesh.indices.get(tri) {
                    lucent_accel::traverse::prefetch(idx);
                }
            }
        }
    }

    /// The unit geometric normal of a hit in world space, the one [`World::surface`] gives
    /// (a triangle's by its winding, `(b − a) × (c − a)`; a shape's outward), without the
    /// rest of the surface point: what ray queries report. Zero for a hit this world does
    /// not hold, or a degenerate triangle.
    #[must_use]
    pub fn geometric_normal(&self, r: &Ray, h: &Hit) -> Vec3 {
        let (Some(inst), Some(placed)) = (self.info.get(h.inst as usize), self.accel.instances().get(h.inst as usize)) else {
            return Vec3::ZERO;
        };
        let n_obj = match inst.geom {
            Geom::Mesh(m) => match self.faces.get(m as usize).and_then(|f| f.get(h.prim as usize)) {
                Some(f) => *f,
                None => return Vec3::ZERO,
            },
            Geom::Shape { kind, .. } => {
                let p_obj = placed.object_from_world.transform_point3(r.at(h.t));
                shape_of(kind).normal_local(p_obj, h.prim)
            }
        };
        if inst.identity {
            n_obj
        } else {
            (inst.normal_to_world * glam::Vec3A::from(n_obj)).normalize_or_zero().into()
        }
    }

    /// The texture coordinates of an analytic shape's hit, computed whether or not its
    /// material reads them (`None` for meshes: [`World::surface`] has theirs).
    #[must_use]
    pub fn shape_uv(&self, r: &Ray, h: &Hit) -> Option<Vec2> {
        let inst = self.info.get(h.inst as usize)?;
        let Geom::Shape { kind, .. } = inst.geom else { return None };
        let p_obj = self.accel.instances().get(h.inst as usize)?.object_from_world.transform_point3(r.at(h.t));
        let (u, v) = shape_of(kind).uv_local(p_obj, h.prim);
        Some(Vec2::new(u, v))
    }

    /// The material index of a hit, the one [`World::surface`] gives, without the rest
    /// of the surface point.
    #[must_use]
    pub fn material_of(&self, h: &Hit) -> u32 {
        match self.info.get(h.inst as usize).map(|i| i.geom) {
            Some(Geom::Mesh(m)) => {
                self.scene.meshes.get(m as usize).and_then(|mesh| mesh.material.get(h.prim as usize)).copied().unwrap_or(0)
            }
            Some(Geom::Shape { material, .. }) => material,
            None => 0,
        }
    }

    /// Rebuilds the surface point of a hit.
    #[must_use]
    pub fn surface(&self, r: &Ray, h: &Hit) -> Surface {
        let inst = &self.info[h.inst as usize];
        let object_from_world = &self.accel.instances()[h.inst as usize].object_from_world;
        match inst.geom {
            Geom::Mesh(m) => {
                let mesh = &self.scene.meshes[m as usize];
                let tri = h.prim as usize;
                // The hit point `o + t d`, and a bound on its distance from the triangle's
                // plane as the triangle test sees it (the unit-triangle test, `triangle.rs`,
                // has no error bound on t of its own): its map is rounded to f32 (2^-24 of
                // each entry) and evaluated at the origin with three fused multiply-adds,
                // and t = -z(o) / z(d) with z(d) rounded as much, so the point found lies
                // within γ(9)·(|o| + |t d|) + γ(6)·|p| of the plane in each coordinate (the
                // plane's own offset, |n · p0| = |n · p| there, counted by the |p| term).
                // An error in t moves the point along the ray, which is why no division by
                // the ray's slope appears: what matters is the distance from the plane.
                // PERF: no vertex is read (rebuilding p from its barycentrics, as pbrt-v4
                // §6.8.5 does, reads three, and took 10% of a shaded Conference frame).
                let p = r.at(h.t);
                let (oa, td) = (r.org.abs(), (r.dir * h.t).abs());
                let p_err = (oa + td) * lucent_accel::gamma(9) + p.abs() * lucent_accel::gamma(6);
                let p_err = if inst.in_place {
                    p_err
                } else {
                    // The test ran in object space, on the ray carried there by the inverse
                    // (rounded: γ(3) of its terms) and against the same bound there, so
                    // those errors show in world space through |M| (`err_k`, `err_c`).
                    p_err
                        + Vec3::from(inst.err_k * glam::Vec3A::from(oa + td + p.abs()) + glam::Vec3A::from(inst.err_c))
                            * lucent_accel::gamma(12)
                };
                let ng_obj = match self.faces.get(m as usize).and_then(|f| f.get(tri)) {
                    Some(f) => *f,
                    None => face_normal(&mesh.positions, &mesh.indices[tri]),
                };
                let ng = if inst.identity { ng_obj } else { (inst.normal_to_world * glam::Vec3A::from(ng_obj)).normalize_or_zero().into() };
                let w = Vec3::new(1.0 - h.u - h.v, h.u, h.v);
                // The vertex indices only for per-vertex normals or texture coordinates.
                let idx = if mesh.normals.values.is_empty() && mesh.uvs.values.is_empty() { [0; 3] } else { mesh.indices[tri] };
                let ns = match mesh.normals.corners(tri, &idx) {
                    Some([n0, n1, n2]) => {
                        let n: Vec3 = (inst.normal_to_world * glam::Vec3A::from(n0 * w.x + n1 * w.y + n2 * w.z)).into();
                        let n = n.normalize_or_zero();
                        if n == Vec3::ZERO || !n.is_finite() {
                            ng
                        } else if n.dot(ng) < 0.0 {
                            // Keep shading normals on the geometric side (flipped winding).
                            -n
                        } else {
                            n
                        }
                    }
                    None => ng,
                };
                let uv = mesh.uvs.corners(tri, &idx).map_or(Vec2::new(h.u, h.v), |[t0, t1, t2]| t0 * w.x + t1 * w.y + t2 * w.z);
                Surface { p, ng, ns, uv, material: mesh.material.get(tri).copied().unwrap_or(0), p_err }
            }
            Geom::Shape { kind, material } => {
                // The hit point `o + t d`. The shape tests solve in f64 (exact next to
                // f32, even near tangency, where a root's error is about the square root
                // of f64's unit roundoff), on the ray carried into object space by the
                // inverse in f32 (γ(3) of its terms): the point is off the surface by at
                // most that carried error, seen through |M| (`err_k`, `err_c`), plus the
                // rounding of t and of `o + t d`.
                let p = r.at(h.t);
                let ot = r.org.abs() + (r.dir * h.t).abs();
                let p_err = ot * lucent_accel::gamma(5)
                    + Vec3::from(inst.err_k * glam::Vec3A::from(ot) + glam::Vec3A::from(inst.err_c)) * lucent_accel::gamma(4);
                let p_obj = object_from_world.transform_point3(p);
                let n_obj = shape_of(kind).normal_local(p_obj, h.prim);
                let ng: Vec3 = (inst.normal_to_world * glam::Vec3A::from(n_obj)).normalize_or_zero().into();
                // PERF: the uv (atan2, acos) only for textured materials (a tenth of a
                // 4,096-sphere REND3R frame went to uvs nobody read).
                let uv = if self.prepared(material).uses_uv {
                    let (u, v) = shape_of(kind).uv_local(p_obj, h.prim);
                    Vec2::new(u, v)
                } else {
                    Vec2::ZERO
                };
                Surface { p, ng, ns: ng, uv, material, p_err }
            }
        }
    }

    /// The world-space derivatives ∂p/∂u and ∂p/∂v of a mesh hit's triangle, from its
    /// corners' texture coordinates (`None` for shapes, meshes without texture coordinates
    /// and triangles whose coordinates are degenerate).
    #[must_use]
    pub fn uv_tangents(&self, r: &Ray, h: &Hit) -> Option<(Vec3, Vec3)> {
        let inst = self.info.get(h.inst as usize)?;
        let m = match inst.geom {
            Geom::Mesh(m) => m,
            Geom::Shape { kind, .. } => {
                let placed = &self.accel.instances()[h.inst as usize];
                let (world_from_object, p_obj) = (placed.world_from_object, placed.object_from_world.transform_point3(r.at(h.t)));
                let (du, dv) = shape_of(kind).uv_tangents_local(p_obj, h.prim);
                let (u, v) = (world_from_object.transform_vector3(du), world_from_object.transform_vector3(dv));
                return (u.is_finite() && v.is_finite() && u != Vec3::ZERO).then_some((u, v));
            }
        };
        let mesh = self.scene.meshes.get(m as usize)?;
        let idx = *mesh.indices.get(h.prim as usize)?;
        let [t0, t1, t2] = mesh.uvs.corners(h.prim as usize, &idx)?;
        let p = idx.map(|i| mesh.positions.get(i as usize).copied().unwrap_or(Vec3::NAN));
        let (dp1, dp2) = (p[1] - p[0], p[2] - p[0]);
        let (d1, d2) = (t1 - t0, t2 - t0);
        let det = d1.x * d2.y - d1.y * d2.x;
        if det.abs() < 1e-20 || !det.is_finite() {
            return None;
        }
        let dpdu = (dp1 * d2.y - dp2 * d1.y) / det;
        let dpdv = (dp2 * d1.x - dp1 * d2.x) / det;
        let m3 = self.accel.instances()[h.inst as usize].world_from_object.matrix3;
        let (u, v): (Vec3, Vec3) = ((m3 * glam::Vec3A::from(dpdu)).into(), (m3 * glam::Vec3A::from(dpdv)).into());
        (u.is_finite() && v.is_finite()).then_some((u, v))
    }
}
