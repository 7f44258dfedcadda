//! The tile renderer: tiles on all cores (rayon), samples deterministic per (pixel, sample).

use crate::camera::Camera;
use crate::coverage::{Coverage, Prepared};
use crate::film::{Film, Region, RegionFilm};
use crate::integrator::{Block, Integrator, Traversal, NO_RAYS};
use crate::world::World;
use glam::Vec3;
use rayon::prelude::*;

/// What to render and how: the image's size and samples per pixel, the integrator (what
/// the rays compute) and the traversal (how they are traced).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel of the image (1 = the pixel centre; more = jittered, see
    /// [`Integrator::pixel_offset`]).
    pub spp: u32,
    /// What the rays compute.
    pub integrator: Integrator,
    /// How they are traced.
    pub traversal: Traversal,
}

impl RenderSettings {
    /// A `width` × `height` image of one sample per pixel with the default integrator
    /// (Whitted) and traversal (packets).
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height, spp: 1, integrator: Integrator::default(), traversal: Traversal::default() }
    }
}

/// Tile edge in pixels.
pub const TILE: u32 = 16;

/// A 32-bit hash (Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 2020: PCG).
#[must_use]
pub fn pcg_hash(x: u32) -> u32 {
    let s = x.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let w = ((s >> ((s >> 28) + 4)) ^ s).wrapping_mul(277_803_737);
    (w >> 22) ^ w
}

/// The jitter of sample `s` of pixel (x, y): a pure function, so images do not depend on
/// thread count or tile order.
#[must_use]
pub fn jitter(x: u32, y: u32, s: u32) -> (f32, f32) {
    let h = pcg_hash(x ^ pcg_hash(y ^ pcg_hash(s)));
    let h2 = pcg_hash(h);
    ((h >> 8) as f32 / (1u32 << 24) as f32, (h2 >> 8) as f32 / (1u32 << 24) as f32)
}

/// Radiance of pixel (x, y) averaged over its samples, ray by ray ([`Integrator::li`]):
/// the reference the tile renderer must match.
#[must_use]
pub fn render_pixel(w: &World, cam: &Camera, s: &RenderSettings, x: u32, y: u32) -> Vec3 {
    let spp = s.spp.max(1);
    let mut c = Vec3::ZERO;
    for k in 0..spp {
        let (jx, jy) = s.integrator.pixel_offset(x, y, k, spp);
        let r = cam.ray(x as f32 + jx, y as f32 + jy);
        let r = if cam.has_lens() { cam.through_lens(&r, s.integrator.lens_offset(x, y, k)) } else { r };
        c += s.integrator.li(w, &r, (x, y), k);
    }
    c / spp as f32
}

/// Weight of each quarter point's shading normal in a pixel's guide normal, the centre's
/// being 1 (so the centre counts half): the normal of a pixel that straddles an edge
/// leans as its samples do. At 4 samples denoised, relMSE Cornell / Sponza / kitchen
/// 0.0015 / 0.0081 / 0.0315 with the centre's normal alone; 0.0014 / 0.0073 / 0.0313 at
/// 0.25; 0.0014 / 0.0073 / 0.0314 at 0.5; 0.0014 / 0.0074 / 0.0314 at 1; the quarters
/// alone 0.0014 / 0.0074 / 0.0319.
const QUARTER_NORMAL: f32 = 0.25;

/// The guide layers of a denoiser for every pixel: the shading normal (the centre's and
/// the quarter points' blended, see [`QUARTER_NORMAL`]) and the distance of the first
/// surface the ray through its centre sees; the albedo, as the mean over four points
/// of the pixel's quarters (a pixel's colour mixes what its samples see, so a texture's
/// edges demodulate and remodulate with the pixel's mean albedo: on Sponza at 4 samples,
/// the denoised relMSE fell from 0.0114 to 0.0091 against the centre's albedo); and the
/// emission seen, as the mean over the centre and those four points, so that pixels an
/// emitter covers even in part are known (see [`crate::film::Aovs`]).
#[must_use]
///
/// Each 8 × 8 block's five sets of rays (centres, then each quarter point) are traced as
/// packets when they are coherent and no surface has an alpha mask (the same hits as
/// single rays, bit for bit); on Sponza at 512 × 384 on 2 threads, 224 ms one ray at a
/// time.
pub fn render_aovs(w: &World, cam: &Camera, width: u32, height: u32) -> crate::film::Aovs {
    use crate::integrator::path::{centre_guides, quarter_guides};
    type Guide = (Vec3, Vec3, f32, Vec3);
    let n = width as usize * height as usize;
    let mut flat: Vec<Guide> = vec![(Vec3::ZERO, Vec3::ZERO, 0.0, Vec3::ZERO); n];
    if n == 0 {
        let empty = || Film { width, height, pixels: Vec::new() };
        return crate::film::Aovs { albedo: empty(), normal: empty(), depth: Vec::new(), emission: empty() };
    }
    // Bands of 8 rows, blocks of 8 × 8 pixels.
    flat.par_chunks_mut(width as usize * 8).enumerate().for_each(|(band, rows)| {
        let y0 = band as u32 * 8;
        let y1 = (y0 + 8).min(height);
        for x0 in (0..width).step_by(8) {
            let x1 = (x0 + 8).min(width);
            let mut at = [(0u32, 0u32); 64];
            let mut m = 0;
            for y in y0..y1 {
                for x in x0..x1 {
                    at[m] = (x, y);
                    m += 1;
                }
            }
            for (k, (dx, dy)) in [(0.5, 0.5), (0.25, 0.25), (0.75, 0.25), (0.75, 0.75), (0.25, 0.75)].into_iter().enumerate() {
                let mut pts = [(0f32, 0f32); 64];
                for (p, &(x, y)) in pts.iter_mut().zip(&at[..m]) {
                    *p = (x as f32 + dx, y as f32 + dy);
                }
                let mut rays = NO_RAYS;
                cam.rays_at(&pts[..m], &mut rays[..m]);
                let mut hits = [None; 64];
                let packet = crate::integrator::packet_first_hits(w, &rays[..m], None, true, &mut hits[..m]);
                for j in 0..m {
                    let first = w.first_hit(&rays[j], packet.then_some(hits[j]));
                    let (x, y) = at[j];
                    let g = &mut rows[((y - y0) * width + x) as usize];
                    if k == 0 {
                        (g.1, g.2, g.3) = centre_guides(w, &rays[j], first);
                    } else {
                        let (a, e, n) = quarter_guides(w, first);
                        g.0 += a;
                        g.3 += e;
                        // (Where the centre sees a surface too.)
                        if let Some(n) = n.filter(|_| g.2.is_finite()) {
                            g.1 += n * QUARTER_NORMAL;
                        }
                    }
                }
            }
        }
    });
    for g in &mut flat {
        g.0 /= 4.0;
        g.3 /= 5.0;
        g.1 = g.1.normalize_or_zero();
    }
    crate::film::Aovs {
        albedo: Film { width, height, pixels: flat.iter().map(|a| a.0).collect() },
        normal: Film { width, height, pixels: flat.iter().map(|a| a.1).collect() },
        depth: flat.iter().map(|a| a.2).collect(),
        emission: Film { width, height, pixels: flat.iter().map(|a| a.3).collect() },
    }
}

/// Renders the image: every pixel, samples `0..spp`, each pixel the mean of its samples
/// (the [`RegionFilm`] of the whole image, resolved, with the division done by the tiles
/// as they go). `progress(tiles_done)` is called after each tile. Returns the film and
/// the number of rays traced.
pub fn render(w: &World, cam: &Camera, s: &RenderSettings, progress: &(dyn Fn(u64) + Sync)) -> (Film, u64) {
    let (width, height) = (s.width, s.height);
    let region = Region::full(width, height, 0, s.spp.max(1));
    if let Integrator::Vpl(v) = &s.integrator {
        let (part, rays) = crate::integrator::vpl::render_region(w, cam, s, v, region, progress);
        let mut acc = crate::film::FilmAccumulator::new(width, height);
        // (A region of the whole image merges into an empty accumulator.)
        let _ = acc.merge(part);
        return (acc.resolve(w.scene.background), rays);
    }
    // PERF: the film is not cleared first: the tiles write every pixel, traced or not, in
    // parallel (clearing 2.4 MB on one thread was a seventh of a sparse REND3R frame).
    let n_pixels = width as usize * height as usize;
    let mut pixels: Vec<Vec3> = Vec::with_capacity(n_pixels);
    // Pixels whose rays provably miss get what tracing them would give, and what
    // `render_region`'s sums resolve to: n backgrounds summed, over n (bit for bit the
    // image of merged regions, on this machine or over MPI).
    let bg = background_sum(w.scene.background, region.s1);
    let bg = if region.s1 <= 1 { bg } else { bg / region.s1 as f32 };
    let sink = MeanSink { out: FilmPtr(pixels.as_mut_ptr()), width, bg: [bg; 8], n: region.s1 };
    let rays = render_tiles(w, cam, s, region, progress, &sink);
    // SAFETY: every pixel lies in exactly one tile and one of its blocks, and each block
    // wrote each of its pixels (see `render_tiles`). (Had a tile panicked, the length would
    // still be zero here.)
    unsafe { pixels.set_len(n_pixels) };
    (Film { width, height, pixels }, rays)
}

/// What tracing `n` samples that miss sums to: the background, once per sample (a pixel
/// whose rays provably miss gets it without tracing).
fn background_sum(bg: Vec3, n: u32) -> Vec3 {
    if n == 1 {
        bg
    } else {
        (0..n).fold(Vec3::ZERO, |a, _| a + bg)
    }
}

/// Renders one region of the image (a rectangle of pixels × a range of sample indices):
/// per pixel, the sum of its samples' radiance and their weight (1 each), for a
/// [`crate::FilmAccumulator`] to merge with other regions, from other threads, passes or
/// processes. The parts of `region` outside the `width` × `height` image are left out. The
/// samples are those [`render`] takes for an image of `spp` samples per pixel, so the
/// regions of an image, merged, give its pixels.
pub fn render_region(w: &World, cam: &Camera, s: &RenderSettings, region: Region, progress: &(dyn Fn(u64) + Sync)) -> (RegionFilm, u64) {
    if let Integrator::Vpl(v) = &s.integrator {
        return crate::integrator::vpl::render_region(w, cam, s, v, region, progress);
    }
    let r = region.clip(s.width, s.height);
    let mut film = RegionFilm::new(r);
    if r.is_empty() {
        return (film, 0);
    }
    let n = r.s1 - r.s0;
    let bg_sum = background_sum(w.scene.background, n);
    let sink = SumSink { sum: FilmPtr(film.sum.as_mut_ptr()), weight: WeightPtr(film.weight.as_mut_ptr()), region: r, bg_sum, n };
    let rays = render_tiles(w, cam, s, r, progress, &sink);
    (film, rays)
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
trait Sink: Sync {
    /// Pixel (x, y) is the sum `sum` of the region's samples (the value itself when there
    /// is one).
    fn put(&self, x: u32, y: u32, sum: Vec3);
    /// Pixels `x0..x1` of row `y` show the background.
    fn background(&self, y: u32, x0: u32, x1: u32);
}

/// [`render`]'s sink: the mean of each pixel's samples, straight into a whole-image film.
struct MeanSink {
    out: FilmPtr,
    width: u32,
    /// A block's row of background. PERF: made once (made per row on the stack, its
    /// 4-byte stores then read as 16-byte loads stalled store forwarding: 60% of a
    /// one-sphere REND3R frame).
    bg: [Vec3; 8],
    /// Samples per pixel.
    n: u32,
}

/// [`render_region`]'s sink: sums and weights into a [`RegionFilm`].
struct SumSink {
    sum: FilmPtr,
    weight: WeightPtr,
    region: Region,
    bg_sum: Vec3,
    n: u32,
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

/// The tile loop shared by [`render`] and [`render_region`]: the tiles that meet `region`
/// on rayon; the pixels of each 8×8 block (clipped to the region) that the frame's
/// [`Coverage`] says may meet something are traced together, sample after sample, by the
/// integrator, and the others show the background. Returns the rays traced.
fn render_tiles(w: &World, cam: &Camera, s: &RenderSettings, region: Region, progress: &(dyn Fn(u64) + Sync), sink: &impl Sink) -> u64 {
    let (width, height) = (s.width, s.height);
    let spp = s.spp.max(1);
    let samples = if s.integrator.centred(spp) { Samples::Centres } else { Samples::Anywhere };
    let (s0, s1) = (region.s0, region.s1);
    let integrator = &s.integrator;
    // Which pixels can meet anything, by projecting the instances (object order): a sparse
    // scene, such as REND3R's 256 small spheres, traces a third of its pixels. `None`
    // (something covers the whole image, or reaches around the eye) traces them all.
    let prep = match samples {
        _ if cam.size() != (width, height) => None,
        // (Rays from a lens, and misses that are not the background colour, need tracing.)
        _ if cam.has_lens() || !integrator.misses_show_background(w) => None,
        Samples::Centres => Prepared::new(w, cam, true),
        Samples::Anywhere => Prepared::new(w, cam, false),
    };
    // PERF: a band of tiles fills its coverage in the task that renders it, so a frame has
    // one parallel step (with the fill as a step of its own, and its hand-off to the
    // workers, REND3R's 16-sphere frame took 0.17 ms, now 0.13).
    const _: () = assert!(TILE == Prepared::BAND_ROWS, "a row of tiles is one band of the coverage");
    // PERF: every tile writes its pixels straight into the film (tiles are disjoint);
    // gathering per-tile buffers and copying them in afterwards, one thread, took half of a
    // one-sphere REND3R frame.
    let tile = |tx: u32, ty: u32, cover: Option<&Coverage>| -> u64 {
        let (x0, y0) = ((tx * TILE).max(region.x0), (ty * TILE).max(region.y0));
        let (x1, y1) = ((tx * TILE + TILE).min(region.x1), (ty * TILE + TILE).min(region.y1));
        let before = crate::world::rays_traced_here();
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
                let mut rays = NO_RAYS;
                let mut pts = [(0f32, 0f32); BLOCK];
                let mut c = [Vec3::ZERO; BLOCK];
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
                for k in s0..s1 {
                    for (p, &(x, y)) in pts.iter_mut().zip(&coords[..n]) {
                        let (jx, jy) = integrator.pixel_offset(x, y, k, spp);
                        *p = (x as f32 + jx, y as f32 + jy);
                    }
                    cam.rays_at(&pts[..n], &mut rays[..n]);
                    if cam.has_lens() {
                        for (r, &(x, y)) in rays[..n].iter_mut().zip(&coords[..n]) {
                            *r = cam.through_lens(r, integrator.lens_offset(x, y, k));
                        }
                    }
                    let block = Block { pixels: &coords[..n], sample: k, among };
                    if s1 - s0 == 1 {
                        // One sample: straight into the sums.
                        integrator.li_block(w, &block, &rays[..n], s.traversal, &mut sum[..n]);
                    } else {
                        if k == s0 {
                            sum[..n].fill(Vec3::ZERO);
                        }
                        integrator.li_block(w, &block, &rays[..n], s.traversal, &mut c[..n]);
                        for (o, v) in sum[..n].iter_mut().zip(&c) {
                            *o += *v;
                        }
                    }
                }
                for (&(x, y), v) in coords[..n].iter().zip(&sum) {
                    sink.put(x, y, *v);
                }
            }
        }
        progress(1);
        crate::world::rays_traced_here() - before
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

/// A film's pixels or sums, shared by the tile tasks (each writes only its own tile).
#[derive(Clone, Copy)]
struct FilmPtr(*mut Vec3);
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
struct WeightPtr(*mut f32);
// SAFETY: as for `FilmPtr`.
unsafe impl Send for WeightPtr {}
// SAFETY: as above.
unsafe impl Sync for WeightPtr {}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::path::{centre_guides, quarter_guides};

    /// The guides traced in packets are those of single rays, pixel by pixel, bit for bit
    /// (the Cornell box, large enough for its blocks to be coherent, at a size whose blocks
    /// are not all whole).
    #[test]
    fn packet_guides_are_single_ray_guides() {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba/cornell_box/scene.xml");
        let scene = lucent_scene::load_mitsuba_with(&dir, &[]).expect("scene");
        let (wd, ht) = (403, 301);
        let cam = Camera::new(&scene.camera.expect("camera"), wd, ht);
        let w = World::new(scene, lucent_accel::MeshOptions::default()).expect("world");
        let a = render_aovs(&w, &cam, wd, ht);
        for y in 0..ht {
            for x in 0..wd {
                let i = (y * wd + x) as usize;
                let r = cam.ray(x as f32 + 0.5, y as f32 + 0.5);
                let (mut normal, depth, mut emission) = centre_guides(&w, &r, w.intersect_solid(&r));
                let mut albedo = Vec3::ZERO;
                for (dx, dy) in [(0.25, 0.25), (0.75, 0.25), (0.75, 0.75), (0.25, 0.75)] {
                    let (al, e, n) = quarter_guides(&w, w.intersect_solid(&cam.ray(x as f32 + dx, y as f32 + dy)));
                    albedo += al;
                    emission += e;
                    if let Some(n) = n.filter(|_| depth.is_finite()) {
                        normal += n * QUARTER_NORMAL;
                    }
                }
                assert_eq!(a.normal.pixels[i], normal.normalize_or_zero(), "normal at ({x}, {y})");
                assert_eq!(a.depth[i].to_bits(), depth.to_bits(), "depth at ({x}, {y})");
                assert_eq!(a.albedo.pixels[i], albedo / 4.0, "albedo at ({x}, {y})");
                assert_eq!(a.emission.pixels[i], emission / 5.0, "emission at ({x}, {y})");
            }
        }
    }
}
