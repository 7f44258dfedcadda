//! A denoiser for path-traced and VPL images: the edge-avoiding à-trous wavelet filter of
//! Dammertz, Sewtz, Hanika and Lensch ("Edge-Avoiding À-Trous Wavelet Transform for fast
//! Global Illumination Filtering", HPG 2010), with the edge-stopping functions of SVGF's
//! spatial filter (Schied et al., "Spatiotemporal Variance-Guided Filtering", HPG 2017):
//! luminance differences measured against the local standard deviation of the noise
//! (estimated from the image itself: the variance over each pixel's 5 × 5 neighbourhood
//! of the same surface, then filtered along with the colour), depth differences against
//! the depth's own slope, and normals by `max(0, n·n')^σn`.
//!
//! The colour is demodulated first: what reflects at the first surface (past mirrors and
//! glass: `render_aovs` follows them) is divided by its albedo (and its own emission kept
//! apart), filtered, and multiplied back, so textures stay sharp ([`crate::film::Aovs`]
//! gives albedo, normal, distance and emission). Pixels
//! that see no surface or an emitter pass through. Surfaces darker than
//! [`crate::aov::FILTER_ALBEDO_MIN`] (black glossy plastic, dark metal: their
//! light is not proportional to their albedo) are filtered in radiance, among themselves
//! only (they were passed through until stop 47: on the BART kitchen, a third of the
//! pixels, and most of the denoised error).
//!
//! Outliers first: a few paths of rare, high contribution (fireflies) dominate a
//! low-sample image's error, and an edge-avoiding filter refuses to average them (their
//! luminance is far from their neighbours'). Their light is neither dropped nor kept in
//! place: a pixel brighter than its neighbourhood's mean by more than
//! [`DenoiseSettings::outlier_sigmas`] standard deviations keeps that bound and shares the
//! rest, in radiance, with the pixels of its surface within
//! [`DenoiseSettings::outlier_radius`] (a conservative splat, in the spirit of the outlier
//! rejection of DeCoro, Weyrich and Rusinkiewicz, "Density-based Outlier Rejection in Monte
//! Carlo Rendering", 2010, which removes the light instead). At 4 samples on Sponza this
//! halved the denoised relMSE (0.0194 to 0.0114).
//!
//! Each of the `iterations` passes is a 5 × 5 B3-spline kernel (1/16, 1/4, 3/8, 1/4, 1/16)
//! with holes: pass `i` takes every `2^i`-th pixel, so five passes reach 62 pixels out.
//!
//! Speed: the guides, colour and weights are kept in planes (one array per quantity), and
//! every stage is written on eight-pixel lanes ([`F8`]) compiled twice, for the baseline
//! CPU and with AVX2 and FMA, which give the same answers (tested). A pass computes each
//! pair's weight once (the weight is symmetric: twelve forward taps per pixel, read back
//! for the twelve backward ones), and `exp` is a polynomial (`exp_neg`). The first
//! version, pixel by pixel with `Vec3`s and the library's `exp`, is kept as the reference
//! the tests compare with (`denoise/reference.rs`): on 2 threads at 512 × 384 it took
//! 560-910 ms (Cornell box, Sponza, kitchen at 4 samples), of which 130-190 ms spreading
//! outliers; this one takes 85, 177 and 176 ms (`bench vpl`, stop 48; on one thread the
//! Sponza image took 174 ms against the reference's 754 in the same run). The outliers'
//! sharing pixels are found once, kept as bits, and reused to hand out their light.

// Lane and channel loops index several arrays at once.
#![allow(clippy::needless_range_loop)]

#[cfg(doc)]
use crate::aov::FILTER_ALBEDO_MIN;
use crate::aov::{dark as is_dark, demodulating, Layers};
use crate::color::LUMINANCE;
use crate::film::{Aovs, Film};
use crate::lanes::{Real, ROUND};
use glam::Vec3;
use lucent_accel::simd::{F8, LANES, M8};
use rayon::prelude::*;

#[cfg(test)]
mod reference;
pub mod regression;

/// The denoiser's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DenoiseSettings {
    /// À-trous passes (kernel steps 1, 2, 4, ...).
    pub iterations: u32,
    /// Luminance edge-stopping: differences of `sigma_luminance` standard deviations of
    /// the noise weigh `1/e` (8: on the Cornell box at 512 × 384, 4 samples denoised, the
    /// relMSE against 256-sample path tracing was 0.0022 at 4, 0.0017 at 8 and 0.0019 at
    /// 16; six passes instead of five did not help).
    pub sigma_luminance: f32,
    /// Normal edge-stopping exponent (on a surface's own kind: see the module's notes). 16:
    /// at 4 samples, denoised relMSE on Sponza / the kitchen 0.0081 / 0.0315; 128 (SVGF's):
    /// 0.0091 / 0.0321; 32: 0.0082 / 0.0317; 8: 0.0082 / 0.0314. (A steep exponent also
    /// refuses neighbours on one curved surface whose interpolated normals differ a
    /// little.)
    pub sigma_normal: f32,
    /// Depth edge-stopping: differences of `sigma_depth` times what the depth's slope
    /// predicts weigh `1/e`.
    pub sigma_depth: f32,
    /// Outliers: a pixel brighter than its 5 × 5 neighbours' mean (their brightest left
    /// out) by more than this many of their standard deviations gives the excess to its
    /// surface (0: off). 2: at 4 samples, denoised relMSE 0.0116 on Sponza and 0.0387 on
    /// the kitchen, against 0.0123 and 0.0382 at 3 (radius 6).
    pub outlier_sigmas: f32,
    /// How far outliers' excess light goes, in pixels (12: Sponza 0.0114, the kitchen
    /// 0.0321; 6: 0.0116, 0.0387; 20: 0.0113, 0.0321).
    pub outlier_radius: u32,
}

impl Default for DenoiseSettings {
    fn default() -> Self {
        Self { iterations: 5, sigma_luminance: 8.0, sigma_normal: 16.0, sigma_depth: 1.0, outlier_sigmas: 2.0, outlier_radius: 12 }
    }
}

/// The B3 spline's weights at offsets -2..=2.
const B3: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// The twelve taps of a 5 × 5 kernel that come after its centre in row-major order (the
/// other twelve are their mirror images): offsets in kernel steps.
const FORWARD: [(i32, i32); 12] = [(1, 0), (2, 0), (-2, 1), (-1, 1), (0, 1), (1, 1), (2, 1), (-2, 2), (-1, 2), (0, 2), (1, 2), (2, 2)];

/// The guides in planes, one entry per pixel (row-major).
struct Guides {
    w: usize,
    h: usize,
    /// 0: no surface to filter (background, emitters, non-finite colour: passes
    /// through); 1: a surface filtered demodulated; 2: a dark one, filtered in radiance
    /// among its own kind (see [`FILTER_ALBEDO_MIN`]).
    kind: Vec<f32>,
    /// Shading normal.
    n: [Vec<f32>; 3],
    /// Distance.
    z: Vec<f32>,
    /// The distance's slope per pixel along x and y (toward the same surface).
    dz: [Vec<f32>; 2],
}

/// Lanes of eight pixels' guides.
#[derive(Clone, Copy)]
struct G8 {
    kind: F8,
    n: [F8; 3],
    z: F8,
}

/// The lanes of `row` from column `x0` on, those outside columns `lo..hi` zero.
#[inline(always)]
fn load_at(row: &[f32], x0: isize, lo: isize, hi: isize) -> F8 {
    if x0 >= lo && x0 + LANES as isize <= hi {
        return F8::load(row, x0 as usize);
    }
    let mut r = [0.0; LANES];
    for (k, v) in r.iter_mut().enumerate() {
        let x = x0 + k as isize;
        if x >= lo && x < hi {
            *v = row[x as usize];
        }
    }
    F8(r)
}

/// The lanes of plane `p` (rows of `w`) in row `y` from column `x0` on (outside the
/// image: zero).
#[inline(always)]
fn plane_at(p: &[f32], w: usize, y: usize, x0: isize) -> F8 {
    load_at(&p[y * w..(y + 1) * w], x0, 0, w as isize)
}

/// Adds the first `cnt` lanes of `v` to `row` from column `x0` on.
#[inline(always)]
fn add_lanes(row: &mut [f32], x0: usize, cnt: usize, v: F8) {
    if cnt == LANES {
        (F8::load(row, x0) + v).store(row, x0);
    } else {
        for k in 0..cnt {
            row[x0 + k] += v.0[k];
        }
    }
}

/// Stores the first `cnt` lanes of `v` into `row` from column `x0` on.
#[inline(always)]
fn store_lanes(row: &mut [f32], x0: usize, cnt: usize, v: F8) {
    if cnt == LANES {
        v.store(row, x0);
    } else {
        row[x0..x0 + cnt].copy_from_slice(&v.0[..cnt]);
    }
}

#[inline(always)]
fn abs8(a: F8) -> F8 {
    F8(a.0.map(|v| f32::from_bits(v.to_bits() & 0x7fff_ffff)))
}

#[inline(always)]
fn mask_to(m: M8, v: F8) -> F8 {
    F8::splat(0.0).blend(m, v)
}

/// `e^-x` for `x` in [0, 30] (other lanes: clamped to it), within 2e-6 of the library's
/// (relative; most of it the rounding of `x log2 e` in `f32`, up to 43 · 2^-24):
/// `2^y` with `y = -x log2 e` split as `n + f`, `n` the nearest integer (rounded by
/// adding and taking away 1.5 · 2^23, as the Phong power does) and `|f| <= 1/2`, `2^n`
/// built in the exponent bits ([`Real::exp2i`]) and `2^f` by its Taylor polynomial of
/// degree 6 (remainder below (ln 2 / 2)^7 / 7! ≈ 1.2e-7; the Phong power's degree 5 would
/// be 2.5e-6). Only float and integer lane operations: no conversion, so it vectorizes.
#[inline(always)]
fn exp_neg(x: F8) -> F8 {
    const C: [f32; 7] = [1.0, std::f32::consts::LN_2, 0.240_226_5, 0.055_504_11, 0.009_618_129, 0.001_333_355_8, 0.000_154_035_3];
    let mut r = [0.0; LANES];
    for k in 0..LANES {
        let v = x.0[k];
        let v = if v > 0.0 { v } else { 0.0 };
        let v = if v < 30.0 { v } else { 30.0 };
        let y = -v * std::f32::consts::LOG2_E;
        let n = (y + ROUND) - ROUND;
        let f = y - n;
        let p = C[0] + f * (C[1] + f * (C[2] + f * (C[3] + f * (C[4] + f * (C[5] + f * C[6])))));
        r[k] = p * Real::exp2i(n);
    }
    F8(r)
}

/// `max(c, 0)^e` lane by lane: by squaring for an integer exponent (`e_int >= 0`), else
/// `powf`.
#[inline(always)]
fn pow8(c: F8, e_int: i32, e: f32) -> F8 {
    let c = c.max(F8::splat(0.0));
    if e_int >= 0 {
        let (mut x, mut r, mut n) = (c, F8::splat(1.0), e_int as u32);
        while n > 0 {
            if n & 1 == 1 {
                r = r * x;
            }
            x = x * x;
            n >>= 1;
        }
        r
    } else {
        F8(c.0.map(|v| v.powf(e)))
    }
}

impl Guides {
    /// Lanes of row `y` from column `x0` (columns outside the image: no surface).
    #[inline(always)]
    fn load(&self, y: usize, x0: isize) -> G8 {
        let w = self.w;
        G8 {
            kind: plane_at(&self.kind, w, y, x0),
            n: [plane_at(&self.n[0], w, y, x0), plane_at(&self.n[1], w, y, x0), plane_at(&self.n[2], w, y, x0)],
            z: plane_at(&self.z, w, y, x0),
        }
    }
}

/// Least cosine between the normals of two pixels of one surface (25°).
const SAME_COS: f32 = 0.9;
/// Most relative difference of the distances of two pixels of one surface.
const SAME_DEPTH: f32 = 0.1;

/// Whether lanes of `b` lie on the surface of the lanes of `a` (the same kind, normals
/// within 25°, distances within 10%): the variance estimate's test ([`Guides::same`] is
/// its one-pixel form, the slopes').
#[inline(always)]
fn same8(a: &G8, b: &G8) -> M8 {
    let dot = a.n[0] * b.n[0] + a.n[1] * b.n[1] + a.n[2] * b.n[2];
    b.kind.ne(F8::splat(0.0)) & a.kind.eq(b.kind) & dot.gt(F8::splat(SAME_COS)) & abs8(a.z - b.z).lt(F8::splat(SAME_DEPTH) * a.z)
}

impl Guides {
    /// Whether pixel `j` lies on pixel `i`'s surface: [`same8`] for one pair, with the same
    /// arithmetic.
    #[inline]
    fn same(&self, i: usize, j: usize) -> bool {
        let dot = self.n[0][i] * self.n[0][j] + self.n[1][i] * self.n[1][j] + self.n[2][i] * self.n[2][j];
        self.kind[j] != 0.0 && self.kind[j] == self.kind[i] && dot > SAME_COS && (self.z[i] - self.z[j]).abs() < SAME_DEPTH * self.z[i]
    }
}

/// Builds the guides' planes. `valid(i)`: pixel `i` has a surface to filter; `dark(i)`: of
/// the dark kind.
fn guides(
    w: usize,
    h: usize,
    normal: &[Vec3],
    depth: &[f32],
    valid: impl Fn(usize) -> bool + Sync,
    dark: impl Fn(usize) -> bool + Sync,
) -> Guides {
    let n = w * h;
    let kind: Vec<f32> = (0..n)
        .into_par_iter()
        .map(|i| {
            if !valid(i) {
                0.0
            } else if dark(i) {
                2.0
            } else {
                1.0
            }
        })
        .collect();
    // Lanes of invalid pixels hold zeros (no NaN or infinity reaches the arithmetic).
    let kept = |i: usize, v: f32| if kind[i] == 0.0 { 0.0 } else { v };
    let planes = [0, 1, 2].map(|k| (0..n).into_par_iter().map(|i| kept(i, normal[i][k])).collect());
    let z = (0..n).into_par_iter().map(|i| kept(i, depth[i])).collect();
    Guides { w, h, kind, n: planes, z, dz: [vec![0.0; n], vec![0.0; n]] }
}

/// The guides of an image of `w` × `h` pixels from its AOVs, with the depth's slopes:
/// a pixel is filtered where it sees a surface that emits nothing (emitters pass through:
/// their light is not the albedo's to scale) and its colour is fine (`colour_ok`); dark
/// surfaces are filtered among themselves (see `FILTER_ALBEDO_MIN`).
fn aov_guides(w: usize, h: usize, aovs: &Aovs, colour_ok: impl Fn(usize) -> bool + Sync) -> Guides {
    let mut g = guides(
        w,
        h,
        &aovs.normal.pixels,
        &aovs.depth,
        |i| {
            let (nn, z) = (aovs.normal.pixels[i], aovs.depth[i]);
            z.is_finite() && z > 0.0 && nn != Vec3::ZERO && aovs.emission.pixels[i].max_element() <= 0.0 && colour_ok(i)
        },
        |i| is_dark(aovs.albedo.pixels[i]),
    );
    slopes(&mut g);
    g
}

/// The depth's slope (the smaller one-sided difference toward the same surface, 0 where
/// there is none), on the guides.
fn slopes(g: &mut Guides) {
    let (w, h) = (g.w, g.h);
    let slope = |i: usize, a: Option<usize>, b: Option<usize>| {
        let d = |j: Option<usize>| j.filter(|&j| g.same(i, j)).map(|j| (g.z[j] - g.z[i]).abs());
        match (d(a), d(b)) {
            (Some(p), Some(q)) => p.min(q),
            (Some(p), None) | (None, Some(p)) => p,
            (None, None) => 0.0,
        }
    };
    let d: Vec<(f32, f32)> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            if g.kind[i] == 0.0 {
                return (0.0, 0.0);
            }
            let (x, y) = (i % w, i / w);
            (slope(i, (x > 0).then(|| i - 1), (x + 1 < w).then_some(i + 1)), slope(i, (y > 0).then(|| i - w), (y + 1 < h).then_some(i + w)))
        })
        .collect();
    for (i, (a, b)) in d.into_iter().enumerate() {
        g.dz[0][i] = a;
        g.dz[1][i] = b;
    }
}

/// Runs `$body` (an expression over the listed arguments) through a function compiled
/// with AVX2 and FMA when `$simd`, else through the portable build.
macro_rules! lanes {
    ($simd:expr, |$($a:ident: $t:ty),*| $body:expr) => {{
        #[inline(always)]
        fn portable($($a: $t),*) {
            $body
        }
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        fn fast($($a: $t),*) {
            portable($($a),*)
        }
        #[cfg(target_arch = "x86_64")]
        if $simd {
            // SAFETY: `$simd` is true only where AVX2 and FMA were detected.
            unsafe { fast($($a),*) }
        } else {
            portable($($a),*)
        }
        #[cfg(not(target_arch = "x86_64"))]
        portable($($a),*)
    }};
}

/// Statistics of a pixel's 5 × 5 neighbours on its surface (row `y`, eight pixels from
/// `x0`), in luminance relative to the pixel's own (shifted, so that `f32` keeps the
/// variance of bright pixels): how many, their sum and sum of squares, and the largest.
/// With `centre`, the pixel itself counts.
#[inline(always)]
fn neighbour_stats(g: &Guides, l: &[f32], y: usize, x0: usize, centre: bool) -> (F8, F8, F8, F8) {
    if x0 >= 2 && x0 + LANES + 2 <= g.w {
        neighbour_stats_at::<false>(g, l, y, x0, centre)
    } else {
        neighbour_stats_at::<true>(g, l, y, x0, centre)
    }
}

/// [`neighbour_stats`]; without `EDGE`, every neighbour's column lies inside the image.
#[inline(always)]
fn neighbour_stats_at<const EDGE: bool>(g: &Guides, l: &[f32], y: usize, x0: usize, centre: bool) -> (F8, F8, F8, F8) {
    let (w, h) = (g.w, g.h);
    let rows = |yy: usize| yy * w..(yy + 1) * w;
    let ri = rows(y);
    let xi = x0 as isize;
    let gi = G8 {
        kind: ld::<EDGE>(&g.kind[ri.clone()], xi),
        n: [ld::<EDGE>(&g.n[0][ri.clone()], xi), ld::<EDGE>(&g.n[1][ri.clone()], xi), ld::<EDGE>(&g.n[2][ri.clone()], xi)],
        z: ld::<EDGE>(&g.z[ri.clone()], xi),
    };
    let li = ld::<EDGE>(&l[ri], xi);
    let (mut k, mut m1, mut m2, mut top) = (F8::splat(0.0), F8::splat(0.0), F8::splat(0.0), F8::splat(f32::NEG_INFINITY));
    for yy in y.saturating_sub(2)..(y + 3).min(h) {
        let rj = rows(yy);
        let (kind, n, z, lj) =
            (&g.kind[rj.clone()], [&g.n[0][rj.clone()], &g.n[1][rj.clone()], &g.n[2][rj.clone()]], &g.z[rj.clone()], &l[rj]);
        for dx in -2..=2isize {
            if !centre && dx == 0 && yy == y {
                continue;
            }
            let xj = xi + dx;
            let gj = G8 {
                kind: ld::<EDGE>(kind, xj),
                n: [ld::<EDGE>(n[0], xj), ld::<EDGE>(n[1], xj), ld::<EDGE>(n[2], xj)],
                z: ld::<EDGE>(z, xj),
            };
            let m = same8(&gi, &gj);
            let d = mask_to(m, ld::<EDGE>(lj, xj) - li);
            k = k + mask_to(m, F8::splat(1.0));
            m1 = m1 + d;
            m2 = m2 + d * d;
            top = top.max(F8::splat(f32::NEG_INFINITY).blend(m, d));
        }
    }
    (k, m1, m2, top)
}

/// Spreads the light of outliers (fireflies: rare paths of high contribution) over their
/// surface, keeping it: a pixel whose demodulated luminance exceeds the mean of its 5 × 5
/// neighbours on the same surface (its brightest neighbour left out) by more than
/// `outlier_sigmas` of their standard deviation keeps that bound, and the rest of its light,
/// in radiance, goes to the pixels of the same surface within `outlier_radius`, in
/// proportion to their albedo (so each gains the same demodulated amount). `c` and
/// `albedo` are planes of red, green and blue.
fn spread_outliers(c: &mut [Vec<f32>; 3], albedo: &[Vec<f32>; 3], g: &Guides, s: &DenoiseSettings, simd: bool) {
    if s.outlier_sigmas <= 0.0 || s.outlier_radius == 0 {
        return;
    }
    let (w, h) = (g.w, g.h);
    let l = luminance(c);
    // Each pixel's bound (or infinity: not an outlier), by rows.
    let mut bound = vec![f32::INFINITY; w * h];
    bound.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let (g, l, sig) = (g, &l[..], s.outlier_sigmas);
        lanes!(simd, |g: &Guides, l: &[f32], y: usize, row: &mut [f32], sig: f32| {
            for x0 in (0..g.w).step_by(LANES) {
                let (k, m1, m2, top) = neighbour_stats(g, l, y, x0, false);
                for j in 0..LANES.min(g.w - x0) {
                    let i = y * g.w + x0 + j;
                    if g.kind[i] == 0.0 || k.0[j] < 4.0 {
                        continue;
                    }
                    let (m1, m2, k) = (m1.0[j] - top.0[j], m2.0[j] - top.0[j] * top.0[j], k.0[j] - 1.0);
                    let mean = m1 / k;
                    let sd = (m2 / k - mean * mean).max(0.0).sqrt();
                    let b = l[i] + mean + sig * sd;
                    if l[i] > b && b >= 0.0 {
                        row[x0 + j] = b;
                    }
                }
            }
        });
    });
    // The outliers, and each one's excess per unit of albedo of the pixels that share it
    // (they lie on its surface within the radius: the test is the outlier's, so the
    // gathering below finds the same ones).
    let r = s.outlier_radius as usize;
    let span = |v: usize, len: usize| v.saturating_sub(r)..(v + r + 1).min(len);
    // Each outlier's excess, which pixels of its (2r + 1)² window share it (a bit per pixel,
    // rows of `words` 64-bit words: kept, as the gathering below needs the same ones), and
    // its excess per unit of their albedo.
    let words = (2 * r + 1).div_ceil(64);
    let outliers: Vec<Outlier> = (0..w * h)
        .into_par_iter()
        .filter(|&i| bound[i].is_finite())
        .map(|i| {
            let scale = 1.0 - bound[i] / l[i];
            let e = [0, 1, 2].map(|k| c[k][i] * scale);
            let mut o = Outlier { i, e, per: [0.0; 3], share: vec![0; (2 * r + 1) * words] };
            let mut sums = [0.0f32; 3];
            let (total, o_ref) = (&mut sums, &mut o);
            lanes!(simd, |g: &Guides, albedo: &[Vec<f32>; 3], r: usize, o_ref: &mut Outlier, total: &mut [f32; 3]| {
                share_of(g, albedo, r, o_ref, total)
            });
            o.per = [0, 1, 2].map(|k| albedo[k][i] * e[k] / sums[k]);
            o
        })
        .collect();
    if outliers.is_empty() {
        return;
    }
    // Gathered per row (in parallel): what each pixel receives from the outliers near it.
    let mut by_row: Vec<Vec<&Outlier>> = vec![Vec::new(); h];
    for o in &outliers {
        by_row[o.i / w].push(o);
    }
    let mut gained = vec![0.0f32; 3 * w * h];
    gained.par_chunks_mut(3 * w).enumerate().for_each(|(y, row)| {
        let rows: Vec<(usize, &[&Outlier])> = span(y, h).map(|yy| (yy, by_row[yy].as_slice())).collect();
        let rows = &rows[..];
        lanes!(simd, |w: usize, r: usize, y: usize, rows: &[(usize, &[&Outlier])], row: &mut [f32]| gather_row(w, r, y, rows, row));
    });
    for o in &outliers {
        for k in 0..3 {
            c[k][o.i] -= o.e[k];
        }
    }
    for (y, row) in gained.chunks(3 * w).enumerate() {
        for k in 0..3 {
            for (v, add) in c[k][y * w..(y + 1) * w].iter_mut().zip(&row[k * w..(k + 1) * w]) {
                *v += add;
            }
        }
    }
}

/// An outlier of [`spread_outliers`].
struct Outlier {
    /// The pixel.
    i: usize,
    /// Its excess light (radiance, demodulated where its surface is).
    e: [f32; 3],
    /// What each pixel sharing it gains, per unit of its albedo.
    per: [f32; 3],
    /// Which pixels of its (2r + 1)² window share it: a bit per pixel, in rows of whole
    /// 64-bit words.
    share: Vec<u64>,
}

/// The pixels that share outlier `o`'s excess (those of its window on its surface), into
/// `o.share`, and the sum of their albedos into `total`.
#[inline(always)]
fn share_of(g: &Guides, albedo: &[Vec<f32>; 3], r: usize, o: &mut Outlier, total: &mut [f32; 3]) {
    let (w, h, i) = (g.w, g.h, o.i);
    let (x, y) = (i % w, i / w);
    let words = (2 * r + 1).div_ceil(64);
    let gi = G8 { kind: F8::splat(g.kind[i]), n: [F8::splat(g.n[0][i]), F8::splat(g.n[1][i]), F8::splat(g.n[2][i])], z: F8::splat(g.z[i]) };
    let (lo, hi) = (x.saturating_sub(r), (x + r + 1).min(w));
    let lanes = F8([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
    let mut t = [F8::splat(0.0); 3];
    for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
        let row = yy * w..(yy + 1) * w;
        let (kind, n, z) = (&g.kind[row.clone()], [&g.n[0][row.clone()], &g.n[1][row.clone()], &g.n[2][row.clone()]], &g.z[row.clone()]);
        let a = [&albedo[0][row.clone()], &albedo[1][row.clone()], &albedo[2][row]];
        let bits = &mut o.share[(yy + r - y) * words..(yy + r - y + 1) * words];
        for x0 in (lo..hi).step_by(LANES) {
            let xi = x0 as isize;
            let (m, al) = if x0 + LANES <= hi {
                share_chunk::<false>(&gi, kind, n, z, a, xi)
            } else {
                // (Columns past the window: not the outlier's.)
                let (m, al) = share_chunk::<true>(&gi, kind, n, z, a, xi);
                (m & lanes.lt(F8::splat((hi - x0) as f32)), al)
            };
            let b = u64::from(m.bits());
            if b == 0 {
                continue;
            }
            for k in 0..3 {
                t[k] = t[k] + mask_to(m, al[k]);
            }
            // Bit of column x0 in the window's row: x0 + r - x.
            let off = x0 + r - x;
            bits[off / 64] |= b << (off % 64);
            if off % 64 > 56 && b >> (64 - off % 64) != 0 {
                bits[off / 64 + 1] |= b >> (64 - off % 64);
            }
        }
    }
    for k in 0..3 {
        total[k] = t[k].0.iter().sum();
    }
}

/// Which of eight pixels (from column `xi` of a row of guides and albedos) lie on the
/// surface of `gi`, and their albedos.
#[inline(always)]
fn share_chunk<const EDGE: bool>(gi: &G8, kind: &[f32], n: [&[f32]; 3], z: &[f32], a: [&[f32]; 3], xi: isize) -> (M8, [F8; 3]) {
    let gj = G8 { kind: ld::<EDGE>(kind, xi), n: [ld::<EDGE>(n[0], xi), ld::<EDGE>(n[1], xi), ld::<EDGE>(n[2], xi)], z: ld::<EDGE>(z, xi) };
    (same8(gi, &gj), [ld::<EDGE>(a[0], xi), ld::<EDGE>(a[1], xi), ld::<EDGE>(a[2], xi)])
}

/// Adds each outlier's gain (`per`) to the pixels of row `y` its `share` bits name: the
/// outliers of rows `y - r..=y + r` (`rows`), each row `row` of red, green, blue.
#[inline(always)]
fn gather_row(w: usize, r: usize, y: usize, rows: &[(usize, &[&Outlier])], row: &mut [f32]) {
    let words = (2 * r + 1).div_ceil(64);
    let (gr, rest) = row.split_at_mut(w);
    let (gg, gb) = rest.split_at_mut(w);
    for &(yy, list) in rows {
        for o in list {
            let (xo, ry) = (o.i % w, y + r - yy);
            let bits = &o.share[ry * words..(ry + 1) * words];
            let per = [F8::splat(o.per[0]), F8::splat(o.per[1]), F8::splat(o.per[2])];
            for q in 0..(2 * r + 1).div_ceil(8) {
                let b = (bits[q / 8] >> ((q % 8) * 8)) as u32 & 0xff;
                if b == 0 {
                    continue;
                }
                // (Bits are set only for pixels inside the image.)
                let x0 = (xo + 8 * q) as isize - r as isize;
                if x0 >= 0 && x0 as usize + LANES <= w {
                    let (x0, m) = (x0 as usize, M8::from_bits(b));
                    add_lanes(gr, x0, LANES, mask_to(m, per[0]));
                    add_lanes(gg, x0, LANES, mask_to(m, per[1]));
                    add_lanes(gb, x0, LANES, mask_to(m, per[2]));
                } else {
                    for k in 0..LANES {
                        if b >> k & 1 == 1 {
                            let x = (x0 + k as isize) as usize;
                            gr[x] += o.per[0];
                            gg[x] += o.per[1];
                            gb[x] += o.per[2];
                        }
                    }
                }
            }
        }
    }
}

/// [`spread_outliers`] on a VPL image's layers (`w` × `h`, row-major): their reflected
/// light, demodulated, before the discontinuity buffer averages it.
pub(crate) fn spread_outliers_of_layers(layers: &mut [Layers], w: usize, h: usize, sigmas: f32, radius: u32) {
    // (Every plane made on all cores: one by one, they were ~40% of this step on a
    // 512 × 384 kitchen frame.)
    let normal: Vec<Vec3> = layers.par_iter().map(|l| l.normal).collect();
    let depth: Vec<f32> = layers.par_iter().map(|l| l.depth).collect();
    let l = &*layers;
    let g = guides(
        w,
        h,
        &normal,
        &depth,
        |i| l[i].depth.is_finite() && l[i].depth > 0.0 && l[i].normal != Vec3::ZERO && l[i].lit.is_finite(),
        |i| is_dark(l[i].albedo),
    );
    let albedo = [0, 1, 2].map(|k| layers.par_iter().map(|l| demodulating(l.albedo)[k]).collect());
    let mut c = [0, 1, 2].map(|k| layers.par_iter().map(|l| l.lit[k]).collect());
    let s = DenoiseSettings { outlier_sigmas: sigmas, outlier_radius: radius, ..DenoiseSettings::default() };
    spread_outliers(&mut c, &albedo, &g, &s, lucent_accel::simd::avx2_fma());
    layers.par_iter_mut().enumerate().for_each(|(i, l)| l.lit = Vec3::new(c[0][i], c[1][i], c[2][i]));
}

/// The luminance of red, green and blue planes (as [`crate::world::luminance`]).
fn luminance(c: &[Vec<f32>; 3]) -> Vec<f32> {
    (0..c[0].len()).into_par_iter().map(|i| LUMINANCE[0] * c[0][i] + LUMINANCE[1] * c[1][i] + LUMINANCE[2] * c[2][i]).collect()
}

/// Red, green and blue planes of `v`.
fn planes(v: &[Vec3]) -> [Vec<f32>; 3] {
    [0, 1, 2].map(|k| v.par_iter().map(|p| p[k]).collect())
}

/// Denoises `color` guided by `aovs` (the same size). Energy is kept: each pass moves
/// light between pairs of pixels by an amount that is the same both ways (a conservative
/// diffusion step), so the image's sum does not change, where a normalised weighted mean
/// loses the light of outliers its neighbours refuse (measured: −3% on a 4-sample
/// Sponza), and demodulated values traded as they are change it where the albedo varies
/// (+8% on the kitchen).
#[must_use]
pub fn denoise(color: &Film, aovs: &Aovs, s: &DenoiseSettings) -> Film {
    denoise_with(color, aovs, s, None, lucent_accel::simd::avx2_fma())
}

/// [`denoise`] with the noise measured from the samples themselves: `variance` holds
/// each pixel's variance of its mean's luminance (such as [`crate::render_halves`] finds
/// from two half images), in place of the estimate from each pixel's 5 × 5 neighbourhood,
/// which also counts the image's own detail as noise. A `variance` of another length is
/// not used.
#[must_use]
pub fn denoise_with_variance(color: &Film, aovs: &Aovs, s: &DenoiseSettings, variance: &[f32]) -> Film {
    denoise_with(color, aovs, s, Some(variance), lucent_accel::simd::avx2_fma())
}

/// The constants of one à-trous pass.
#[derive(Clone, Copy)]
struct PassConsts {
    step: usize,
    sigma_depth: f32,
    sigma_luminance: f32,
    cos_min: f32,
    /// The normal exponent when it is a whole number up to 1024, else -1.
    normal_int: i32,
    normal: f32,
}

/// What one pass reads.
struct PassIn<'a> {
    g: &'a Guides,
    /// Luminance of the demodulated colour, and the noise's standard deviation.
    l: &'a [f32],
    sd: &'a [f32],
    k: PassConsts,
}

/// One row of the guides and of a pass's luminance and noise level, as slices.
struct GuideRow<'a> {
    kind: &'a [f32],
    n: [&'a [f32]; 3],
    z: &'a [f32],
    dz: [&'a [f32]; 2],
    l: &'a [f32],
    sd: &'a [f32],
}

impl<'a> GuideRow<'a> {
    #[inline(always)]
    fn new(p: &PassIn<'a>, y: usize) -> Self {
        let g = p.g;
        let r = y * g.w..(y + 1) * g.w;
        GuideRow {
            kind: &g.kind[r.clone()],
            n: [&g.n[0][r.clone()], &g.n[1][r.clone()], &g.n[2][r.clone()]],
            z: &g.z[r.clone()],
            dz: [&g.dz[0][r.clone()], &g.dz[1][r.clone()]],
            l: &p.l[r.clone()],
            sd: &p.sd[r],
        }
    }
}

/// The lanes of `row` from column `x0` on (outside the row: zero).
#[inline(always)]
fn lanes_at(row: &[f32], x0: isize) -> F8 {
    load_at(row, x0, 0, row.len() as isize)
}

/// The lanes of `row` from column `x0` on: all inside the row unless `EDGE` (then those
/// outside are zero).
#[inline(always)]
fn ld<const EDGE: bool>(row: &[f32], x0: isize) -> F8 {
    if EDGE {
        lanes_at(row, x0)
    } else {
        F8::load(row, x0 as usize)
    }
}

/// The weights of eight pixels of row `ri` (from column `xi`) toward those of `rj` (from
/// `xj`): `b3` the B3 taps' product, `(ax, ay)` the tap's distance in pixels.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn weight_chunk<const EDGE: bool>(
    ri: &GuideRow,
    rj: &GuideRow,
    xi: isize,
    xj: isize,
    k: &PassConsts,
    b3: F8,
    ax: F8,
    ay: F8,
) -> Option<F8> {
    let ki = ld::<EDGE>(ri.kind, xi);
    let mut m = ki.ne(F8::splat(0.0)) & ki.eq(ld::<EDGE>(rj.kind, xj));
    if m.bits() == 0 {
        return None;
    }
    let cos = ld::<EDGE>(ri.n[0], xi) * ld::<EDGE>(rj.n[0], xj)
        + ld::<EDGE>(ri.n[1], xi) * ld::<EDGE>(rj.n[1], xj)
        + ld::<EDGE>(ri.n[2], xi) * ld::<EDGE>(rj.n[2], xj);
    m = m & cos.ge(F8::splat(k.cos_min));
    if m.bits() == 0 {
        return None;
    }
    let expect =
        (ld::<EDGE>(ri.dz[0], xi) * ax + ld::<EDGE>(ri.dz[1], xi) * ay).max(ld::<EDGE>(rj.dz[0], xj) * ax + ld::<EDGE>(rj.dz[1], xj) * ay);
    let (zi, zj) = (ld::<EDGE>(ri.z, xi), ld::<EDGE>(rj.z, xj));
    let ez = abs8(zi - zj) / (F8::splat(k.sigma_depth) * expect + F8::splat(1e-3) * zi.max(zj));
    let sl = F8::splat(k.sigma_luminance) * ld::<EDGE>(ri.sd, xi).max(ld::<EDGE>(rj.sd, xj)) + F8::splat(1e-6);
    let e = ez + abs8(ld::<EDGE>(ri.l, xi) - ld::<EDGE>(rj.l, xj)) / sl;
    m = m & e.le(F8::splat(30.0));
    Some(mask_to(m, b3 * pow8(cos, k.normal_int, k.normal) * exp_neg(e)))
}

/// The weights of row `y`'s pixels toward their twelve forward taps (`out`: twelve rows
/// of `w`), zero where a tap leaves the image or weighs less than e^-30.
#[inline(always)]
fn weights_row(p: &PassIn, y: usize, out: &mut [f32]) {
    let (g, k) = (p.g, p.k);
    let (w, h) = (g.w, g.h);
    out.fill(0.0);
    let ri = GuideRow::new(p, y);
    for (t, &(tx, ty)) in FORWARD.iter().enumerate() {
        let (dx, dy) = (tx as isize * k.step as isize, ty as usize * k.step);
        let yy = y + dy;
        if yy >= h {
            continue;
        }
        let rj = GuideRow::new(p, yy);
        let (ax, ay) = (F8::splat((tx.unsigned_abs() as usize * k.step) as f32), F8::splat(dy as f32));
        let b3 = F8::splat(B3[(tx + 2) as usize] * B3[(ty + 2) as usize]);
        let o = &mut out[t * w..(t + 1) * w];
        // (Only the columns whose tap lies inside the image.)
        let (xa, xb) = ((-dx).max(0) as usize, (w as isize - dx.max(0)).max(0) as usize);
        for x0 in (xa..xb).step_by(LANES) {
            let (xi, xj) = (x0 as isize, x0 as isize + dx);
            // (Inside the span the taps lie inside the image; the last chunk may reach past
            // it, where the weights stay 0.)
            let cnt = LANES.min(xb - x0);
            let wt = if cnt == LANES {
                weight_chunk::<false>(&ri, &rj, xi, xj, &k, b3, ax, ay)
            } else {
                weight_chunk::<true>(&ri, &rj, xi, xj, &k, b3, ax, ay)
                    .map(|v| mask_to(F8([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]).lt(F8::splat(cnt as f32)), v))
            };
            if let Some(wt) = wt {
                store_lanes(o, x0, cnt, wt);
            }
        }
    }
}

/// Each pixel's sum of weights in row `y` (its own tap included; 0 for pixels that are not
/// filtered), from the forward weights `wts` (per row, twelve rows of `w`).
#[inline(always)]
fn sums_row(p: &PassIn, wts: &[f32], y: usize, out: &mut [f32]) {
    let (g, k) = (p.g, p.k);
    let w = g.w;
    let b3 = F8::splat(B3[2] * B3[2]);
    for x0 in (0..w).step_by(LANES) {
        let gi = g.load(y, x0 as isize);
        let cos = gi.n[0] * gi.n[0] + gi.n[1] * gi.n[1] + gi.n[2] * gi.n[2];
        let mut sum = b3 * pow8(cos, k.normal_int, k.normal);
        for (t, &(tx, ty)) in FORWARD.iter().enumerate() {
            let (dx, dy) = (tx as isize * k.step as isize, ty as usize * k.step);
            sum = sum + load_at(&wts[(y * 12 + t) * w..(y * 12 + t + 1) * w], x0 as isize, 0, w as isize);
            if let Some(yy) = y.checked_sub(dy) {
                sum = sum + load_at(&wts[(yy * 12 + t) * w..(yy * 12 + t + 1) * w], x0 as isize - dx, 0, w as isize);
            }
        }
        store_lanes(out, x0, LANES.min(w - x0), mask_to(gi.kind.ne(F8::splat(0.0)), sum));
    }
}

/// The colour and variance planes a pass reads.
struct Light<'a> {
    c: &'a [Vec<f32>; 3],
    albedo: &'a [Vec<f32>; 3],
    var: &'a [f32],
    sums: &'a [f32],
}

/// One row of [`Light`], as slices.
struct LightRow<'a> {
    c: [&'a [f32]; 3],
    albedo: [&'a [f32]; 3],
    var: &'a [f32],
    sums: &'a [f32],
}

impl<'a> LightRow<'a> {
    #[inline(always)]
    fn new(lt: &Light<'a>, w: usize, y: usize) -> Self {
        let r = y * w..(y + 1) * w;
        LightRow {
            c: [&lt.c[0][r.clone()], &lt.c[1][r.clone()], &lt.c[2][r.clone()]],
            albedo: [&lt.albedo[0][r.clone()], &lt.albedo[1][r.clone()], &lt.albedo[2][r.clone()]],
            var: &lt.var[r.clone()],
            sums: &lt.sums[r],
        }
    }
}

/// Row `y`'s trades with row `rj`'s pixels `dx` columns on, by the weights `wrow`
/// (indexed from column `wx` = 0 or `dx`, where the pair's forward weight is kept),
/// added to the running sums `acc` (the change of red, green and blue times the albedo,
/// what each pixel keeps of itself, and its variance's sum; rows of `w`).
#[inline(always)]
fn trade_taps(ri: &LightRow, rj: &LightRow, wrow: &[f32], dx: isize, backward: bool, acc: &mut [f32]) {
    let w = ri.sums.len();
    let (ad, rest) = acc.split_at_mut(3 * w);
    let (kept, v) = rest.split_at_mut(w);
    // (Only the columns whose tap lies inside the image.)
    let (xa, xb) = ((-dx).max(0) as usize, (w as isize - dx.max(0)).max(0) as usize);
    for x0 in (xa..xb).step_by(LANES) {
        let (xi, xj) = (x0 as isize, x0 as isize + dx);
        let cnt = LANES.min(xb - x0);
        if cnt == LANES {
            trade_chunk::<false>(ri, rj, wrow, xi, xj, backward, ad, kept, v);
        } else {
            trade_chunk::<true>(ri, rj, wrow, xi, xj, backward, ad, kept, v);
        }
    }
}

/// [`trade_taps`] at eight pixels from column `xi` (their partners from `xj`; with
/// `EDGE`, some lanes lie past the row's span: their weights are zero).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn trade_chunk<const EDGE: bool>(
    ri: &LightRow,
    rj: &LightRow,
    wrow: &[f32],
    xi: isize,
    xj: isize,
    backward: bool,
    ad: &mut [f32],
    kept: &mut [f32],
    v: &mut [f32],
) {
    let w = ri.sums.len();
    let wt = ld::<EDGE>(wrow, if backward { xj } else { xi });
    if wt.gt(F8::splat(0.0)).bits() == 0 {
        return;
    }
    let x0 = xi as usize;
    let cnt = if EDGE { LANES.min(w - x0) } else { LANES };
    let a = wt / ld::<EDGE>(ri.sums, xi).max(ld::<EDGE>(rj.sums, xj));
    for ch in 0..3 {
        let d =
            (ld::<EDGE>(rj.c[ch], xj) - ld::<EDGE>(ri.c[ch], xi)) * (ld::<EDGE>(ri.albedo[ch], xi).min(ld::<EDGE>(rj.albedo[ch], xj)) * a);
        add_lanes(&mut ad[ch * w..(ch + 1) * w], x0, cnt, d);
    }
    add_lanes(kept, x0, cnt, -a);
    add_lanes(v, x0, cnt, a * a * ld::<EDGE>(rj.var, xj));
}

/// One pass's trade of light in row `y`: every pair trades light by its weight over the
/// larger of the two sums, in radiance `a · min(albedos)` of the difference, the same both
/// ways; the variance follows. `out`: the row's new red, green, blue, variance and
/// luminance; `acc`: room for 5 rows.
#[inline(always)]
fn trade_row(p: &PassIn, wts: &[f32], lt: &Light, y: usize, out: [&mut [f32]; 5], acc: &mut [f32]) {
    let (g, k) = (p.g, p.k);
    let (w, h) = (g.w, g.h);
    acc[..3 * w].fill(0.0);
    acc[3 * w..4 * w].fill(1.0);
    acc[4 * w..5 * w].fill(0.0);
    let ri = LightRow::new(lt, w, y);
    for (tap, &(tx, ty)) in FORWARD.iter().enumerate() {
        let (dx, dy) = (tx as isize * k.step as isize, ty as usize * k.step);
        if y + dy < h {
            let wrow = &wts[(y * 12 + tap) * w..(y * 12 + tap + 1) * w];
            trade_taps(&ri, &LightRow::new(lt, w, y + dy), wrow, dx, false, acc);
        }
        if let Some(yy) = y.checked_sub(dy) {
            let wrow = &wts[(yy * 12 + tap) * w..(yy * 12 + tap + 1) * w];
            trade_taps(&ri, &LightRow::new(lt, w, yy), wrow, -dx, true, acc);
        }
    }
    let [or, og, ob, ov, ol] = out;
    let kind = &g.kind[y * w..(y + 1) * w];
    for x0 in (0..w).step_by(LANES) {
        let xi = x0 as isize;
        let cnt = LANES.min(w - x0);
        let si = lanes_at(ri.sums, xi);
        let live = lanes_at(kind, xi).ne(F8::splat(0.0)) & si.gt(F8::splat(0.0));
        let c = [0, 1, 2].map(|ch| {
            let ci = lanes_at(ri.c[ch], xi);
            ci.blend(live, ci + lanes_at(&acc[ch * w..(ch + 1) * w], xi) / lanes_at(ri.albedo[ch], xi))
        });
        let (kept, vs, vi) = (lanes_at(&acc[3 * w..4 * w], xi), lanes_at(&acc[4 * w..], xi), lanes_at(ri.var, xi));
        store_lanes(or, x0, cnt, c[0]);
        store_lanes(og, x0, cnt, c[1]);
        store_lanes(ob, x0, cnt, c[2]);
        store_lanes(ov, x0, cnt, vi.blend(live, vs + kept * kept * vi));
        store_lanes(ol, x0, cnt, F8::splat(LUMINANCE[0]) * c[0] + F8::splat(LUMINANCE[1]) * c[1] + F8::splat(LUMINANCE[2]) * c[2]);
    }
}

/// The noise's standard deviation in row `y`: the variance `var` (rows of `w`, `h` of
/// them) blurred over 3 × 3 by (1/4, 1/2, 1/4) in each direction (SVGF: a steadier
/// estimate), the weights renormalised where the kernel leaves the image. (Plain loops,
/// which the compiler vectorizes.)
fn blur_sd(var: &[f32], w: usize, h: usize, y: usize, out: &mut [f32]) {
    let mut acc = vec![0.0f32; w];
    let mut wsum = 0.0f32;
    for (dy, wy) in [(-1isize, 0.25f32), (0, 0.5), (1, 0.25)] {
        let yy = y as isize + dy;
        if yy < 0 || yy >= h as isize {
            continue;
        }
        wsum += wy;
        let r = &var[yy as usize * w..(yy as usize + 1) * w];
        // The horizontal blur of row yy, renormalised at the ends.
        for x in 1..w.saturating_sub(1) {
            acc[x] += wy * (0.25 * r[x - 1] + 0.5 * r[x] + 0.25 * r[x + 1]);
        }
        if w == 1 {
            acc[0] += wy * r[0];
        } else {
            acc[0] += wy * ((0.5 * r[0] + 0.25 * r[1]) / 0.75);
            acc[w - 1] += wy * ((0.25 * r[w - 2] + 0.5 * r[w - 1]) / 0.75);
        }
    }
    for (o, a) in out.iter_mut().zip(&acc) {
        *o = (a / wsum).max(0.0).sqrt();
    }
}

/// [`denoise`] with the lane kernels' AVX2 build (`simd`, where the CPU has it) or their
/// portable one: the same image.
#[must_use]
pub(crate) fn denoise_with(color: &Film, aovs: &Aovs, s: &DenoiseSettings, variance: Option<&[f32]>, simd: bool) -> Film {
    let simd = simd && lucent_accel::simd::avx2_fma();
    let (w, h) = (color.width as usize, color.height as usize);
    let n = w * h;
    if n == 0 || aovs.albedo.pixels.len() != n || aovs.normal.pixels.len() != n || aovs.depth.len() != n || aovs.emission.pixels.len() != n
    {
        return color.clone();
    }
    let alb: Vec<Vec3> = aovs.albedo.pixels.iter().map(|&a| demodulating(a)).collect();
    let g = aov_guides(w, h, aovs, |i| color.pixels[i].is_finite());
    let albedo = planes(&alb);
    // Demodulated colour.
    let mut c = planes(&(0..n).map(|i| if g.kind[i] != 0.0 { color.pixels[i] / alb[i] } else { Vec3::ZERO }).collect::<Vec<_>>());
    spread_outliers(&mut c, &albedo, &g, s, simd);
    let mut l = luminance(&c);
    // The noise's variance (of luminance): over each pixel's 5 × 5 neighbourhood on its
    // surface.
    let mut var = vec![0.0f32; n];
    if let Some(v) = variance.filter(|v| v.len() == n) {
        // The samples' own: of the demodulated luminance (the colour over the albedo).
        for (i, o) in var.iter_mut().enumerate() {
            let a = crate::color::luminance(alb[i]);
            *o = if g.kind[i] == 0.0 || !(v[i].is_finite() && v[i] >= 0.0) { 0.0 } else { v[i] / (a * a) };
        }
    } else {
        var.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            let (g, l) = (&g, &l[..]);
            lanes!(simd, |g: &Guides, l: &[f32], y: usize, row: &mut [f32]| {
                for x0 in (0..g.w).step_by(LANES) {
                    let (k, m1, m2, _) = neighbour_stats(g, l, y, x0, true);
                    for j in 0..LANES.min(g.w - x0) {
                        let k = k.0[j];
                        row[x0 + j] = if g.kind[y * g.w + x0 + j] == 0.0 || k < 2.0 {
                            0.0
                        } else {
                            let mean = m1.0[j] / k;
                            (m2.0[j] / k - mean * mean).max(0.0) * k / (k - 1.0)
                        };
                    }
                }
            });
        });
    }
    let normal_int = if s.sigma_normal.fract() == 0.0 && (0.0..=1024.0).contains(&s.sigma_normal) { s.sigma_normal as i32 } else { -1 };
    // The least cosine between normals whose weight reaches e^-30.
    let cos_min = if s.sigma_normal > 0.0 { (-30.0 / s.sigma_normal).exp() } else { -1.0 };
    let mut wts = vec![0.0f32; 12 * n];
    let mut sums = vec![0.0f32; n];
    // The next pass's colour, variance and luminance (swapped in).
    let (mut c2, mut var2, mut l2) = ([vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]], vec![0.0f32; n], vec![0.0f32; n]);
    let mut sd = vec![0.0f32; n];
    for it in 0..s.iterations.min(12) {
        let step = 1usize << it;
        // The noise's standard deviation at each pixel: the variance blurred over 3 × 3
        // (SVGF: a steadier estimate).
        sd.par_chunks_mut(w).enumerate().for_each(|(y, row)| blur_sd(&var, w, h, y, row));
        let k = PassConsts {
            step,
            sigma_depth: s.sigma_depth,
            sigma_luminance: s.sigma_luminance,
            cos_min,
            normal_int,
            normal: s.sigma_normal,
        };
        let p = PassIn { g: &g, l: &l, sd: &sd, k };
        let p = &p;
        wts.par_chunks_mut(12 * w).enumerate().for_each(|(y, out)| {
            lanes!(simd, |p: &PassIn, y: usize, out: &mut [f32]| weights_row(p, y, out));
        });
        let wts = &wts[..];
        sums.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
            lanes!(simd, |p: &PassIn, wts: &[f32], y: usize, out: &mut [f32]| sums_row(p, wts, y, out));
        });
        let lt = &Light { c: &c, albedo: &albedo, var: &var, sums: &sums };
        let [r2, g2, b2] = &mut c2;
        r2.par_chunks_mut(w)
            .zip(g2.par_chunks_mut(w))
            .zip(b2.par_chunks_mut(w))
            .zip(var2.par_chunks_mut(w))
            .zip(l2.par_chunks_mut(w))
            .enumerate()
            .for_each_init(
                || vec![0.0f32; 5 * w],
                |acc, (y, ((((r, gr), b), v), l))| {
                    let (out, acc) = ([r, gr, b, v, l], &mut acc[..]);
                    lanes!(simd, |p: &PassIn, wts: &[f32], lt: &Light, y: usize, out: [&mut [f32]; 5], acc: &mut [f32]| {
                        trade_row(p, wts, lt, y, out, acc)
                    });
                },
            );
        std::mem::swap(&mut c, &mut c2);
        std::mem::swap(&mut var, &mut var2);
        std::mem::swap(&mut l, &mut l2);
    }
    let pixels = (0..n).map(|i| if g.kind[i] != 0.0 { alb[i] * Vec3::new(c[0][i], c[1][i], c[2][i]) } else { color.pixels[i] }).collect();
    Film { width: color.width, height: color.height, pixels }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The polynomial `exp` against the library's over its range.
    #[test]
    fn exp_neg_is_close_to_exp() {
        let mut worst = 0.0f32;
        for k in 0..=300_000 {
            let x = k as f32 * 1e-4;
            let got = exp_neg(F8::splat(x)).0[0];
            let want = (-x).exp();
            worst = worst.max((got / want - 1.0).abs());
        }
        assert!(worst < 3e-6, "relative error {worst}");
    }

    /// The surface test's lanes and its one-pixel form agree on every pair of a picture
    /// with edges of depth, normal and kind (three kinds, random normals near two
    /// directions, depths in two bands), compared lane by lane.
    #[test]
    fn same_for_one_pixel_is_same8_lane_by_lane() {
        let (w, h) = (16usize, 16usize);
        let mut seed = 0x9e37_79b9u32;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        let normal: Vec<Vec3> = (0..w * h)
            .map(|_| {
                let base = if rnd() < 0.5 { Vec3::Y } else { Vec3::X };
                (base + Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * 0.6).normalize()
            })
            .collect();
        let depth: Vec<f32> = (0..w * h).map(|_| if rnd() < 0.5 { 1.0 + 0.2 * rnd() } else { 3.0 + rnd() }).collect();
        let kinds: Vec<u32> = (0..w * h).map(|_| (rnd() * 3.0) as u32).collect();
        let g = guides(w, h, &normal, &depth, |i| kinds[i] != 0, |i| kinds[i] == 2);
        let (mut yes, mut no) = (0, 0);
        for i in 0..w * h {
            let a = G8 {
                kind: F8::splat(g.kind[i]),
                n: [F8::splat(g.n[0][i]), F8::splat(g.n[1][i]), F8::splat(g.n[2][i])],
                z: F8::splat(g.z[i]),
            };
            for y in 0..h {
                for x0 in (0..w).step_by(LANES) {
                    let lanes = same8(&a, &g.load(y, x0 as isize));
                    for k in 0..LANES {
                        let one = g.same(i, y * w + x0 + k);
                        assert_eq!(lanes.0[k] != 0, one, "pixel {i} against ({}, {y})", x0 + k);
                        if one {
                            yes += 1;
                        } else {
                            no += 1;
                        }
                    }
                }
            }
        }
        assert!(yes > 1000 && no > 1000, "both answers occur: {yes} same, {no} not");
    }

    /// The Cornell box at 4 samples (160 × 120), its guides, and the 4096-sample reference's
    /// size.
    fn cornell() -> (Film, Aovs) {
        use crate::{render, render_aovs, Camera, Integrator, PathSettings, RenderSettings, World};
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba/cornell_box/scene.xml");
        let scene = lucent_scene::load_mitsuba_with(&dir, &[]).expect("scene");
        let (wd, ht) = (160, 120);
        let cam = Camera::new(&scene.camera.expect("camera"), wd, ht);
        let w = World::new(scene, lucent_accel::MeshOptions::default()).expect("world");
        let st = RenderSettings { spp: 4, integrator: Integrator::Path(PathSettings::default()), ..RenderSettings::new(wd, ht) };
        (render(&w, &cam, &st, &|_| {}).0, render_aovs(&w, &cam, wd, ht))
    }

    /// The lane kernels' AVX2 build and their portable build give the same image, bit for
    /// bit; and both agree with the first, pixel-by-pixel implementation (`reference.rs`)
    /// up to rounding: the polynomial `exp` and the order of sums move a few weights by
    /// about 1e-7, which the edge-stopping tests (a threshold, e^-30) can turn into a
    /// larger change at a rare pixel.
    #[test]
    fn lanes_match_the_reference_on_the_cornell_box() {
        let (noisy, aovs) = cornell();
        compare_with_reference(&noisy, &aovs);
    }

    /// As above on a picture with dark surfaces (filtered among themselves) beside bright
    /// ones, a depth edge, fireflies and an emitter, at a width that is not a multiple of
    /// eight (the lanes' partial chunks).
    #[test]
    fn lanes_match_the_reference_on_dark_surfaces_and_edges() {
        let (w, h) = (61u32, 37u32);
        let n = (w * h) as usize;
        let mut state = 0x1234_5678u32;
        let mut rnd = move || {
            state = crate::pcg_hash(state);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        let film = |pixels| Film { width: w, height: h, pixels };
        let (mut color, mut albedo, mut normal, mut depth, mut emission) = (vec![], vec![], vec![], vec![], vec![Vec3::ZERO; n]);
        for i in 0..n {
            let (x, y) = (i as u32 % w, i as u32 / w);
            let dark = x < 20;
            let a = if dark { Vec3::splat(0.005) } else { Vec3::new(0.8, 0.5, 0.2) * if (x / 3 + y / 3) % 2 == 0 { 1.0 } else { 0.3 } };
            let mut c = a * (0.5 + rnd()) * if dark { 60.0 } else { 1.0 };
            if rnd() < 0.02 {
                c *= 50.0;
            }
            color.push(c);
            albedo.push(a);
            normal.push(if y > 25 { Vec3::Y } else { Vec3::Z });
            depth.push(if x > 45 { 7.0 + 0.01 * x as f32 } else { 2.0 + 0.003 * y as f32 });
        }
        emission[5 * w as usize + 50] = Vec3::ONE;
        let aovs = Aovs { albedo: film(albedo), normal: film(normal), depth, emission: film(emission) };
        compare_with_reference(&film(color), &aovs);
    }

    fn compare_with_reference(noisy: &Film, aovs: &Aovs) {
        let s = DenoiseSettings::default();
        let fast = denoise_with(noisy, aovs, &s, None, true);
        let portable = denoise_with(noisy, aovs, &s, None, false);
        let slow = reference::denoise(noisy, aovs, &s);
        for (i, (a, b)) in fast.pixels.iter().zip(&portable.pixels).enumerate() {
            assert!(a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits), "pixel {i}: AVX2 {a} portable {b}");
        }
        let n = fast.pixels.len();
        let (mut sum, mut worst) = (0.0f64, 0.0f32);
        for (a, b) in fast.pixels.iter().zip(&slow.pixels) {
            let d = ((*a - *b).abs() / (b.abs() + Vec3::splat(1e-3))).max_element();
            sum += f64::from(d);
            worst = worst.max(d);
        }
        let mean = sum / n as f64;
        // (Measured: mean 1.1e-7 and largest 7.2e-6 on the Cornell box; 1.4e-5 and 6.1e-4
        // on the synthetic picture, whose dark side is 60 times brighter than its albedo and
        // whose fireflies are 50 times their surface, where the statistics' rounding (`f32`
        // here, `f64` there) shows most.)
        assert!(mean < 1e-4 && worst < 5e-3, "relative difference from the reference: mean {mean:e}, largest {worst:e}");
    }
}
