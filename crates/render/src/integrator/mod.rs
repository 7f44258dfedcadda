//! The integrators: what radiance a camera ray carries back. One closed enum,
//! [`Integrator`], behind one entry point, [`Integrator::render`]: every integrator renders
//! a [`Region`] (pixels × sample range) of a [`Job`]'s image into a [`Sink`]. Those that
//! shade pixel by pixel do it through the tile loop ([`render_blocks`], with
//! [`Integrator`] as its [`BlockShader`]); VPLs render whole frames. [`Integrator::li`] is
//! the single-ray reference. How rays are traced (packets or one by one) is a
//! [`crate::tiles::Traversal`], apart from what an integrator computes: the same settings
//! give the same image either way.
//!
//! - [`whitted`]: Whitted ray tracing (point lights, hard shadows, mirror and glass);
//! - [`path`]: path tracing (next-event estimation and BSDF sampling, MIS, roulette);
//! - [`vpl`]: instant global illumination (virtual point lights, interleaved sampling,
//!   the discontinuity buffer);
//! - the debug views, [`Integrator::EyeLight`] and [`Integrator::Normals`];
//! - [`guides`]: a denoiser's guides (albedo, normal, depth, emission per pixel);
//! - [`layers`]: the layers of Mitsuba's `aov` integrator and its alpha.
//!
//! Adding an integrator: a file here with its settings and its `li` (or its own frame
//! loop, as [`vpl`]), a variant of [`Integrator`], and an arm in [`Integrator::render`],
//! [`Integrator::li`] and, if it shades blocks, [`Integrator::li_block`].

pub mod guides;
pub(crate) mod hit;
pub mod layers;
pub mod path;
pub mod vpl;
pub mod wave;
pub mod wave_profile;
pub mod whitted;

pub use path::{LightSampling, PathSettings};
pub use vpl::VplSettings;
pub use whitted::{fresnel_dielectric, li_packet, refract, WhittedSettings};

use crate::camera::Camera;
use crate::film::Region;
use crate::sampler::CameraSamples;
use crate::tiles::{render_blocks, shade_samples, Block, BlockShader, Job, SampleBlock, Sink, Traversal};
use crate::world::World;
use glam::Vec3;
use hit::{material, packet_first_hits, textured_kd};
use lucent_accel::Ray;

/// What a pixel shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// Whitted ray tracing: lights, shadows, reflection, refraction ([`whitted`]).
    Whitted(WhittedSettings),
    /// Path tracing: all light transport the materials describe, converging with samples
    /// ([`path`]).
    Path(PathSettings),
    /// Direct light plus indirect light from virtual point lights ([`vpl`]): the
    /// renderer traces whole frames ([`vpl::render`]); [`Integrator::li`] is the
    /// ray-by-ray reference (it makes the frame's VPLs on every call).
    Vpl(VplSettings),
    /// A light at the eye, no shadows, no secondary rays: the fastest preview.
    EyeLight,
    /// Shading normals as colours (0.5 + 0.5 n), for inspecting geometry.
    Normals,
    /// A layer of Mitsuba's `aov` integrator (or its alpha): a value of the first surface
    /// each camera ray meets ([`layers`]), zero where it meets none.
    Aov(lucent_scene::AovKind),
}

impl Default for Integrator {
    fn default() -> Self {
        Self::Whitted(WhittedSettings::default())
    }
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
            Self::Aov(_) => "aov",
        }
    }

    /// Where the camera samples of an image of `spp` samples per pixel lie: the path
    /// tracer's and VPLs' sampler (its first pair in the pixel, [`crate::sampler::LENS_PAIR`]
    /// on the lens), hashes for the others; at the pixel's centre for one-sample images of
    /// all but the path tracer.
    #[inline]
    #[must_use]
    pub fn camera_samples(&self, spp: u32) -> CameraSamples {
        let sobol = match self {
            Self::Path(s) => Some(s.sampler()),
            Self::Vpl(s) => Some(s.sampler()),
            _ => None,
        };
        CameraSamples { sobol, centred: spp <= 1 && !matches!(self, Self::Path(_)), filter: lucent_scene::PixelFilter::Box }
    }

    /// Renders `region` of `job`'s image into `sink` (per pixel, the sum of the region's
    /// samples): the one way every integrator is reached. `progress(tiles)` is called as
    /// tiles finish. Returns the rays traced.
    pub fn render(&self, w: &World, cam: &Camera, job: &Job, region: Region, sink: &impl Sink, progress: &(dyn Fn(u64) + Sync)) -> u64 {
        match self {
            Self::Vpl(v) => vpl::render(w, cam, job, v, region, sink, progress),
            _ => render_blocks(w, cam, job, self, region, progress, sink),
        }
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
            Self::Aov(kind) => layers::value(w, ray, *kind),
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

impl BlockShader for Integrator {
    fn camera_samples(&self, spp: u32) -> CameraSamples {
        Integrator::camera_samples(self, spp)
    }

    /// Not for the path tracer with an environment light or hidden emitters, nor VPLs
    /// with an environment.
    fn misses_show_background(&self, w: &World) -> bool {
        match self {
            Self::Path(s) => w.scene.environment.is_none() && !s.hide_emitters,
            Self::Vpl(_) => w.scene.environment.is_none(),
            Self::Aov(_) => false,
            _ => true,
        }
    }

    fn li_block(&self, w: &World, block: &Block, rays: &[Ray], traversal: Traversal, out: &mut [Vec3]) {
        Integrator::li_block(self, w, block, rays, traversal, out);
    }

    fn shade_samples(&self, s: &SampleBlock, block: &Block, sums: &mut [Vec3]) {
        match self {
            Self::Path(p) if p.lanes => wave::shade_samples(p, s, block, sums),
            _ => shade_samples(self, s, block, sums),
        }
    }

    fn shade_each(&self, s: &SampleBlock, block: &Block, out: &mut [Vec3]) {
        match self {
            Self::Path(p) if p.lanes => wave::shade_each(p, s, block, out),
            _ => crate::tiles::shade_each(self, s, block, out),
        }
    }
}
