//! The tile renderer: tiles on all cores (rayon), samples deterministic per (pixel, sample).

use crate::camera::Camera;
use crate::film::Film;
use crate::integrator::{li, radiance, Integrator, WhittedSettings};
use crate::world::World;
use glam::Vec3;
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
    render_tiles(w, cam, s.width, s.height, progress, &|x, y| render_pixel(w, cam, s, x, y))
}

/// One sample per pixel: sample `index` of every pixel (0 = the pixel centre, then the
/// jittered samples of [`jitter`]), with the chosen integrator. Averaging passes 0..n gives
/// an n-sample image that does not depend on how the passes were split (the viewer
/// accumulates these while the camera stands still).
pub fn render_pass(w: &World, cam: &Camera, s: &RenderSettings, integrator: Integrator, index: u32) -> (Film, u64) {
    render_tiles(w, cam, s.width, s.height, &|_| {}, &|x, y| {
        let (jx, jy) = if index == 0 { (0.5, 0.5) } else { jitter(x, y, index) };
        radiance(w, &cam.ray(x as f32 + jx, y as f32 + jy), &s.whitted, integrator)
    })
}

/// The tile loop shared by every renderer: tiles on rayon, empty tiles culled by their
/// frustum, `pixel(x, y)` for the rest.
fn render_tiles(
    w: &World,
    cam: &Camera,
    width: u32,
    height: u32,
    progress: &(dyn Fn(u64) + Sync),
    pixel: &(dyn Fn(u32, u32) -> Vec3 + Sync),
) -> (Film, u64) {
    let (tw, th) = (width.div_ceil(TILE), height.div_ceil(TILE));
    let tiles: Vec<(u32, u32)> = (0..th).flat_map(|ty| (0..tw).map(move |tx| (tx, ty))).collect();
    let done: Vec<(u32, u32, Vec<Vec3>, u64)> = tiles
        .par_iter()
        .map(|&(tx, ty)| {
            let (x0, y0) = (tx * TILE, ty * TILE);
            let (x1, y1) = ((x0 + TILE).min(width), (y0 + TILE).min(height));
            let before = crate::world::rays_traced_here();
            let n = ((x1 - x0) * (y1 - y0)) as usize;
            // Frustum culling: a tile whose frustum meets no instance shows the background
            // (exactly what its primary rays would return), so nothing is traced.
            let empty = cam.tile_frustum(x0 as f32, y0 as f32, x1 as f32, y1 as f32).is_some_and(|f| !w.accel.frustum_may_hit(&f));
            let px = if empty {
                vec![w.scene.background; n]
            } else {
                let mut px = Vec::with_capacity(n);
                for y in y0..y1 {
                    for x in x0..x1 {
                        px.push(pixel(x, y));
                    }
                }
                px
            };
            progress(1);
            (tx, ty, px, crate::world::rays_traced_here() - before)
        })
        .collect();
    let mut film = Film::new(width, height);
    let mut rays = 0;
    for (tx, ty, px, r) in done {
        rays += r;
        let (x0, y0) = (tx * TILE, ty * TILE);
        let x1 = (x0 + TILE).min(width);
        let wdt = (x1 - x0) as usize;
        for (i, c) in px.into_iter().enumerate() {
            let (x, y) = (x0 + (i % wdt) as u32, y0 + (i / wdt) as u32);
            film.pixels[(y * width + x) as usize] = c;
        }
    }
    (film, rays)
}
