//! The tile renderer: tiles on all cores (rayon), samples deterministic per (pixel, sample).

use crate::camera::Camera;
use crate::coverage::{Coverage, Prepared};
use crate::film::Film;
use crate::integrator::{li, li_packet_among, radiance, Integrator, WhittedSettings, NO_RAYS};
use crate::world::World;
use glam::Vec3;
use lucent_accel::Ray;
use rayon::prelude::*;

/// Render settings.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel (1 = pixel centre; more = jittered).
    pub spp: u32,
    /// Integrator settings.
    pub whitted: WhittedSettings,
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

/// Radiance of pixel (x, y) averaged over its samples.
#[must_use]
pub fn render_pixel(w: &World, cam: &Camera, s: &RenderSettings, x: u32, y: u32) -> Vec3 {
    let spp = s.spp.max(1);
    let mut c = Vec3::ZERO;
    for k in 0..spp {
        let (jx, jy) = if spp == 1 { (0.5, 0.5) } else { jitter(x, y, k) };
        c += li(w, &cam.ray(x as f32 + jx, y as f32 + jy), &s.whitted, 0);
    }
    c / spp as f32
}

/// Renders a frame; `progress(tiles_done)` is called after each tile. Returns the film and
/// the number of rays traced.
pub fn render(w: &World, cam: &Camera, s: &RenderSettings, progress: &(dyn Fn(u64) + Sync)) -> (Film, u64) {
    if !s.whitted.packets {
        let samples = if s.spp.max(1) == 1 { Samples::Centres } else { Samples::Anywhere };
        return render_tiles(w, cam, samples, s.width, s.height, progress, &|px, _, out| {
            for (o, &(x, y)) in out.iter_mut().zip(px) {
                *o = render_pixel(w, cam, s, x, y);
            }
        });
    }
    let spp = s.spp.max(1);
    let samples = if spp == 1 { Samples::Centres } else { Samples::Anywhere };
    render_tiles(w, cam, samples, s.width, s.height, progress, &|px, among, out| {
        let mut rays = NO_RAYS;
        let rays = &mut rays[..px.len()];
        let n = px.len();
        if spp == 1 {
            // One sample: straight into the block's output.
            block_rays(cam, px, spp, 0, rays);
            li_packet_among(w, rays, among, &s.whitted, out);
            return;
        }
        let mut c = [Vec3::ZERO; BLOCK];
        out.fill(Vec3::ZERO);
        for k in 0..spp {
            block_rays(cam, px, spp, k, rays);
            li_packet_among(w, rays, among, &s.whitted, &mut c[..n]);
            for (o, v) in out.iter_mut().zip(&c) {
                *o += *v;
            }
        }
        for o in out.iter_mut() {
            *o /= spp as f32;
        }
    })
}

/// Sample `k` of `spp` through each pixel of `px` (the centre when `spp` is 1).
#[inline(always)]
fn block_rays(cam: &Camera, px: &[(u32, u32)], spp: u32, k: u32, rays: &mut [Ray]) {
    let mut pts = [(0f32, 0f32); BLOCK];
    for (p, &(x, y)) in pts.iter_mut().zip(px) {
        let (jx, jy) = if spp == 1 { (0.5, 0.5) } else { jitter(x, y, k) };
        *p = (x as f32 + jx, y as f32 + jy);
    }
    cam.rays_at(&pts[..px.len().min(BLOCK)], rays);
}

/// One sample per pixel: sample `index` of every pixel (0 = the pixel centre, then the
/// jittered samples of [`jitter`]), with the chosen integrator. Averaging passes 0..n gives
/// an n-sample image that does not depend on how the passes were split (the viewer
/// accumulates these while the camera stands still).
pub fn render_pass(w: &World, cam: &Camera, s: &RenderSettings, integrator: Integrator, index: u32) -> (Film, u64) {
    let ray = |x: u32, y: u32| {
        let (jx, jy) = if index == 0 { (0.5, 0.5) } else { jitter(x, y, index) };
        cam.ray(x as f32 + jx, y as f32 + jy)
    };
    let samples = if index == 0 { Samples::Centres } else { Samples::Anywhere };
    render_tiles(w, cam, samples, s.width, s.height, &|_| {}, &|px, among, out| {
        if integrator == Integrator::Whitted && s.whitted.packets {
            let mut rays = NO_RAYS;
            for (r, &(x, y)) in rays.iter_mut().zip(px) {
                *r = ray(x, y);
            }
            li_packet_among(w, &rays[..px.len()], among, &s.whitted, out);
        } else {
            for (o, &(x, y)) in out.iter_mut().zip(px) {
                *o = radiance(w, &ray(x, y), &s.whitted, integrator);
            }
        }
    })
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

/// Computes the pixels of a block: `block(pixels, among, out)`, where `among` (when given)
/// lists the only instances the pixels' primary rays can meet.
type BlockFn<'a> = dyn Fn(&[(u32, u32)], Option<&[u32]>, &mut [Vec3]) + Sync + 'a;

/// Pixels per block handed to the integrators: 8×8 (one bit each in a coverage mask), one
/// ray packet.
const BLOCK: usize = 64;
const _: () = assert!(BLOCK == lucent_accel::MAX_PACKET, "a block is one packet, and NO_RAYS holds a packet");

/// The tile loop shared by every renderer: tiles on rayon; the pixels of each 8×8 block
/// that the frame's [`Coverage`] says may meet something are handed out together,
/// `block(pixels, among, out)` with the block's candidate instances, and the others show
/// the background.
fn render_tiles(
    w: &World,
    cam: &Camera,
    samples: Samples,
    width: u32,
    height: u32,
    progress: &(dyn Fn(u64) + Sync),
    block: &BlockFn,
) -> (Film, u64) {
    let (tw, th) = (width.div_ceil(TILE), height.div_ceil(TILE));
    // PERF: the film is not cleared first: the tiles write every pixel, traced or not, in
    // parallel (clearing 2.4 MB on one thread was a seventh of a sparse REND3R frame).
    let n_pixels = width as usize * height as usize;
    let mut pixels: Vec<Vec3> = Vec::with_capacity(n_pixels);
    let out = FilmPtr(pixels.as_mut_ptr());
    let bg = w.scene.background;
    // Which pixels can meet anything, by projecting the instances (object order): a sparse
    // scene, such as REND3R's 256 small spheres, traces a third of its pixels. `None`
    // (something covers the whole image, or reaches around the eye) traces them all.
    let prep = match samples {
        _ if cam.size() != (width, height) => None,
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
        let (x0, y0) = (tx * TILE, ty * TILE);
        let (x1, y1) = ((x0 + TILE).min(width), (y0 + TILE).min(height));
        let before = crate::world::rays_traced_here();
        let put = |x: u32, y: u32, c: Vec3| {
            // SAFETY: (x, y) lies inside this tile and inside the film's allocation
            // (`n_pixels` long), and no other tile writes this pixel; the buffer
            // outlives the parallel loop.
            unsafe { out.get().add((y * width + x) as usize).write(c) };
        };
        let mut coords = [(0u32, 0u32); BLOCK];
        let mut px = [Vec3::ZERO; BLOCK];
        for by in (y0..y1).step_by(8) {
            for bx in (x0..x1).step_by(8) {
                let (bx1, by1) = ((bx + 8).min(x1), (by + 8).min(y1));
                let mask = cover.map_or(u64::MAX, |c| c.block(bx / 8, by / 8));
                let (cols, rows) = (bx1 - bx, by1 - by);
                // The pixels of the block inside the tile (a partial block at the image's
                // right or bottom edge has fewer).
                let inside = if cols == 8 && rows == 8 {
                    u64::MAX
                } else {
                    (u64::MAX >> (64 - 8 * rows)) & ((0xffu64 >> (8 - cols)) * 0x0101_0101_0101_0101)
                };
                let trace = mask & inside;
                if trace != inside {
                    // PERF: the background a row at a time (pixel by pixel, the background
                    // of sparse REND3R frames was a tenth of their time); traced pixels
                    // overwrite it below.
                    let row = [bg; 8];
                    for y in by..by1 {
                        let dst = out.get().wrapping_add((y * width + bx) as usize);
                        // SAFETY: the row's pixels bx..bx1 lie inside this tile and the
                        // film's allocation, and no other tile writes them. PERF: a whole
                        // row of a block as a copy of known size, which compiles to a few
                        // vector stores (not a call to `memcpy`).
                        unsafe {
                            if cols == 8 {
                                dst.cast::<[Vec3; 8]>().write_unaligned(row);
                            } else {
                                std::ptr::copy_nonoverlapping(row.as_ptr(), dst, cols as usize);
                            }
                        }
                    }
                }
                if trace == 0 {
                    continue;
                }
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
                block(&coords[..n], among, &mut px[..n]);
                for (&(x, y), c) in coords[..n].iter().zip(&px) {
                    put(x, y, *c);
                }
            }
        }
        progress(1);
        crate::world::rays_traced_here() - before
    };
    let rays = (0..th)
        .into_par_iter()
        .map(|ty| {
            let cover = prep.as_ref().map(|p| p.band(ty as usize));
            (0..tw).into_par_iter().map(|tx| tile(tx, ty, cover.as_ref())).sum::<u64>()
        })
        .sum();
    // SAFETY: every pixel lies in exactly one tile and one of its blocks, and each block
    // wrote each of its pixels above: the traced ones from `block` (over the background
    // where the block was only partly traced), the others the background. (Had a tile
    // panicked, the length would still be zero here.)
    unsafe { pixels.set_len(n_pixels) };
    (Film { width, height, pixels }, rays)
}

/// The film's pixels, shared by the tile tasks (each writes only its own tile).
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
