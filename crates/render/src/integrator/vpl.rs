//! Instant global illumination: indirect light from virtual point lights (VPLs), as
//! SaarCOR lit its scenes. Keller, "Instant Radiosity" (SIGGRAPH 1997): light paths
//! leave the lights and a VPL is left wherever one meets a non-specular surface; Wald,
//! Kollig, Benthin, Keller and Slusallek, "Interactive Global Illumination using Fast Ray
//! Tracing" (EGWR 2002), and Benthin, Wald and Slusallek, "A Scalable Approach to
//! Interactive Global Illumination" (Eurographics 2003): interleaved sampling (the VPLs
//! are split into M × M sets, pixel (x, y) is lit by set (x mod M, y mod M) only) and a
//! discontinuity buffer that averages the indirect light over each M × M neighbourhood
//! among neighbours of similar depth and normal, which gives every pixel the light of all
//! sets at the cost of one.
//!
//! A pixel's radiance is
//! - emission seen directly or through mirrors and glass (delta lobes are followed, up to
//!   [`SPECULAR_DEPTH`] of them, as the path tracer does);
//! - direct light at the first non-specular surface, by next-event estimation (one light
//!   sample, as the path tracer chooses it);
//! - indirect light there: for each VPL `v` of the pixel's set,
//!   `Φ_v · f_v(ω_v, v→x) |cos| · f_x(x→v, ω_o) |cos| / max(d², d_min²) · V(v, x)`,
//!   where `Φ_v` is the power the light path carried to `v` over the set's number of
//!   paths, `f_v` the BSDF where the VPL lies (seen from where its light came) and `V`
//!   the shadow ray's answer.
//!
//! Bias, as stated: clamping (`d_min` = [`VplSettings::clamp`] × the scene's diagonal)
//! removes the light of VPLs nearer than `d_min`, which darkens concave corners and
//! contact regions only; without clamping (`clamp = 0`) the estimate converges to the
//! path tracer's (tests/vpl.rs). Caustics seen directly (light → mirror or glass → a
//! diffuse surface seen by the camera) are not estimated: no VPL lies on a delta surface
//! and next-event estimation cannot pass one. The user's lights ([`crate::LightModel`])
//! give direct light only (they cannot start a light path).
//!
//! Shadow rays leave the VPL: the rays toward one VPL from one tile's pixels of its set
//! are grouped and share their origin (the packet kernels cull whole triangles for rays
//! of a common origin). They are traced as a packet when there are at least
//! `SHADOW_PACKET_MIN` (interleaving 1 or 2), else one by one, which measured faster
//! for 4 × 4 interleaving's 16 (SaarCOR's "shadow rays toward a point light are
//! coherent" does not make these long, mostly unoccluded rays cheap here: `bench vpl`).
//!
//! Faint terms by Russian roulette ([`SHADOW_ROULETTE`]): a VPL whose unshadowed light at
//! a pixel is under half the mean of its set's terms there has its shadow ray traced only
//! with probability (its light / that bar), and its light divided by that probability when
//! traced.
//! Unbiased; at 512 × 384 it leaves 74% of the rays of a Conference frame and 49% of a
//! kitchen frame, the frames take 1/1.15 and 1/1.27 of the time (medians of five
//! interleaved pairs), and the VPL images' relMSE against path tracing is unchanged to the
//! fourth digit on the Cornell box, Sponza and both kitchens (`bench vpl`, stop 62).
//!
//! The terms run on lanes without packing anything (`TermLanes`): a VPL's BSDF is one
//! BSDF over the chunk's pixels (their directions, distances and the VPL's BSDF values
//! in one loop over lanes), and a pixel's BSDF is one BSDF over its set's VPLs; then
//! the terms, their shadow rays and the roulette are loops over lanes again. The same
//! numbers as `vpl_term` and `shadow_roulette`, which the ray-by-ray reference
//! keeps. (Packing the pixels' BSDFs by model, as the lane path tracer does, had been
//! measured slower than the scalar terms: 1.17x on the kitchen.)
//!
//! Random numbers: light paths from the [`Sampler`] (Owen-scrambled Sobol'), path `i` of
//! frame `k` its index `i` in a sequence scrambled per frame, so each frame (sample index)
//! has its own set and a still image converges as frames accumulate; camera-side numbers
//! from the pixel's sampler, as the path tracer's. Everything is a pure function of
//! (pixel, sample): images do not depend on thread count or tile order.

use super::hit::{bsdf_frame, emitted, light_normal, material, packet_first_hits, shading_normal};
use crate::aov::{dark, demodulate, demodulating, Layers};
use crate::bsdf::{Bsdf, Diffuse, DiffuseGlossy};
use crate::camera::Camera;
use crate::color::luminance;
use crate::denoise::spread_outliers_of_layers;
use crate::film::Region;
use crate::lanes::{get3, on_lanes, put3};
use crate::sampler::{hashed_at, CameraSamples, PixelSampler, DEFAULT_SEED};
use crate::sampling::ShadingFrame;
use crate::tiles::{Job, Sink, NO_RAYS, TILE};
use crate::world::record::rays_traced_here;

/// Tile edge of VPL frames: 16 × 16 pixels (with 4 × 4 interleaving a VPL's shadow rays
/// from one tile are a packet of 16). Measured on the Cornell box at 512 × 384 (4 frames,
/// 2 threads): 32 × 32 tiles (packets of 64) took the same CPU time and more wall time.
const VPL_TILE: u32 = 16;
use crate::sampler::Sampler;
use crate::world::World;
use glam::Vec3;
use lucent_accel::{Hit, Ray};
use rayon::prelude::*;

/// The instant-radiosity integrator's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VplSettings {
    /// VPLs per frame (at least; light paths are finished and every set gets as many
    /// paths).
    pub count: u32,
    /// Most path segments, as the path tracer counts them (`u32::MAX`: unlimited): a
    /// VPL left at a light path's `d`-th surface (from 1) lights a camera ray's surface
    /// through paths of `d + 2` segments, so only those with `d + 2 ≤ max_depth` are
    /// made. Light paths also end by Russian roulette after the third surface, and after
    /// [`MAX_BOUNCES`].
    pub max_depth: u32,
    /// The least distance, as a fraction of the scene's diagonal, at which a VPL's light
    /// is evaluated (the geometry term's clamp); 0: no clamping (unbiased, noisier).
    pub clamp: f32,
    /// Interleaving: the VPLs are split into `interleave²` sets, one per pixel of each
    /// `interleave` × `interleave` square (1: every pixel sees every VPL).
    pub interleave: u32,
    /// Filter the indirect light with the discontinuity buffer (removes the interleaving
    /// pattern).
    pub discontinuity: bool,
    /// The sampler's seed.
    pub seed: u32,
}

impl Eq for VplSettings {}

impl Default for VplSettings {
    fn default() -> Self {
        Self { count: 256, max_depth: u32::MAX, clamp: DEFAULT_CLAMP, interleave: 4, discontinuity: true, seed: DEFAULT_SEED }
    }
}

/// The default clamp (fraction of the scene's diagonal; see [`VplSettings::clamp`]).
pub const DEFAULT_CLAMP: f32 = 0.04;

/// The fewest shadow rays toward one VPL that are traced as a packet (see
/// `trace_layers`).
const SHADOW_PACKET_MIN: usize = 48;

/// Most surfaces a light path meets.
pub const MAX_BOUNCES: u32 = 64;

/// Most delta lobes (mirror, glass) a camera path follows to its shading point.
pub const SPECULAR_DEPTH: u32 = 8;

/// The sampler row of light paths (far from any pixel's; two rows per set).
const LIGHT_ROW: u32 = 0x7fff_0000;

impl VplSettings {
    /// Where the camera samples of an image of `spp` samples per pixel lie (see
    /// [`crate::Integrator::camera_samples`]).
    #[must_use]
    pub fn camera_samples(&self, spp: u32) -> CameraSamples {
        CameraSamples { sobol: Some(self.sampler()), centred: spp <= 1, filter: lucent_scene::PixelFilter::Box }
    }

    /// The sampler of the camera side.
    #[must_use]
    pub fn sampler(&self) -> Sampler {
        Sampler::new(self.seed)
    }

    /// Sets of VPLs (`interleave²`).
    #[must_use]
    pub fn sets(&self) -> u32 {
        self.interleave.clamp(1, 64).pow(2)
    }

    /// The set of pixel (x, y).
    #[inline]
    #[must_use]
    pub fn set_of(&self, x: u32, y: u32) -> u32 {
        let m = self.interleave.clamp(1, 64);
        (y % m) * m + x % m
    }
}

/// A virtual point light.
#[derive(Clone, Copy, Debug)]
pub struct Vpl<'w> {
    /// Position.
    pub p: Vec3,
    /// Where its shadow rays start: off the surface on the side of its geometric normal,
    /// and on the other side.
    org: [Vec3; 2],
    ng: Vec3,
    frame: ShadingFrame,
    /// Toward where its light came from (local).
    wo: Vec3,
    bsdf: Bsdf<'w>,
    /// Power (over the set's number of paths).
    pub flux: Vec3,
}

/// The VPLs of one frame, grouped by set.
#[derive(Clone, Debug)]
pub struct VplSet<'w> {
    /// The settings it was made with.
    pub settings: VplSettings,
    /// The frame (sample index) it belongs to.
    pub frame: u32,
    vpls: Vec<Vpl<'w>>,
    /// Where each set's VPLs lie in `vpls`.
    ranges: Vec<std::ops::Range<usize>>,
    /// Light paths per set.
    pub paths_per_set: u32,
}

impl<'w> VplSet<'w> {
    /// The VPLs of frame (sample index) `frame`: light paths, one set after another,
    /// until there are [`VplSettings::count`] VPLs and every set has as many paths (or
    /// 64 × `count` paths left none: a scene whose light escapes).
    #[must_use]
    pub fn generate(w: &'w World, s: &VplSettings, frame: u32) -> Self {
        let sets = s.sets() as usize;
        let mut per_set: Vec<Vec<Vpl<'w>>> = vec![Vec::new(); sets];
        let lights = &w.light_set;
        if lights.is_empty() {
            return Self { settings: *s, frame, vpls: Vec::new(), ranges: vec![0..0; sets], paths_per_set: 0 };
        }
        let sampler = Sampler::new(s.seed ^ 0x9e37_79b9);
        let cap = (s.count as usize).saturating_mul(64).max(sets);
        let (mut paths, mut total) = (0usize, 0usize);
        while total < s.count as usize || !paths.is_multiple_of(sets) {
            if paths >= cap && paths.is_multiple_of(sets) {
                break;
            }
            // Each set's paths are a sequence of their own (every set covers the lights).
            let set = paths % sets;
            let i = (paths / sets) as u32;
            let row = LIGHT_ROW + 2 * set as u32;
            paths += 1;
            let u = |pair: u32| sampler.get2(frame, row, i, pair);
            let choice = |k: u32| sampler.get1(frame, row + 1, i, k);
            let Some(e) = lights.sample_emission(choice(0), u(0), u(1), &w.scene.textures) else { continue };
            let org = match e.n {
                // (Off the emitting surface by a bound on the point's rounding error.)
                Some(n) => e.p + n * (e.p.abs().max_element() * 8.0 * f32::EPSILON + f32::MIN_POSITIVE),
                None => e.p,
            };
            let mut ray = Ray::new(org, e.dir);
            let mut beta = e.flux;
            for depth in 0..MAX_BOUNCES.min(s.max_depth.saturating_sub(2)) {
                let Some((hit_ray, hit)) = w.intersect_solid(&ray) else { break };
                let surf = w.surface(&hit_ray, &hit);
                let d = hit_ray.dir.normalize();
                let ns = shading_normal(w, &hit_ray, &hit, &surf);
                let (bsdf, fr) = bsdf_frame(w, &hit_ray, &hit, &surf, ns, d);
                let wo = fr.to_local(-d);
                if !bsdf.is_delta() {
                    let off = surf.offset();
                    per_set[set].push(Vpl {
                        p: surf.p,
                        org: [surf.p + surf.ng * off, surf.p - surf.ng * off],
                        ng: surf.ng,
                        frame: fr,
                        wo,
                        bsdf,
                        flux: beta,
                    });
                    total += 1;
                }
                let Some(bs) = bsdf.sample(wo, choice(2 + 2 * depth), u(2 + depth)) else { break };
                // Light (importance) crosses a refracting boundary without the radiance's
                // 1/η² (Veach 1997, §5.2): the sample's weight carries it, so it is undone.
                let prev = beta;
                beta *= bs.weight * (bs.eta * bs.eta);
                if !beta.is_finite() || beta.max_element() <= 0.0 {
                    break;
                }
                // Russian roulette after the third bounce: survival by the power kept.
                if depth >= 3 {
                    let q = (beta.max_element() / prev.max_element().max(1e-30)).min(0.95);
                    if choice(3 + 2 * depth) >= q {
                        break;
                    }
                    beta /= q;
                }
                ray = surf.spawn(fr.to_world(bs.wi));
            }
        }
        let paths_per_set = (paths / sets).max(1) as u32;
        let mut vpls = Vec::with_capacity(total);
        let mut ranges = Vec::with_capacity(sets);
        for mut v in per_set {
            for x in &mut v {
                x.flux /= paths_per_set as f32;
            }
            let start = vpls.len();
            vpls.extend(v);
            ranges.push(start..vpls.len());
        }
        Self { settings: *s, frame, vpls, ranges, paths_per_set }
    }

    /// Every VPL.
    #[must_use]
    pub fn all(&self) -> &[Vpl<'w>] {
        &self.vpls
    }

    /// The VPLs of set `k`.
    #[must_use]
    pub fn set(&self, k: u32) -> &[Vpl<'w>] {
        self.ranges.get(k as usize).map_or(&[], |r| &self.vpls[r.clone()])
    }
}

/// The first non-specular surface a camera ray leads to, as the VPLs light it.
#[derive(Clone, Copy, Debug)]
struct Shade<'w> {
    p: Vec3,
    ng: Vec3,
    off: f32,
    frame: ShadingFrame,
    wo: Vec3,
    bsdf: Bsdf<'w>,
    /// Throughput of the specular chain that led here.
    beta: Vec3,
}

/// Follows a camera ray (its first hit given, when known) through delta lobes to its
/// shading point: the emission on the way into `l.emitted`, the shading point's normal and
/// distance along the way into `l`; returns the shading point and its direct light.
fn camera_path<'w>(
    w: &'w World,
    camera_ray: &Ray,
    s: &VplSettings,
    (x, y): (u32, u32),
    k: u32,
    first: Option<Option<Hit>>,
    l: &mut Layers,
) -> Option<(Shade<'w>, Vec3)> {
    let px = s.sampler().pixel(x, y);
    let lights = &w.light_set;
    let textures = &w.scene.textures;
    let mut beta = Vec3::ONE;
    let mut ray = *camera_ray;
    let mut first = first;
    let mut dist = 0.0f32;
    l.depth = f32::INFINITY;
    for depth in 0..=SPECULAR_DEPTH {
        let found = w.first_hit(&ray, first.take());
        let Some((hit_ray, hit)) = found else {
            let d = ray.dir.normalize();
            l.emitted += beta * lights.env_radiance(d).unwrap_or(w.scene.background);
            return None;
        };
        ray = hit_ray;
        let surf = w.surface(&ray, &hit);
        let d = ray.dir.normalize();
        let mat = material(w, surf.material);
        if mat.emission.max_element() > 0.0 && d.dot(surf.ng) < 0.0 {
            l.emitted += beta * emitted(w, mat, surf.uv);
        }
        let ns = shading_normal(w, &ray, &hit, &surf);
        dist += (surf.p - ray.org).length();
        let (bsdf, fr) = bsdf_frame(w, &ray, &hit, &surf, ns, d);
        let wo = fr.to_local(-d);
        // The guides of the surface lit, past mirrors and glass (as the path tracer's
        // guides, `guides::through_specular`): its normal, the distance along the way; the
        // last mirror's or glass's where the way leaves the scene.
        l.normal = ns;
        l.depth = dist;
        if !bsdf.is_delta() {
            // Direct light: next-event estimation alone (emitters met through delta lobes
            // counted above; no BSDF-sampled direct light to weigh against).
            let mut direct = Vec3::ZERO;
            if let Some(ls) = lights.sample(surf.p, light_normal(&bsdf, &fr), px.get1(k, depth), px.get2(k, 1 + depth), textures, false) {
                let f = bsdf.eval(wo, fr.to_local(ls.dir));
                if f.max_element() > 0.0 {
                    let tmax = if ls.dist.is_finite() { ls.dist * (1.0 - 1e-4) } else { f32::INFINITY };
                    if !w.occluded_solid(&surf.spawn(ls.dir).with_range(0.0, tmax)) {
                        direct = beta * f * ls.li / ls.pdf;
                    }
                }
            }
            l.albedo = beta * w.prepared(surf.material).albedo(textures, surf.uv);
            return Some((Shade { p: surf.p, ng: surf.ng, off: surf.offset(), frame: fr, wo, bsdf, beta }, direct));
        }
        let bs = bsdf.sample(wo, px.get1_hashed(k, 0x100 + depth), (0.5, 0.5))?;
        beta *= bs.weight;
        if !beta.is_finite() || beta.max_element() <= 0.0 {
            return None;
        }
        ray = surf.spawn(fr.to_world(bs.wi));
    }
    None
}

/// A VPL's light at a shading point, before the shadow ray: the contribution and the
/// shadow ray (from the VPL toward the point); `None` when it is zero.
#[inline]
fn vpl_term(v: &Vpl, sh: &Shade, d_min2: f32) -> Option<(Vec3, Ray)> {
    let to = sh.p - v.p;
    let d2 = to.length_squared();
    if d2.is_nan() || d2 <= 0.0 {
        return None;
    }
    let dir = to / d2.sqrt();
    let fv = v.bsdf.eval(v.wo, v.frame.to_local(dir));
    if fv.max_element() <= 0.0 {
        return None;
    }
    let fx = sh.bsdf.eval(sh.wo, sh.frame.to_local(-dir));
    term_of(v, sh, d2, fv, fx, d_min2)
}

/// [`vpl_term`] from the squared distance and the two BSDF values (the VPL's toward the
/// point, the point's toward the VPL), once `d2` is a positive number and `fv` positive.
#[inline]
fn term_of(v: &Vpl, sh: &Shade, d2: f32, fv: Vec3, fx: Vec3, d_min2: f32) -> Option<(Vec3, Ray)> {
    let t = term_parts((v.p, v.ng, v.flux), (sh.p, sh.ng, sh.off, sh.beta), d2, fv, fx, d_min2, v.org);
    t.ok.then(|| (t.c, Ray::new(t.org, t.dir).with_range(0.0, t.len)))
}

/// A VPL's term at a shading point, and its shadow ray, as [`term_parts`] makes them.
struct TermParts {
    /// The term.
    c: Vec3,
    /// The shadow ray: its origin (off the VPL's surface on the point's side), unit
    /// direction and length (it ends off the point's surface on the VPL's side).
    org: Vec3,
    dir: Vec3,
    len: f32,
    /// Whether it leaves the VPL's upper side (`org` is the first of the VPL's origins).
    upper: bool,
    /// Whether the term carries light (else [`vpl_term`] gives `None`).
    ok: bool,
}

/// The term of VPL (position, geometric normal, flux) at shading point (position,
/// geometric normal, offset, throughput), from the squared distance between them and the
/// two BSDF values, branch-free: one piece for [`vpl_term`] and the lanes
/// ([`TermLanes::finish`]), so both give the same bits.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn term_parts(
    (vp, vng, flux): (Vec3, Vec3, Vec3),
    (p, png, off, beta): (Vec3, Vec3, f32, Vec3),
    d2: f32,
    fv: Vec3,
    fx: Vec3,
    d_min2: f32,
    orgs: [Vec3; 2],
) -> TermParts {
    let c = flux * fv * fx * beta / d2.max(d_min2);
    let upper = (p - vp).dot(vng) >= 0.0;
    let org = if upper { orgs[0] } else { orgs[1] };
    // (The shadow ray ends off the point's surface, on the VPL's side.)
    let n = if (vp - p).dot(png) < 0.0 { -png } else { png };
    let seg = (p + n * off) - org;
    let len = seg.length();
    let ok = !(d2.is_nan() | (d2 <= 0.0)) & (fv.max_element() > 0.0) & (fx.max_element() > 0.0) & c.is_finite() & (len > 0.0);
    TermParts { c, org, dir: seg / len, len, upper, ok }
}

/// Pixels per chunk of a set's pixels in a tile: the VPL terms' lanes.
const CHUNK: usize = 64;
/// Rows of a chunk's lanes (x, y, z).
type ChunkRows = [[f32; CHUNK]; 3];

/// Lanes per strip of the VPL terms' loops: `n` lanes run as whole strips (a loop of this
/// constant count vectorizes whole).
const STRIP: usize = 16;

/// The strips that hold `n` lanes (at most a chunk's).
#[inline]
fn strips(n: usize) -> usize {
    n.div_ceil(STRIP).min(CHUNK / STRIP)
}

/// One VPL's terms at a chunk's pixels, computed on lanes: the same numbers as
/// [`vpl_term`]'s (the same operations in the same order).
#[derive(Clone)]
struct TermLanes {
    /// From the VPL toward each pixel's point: the unit direction (then the shadow ray's)
    /// and the squared distance.
    dir: ChunkRows,
    d2: [f32; CHUNK],
    /// The VPL's BSDF toward each pixel, each pixel's toward the VPL, then the term.
    fv: ChunkRows,
    fx: ChunkRows,
    /// The shadow ray's length, whether it leaves the VPL's upper side, and whether
    /// the term carries light (else [`vpl_term`] gives `None`).
    len: [f32; CHUNK],
    upper: [bool; CHUNK],
    ok: [bool; CHUNK],
    /// The term's luminance (for the shadow roulette).
    lum: [f32; CHUNK],
}

/// A chunk's shading points as rows: position, geometric normal, offset, throughput.
struct Points {
    p: ChunkRows,
    ng: ChunkRows,
    off: [f32; CHUNK],
    beta: ChunkRows,
}

impl TermLanes {
    fn new() -> Self {
        let z = [[0.0; CHUNK]; 3];
        Self { dir: z, d2: [0.0; CHUNK], fv: z, fx: z, len: [0.0; CHUNK], upper: [false; CHUNK], ok: [false; CHUNK], lum: [0.0; CHUNK] }
    }

    /// The directions from `v` toward the points `p` (every lane) and `v`'s BSDF toward
    /// the first `n`.
    fn toward(&mut self, v: &Vpl, p: &ChunkRows, n: usize) {
        let mut local = [[0.0; CHUNK]; 3];
        on_lanes!(|t: &mut TermLanes, local: &mut ChunkRows, p: &ChunkRows, vp: Vec3, fr: ShadingFrame, strips: usize| {
            for s in 0..strips {
                for k in 0..STRIP {
                    let j = s * STRIP + k;
                    let to = get3(p, j) - vp;
                    let d2 = to.length_squared();
                    let dir = to / d2.sqrt();
                    t.d2[j] = d2;
                    put3(&mut t.dir, j, dir);
                    put3(local, j, fr.to_local(dir));
                }
            }
        })(self, &mut local, p, v.p, v.frame, strips(n));
        eval_lanes(&v.bsdf, v.wo, &local, n, &mut self.fv);
    }

    /// With both BSDFs' values: the terms (into `fv`), whether each carries light, and
    /// the shadow rays ([`term_parts`], as [`term_of`]).
    fn finish(&mut self, v: &Vpl, pts: &Points, n: usize, d_min2: f32) {
        on_lanes!(|t: &mut TermLanes, pts: &Points, v: (Vec3, Vec3, Vec3), orgs: [Vec3; 2], d_min2: f32, strips: usize| {
            for s in 0..strips {
                for k in 0..STRIP {
                    let j = s * STRIP + k;
                    let point = (get3(&pts.p, j), get3(&pts.ng, j), pts.off[j], get3(&pts.beta, j));
                    let r = term_parts(v, point, t.d2[j], get3(&t.fv, j), get3(&t.fx, j), d_min2, orgs);
                    put3(&mut t.fv, j, r.c);
                    put3(&mut t.dir, j, r.dir);
                    t.len[j] = r.len;
                    t.upper[j] = r.upper;
                    t.ok[j] = r.ok;
                    t.lum[j] = luminance(r.c);
                }
            }
        })(self, pts, (v.p, v.ng, v.flux), v.org, d_min2, strips(n));
    }

    /// The shadow roulette ([`shadow_roulette`]) of every lane: `bar`, the lanes' bars,
    /// `seeds` their pixels' [`PixelSampler::hashed_seed`], `vi` the VPL's number in its
    /// set. A term it drops no longer carries light; one it keeps is divided by its
    /// chance.
    fn roulette(&mut self, bar: &[f32; CHUNK], seeds: &[u32; CHUNK], vi: usize, n: usize) {
        on_lanes!(|t: &mut TermLanes, bar: &[f32; CHUNK], seeds: &[u32; CHUNK], dim: u32, strips: usize| {
            for s in 0..strips {
                for k in 0..STRIP {
                    let j = s * STRIP + k;
                    let (c, kept) = roulette_of(get3(&t.fv, j), t.lum[j], bar[j], hashed_at(seeds[j], dim));
                    put3(&mut t.fv, j, c);
                    t.ok[j] &= kept;
                }
            }
        })(self, bar, seeds, ROULETTE_DIM + vi as u32, strips(n));
    }

    /// Lane `j`'s term and shadow ray, when it carries light.
    #[inline]
    fn term(&self, v: &Vpl, j: usize) -> Option<(Vec3, Ray)> {
        let org = if self.upper[j] { v.org[0] } else { v.org[1] };
        self.ok[j].then(|| (get3(&self.fv, j), Ray::new(org, get3(&self.dir, j)).with_range(0.0, self.len[j])))
    }
}

/// `bsdf.eval(wo, wi[j])` into `f[j]` for the lanes `j < n` (and, for the models on
/// lanes, past it to a whole strip of 16, unused): the Lambertian and MTL's models (the
/// VPL scenes' materials) in loops over lanes, the others one by one.
fn eval_lanes(bsdf: &Bsdf, wo: Vec3, wi: &ChunkRows, n: usize, f: &mut ChunkRows) {
    let strips = strips(n);
    match *bsdf {
        Bsdf::Diffuse(b) => on_lanes!(|b: Diffuse, wo: Vec3, wi: &ChunkRows, strips: usize, f: &mut ChunkRows| {
            for s in 0..strips {
                for k in 0..STRIP {
                    let j = s * STRIP + k;
                    put3(f, j, b.eval(wo, get3(wi, j)));
                }
            }
        })(b, wo, wi, strips, f),
        Bsdf::DiffuseGlossy(b) => on_lanes!(|b: DiffuseGlossy, wo: Vec3, wi: &ChunkRows, strips: usize, f: &mut ChunkRows| {
            for s in 0..strips {
                for k in 0..STRIP {
                    let j = s * STRIP + k;
                    put3(f, j, b.eval_pdf(wo, get3(wi, j)).0);
                }
            }
        })(b, wo, wi, strips, f),
        _ => {
            for j in 0..n.min(CHUNK) {
                put3(f, j, bsdf.eval(wo, get3(wi, j)));
            }
        }
    }
}

/// The terms of the VPLs `vpls` at the shading points `shades` (at most [`CHUNK`]), one
/// [`TermLanes`] per VPL in `lanes`, as [`vpl_term`] gives them: each VPL's directions
/// and BSDF over the points on lanes, then each point's BSDF over the VPLs, then the
/// terms and shadow rays on lanes.
fn chunk_terms<'w>(vpls: &[Vpl<'w>], shades: &[&Shade<'w>], d_min2: f32, lanes: &mut Vec<TermLanes>) {
    let n = shades.len().min(CHUNK);
    let z = [[0.0; CHUNK]; 3];
    let mut pts = Points { p: z, ng: z, off: [0.0; CHUNK], beta: z };
    for (j, sh) in shades[..n].iter().enumerate() {
        put3(&mut pts.p, j, sh.p);
        put3(&mut pts.ng, j, sh.ng);
        pts.off[j] = sh.off;
        put3(&mut pts.beta, j, sh.beta);
    }
    if lanes.len() < vpls.len() {
        lanes.resize(vpls.len(), TermLanes::new());
    }
    for (t, v) in lanes.iter_mut().zip(vpls) {
        t.toward(v, &pts.p, n);
    }
    // Each point's BSDF toward the VPLs, up to CHUNK of them at a time.
    let (mut local, mut f) = (z, z);
    for (j, sh) in shades[..n].iter().enumerate() {
        for group in lanes[..vpls.len()].chunks_mut(CHUNK) {
            for (i, t) in group.iter().enumerate() {
                put3(&mut local, i, sh.frame.to_local(-get3(&t.dir, j)));
            }
            eval_lanes(&sh.bsdf, sh.wo, &local, group.len(), &mut f);
            for (i, t) in group.iter_mut().enumerate() {
                put3(&mut t.fx, j, get3(&f, i));
            }
        }
    }
    for (t, v) in lanes.iter_mut().zip(vpls) {
        t.finish(v, &pts, n, d_min2);
        // (Lanes past the chunk's points carry nothing.)
        t.ok[n..].fill(false);
    }
}

/// The squared least distance of a VPL's light (see [`VplSettings::clamp`]).
fn d_min2(w: &World, s: &VplSettings) -> f32 {
    let d = s.clamp.max(0.0) * w.scale();
    if d.is_finite() {
        d * d
    } else {
        0.0
    }
}

/// One pixel sample, ray by ray (the reference the tiled renderer must match): its
/// layers, with the indirect light of the VPLs of the pixel's set.
#[must_use]
pub fn li_layers(w: &World, ray: &Ray, set: &VplSet, pixel: (u32, u32)) -> Layers {
    let (s, k) = (&set.settings, set.frame);
    let mut l = Layers::default();
    let Some((sh, direct)) = camera_path(w, ray, s, pixel, k, None, &mut l) else { return l };
    let d_min2 = d_min2(w, s);
    let mut ind = direct;
    let vpls = set.set(s.set_of(pixel.0, pixel.1));
    let terms: Vec<_> = vpls.iter().map(|v| vpl_term(v, &sh, d_min2)).collect();
    let bar = roulette_bar(terms.iter().flatten().map(|(c, _)| *c));
    let px = s.sampler().pixel(pixel.0, pixel.1);
    for (i, t) in terms.iter().enumerate() {
        if let Some((c, r)) = t {
            if let Some(c) = shadow_roulette(*c, bar, &px, k, i) {
                if !w.occluded_solid(r) {
                    ind += c;
                }
            }
        }
    }
    l.lit = demodulate(ind, l.albedo);
    l
}

/// Shadow rays of faint VPL terms are traced by Russian roulette: a term whose unshadowed
/// light is less than this fraction of the mean of its pixel's VPL terms (those that carry
/// light) is traced with probability (its light / the bar) and, if traced, weighed by the
/// inverse, so the estimate stays unbiased (Ward's adaptive shadow testing, "Adaptive
/// Shadow Testing for Ray Tracing", EGWR 1991, made unbiased by Russian roulette); 0
/// traces every term. Relative to the mean, not the sum, so that the added noise does not
/// grow with the VPLs per pixel (interleaving 1 gives each pixel all of them).
pub const SHADOW_ROULETTE: f32 = 0.5;

/// The shadow roulette's bar for a pixel whose VPL terms are `terms` (see
/// [`SHADOW_ROULETTE`]).
#[inline]
fn roulette_bar(terms: impl Iterator<Item = Vec3>) -> f32 {
    let (mut sum, mut n) = (0f32, 0u32);
    for c in terms {
        sum += luminance(c);
        n += 1;
    }
    bar_of(sum, n)
}

/// The shadow roulette's bar for `n` terms whose luminances sum to `sum`.
#[inline]
fn bar_of(sum: f32, n: u32) -> f32 {
    if n == 0 {
        0.0
    } else {
        SHADOW_ROULETTE * sum / n as f32
    }
}

/// Sampler dimensions of the shadow roulette (one per VPL of the set), past the camera
/// path's.
const ROULETTE_DIM: u32 = 0x1000;

/// VPL term `c` (number `i` of its pixel's set, whose [`roulette_bar`] is `bar`) after the
/// shadow roulette (see [`SHADOW_ROULETTE`]): `None` when its shadow ray is not traced.
#[inline]
fn shadow_roulette(c: Vec3, bar: f32, px: &PixelSampler, k: u32, i: usize) -> Option<Vec3> {
    let (c, kept) = roulette_of(c, luminance(c), bar, px.get1_hashed(k, ROULETTE_DIM + i as u32));
    kept.then_some(c)
}

/// [`shadow_roulette`] of term `c` of luminance `l` against `bar`, with the number `u`,
/// branch-free (one piece for it and the lanes, [`TermLanes::roulette`]): the term (divided
/// by its chance where it had one) and whether it is kept.
#[inline(always)]
fn roulette_of(c: Vec3, l: f32, bar: f32, u: f32) -> (Vec3, bool) {
    let chance = (bar > 0.0) & bar.is_finite() & (l < bar);
    let q = l / bar;
    (if chance { c / q } else { c }, !chance | (u < q))
}

/// The layers of every pixel of `r` (row-major) for the sample `set` belongs to, tile by
/// tile (32 × 32) on all cores: camera rays of each 8 × 8 block as a packet, then per
/// tile and VPL one packet of shadow rays from the VPL to the tile's pixels of its set. Returns the
/// rays traced.
pub fn trace_layers(w: &World, cam: &Camera, job: &Job, set: &VplSet, r: Region, out: &mut [Layers]) -> u64 {
    let (s, k) = (&set.settings, set.frame);
    let width = r.x1 - r.x0;
    if width == 0 || r.y1 <= r.y0 {
        return 0;
    }
    let d_min2 = d_min2(w, s);
    // (A filter with negative lobes would need signed weights through the discontinuity
    // buffer: VPL frames take the box filter instead.)
    let filter = if job.filter.signed() { lucent_scene::PixelFilter::Box } else { job.filter };
    let cs = CameraSamples { filter, ..set.settings.camera_samples(job.spp.max(1)) };
    let packets = job.traversal.packets;
    // Bands of VPL_TILE rows, tiles of VPL_TILE columns; per band, the tile's buffers.
    const N: usize = (VPL_TILE * VPL_TILE) as usize;
    out.par_chunks_mut((width * VPL_TILE) as usize)
        .enumerate()
        .map(|(band, rows)| {
            let y0 = r.y0 + band as u32 * VPL_TILE;
            let y1 = (y0 + VPL_TILE).min(r.y1);
            let before = rays_traced_here();
            let mut shades: Vec<Option<Shade>> = vec![None; N];
            let mut layers = vec![Layers::default(); N];
            let mut coords = vec![(0u32, 0u32); N];
            // Each pixel's VPL set (computed once: `set_of` divides).
            let mut set_ids = vec![0u32; N];
            // Light reflected at each pixel's shading point: direct, then the VPLs'.
            let mut ind = vec![Vec3::ZERO; N];
            let mut who = vec![0usize; N];
            let mut term_lanes: Vec<TermLanes> = Vec::new();
            // (A VPL's shadow rays and terms; only the first `q` are read.)
            let mut rays = NO_RAYS;
            let mut terms = [(0usize, Vec3::ZERO); 64];
            let mut x0 = r.x0;
            while x0 < r.x1 {
                let x1 = (x0 + VPL_TILE).min(r.x1);
                shades.fill(None);
                layers.fill(Layers::default());
                ind.fill(Vec3::ZERO);
                let mut n = 0;
                // (In 8 × 8 blocks: each a coherent packet of camera rays.)
                for by in (y0..y1).step_by(8) {
                    for bx in (x0..x1).step_by(8) {
                        for y in by..(by + 8).min(y1) {
                            for x in bx..(bx + 8).min(x1) {
                                coords[n] = (x, y);
                                set_ids[n] = s.set_of(x, y);
                                n += 1;
                            }
                        }
                    }
                }
                // Camera rays, 64 at a time.
                for c in (0..n).step_by(64) {
                    let m = (n - c).min(64);
                    let mut rays = NO_RAYS;
                    let mut pts = [(0f32, 0f32); 64];
                    for (p, &(x, y)) in pts.iter_mut().zip(&coords[c..c + m]) {
                        let (jx, jy) = cs.pixel(x, y, k);
                        *p = (x as f32 + jx, y as f32 + jy);
                    }
                    cam.rays_at(&pts[..m], &mut rays[..m]);
                    if cam.has_lens() {
                        for (ray, &(x, y)) in rays[..m].iter_mut().zip(&coords[c..c + m]) {
                            *ray = cam.through_lens(ray, cs.lens(x, y, k));
                        }
                    }
                    let mut hits = [None; 64];
                    let first = packet_first_hits(w, &rays[..m], None, packets, &mut hits[..m]);
                    for j in 0..m {
                        let (x, y) = coords[c + j];
                        if let Some((sh, direct)) = camera_path(w, &rays[j], s, (x, y), k, first.then_some(hits[j]), &mut layers[c + j]) {
                            shades[c + j] = Some(sh);
                            ind[c + j] = direct;
                        }
                    }
                }
                // Indirect light: per set, per VPL, one packet of the set's pixels.
                for si in 0..s.sets() {
                    let mut m = 0;
                    for (j, sh) in shades[..n].iter().enumerate() {
                        if sh.is_some() && set_ids[j] == si {
                            who[m] = j;
                            m += 1;
                        }
                    }
                    if m == 0 {
                        continue;
                    }
                    let vpls = set.set(si);
                    for c in (0..m).step_by(64) {
                        let cm = (m - c).min(64);
                        // Every VPL's term at each of the chunk's pixels first: the shadow
                        // roulette weighs each against their mean.
                        let points: Vec<&Shade> = who[c..c + cm].iter().filter_map(|&j| shades[j].as_ref()).collect();
                        chunk_terms(vpls, &points, d_min2, &mut term_lanes);
                        let (mut sums, mut counts) = ([0f32; CHUNK], [0u32; CHUNK]);
                        for t in &term_lanes[..vpls.len()] {
                            for jj in 0..cm {
                                if t.ok[jj] {
                                    sums[jj] += t.lum[jj];
                                    counts[jj] += 1;
                                }
                            }
                        }
                        let (mut bar, mut seeds) = ([0f32; CHUNK], [0u32; CHUNK]);
                        for (jj, &j) in who[c..c + cm].iter().enumerate() {
                            bar[jj] = bar_of(sums[jj], counts[jj]);
                            seeds[jj] = s.sampler().pixel(coords[j].0, coords[j].1).hashed_seed(k);
                        }
                        for (vi, (t, v)) in term_lanes.iter_mut().zip(vpls).enumerate() {
                            t.roulette(&bar, &seeds, vi, cm);
                            let mut q = 0;
                            for (jj, &j) in who[c..c + cm].iter().enumerate() {
                                if let Some((c, ray)) = t.term(v, jj) {
                                    rays[q] = ray;
                                    terms[q] = (j, c);
                                    q += 1;
                                }
                            }
                            if q == 0 {
                                continue;
                            }
                            let mut blocked = [false; 64];
                            // PERF: a VPL's rays from one tile are traced one by one unless
                            // they nearly fill a packet: measured on one VPL frame's own
                            // rays (`bench vpl`, 512 × 384, one thread), packets of ~14
                            // rays ran at 3.6 M rays/s on Conference and the kitchen, single
                            // rays at 6.1 and 5.4; 64-ray packets (32 × 32 tiles) took the
                            // same CPU time as 16-ray ones.
                            if packets && q >= SHADOW_PACKET_MIN {
                                w.occluded_packet(&rays[..q], &mut blocked[..q]);
                            } else {
                                for (b, ray) in blocked[..q].iter_mut().zip(&rays[..q]) {
                                    *b = w.occluded_solid(ray);
                                }
                            }
                            for (&(j, t), &b) in terms[..q].iter().zip(&blocked[..q]) {
                                if !b {
                                    ind[j] += t;
                                }
                            }
                        }
                    }
                }
                for j in 0..n {
                    let (x, y) = coords[j];
                    let mut l = layers[j];
                    l.lit = demodulate(ind[j], l.albedo);
                    rows[((y - y0) * width + (x - r.x0)) as usize] = l;
                }
                x0 = x1;
            }
            rays_traced_here() - before
        })
        .sum()
}

/// With the discontinuity buffer, outliers of the reflected light (a VPL too near a glossy
/// surface, a rare specular path of the direct light) first give their excess to their
/// surface, as the denoiser's do ([`crate::DenoiseSettings::outlier_sigmas`]): a pixel
/// brighter than its 5 × 5 neighbours' mean by this many standard deviations. (Kitchen
/// relMSE at 512 × 384, radius 6: 3: 0.0541, 2: 0.0530, 1: 0.0511, 0.5: 0.0504, where it
/// smooths more than it rejects; without: 0.0606.)
pub const OUTLIER_SIGMAS: f32 = 2.0;
/// How far outliers' excess light goes, in pixels (12: kitchen 0.0546).
pub const OUTLIER_RADIUS: u32 = 6;

/// The discontinuity buffer at pixel (x, y) of `layers` (region `r`, row-major): the
/// demodulated reflected light averaged over the `m` × `m` neighbourhood (for even `m`,
/// the (m + 1)-wide window with half weights on its outer rows and columns, so that each
/// set counts once), over the neighbours whose surface lies within 5% of the pixel's
/// distance, whose normal is within 25° of its normal, and which are dark (see
/// [`crate::aov::FILTER_ALBEDO_MIN`]: their light is kept in radiance) when it is. Pixels that see no
/// surface keep their own value.
#[must_use]
pub fn discontinuity(layers: &[Layers], r: Region, m: u32, x: u32, y: u32) -> Vec3 {
    let width = r.x1 - r.x0;
    discontinuity_with(|x, y| Near::of(&layers[((y - r.y0) * width + (x - r.x0)) as usize]), r, m, x, y)
}

/// What the discontinuity buffer reads of a pixel's layers.
#[derive(Clone, Copy, Debug)]
struct Near {
    lit: Vec3,
    normal: Vec3,
    depth: f32,
    dark: bool,
}

impl Near {
    #[inline]
    fn of(l: &Layers) -> Self {
        Self { lit: l.lit, normal: l.normal, depth: l.depth, dark: dark(l.albedo) }
    }
}

/// [`discontinuity`] over pixels `at(x, y)` of region `r`.
#[inline]
fn discontinuity_with(at: impl Fn(u32, u32) -> Near, r: Region, m: u32, x: u32, y: u32) -> Vec3 {
    let c = at(x, y);
    if m <= 1 || !c.depth.is_finite() || c.normal == Vec3::ZERO {
        return c.lit;
    }
    let h = (m / 2) as i64;
    let even = m.is_multiple_of(2);
    let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
    for dy in -h..=h {
        let yy = i64::from(y) + dy;
        if yy < i64::from(r.y0) || yy >= i64::from(r.y1) {
            continue;
        }
        let wy = if even && dy.abs() == h { 0.5 } else { 1.0 };
        for dx in -h..=h {
            let xx = i64::from(x) + dx;
            if xx < i64::from(r.x0) || xx >= i64::from(r.x1) {
                continue;
            }
            let wx = if even && dx.abs() == h { 0.5 } else { 1.0 };
            let q = at(xx as u32, yy as u32);
            if !q.depth.is_finite() || (q.depth - c.depth).abs() > 0.05 * c.depth || q.normal.dot(c.normal) < 0.906 || q.dark != c.dark {
                continue;
            }
            sum += q.lit * (wx * wy);
            wsum += wx * wy;
        }
    }
    if wsum > 0.0 {
        sum / wsum
    } else {
        c.lit
    }
}

/// Renders a region (rectangle × samples) with virtual point lights into `sink`: per
/// sample, the frame's VPLs, the layers of the region and a margin of `interleave / 2`
/// pixels around it (which the discontinuity buffer reads; the layers are a pure function
/// of pixel and sample, so regions merged give the whole image's pixels), then per pixel
/// `emitted + albedo × lit`, the reflected light filtered when
/// [`VplSettings::discontinuity`] is on; each pixel's sum over the samples goes to the
/// sink. `progress(tiles)` as the tile loop calls it (during the last sample). Returns the
/// rays traced.
pub fn render(
    w: &World,
    cam: &Camera,
    job: &Job,
    s: &VplSettings,
    region: Region,
    sink: &impl Sink,
    progress: &(dyn Fn(u64) + Sync),
) -> u64 {
    let r = region.clip(job.width, job.height);
    if r.is_empty() {
        return 0;
    }
    let m = s.interleave.clamp(1, 64);
    // (Outliers spread first: a pixel's value depends on outliers up to OUTLIER_RADIUS
    // away, and theirs on pixels up to OUTLIER_RADIUS + 2 away.)
    let spread = s.discontinuity && m > 1;
    let margin = if spread { m / 2 + 2 * OUTLIER_RADIUS + 2 } else { 0 };
    let ext = Region {
        x0: r.x0.saturating_sub(margin),
        y0: r.y0.saturating_sub(margin),
        x1: (r.x1 + margin).min(job.width),
        y1: (r.y1 + margin).min(job.height),
        ..r
    };
    let mut layers = vec![Layers::default(); ext.pixels()];
    let mut sums = vec![Vec3::ZERO; r.pixels()];
    let rw = r.x1 - r.x0;
    let mut rays = 0;
    for k in r.s0..r.s1 {
        // (The light paths are traced on this thread: its count tells their rays.)
        let before = rays_traced_here();
        let set = VplSet::generate(w, s, k);
        rays += rays_traced_here() - before;
        rays += trace_layers(w, cam, job, &set, ext, &mut layers);
        let ew = ext.x1 - ext.x0;
        if spread {
            spread_outliers_of_layers(&mut layers, ew as usize, (ext.y1 - ext.y0) as usize, OUTLIER_SIGMAS, OUTLIER_RADIUS);
        }
        // (Rows on all cores: the discontinuity buffer was a serial fifth of a frame.
        // What it reads of each pixel made first, once: 32 bytes of the layers' 52.)
        let layers = &layers;
        let near: Vec<Near> = if margin > 0 { layers.par_iter().map(Near::of).collect() } else { Vec::new() };
        sums.par_chunks_mut(rw as usize).enumerate().for_each(|(row, sums)| {
            let y = r.y0 + row as u32;
            for (x, sum) in (r.x0..r.x1).zip(sums) {
                let l = &layers[((y - ext.y0) * ew + (x - ext.x0)) as usize];
                let at = |x: u32, y: u32| near[((y - ext.y0) * ew + (x - ext.x0)) as usize];
                let lit = if margin > 0 { discontinuity_with(at, ext, m, x, y) } else { l.lit };
                let v = l.emitted + demodulating(l.albedo) * lit;
                *sum += if v.is_finite() { v } else { Vec3::ZERO };
            }
        });
        if k + 1 == r.s1 {
            progress(u64::from(r.x1.div_ceil(TILE) - r.x0 / TILE) * u64::from(r.y1.div_ceil(TILE) - r.y0 / TILE));
        }
    }
    for y in r.y0..r.y1 {
        for x in r.x0..r.x1 {
            sink.put(x, y, sums[((y - r.y0) * rw + (x - r.x0)) as usize]);
        }
    }
    rays
}

/// The rays of one VPL frame, grouped as the renderer traces them (for measuring their
/// speed apart from shading): the camera rays, one packet per 8 × 8 block, and the shadow
/// rays toward the VPLs, one packet per 16 × 16 tile, set and VPL (rays of zero
/// contribution, and those the shadow roulette drops, left out, as the renderer does).
#[must_use]
pub fn frame_rays(w: &World, cam: &Camera, job: &Job, set: &VplSet) -> (Vec<Vec<Ray>>, Vec<Vec<Ray>>) {
    let (s, k) = (&set.settings, set.frame);
    let d_min2 = d_min2(w, s);
    let filter = if job.filter.signed() { lucent_scene::PixelFilter::Box } else { job.filter };
    let cs = CameraSamples { filter, ..s.camera_samples(job.spp.max(1)) };
    let (mut primary, mut shadow) = (Vec::new(), Vec::new());
    for ty in (0..job.height).step_by(VPL_TILE as usize) {
        for tx in (0..job.width).step_by(VPL_TILE as usize) {
            let mut shades = Vec::new();
            for by in (ty..(ty + VPL_TILE).min(job.height)).step_by(8) {
                for bx in (tx..(tx + VPL_TILE).min(job.width)).step_by(8) {
                    let mut rays = Vec::new();
                    for y in by..(by + 8).min(job.height) {
                        for x in bx..(bx + 8).min(job.width) {
                            let (jx, jy) = cs.pixel(x, y, k);
                            let ray = cam.ray(x as f32 + jx, y as f32 + jy);
                            let mut l = Layers::default();
                            if let Some((sh, _)) = camera_path(w, &ray, s, (x, y), k, None, &mut l) {
                                shades.push((s.set_of(x, y), sh, (x, y)));
                            }
                            rays.push(ray);
                        }
                    }
                    primary.push(rays);
                }
            }
            for si in 0..s.sets() {
                let vpls = set.set(si);
                // Each pixel's shadow rays that the roulette keeps, VPL by VPL.
                let kept: Vec<Vec<Option<Ray>>> = shades
                    .iter()
                    .filter(|(k, ..)| *k == si)
                    .map(|(_, sh, (x, y))| {
                        let terms: Vec<_> = vpls.iter().map(|v| vpl_term(v, sh, d_min2)).collect();
                        let bar = roulette_bar(terms.iter().flatten().map(|(c, _)| *c));
                        let px = s.sampler().pixel(*x, *y);
                        let keep =
                            |(i, t): (usize, Option<(Vec3, Ray)>)| t.and_then(|(c, r)| shadow_roulette(c, bar, &px, k, i).map(|_| r));
                        terms.into_iter().enumerate().map(keep).collect()
                    })
                    .collect();
                for vi in 0..vpls.len() {
                    let rays: Vec<Ray> = kept.iter().filter_map(|p| p[vi]).collect();
                    if !rays.is_empty() {
                        shadow.push(rays);
                    }
                }
            }
        }
    }
    (primary, shadow)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shadow roulette keeps a term's mean: a faint term is traced about as often as
    /// its share over the bar says, and weighed back up; a bright one always, as it is.
    #[test]
    fn shadow_roulette_keeps_the_mean() {
        let sampler = Sampler::new(7);
        let c = Vec3::new(0.02, 0.01, 0.005);
        let bar = luminance(c) / 0.2; // traced with probability 0.2
        let (mut kept, mut total) = (0u32, Vec3::ZERO);
        let n = 20_000u32;
        for i in 0..n {
            if let Some(v) = shadow_roulette(c, bar, &sampler.pixel(i % 200, i / 200), 3, 5) {
                kept += 1;
                total += v;
            }
        }
        let rate = f64::from(kept) / f64::from(n);
        assert!((rate - 0.2).abs() < 0.015, "traced {rate}");
        let mean = total / n as f32;
        assert!(((mean - c).abs() / c).max_element() < 0.08, "{mean} against {c}");
        let px = sampler.pixel(1, 2);
        assert_eq!(shadow_roulette(c, luminance(c) * 0.9, &px, 0, 0), Some(c));
        // The bar: half the mean of the terms that carry light.
        let bar = roulette_bar([Vec3::ONE, Vec3::splat(3.0)].into_iter());
        assert!((bar - 0.5 * 2.0 * luminance(Vec3::ONE)).abs() < 1e-6, "{bar}");
        assert_eq!(roulette_bar(std::iter::empty()), 0.0);
        assert_eq!(shadow_roulette(c, 0.0, &px, 0, 0), Some(c));
    }
}
