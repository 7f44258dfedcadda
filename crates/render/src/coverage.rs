//! Screen coverage of primary rays: which pixels' rays can meet anything at all, found in
//! object order, as a rasterizer would, by projecting every instance onto the image. The
//! tile renderer traces only covered pixels; the others show the background, which is
//! exactly what their rays would return.
//!
//! Regions are conservative (a covered pixel may still miss; an uncovered one never hits):
//! - a sphere instance (an ellipsoid under its affine map) wholly in front of the eye
//!   projects to an ellipse, the set of image points whose line through the eye meets
//!   it: `k |d'|² − (o'·d')² ≤ 0` with `o'` the eye and `d'` the direction carried into
//!   the unit sphere's space and `k = |o'|² − 1`, a quadratic in the image coordinates. It
//!   is filled row by row, each row spanning the ellipse over the row's height;
//! - any other bounded instance projects through the corners of its object-space box
//!   carried by its map (tighter than its world box). A box that reaches behind the eye
//!   is clipped at the eye plane: its image runs to the edge of the screen on each side
//!   where the part cut off lies (the corners in front give the other sides);
//! - an unbounded instance (infinite cylinder or cone) covers everything, and so does
//!   anything not finite.
//!
//! Every region grows by [`MARGIN`] pixels, and covers whole pixels (any sample inside a
//! covered pixel's square is covered), so jittered samples and rounding in the ray tests
//! are inside.

use crate::camera::Camera;
use crate::world::World;
use glam::{DMat3, DVec3};
use lucent_accel::{Aabb, Geometry, Shape};
use rayon::prelude::*;

/// Pixels along each edge of a coverage block (blocks of 8×8 pixels, one bit each).
pub const BLOCK_EDGE: u32 = 8;

/// Margin in pixels around every projected region.
const MARGIN: f64 = 0.25;

/// Beyond this many instances, coverage is not computed (everything counts as covered):
/// projecting them would cost more than it saves.
const MAX_INSTANCES: usize = 1 << 16;

/// Instances projected per parallel task.
const CHUNK: usize = 64;

/// Most instances a block lists (see [`Coverage::candidates`]); more, and the block's rays
/// go through the top-level index.
pub const MAX_CANDIDATES: usize = 4;

/// A block's candidate instances: the count (above [`MAX_CANDIDATES`]: too many to list),
/// then the ids.
#[derive(Clone, Copy, Debug, Default)]
struct Candidates {
    count: u32,
    ids: [u32; MAX_CANDIDATES],
}

impl Candidates {
    #[inline]
    fn add(&mut self, id: u32) {
        let n = self.count as usize;
        // An instance fills a block row by row: only its first row adds it.
        if n > 0 && n <= MAX_CANDIDATES && self.ids[n - 1] == id {
            return;
        }
        if n < MAX_CANDIDATES {
            self.ids[n] = id;
        }
        self.count = self.count.saturating_add(1).min(MAX_CANDIDATES as u32 + 1);
    }
}

/// Which pixels' primary rays may meet an instance, as one 64-bit mask per 8×8 block (bit
/// `8·row + column` within the block), and which instances those can be, per block (when
/// there are few).
#[derive(Clone, Debug)]
pub struct Coverage {
    width: u32,
    height: u32,
    blocks_x: u32,
    masks: Vec<u64>,
    cands: Vec<Candidates>,
}

/// The camera's map from world points to image positions.
struct Projection {
    eye: DVec3,
    /// World vectors to (right, up, forward) coordinates: the inverse of the basis the
    /// camera's rays are built from (`forward + sx·right + sy·up`).
    to_cam: DMat3,
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    half_w: f64,
    half_h: f64,
    ortho: bool,
    width: f64,
    height: f64,
}

impl Projection {
    /// Image x (pixels) of screen coordinate `sx`.
    fn px(&self, sx: f64) -> f64 {
        (sx / self.half_w + 1.0) * 0.5 * self.width
    }
    /// Image y (pixels, down) of screen coordinate `sy`.
    fn py(&self, sy: f64) -> f64 {
        (1.0 - sy / self.half_h) * 0.5 * self.height
    }
}

/// Where an instance may show.
enum Region {
    Nothing,
    Everything,
    /// Image rectangle in pixels: x0, x1, y0, y1 (without the margin).
    Rect([f64; 4]),
    /// An ellipse in screen coordinates, `G(sx, sy) ≤ 0` with the symmetric matrix `K`
    /// over `(1, sx, sy)`.
    Ellipse([[f64; 3]; 3]),
}

impl Coverage {
    /// The coverage of `cam`'s primary rays over `w`; `None` when every pixel must be
    /// traced (an unbounded instance, an instance over the whole image, a huge crowd).
    #[must_use]
    pub fn of(w: &World, cam: &Camera) -> Option<Self> {
        let proj = projection(cam)?;
        let accel = &w.accel;
        let insts = accel.instances();
        if insts.len() > MAX_INSTANCES {
            return None;
        }
        let (width, height) = cam.size();
        let blocks_x = width.div_ceil(BLOCK_EDGE);
        let blocks_y = height.div_ceil(BLOCK_EDGE);
        let n_blocks = (blocks_x * blocks_y) as usize;
        let empty = || Coverage { width, height, blocks_x, masks: vec![0; n_blocks], cands: vec![Candidates::default(); n_blocks] };
        // Chunks of instances in parallel, each job into masks of its own, then merged.
        insts
            .par_chunks(CHUNK)
            .enumerate()
            // One set of masks per rayon job, not per chunk (PERF: a chunk's masks are
            // 24 KB at 512×384, and the sunflowers have 88 chunks).
            .try_fold(empty, |mut c, (ci, chunk)| {
                for (k, inst) in chunk.iter().enumerate() {
                    let id = (ci * CHUNK + k) as u32;
                    let geom = accel.geometries().get(inst.geometry as usize)?;
                    match region(geom, inst, &proj) {
                        Region::Nothing => {}
                        Region::Everything => return None,
                        Region::Rect(r) => {
                            if r[0] - MARGIN <= 0.0 && r[2] - MARGIN <= 0.0 && r[1] + MARGIN >= proj.width && r[3] + MARGIN >= proj.height {
                                return None;
                            }
                            c.fill_rect(&r, id);
                        }
                        Region::Ellipse(k) => c.fill_ellipse(&k, &proj, id),
                    }
                }
                Some(c)
            })
            .try_reduce(empty, |mut a, b| {
                for (x, y) in a.masks.iter_mut().zip(&b.masks) {
                    *x |= y;
                }
                for (x, y) in a.cands.iter_mut().zip(&b.cands) {
                    for &id in &y.ids[..(y.count as usize).min(MAX_CANDIDATES)] {
                        x.add(id);
                    }
                    if y.count as usize > MAX_CANDIDATES {
                        x.count = MAX_CANDIDATES as u32 + 1;
                    }
                }
                Some(a)
            })
    }

    /// The mask of block (`bx`, `by`) (in blocks); zero outside the image.
    #[must_use]
    pub fn block(&self, bx: u32, by: u32) -> u64 {
        if bx >= self.blocks_x {
            return 0;
        }
        self.masks.get((by * self.blocks_x + bx) as usize).copied().unwrap_or(0)
    }

    /// The instances that block (`bx`, `by`)'s covered pixels may meet, when there are at
    /// most [`MAX_CANDIDATES`] (in the order they were found); `None` when there are more
    /// (or outside the image). A ray of a covered pixel meets nothing else, so its closest
    /// hit is the closest among these.
    #[must_use]
    pub fn candidates(&self, bx: u32, by: u32) -> Option<&[u32]> {
        if bx >= self.blocks_x {
            return None;
        }
        let c = self.cands.get((by * self.blocks_x + bx) as usize)?;
        (c.count as usize <= MAX_CANDIDATES).then(|| &c.ids[..c.count as usize])
    }

    /// Whether pixel (`x`, `y`) is covered.
    #[must_use]
    pub fn covered(&self, x: u32, y: u32) -> bool {
        self.block(x / BLOCK_EDGE, y / BLOCK_EDGE) >> ((y % BLOCK_EDGE) * BLOCK_EDGE + x % BLOCK_EDGE) & 1 != 0
    }

    /// Number of covered pixels.
    #[must_use]
    pub fn count(&self) -> u64 {
        self.masks.iter().map(|m| u64::from(m.count_ones())).sum()
    }

    /// The pixel range `[lo, hi]` (clamped to `0..n`) of pixels whose squares meet
    /// `[a, b]` grown by the margin; `None` when empty.
    fn pixels(a: f64, b: f64, n: u32) -> Option<(u32, u32)> {
        if n == 0 {
            return None;
        }
        if a.is_nan() || b.is_nan() {
            return Some((0, n - 1));
        }
        let lo = floor(a - MARGIN).max(0.0);
        let hi = floor(b + MARGIN).min(f64::from(n) - 1.0);
        (lo <= hi).then_some((lo as u32, hi as u32))
    }

    /// Covers pixels `xa..=xb` of row `y` for instance `id`.
    fn fill_row(&mut self, y: u32, xa: u32, xb: u32, id: u32) {
        self.fill_rows(y, y, xa, xb, id);
    }

    /// Covers pixels `xa..=xb` of rows `ya..=yb` for instance `id`, one mask update per
    /// block.
    fn fill_rows(&mut self, ya: u32, yb: u32, xa: u32, xb: u32, id: u32) {
        for by in ya / BLOCK_EDGE..=yb / BLOCK_EDGE {
            let r0 = ya.max(by * BLOCK_EDGE) - by * BLOCK_EDGE;
            let r1 = yb.min(by * BLOCK_EDGE + BLOCK_EDGE - 1) - by * BLOCK_EDGE;
            // One byte per row: the rows r0..=r1.
            let rows = (u64::MAX >> (56 - 8 * r1)) & (u64::MAX << (8 * r0));
            for bx in xa / BLOCK_EDGE..=xb / BLOCK_EDGE {
                let c0 = xa.max(bx * BLOCK_EDGE) - bx * BLOCK_EDGE;
                let c1 = xb.min(bx * BLOCK_EDGE + BLOCK_EDGE - 1) - bx * BLOCK_EDGE;
                let cols = (0xffu64 >> (7 - c1)) & (0xffu64 << c0);
                let i = (by * self.blocks_x + bx) as usize;
                if let (Some(m), Some(c)) = (self.masks.get_mut(i), self.cands.get_mut(i)) {
                    *m |= rows & (cols * 0x0101_0101_0101_0101);
                    c.add(id);
                }
            }
        }
    }

    fn fill_rect(&mut self, r: &[f64; 4], id: u32) {
        let (Some((xa, xb)), Some((ya, yb))) = (Self::pixels(r[0], r[1], self.width), Self::pixels(r[2], r[3], self.height)) else {
            return;
        };
        self.fill_rows(ya, yb, xa, xb, id);
    }

    fn fill_ellipse(&mut self, k: &[[f64; 3]; 3], proj: &Projection, id: u32) {
        let [[k00, k01, k02], [_, k11, k12], [_, _, k22]] = *k;
        // The chord at screen height y: centre -(k12 y + k01)/k11, half-width
        // sqrt(D(y))/k11 with D(y) = a y² + 2 b y + c (a < 0 for an ellipse).
        let (a, b, c) = (k12 * k12 - k11 * k22, k12 * k01 - k11 * k02, k01 * k01 - k11 * k00);
        let roots = |b: f64, c: f64| -> Option<(f64, f64)> {
            let disc = b * b - a * c;
            (disc >= 0.0).then(|| {
                let s = disc.sqrt();
                let (r1, r2) = ((-b + s) / a, (-b - s) / a);
                (r1.min(r2), r1.max(r2))
            })
        };
        // Extent in sy (where D vanishes) and in sx (the same for the transposed form).
        let Some((y_lo, y_hi)) = roots(b, c) else { return };
        let Some((x_lo, x_hi)) = roots(k12 * k02 - k22 * k01, k02 * k02 - k22 * k00) else { return };
        // Heights of the leftmost and rightmost points.
        let (yl, yr) = (-(k12 * x_lo + k02) / k22, -(k12 * x_hi + k02) / k22);
        let r11 = 1.0 / k11;
        // The chord in image x (pixels): px = px0 + px1 * sx.
        let (px1, px0) = (0.5 * proj.width / proj.half_w, 0.5 * proj.width);
        let chord = |y: f64| {
            let mid = -(k12 * y + k01) * r11;
            let half = (a * y * y + 2.0 * b * y + c).max(0.0).sqrt() * r11;
            (px0 + px1 * (mid - half), px0 + px1 * (mid + half))
        };
        let (left_most, right_most) = (px0 + px1 * x_lo, px0 + px1 * x_hi);
        let Some((ya, yb)) = Self::pixels(proj.py(y_hi), proj.py(y_lo), self.height) else { return };
        // sy of image row position py: sy0 + sy1 * py.
        let (sy0, sy1) = (proj.half_h, -2.0 * proj.half_h / proj.height);
        for y in ya..=yb {
            // The row's band in sy (sy falls as the image row grows), within the ellipse.
            let top = (sy0 + sy1 * (f64::from(y) - MARGIN)).min(y_hi);
            let bottom = (sy0 + sy1 * (f64::from(y) + 1.0 + MARGIN)).max(y_lo);
            if bottom > top {
                continue;
            }
            // The left edge is convex and the right edge concave in sy: over the band they
            // reach out furthest at the extreme points, or else at the band's ends.
            let (l0, r0) = chord(bottom);
            let (l1, r1) = chord(top);
            let left = if bottom <= yl && yl <= top { left_most } else { l0.min(l1) };
            let right = if bottom <= yr && yr <= top { right_most } else { r0.max(r1) };
            if let Some((xa, xb)) = Self::pixels(left, right, self.width) {
                self.fill_row(y, xa, xb, id);
            }
        }
    }
}

/// `x.floor()` for the finite values of pixel coordinates (clamped far outside any image),
/// without a library call.
#[inline]
fn floor(x: f64) -> f64 {
    let x = x.clamp(-1e15, 1e15);
    let t = x as i64 as f64;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

fn projection(cam: &Camera) -> Option<Projection> {
    let v = cam.frame();
    let [eye, right, up, forward] = v.vectors.map(|x| x.as_dvec3());
    let basis = DMat3::from_cols(right, up, forward);
    let det = basis.determinant();
    if !det.is_finite() || det.abs() < 1e-300 || !eye.is_finite() {
        return None;
    }
    let (half_w, half_h) = (f64::from(v.half_w), f64::from(v.half_h));
    if !(half_w > 0.0 && half_h > 0.0 && half_w.is_finite() && half_h.is_finite()) {
        return None;
    }
    let (w, h) = cam.size();
    Some(Projection {
        eye,
        to_cam: basis.inverse(),
        right,
        up,
        forward,
        half_w,
        half_h,
        ortho: v.ortho,
        width: f64::from(w),
        height: f64::from(h),
    })
}

/// Where instance `inst` of `geom` may show.
fn region(geom: &Geometry, inst: &lucent_accel::Instance, proj: &Projection) -> Region {
    match geom {
        Geometry::Shape(Shape::Sphere) if !proj.ortho => {
            ellipse(inst, proj).unwrap_or_else(|| box_region(&Shape::Sphere.bounds_local(), inst, proj))
        }
        Geometry::Shape(s) if !s.is_bounded() => Region::Everything,
        g => box_region(&g.bounds(), inst, proj),
    }
}

/// The twelve edges of a box, as corner indices (bit k of an index = upper end on axis k).
const EDGES: [(usize, usize); 12] = [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)];

/// The image rectangle of the object-space box `b` of instance `inst`.
fn box_region(b: &Aabb, inst: &lucent_accel::Instance, proj: &Projection) -> Region {
    if b.is_empty() {
        return Region::Nothing;
    }
    let m = inst.world_from_object.as_daffine3();
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    // Corners in camera coordinates (right, up, forward).
    let q: [DVec3; 8] = std::array::from_fn(|i| {
        let c =
            DVec3::new(if i & 1 != 0 { hi.x } else { lo.x }, if i & 2 != 0 { hi.y } else { lo.y }, if i & 4 != 0 { hi.z } else { lo.z });
        proj.to_cam * (m.transform_point3(c) - proj.eye)
    });
    if q.iter().any(|c| !c.is_finite()) {
        return Region::Everything;
    }
    if q.iter().all(|c| c.z < 0.0) {
        return Region::Nothing;
    }
    let (mut smin, mut smax) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    if proj.ortho {
        for c in &q {
            for k in 0..2 {
                smin[k] = smin[k].min(c[k]);
                smax[k] = smax[k].max(c[k]);
            }
        }
    } else {
        for c in q.iter().filter(|c| c.z > 0.0) {
            for k in 0..2 {
                smin[k] = smin[k].min(c[k] / c.z);
                smax[k] = smax[k].max(c[k] / c.z);
            }
        }
        // The part behind the eye plane: where the box meets that plane, a point right of
        // (above) the view axis sends the image to the right (top) edge, and so on.
        let mut touch = |c: DVec3, scale: f64| {
            for k in 0..2 {
                let eps = 1e-9 * scale;
                if c[k] > -eps {
                    smax[k] = f64::INFINITY;
                }
                if c[k] < eps {
                    smin[k] = f64::NEG_INFINITY;
                }
            }
        };
        for &(i, j) in &EDGES {
            let (a, b) = (q[i], q[j]);
            let scale = a.abs().max_element() + b.abs().max_element();
            match (a.z > 0.0, b.z > 0.0) {
                (true, true) => {}
                (false, false) => {
                    for e in [a, b] {
                        if e.z == 0.0 {
                            touch(e, scale);
                        }
                    }
                }
                _ => {
                    let (p, n) = if a.z > 0.0 { (a, b) } else { (b, a) };
                    touch(p + (n - p) * (p.z / (p.z - n.z)), scale);
                }
            }
        }
    }
    if smin[0] > smax[0] {
        return Region::Nothing;
    }
    let big = 1e12;
    let (x0, x1) = (proj.px(smin[0].max(-big)), proj.px(smax[0].min(big)));
    let (y0, y1) = (proj.py(smax[1].min(big)), proj.py(smin[1].max(-big)));
    Region::Rect([x0, x1, y0, y1])
}

/// The image ellipse of a sphere instance wholly in front of the eye; `None` when it is
/// not (or the quadric is degenerate), for the box to stand in.
fn ellipse(inst: &lucent_accel::Instance, proj: &Projection) -> Option<Region> {
    let (wfo, ofw) = (inst.world_from_object.as_daffine3(), inst.object_from_world.as_daffine3());
    // Nearest depth of the ellipsoid along the camera's forward coordinate.
    let n = proj.to_cam.row(2);
    let depth = n.dot(wfo.translation - proj.eye);
    let reach = (wfo.matrix3.transpose() * n).length();
    // (NaN fails the test too.)
    if (depth - reach).partial_cmp(&(1e-9 * (depth.abs() + reach))) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let inv = ofw.matrix3;
    let o = ofw.transform_point3(proj.eye);
    let k = o.length_squared() - 1.0;
    if k.is_nan() || k <= 0.0 {
        return None;
    }
    // Directions forward + sx·right + sy·up in the sphere's space: P0 + sx P1 + sy P2.
    let p = [inv * proj.forward, inv * proj.right, inv * proj.up];
    let mut kk = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            kk[i][j] = k * p[i].dot(p[j]) - o.dot(p[i]) * o.dot(p[j]);
        }
    }
    let ok = kk.iter().flatten().all(|x| x.is_finite()) && kk[1][1] > 0.0 && kk[2][2] > 0.0 && kk[1][1] * kk[2][2] > kk[1][2] * kk[1][2];
    ok.then_some(Region::Ellipse(kk))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_masks_cover_exactly_the_filled_pixels() {
        let mut c = Coverage { width: 20, height: 13, blocks_x: 3, masks: vec![0; 6], cands: vec![Candidates::default(); 6] };
        c.fill_rows(3, 10, 6, 17, 7);
        c.fill_row(12, 0, 0, 9);
        for y in 0..13 {
            for x in 0..20 {
                let want = ((3..=10).contains(&y) && (6..=17).contains(&x)) || (y == 12 && x == 0);
                assert_eq!(c.covered(x, y), want, "{x},{y}");
            }
        }
        assert_eq!(c.count(), 8 * 12 + 1);
        // Each block lists the instances that cover it, once each.
        assert_eq!(c.candidates(0, 0), Some(&[7][..]));
        assert_eq!(c.candidates(2, 1), Some(&[7][..]));
        assert_eq!(c.candidates(0, 1), Some(&[7, 9][..]));
        for id in 10..13 {
            c.fill_row(0, 0, 0, id);
        }
        assert_eq!(c.candidates(0, 0), Some(&[7, 10, 11, 12][..]));
        c.fill_row(1, 0, 0, 14);
        assert_eq!(c.candidates(0, 0), None, "too many to list");
        c.fill_row(1, 0, 0, 15);
        assert_eq!(c.candidates(0, 0), None);
        assert_eq!(c.candidates(3, 0), None, "outside");
        assert_eq!(Coverage::pixels(2.6, 5.1, 20), Some((2, 5)));
        assert_eq!(Coverage::pixels(2.2, 5.8, 20), Some((1, 6)));
        assert_eq!(Coverage::pixels(-9.0, 50.0, 20), Some((0, 19)));
        assert_eq!(Coverage::pixels(30.0, 50.0, 20), None);
        assert_eq!(Coverage::pixels(-30.0, -5.0, 20), None);
    }
}
