//! The driver: what to render ([`RenderSettings`]) and the two ways to render it, a whole
//! image of pixel means ([`render()`]) or a region's sums for an accumulator to merge
//! ([`render_region`]). Both hand the work to the integrator ([`Integrator::render`]) with
//! a sink of their own; neither knows which integrator it is.

use crate::camera::Camera;
use crate::film::{Film, Region, RegionFilm};
use crate::integrator::Integrator;
use crate::tiles::{background_sum, FilmPtr, Job, MeanSink, SumSink, Traversal, WeightPtr};
use crate::world::World;
use glam::Vec3;

/// What to render and how: the image's size and samples per pixel, the integrator (what
/// the rays compute) and the traversal (how they are traced).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel of the image (1 = the pixel centre; more = jittered, see
    /// [`Integrator::camera_samples`]).
    pub spp: u32,
    /// What the rays compute.
    pub integrator: Integrator,
    /// How they are traced.
    pub traversal: Traversal,
    /// The film's reconstruction filter (box: each pixel the mean of samples in its square;
    /// the others spread each sample over the pixels around it, as Mitsuba's film does).
    pub filter: lucent_scene::PixelFilter,
    /// The film's crop window (x, y, width, height; Mitsuba's `crop_offset_*`,
    /// `crop_width`, `crop_height`), or none: the whole image. Samples lie only inside it,
    /// as Mitsuba's film takes them, so a filter wider than the pixel gives the window's
    /// edge pixels fewer samples, as at the image's edge (pixels outside it get none).
    pub window: Option<[u32; 4]>,
}

impl RenderSettings {
    /// A `width` × `height` image of one sample per pixel with the default integrator
    /// (Whitted) and traversal (packets).
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            spp: 1,
            integrator: Integrator::default(),
            traversal: Traversal::default(),
            filter: lucent_scene::PixelFilter::Box,
            window: None,
        }
    }

    /// The image the integrator renders regions of.
    #[must_use]
    pub fn job(&self) -> Job {
        let window = match self.window {
            Some([x, y, w, h]) => {
                let (x1, y1) = (x.saturating_add(w).min(self.width), y.saturating_add(h).min(self.height));
                [x.min(x1), y.min(y1), x1, y1]
            }
            None => [0, 0, self.width, self.height],
        };
        Job { width: self.width, height: self.height, spp: self.spp, traversal: self.traversal, filter: self.filter, window }
    }
}

/// Radiance of pixel (x, y) averaged over its samples, ray by ray ([`Integrator::li`]):
/// the reference the tile renderer must match.
#[must_use]
pub fn render_pixel(w: &World, cam: &Camera, s: &RenderSettings, x: u32, y: u32) -> Vec3 {
    let spp = s.spp.max(1);
    let cs = crate::sampler::CameraSamples { filter: s.filter, ..s.integrator.camera_samples(spp) };
    let mut c = Vec3::ZERO;
    for k in 0..spp {
        let (jx, jy) = cs.pixel(x, y, k);
        let r = cam.ray(x as f32 + jx, y as f32 + jy);
        let r = if cam.has_lens() { cam.through_lens(&r, cs.lens(x, y, k)) } else { r };
        c += s.integrator.li(w, &r, (x, y), k) * cs.weight(x, y, k);
    }
    c / spp as f32
}

/// Renders the image: every pixel, samples `0..spp`, each pixel the mean of its samples
/// (the [`RegionFilm`] of the whole image, resolved, with the division done as pixels
/// finish). `progress(tiles_done)` is called after each tile. Returns the film and the
/// number of rays traced.
pub fn render(w: &World, cam: &Camera, s: &RenderSettings, progress: &(dyn Fn(u64) + Sync)) -> (Film, u64) {
    let (width, height) = (s.width, s.height);
    let region = Region::full(width, height, 0, s.spp.max(1));
    // PERF: the film is not cleared first: the integrators write every pixel, traced or
    // not, in parallel (clearing 2.4 MB on one thread was a seventh of a sparse REND3R
    // frame).
    let n_pixels = width as usize * height as usize;
    let mut pixels: Vec<Vec3> = Vec::with_capacity(n_pixels);
    // Pixels whose rays provably miss get what tracing them would give, and what
    // `render_region`'s sums resolve to: n backgrounds summed, over n (bit for bit the
    // image of merged regions, on this machine or over MPI).
    let bg = background_sum(w.scene.background, region.s1);
    let bg = if region.s1 <= 1 { bg } else { bg / region.s1 as f32 };
    let sink = MeanSink { out: FilmPtr(pixels.as_mut_ptr()), width, bg: [bg; 8], n: region.s1 };
    let rays = s.integrator.render(w, cam, &s.job(), region, &sink, progress);
    // SAFETY: every integrator puts every pixel of the region it renders exactly once (the
    // tile loop: each pixel lies in one tile and one of its blocks; VPLs: each pixel after
    // its samples), and the region is the whole image. (Had a worker panicked, the length
    // would still be zero here.)
    unsafe { pixels.set_len(n_pixels) };
    (Film { width, height, pixels }, rays)
}

/// Renders one region of the image (a rectangle of pixels × a range of sample indices):
/// per pixel, the sum of its samples' radiance and their weight (1 each), for a
/// [`crate::FilmAccumulator`] to merge with other regions, from other threads, passes or
/// processes. The parts of `region` outside the `width` × `height` image are left out. The
/// samples are those [`render`] takes for an image of `spp` samples per pixel, so the
/// regions of an image, merged, give its pixels.
pub fn render_region(w: &World, cam: &Camera, s: &RenderSettings, region: Region, progress: &(dyn Fn(u64) + Sync)) -> (RegionFilm, u64) {
    let r = region.clip(s.width, s.height);
    let mut film = RegionFilm::new(r);
    if r.is_empty() {
        return (film, 0);
    }
    let n = r.s1 - r.s0;
    let bg_sum = background_sum(w.scene.background, n);
    let sink = SumSink { sum: FilmPtr(film.sum.as_mut_ptr()), weight: WeightPtr(film.weight.as_mut_ptr()), region: r, bg_sum, n };
    let rays = s.integrator.render(w, cam, &s.job(), r, &sink, progress);
    (film, rays)
}

/// [`render`]'s image (the same samples; their sums added half by half, so the last bits
/// may differ) and each pixel's variance of its mean's luminance,
/// from the two halves of its samples (samples `0..spp/2` and `spp/2..spp`, whose means
/// `a` and `b` give (ℓ(a) − ℓ(b))² / 4): what [`crate::denoise::denoise_with_variance`]
/// takes. With one sample per pixel there are no halves: `None`.
pub fn render_halves(w: &World, cam: &Camera, s: &RenderSettings, progress: &(dyn Fn(u64) + Sync)) -> (Film, Option<Vec<f32>>, u64) {
    match render_two_halves(w, cam, s, progress) {
        Ok(h) => {
            let variance = h.luminance_variance();
            (h.whole, Some(variance), h.rays)
        }
        Err((f, rays)) => (f, None, rays),
    }
}

/// The two halves of an image's samples, each its own image, and the whole: what the
/// regression denoiser ([`crate::denoise::regression`]) takes.
#[derive(Clone, Debug)]
pub struct Halves {
    /// The mean of samples `0..spp/2` of each pixel.
    pub a: Film,
    /// The mean of samples `spp/2..spp`.
    pub b: Film,
    /// [`render`]'s image: the mean of all of them (the halves' sums added).
    pub whole: Film,
    /// Rays traced.
    pub rays: u64,
}

impl Halves {
    /// Each pixel's variance of its mean's luminance, from the halves' means `a` and `b`:
    /// (ℓ(a) − ℓ(b))² / 4 (what [`crate::denoise::denoise_with_variance`] takes).
    #[must_use]
    pub fn luminance_variance(&self) -> Vec<f32> {
        self.a
            .pixels
            .iter()
            .zip(&self.b.pixels)
            .map(|(&a, &b)| {
                let d = crate::color::luminance(a) - crate::color::luminance(b);
                d * d / 4.0
            })
            .collect()
    }
}

/// [`Halves`] of `s.spp` samples per pixel; with fewer than two samples there are no
/// halves: the image alone (`Err`).
pub fn render_two_halves(w: &World, cam: &Camera, s: &RenderSettings, progress: &(dyn Fn(u64) + Sync)) -> Result<Halves, (Film, u64)> {
    let spp = s.spp.max(1);
    if spp < 2 {
        return Err(render(w, cam, s, progress));
    }
    let half = spp / 2;
    let (a, ra) = render_region(w, cam, s, Region::full(s.width, s.height, 0, half), progress);
    let (b, rb) = render_region(w, cam, s, Region::full(s.width, s.height, half, spp), progress);
    // Each pixel's weighted mean of its samples, or the background where none landed (as
    // `FilmAccumulator::resolve`, which would add the two halves' sums the same way).
    let bg = w.scene.background;
    let mean = |sum: Vec3, weight: f32| if weight > 0.0 { sum / weight } else { bg };
    let film = |f: &dyn Fn(usize) -> Vec3| Film { width: s.width, height: s.height, pixels: (0..a.sum.len()).map(f).collect() };
    Ok(Halves {
        a: film(&|i| mean(a.sum[i], a.weight[i])),
        b: film(&|i| mean(b.sum[i], b.weight[i])),
        whole: film(&|i| mean(a.sum[i] + b.sum[i], a.weight[i] + b.weight[i])),
        rays: ra + rb,
    })
}
