//! The tile loop: an image region's pixels in 16 × 16 tiles on all cores (rayon), each in
//! 8 × 8 blocks whose camera rays a [`BlockShader`] shades, sample after sample, into a
//! [`Sink`] (a whole image's means, or a region's sums). Pixels that the frame's
//! [`Coverage`] proves to miss everything get the background without a ray. Samples are a
//! pure function of (pixel, sample), so images do not depend on threads or tile order.

use crate::camera::Camera;
use crate::coverage::{Coverage, CoverageBands};
use crate::film::Region;
use crate::sampler::CameraSamples;
use crate::world::record::rays_traced_here;
use crate::world::World;
use glam::Vec3;
use lucent_accel::Ray;
use rayon::prelude::*;

/// Tile edge in pixels.
pub const TILE: u32 = 16;

/// The image a piece of work belongs to: its size, its samples per pixel, and how rays are
/// traced. Every integrator renders a [`Region`] of one into a [`Sink`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Job {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel of the image.
    pub spp: u32,
    /// How rays are traced.
    pub traversal: Traversal,
    /// The film's reconstruction filter (where in and around its pixel a sample lies).
    pub filter: lucent_scene::PixelFilter,
    /// The pixels samples lie in (x0, y0, x1, y1; the film's crop window, else the whole
    /// image): a wide filter's samples are taken only there.
    pub window: [u32; 4],
}

/// What shades a block of camera rays: the integrators that work pixel by pixel (all but
/// VPLs, which render whole frames).
pub trait BlockShader: Sync {
    /// Where the camera samples of an image of `spp` samples per pixel lie.
    fn camera_samples(&self, spp: u32) -> CameraSamples;
    /// Whether a camera ray that meets nothing shows the scene's background colour (so
    /// the loop may skip tracing it).
    fn misses_show_background(&self, w: &World) -> bool;
    /// Radiance along each of a block's camera rays, into `out`.
    fn li_block(&self, w: &World, block: &Block, rays: &[Ray], traversal: Traversal, out: &mut [Vec3]);
    /// Each pixel's sum over samples `samples` (in order of the sample index) into `sums`,
    /// for the block's pixels (`block.sample` unused). By default sample after sample
    /// through [`BlockShader::li_block`] ([`shade_samples`]); an integrator may take the
    /// samples in any order of its own, as long as each sample's value is what it would be
    /// alone and the sums add them in order.
    fn shade_samples(&self, s: &SampleBlock, block: &Block, sums: &mut [Vec3]) {
        shade_samples(self, s, block, sums);
    }
    /// Each sample's value, `out[j · n + kk]` for the block's pixel `j` and sample
    /// `samples.start + kk` (`n` samples): what the splatting loop spreads over the
    /// pixels around. By default sample after sample through [`BlockShader::li_block`]
    /// ([`shade_each`]); each value must be what [`BlockShader::shade_samples`] adds.
    fn shade_each(&self, s: &SampleBlock, block: &Block, out: &mut [Vec3]) {
        shade_each(self, s, block, out);
    }
}

/// What a block's samples need besides its pixels: the world, the camera, where samples
/// lie, which samples, and how rays are traced.
#[derive(Clone)]
pub struct SampleBlock<'a> {
    /// The world.
    pub world: &'a World,
    /// The camera.
    pub camera: &'a Camera,
    /// Where the samples lie in their pixels and on the lens.
    pub samples: CameraSamples,
    /// The sample indices.
    pub range: std::ops::Range<u32>,
    /// How rays are traced.
    pub traversal: Traversal,
}

impl SampleBlock<'_> {
    /// The camera ray of sample `k` of pixel (x, y).
    #[inline]
    #[must_use]
    pub fn camera_ray(&self, x: u32, y: u32, k: u32) -> Ray {
        let (jx, jy) = self.samples.pixel(x, y, k);
        let r = self.camera.ray(x as f32 + jx, y as f32 + jy);
        if self.camera.has_lens() {
            self.camera.through_lens(&r, self.samples.lens(x, y, k))
        } else {
            r
        }
    }
}

/// The camera rays of sample `k` of the block's pixels, made together (into `rays`, one
/// per pixel).
fn block_rays(s: &SampleBlock, block: &Block, k: u32, rays: &mut [Ray]) {
    let (cam, cs) = (s.camera, s.samples);
    let mut pts = [(0f32, 0f32); BLOCK];
    for (p, &(x, y)) in pts.iter_mut().zip(block.pixels) {
        let (jx, jy) = cs.pixel(x, y, k);
        *p = (x as f32 + jx, y as f32 + jy);
    }
    cam.rays_at(&pts[..rays.len()], rays);
    if cam.has_lens() {
        for (r, &(x, y)) in rays.iter_mut().zip(block.pixels) {
            *r = cam.through_lens(r, cs.lens(x, y, k));
        }
    }
}

/// [`BlockShader::shade_samples`] sample after sample: the block's camera rays of each
/// sample made together, shaded by [`BlockShader::li_block`], added to the sums.
pub fn shade_samples(shader: &(impl BlockShader + ?Sized), s: &SampleBlock, block: &Block, sums: &mut [Vec3]) {
    let n = block.pixels.len();
    let mut rays = NO_RAYS;
    let mut c = [Vec3::ZERO; BLOCK];
    let w = s.world;
    for k in s.range.clone() {
        block_rays(s, block, k, &mut rays[..n]);
        let one = Block { sample: k, ..*block };
        if s.range.len() == 1 {
            // One sample: straight into the sums.
            shader.li_block(w, &one, &rays[..n], s.traversal, &mut sums[..n]);
        } else {
            if k == s.range.start {
                sums[..n].fill(Vec3::ZERO);
            }
            shader.li_block(w, &one, &rays[..n], s.traversal, &mut c[..n]);
            for (o, v) in sums[..n].iter_mut().zip(&c) {
                *o += *v;
            }
        }
    }
}

/// [`BlockShader::shade_each`] sample after sample: the block's camera rays of each sample
/// made together, shaded by [`BlockShader::li_block`], each value kept.
pub fn shade_each(shader: &(impl BlockShader + ?Sized), s: &SampleBlock, block: &Block, out: &mut [Vec3]) {
    let n = block.pixels.len();
    let m = s.range.len();
    let mut rays = NO_RAYS;
    let mut c = [Vec3::ZERO; BLOCK];
    for (kk, k) in s.range.clone().enumerate() {
        block_rays(s, block, k, &mut rays[..n]);
        let one = Block { sample: k, ..*block };
        shader.li_block(s.world, &one, &rays[..n], s.traversal, &mut c[..n]);
        for (j, v) in c[..n].iter().enumerate() {
            out[j * m + kk] = *v;
        }
    }
}

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

/// A packet's ray buffer before its rays are made (PERF: a constant copied in; filling it
/// ray by ray showed in profiles of sparse REND3R frames).
pub(crate) const NO_RAYS: [Ray; lucent_accel::MAX_PACKET] =
    [Ray { org: Vec3::ZERO, dir: Vec3::X, tmin: 0.0, tmax: f32::INFINITY }; lucent_accel::MAX_PACKET];

/// What tracing `n` samples that miss sums to: the background, once per sample (a pixel
/// whose rays provably miss gets it without tracing).
pub(crate) fn background_sum(bg: Vec3, n: u32) -> Vec3 {
    if n == 1 {
        bg
    } else {
        (0..n).fold(Vec3::ZERO, |a, _| a + bg)
    }
}

/// Where in its pixel a ray of the frame starts: decides which pixels the coverage must
/// count.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Samples {
    /// The centre only (one sample per pixel).
    Centres,
    /// Anywhere in the pixel's square (jittered samples).
    Anywhere,
}

/// Pixels per block handed to the integrators: 8×8 (one bit each in a coverage mask), one
/// ray packet.
const BLOCK: usize = 64;
const _: () = assert!(BLOCK == lucent_accel::MAX_PACKET, "a block is one packet, and NO_RAYS holds a packet");

/// Where the tiles put their pixels: per pixel, the sum of `n` samples.
pub trait Sink: Sync {
    /// Pixel (x, y) is the sum `sum` of the region's samples (the value itself when there
    /// is one).
    fn put(&self, x: u32, y: u32, sum: Vec3);
    /// Pixel (x, y) is the sum `sum` of its samples' weighted values, of total weight
    /// `weight` (the splatting loop's: the reconstruction filter's weights).
    fn put_weighted(&self, x: u32, y: u32, sum: Vec3, weight: f32);
    /// Pixels `x0..x1` of row `y` show the background.
    fn background(&self, y: u32, x0: u32, x1: u32);
}

/// [`crate::render()`]'s sink: the mean of each pixel's samples, straight into a
/// whole-image film.
pub(crate) struct MeanSink {
    pub(crate) out: FilmPtr,
    pub(crate) width: u32,
    /// A block's row of background. PERF: made once (made per row on the stack, its
    /// 4-byte stores then read as 16-byte loads stalled store forwarding: 60% of a
    /// one-sphere REND3R frame).
    pub(crate) bg: [Vec3; 8],
    /// Samples per pixel.
    pub(crate) n: u32,
}

/// [`crate::render_region`]'s sink: sums and weights into a [`crate::RegionFilm`].
pub(crate) struct SumSink {
    pub(crate) sum: FilmPtr,
    pub(crate) weight: WeightPtr,
    pub(crate) region: Region,
    pub(crate) bg_sum: Vec3,
    pub(crate) n: u32,
}

impl Sink for MeanSink {
    #[inline(always)]
    fn put(&self, x: u32, y: u32, sum: Vec3) {
        let mean = if self.n == 1 { sum } else { sum / self.n as f32 };
        // SAFETY: (x, y) lies inside the image (the film's allocation is `width × height`
        // long), and only the tile that holds (x, y) writes it; the buffer outlives the
        // parallel loop.
        unsafe { self.out.get().add((y * self.width + x) as usize).write(mean) };
    }
    fn put_weighted(&self, x: u32, y: u32, sum: Vec3, weight: f32) {
        let mean = if weight != 0.0 { sum / weight } else { Vec3::ZERO };
        // SAFETY: as in `put`.
        unsafe { self.out.get().add((y * self.width + x) as usize).write(mean) };
    }
    #[inline(always)]
    fn background(&self, y: u32, x0: u32, x1: u32) {
        // PERF: the background a row at a time (pixel by pixel, the background of sparse
        // REND3R frames was a tenth of their time); traced pixels overwrite it.
        let dst = self.out.get().wrapping_add((y * self.width + x0) as usize);
        // SAFETY: the row's pixels x0..x1 (at most 8, one block's) lie inside the image and
        // the film's allocation, and no other tile writes them. PERF: a whole row of a
        // block as a copy of known size, which compiles to a few vector stores (not a call
        // to `memcpy`).
        unsafe {
            if x1 - x0 == 8 {
                dst.cast::<[Vec3; 8]>().write_unaligned(self.bg);
            } else {
                // PERF: pixel by pixel (at most 7): as a copy of variable length, both cases
                // became calls to `memcpy`, 40% of a one-sphere frame.
                for k in 0..(x1 - x0) as usize {
                    dst.add(k).write(self.bg[0]);
                }
            }
        }
    }
}

impl SumSink {
    #[inline(always)]
    fn index(&self, x: u32, y: u32) -> usize {
        let r = &self.region;
        ((y - r.y0) * (r.x1 - r.x0) + (x - r.x0)) as usize
    }
}

impl Sink for SumSink {
    #[inline(always)]
    fn put(&self, x: u32, y: u32, sum: Vec3) {
        let i = self.index(x, y);
        // SAFETY: (x, y) lies inside the region, whose film holds one sum and one weight per
        // pixel; only the tile that holds (x, y) writes them, and the buffers outlive the
        // parallel loop.
        unsafe {
            self.sum.0.add(i).write(sum);
            self.weight.0.add(i).write(self.n as f32);
        }
    }
    fn put_weighted(&self, x: u32, y: u32, sum: Vec3, weight: f32) {
        let i = self.index(x, y);
        // SAFETY: as in `put`.
        unsafe {
            self.sum.0.add(i).write(sum);
            self.weight.0.add(i).write(weight);
        }
    }
    #[inline(always)]
    fn background(&self, y: u32, x0: u32, x1: u32) {
        for x in x0..x1 {
            let i = self.index(x, y);
            // SAFETY: as in `put`.
            unsafe {
                self.sum.0.add(i).write(self.bg_sum);
                self.weight.0.add(i).write(self.n as f32);
            }
        }
    }
}

/// The 8×8 block mask (bit `8·row + column`) of columns `c0..c1` and rows `r0..r1`.
#[inline]
fn block_mask(c0: u32, c1: u32, r0: u32, r1: u32) -> u64 {
    let cols = ((0xffu64 >> (8 - (c1 - c0))) << c0) * 0x0101_0101_0101_0101;
    let rows = (u64::MAX >> (64 - 8 * (r1 - r0))) << (8 * r0);
    cols & rows
}

/// The tile loop of every [`BlockShader`]: the tiles that meet `region`
/// on rayon; the pixels of each 8×8 block (clipped to the region) that the frame's
/// [`Coverage`] says may meet something are traced together, sample after sample, by the
/// integrator, and the others show the background. A filter wider than the pixel's box
/// (with samples off the pixel centres) takes the splatting loop instead, `render_splat`.
/// Returns the rays traced.
pub fn render_blocks(
    w: &World,
    cam: &Camera,
    job: &Job,
    shader: &impl BlockShader,
    region: Region,
    progress: &(dyn Fn(u64) + Sync),
    sink: &impl Sink,
) -> u64 {
    let (width, height) = (job.width, job.height);
    let spp = job.spp.max(1);
    let cs = crate::sampler::CameraSamples { filter: job.filter, ..shader.camera_samples(spp) };
    if !cs.centred && cs.filter != lucent_scene::PixelFilter::Box {
        return render_splat(w, cam, job, shader, cs, region, progress, sink);
    }
    let samples = if cs.centred { Samples::Centres } else { Samples::Anywhere };
    let (s0, s1) = (region.s0, region.s1);
    // Which pixels can meet anything, by projecting the instances (object order): a sparse
    // scene, such as REND3R's 256 small spheres, traces a third of its pixels. `None`
    // (something covers the whole image, or reaches around the eye) traces them all.
    let prep = match samples {
        _ if cam.size() != (width, height) => None,
        // (Rays from a lens, and misses that are not the background colour, need tracing.)
        _ if cam.has_lens() || !shader.misses_show_background(w) => None,
        Samples::Centres => CoverageBands::new(w, cam, true),
        Samples::Anywhere => CoverageBands::new(w, cam, false),
    };
    // PERF: a band of tiles fills its coverage in the task that renders it, so a frame has
    // one parallel step (with the fill as a step of its own, and its hand-off to the
    // workers, REND3R's 16-sphere frame took 0.17 ms, now 0.13).
    const _: () = assert!(TILE == CoverageBands::BAND_ROWS, "a row of tiles is one band of the coverage");
    // PERF: every tile writes its pixels straight into the film (tiles are disjoint);
    // gathering per-tile buffers and copying them in afterwards, one thread, took half of a
    // one-sphere REND3R frame.
    let samples_of = SampleBlock { world: w, camera: cam, samples: cs, range: s0..s1, traversal: job.traversal };
    let tile = |tx: u32, ty: u32, cover: Option<&Coverage>| -> u64 {
        let (x0, y0) = ((tx * TILE).max(region.x0), (ty * TILE).max(region.y0));
        let (x1, y1) = ((tx * TILE + TILE).min(region.x1), (ty * TILE + TILE).min(region.y1));
        let before = rays_traced_here();
        // Blocks are aligned to the image's 8-pixel grid (the coverage's), clipped to the
        // tile's part of the region.
        for by in (y0 & !7..y1).step_by(8) {
            for bx in (x0 & !7..x1).step_by(8) {
                let (cx0, cy0) = (bx.max(x0), by.max(y0));
                let (cx1, cy1) = ((bx + 8).min(x1), (by + 8).min(y1));
                let mask = cover.map_or(u64::MAX, |c| c.block(bx / 8, by / 8));
                // The block's pixels inside the tile and the region.
                let inside = block_mask(cx0 - bx, cx1 - bx, cy0 - by, cy1 - by);
                let trace = mask & inside;
                if trace != inside {
                    for y in cy0..cy1 {
                        sink.background(y, cx0, cx1);
                    }
                }
                if trace == 0 {
                    continue;
                }
                // PERF: the block's buffers only for traced blocks (made per tile, they were 3 KB
                // to initialise per tile of a sparse REND3R frame).
                let mut coords = [(0u32, 0u32); BLOCK];
                let mut sum = [Vec3::ZERO; BLOCK];
                // (`trace` is not zero, so `n` is at least one below.)
                let mut n = 0;
                let mut b = trace;
                while b != 0 {
                    let i = b.trailing_zeros();
                    b &= b - 1;
                    coords[n] = (bx + i % 8, by + i / 8);
                    n += 1;
                }
                let among = cover.and_then(|c| c.candidates(bx / 8, by / 8));
                let block = Block { pixels: &coords[..n], sample: s0, among };
                shader.shade_samples(&samples_of, &block, &mut sum[..n]);
                for (&(x, y), v) in coords[..n].iter().zip(&sum) {
                    sink.put(x, y, *v);
                }
            }
        }
        progress(1);
        rays_traced_here() - before
    };
    if region.is_empty() {
        return 0;
    }
    let (tx0, tx1) = (region.x0 / TILE, region.x1.div_ceil(TILE));
    let (ty0, ty1) = (region.y0 / TILE, region.y1.div_ceil(TILE));
    (ty0..ty1)
        .into_par_iter()
        .map(|ty| {
            let cover = prep.as_ref().map(|p| p.band(ty as usize));
            (tx0..tx1).into_par_iter().map(|tx| tile(tx, ty, cover.as_ref())).sum::<u64>()
        })
        .sum()
}

/// Most bytes of sample values the splatting loop keeps for one pass (see
/// [`pass_samples`]).
const SPLAT_BUDGET: usize = 256 << 20;

/// Most samples per pass of the splatting loop.
const SPLAT_SAMPLES: u32 = 64;

/// Samples per pass of the splatting loop for an image of `width × height`: 64, or fewer
/// where a pass's values of every pixel would pass [`SPLAT_BUDGET`] (a function of the
/// image alone: the same passes, so the same order of sums, for any region, tiling or
/// thread count).
fn pass_samples(width: u32, height: u32) -> u32 {
    let per_sample = (width as usize * height as usize * std::mem::size_of::<Vec3>()).max(1);
    (SPLAT_BUDGET / per_sample).clamp(1, SPLAT_SAMPLES as usize) as u32
}

/// The loop for a reconstruction filter wider than the pixel's box: every sample lies in
/// its own pixel (uniformly, as Mitsuba's), and its value is spread over the pixels whose
/// filter reaches it, each pixel the filter-weighted mean of the samples around it
/// (Σ f·L / Σ f, Mitsuba's film; a pixel thus averages several pixels' samples, about π
/// times as many for the Gaussian of σ 0.5, where placing samples by the filter, which
/// [`crate::render_pixel`] does, keeps each pixel to its own).
///
/// Pass by pass ([`pass_samples`] samples a pixel), two phases: the 8 × 8 blocks of the
/// region's pixels and of the border of neighbours its filter reaches are shaded once each,
/// in parallel, their values kept; then bands of 8 rows, in parallel, each add to their own
/// pixels the values that reach them, in one global order: by pass, 8 × 8 block of the
/// image (row by row), pixel in the block (row by row), sample index. Each pixel's sums
/// thus add the same values in the same order whatever the regions or the thread count
/// (samples are a pure function of pixel and index). Samples lie inside the image only (as
/// Mitsuba's): pixels at its edge average fewer.
#[allow(clippy::too_many_arguments)]
fn render_splat(
    w: &World,
    cam: &Camera,
    job: &Job,
    shader: &impl BlockShader,
    cs: CameraSamples,
    region: Region,
    progress: &(dyn Fn(u64) + Sync),
    sink: &impl Sink,
) -> u64 {
    if region.is_empty() {
        return 0;
    }
    let filter = FilterTable::new(cs.filter);
    let r = cs.filter.radius();
    // A sample in pixel s lies in [s, s + 1): it reaches the centres of pixels closer than
    // r + 1/2.
    let reach = ((r + 0.5).ceil() as u32).saturating_sub(1);
    let own = CameraSamples { filter: lucent_scene::PixelFilter::Box, ..cs };
    let (x0, y0, x1, y1) = (region.x0, region.y0, region.x1, region.y1);
    // The pixels whose samples reach the region (inside the window), and their 8 × 8
    // blocks, row by row.
    let [wx0, wy0, wx1, wy1] = job.window;
    let (sx0, sy0) = (x0.saturating_sub(reach).max(wx0), y0.saturating_sub(reach).max(wy0));
    // (Empty where no sample reaches the region: its pixels then get no weight.)
    let (sx1, sy1) = ((x1 + reach).min(job.width).min(wx1), (y1 + reach).min(job.height).min(wy1));
    let blocks: Vec<(u32, u32)> = (sy0 & !7..sy1).step_by(8).flat_map(|by| (sx0 & !7..sx1).step_by(8).map(move |bx| (bx, by))).collect();
    let coords_of = |(bx, by): (u32, u32)| {
        let mut coords = [(0u32, 0u32); BLOCK];
        let mut n = 0;
        for y in by.max(sy0)..(by + 8).min(sy1) {
            for x in bx.max(sx0)..(bx + 8).min(sx1) {
                coords[n] = (x, y);
                n += 1;
            }
        }
        (coords, n)
    };
    let rw = (x1 - x0) as usize;
    let mut sum = vec![Vec3::ZERO; rw * (y1 - y0) as usize];
    let mut wsum = vec![0f32; sum.len()];
    let per_pass = pass_samples(job.width, job.height);
    let tiles = u64::from(x1.div_ceil(TILE) - x0 / TILE) * u64::from(y1.div_ceil(TILE) - y0 / TILE);
    let (mut reported, mut rays) = (0u64, 0u64);
    let mut k0 = region.s0;
    while k0 < region.s1 {
        // (Passes end at multiples of `per_pass`: the same passes for any region.)
        let k1 = ((k0 / per_pass + 1) * per_pass).min(region.s1);
        let m = (k1 - k0) as usize;
        let samples_of = SampleBlock { world: w, camera: cam, samples: own, range: k0..k1, traversal: job.traversal };
        // Phase 1: every block's values, once.
        let shaded: Vec<(Vec<Vec3>, u64)> = blocks
            .par_iter()
            .map(|&b| {
                let before = rays_traced_here();
                let (coords, n) = coords_of(b);
                let mut vals = vec![Vec3::ZERO; n * m];
                let block = Block { pixels: &coords[..n], sample: k0, among: None };
                shader.shade_each(&samples_of, &block, &mut vals);
                (vals, rays_traced_here() - before)
            })
            .collect();
        rays += shaded.iter().map(|v| v.1).sum::<u64>();
        // Phase 2: bands of 8 rows add what reaches their pixels, in the global order.
        sum.par_chunks_mut(8 * rw).zip(wsum.par_chunks_mut(8 * rw)).enumerate().for_each(|(band, (sum, wsum))| {
            let ya = y0 + 8 * band as u32;
            let yb = (ya + 8).min(y1);
            let (mut wx, mut wy) = (Vec::new(), Vec::new());
            for (&b, (vals, _)) in blocks.iter().zip(&shaded) {
                // (Blocks whose rows cannot reach the band.)
                if b.1 + 8 + reach <= ya || b.1 >= yb + reach {
                    continue;
                }
                let (coords, n) = coords_of(b);
                for (j, &(x, y)) in coords[..n].iter().enumerate() {
                    if y + reach < ya || y >= yb + reach {
                        continue;
                    }
                    for kk in 0..m {
                        let (u, v) = own.pixel(x, y, k0 + kk as u32);
                        let (px, py) = (x as f32 + u, y as f32 + v);
                        // The pixels of the band whose centres lie within r.
                        let (ax, ay) = (filter.weights(px, x0, x1, &mut wx), filter.weights(py, ya, yb, &mut wy));
                        let l = vals[j * m + kk];
                        for (iy, &fy) in wy.iter().enumerate() {
                            let row = (ay + iy as u32 - ya) as usize * rw + (ax - x0) as usize;
                            for (ix, &fx) in wx.iter().enumerate() {
                                let f = fx * fy;
                                sum[row + ix] += l * f;
                                wsum[row + ix] += f;
                            }
                        }
                    }
                }
            }
        });
        // (Progress counts TILE tiles, as the other loop's, in proportion to the passes.)
        let done = tiles * u64::from(k1 - region.s0) / u64::from(region.s1 - region.s0);
        progress(done - reported);
        reported = done;
        k0 = k1;
    }
    for y in y0..y1 {
        for x in x0..x1 {
            let i = (y - y0) as usize * rw + (x - x0) as usize;
            sink.put_weighted(x, y, sum[i], wsum[i]);
        }
    }
    rays
}

/// A reconstruction filter tabulated along one axis for splatting: |x| in [0, r] at
/// [`FilterTable::STEPS`] points a pixel, linearly interpolated.
struct FilterTable {
    radius: f32,
    values: Vec<f32>,
}

impl FilterTable {
    const STEPS: f32 = 256.0;

    fn new(f: lucent_scene::PixelFilter) -> Self {
        let radius = f.radius();
        let n = (radius * Self::STEPS).ceil() as usize + 2;
        Self { radius, values: (0..n).map(|i| f.eval(i as f32 / Self::STEPS)).collect() }
    }

    fn eval(&self, x: f32) -> f32 {
        let t = x.abs() * Self::STEPS;
        let i = t as usize;
        match (self.values.get(i), self.values.get(i + 1)) {
            (Some(&a), Some(&b)) if x.abs() < self.radius => a + (b - a) * (t - i as f32),
            _ => 0.0,
        }
    }

    /// The weights at position `p` (along one axis) of the pixels `lo..hi` whose centres
    /// lie within the radius, into `out`; returns the first such pixel.
    fn weights(&self, p: f32, lo: u32, hi: u32, out: &mut Vec<f32>) -> u32 {
        out.clear();
        // Centres c + 1/2 with |p − c − 1/2| < r.
        let first = ((p - 0.5 - self.radius).floor() as i64 + 1).max(i64::from(lo));
        let last = ((p - 0.5 + self.radius).ceil() as i64 - 1).min(i64::from(hi) - 1);
        for c in first..=last {
            out.push(self.eval(p - (c as f32 + 0.5)));
        }
        first.max(0) as u32
    }
}

/// A film's pixels or sums, shared by the tile tasks (each writes only its own tile).
#[derive(Clone, Copy)]
pub(crate) struct FilmPtr(pub(crate) *mut Vec3);
// SAFETY: the tasks write disjoint pixels (see `render_tiles`), so sharing the pointer
// between threads cannot race.
unsafe impl Send for FilmPtr {}
// SAFETY: as above.
unsafe impl Sync for FilmPtr {}
impl FilmPtr {
    fn get(self) -> *mut Vec3 {
        self.0
    }
}

/// A region film's weights, shared as [`FilmPtr`].
#[derive(Clone, Copy)]
pub(crate) struct WeightPtr(pub(crate) *mut f32);
// SAFETY: as for `FilmPtr`.
unsafe impl Send for WeightPtr {}
// SAFETY: as above.
unsafe impl Sync for WeightPtr {}
