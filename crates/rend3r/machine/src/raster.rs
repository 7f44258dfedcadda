//! The rasterization mode: triangles projected through the same camera and filled with
//! edge functions (Pineda, "A Parallel Algorithm for Polygon Rasterization", SIGGRAPH
//! 1988) inside each triangle's bounding box, either winding; flat Lambert shading on the
//! face normal (turned towards the camera); a z-buffer, or the paper's painter's order
//! (farthest centroid first) with `painter`.

use crate::frame::{lights, rgb565, FrameInfo, FrameSettings};
use crate::processor::DeviceState;
use glam::Vec3;
use lucent_render::{Camera, Film};
use lucent_scene::LightKind;

/// A triangle in image space.
#[derive(Clone, Copy, Debug)]
pub struct ScreenTri {
    /// Vertices: pixel x, pixel y (down), depth.
    pub v: [(f32, f32, f32); 3],
    /// Shaded colour.
    pub color: Vec3,
    /// Distance of the centroid from the eye (painter's order).
    pub dist: f32,
}

/// Projects and shades every written triangle record (those behind the near plane are
/// dropped, as the prototype does).
#[must_use]
pub fn project(state: &DeviceState, cam: &Camera) -> Vec<ScreenTri> {
    project_lit(state, cam, &lights(state))
}

fn project_lit(state: &DeviceState, cam: &Camera, ls: &[lucent_scene::Light]) -> Vec<ScreenTri> {
    let (near, _) = cam.clip();
    let mut out = Vec::new();
    for r in state.sets.iter().filter(|r| r.used()) {
        let p = [Vec3::new(r.f(1), r.f(2), r.f(3)), Vec3::new(r.f(4), r.f(5), r.f(6)), Vec3::new(r.f(7), r.f(8), r.f(9))];
        if p.iter().any(|v| !v.is_finite()) {
            continue;
        }
        let Some(a) = cam.project(p[0]) else { continue };
        let Some(b) = cam.project(p[1]) else { continue };
        let Some(c) = cam.project(p[2]) else { continue };
        if [a.2, b.2, c.2].iter().any(|&z| z < near.max(1e-6)) {
            continue;
        }
        let centroid = (p[0] + p[1] + p[2]) / 3.0;
        let mut n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        let eye = cam.ray(0.0, 0.0).org;
        if n.dot(eye - centroid) < 0.0 {
            n = -n;
        }
        let albedo = if r.has(11) { rgb565(r.u(11)) } else { Vec3::ONE };
        let mut light = Vec3::splat(0.05);
        for l in ls {
            let dir = match l.kind {
                LightKind::Directional { direction } => -direction,
                LightKind::Point { position } | LightKind::Spot { position, .. } => (position - centroid).normalize_or_zero(),
            };
            light += l.color * n.dot(dir).max(0.0);
        }
        out.push(ScreenTri { v: [a, b, c], color: albedo * light, dist: (centroid - eye).length() });
    }
    out
}

/// Rasterizes a frame.
#[must_use]
pub fn rasterize(state: &DeviceState, cam: &Camera, fs: &FrameSettings) -> (Film, FrameInfo) {
    let (w, h) = (fs.width as usize, fs.height as usize);
    let ls = lights(state);
    let mut tris = project_lit(state, cam, &ls);
    if fs.painter {
        tris.sort_by(|a, b| b.dist.total_cmp(&a.dist));
    }
    let mut film = Film::new(fs.width, fs.height);
    let mut depth = vec![f32::INFINITY; w * h];
    for t in &tris {
        let [(ax, ay, az), (bx, by, bz), (cx, cy, cz)] = t.v;
        let area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
        if area == 0.0 || !area.is_finite() {
            continue;
        }
        let x0 = ax.min(bx).min(cx).floor().max(0.0) as usize;
        let y0 = ay.min(by).min(cy).floor().max(0.0) as usize;
        let x1 = (ax.max(bx).max(cx).ceil().max(0.0) as usize).min(w);
        let y1 = (ay.max(by).max(cy).ceil().max(0.0) as usize).min(h);
        let edge = |px: f32, py: f32, (x0, y0): (f32, f32), (x1, y1): (f32, f32)| (x1 - x0) * (py - y0) - (y1 - y0) * (px - x0);
        for y in y0..y1 {
            for x in x0..x1 {
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let e0 = edge(px, py, (bx, by), (cx, cy));
                let e1 = edge(px, py, (cx, cy), (ax, ay));
                let e2 = edge(px, py, (ax, ay), (bx, by));
                // Inside for either winding, edges included.
                let inside = (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0);
                if !inside {
                    continue;
                }
                let i = y * w + x;
                if !fs.painter {
                    // Perspective-correct depth: interpolate 1/z with the barycentrics.
                    let (l0, l1, l2) = (e0 / area, e1 / area, e2 / area);
                    let z = 1.0 / (l0 / az + l1 / bz + l2 / cz);
                    // NaN depths (degenerate) never win.
                    if z.is_nan() || z >= depth[i] {
                        continue;
                    }
                    depth[i] = z;
                }
                film.pixels[i] = t.color;
            }
        }
    }
    (film, FrameInfo { shapes: tris.len(), lights: ls.len(), skipped: 0, rays: 0 })
}
