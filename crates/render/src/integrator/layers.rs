//! The layers of Mitsuba 3's `aov` integrator (`integrators/aov.cpp`, as its documentation
//! and source define them) and the alpha of a film whose `pixel_format` has one: a value
//! of the first surface a camera ray meets, zero where it meets none, rendered through the
//! tile loop like any image (so averaged over a pixel's samples with the film's filter).
//!
//! - depth: the distance along the ray; position, geometric and shading normals (not
//!   turned toward the viewer), texture coordinates (analytic shapes' too), ∂p/∂u and
//!   ∂p/∂v (meshes with texture coordinates; zero elsewhere);
//! - albedo: the diffuse reflectance where the model has one, else Mitsuba's default, the
//!   BSDF's value toward the normal times π (zero for smooth conductors and glass);
//! - the primitive's index; the shape's, numbered in lucent's order from 1 (Mitsuba's is
//!   its object registry's id, which another renderer cannot reproduce);
//! - alpha: 1 where the ray meets a surface, or anything at all under an environment.

use super::hit::{bsdf_frame, shading_normal};
use crate::world::World;
use glam::Vec3;
use lucent_accel::Ray;
use lucent_scene::AovKind;
use std::f32::consts::PI;

/// The layer `kind` along camera ray `ray` (its channels in x, y, z).
#[must_use]
pub fn value(w: &World, ray: &Ray, kind: AovKind) -> Vec3 {
    let Some(hit) = w.intersect(ray) else {
        return if kind == AovKind::Alpha && w.scene.environment.is_some() { Vec3::ONE } else { Vec3::ZERO };
    };
    let surf = w.surface(ray, &hit);
    match kind {
        AovKind::Alpha => Vec3::ONE,
        AovKind::Depth => Vec3::splat(hit.t * ray.dir.length()),
        AovKind::Position => surf.p,
        AovKind::Uv => {
            let uv = w.shape_uv(ray, &hit).unwrap_or(surf.uv);
            Vec3::new(uv.x, uv.y, 0.0)
        }
        AovKind::GeoNormal => surf.ng,
        AovKind::ShNormal => surf.ns,
        AovKind::DpDu => w.uv_tangents(ray, &hit).map_or(Vec3::ZERO, |t| t.0),
        AovKind::DpDv => w.uv_tangents(ray, &hit).map_or(Vec3::ZERO, |t| t.1),
        AovKind::PrimIndex => Vec3::splat(hit.prim as f32),
        AovKind::ShapeIndex => Vec3::splat((hit.inst + 1) as f32),
        AovKind::Albedo => {
            let textures = &w.scene.textures;
            match w.prepared(surf.material).diffuse_reflectance(textures, surf.uv) {
                Some(c) => c,
                None => {
                    let d = ray.dir.normalize();
                    let ns = shading_normal(w, ray, &hit, &surf);
                    let (bsdf, frame) = bsdf_frame(w, ray, &hit, &surf, ns, d);
                    bsdf.eval(frame.to_local(-d), Vec3::Z) * PI
                }
            }
        }
    }
}
