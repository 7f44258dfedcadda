//! Area lights: emitting triangles, parallelograms (two triangles of a mesh that make
//! one), spheres and disks, one-sided toward their normal as Mitsuba's `area` emitter.
//! Triangles, parallelograms and disks are sampled by area, spheres by the cone they
//! subtend (uniformly within it, Shirley and Wang 1994).

use super::sample::{EmissionSample, LightSample};
use crate::color::luminance;
use crate::sampling::{concentric_disk, cosine_hemisphere, uniform_cone, uniform_sphere};
use glam::{Affine3A, Vec2, Vec3};
use lucent_scene::{Material, Mesh, Scene, ShapeKind, Texture};
use std::f32::consts::PI;

/// Per mesh of `scene`: the triangles whose material emits (in order), the only ones a
/// light set looks at. Found once per mesh, not per instance (the sunflower field places
/// one mesh 5,622 times).
pub(crate) fn emissive_triangles(scene: &Scene) -> Vec<Box<[u32]>> {
    use rayon::prelude::*;
    let emits: Vec<bool> = scene.materials.iter().map(|m| m.emission.max_element() > 0.0).collect();
    scene
        .meshes
        .par_iter()
        .map(|mesh| {
            let material = |t: usize| mesh.material.get(t).copied().unwrap_or(0) as usize;
            if !emits.iter().any(|&e| e) {
                return Box::default();
            }
            (0..mesh.indices.len()).filter(|&t| emits.get(material(t)).copied().unwrap_or(false)).map(|t| t as u32).collect()
        })
        .collect()
}

/// One emitting triangle in world space.
#[derive(Clone, Copy, Debug)]
pub(crate) struct EmissiveTri {
    pub p0: Vec3,
    pub e1: Vec3,
    pub e2: Vec3,
    /// Unit normal `e1 × e2` (the emitting side).
    pub n: Vec3,
    pub area: f32,
    /// Emitted radiance (times the texture, when there is one).
    pub le: Vec3,
    /// Emission texture and the corners' texture coordinates.
    pub tex: Option<(u32, [Vec2; 3])>,
}

/// An area light.
#[derive(Clone, Debug)]
pub(crate) enum AreaLight {
    /// One emitting triangle.
    Tri(EmissiveTri),
    /// A sphere, centre and radius, emitting `le` outward.
    Sphere { c: Vec3, r: f32, le: Vec3 },
    /// Two emitting triangles of a mesh that make a parallelogram (a quad split along a
    /// diagonal, as Mitsuba's `rectangle` and OBJ's quads are), as one light: corner `p0`,
    /// edges `e1` and `e2`, its whole area. Sampled by a point of the parallelogram for
    /// the whole pair, so the sampler's 2-D stratification covers the light at once (two
    /// triangles split the samples by a choice, and each folds its square in two).
    Quad(EmissiveTri),
    /// A disk: centre, axes (scaled), unit normal, area.
    Disk { c: Vec3, ax: Vec3, ay: Vec3, n: Vec3, area: f32, le: Vec3 },
}

/// Triangle `t` of `mesh` (corners `idx`), placed by `to_world`, as a light of material
/// `mat` (which emits), with its power (`None` when it has none).
pub(crate) fn triangle(
    mesh: &Mesh,
    t: usize,
    idx: &[u32; 3],
    to_world: &Affine3A,
    mat: &Material,
    textures: &[Texture],
) -> Option<(AreaLight, f32)> {
    let [a, b, c] = idx.map(|i| to_world.transform_point3(mesh.positions.get(i as usize).copied().unwrap_or(Vec3::NAN)));
    let (e1, e2) = (b - a, c - a);
    let cross = e1.cross(e2);
    let area = 0.5 * cross.length();
    let tex = mat.emission_tex.filter(|&tx| (tx as usize) < textures.len()).map(|tx| {
        let uv = mesh.uvs.corners(t, idx).unwrap_or([Vec2::ZERO, Vec2::X, Vec2::Y]);
        (tx, uv)
    });
    let tex_mean = tex.map_or(1.0, |(t, uv)| {
        let c = (uv[0] + uv[1] + uv[2]) / 3.0;
        luminance(crate::texture::sample(&textures[t as usize], c).truncate()).max(1e-3)
    });
    let p = area * luminance(mat.emission) * tex_mean * PI;
    if !(p > 0.0 && p.is_finite()) {
        return None;
    }
    Some((AreaLight::Tri(EmissiveTri { p0: a, e1, e2, n: cross / (2.0 * area), area, le: mat.emission, tex }), p))
}

/// Triangles `t` and `t2` of `mesh` (lights `a` and `b`, as [`triangle`] made them) as
/// one [`AreaLight::Quad`] when they share two vertices (by index), face one way, emit
/// alike without a texture, and their other corners complete a parallelogram; with its
/// power. `None` otherwise.
pub(crate) fn quad(
    mesh: &Mesh,
    (t, a): (usize, &AreaLight),
    (t2, b): (usize, &AreaLight),
    to_world: &Affine3A,
) -> Option<(AreaLight, f32)> {
    let (AreaLight::Tri(a), AreaLight::Tri(b)) = (a, b) else { return None };
    if a.tex.is_some() || b.tex.is_some() || a.le != b.le || a.n.dot(b.n) < 1.0 - 1e-5 {
        return None;
    }
    let (ia, ib) = (mesh.indices.get(t)?, mesh.indices.get(t2)?);
    let shared: Vec<u32> = ia.iter().copied().filter(|i| ib.contains(i)).collect();
    let [s0, s1] = shared[..] else { return None };
    let other = |idx: &[u32; 3]| idx.iter().copied().find(|&i| i != s0 && i != s1);
    let at = |i: u32| mesh.positions.get(i as usize).map(|&q| to_world.transform_point3(q));
    let (pa, pb, q0, q1) = (at(other(ia)?)?, at(other(ib)?)?, at(s0)?, at(s1)?);
    let scale = (q1 - q0).length().max((pb - pa).length());
    if scale.is_nan() || scale <= 0.0 || (pa + pb - q0 - q1).length() > 1e-5 * scale {
        return None;
    }
    let (e1, e2) = (q0 - pa, q1 - pa);
    let area = e1.cross(e2).length();
    let p = area * luminance(a.le) * PI;
    (area > 0.0 && p > 0.0 && p.is_finite())
        .then_some((AreaLight::Quad(EmissiveTri { p0: pa, e1, e2, n: a.n, area, le: a.le, tex: None }), p))
}

/// An analytic shape of kind `kind` placed by `m`, emitting `le`, as a light with its
/// power (`None` for shapes that are not sampled: they are lit only where rays meet them).
pub(crate) fn shape(kind: ShapeKind, m: &Affine3A, le: Vec3) -> Option<(AreaLight, f32)> {
    let light = match kind {
        ShapeKind::Sphere => {
            // Only a sphere (a similarity transform) is sampled by its cone.
            let (sx, sy, sz) = (m.matrix3.x_axis.length(), m.matrix3.y_axis.length(), m.matrix3.z_axis.length());
            if (sx - sy).abs() > 1e-4 * sx || (sx - sz).abs() > 1e-4 * sx {
                tracing::warn!("an emitting ellipsoid is lit only where rays meet it (no light sampling)");
                return None;
            }
            AreaLight::Sphere { c: m.translation.into(), r: sx, le }
        }
        ShapeKind::Disk => {
            let (ax, ay): (Vec3, Vec3) = (m.matrix3.x_axis.into(), m.matrix3.y_axis.into());
            let cross = ax.cross(ay);
            AreaLight::Disk { c: m.translation.into(), ax, ay, n: cross.normalize_or_zero(), area: PI * cross.length(), le }
        }
        _ => {
            tracing::warn!("an emitting {kind:?} is lit only where rays meet it (no light sampling)");
            return None;
        }
    };
    let p = match &light {
        AreaLight::Sphere { r, .. } => 4.0 * PI * r * r,
        AreaLight::Disk { area, .. } => *area,
        AreaLight::Tri(_) | AreaLight::Quad(_) => 0.0,
    } * luminance(le)
        * PI;
    (p > 0.0 && p.is_finite()).then_some((light, p))
}

/// The emitted radiance of triangle `t` at barycentrics (a, b) (times its texture).
fn tri_radiance(t: &EmissiveTri, a: f32, b: f32, textures: &[Texture]) -> Vec3 {
    match t.tex {
        Some((tex, uv)) => {
            let uvq = uv[0] * (1.0 - a - b) + uv[1] * a + uv[2] * b;
            t.le * crate::texture::sample(&textures[tex as usize], uvq).truncate()
        }
        None => t.le,
    }
}

/// A uniform point of a triangle for `u`, as barycentrics (branch-free).
#[inline(always)]
pub(crate) fn tri_point(u: (f32, f32)) -> (f32, f32) {
    let (a, b) = u;
    let fold = a + b > 1.0;
    (if fold { 1.0 - a } else { a }, if fold { 1.0 - b } else { b })
}

impl AreaLight {
    /// A sample toward the light from `p` (a point on it by `u2`), its density per solid
    /// angle not yet times the light's choice.
    pub(crate) fn sample(&self, p: Vec3, u2: (f32, f32), textures: &[Texture]) -> Option<LightSample> {
        match self {
            Self::Tri(t) => {
                let (a, b) = tri_point(u2);
                let q = t.p0 + t.e1 * a + t.e2 * b;
                area_sample(p, q, t.n, t.area, tri_radiance(t, a, b, textures))
            }
            Self::Quad(t) => area_sample(p, t.p0 + t.e1 * u2.0 + t.e2 * u2.1, t.n, t.area, t.le),
            Self::Sphere { c, r, le } => sphere_sample(p, *c, *r, *le, u2),
            Self::Disk { c, ax, ay, n, area, le } => {
                let d = concentric_disk(u2);
                area_sample(p, *c + *ax * d.x + *ay * d.y, *n, *area, *le)
            }
        }
    }

    /// The density with which [`AreaLight::sample`] from `p` picks its point `q`, seen
    /// along unit `dir` (`d2`: the squared distance from `p` to `q`).
    pub(crate) fn pdf(&self, p: Vec3, q: Vec3, dir: Vec3, d2: f32) -> f32 {
        match self {
            Self::Tri(t) | Self::Quad(t) => d2 / (t.area * t.n.dot(-dir).abs().max(1e-12)),
            Self::Disk { n, area, .. } => d2 / (area * n.dot(-dir).abs().max(1e-12)),
            Self::Sphere { c, r, .. } => sphere_pdf(p, *c, *r, q, dir),
        }
    }

    /// A ray of light leaving it: a uniform point (by `u_pos`), a cosine-weighted direction
    /// (by `u_dir`); its flux not yet over the light's choice.
    pub(crate) fn emit(&self, u_pos: (f32, f32), u_dir: (f32, f32), textures: &[Texture]) -> Option<EmissionSample> {
        match self {
            Self::Tri(t) => {
                let (a, b) = tri_point(u_pos);
                area_emission(t.p0 + t.e1 * a + t.e2 * b, t.n, t.area, tri_radiance(t, a, b, textures), u_dir)
            }
            Self::Quad(t) => area_emission(t.p0 + t.e1 * u_pos.0 + t.e2 * u_pos.1, t.n, t.area, t.le, u_dir),
            Self::Sphere { c, r, le } => {
                let n = uniform_sphere(u_pos);
                area_emission(*c + n * *r, n, 4.0 * PI * r * r, *le, u_dir)
            }
            Self::Disk { c, ax, ay, n, area, le } => {
                let d = concentric_disk(u_pos);
                area_emission(*c + *ax * d.x + *ay * d.y, *n, *area, *le, u_dir)
            }
        }
    }
}

/// A point and a cosine-weighted direction about `n` leaving an area light of radiance
/// `le` and area `area`: the flux is `le · area · π`.
fn area_emission(q: Vec3, n: Vec3, area: f32, le: Vec3, u: (f32, f32)) -> Option<EmissionSample> {
    let local = cosine_hemisphere(u);
    let (t, b) = n.any_orthonormal_pair();
    let dir = (t * local.x + b * local.y + n * local.z).normalize_or_zero();
    (local.z > 0.0 && dir != Vec3::ZERO).then_some(EmissionSample { p: q, dir, n: Some(n), flux: le * (area * PI) })
}

/// An area light's point `q` (normal `n`, one-sided, of total area `area`) seen from `p`.
fn area_sample(p: Vec3, q: Vec3, n: Vec3, area: f32, le: Vec3) -> Option<LightSample> {
    let (s, ok) = area_sample_lane(p, q, n, area, le);
    ok.then_some(s)
}

/// [`area_sample`] without a branch (for loops over lanes): the sample and whether there
/// is one (when not, its fields mean nothing).
#[inline(always)]
pub(crate) fn area_sample_lane(p: Vec3, q: Vec3, n: Vec3, area: f32, le: Vec3) -> (LightSample, bool) {
    let to = q - p;
    let dist = to.length();
    let dir = to / dist;
    let cos_l = n.dot(-dir);
    let ok = (cos_l > 0.0) & (dist > 0.0) & dist.is_finite();
    (LightSample { dir, dist, li: le, pdf: dist * dist / (cos_l * area), delta: false }, ok)
}

/// A direction toward a sphere: uniformly within the cone it subtends from outside
/// ([`uniform_cone`]), or toward a uniformly chosen point of it from inside.
fn sphere_sample(p: Vec3, c: Vec3, r: f32, le: Vec3, u: (f32, f32)) -> Option<LightSample> {
    let to_c = c - p;
    let d2 = to_c.length_squared();
    if d2 <= r * r * (1.0 + 1e-4) {
        // Inside (or on): a uniform point of the surface, seen from p.
        let n = uniform_sphere(u);
        return area_sample(p, c + n * r, -n, 4.0 * PI * r * r, le).map(|mut x| {
            // (It emits outward; seen from inside, its inner side does not emit.)
            x.li = Vec3::ZERO;
            x
        });
    }
    let d = d2.sqrt();
    let w = to_c / d;
    let sin2_max = (r * r / d2).min(1.0);
    let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
    let dir = uniform_cone(w, cos_max, u);
    // The nearer intersection of the ray with the sphere.
    let bq = dir.dot(to_c);
    let disc = bq * bq - (d2 - r * r);
    let dist = bq - disc.max(0.0).sqrt();
    let pdf = 1.0 / (2.0 * PI * (1.0 - cos_max));
    (dist > 0.0 && pdf.is_finite()).then_some(LightSample { dir, dist, li: le, pdf, delta: false })
}

/// [`sphere_sample`]'s density for the direction `dir` meeting the sphere at `q`.
fn sphere_pdf(p: Vec3, c: Vec3, r: f32, q: Vec3, dir: Vec3) -> f32 {
    let d2 = (c - p).length_squared();
    if d2 <= r * r * (1.0 + 1e-4) {
        // (Seen from inside the light gives nothing: no density needed.)
        let n = (q - c) / r;
        return (q - p).length_squared() / (4.0 * PI * r * r * n.dot(dir).abs().max(1e-12));
    }
    let cos_max = (1.0 - (r * r / d2).min(1.0)).max(0.0).sqrt();
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_scene::Attr;

    /// An emission texture is read at the triangle's own texture coordinates, also where
    /// they have index triples of their own (OBJ's `f v/vt`): triangle 1's light samples
    /// its uvs, not triangle 0's (the texture's index once stood in for the triangle's).
    #[test]
    fn an_emission_texture_is_read_at_the_triangles_own_uvs() {
        let mesh = Mesh {
            name: "lamp".into(),
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE],
            indices: vec![[0, 1, 2], [1, 3, 2]],
            uvs: Attr {
                values: vec![Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE, Vec2::splat(0.5)],
                indices: Some(vec![[0, 1, 2], [3, 4, 3]]),
            },
            material: vec![0, 0],
            ..Mesh::default()
        };
        let tex = Texture::new("white".into(), 1, 1, vec![[255; 4]], false, Default::default(), Default::default());
        let mat = Material { emission: Vec3::ONE, emission_tex: Some(0), ..Material::default() };
        let (light, _) = triangle(&mesh, 1, &mesh.indices[1], &Affine3A::IDENTITY, &mat, &[tex]).expect("a light");
        let AreaLight::Tri(t) = light else { panic!("a triangle") };
        assert_eq!(t.tex.map(|(_, uv)| uv), Some([Vec2::ONE, Vec2::splat(0.5), Vec2::ONE]));
    }
}
