//! The lights the path tracer samples (next-event estimation), one chosen uniformly among
//! the light objects and, within an emitting mesh, a triangle in proportion to its power
//! (see [`LightSet::of`]): emitting triangles and emitting spheres and disks (area lights, one-sided
//! toward their normal as Mitsuba's `area` emitter), the scene's point, spot and
//! directional lights, the environment (constant, or an equirectangular map sampled by
//! its luminance), and lights of the library user's own ([`LightModel`]).
//!
//! Densities are per solid angle at the shading point, the choice among lights included;
//! a delta light's "density" is the probability of choosing it.

pub use crate::world::luminance;
use glam::{Affine3A, Vec2, Vec3};
use lucent_scene::{Environment, Geom, HdrImage, LightKind, Scene, ShapeKind};
use std::collections::HashMap;
use std::f32::consts::PI;
use std::sync::Arc;

/// No light.
const NONE: u32 = u32::MAX;

/// A light's answer for one shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point toward the light.
    pub dir: Vec3,
    /// Distance to the light's point (infinite for directional and environment lights).
    pub dist: f32,
    /// Radiance arriving along `dir` (for a delta light: its intensity over the squared
    /// distance, the irradiance it gives at normal incidence).
    pub li: Vec3,
    /// Density per solid angle of this direction (for a delta light: its probability).
    pub pdf: f32,
    /// A delta light (point, spot, directional, or the user's): no BSDF ray can meet it.
    pub delta: bool,
}

/// A light of the library user's own: it answers for a shading point with a direction,
/// the radiance arriving and the density of its choice (see [`LightSample`]). Rays never
/// meet it (it has no geometry), so it is treated as a delta light in multiple importance
/// sampling. Give it to [`crate::World::add_light`]; `examples/custom_bsdf.rs` shows one.
pub trait LightModel: Send + Sync + std::fmt::Debug {
    /// A sample toward the light from `p`, for `u` in [0, 1)².
    fn sample(&self, p: Vec3, u: (f32, f32)) -> Option<LightSample>;
    /// Its power (watts in the scene's units), for choosing among lights.
    fn power(&self) -> f32;
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

/// An environment light.
#[derive(Clone, Debug)]
pub(crate) struct EnvLight {
    scale: Vec3,
    map: Option<(Arc<HdrImage>, Distribution2D)>,
    to_world: Affine3A,
    to_local: Affine3A,
    /// Mean radiance (power estimate).
    mean: Vec3,
}

#[derive(Clone, Debug)]
enum Entry {
    Tri(EmissiveTri),
    /// A sphere, centre and radius, emitting `le` outward.
    Sphere {
        c: Vec3,
        r: f32,
        le: Vec3,
    },
    /// A disk: centre, axes (scaled), unit normal, area.
    Disk {
        c: Vec3,
        ax: Vec3,
        ay: Vec3,
        n: Vec3,
        area: f32,
        le: Vec3,
    },
    /// Scene light `i`.
    Delta(usize),
    Env,
    Custom(Arc<dyn LightModel>),
}

/// The lights of a scene, for sampling.
#[derive(Clone, Debug, Default)]
pub(crate) struct LightSet {
    entries: Vec<Entry>,
    /// Cumulative power, normalised.
    cdf: Vec<f32>,
    /// Per instance: for an instance with emitting triangles, each triangle's entry
    /// (`NONE` for the others); for an emitting shape, its entry alone.
    /// PERF: indexed, not hashed (a hash lookup per emitter met by a BSDF ray).
    index: Vec<Option<Box<[u32]>>>,
    env: Option<(u32, EnvLight)>,
    /// The scene's lights (point, spot, directional), as posed.
    delta: Vec<lucent_scene::Light>,
    /// Radius of the scene's bounding sphere (directional and environment power).
    radius: f32,
    /// Centre of the scene's bounding sphere (where directional and environment light
    /// paths start from).
    centre: Vec3,
    /// The scene's bounds the set was made for (its radius and centre come from them).
    bounds: Option<(Vec3, Vec3)>,
    /// Cumulative power of the entries, normalised, for light paths
    /// ([`LightSet::sample_emission`]): by power alone (user lights, which cannot emit
    /// paths, at zero).
    emit_cdf: Vec<f32>,
}

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

/// A ray of light leaving a light, for light paths (virtual point lights).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissionSample {
    /// Where it starts.
    pub p: Vec3,
    /// Unit direction it travels.
    pub dir: Vec3,
    /// The emitting surface's normal (area lights), for offsetting the start.
    pub n: Option<Vec3>,
    /// Power it carries: the emitted radiance times the cosine over the densities of
    /// its choice, point and direction.
    pub flux: Vec3,
}

impl LightSet {
    /// The lights of `scene` (whose bounds are `bounds`, and whose meshes' emitting
    /// triangles are `emissive`, see [`emissive_triangles`]), plus the user's.
    pub fn of(scene: &Scene, bounds: Option<(Vec3, Vec3)>, emissive: &[Box<[u32]>], custom: &[Arc<dyn LightModel>]) -> Self {
        let mut s = Self { delta: scene.lights.clone(), index: vec![None; scene.instances.len()], bounds, ..Self::default() };
        s.radius = bounds.map_or(1.0, |(lo, hi)| 0.5 * (hi - lo).length()).max(1e-6);
        s.centre = bounds.map_or(Vec3::ZERO, |(lo, hi)| 0.5 * (lo + hi));
        if !s.centre.is_finite() {
            s.centre = Vec3::ZERO;
        }
        let mut power: Vec<f64> = Vec::new();
        // Which light object each entry belongs to.
        let mut group: Vec<u64> = Vec::new();
        let textures = &scene.textures;
        for (ii, inst) in scene.instances.iter().enumerate() {
            match inst.geom {
                Geom::Mesh(m) => {
                    let Some(mesh) = scene.meshes.get(m as usize) else { continue };
                    // (Only the triangles that emit: an instance of a mesh without
                    // emitters costs nothing here.)
                    for &t in emissive.get(m as usize).map_or(&[][..], |e| &e[..]) {
                        let t = t as usize;
                        let Some(idx) = mesh.indices.get(t) else { continue };
                        let Some(mat) = scene.materials.get(mesh.material.get(t).copied().unwrap_or(0) as usize) else { continue };
                        if mat.emission.max_element() <= 0.0 || !mat.emission.is_finite() {
                            continue;
                        }
                        let [a, b, c] = idx
                            .map(|i| inst.world_from_object.transform_point3(mesh.positions.get(i as usize).copied().unwrap_or(Vec3::NAN)));
                        let (e1, e2) = (b - a, c - a);
                        let cross = e1.cross(e2);
                        let area = 0.5 * cross.length();
                        let tex = mat.emission_tex.filter(|&t| (t as usize) < textures.len()).map(|t| {
                            let uv = mesh.uvs.corners(t as usize, idx).unwrap_or([Vec2::ZERO, Vec2::X, Vec2::Y]);
                            (t, uv)
                        });
                        let tex_mean = tex.map_or(1.0, |(t, uv)| {
                            let c = (uv[0] + uv[1] + uv[2]) / 3.0;
                            luminance(crate::texture::sample(&textures[t as usize], c).truncate()).max(1e-3)
                        });
                        let p = area * luminance(mat.emission) * tex_mean * PI;
                        if !(p > 0.0 && p.is_finite()) {
                            continue;
                        }
                        let tris = s.index[ii].get_or_insert_with(|| vec![NONE; mesh.indices.len()].into_boxed_slice());
                        tris[t] = s.entries.len() as u32;
                        s.entries.push(Entry::Tri(EmissiveTri { p0: a, e1, e2, n: cross / (2.0 * area), area, le: mat.emission, tex }));
                        power.push(f64::from(p));
                        group.push(ii as u64);
                    }
                }
                Geom::Shape { kind, material } => {
                    let Some(mat) = scene.materials.get(material as usize) else { continue };
                    let le = mat.emission;
                    if le.max_element() <= 0.0 || !le.is_finite() {
                        continue;
                    }
                    let m = inst.world_from_object;
                    let entry = match kind {
                        ShapeKind::Sphere => {
                            // Only a sphere (a similarity transform) is sampled by its cone.
                            let (sx, sy, sz) = (m.matrix3.x_axis.length(), m.matrix3.y_axis.length(), m.matrix3.z_axis.length());
                            if (sx - sy).abs() > 1e-4 * sx || (sx - sz).abs() > 1e-4 * sx {
                                tracing::warn!("an emitting ellipsoid is lit only where rays meet it (no light sampling)");
                                continue;
                            }
                            Entry::Sphere { c: m.translation.into(), r: sx, le }
                        }
                        ShapeKind::Disk => {
                            let (ax, ay): (Vec3, Vec3) = (m.matrix3.x_axis.into(), m.matrix3.y_axis.into());
                            let cross = ax.cross(ay);
                            Entry::Disk { c: m.translation.into(), ax, ay, n: cross.normalize_or_zero(), area: PI * cross.length(), le }
                        }
                        _ => {
                            tracing::warn!("an emitting {kind:?} is lit only where rays meet it (no light sampling)");
                            continue;
                        }
                    };
                    let p = match &entry {
                        Entry::Sphere { r, .. } => 4.0 * PI * r * r,
                        Entry::Disk { area, .. } => *area,
                        _ => 0.0,
                    } * luminance(le)
                        * PI;
                    if !(p > 0.0 && p.is_finite()) {
                        continue;
                    }
                    s.index[ii] = Some(vec![s.entries.len() as u32].into_boxed_slice());
                    s.entries.push(entry);
                    power.push(f64::from(p));
                    group.push(1 << 32 | ii as u64);
                }
            }
        }
        for (i, l) in scene.lights.iter().enumerate() {
            let p = luminance(l.color)
                * match l.kind {
                    LightKind::Point { .. } => 4.0 * PI,
                    LightKind::Spot { inner, outer, .. } => 2.0 * PI * (1.0 - (0.5 * (inner + outer)).cos()),
                    LightKind::Directional { .. } => PI * s.radius * s.radius,
                };
            if p > 0.0 && p.is_finite() {
                s.entries.push(Entry::Delta(i));
                power.push(f64::from(p));
                group.push(2 << 32 | i as u64);
            }
        }
        if let Some(env) = scene.environment.as_ref().and_then(EnvLight::new) {
            let p = luminance(env.mean) * 4.0 * PI * PI * s.radius * s.radius;
            if p > 0.0 && p.is_finite() {
                s.env = Some((s.entries.len() as u32, env));
                s.entries.push(Entry::Env);
                power.push(f64::from(p));
                group.push(3 << 32);
            }
        }
        for (k, c) in custom.iter().enumerate() {
            let p = c.power();
            if p > 0.0 && p.is_finite() {
                s.entries.push(Entry::Custom(c.clone()));
                power.push(f64::from(p));
                group.push(4 << 32 | k as u64);
            }
        }
        // Light paths leave lights in proportion to their power (user lights, which only
        // answer toward a point, emit none).
        let emit: Vec<f64> = power.iter().zip(&s.entries).map(|(&p, e)| if matches!(e, Entry::Custom(_)) { 0.0 } else { p }).collect();
        s.emit_cdf = cumulative(&emit);
        // The choice: uniform among light objects (each mesh instance's emitters, each
        // emitting shape, each point, spot and directional light, the environment, each
        // user light), and within a mesh instance by the triangles' power (as Mitsuba
        // chooses). Measured against choosing by power across all lights and a half-and-
        // half mixture (relMSE of direct light against Mitsuba's 4096-spp references, 64
        // and 256 spp): power alone was 80x worse on the bunny scene (its sky's power,
        // from the scene's radius, dwarfs the spot that lights the bunny) and 1.7x on the
        // materials scene; the mixture 2.6x worse on the bunny, 10% better on materials.
        let mut group_power: HashMap<u64, f64> = HashMap::new();
        for (p, g) in power.iter().zip(&group) {
            *group_power.entry(*g).or_default() += p;
        }
        let groups = group_power.len() as f64;
        for (p, g) in power.iter_mut().zip(&group) {
            *p = *p / group_power[g].max(f64::MIN_POSITIVE) / groups;
        }
        s.cdf = cumulative(&power);
        s
    }

    /// The scene's bounds the set was made for.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.bounds
    }

    /// Whether an instance has light entries (emitting triangles, or an emitting shape).
    pub fn lights_instance(&self, inst: usize) -> bool {
        self.index.get(inst).is_some_and(Option::is_some)
    }

    /// Replaces the point, spot and directional lights (an animation posed them), keeping
    /// the choice among lights.
    pub fn set_delta(&mut self, lights: &[lucent_scene::Light]) {
        if lights.len() == self.delta.len() {
            self.delta = lights.to_vec();
        }
    }

    /// Whether there is anything to sample.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    fn pmf(&self, i: usize) -> f32 {
        let lo = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        self.cdf.get(i).map_or(0.0, |&c| c - lo)
    }

    /// A light sample from `p` (a light chosen by `u`, a point on it by `u2`).
    pub fn sample(&self, p: Vec3, u: f32, u2: (f32, f32), textures: &[lucent_scene::Texture]) -> Option<LightSample> {
        let i = self.cdf.partition_point(|&c| c <= u).min(self.entries.len().checked_sub(1)?);
        let pmf = self.pmf(i);
        if pmf <= 0.0 {
            return None;
        }
        let mut s = match &self.entries[i] {
            Entry::Tri(t) => {
                let (mut a, mut b) = u2;
                if a + b > 1.0 {
                    (a, b) = (1.0 - a, 1.0 - b);
                }
                let q = t.p0 + t.e1 * a + t.e2 * b;
                let le = match t.tex {
                    Some((tex, uv)) => {
                        let uvq = uv[0] * (1.0 - a - b) + uv[1] * a + uv[2] * b;
                        t.le * crate::texture::sample(&textures[tex as usize], uvq).truncate()
                    }
                    None => t.le,
                };
                area_sample(p, q, t.n, t.area, le)?
            }
            Entry::Sphere { c, r, le } => sphere_sample(p, *c, *r, *le, u2)?,
            Entry::Disk { c, ax, ay, n, area, le } => {
                let d = concentric_disk(u2);
                area_sample(p, *c + *ax * d.x + *ay * d.y, *n, *area, *le)?
            }
            Entry::Delta(k) => delta_sample(self.delta.get(*k)?, p)?,
            Entry::Env => self.env.as_ref()?.1.sample(u2)?,
            Entry::Custom(c) => {
                // (Rays never meet it: no multiple importance sampling, its own density.)
                let mut s = c.sample(p, u2)?;
                s.delta = true;
                s
            }
        };
        s.pdf *= pmf;
        (s.pdf > 0.0 && s.pdf.is_finite() && s.li.is_finite()).then_some(s)
    }

    /// The density with which [`LightSet::sample`] from `p` picks the point `q` (normal
    /// `n`) of instance `inst`'s triangle `prim` or shape, seen along unit `dir`; `None`
    /// when that surface is not a sampled light.
    pub fn pdf_hit(&self, inst: u32, prim: u32, p: Vec3, q: Vec3, dir: Vec3) -> Option<f32> {
        let tris = self.index.get(inst as usize)?.as_ref()?;
        // (A shape's table has its one entry.)
        let i = *tris.get(if tris.len() == 1 { 0 } else { prim as usize })?;
        if i == NONE {
            return None;
        }
        let i = i as usize;
        let pmf = self.pmf(i);
        let d2 = (q - p).length_squared();
        Some(
            pmf * match &self.entries[i] {
                Entry::Tri(t) => d2 / (t.area * t.n.dot(-dir).abs().max(1e-12)),
                Entry::Disk { n, area, .. } => d2 / (area * n.dot(-dir).abs().max(1e-12)),
                Entry::Sphere { c, r, .. } => sphere_pdf(p, *c, *r, q, dir),
                _ => return None,
            },
        )
    }

    /// Radiance of the environment along unit `dir` (zero without one).
    pub fn env_radiance(&self, dir: Vec3) -> Option<Vec3> {
        self.env.as_ref().map(|(_, e)| e.eval(dir))
    }

    /// A ray of light leaving one of the lights (chosen by `u` in proportion to power; a
    /// point on it by `u_pos`, a direction by `u_dir`), for light paths: area lights emit
    /// cosine-weighted from a uniform point, point lights uniformly in all directions,
    /// spot lights uniformly within their outer cone (times the falloff), directional
    /// and environment light from a uniform point of a disk of the scene's bounding radius
    /// across the scene, facing the light's direction. User lights emit nothing (they
    /// only answer toward a point: they light surfaces directly, not through paths).
    pub fn sample_emission(
        &self,
        u: f32,
        u_pos: (f32, f32),
        u_dir: (f32, f32),
        textures: &[lucent_scene::Texture],
    ) -> Option<EmissionSample> {
        let i = self.emit_cdf.partition_point(|&c| c <= u).min(self.entries.len().checked_sub(1)?);
        let lo = if i == 0 { 0.0 } else { self.emit_cdf[i - 1] };
        let pmf = self.emit_cdf[i] - lo;
        if pmf <= 0.0 {
            return None;
        }
        // A start on the disk of the scene's bounding sphere facing `dir`, behind the scene.
        let disk_start = |dir: Vec3| {
            let (t, b) = dir.any_orthonormal_pair();
            let d = concentric_disk(u_pos) * self.radius;
            self.centre - dir * self.radius + t * d.x + b * d.y
        };
        let disk_area = PI * self.radius * self.radius;
        let mut e = match &self.entries[i] {
            Entry::Tri(t) => {
                let (mut a, mut b) = u_pos;
                if a + b > 1.0 {
                    (a, b) = (1.0 - a, 1.0 - b);
                }
                let le = match t.tex {
                    Some((tex, uv)) => {
                        let uvq = uv[0] * (1.0 - a - b) + uv[1] * a + uv[2] * b;
                        t.le * crate::texture::sample(&textures[tex as usize], uvq).truncate()
                    }
                    None => t.le,
                };
                area_emission(t.p0 + t.e1 * a + t.e2 * b, t.n, t.area, le, u_dir)?
            }
            Entry::Sphere { c, r, le } => {
                let n = uniform_sphere(u_pos);
                area_emission(*c + n * *r, n, 4.0 * PI * r * r, *le, u_dir)?
            }
            Entry::Disk { c, ax, ay, n, area, le } => {
                let d = concentric_disk(u_pos);
                area_emission(*c + *ax * d.x + *ay * d.y, *n, *area, *le, u_dir)?
            }
            Entry::Delta(k) => {
                let l = self.delta.get(*k)?;
                match l.kind {
                    LightKind::Point { position } => {
                        EmissionSample { p: position, dir: uniform_sphere(u_dir), n: None, flux: l.color * (4.0 * PI) }
                    }
                    LightKind::Spot { position, direction, outer, .. } => {
                        let axis = direction.normalize_or_zero();
                        let cos_max = outer.cos();
                        let dir = uniform_cone(axis, cos_max, u_dir);
                        // (The falloff is what a shading point on this direction receives.)
                        let falloff = delta_sample(l, position + dir)?.li;
                        EmissionSample { p: position, dir, n: None, flux: falloff * (2.0 * PI * (1.0 - cos_max)) }
                    }
                    LightKind::Directional { direction } => {
                        let dir = direction.normalize_or_zero();
                        EmissionSample { p: disk_start(dir), dir, n: None, flux: l.color * disk_area }
                    }
                }
            }
            Entry::Env => {
                let s = self.env.as_ref()?.1.sample(u_dir)?;
                let dir = -s.dir;
                EmissionSample { p: disk_start(dir), dir, n: None, flux: s.li * (disk_area / s.pdf) }
            }
            Entry::Custom(_) => return None,
        };
        e.flux /= pmf;
        (e.flux.is_finite() && e.flux.max_element() > 0.0 && e.dir != Vec3::ZERO && e.p.is_finite()).then_some(e)
    }

    /// The density with which [`LightSet::sample`] picks direction `dir` of the
    /// environment.
    pub fn env_pdf(&self, dir: Vec3) -> f32 {
        match &self.env {
            Some((i, e)) => self.pmf(*i as usize) * e.pdf(dir),
            None => 0.0,
        }
    }
}

/// The normalised cumulative sums of `w` (all zero when `w` sums to zero).
fn cumulative(w: &[f64]) -> Vec<f32> {
    let total: f64 = w.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return vec![0.0; w.len()];
    }
    let mut acc = 0f64;
    let mut cdf: Vec<f32> = w
        .iter()
        .map(|&p| {
            acc += p;
            (acc / total) as f32
        })
        .collect();
    // (The last entry with any weight ends at exactly 1.)
    if let Some(last) = w.iter().rposition(|&p| p > 0.0) {
        for c in &mut cdf[last..] {
            *c = 1.0;
        }
    }
    cdf
}

/// A point and a cosine-weighted direction about `n` leaving an area light of radiance
/// `le` and area `area`: the flux is `le · area · π`.
fn area_emission(q: Vec3, n: Vec3, area: f32, le: Vec3, u: (f32, f32)) -> Option<EmissionSample> {
    let local = crate::bsdf::cosine_hemisphere(u);
    let (t, b) = n.any_orthonormal_pair();
    let dir = (t * local.x + b * local.y + n * local.z).normalize_or_zero();
    (local.z > 0.0 && dir != Vec3::ZERO).then_some(EmissionSample { p: q, dir, n: Some(n), flux: le * (area * PI) })
}

/// A uniformly chosen unit vector, for `u` in [0, 1)².
#[must_use]
pub fn uniform_sphere(u: (f32, f32)) -> Vec3 {
    let z = 1.0 - 2.0 * u.0;
    let s = (1.0 - z * z).max(0.0).sqrt();
    let (sp, cp) = (2.0 * PI * u.1).sin_cos();
    Vec3::new(s * cp, s * sp, z)
}

/// A direction chosen uniformly within the cone of unit `axis` whose half-angle has
/// cosine `cos_max`, for `u` in [0, 1)²; its density per solid angle is
/// `1 / (2π (1 − cos_max))` (Shirley and Wang 1994).
#[must_use]
pub fn uniform_cone(axis: Vec3, cos_max: f32, u: (f32, f32)) -> Vec3 {
    let cos_t = 1.0 - u.0 * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let (sp, cp) = (2.0 * PI * u.1).sin_cos();
    let (t, b) = axis.any_orthonormal_pair();
    (t * (sin_t * cp) + b * (sin_t * sp) + axis * cos_t).normalize_or_zero()
}

/// An area light's point `q` (normal `n`, one-sided, of total area `area`) seen from `p`.
fn area_sample(p: Vec3, q: Vec3, n: Vec3, area: f32, le: Vec3) -> Option<LightSample> {
    let to = q - p;
    let dist = to.length();
    let dir = to / dist;
    let cos_l = n.dot(-dir);
    if !(cos_l > 0.0 && dist > 0.0 && dist.is_finite()) {
        return None;
    }
    Some(LightSample { dir, dist, li: le, pdf: dist * dist / (cos_l * area), delta: false })
}

/// A point on Shirley and Chiu's concentric map of the unit disk.
fn concentric_disk(u: (f32, f32)) -> Vec2 {
    let (a, b) = (2.0 * u.0 - 1.0, 2.0 * u.1 - 1.0);
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, std::f32::consts::FRAC_PI_4 * (b / a))
    } else {
        (b, std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a / b))
    };
    Vec2::new(r * phi.cos(), r * phi.sin())
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

/// A point, spot or directional light seen from `p`.
fn delta_sample(l: &lucent_scene::Light, p: Vec3) -> Option<LightSample> {
    match l.kind {
        LightKind::Directional { direction } => {
            let dir = -direction.normalize_or_zero();
            (dir != Vec3::ZERO).then_some(LightSample { dir, dist: f32::INFINITY, li: l.color, pdf: 1.0, delta: true })
        }
        LightKind::Point { position } | LightKind::Spot { position, .. } => {
            let to = position - p;
            let dist = to.length();
            if !(dist > 0.0 && dist.is_finite()) {
                return None;
            }
            let dir = to / dist;
            let falloff = match l.kind {
                LightKind::Spot { direction, inner, outer, .. } => {
                    // Mitsuba's spot falloff: full inside `inner`, then linear in the angle
                    // down to zero at `outer`.
                    let angle = (-dir).dot(direction.normalize_or_zero()).clamp(-1.0, 1.0).acos();
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

/// A piecewise-constant 1D distribution.
#[derive(Clone, Debug, Default)]
struct Distribution1D {
    /// Cumulative, normalised, `n + 1` entries from 0 to 1.
    cdf: Vec<f32>,
    /// Function values, normalised to integrate to 1 over [0, 1).
    pdf: Vec<f32>,
    integral: f64,
}

impl Distribution1D {
    fn new(f: &[f32]) -> Self {
        let n = f.len().max(1);
        let sum: f64 = f.iter().map(|&x| f64::from(x.max(0.0))).sum();
        let integral = sum / n as f64;
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0);
        let mut acc = 0f64;
        for &x in f {
            acc += f64::from(x.max(0.0));
            cdf.push(if sum > 0.0 { (acc / sum) as f32 } else { cdf.len() as f32 / n as f32 });
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        let pdf = f.iter().map(|&x| if sum > 0.0 { (f64::from(x.max(0.0)) / integral) as f32 } else { 1.0 }).collect();
        Self { cdf, pdf, integral }
    }

    /// A point in [0, 1) and the density there.
    fn sample(&self, u: f32) -> (f32, f32, usize) {
        let n = self.pdf.len();
        let i = self.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
        let (lo, hi) = (self.cdf[i], self.cdf[i + 1]);
        let t = if hi > lo { (u - lo) / (hi - lo) } else { 0.5 };
        (((i as f32 + t) / n as f32).min(1.0 - f32::EPSILON), self.pdf[i], i)
    }

    fn pdf_at(&self, x: f32) -> f32 {
        let n = self.pdf.len();
        self.pdf[((x * n as f32) as usize).min(n - 1)]
    }
}

/// A piecewise-constant 2D distribution over [0, 1)²: rows (v) by their totals, then a
/// column (u) within the row (pbrt's marginal and conditional densities).
#[derive(Clone, Debug, Default)]
struct Distribution2D {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    fn new(f: &[f32], w: usize, h: usize) -> Self {
        let rows: Vec<Distribution1D> = (0..h).map(|y| Distribution1D::new(&f[y * w..(y + 1) * w])).collect();
        let marginal = Distribution1D::new(&rows.iter().map(|r| r.integral as f32).collect::<Vec<_>>());
        Self { rows, marginal }
    }

    fn sample(&self, u: (f32, f32)) -> (Vec2, f32) {
        let (v, pv, row) = self.marginal.sample(u.1);
        let (x, pu, _) = self.rows[row].sample(u.0);
        (Vec2::new(x, v), pv * pu)
    }

    fn pdf(&self, uv: Vec2) -> f32 {
        let h = self.rows.len();
        let row = ((uv.y * h as f32) as usize).min(h - 1);
        self.marginal.pdf_at(uv.y) * self.rows[row].pdf_at(uv.x)
    }
}

impl EnvLight {
    fn new(e: &Environment) -> Option<Self> {
        let to_local = e.to_world.inverse();
        if !to_local.is_finite() {
            return None;
        }
        let Some(img) = e.image.clone() else {
            return Some(Self { scale: e.scale, map: None, to_world: e.to_world, to_local, mean: e.scale });
        };
        let (w, h) = (img.width as usize, img.height as usize);
        if w < 2 || h < 3 || img.texels.len() < w * h {
            return None;
        }
        // The sampling density: a grid of cells over (u, v) in [0, 1)² (twice the map's
        // resolution, at least 256 × 128), each the mean over 4 × 4 points of the
        // luminance the lookup gives there times sin θ, plus a tenth of the largest
        // luminance of the texels the lookup may blend anywhere in the cell: the density
        // follows the radiance closely and is not zero wherever some light comes from.
        let (gw, gh) = ((2 * w).max(256), (2 * h).max(128));
        let unit = Self { scale: Vec3::ONE, map: None, to_world: Affine3A::IDENTITY, to_local: Affine3A::IDENTITY, mean: Vec3::ONE };
        let lookup = |u: f32, v: f32| luminance(unit.lookup(&img, u, v)).max(0.0);
        let lum = |x: usize, y: usize| luminance(img.texels[y.min(h - 1) * w + x % w]).max(0.0);
        let mut f = vec![0f32; gw * gh];
        for (gy, row) in f.chunks_mut(gw).enumerate() {
            let (v0, v1) = (gy as f32 / gh as f32, (gy + 1) as f32 / gh as f32);
            let (r0, r1) = ((v0 * (h - 1) as f32).floor() as usize, ((v1 * (h - 1) as f32).ceil() as usize).min(h - 1));
            let s_mid = (PI * 0.5 * (v0 + v1)).sin();
            for (gx, cell) in row.iter_mut().enumerate() {
                let (u0, u1) = (gx as f32 / gw as f32, (gx + 1) as f32 / gw as f32);
                let mut sum = 0.0;
                for j in 0..4 {
                    let v = v0 + (v1 - v0) * (j as f32 + 0.5) / 4.0;
                    let st = (PI * v).sin();
                    for i in 0..4 {
                        sum += lookup(u0 + (u1 - u0) * (i as f32 + 0.5) / 4.0, v) * st;
                    }
                }
                // The texel columns whose bilinear footprint reaches the cell.
                let (c0, c1) = ((u0 * w as f32 - 0.5).floor() as i64, (u1 * w as f32 - 0.5).floor() as i64 + 1);
                let mut m = 0f32;
                for r in r0..=r1 {
                    for c in c0..=c1 {
                        m = m.max(lum(c.rem_euclid(w as i64) as usize, r));
                    }
                }
                *cell = sum / 16.0 + 0.1 * m * s_mid;
            }
        }
        let mut mean = Vec3::ZERO;
        let mut wsum = 0.0;
        for y in 0..h {
            let st = (PI * y as f32 / (h - 1) as f32).sin();
            for x in 0..w {
                mean += img.texels[y * w + x] * st;
                wsum += st;
            }
        }
        let mean = if wsum > 0.0 { mean / wsum * e.scale } else { e.scale };
        Some(Self { scale: e.scale, map: Some((img, Distribution2D::new(&f, gw, gh))), to_world: e.to_world, to_local, mean })
    }

    /// Radiance arriving from world direction `dir` (unit): Mitsuba's lookup, u =
    /// atan2(x, −z) / 2π and v = acos(y) / π in the map's frame, bilinear with texel
    /// columns centred at (i + ½) / w (wrapping) and rows at j / (h − 1), pole to pole.
    pub fn eval(&self, dir: Vec3) -> Vec3 {
        let Some((img, _)) = &self.map else { return self.scale };
        let d = self.to_local.transform_vector3(dir).normalize_or_zero();
        let u = d.x.atan2(-d.z) * (0.5 / PI);
        let v = d.y.clamp(-1.0, 1.0).acos() / PI;
        self.lookup(img, u, v) * self.scale
    }

    /// The map's bilinear value at (u, v) (see [`EnvLight::eval`]).
    fn lookup(&self, img: &HdrImage, u: f32, v: f32) -> Vec3 {
        let (w, h) = (img.width as usize, img.height as usize);
        let mut x = u - 0.5 / w as f32;
        x -= x.floor();
        let x = x * w as f32;
        let y = v * (h - 1) as f32;
        let (x0, y0) = ((x as usize).min(w - 1), (y as usize).min(h - 2));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let t = |xi: usize, yi: usize| img.texels[yi * w + xi % w];
        let top = t(x0, y0) * (1.0 - fx) + t(x0 + 1, y0) * fx;
        let bottom = t(x0, y0 + 1) * (1.0 - fx) + t(x0 + 1, y0 + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// A direction (unit, world) and its density per solid angle.
    fn sample(&self, u: (f32, f32)) -> Option<LightSample> {
        let (local, pdf) = match &self.map {
            None => (uniform_sphere(u), 1.0 / (4.0 * PI)),
            Some((_, dist)) => {
                let (uv, p) = dist.sample(u);
                let (theta, phi) = (uv.y * PI, uv.x * 2.0 * PI);
                let (st, ct) = theta.sin_cos();
                let (sp, cp) = phi.sin_cos();
                if st <= 0.0 {
                    return None;
                }
                (Vec3::new(sp * st, ct, -cp * st), p / (2.0 * PI * PI * st))
            }
        };
        let dir = self.to_world.transform_vector3(local).normalize_or_zero();
        if dir == Vec3::ZERO {
            return None;
        }
        Some(LightSample { dir, dist: f32::INFINITY, li: self.eval(dir), pdf, delta: false })
    }

    /// The density of [`EnvLight::sample`] for world direction `dir`.
    fn pdf(&self, dir: Vec3) -> f32 {
        match &self.map {
            None => 1.0 / (4.0 * PI),
            Some((_, dist)) => {
                let d = self.to_local.transform_vector3(dir).normalize_or_zero();
                let u = d.x.atan2(-d.z) * (0.5 / PI);
                let u = u - u.floor();
                let v = d.y.clamp(-1.0, 1.0).acos() / PI;
                let st = (1.0 - d.y * d.y).max(0.0).sqrt();
                if st <= 0.0 {
                    return 0.0;
                }
                dist.pdf(Vec2::new(u, v)) / (2.0 * PI * PI * st)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distribution_2d_density_integrates_to_one_and_matches_samples() {
        let (w, h) = (7, 5);
        let f: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32 + 0.5).collect();
        let d = Distribution2D::new(&f, w, h);
        // ∫ pdf = 1 (cells of area 1 / (w h)).
        let s: f32 =
            (0..w * h).map(|i| d.pdf(Vec2::new(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32))).sum::<f32>()
                / (w * h) as f32;
        assert!((s - 1.0).abs() < 1e-4, "{s}");
        // A sample's density is the density at its point.
        for k in 0..50 {
            let u = (((k * 13) % 50) as f32 / 50.0 + 0.01, (k as f32 + 0.5) / 50.0);
            let (p, pdf) = d.sample(u);
            assert!((d.pdf(p) - pdf).abs() < 1e-3 * pdf, "{p} {pdf} {}", d.pdf(p));
        }
    }
}
