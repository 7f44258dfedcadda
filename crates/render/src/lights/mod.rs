//! The lights the path tracer samples (next-event estimation), one light object chosen by
//! its estimated contribution at the shading point (`reach`: a bound on the irradiance it
//! may send there; uniformly in scenes with lights of the user's) and, within an emitting
//! mesh, a triangle in proportion to its power, or (past eight triangles) by a
//! light tree over them (`tree`: the same bound for nodes of lights, Conty Estevez and
//! Kulla 2018). In a scene of more than [`MAX_WEIGHED`] light objects, every light with a
//! place (area, point and spot lights) is in one light tree, chosen beside the
//! environment and directional lights (see `LightSet::of`): area lights (`area`: emitting triangles, spheres and disks),
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
mod reach;
mod sample;
mod tree;

pub(crate) use area::emissive_triangles;
use area::AreaLight;
pub(crate) use delta::toward_directional;
use environment::EnvLight;
use reach::Reach;
pub use sample::{EmissionSample, LightSample};

use crate::color::luminance;
use crate::sampling::concentric_disk;
use glam::Vec3;
use lucent_scene::{Geom, Scene};
use std::f32::consts::PI;
use std::sync::Arc;

/// No light.
const NONE: u32 = u32::MAX;

/// The most light objects chosen among by their contribution at each shading point (each
/// choice weighs every one of them); past this, they are chosen uniformly.
pub const MAX_WEIGHED: usize = reach::WIDTH;

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

/// The weights of the light objects at a point, as [`LightSet`] chooses among them there
/// ([`LightSet::weigh`]): kept by the lane integrator for the next bounce's multiple
/// importance sampling, which asks for the probability of choosing the light it met from
/// the same point.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Weights {
    w: [f32; MAX_WEIGHED],
    /// Their sum; `None`: chosen uniformly.
    total: Option<f32>,
    /// The point and its normal (for the choice within a light tree).
    p: Vec3,
    n: Vec3,
}

impl Weights {
    /// None yet (uniform).
    pub(crate) const UNIFORM: Self = Self { w: [0.0; MAX_WEIGHED], total: None, p: Vec3::ZERO, n: Vec3::ZERO };

    /// Whether the lights are chosen by these weights (not uniformly).
    #[inline(always)]
    pub(crate) fn is_weighed(&self) -> bool {
        self.total.is_some()
    }
}

/// What [`LightSet::choice`] found.
pub(crate) enum Choice<'a> {
    /// No light (no sample).
    Nothing,
    /// An untextured triangle (`quad` false) or parallelogram, with the probability of its
    /// choice: sampled as [`flat_sample`] does.
    Flat { light: &'a area::EmissiveTri, quad: bool, pmf: f32 },
    /// The environment map, chosen with probability `pmf`: sampled in batches
    /// ([`LightSet::sample_env_batch`]).
    Env { pmf: f32 },
    /// A point, spot or directional light, chosen with probability `pmf`: sampled as
    /// [`delta::sample_lane`] does.
    Delta { light: delta::DeltaLane, pmf: f32 },
    /// Another kind: entry `entry`, chosen with probability `pmf`;
    /// [`LightSet::sample_entry`] samples it.
    Other { entry: usize, pmf: f32 },
}

/// [`LightSet::sample`] of a [`Choice::Delta`] light, branch-free for loops over lanes
/// (the same bits): the sample (its density times the choice's `pmf`) and whether there
/// is one.
#[inline(always)]
pub(crate) fn delta_sample(light: &delta::DeltaLane, pmf: f32, p: Vec3) -> (LightSample, bool) {
    let (s, ok) = delta::sample_lane(light, p);
    let pdf = s.pdf * pmf;
    (LightSample { pdf, ..s }, ok & (pdf > 0.0) & pdf.is_finite() & s.li.is_finite())
}

/// [`LightSet::sample`] of a [`Choice::Flat`] light, branch-free for loops over lanes
/// (the same bits): the direction, distance, radiance and density (times the choice's
/// `pmf`), and whether there is a sample.
#[inline(always)]
pub(crate) fn flat_sample(light: &area::EmissiveTri, quad: bool, pmf: f32, p: Vec3, u2: (f32, f32)) -> (LightSample, bool) {
    let (a, b) = if quad { u2 } else { area::tri_point(u2) };
    let q = light.p0 + light.e1 * a + light.e2 * b;
    let (s, ok) = area::area_sample_lane(p, q, light.n, light.area, light.le);
    let pdf = s.pdf * pmf;
    (LightSample { pdf, ..s }, ok & (pdf > 0.0) & pdf.is_finite() & s.li.is_finite())
}

/// A light's sample `s` once its light was chosen with probability `pmf`: its density
/// times `pmf`, where that is positive and finite and the radiance finite.
#[inline]
fn chosen(s: LightSample, pmf: f32) -> Option<LightSample> {
    let s = LightSample { pdf: s.pdf * pmf, ..s };
    (s.pdf > 0.0 && s.pdf.is_finite() && s.li.is_finite()).then_some(s)
}

/// A light object's entries and how one of them is chosen.
#[derive(Clone, Debug)]
enum Members {
    /// Contiguous entries, chosen in proportion to their power (`LightSet::within`).
    Run(std::ops::Range<u32>),
    /// Entries chosen by a light tree, each the light of its place in the list.
    Tree { entries: Box<[u32]>, tree: tree::LightTree },
}

/// Emitting meshes of more triangles than this choose among them with a light tree (by
/// their contribution at the point rather than by power alone).
const TREE_MIN: usize = 8;

/// The lights of a scene, for sampling.
#[derive(Clone, Debug, Default)]
pub(crate) struct LightSet {
    entries: Vec<Entry>,
    /// The light objects: each one's entries. In a scene of more than [`MAX_WEIGHED`],
    /// those with a place (area, point and spot lights) are one object, a light tree.
    groups: Vec<Members>,
    /// How far each one's light reaches (the first [`MAX_WEIGHED`]).
    reach: reach::Lanes,
    /// Per entry: its group; the cumulative power of its group's entries up to it,
    /// normalised within the group (runs); its place in its group's list (trees).
    group_of: Vec<u32>,
    within: Vec<f32>,
    leaf_of: Vec<u32>,
    /// Whether light objects are chosen by their reach (else uniformly).
    weighed: bool,
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
                    // The instance's emitting triangles; two in a row that make a
                    // parallelogram become one light (`area::quad`).
                    let mut tris_here: Vec<(usize, AreaLight, f32)> = Vec::new();
                    for &t in emissive.get(m as usize).map_or(&[][..], |e| &e[..]) {
                        let t = t as usize;
                        let Some(idx) = mesh.indices.get(t) else { continue };
                        let Some(mat) = scene.materials.get(mesh.material.get(t).copied().unwrap_or(0) as usize) else { continue };
                        if mat.emission.max_element() <= 0.0 || !mat.emission.is_finite() {
                            continue;
                        }
                        let Some((light, p)) = area::triangle(mesh, t, idx, &inst.world_from_object, mat, textures) else { continue };
                        tris_here.push((t, light, p));
                    }
                    let mut k = 0;
                    while k < tris_here.len() {
                        let tris = s.index[ii].get_or_insert_with(|| vec![NONE; mesh.indices.len()].into_boxed_slice());
                        let (t, light, p) = &tris_here[k];
                        let pair = tris_here
                            .get(k + 1)
                            .filter(|(t2, ..)| *t2 == t + 1)
                            .and_then(|(t2, l2, _)| Some((*t2, area::quad(mesh, (*t, light), (*t2, l2), &inst.world_from_object)?)));
                        tris[*t] = s.entries.len() as u32;
                        if let Some((t2, (q, qp))) = pair {
                            tris[t2] = s.entries.len() as u32;
                            s.entries.push(Entry::Area(q));
                            power.push(f64::from(qp));
                            k += 2;
                        } else {
                            s.entries.push(Entry::Area(light.clone()));
                            power.push(f64::from(*p));
                            k += 1;
                        }
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
        // The choice: among light objects (each mesh instance's emitters, each emitting
        // shape, each point, spot and directional light, the environment, each user
        // light) by their reach at the shading point, and within a mesh instance by the
        // triangles' power (as Mitsuba chooses within a mesh). Measured before: choosing
        // by power across all lights was 80x worse than uniform on the bunny scene (its
        // sky's power, from the scene's radius, dwarfs the spot that lights the bunny);
        // the reach compares irradiances at the point instead.
        let mut start = 0;
        let mut runs = Vec::new();
        let mut reaches = Vec::new();
        for e in 1..=s.entries.len() {
            if e == s.entries.len() || group[e] != group[start] {
                let ids = start..e;
                s.within.extend(cumulative(&power[ids.clone()]));
                reaches.push(s.reach(&s.entries[ids.clone()], &power[ids.clone()]));
                runs.push(start as u32..e as u32);
                start = e;
            }
        }
        let local = |r: &Reach| matches!(r, Reach::Local { .. });
        let crowd: Vec<usize> = (0..runs.len()).filter(|&g| local(&reaches[g])).collect();
        let mut kept = Vec::new();
        // A crowd of light objects: those with a place become one, a light tree over all
        // their entries, chosen beside the others (the environment, directional lights).
        let tree = if runs.len() > MAX_WEIGHED && crowd.len() > 1 {
            let ids: Vec<u32> = crowd.iter().flat_map(|&g| runs[g].clone()).collect();
            s.tree_of(ids, &power)
        } else {
            None
        };
        if let Some((members, reach)) = tree {
            for (g, run) in runs.into_iter().enumerate() {
                if !local(&reaches[g]) {
                    s.groups.push(Members::Run(run));
                    kept.push(reaches[g]);
                }
            }
            s.groups.push(members);
            kept.push(reach);
        } else {
            // An emitting mesh of many triangles: a tree over them.
            for (g, run) in runs.into_iter().enumerate() {
                let tree = (run.len() > TREE_MIN && local(&reaches[g])).then(|| s.tree_of(run.clone().collect(), &power)).flatten();
                s.groups.push(tree.map_or(Members::Run(run), |(m, _)| m));
                kept.push(reaches[g]);
            }
        }
        s.group_of = vec![NONE; s.entries.len()];
        s.leaf_of = vec![NONE; s.entries.len()];
        for (g, m) in s.groups.iter().enumerate() {
            match m {
                Members::Run(run) => run.clone().for_each(|i| s.group_of[i as usize] = g as u32),
                Members::Tree { entries, .. } => {
                    for (k, &i) in entries.iter().enumerate() {
                        (s.group_of[i as usize], s.leaf_of[i as usize]) = (g as u32, k as u32);
                    }
                }
            }
        }
        s.reach = reach::Lanes::new(&kept);
        s.weighed = s.groups.len() <= MAX_WEIGHED && !s.entries.iter().any(|e| matches!(e, Entry::Custom(_)));
        s
    }

    /// A light tree over entries `ids` (which all have a place), and the reach of the whole.
    fn tree_of(&self, ids: Vec<u32>, power: &[f64]) -> Option<(Members, Reach)> {
        let lights = ids
            .iter()
            .map(|&i| {
                let i = i as usize;
                let (e, p) = (self.entries.get(i..=i)?, power.get(i..=i)?);
                Some((self.extent(e, p)?, self.reach(e, p)))
            })
            .collect::<Option<Vec<_>>>()?;
        let tree = tree::LightTree::new(&lights)?;
        let reach = tree.whole().reach();
        Some((Members::Tree { entries: ids.into_boxed_slice(), tree }, reach))
    }

    /// How far the light of one light object (its entries, with their powers) reaches.
    fn reach(&self, entries: &[Entry], power: &[f64]) -> Reach {
        match entries.first() {
            Some(Entry::Area(AreaLight::Sphere { c, r, .. })) => Reach::local(*c, *r, Vec3::ZERO, PI, PI, power[0] as f32 / 4.0),
            Some(Entry::Delta(k)) => match self.delta.get(*k) {
                Some(l @ lucent_scene::Light { kind: lucent_scene::LightKind::Directional { direction }, .. }) => {
                    Reach::Directional { toward: toward_directional(*direction), irradiance: luminance(l.color) }
                }
                _ => self.extent(entries, power).map_or(Reach::Everywhere { irradiance: 0.0 }, |e| e.reach()),
            },
            Some(Entry::Env) => Reach::Everywhere { irradiance: self.env.as_ref().map_or(0.0, |(_, e)| PI * e.mean_luminance()) },
            Some(Entry::Area(_)) => self.extent(entries, power).map_or(Reach::Everywhere { irradiance: 0.0 }, |e| e.reach()),
            Some(Entry::Custom(_)) | None => Reach::Everywhere { irradiance: 1.0 },
        }
    }

    /// The place, cone of normals and intensity of one light object with a place (its
    /// entries, with their powers); `None` for directional lights, the environment and
    /// user lights.
    fn extent(&self, entries: &[Entry], power: &[f64]) -> Option<tree::Extent> {
        use lucent_scene::LightKind;
        let (pi, half_pi) = (PI, 0.5 * PI);
        let point = |c: Vec3, axis: Vec3, theta_o: f32, theta_e: f32, intensity: f32| tree::Extent {
            lo: c,
            hi: c,
            axis,
            theta_o,
            theta_e,
            intensity,
        };
        match entries.first()? {
            Entry::Area(AreaLight::Sphere { c, r, .. }) => Some(tree::Extent {
                lo: *c - *r,
                hi: *c + *r,
                axis: Vec3::ZERO,
                theta_o: pi,
                theta_e: pi,
                intensity: power[0] as f32 / 4.0,
            }),
            Entry::Area(_) => {
                // Emitting triangles or a disk: one-sided, within a cone of normals.
                let (mut lo, mut hi, mut axis) = (Vec3::INFINITY, Vec3::NEG_INFINITY, Vec3::ZERO);
                let mut normals = Vec::with_capacity(entries.len());
                for (e, &p) in entries.iter().zip(power) {
                    let (n, corners) = match e {
                        Entry::Area(AreaLight::Tri(t)) => (t.n, [t.p0, t.p0 + t.e1, t.p0 + t.e2, t.p0]),
                        Entry::Area(AreaLight::Quad(t)) => (t.n, [t.p0, t.p0 + t.e1, t.p0 + t.e2, t.p0 + t.e1 + t.e2]),
                        Entry::Area(AreaLight::Disk { c, ax, ay, n, .. }) => {
                            (*n, [*c + *ax + *ay, *c - *ax - *ay, *c + *ax - *ay, *c - *ax + *ay])
                        }
                        _ => continue,
                    };
                    for q in corners {
                        (lo, hi) = (lo.min(q), hi.max(q));
                    }
                    axis += n * p as f32;
                    normals.push(n);
                }
                let axis = axis.normalize_or_zero();
                let cos_o = normals.iter().map(|n| n.dot(axis)).fold(1.0f32, f32::min);
                let theta_o = if axis == Vec3::ZERO { pi } else { lucent_accel::math::acos(cos_o.clamp(-1.0, 1.0)) };
                let flat: f64 = power.iter().sum::<f64>() / f64::from(pi);
                // (Spread over every direction, a closed emitter's intensity is about a
                // quarter of its power, as a sphere's.)
                let intensity = if theta_o >= half_pi { flat * f64::from(pi) / 4.0 } else { flat };
                Some(tree::Extent { lo, hi, axis, theta_o, theta_e: half_pi, intensity: intensity as f32 })
            }
            Entry::Delta(k) => {
                let l = self.delta.get(*k)?;
                let lum = luminance(l.color);
                match l.kind {
                    LightKind::Point { position } => Some(point(position, Vec3::ZERO, pi, pi, lum)),
                    LightKind::Spot { position, direction, inner, outer } => {
                        Some(point(position, direction, inner.min(outer), (outer - inner).max(0.0), lum))
                    }
                    LightKind::Directional { .. } => None,
                }
            }
            Entry::Env | Entry::Custom(_) => None,
        }
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

    /// The weights of the light objects at `p` (unit normal `n`, or zero) into `w`, and
    /// their sum; `None` when they are chosen uniformly (too many to weigh, user lights,
    /// or no light reaches the point).
    #[inline]
    fn weights(&self, p: Vec3, n: Vec3, w: &mut [f32; MAX_WEIGHED]) -> Option<f32> {
        if !self.weighed || self.groups.len() < 2 {
            return None;
        }
        let total = self.reach.weights(p, n, w);
        (total > 0.0 && total.is_finite()).then_some(total)
    }

    /// The weights of the light objects at `p` (unit normal `n`, or zero).
    #[inline(always)]
    pub(crate) fn weigh(&self, p: Vec3, n: Vec3) -> Weights {
        if !self.weighed || self.groups.len() < 2 {
            return Weights { p, n, ..Weights::UNIFORM };
        }
        let mut w = [0.0; MAX_WEIGHED];
        let total = self.weights(p, n, &mut w);
        Weights { w, total, p, n }
    }

    /// The probability of choosing entry `i` from `p` (normal `n`).
    #[cfg(test)]
    fn pmf(&self, i: usize, p: Vec3, n: Vec3) -> f32 {
        self.pmf_in(i, &self.weigh(p, n))
    }

    /// The probability of choosing entry `i` where the weights are `wt`.
    fn pmf_in(&self, i: usize, wt: &Weights) -> f32 {
        let (Some(&g), Some(&c)) = (self.group_of.get(i), self.within.get(i)) else { return 0.0 };
        let in_group = match self.groups.get(g as usize) {
            Some(Members::Run(ids)) if i == ids.start as usize => c,
            Some(Members::Run(_)) => c - self.within[i - 1],
            Some(Members::Tree { tree, .. }) => tree.pmf(self.leaf_of[i] as usize, wt.p, wt.n),
            None => return 0.0,
        };
        in_group
            * match wt.total {
                Some(total) => wt.w[g as usize] / total,
                None => 1.0 / self.groups.len() as f32,
            }
    }

    /// The entry `u` chooses from `p` (normal `n`), and its probability.
    #[inline]
    fn choose(&self, p: Vec3, n: Vec3, u: f32) -> Option<(usize, f32)> {
        self.choose_in(&self.weigh(p, n), u)
    }

    /// The entry `u` chooses where the weights are `wt`, and its probability.
    #[inline(always)]
    fn choose_in(&self, wt: &Weights, u: f32) -> Option<(usize, f32)> {
        let count = self.groups.len();
        let w = &wt.w;
        // The group, its probability, and `u` within it.
        let (g, pg, u) = match wt.total {
            Some(total) => {
                let (g, pg, rest) = reach::pick(&w[..count], total, u);
                (g, pg, rest.clamp(0.0, 1.0))
            }
            None => {
                let x = u * count as f32;
                let g = (x as usize).min(count.checked_sub(1)?);
                (g, 1.0 / count as f32, (x - g as f32).clamp(0.0, 1.0))
            }
        };
        let ids = match &self.groups[g] {
            Members::Run(ids) => ids.clone(),
            Members::Tree { entries, tree } => {
                let (k, q) = tree.choose(wt.p, wt.n, u)?;
                return Some((*entries.get(k)? as usize, pg * q));
            }
        };
        let (start, end) = (ids.start as usize, ids.end as usize);
        let i = if end - start == 1 { start } else { (start + self.within[start..end].partition_point(|&c| c <= u)).min(end - 1) };
        let lo = if i == start { 0.0 } else { self.within[i - 1] };
        Some((i, pg * (self.within[i] - lo)))
    }

    /// The light [`LightSet::sample`] chooses with `u` from `p` (normal `n`), for the lane
    /// integrator, which samples untextured triangles and parallelograms on lanes: what
    /// `sample` would sample there.
    #[inline]
    pub(crate) fn choice(&self, wt: &Weights, u: f32) -> Choice<'_> {
        let Some((i, pmf)) = self.choose_in(wt, u) else { return Choice::Nothing };
        if pmf <= 0.0 {
            return Choice::Nothing;
        }
        match &self.entries[i] {
            Entry::Area(AreaLight::Tri(t)) if t.tex.is_none() => Choice::Flat { light: t, quad: false, pmf },
            Entry::Area(AreaLight::Quad(t)) => Choice::Flat { light: t, quad: true, pmf },
            Entry::Env => Choice::Env { pmf },
            Entry::Delta(k) => match self.delta.get(*k) {
                Some(l) => Choice::Delta { light: delta::DeltaLane::of(l), pmf },
                None => Choice::Nothing,
            },
            _ => Choice::Other { entry: i, pmf },
        }
    }

    /// A light sample from `p` (a point of a surface with unit normal `n`, or zero: see
    /// `reach`), a light chosen by `u`, a point on it by `u2`. With `mis` the sample is
    /// for multiple importance sampling with the BSDF's samples (which must then reach
    /// every direction the BSDF scatters from): an environment map is sampled by its
    /// compensated density, zero where the map is dimmer than its mean.
    pub fn sample(&self, p: Vec3, n: Vec3, u: f32, u2: (f32, f32), textures: &[lucent_scene::Texture], mis: bool) -> Option<LightSample> {
        let (i, pmf) = self.choose(p, n, u)?;
        self.sample_entry(i, pmf, p, n, u2, textures, mis)
    }

    /// [`LightSet::sample`] of entry `i`, once chosen with probability `pmf` (as
    /// [`LightSet::choice`] reports it).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn sample_entry(
        &self,
        i: usize,
        pmf: f32,
        p: Vec3,
        n: Vec3,
        u2: (f32, f32),
        textures: &[lucent_scene::Texture],
        mis: bool,
    ) -> Option<LightSample> {
        if pmf <= 0.0 {
            return None;
        }
        let s = match self.entries.get(i)? {
            Entry::Area(a) => a.sample(p, u2, textures)?,
            Entry::Delta(k) => delta::sample(self.delta.get(*k)?, p)?,
            Entry::Env => self.env.as_ref()?.1.sample(u2, n, mis)?,
            Entry::Custom(c) => {
                // (Rays never meet it: no multiple importance sampling, its own density.)
                let mut s = c.sample(p, u2)?;
                s.delta = true;
                s
            }
        };
        chosen(s, pmf)
    }

    /// The density with which [`LightSet::sample`] from `p` (normal `n`) picks the point
    /// `q` of instance `inst`'s triangle `prim` or shape, seen along unit `dir`; `None`
    /// when that surface is not a sampled light.
    pub fn pdf_hit(&self, inst: u32, prim: u32, p: Vec3, n: Vec3, q: Vec3, dir: Vec3) -> Option<f32> {
        self.pdf_hit_in(&self.weigh(p, n), inst, prim, p, q, dir)
    }

    /// [`LightSet::pdf_hit`] where the weights at `p` are `wt` (of [`LightSet::weigh`]).
    pub(crate) fn pdf_hit_in(&self, wt: &Weights, inst: u32, prim: u32, p: Vec3, q: Vec3, dir: Vec3) -> Option<f32> {
        let tris = self.index.get(inst as usize)?.as_ref()?;
        // (A shape's table has its one entry.)
        let i = *tris.get(if tris.len() == 1 { 0 } else { prim as usize })?;
        if i == NONE {
            return None;
        }
        let i = i as usize;
        let pmf = self.pmf_in(i, wt);
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
                let s = self.env.as_ref()?.1.sample(u_dir, Vec3::ZERO, false)?;
                let dir = -s.dir;
                EmissionSample { p: disk_start(dir), dir, n: None, flux: s.li * (disk_area / s.pdf) }
            }
            Entry::Custom(_) => return None,
        };
        e.flux /= pmf;
        (e.flux.is_finite() && e.flux.max_element() > 0.0 && e.dir != Vec3::ZERO && e.p.is_finite()).then_some(e)
    }

    /// [`LightSet::sample_entry`] of the environment for the lanes of `b` (each chosen with
    /// its `pmf`; the same bits), into `b.out`.
    pub(crate) fn sample_env_batch(&self, b: &mut environment::EnvBatch, mis: bool) {
        let Some((_, env)) = &self.env else {
            b.out.fill(None);
            return;
        };
        env.sample_batch(b, mis);
        for (out, &pmf) in b.out.iter_mut().zip(&b.pmf).take(b.n) {
            *out = out.filter(|_| pmf > 0.0).and_then(|s| chosen(s, pmf));
        }
    }

    /// [`LightSet::env_radiance_pdf`] of many directions into `out`; false (and `out`
    /// untouched) without an environment.
    pub(crate) fn env_radiance_pdf_batch(&self, dirs: &[Vec3], normals: &[Vec3], mis: bool, out: &mut [(Vec3, f32)]) -> bool {
        let Some((_, env)) = &self.env else { return false };
        env.eval_pdf_batch(dirs, normals, mis, out);
        true
    }

    /// Radiance of the environment along unit `dir` ([`LightSet::env_radiance`]) and the
    /// density with which [`LightSet::sample`] from a point of normal `n` picks that
    /// direction once it has chosen the environment (`None` without one); times
    /// [`LightSet::env_choice`], the whole density. `mis` as for [`LightSet::sample`].
    pub fn env_radiance_pdf(&self, dir: Vec3, n: Vec3, mis: bool) -> Option<(Vec3, f32)> {
        self.env.as_ref().map(|(_, e)| e.eval_pdf(dir, n, mis))
    }

    /// The probability of choosing the environment from `p` (normal `n`).
    pub fn env_choice(&self, p: Vec3, n: Vec3) -> f32 {
        self.env_choice_in(&self.weigh(p, n))
    }

    /// [`LightSet::env_choice`] where the weights are `wt` (of [`LightSet::weigh`]).
    pub(crate) fn env_choice_in(&self, wt: &Weights) -> f32 {
        self.env.as_ref().map_or(0.0, |(i, _)| self.pmf_in(*i as usize, wt))
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Affine3A;
    use lucent_scene::{Environment, Geom, Instance, Light, LightKind, Material, ShapeKind};

    /// A point, a spot, a sun, an emitting sphere and a sky.
    fn lights() -> LightSet {
        let mut scene = Scene::default();
        scene.materials.push(Material { emission: Vec3::new(4.0, 3.0, 2.0), ..Material::default() });
        scene.instances.push(Instance {
            geom: Geom::Shape { kind: ShapeKind::Sphere, material: 0 },
            world_from_object: Affine3A::from_scale_rotation_translation(Vec3::splat(0.3), glam::Quat::IDENTITY, Vec3::new(-1.0, 1.0, 0.0)),
        });
        let light = |kind, color| Light { kind, color, inverse_square: true };
        scene.lights.push(light(LightKind::Point { position: Vec3::new(1.0, 2.0, 0.0) }, Vec3::splat(3.0)));
        let (inner, outer) = (0.2f32, 0.4f32);
        scene
            .lights
            .push(light(LightKind::Spot { position: Vec3::new(0.0, 2.0, 0.0), direction: -Vec3::Y, inner, outer }, Vec3::splat(5.0)));
        scene.lights.push(light(LightKind::Directional { direction: Vec3::new(0.2, -1.0, 0.1) }, Vec3::splat(0.8)));
        scene.environment = Some(Environment { scale: Vec3::splat(0.2), image: None, to_world: Affine3A::IDENTITY });
        LightSet::of(&scene, Some((Vec3::splat(-3.0), Vec3::splat(3.0))), &[], &[])
    }

    #[test]
    fn the_choice_is_a_distribution_that_its_densities_describe() {
        let set = lights();
        assert!(set.weighed);
        assert_eq!(set.groups.len(), 5);
        let spot = set.entries.iter().position(|e| matches!(e, Entry::Delta(1))).expect("the spot");
        for (p, n) in [
            (Vec3::ZERO, Vec3::Y),
            (Vec3::new(2.0, 0.0, 1.0), Vec3::new(0.3, 1.0, 0.0).normalize()),
            (Vec3::new(-1.0, 0.5, 0.2), Vec3::ZERO),
            (Vec3::new(0.1, 0.0, 0.0), -Vec3::Y),
        ] {
            let pmf: Vec<f32> = (0..set.entries.len()).map(|i| set.pmf(i, p, n)).collect();
            let sum: f32 = pmf.iter().sum();
            assert!((sum - 1.0).abs() < 1e-5, "{p}: {pmf:?}");
            // Choices over a fine grid of u land on each entry as often as its pmf says,
            // and each reports that pmf.
            let k = 100_000;
            let mut seen = vec![0u32; pmf.len()];
            for j in 0..k {
                let (i, q) = set.choose(p, n, (j as f32 + 0.5) / k as f32).expect("a light");
                assert_eq!(q.to_bits(), pmf[i].to_bits(), "{p}, entry {i}");
                seen[i] += 1;
            }
            for (i, &c) in seen.iter().enumerate() {
                assert!((c as f32 / k as f32 - pmf[i]).abs() < 1e-3, "{p}, entry {i}: {c} of {k}, pmf {}", pmf[i]);
            }
        }
        // Under the spot, inside its cone, it is chosen; beside it, outside, never.
        assert!(set.pmf(spot, Vec3::ZERO, Vec3::Y) > 0.2);
        assert_eq!(set.pmf(spot, Vec3::new(2.0, 0.0, 1.0), Vec3::Y), 0.0);
    }

    /// A rectangle of two emitting triangles (as Mitsuba's `rectangle` is made), tilted,
    /// is one light for both triangles; its samples' densities are the ones `pdf_hit`
    /// reports where their rays meet either triangle, and their mean is the irradiance
    /// found by quadrature over the rectangle. A fan of two triangles that is no
    /// parallelogram stays two lights.
    #[test]
    fn a_rectangle_of_two_triangles_is_one_light() {
        use lucent_scene::Mesh;
        let quad_scene = |positions: Vec<Vec3>| {
            let mut scene = Scene::default();
            scene.materials.push(Material { emission: Vec3::new(2.0, 1.0, 0.5), ..Material::default() });
            scene.meshes.push(Mesh {
                name: "lamp".into(),
                positions,
                indices: vec![[0, 1, 2], [2, 3, 0]],
                material: vec![0, 0],
                ..Mesh::default()
            });
            let place = glam::Affine3A::from_scale_rotation_translation(
                Vec3::new(0.6, 0.4, 1.0),
                glam::Quat::from_rotation_x(2.0) * glam::Quat::from_rotation_y(0.3),
                Vec3::new(0.2, 1.5, -0.1),
            );
            scene.instances.push(Instance { geom: Geom::Mesh(0), world_from_object: place });
            let emissive = area::emissive_triangles(&scene);
            (LightSet::of(&scene, Some((Vec3::splat(-3.0), Vec3::splat(3.0))), &emissive, &[]), place)
        };
        let corners = vec![Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)];
        let (set, place) = quad_scene(corners.clone());
        assert_eq!(set.entries.len(), 1);
        assert!(matches!(set.entries[0], Entry::Area(AreaLight::Quad(_))));
        let Entry::Area(AreaLight::Quad(q)) = &set.entries[0] else { unreachable!() };
        let world = corners.iter().map(|&c| place.transform_point3(c)).collect::<Vec<_>>();
        let normal = q.n;
        // Where the light is seen from: below its emitting side.
        let p = place.transform_point3(Vec3::ZERO) + normal * 1.3 + Vec3::new(0.2, 0.0, 0.1);
        let n = (-normal + Vec3::new(0.3, 0.1, 0.0)).normalize();
        // The irradiance at p (normal n) from the light, by a midpoint rule over it.
        let (o, ex, ey) = (world[0], world[1] - world[0], world[3] - world[0]);
        let da = ex.cross(ey).length();
        let k = 400;
        let mut by_quadrature = 0.0f64;
        for i in 0..k {
            for j in 0..k {
                let x = o + ex * ((i as f32 + 0.5) / k as f32) + ey * ((j as f32 + 0.5) / k as f32);
                let to = x - p;
                let d2 = to.length_squared();
                let w = to / d2.sqrt();
                let g = n.dot(w).max(0.0) * normal.dot(-w).max(0.0) / d2;
                by_quadrature += f64::from(g * da) / f64::from(k * k);
            }
        }
        let m = 256;
        let mut by_samples = 0.0f64;
        for i in 0..m {
            for j in 0..m {
                let u = ((i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32);
                let ls = set.sample(p, n, 0.5, u, &[], false).expect("a sample");
                by_samples += f64::from(ls.li.x / 2.0 * n.dot(ls.dir).max(0.0) / ls.pdf) / f64::from(m * m);
                // Its density as an emitter met says it, through either triangle.
                let q = p + ls.dir * ls.dist;
                let local = place.inverse().transform_point3(q);
                let prim = if local.x - local.y >= 0.0 { 0 } else { 1 };
                let hit_pdf = set.pdf_hit(0, prim, p, n, q, ls.dir).expect("a light");
                assert!((hit_pdf - ls.pdf).abs() <= 1e-4 * ls.pdf, "{hit_pdf} against {}", ls.pdf);
            }
        }
        assert!((by_samples / by_quadrature - 1.0).abs() < 2e-3, "{by_samples} against {by_quadrature}");
        // Not a parallelogram: two lights.
        let (set, _) = quad_scene(vec![corners[0], corners[1], corners[2], Vec3::new(-1.0, 1.4, 0.0)]);
        assert_eq!(set.entries.len(), 2);
    }

    /// Past [`MAX_WEIGHED`] light objects, those with a place are one light tree, chosen
    /// beside the others (here a directional light) by their reach; the nearer lights of
    /// the crowd are chosen more often, and the choice is a distribution its densities
    /// describe.
    #[test]
    fn crowds_are_one_light_tree() {
        let mut scene = Scene::default();
        let count = 3 * MAX_WEIGHED;
        for i in 0..count {
            scene.lights.push(Light {
                kind: LightKind::Point { position: Vec3::new(i as f32, 1.0, 0.0) },
                color: Vec3::ONE,
                inverse_square: true,
            });
        }
        scene.lights.push(Light { kind: LightKind::Directional { direction: -Vec3::Y }, color: Vec3::splat(0.1), inverse_square: true });
        let set = LightSet::of(&scene, Some((Vec3::splat(-1.0), Vec3::splat(50.0))), &[], &[]);
        assert!(set.weighed);
        assert_eq!(set.groups.len(), 2);
        let sun = set.entries.iter().position(|e| matches!(e, Entry::Delta(k) if *k == count)).expect("the sun");
        for p in [Vec3::ZERO, Vec3::new(30.0, 0.0, 2.0)] {
            let pmf: Vec<f32> = (0..set.entries.len()).map(|i| set.pmf(i, p, Vec3::Y)).collect();
            assert!((pmf.iter().sum::<f32>() - 1.0).abs() < 1e-5, "{pmf:?}");
            let nearest = (p.x.round() as usize).min(count - 1);
            assert!(pmf[nearest] > 4.0 * pmf[(nearest + 20) % count], "{p}: {pmf:?}");
            assert!(pmf[sun] > 0.0);
            let k = 50_000;
            for j in 0..k {
                let (i, q) = set.choose(p, Vec3::Y, (j as f32 + 0.5) / k as f32).expect("a light");
                assert_eq!(q.to_bits(), pmf[i].to_bits(), "{p}, entry {i}");
            }
        }
    }

    /// An emitting mesh of many small triangles scattered over a ceiling: a light tree
    /// chooses among them; the densities describe the choice, the nearest triangles are
    /// chosen most often, and the samples' mean is the irradiance the triangles send.
    #[test]
    fn an_emitting_mesh_of_many_triangles_is_a_light_tree() {
        use lucent_scene::Mesh;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut positions, mut indices) = (Vec::new(), Vec::new());
        for t in 0..60u32 {
            // Facing down (corners clockwise from below), 2 cm across, over 8 × 8 m.
            let c = Vec3::new(next() * 8.0 - 4.0, 2.0 + next(), next() * 8.0 - 4.0);
            positions.extend([c, c + Vec3::new(0.02, 0.0, 0.0), c + Vec3::new(0.0, 0.0, 0.02)]);
            indices.push([3 * t, 3 * t + 1, 3 * t + 2]);
        }
        let mut scene = Scene::default();
        scene.materials.push(Material { emission: Vec3::splat(50.0), ..Material::default() });
        scene.meshes.push(Mesh { name: "lamps".into(), material: vec![0; indices.len()], positions, indices, ..Mesh::default() });
        scene.instances.push(Instance { geom: Geom::Mesh(0), world_from_object: Affine3A::IDENTITY });
        let emissive = area::emissive_triangles(&scene);
        let set = LightSet::of(&scene, Some((Vec3::splat(-4.0), Vec3::splat(4.0))), &emissive, &[]);
        assert_eq!(set.entries.len(), 60);
        assert!(matches!(set.groups.as_slice(), [Members::Tree { .. }]));
        let (p, n) = (Vec3::new(1.0, 0.0, -1.0), Vec3::Y);
        let pmf: Vec<f32> = (0..60).map(|i| set.pmf(i, p, n)).collect();
        assert!((pmf.iter().sum::<f32>() - 1.0).abs() < 1e-4, "{pmf:?}");
        // The irradiance at p: each tiny triangle as a point of its area.
        let mut expected = 0.0f64;
        let mut nearest = (f32::INFINITY, 0);
        for (i, e) in set.entries.iter().enumerate() {
            let Entry::Area(AreaLight::Tri(t)) = e else { panic!("a triangle") };
            let to = t.p0 + (t.e1 + t.e2) / 3.0 - p;
            let (d2, w) = (to.length_squared(), to.normalize());
            expected += f64::from(50.0 * t.area * n.dot(w).max(0.0) * t.n.dot(-w).max(0.0) / d2);
            if d2 < nearest.0 {
                nearest = (d2, i);
            }
        }
        assert!(pmf[nearest.1] > 2.0 / 60.0, "the nearest: {}", pmf[nearest.1]);
        let m = 400;
        let mut sum = 0.0f64;
        for i in 0..m {
            for j in 0..16 {
                let u2 = ((j % 4) as f32 / 4.0 + 0.125, (j / 4) as f32 / 4.0 + 0.125);
                let Some(ls) = set.sample(p, n, (i as f32 + 0.5) / m as f32, u2, &[], false) else { continue };
                sum += f64::from(ls.li.x * n.dot(ls.dir).max(0.0) / ls.pdf);
            }
        }
        let mean = sum / f64::from(16 * m);
        assert!((mean / expected - 1.0).abs() < 0.03, "{mean} against {expected}");
    }

    #[test]
    fn with_user_lights_light_objects_are_chosen_uniformly() {
        #[derive(Debug)]
        struct Lamp;
        impl LightModel for Lamp {
            fn sample(&self, _: Vec3, _: (f32, f32)) -> Option<LightSample> {
                None
            }
            fn power(&self) -> f32 {
                1.0
            }
        }
        let mut scene = Scene::default();
        for i in 0..3 {
            scene.lights.push(Light {
                kind: LightKind::Point { position: Vec3::new(i as f32, 1.0, 0.0) },
                color: Vec3::ONE,
                inverse_square: true,
            });
        }
        let set = LightSet::of(&scene, Some((Vec3::splat(-1.0), Vec3::splat(20.0))), &[], &[Arc::new(Lamp)]);
        assert!(!set.weighed);
        for i in 0..4 {
            assert_eq!(set.pmf(i, Vec3::ZERO, Vec3::Y), 0.25);
        }
    }
}
