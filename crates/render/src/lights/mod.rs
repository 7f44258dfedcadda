//! The lights the path tracer samples (next-event estimation), one chosen uniformly among
//! the light objects and, within an emitting mesh, a triangle in proportion to its power
//! (see `LightSet::of`): area lights (`area`: emitting triangles, spheres and disks),
//! the scene's point, spot and directional lights (`delta`), the environment
//! (`environment`: constant, or an equirectangular map sampled by its luminance), and
//! lights of the library user's own ([`LightModel`]).
//!
//! Densities are per solid angle at the shading point, the choice among lights included;
//! a delta light's "density" is the probability of choosing it.
//!
//! Adding a kind of light: a file beside these with its construction, `sample`, `pdf`
//! (if rays can meet it) and `emit`, and one arm in each of `LightSet`'s matches.

pub(crate) mod area;
pub(crate) mod delta;
pub(crate) mod environment;
mod sample;

pub(crate) use area::emissive_triangles;
use area::AreaLight;
pub(crate) use delta::toward_directional;
use environment::EnvLight;
pub use sample::{EmissionSample, LightSample};

use crate::sampling::concentric_disk;
use glam::Vec3;
use lucent_scene::{Geom, Scene};
use std::collections::HashMap;
use std::f32::consts::PI;
use std::sync::Arc;

/// No light.
const NONE: u32 = u32::MAX;

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

#[derive(Clone, Debug)]
enum Entry {
    Area(AreaLight),
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
                        let Some((light, p)) = area::triangle(mesh, t, idx, &inst.world_from_object, mat, textures) else { continue };
                        let tris = s.index[ii].get_or_insert_with(|| vec![NONE; mesh.indices.len()].into_boxed_slice());
                        tris[t] = s.entries.len() as u32;
                        s.entries.push(Entry::Area(light));
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
                    let Some((light, p)) = area::shape(kind, &inst.world_from_object, le) else { continue };
                    s.index[ii] = Some(vec![s.entries.len() as u32].into_boxed_slice());
                    s.entries.push(Entry::Area(light));
                    power.push(f64::from(p));
                    group.push(1 << 32 | ii as u64);
                }
            }
        }
        for (i, l) in scene.lights.iter().enumerate() {
            let p = delta::power(l, s.radius);
            if p > 0.0 && p.is_finite() {
                s.entries.push(Entry::Delta(i));
                power.push(f64::from(p));
                group.push(2 << 32 | i as u64);
            }
        }
        if let Some(env) = scene.environment.as_ref().and_then(EnvLight::new) {
            let p = env.power(s.radius);
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
            Entry::Area(a) => a.sample(p, u2, textures)?,
            Entry::Delta(k) => delta::sample(self.delta.get(*k)?, p)?,
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
                Entry::Area(a) => a.pdf(p, q, dir, d2),
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
            Entry::Area(a) => a.emit(u_pos, u_dir, textures)?,
            Entry::Delta(k) => delta::emit(self.delta.get(*k)?, u_dir, disk_start, disk_area)?,
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
