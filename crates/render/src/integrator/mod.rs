//! The integrators: what radiance a camera ray carries back. One closed enum,
//! [`Integrator`], behind one entry point ([`Integrator::li_block`], which the tile
//! renderer calls with a block of camera rays, and [`Integrator::li`], the single-ray
//! reference). How rays are traced (packets or one by one) is a [`Traversal`], apart from
//! what an integrator computes: the same settings give the same image either way.
//!
//! - [`whitted`]: Whitted ray tracing (point lights, hard shadows, mirror and glass);
//! - [`path`]: path tracing (next-event estimation and BSDF sampling, MIS, roulette);
//! - [`vpl`]: instant global illumination (virtual point lights, interleaved sampling,
//!   the discontinuity buffer): whole frames, through [`vpl::render_region`];
//! - the debug views, [`Integrator::EyeLight`] and [`Integrator::Normals`].

pub mod path;
pub mod vpl;
pub mod whitted;

pub use path::{LightSampling, PathSettings};
pub use vpl::VplSettings;
pub(crate) use whitted::NO_RAYS;
pub use whitted::{fresnel_dielectric, li_packet, refract, WhittedSettings};

use crate::render::jitter;
use crate::texture::sample;
use crate::world::World;
use glam::Vec3;
use lucent_accel::{Hit, Ray};
use lucent_scene::Material;

/// How rays are traced: choices that change the speed, never the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Traversal {
    /// Trace coherent rays (a block's camera rays, their shadow rays toward one light, a
    /// flat mirror's reflections) as packets of up to 8×8 (the default), rather than one
    /// by one.
    pub packets: bool,
}

impl Default for Traversal {
    fn default() -> Self {
        Self { packets: true }
    }
}

/// What a pixel shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// Whitted ray tracing: lights, shadows, reflection, refraction ([`whitted`]).
    Whitted(WhittedSettings),
    /// Path tracing: all light transport the materials describe, converging with samples
    /// ([`path`]).
    Path(PathSettings),
    /// Direct light plus indirect light from virtual point lights ([`vpl`]): the
    /// renderer traces whole frames ([`vpl::render_region`]); [`Integrator::li`] is the
    /// ray-by-ray reference (it makes the frame's VPLs on every call).
    Vpl(VplSettings),
    /// A light at the eye, no shadows, no secondary rays: the fastest preview.
    EyeLight,
    /// Shading normals as colours (0.5 + 0.5 n), for inspecting geometry.
    Normals,
}

impl Default for Integrator {
    fn default() -> Self {
        Self::Whitted(WhittedSettings::default())
    }
}

/// One block's camera rays as the tile renderer hands them to an integrator: the pixel and
/// the sample index of each ray (so an integrator's random numbers are a pure function of
/// pixel, sample and dimension), and the only instances the rays can meet, when known.
#[derive(Clone, Copy, Debug)]
pub struct Block<'a> {
    /// Pixel of each ray.
    pub pixels: &'a [(u32, u32)],
    /// Sample index (the same for every ray of the block).
    pub sample: u32,
    /// The instances the block's camera rays can meet, when the frame's coverage lists
    /// them (see [`crate::Coverage::candidates`]); `None`: any.
    pub among: Option<&'a [u32]>,
}

impl Integrator {
    /// Name (the heads-up line, `--integrator`).
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Whitted(_) => "whitted",
            Self::Path(_) => "path",
            Self::Vpl(_) => "vpl",
            Self::EyeLight => "eye light",
            Self::Normals => "normals",
        }
    }

    /// The low-discrepancy sampler the path tracer and the VPL integrator draw from
    /// (`None` for the others).
    #[inline]
    fn sampler(&self) -> Option<crate::sampler::Sampler> {
        match self {
            Self::Path(s) => Some(s.sampler()),
            Self::Vpl(s) => Some(s.sampler()),
            _ => None,
        }
    }

    /// Where in pixel (x, y) sample `k` of an image of `spp` samples per pixel lies, as an
    /// offset in [0, 1)²: the centre when [`Integrator::centred`]; else, for the path
    /// tracer and VPLs, the sampler's first pair of dimensions, and for the others a
    /// jittered position that is a pure function of (x, y, k) ([`jitter`]).
    #[inline]
    #[must_use]
    pub fn pixel_offset(&self, x: u32, y: u32, k: u32, spp: u32) -> (f32, f32) {
        match self.sampler() {
            _ if self.centred(spp) => (0.5, 0.5),
            Some(s) => s.get2(x, y, k, 0),
            None => jitter(x, y, k),
        }
    }

    /// Where on the lens sample `k` of pixel (x, y) passes, in [0, 1)² (cameras with a
    /// thin lens): for the path tracer and VPLs, a pair of the sampler's dimensions of its
    /// own; for the others, a hash.
    #[inline]
    #[must_use]
    pub fn lens_offset(&self, x: u32, y: u32, k: u32) -> (f32, f32) {
        match self.sampler() {
            Some(s) => s.get2(x, y, k, path::LENS_PAIR),
            None => jitter(x ^ 0x5bd1_e995, y, k),
        }
    }

    /// Whether a camera ray that meets nothing shows the scene's background colour (so
    /// the renderer may skip tracing it): not for the path tracer with an environment
    /// light or hidden emitters.
    #[must_use]
    pub fn misses_show_background(&self, w: &World) -> bool {
        match self {
            Self::Path(s) => w.scene.environment.is_none() && !s.hide_emitters,
            Self::Vpl(_) => w.scene.environment.is_none(),
            _ => true,
        }
    }

    /// Whether every sample of an image of `spp` samples lies at its pixel's centre.
    #[inline]
    #[must_use]
    pub fn centred(&self, spp: u32) -> bool {
        spp <= 1 && !matches!(self, Self::Path(_))
    }

    /// Radiance along one camera ray, the ray of sample `sample` of pixel `pixel` (which
    /// the path tracer's random numbers depend on): the reference every fast path must
    /// match.
    #[must_use]
    pub fn li(&self, w: &World, ray: &Ray, pixel: (u32, u32), sample: u32) -> Vec3 {
        match self {
            Self::Whitted(s) => whitted::li(w, ray, s, 0),
            Self::Path(s) => path::li(w, ray, s, pixel.0, pixel.1, sample, None),
            Self::Vpl(s) => vpl::li_layers(w, ray, &vpl::VplSet::generate(w, s, sample), pixel).radiance(),
            Self::EyeLight | Self::Normals => self.debug_view(w, ray),
        }
    }

    /// Radiance along each of a block's camera rays, into `out` (`rays.len()` of them, at
    /// most [`lucent_accel::MAX_PACKET`]).
    pub fn li_block(&self, w: &World, block: &Block, rays: &[Ray], traversal: Traversal, out: &mut [Vec3]) {
        match self {
            Self::Whitted(s) if traversal.packets => whitted::li_packet_among(w, rays, block.among, s, out),
            Self::Path(s) => {
                // The camera rays' closest hits as one packet; each path goes on alone.
                let mut hits = [None; lucent_accel::MAX_PACKET];
                let hits = &mut hits[..rays.len()];
                let known = packet_first_hits(w, rays, block.among, traversal.packets, hits);
                for (((o, r), &(x, y)), h) in out.iter_mut().zip(rays).zip(block.pixels).zip(hits.iter()) {
                    *o = path::li(w, r, s, x, y, block.sample, known.then_some(*h));
                }
            }
            _ => {
                for ((o, r), &px) in out.iter_mut().zip(rays).zip(block.pixels) {
                    *o = self.li(w, r, px, block.sample);
                }
            }
        }
    }

    /// The eye-light and normal views.
    fn debug_view(&self, w: &World, ray: &Ray) -> Vec3 {
        let Some(hit) = w.intersect(ray) else {
            return w.scene.background;
        };
        let surf = w.surface(ray, &hit);
        let d = ray.dir.normalize();
        let ns = if d.dot(surf.ng) < 0.0 { surf.ns } else { -surf.ns };
        if *self == Self::Normals {
            return ns * 0.5 + Vec3::splat(0.5);
        }
        let mat = material(w, surf.material);
        let kd = textured_kd(w, mat, surf.uv);
        let base = if kd.max_element() > 0.0 { kd } else { mat.specular.max(mat.reflect).max(mat.transmit) };
        base * (0.15 + 0.85 * (-d).dot(ns).max(0.0)) + mat.emission.min(Vec3::ONE)
    }
}

/// Whether a block's camera rays are narrow enough for a packet to pay: their unit
/// directions differ by at most [`PACKET_SPREAD`] in every component. Measured on the
/// bunny reference scene, path traced (median of two runs, 2 threads): at 64 × 64 pixels
/// (8-pixel blocks span 0.065) single rays took 0.90 s where packets took 1.13 s; at
/// 256 × 256 (0.016) packets took 0.67 s against 0.71, at 512 × 512 2.46 s against 2.62.
const PACKET_SPREAD: f32 = 0.03;

/// Traces a block's camera rays (at most [`lucent_accel::MAX_PACKET`]) as one packet, their
/// closest hits into `hits`, when `packets` is on, no surface has an alpha mask (a packet
/// stops at cut-out parts) and the rays are [`coherent`]; returns whether it did. The
/// camera paths then start from those hits ([`World::first_hit`]), else they trace alone.
pub(crate) fn packet_first_hits(w: &World, rays: &[Ray], among: Option<&[u32]>, packets: bool, hits: &mut [Option<Hit>]) -> bool {
    if !packets || w.has_alpha() || !coherent(rays) {
        return false;
    }
    match among {
        Some(ids) => w.intersect_packet_among(rays, ids, hits),
        None => w.intersect_packet(rays, hits),
    }
    true
}

pub(crate) fn coherent(rays: &[Ray]) -> bool {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for r in rays {
        let d = r.dir.normalize_or_zero();
        lo = lo.min(d);
        hi = hi.max(d);
    }
    (hi - lo).max_element() <= PACKET_SPREAD
}

/// The radiance `mat` emits at texture coordinates `uv` (its emission times its emission
/// texture, when it has one), on the side its normal points to.
pub(crate) fn emitted(w: &World, mat: &Material, uv: glam::Vec2) -> Vec3 {
    match mat.emission_tex.and_then(|t| w.scene.textures.get(t as usize)) {
        Some(t) => mat.emission * sample(t, uv).truncate(),
        None => mat.emission,
    }
}

/// Material `index` of the scene, or the default one for an index out of range (PERF:
/// borrowed, not cloned: a clone allocates the name on every hit).
pub(crate) fn material(w: &World, index: u32) -> &Material {
    w.scene.materials.get(index as usize).unwrap_or_else(|| default_material())
}

/// `Material::default()`, made once.
pub(crate) fn default_material() -> &'static Material {
    static DEFAULT: std::sync::OnceLock<Material> = std::sync::OnceLock::new();
    DEFAULT.get_or_init(Material::default)
}

/// The material's diffuse reflectance at `uv`, textured.
#[inline(always)]
pub(crate) fn textured_kd(w: &World, mat: &Material, uv: glam::Vec2) -> Vec3 {
    let mut kd = mat.diffuse;
    if let Some(t) = mat.diffuse_tex.and_then(|t| w.scene.textures.get(t as usize)) {
        kd *= sample(t, uv).truncate();
    }
    kd
}
