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

/// Wider images are not covered (every pixel is traced): the row kernels' pixel
/// coordinates are 32-bit signed integers.
const MAX_WIDTH: u32 = 1 << 24;

/// Up to this many instances, their regions are found on the calling thread.
const SERIAL_MAX: usize = 1024;

/// Up to this many regions, their rows are filled on the calling thread.
const SERIAL_FILLS: usize = 16;

/// Image rows per band of the parallel fill (whole blocks).
const BAND_ROWS: u32 = 2 * BLOCK_EDGE;

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
/// It covers the whole image, or one band of rows (`CoverageBands::band`).
#[derive(Clone, Debug)]
pub struct Coverage {
    /// The first block row held (0 for the whole image).
    by0: u32,
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
        Self::with(w, cam, false)
    }

    /// [`Coverage::of`] for rays through pixel centres only (one sample per pixel, not
    /// jittered): a pixel is covered when a region comes within `MARGIN` of its centre,
    /// rather than of its square, so the rim of pixels whose rays only graze a region's
    /// box goes (a quarter of the traced pixels of REND3R's 256 spheres). Boxes still cover
    /// whole squares.
    #[must_use]
    pub fn of_centres(w: &World, cam: &Camera) -> Option<Self> {
        Self::with(w, cam, true)
    }

    fn with(w: &World, cam: &Camera, centres: bool) -> Option<Self> {
        let prep = CoverageBands::new(w, cam, centres)?;
        let mut c = Coverage {
            by0: 0,
            blocks_x: prep.blocks_x,
            masks: vec![0; prep.n_blocks()],
            cands: vec![Candidates::default(); prep.n_blocks()],
        };
        let per_band = prep.blocks_per_band();
        let band = |(bi, (masks, cands)): (usize, (&mut [u64], &mut [Candidates]))| prep.fill_band(bi, masks, cands);
        if prep.fills.len() <= SERIAL_FILLS {
            c.masks.chunks_mut(per_band).zip(c.cands.chunks_mut(per_band)).enumerate().for_each(band);
        } else {
            c.masks.par_chunks_mut(per_band).zip(c.cands.par_chunks_mut(per_band)).enumerate().for_each(band);
        }
        Some(c)
    }

    /// Where block (`bx`, `by`) (in blocks, image coordinates) is kept, if it is.
    fn index(&self, bx: u32, by: u32) -> Option<usize> {
        (bx < self.blocks_x && by >= self.by0).then(|| ((by - self.by0) * self.blocks_x + bx) as usize)
    }

    /// The mask of block (`bx`, `by`) (in blocks); zero outside the image (or the band).
    #[must_use]
    pub fn block(&self, bx: u32, by: u32) -> u64 {
        self.index(bx, by).and_then(|i| self.masks.get(i)).copied().unwrap_or(0)
    }

    /// The instances that block (`bx`, `by`)'s covered pixels may meet, when there are at
    /// most `MAX_CANDIDATES` (in the order they were found); `None` when there are more
    /// (or outside the image or the band). A ray of a covered pixel meets nothing else, so
    /// its closest hit is the closest among these.
    #[must_use]
    pub fn candidates(&self, bx: u32, by: u32) -> Option<&[u32]> {
        let c = self.cands.get(self.index(bx, by)?)?;
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

    /// The whole image as one band (for tests).
    #[cfg(test)]
    fn all(&mut self) -> Band<'_> {
        let y1 = (self.masks.len() as u32 / self.blocks_x.max(1)) * BLOCK_EDGE;
        Band { y0: 0, y1, blocks_x: self.blocks_x, masks: &mut self.masks, cands: &mut self.cands }
    }
}

/// A frame's coverage before its rows are filled: what each instance covers, and which
/// instances each band of [`BAND_ROWS`] image rows must fill. Bands are filled apart
/// ([`CoverageBands::band`]), so the tile renderer fills each band in the task that renders it:
/// one parallel step per frame, not two.
pub struct CoverageBands {
    blocks_x: u32,
    height: u32,
    centres: bool,
    /// Ellipses are filled with the AVX2 row kernel.
    simd: bool,
    /// The instances' regions (instance id, region), in instance order.
    fills: Vec<(u32, Fill)>,
    /// Band `b`'s regions: `list[start[b]..start[b + 1]]` (indices into `fills`).
    start: Vec<u32>,
    list: Vec<u32>,
}

impl CoverageBands {
    /// Image rows per band (whole blocks).
    pub const BAND_ROWS: u32 = BAND_ROWS;

    /// The regions of `w`'s instances seen by `cam` (pixel squares, or with `centres` pixel
    /// centres; see [`Coverage::of_centres`]); `None` when every pixel must be traced.
    #[must_use]
    pub fn new(w: &World, cam: &Camera, centres: bool) -> Option<Self> {
        let proj = projection(cam)?;
        let accel = &w.accel;
        let insts = accel.instances();
        if insts.len() > MAX_INSTANCES {
            return None;
        }
        let (width, height) = cam.size();
        if width == 0 || height == 0 || width > MAX_WIDTH {
            return None;
        }
        let blocks_x = width.div_ceil(BLOCK_EDGE);
        // First what each instance covers (its rows, and how to find each row's span);
        // the rows are filled band by band, each band owning its masks: no merging.
        let fill = |(id, inst): (usize, &lucent_accel::Instance)| -> Option<Option<(u32, Fill)>> {
            let geom = accel.geometries().get(inst.geometry as usize)?;
            Some(match region(geom, inst, &proj) {
                Region::Nothing => None,
                Region::Everything => return None,
                Region::Rect(r) => {
                    if r[0] - MARGIN <= 0.0 && r[2] - MARGIN <= 0.0 && r[1] + MARGIN >= proj.width && r[3] + MARGIN >= proj.height {
                        return None;
                    }
                    match (pixels(r[0], r[1], width), pixels(r[2], r[3], height)) {
                        (Some((xa, xb)), Some((ya, yb))) => Some((id as u32, Fill::Rect { xa, xb, ya, yb })),
                        _ => None,
                    }
                }
                Region::Ellipse(k) => EllipseRows::new(&k, &proj).map(|e| (id as u32, Fill::Ellipse(e))),
            })
        };
        // PERF: a few hundred instances are prepared on the calling thread (a job per
        // chunk cost more than the work).
        let fills: Vec<(u32, Fill)> = if insts.len() <= SERIAL_MAX {
            // PERF: straight into one vector (collecting `Option`s and flattening them moved
            // every region twice).
            let mut v = Vec::with_capacity(insts.len());
            for x in insts.iter().enumerate() {
                if let Some(f) = fill(x)? {
                    v.push(f);
                }
            }
            v
        } else {
            insts.par_iter().enumerate().map(fill).collect::<Option<Vec<_>>>()?.into_iter().flatten().collect()
        };
        // Each band's fills, in instance order (PERF: every band scanning every fill read
        // the whole list once per band).
        let n_bands = height.div_ceil(BAND_ROWS).max(1) as usize;
        let bands_of = |f: &Fill| {
            let (ya, yb) = f.rows();
            (ya / BAND_ROWS) as usize..=((yb / BAND_ROWS) as usize).min(n_bands - 1)
        };
        let mut start = vec![0u32; n_bands + 1];
        for (_, f) in &fills {
            for b in bands_of(f) {
                start[b + 1] += 1;
            }
        }
        for b in 0..n_bands {
            start[b + 1] += start[b];
        }
        let mut list = vec![0u32; start[n_bands] as usize];
        let mut next = start.clone();
        for (k, (_, f)) in fills.iter().enumerate() {
            for b in bands_of(f) {
                list[next[b] as usize] = k as u32;
                next[b] += 1;
            }
        }
        let simd = lucent_accel::simd::avx2();
        Some(Self { blocks_x, height, centres, simd, fills, start, list })
    }

    /// Blocks in the whole image.
    fn n_blocks(&self) -> usize {
        (self.blocks_x * self.height.div_ceil(BLOCK_EDGE)) as usize
    }

    /// Blocks in a (whole) band.
    fn blocks_per_band(&self) -> usize {
        (self.blocks_x * BAND_ROWS / BLOCK_EDGE) as usize
    }

    /// Fills band `bi` (image rows `bi·BAND_ROWS ..`) into its blocks' `masks` and
    /// `cands` (cleared by the caller).
    fn fill_band(&self, bi: usize, masks: &mut [u64], cands: &mut [Candidates]) {
        let y0 = bi as u32 * BAND_ROWS;
        let mut band = Band { y0, y1: (y0 + BAND_ROWS).min(self.height), blocks_x: self.blocks_x, masks, cands };
        let mine = self.start.get(bi..bi + 2).map_or(&[][..], |s| &self.list[s[0] as usize..s[1] as usize]);
        for (id, f) in mine.iter().map(|&k| &self.fills[k as usize]) {
            let (ya, yb) = f.rows();
            let (ya, yb) = (ya.max(band.y0), yb.min(band.y1.saturating_sub(1)));
            if ya > yb {
                continue;
            }
            match f {
                Fill::Rect { xa, xb, .. } => band.fill_rows(ya, yb, *xa, *xb, *id),
                Fill::Ellipse(e) => e.fill(&mut band, ya, yb, *id, self.centres, self.simd),
            }
        }
    }

    /// The coverage of band `bi`: the blocks of image rows `bi·BAND_ROWS ..` (block rows
    /// `bi·BAND_ROWS/8 ..`).
    #[must_use]
    pub fn band(&self, bi: usize) -> Coverage {
        let n = self.blocks_per_band();
        let mut b = Coverage {
            by0: bi as u32 * (BAND_ROWS / BLOCK_EDGE),
            blocks_x: self.blocks_x,
            masks: vec![0; n],
            cands: vec![Candidates::default(); n],
        };
        self.fill_band(bi, &mut b.masks, &mut b.cands);
        b
    }
}

/// What one instance covers, ready to be filled band by band.
enum Fill {
    /// Pixels `xa..=xb` of rows `ya..=yb`.
    Rect {
        xa: u32,
        xb: u32,
        ya: u32,
        yb: u32,
    },
    Ellipse(EllipseRows),
}

impl Fill {
    /// The image rows covered (inclusive).
    fn rows(&self) -> (u32, u32) {
        match self {
            Fill::Rect { ya, yb, .. } => (*ya, *yb),
            Fill::Ellipse(e) => (e.ya, e.yb),
        }
    }
}

/// Rows `y0..y1` (pixels; `y0` a multiple of [`BLOCK_EDGE`]) of the coverage, with their
/// blocks' masks and candidates, filled by one task.
struct Band<'a> {
    y0: u32,
    y1: u32,
    blocks_x: u32,
    masks: &'a mut [u64],
    cands: &'a mut [Candidates],
}

impl Band<'_> {
    /// Covers, in block row `by` (inside the band), each row `r` with bit `r` in `live` from
    /// pixel `spans[r].0` to `spans[r].1`, for instance `id`: one mask update per block.
    fn fill_block_row(&mut self, by: u32, spans: &[(u32, u32); BLOCK_EDGE as usize], live: u8, id: u32) {
        let (mut lo, mut hi) = (u32::MAX, 0);
        for (r, &(xa, xb)) in spans.iter().enumerate() {
            if (live >> r) & 1 != 0 {
                lo = lo.min(xa);
                hi = hi.max(xb);
            }
        }
        if lo > hi {
            return;
        }
        let row0 = (by - self.y0 / BLOCK_EDGE) * self.blocks_x;
        for bx in lo / BLOCK_EDGE..=hi / BLOCK_EDGE {
            let (x0, x1) = (bx * BLOCK_EDGE, bx * BLOCK_EDGE + BLOCK_EDGE - 1);
            let mut mask = 0u64;
            for (r, &(xa, xb)) in spans.iter().enumerate() {
                if (live >> r) & 1 == 0 || xb < x0 || xa > x1 {
                    continue;
                }
                let (c0, c1) = (xa.max(x0) - x0, xb.min(x1) - x0);
                mask |= ((0xffu64 >> (7 - c1)) & (0xffu64 << c0)) << (8 * r);
            }
            let i = (row0 + bx) as usize;
            if mask != 0 {
                if let (Some(m), Some(c)) = (self.masks.get_mut(i), self.cands.get_mut(i)) {
                    *m |= mask;
                    c.add(id);
                }
            }
        }
    }

    /// Covers pixels `xa..=xb` of row `y` for instance `id`.
    #[cfg(test)]
    fn fill_row(&mut self, y: u32, xa: u32, xb: u32, id: u32) {
        self.fill_rows(y, y, xa, xb, id);
    }

    /// Covers pixels `xa..=xb` of rows `ya..=yb` (inside the band) for instance `id`, one
    /// mask update per block.
    fn fill_rows(&mut self, ya: u32, yb: u32, xa: u32, xb: u32, id: u32) {
        let first = self.y0 / BLOCK_EDGE;
        for by in ya / BLOCK_EDGE..=yb / BLOCK_EDGE {
            let r0 = ya.max(by * BLOCK_EDGE) - by * BLOCK_EDGE;
            let r1 = yb.min(by * BLOCK_EDGE + BLOCK_EDGE - 1) - by * BLOCK_EDGE;
            // One byte per row: the rows r0..=r1.
            let rows = (u64::MAX >> (56 - 8 * r1)) & (u64::MAX << (8 * r0));
            for bx in xa / BLOCK_EDGE..=xb / BLOCK_EDGE {
                let c0 = xa.max(bx * BLOCK_EDGE) - bx * BLOCK_EDGE;
                let c1 = xb.min(bx * BLOCK_EDGE + BLOCK_EDGE - 1) - bx * BLOCK_EDGE;
                let cols = (0xffu64 >> (7 - c1)) & (0xffu64 << c0);
                let i = ((by - first) * self.blocks_x + bx) as usize;
                if let (Some(m), Some(c)) = (self.masks.get_mut(i), self.cands.get_mut(i)) {
                    *m |= rows & (cols * 0x0101_0101_0101_0101);
                    c.add(id);
                }
            }
        }
    }
}

/// The pixel range `[lo, hi]` (clamped to `0..n`) of pixels whose squares meet `[a, b]`
/// grown by the margin; `None` when empty.
fn pixels(a: f64, b: f64, n: u32) -> Option<(u32, u32)> {
    pixel_range(a, b, n, false)
}

/// [`pixels`], or with `centres` the range of pixels whose centres (pixel `x`'s is
/// `x + 0.5`) lie in `[a, b]` grown by the margin.
fn pixel_range(a: f64, b: f64, n: u32, centres: bool) -> Option<(u32, u32)> {
    if n == 0 {
        return None;
    }
    if a.is_nan() || b.is_nan() {
        return Some((0, n - 1));
    }
    // Squares: x from ⌊a − margin⌋ to ⌊b + margin⌋. Centres: x from ⌈a − margin − 0.5⌉
    // to ⌊b + margin − 0.5⌋.
    let shift = if centres { 0.5 } else { 0.0 };
    let (a, b) = (a - MARGIN - shift, b + MARGIN - shift);
    if b < 0.0 {
        return None;
    }
    // Clamped into the image first, where truncation is the floor: ⌊max(x, 0)⌋ =
    // max(⌊x⌋, 0) and ⌊min(x, n − 1)⌋ = min(⌊x⌋, n − 1).
    let lo = a.clamp(0.0, f64::from(n));
    let hi = b.min(f64::from(n) - 1.0);
    // SAFETY: both are finite (NaN was handled above), non-negative and at most `n`, so
    // they fit a u32. PERF: Rust's saturating `as` conversion, and a floor made of it,
    // were a third of the coverage's time.
    let (lo_t, hi) = unsafe { (lo.to_int_unchecked::<u32>(), hi.to_int_unchecked::<u32>()) };
    let lo = if centres && f64::from(lo_t) < lo { lo_t + 1 } else { lo_t };
    (lo <= hi).then_some((lo, hi))
}

/// A projected ellipse prepared for filling row by row: `G(sx, sy) ≤ 0` with the
/// symmetric matrix `K` over `(1, sx, sy)`. The chord at screen height `y` has its centre
/// at `−(k12 y + k01)/k11` and half-width `sqrt(D(y))/k11` with `D(y) = a y² + 2 b y + c`
/// (`a < 0` for an ellipse).
#[derive(Clone, Copy, Debug)]
struct EllipseRows {
    /// Image rows covered.
    ya: u32,
    yb: u32,
    k01: f64,
    k12: f64,
    r11: f64,
    a: f64,
    b: f64,
    c: f64,
    /// Extent in sy.
    y_lo: f64,
    y_hi: f64,
    /// Heights of the leftmost and rightmost points, and their image x.
    yl: f64,
    yr: f64,
    left_most: f64,
    right_most: f64,
    /// Image x of screen x: `px0 + px1 · sx`; screen y of image row position: `sy0 + sy1 · py`.
    px0: f64,
    px1: f64,
    sy0: f64,
    sy1: f64,
    width: u32,
}

impl EllipseRows {
    fn new(k: &[[f64; 3]; 3], proj: &Projection) -> Option<Self> {
        let [[k00, k01, k02], [_, k11, k12], [_, _, k22]] = *k;
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
        let (y_lo, y_hi) = roots(b, c)?;
        let (x_lo, x_hi) = roots(k12 * k02 - k22 * k01, k02 * k02 - k22 * k00)?;
        let (px1, px0) = (0.5 * proj.width / proj.half_w, 0.5 * proj.width);
        let (ya, yb) = pixels(proj.py(y_hi), proj.py(y_lo), proj.height as u32)?;
        Some(Self {
            ya,
            yb,
            k01,
            k12,
            r11: 1.0 / k11,
            a,
            b,
            c,
            y_lo,
            y_hi,
            yl: -(k12 * x_lo + k02) / k22,
            yr: -(k12 * x_hi + k02) / k22,
            left_most: px0 + px1 * x_lo,
            right_most: px0 + px1 * x_hi,
            px0,
            px1,
            sy0: proj.half_h,
            sy1: -2.0 * proj.half_h / proj.height,
            width: proj.width as u32,
        })
    }

    /// Fills rows `ya..=yb` (within the ellipse's rows and the band's) of `band`: the
    /// pixels whose squares (or, with `centres`, whose centres) come within [`MARGIN`].
    /// `simd`: with the AVX2 row kernel (the same spans as the scalar one, bit for bit).
    fn fill(&self, band: &mut Band, ya: u32, yb: u32, id: u32, centres: bool, simd: bool) {
        #[cfg(target_arch = "x86_64")]
        if simd {
            // SAFETY: `simd` is set only where AVX2 was detected.
            return unsafe { self.fill_avx2(band, ya, yb, id, centres) };
        }
        let _ = simd;
        self.fill_with::<ScalarRows>(band, ya, yb, id, centres);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn fill_avx2(&self, band: &mut Band, ya: u32, yb: u32, id: u32, centres: bool) {
        self.fill_with::<Avx2Rows>(band, ya, yb, id, centres);
    }

    /// [`EllipseRows::fill`] with the row kernel `K`: four rows at a time (aligned to four,
    /// so each group lies in one block row), each block row's spans handed over together
    /// (PERF: one mask update per block; row by row, the updates were a third of the fill).
    #[inline(always)]
    fn fill_with<K: RowKernel>(&self, band: &mut Band, ya: u32, yb: u32, id: u32, centres: bool) {
        let mut spans = [(0u32, 0u32); BLOCK_EDGE as usize];
        let mut live = 0u8;
        let mut y = ya & !3;
        while y <= yb {
            let r = K::rows4(self, y, centres);
            for i in 0..4u32 {
                let row = y + i;
                if (r.ok >> i) & 1 != 0 && (ya..=yb).contains(&row) {
                    let k = (row % BLOCK_EDGE) as usize;
                    spans[k] = (r.lo[i as usize], r.hi[i as usize]);
                    live |= 1 << k;
                }
            }
            let last = y + 3;
            if last % BLOCK_EDGE == BLOCK_EDGE - 1 || last >= yb {
                band.fill_block_row(y / BLOCK_EDGE, &spans, live, id);
                live = 0;
            }
            y += 4;
        }
    }

    /// The spans of image rows `y..y + 4`, in scalar code (the reference for the AVX2
    /// kernel, which does the same operations in the same order; `min`/`max` are written as
    /// the SIMD instructions behave: the second operand unless the first is smaller or
    /// larger, so NaNs go the same way in both). Each row's span is [`pixel_range`] of its
    /// extent, as for every other region.
    fn rows4_scalar(&self, y: u32, centres: bool) -> Rows4 {
        let e = self;
        let min = |a: f64, b: f64| if a < b { a } else { b };
        let max = |a: f64, b: f64| if a > b { a } else { b };
        // The image rows' extent that counts: the square, or the centre.
        let (above, below) = if centres { (-0.5 + MARGIN, 0.5 + MARGIN) } else { (MARGIN, 1.0 + MARGIN) };
        let mut out = Rows4 { lo: [0; 4], hi: [0; 4], ok: 0 };
        for i in 0..4 {
            let yf = f64::from(y + i as u32);
            // The row's band in sy (sy falls as the image row grows), within the ellipse.
            let top = min(e.sy0 + e.sy1 * (yf - above), e.y_hi);
            let bottom = max(e.sy0 + e.sy1 * (yf + below), e.y_lo);
            // The chords at both ends of the band.
            let d = |y: f64| max(e.a * y * y + 2.0 * e.b * y + e.c, 0.0);
            let (h0, h1) = (d(bottom).sqrt() * e.r11, d(top).sqrt() * e.r11);
            let (m0, m1) = (-(e.k12 * bottom + e.k01) * e.r11, -(e.k12 * top + e.k01) * e.r11);
            let (l0, r0) = (e.px0 + e.px1 * (m0 - h0), e.px0 + e.px1 * (m0 + h0));
            let (l1, r1) = (e.px0 + e.px1 * (m1 - h1), e.px0 + e.px1 * (m1 + h1));
            // The left edge is convex and the right edge concave in sy: over the band they
            // reach out furthest at the extreme points, or else at the band's ends.
            let left = if bottom <= e.yl && e.yl <= top { e.left_most } else { min(l0, l1) };
            let right = if bottom <= e.yr && e.yr <= top { e.right_most } else { max(r0, r1) };
            // (A NaN bound keeps the row, as the kernel's unordered compare does.)
            let rows = bottom.partial_cmp(&top) != Some(std::cmp::Ordering::Greater);
            if let Some((lo, hi)) = rows.then(|| pixel_range(left, right, e.width, centres)).flatten() {
                out.lo[i] = lo;
                out.hi[i] = hi;
                out.ok |= 1 << i;
            }
        }
        out
    }

    /// [`EllipseRows::rows4_scalar`] on four lanes.
    #[cfg(target_arch = "x86_64")]
    #[inline]
    #[target_feature(enable = "avx2")]
    fn rows4_avx2(&self, y: u32, centres: bool) -> Rows4 {
        use std::arch::x86_64::*;
        let e = self;
        let s = _mm256_set1_pd;
        let (above, below) = if centres { (-0.5 + MARGIN, 0.5 + MARGIN) } else { (MARGIN, 1.0 + MARGIN) };
        let shift = if centres { 0.5 } else { 0.0 };
        let n = f64::from(e.width);
        let yf = _mm256_add_pd(s(f64::from(y)), _mm256_set_pd(3.0, 2.0, 1.0, 0.0));
        let (add, sub, mul) = (_mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd);
        let top = _mm256_min_pd(add(s(e.sy0), mul(s(e.sy1), sub(yf, s(above)))), s(e.y_hi));
        let bottom = _mm256_max_pd(add(s(e.sy0), mul(s(e.sy1), add(yf, s(below)))), s(e.y_lo));
        let d = |y: __m256d| _mm256_max_pd(add(add(mul(mul(s(e.a), y), y), mul(s(2.0 * e.b), y)), s(e.c)), _mm256_setzero_pd());
        let (h0, h1) = (mul(_mm256_sqrt_pd(d(bottom)), s(e.r11)), mul(_mm256_sqrt_pd(d(top)), s(e.r11)));
        let neg = |v: __m256d| _mm256_xor_pd(v, s(-0.0));
        let (m0, m1) = (mul(neg(add(mul(s(e.k12), bottom), s(e.k01))), s(e.r11)), mul(neg(add(mul(s(e.k12), top), s(e.k01))), s(e.r11)));
        let (l0, r0) = (add(s(e.px0), mul(s(e.px1), sub(m0, h0))), add(s(e.px0), mul(s(e.px1), add(m0, h0))));
        let (l1, r1) = (add(s(e.px0), mul(s(e.px1), sub(m1, h1))), add(s(e.px0), mul(s(e.px1), add(m1, h1))));
        let le = |a: __m256d, b: __m256d| _mm256_cmp_pd::<_CMP_LE_OQ>(a, b);
        let at_l = _mm256_and_pd(le(bottom, s(e.yl)), le(s(e.yl), top));
        let at_r = _mm256_and_pd(le(bottom, s(e.yr)), le(s(e.yr), top));
        let left = _mm256_blendv_pd(_mm256_min_pd(l0, l1), s(e.left_most), at_l);
        let right = _mm256_blendv_pd(_mm256_max_pd(r0, r1), s(e.right_most), at_r);
        let (a, b) = (sub(sub(left, s(MARGIN)), s(shift)), sub(add(right, s(MARGIN)), s(shift)));
        let lo = _mm256_min_pd(_mm256_max_pd(a, _mm256_setzero_pd()), s(n));
        let hi = _mm256_min_pd(b, s(n - 1.0));
        let (lo_t, hi_t) = (_mm256_cvttpd_epi32(lo), _mm256_cvttpd_epi32(hi));
        // (The comparison's 64-bit lanes narrowed to 32 bits: its low halves, in order.)
        let narrow = |m: __m256d| {
            let m = _mm256_castpd_si256(m);
            _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(m, _mm256_set_epi32(7, 5, 3, 1, 6, 4, 2, 0)))
        };
        let lo_i = if centres {
            // `lo_t + 1` where the truncation fell below `lo` (all ones is −1).
            _mm_sub_epi32(lo_t, narrow(_mm256_cmp_pd::<_CMP_LT_OQ>(_mm256_cvtepi32_pd(lo_t), lo)))
        } else {
            lo_t
        };
        let nan = _mm256_cmp_pd::<_CMP_UNORD_Q>(left, right);
        let nan32 = narrow(nan);
        let fits = _mm_andnot_si128(_mm_cmpgt_epi32(lo_i, hi_t), narrow(_mm256_cmp_pd::<_CMP_GE_OQ>(b, _mm256_setzero_pd())));
        let rows = _mm256_cmp_pd::<_CMP_NGT_UQ>(bottom, top);
        let ok = _mm_and_si128(narrow(rows), _mm_or_si128(nan32, fits));
        // Rows without a span read as (0, 0), as the scalar kernel leaves them.
        let lo_i = _mm_and_si128(_mm_blendv_epi8(lo_i, _mm_setzero_si128(), nan32), ok);
        let hi_t = _mm_and_si128(_mm_blendv_epi8(hi_t, _mm_set1_epi32(e.width as i32 - 1), nan32), ok);
        let mut out = Rows4 { lo: [0; 4], hi: [0; 4], ok: _mm_movemask_ps(_mm_castsi128_ps(ok)) as u8 };
        // SAFETY: each array holds four u32 (16 bytes); unaligned stores.
        unsafe {
            _mm_storeu_si128(out.lo.as_mut_ptr().cast(), lo_i);
            _mm_storeu_si128(out.hi.as_mut_ptr().cast(), hi_t);
        }
        out
    }
}

/// The spans of four image rows: row `i` covers pixels `lo[i]..=hi[i]` when bit `i` of `ok`
/// is set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rows4 {
    lo: [u32; 4],
    hi: [u32; 4],
    ok: u8,
}

/// A way to compute [`Rows4`].
trait RowKernel {
    fn rows4(e: &EllipseRows, y: u32, centres: bool) -> Rows4;
}

/// The scalar row kernel.
struct ScalarRows;
impl RowKernel for ScalarRows {
    #[inline(always)]
    fn rows4(e: &EllipseRows, y: u32, centres: bool) -> Rows4 {
        e.rows4_scalar(y, centres)
    }
}

/// The AVX2 row kernel (only called from `target_feature(enable = "avx2")` code).
#[cfg(target_arch = "x86_64")]
struct Avx2Rows;
#[cfg(target_arch = "x86_64")]
impl RowKernel for Avx2Rows {
    #[inline(always)]
    fn rows4(e: &EllipseRows, y: u32, centres: bool) -> Rows4 {
        // SAFETY: only `EllipseRows::fill_avx2` uses this kernel, and it runs with AVX2.
        unsafe { e.rows4_avx2(y, centres) }
    }
}

fn projection(cam: &Camera) -> Option<Projection> {
    let v = cam.basis();
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
        let mut c = Coverage { by0: 0, blocks_x: 3, masks: vec![0; 6], cands: vec![Candidates::default(); 6] };
        c.all().fill_rows(3, 10, 6, 17, 7);
        c.all().fill_row(12, 0, 0, 9);
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
            c.all().fill_row(0, 0, 0, id);
        }
        assert_eq!(c.candidates(0, 0), Some(&[7, 10, 11, 12][..]));
        c.all().fill_row(1, 0, 0, 14);
        assert_eq!(c.candidates(0, 0), None, "too many to list");
        c.all().fill_row(1, 0, 0, 15);
        assert_eq!(c.candidates(0, 0), None);
        assert_eq!(c.candidates(3, 0), None, "outside");
        assert_eq!(pixels(2.6, 5.1, 20), Some((2, 5)));
        assert_eq!(pixels(2.2, 5.8, 20), Some((1, 6)));
        assert_eq!(pixels(-9.0, 50.0, 20), Some((0, 19)));
        assert_eq!(pixels(30.0, 50.0, 20), None);
        assert_eq!(pixels(-30.0, -5.0, 20), None);
        // Centres: pixel x counts when x + 0.5 lies within the margin of [a, b].
        assert_eq!(pixel_range(2.6, 5.1, 20, true), Some((2, 4)));
        assert_eq!(pixel_range(2.2, 5.8, 20, true), Some((2, 5)));
        assert_eq!(pixel_range(3.75, 3.75, 20, true), Some((3, 3)));
        assert_eq!(pixel_range(3.76, 4.0, 20, true), None);
        assert_eq!(pixel_range(-9.0, 50.0, 20, true), Some((0, 19)));
    }

    /// Random spheres (ellipsoids under translate·rotate·scale) seen by random cameras at
    /// a few image sizes, as prepared ellipses.
    fn random_ellipses(seed: u64) -> Vec<(EllipseRows, Projection)> {
        use glam::{Affine3A, Quat, Vec3};
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let mut out = Vec::new();
        for k in 0..600 {
            let (w, h) = [(512, 384), (37, 23), (1024, 768), (1, 1)][k % 4];
            let eye = Vec3::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0), rng.random_range(5.0..30.0));
            let desc = lucent_scene::CameraDesc {
                eye,
                look_at: Vec3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), 0.0),
                up: Vec3::Y,
                vfov_deg: rng.random_range(10.0..120.0),
                ortho_height: None,
            };
            let Some(proj) = projection(&Camera::new(&desc, w, h)) else { continue };
            let scale = Vec3::new(rng.random_range(0.01..4.0), rng.random_range(0.01..4.0), rng.random_range(0.01..4.0));
            let q =
                Quat::from_euler(glam::EulerRot::XYZ, rng.random_range(0.0..6.3), rng.random_range(0.0..6.3), rng.random_range(0.0..6.3));
            let t = Vec3::new(rng.random_range(-12.0..12.0), rng.random_range(-12.0..12.0), rng.random_range(-12.0..12.0));
            let inst = lucent_accel::Instance::new(0, Affine3A::from_scale_rotation_translation(scale, q, t));
            if let Some(Region::Ellipse(k)) = ellipse(&inst, &proj) {
                if let Some(e) = EllipseRows::new(&k, &proj) {
                    out.push((e, proj));
                }
            }
        }
        out
    }

    /// The AVX2 row kernel gives the scalar kernel's spans bit for bit, on every row of
    /// random ellipses and a few rows past them, for squares and centres, and on ellipses
    /// whose numbers are not finite.
    #[test]
    fn row_kernels_agree() {
        #[cfg(target_arch = "x86_64")]
        {
            if !lucent_accel::simd::avx2() {
                eprintln!("no AVX2 here: only the scalar kernel runs");
                return;
            }
            let mut ellipses: Vec<EllipseRows> = random_ellipses(11).into_iter().map(|(e, _)| e).collect();
            assert!(ellipses.len() > 300, "{} ellipses", ellipses.len());
            let (e0, _) = random_ellipses(12).into_iter().next().expect("an ellipse");
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e300] {
                ellipses.push(EllipseRows { a: bad, ..e0 });
                ellipses.push(EllipseRows { k12: bad, y_hi: bad, ..e0 });
                ellipses.push(EllipseRows { px1: bad, yl: bad, ..e0 });
                ellipses.push(EllipseRows { r11: bad, left_most: bad, right_most: -bad, ..e0 });
            }
            let mut rows = 0;
            for e in &ellipses {
                for centres in [false, true] {
                    let mut y = e.ya.saturating_sub(8) & !3;
                    while y <= e.yb.saturating_add(8) {
                        // SAFETY: AVX2 was detected above.
                        let simd = unsafe { e.rows4_avx2(y, centres) };
                        assert_eq!(simd, e.rows4_scalar(y, centres), "rows {y}.. of {e:?}, centres {centres}");
                        y += 4;
                        rows += 4;
                    }
                }
            }
            assert!(rows > 10_000, "{rows} rows");
        }
    }

    /// Both row kernels fill the same masks and candidates, and what the fill marks holds
    /// every pixel whose centre (or square) the ellipse's span reaches: a NaN span covers
    /// the whole row.
    #[test]
    fn ellipse_fills_agree_and_nan_rows_cover_everything() {
        for (e, proj) in random_ellipses(13).iter().take(150) {
            let (w, h) = (proj.width as u32, proj.height as u32);
            let bx = w.div_ceil(BLOCK_EDGE);
            let n = (bx * h.div_ceil(BLOCK_EDGE)) as usize;
            for centres in [false, true] {
                let mut got = Vec::new();
                for simd in [false, lucent_accel::simd::avx2()] {
                    let mut c = Coverage { by0: 0, blocks_x: bx, masks: vec![0; n], cands: vec![Candidates::default(); n] };
                    e.fill(&mut c.all(), e.ya, e.yb, 3, centres, simd);
                    got.push(c);
                }
                assert_eq!(got[0].masks, got[1].masks);
                assert_eq!(
                    got[0].cands.iter().map(|c| (c.count, c.ids)).collect::<Vec<_>>(),
                    got[1].cands.iter().map(|c| (c.count, c.ids)).collect::<Vec<_>>()
                );
            }
        }
        let (e0, proj) = random_ellipses(14).into_iter().next().expect("an ellipse");
        let e = EllipseRows { px1: f64::NAN, ya: 0, yb: proj.height as u32 - 1, y_lo: f64::NEG_INFINITY, y_hi: f64::INFINITY, ..e0 };
        for simd in [false, true] {
            let (w, h) = (proj.width as u32, proj.height as u32);
            let bx = w.div_ceil(BLOCK_EDGE);
            let n = (bx * h.div_ceil(BLOCK_EDGE)) as usize;
            let mut c = Coverage { by0: 0, blocks_x: bx, masks: vec![0; n], cands: vec![Candidates::default(); n] };
            let simd = simd && lucent_accel::simd::avx2();
            e.fill(&mut c.all(), 0, h - 1, 1, true, simd);
            assert_eq!(c.count(), u64::from(w * h), "simd {simd}");
        }
    }
}
