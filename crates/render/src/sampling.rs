//! Sampling: warps of the unit square onto disks, hemispheres, spheres and cones, shading
//! frames, piecewise-constant 1D and 2D distributions (pbrt-v4's `PiecewiseConstant1D`
//! and `2D`), and the power heuristic of multiple importance sampling. The warps take their
//! sines and cosines from [`crate::lanes::sin_cos`], so that a loop over lanes that calls
//! them vectorizes and gives the same bits as one call.

use crate::lanes::sin_cos;
use glam::{Vec2, Vec3};
use lucent_accel::traverse::prefetch;
use std::f32::consts::PI;

/// A point on Shirley and Chiu's concentric map of the unit disk.
#[inline]
#[must_use]
pub fn concentric_disk(u: (f32, f32)) -> Vec2 {
    let (a, b) = (2.0 * u.0 - 1.0, 2.0 * u.1 - 1.0);
    // (Branch-free, so that a loop over lanes vectorizes: both wedges' angles are
    // selected from, and the centre's NaN angle is selected away.)
    let major = a.abs() > b.abs();
    let (r, ratio) = if major { (a, b / a) } else { (b, a / b) };
    let phi = if major { std::f32::consts::FRAC_PI_4 * ratio } else { std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * ratio };
    let (sp, cp) = sin_cos(phi);
    let centre = (a == 0.0) & (b == 0.0);
    Vec2::new(if centre { 0.0 } else { r * cp }, if centre { 0.0 } else { r * sp })
}

/// Cosine-weighted hemisphere sampling (Malley's method over Shirley and Chiu's concentric
/// disk), local frame.
#[inline(always)]
#[must_use]
pub fn cosine_hemisphere(u: (f32, f32)) -> Vec3 {
    let d = concentric_disk(u);
    Vec3::new(d.x, d.y, (1.0 - d.x * d.x - d.y * d.y).max(0.0).sqrt())
}

/// A uniformly chosen unit vector, for `u` in [0, 1)².
#[must_use]
pub fn uniform_sphere(u: (f32, f32)) -> Vec3 {
    let z = 1.0 - 2.0 * u.0;
    let s = (1.0 - z * z).max(0.0).sqrt();
    let (sp, cp) = sin_cos(2.0 * PI * u.1);
    Vec3::new(s * cp, s * sp, z)
}

/// A direction chosen uniformly within the cone of unit `axis` whose half-angle has
/// cosine `cos_max`, for `u` in [0, 1)²; its density per solid angle is
/// `1 / (2π (1 − cos_max))` (Shirley and Wang 1994).
#[must_use]
pub fn uniform_cone(axis: Vec3, cos_max: f32, u: (f32, f32)) -> Vec3 {
    let cos_t = 1.0 - u.0 * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let (sp, cp) = sin_cos(2.0 * PI * u.1);
    let (t, b) = axis.any_orthonormal_pair();
    (t * (sin_t * cp) + b * (sin_t * sp) + axis * cos_t).normalize_or_zero()
}

/// The power heuristic with β = 2 for `a` against `b` (pdfs of one sample each).
#[inline]
#[must_use]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 && (a2 + b2).is_finite() {
        a2 / (a2 + b2)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// A unit vector's orthonormal frame: tangent, bitangent (Duff et al., "Building an
/// Orthonormal Basis, Revisited", JCGT 2017).
#[inline]
fn frame(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), Vec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// A shading frame about a unit normal: world directions to local ones (z along the
/// normal, as the BSDFs see them) and back.
#[derive(Clone, Copy, Debug)]
pub struct ShadingFrame {
    pub(crate) t: Vec3,
    pub(crate) b: Vec3,
    /// The normal (local z).
    pub n: Vec3,
}

impl ShadingFrame {
    /// The frame about unit `n`.
    #[must_use]
    pub fn new(n: Vec3) -> Self {
        let (t, b) = frame(n);
        Self { t, b, n }
    }
    /// The frame about unit `n` whose x axis is `tangent` made orthogonal to `n` (and y
    /// is n × x, as Mitsuba's shading frame); `new(n)`'s where the tangent is (nearly)
    /// along `n` or not finite.
    #[must_use]
    pub fn with_tangent(n: Vec3, tangent: Vec3) -> Self {
        let t = (tangent - n * n.dot(tangent)).normalize_or_zero();
        if t == Vec3::ZERO || !t.is_finite() {
            return Self::new(n);
        }
        Self { t, b: n.cross(t), n }
    }

    /// World `v` in the frame.
    #[inline]
    #[must_use]
    pub fn to_local(self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
    /// Local `v` in the world.
    #[inline]
    #[must_use]
    pub fn to_world(self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

/// A piecewise-constant 1D distribution over [0, 1).
#[derive(Clone, Debug, Default)]
pub struct Distribution1D {
    /// Cumulative, normalised, `n + 1` entries from 0 to 1.
    cdf: Vec<f32>,
    /// Function values, normalised to integrate to 1 over [0, 1).
    pdf: Vec<f32>,
    integral: f64,
    /// The guide table (Chen and Asau's cutpoint method, 1974): entry `j` of `n` is the
    /// last cell whose cumulative start is at most `j / n`, so a search for `u` starts in
    /// the right cell or a few before it (expected O(1) steps, against a binary search's
    /// log₂ n dependent loads), and ends in the cell the binary search finds.
    guide: Vec<u32>,
}

impl Distribution1D {
    /// The distribution of `n` equal cells with values `f` (negative values count as 0;
    /// all zero: uniform).
    #[must_use]
    pub fn new(f: &[f32]) -> Self {
        let n = f.len().max(1);
        let sum: f64 = f.iter().map(|&x| f64::from(x.max(0.0))).sum();
        let integral = sum / n as f64;
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0);
        let mut acc = 0f64;
        for &x in f {
            acc += f64::from(x.max(0.0));
            cdf.push(if sum > 0.0 { (acc / sum) as f32 } else { cdf.len() as f32 / n as f32 });
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        let pdf = f.iter().map(|&x| if sum > 0.0 { (f64::from(x.max(0.0)) / integral) as f32 } else { 1.0 }).collect();
        let mut guide = Vec::with_capacity(n);
        let mut i = 0usize;
        for j in 0..n {
            let at = j as f32 / n as f32;
            while i + 1 < n && cdf[i + 1] <= at {
                i += 1;
            }
            guide.push(i as u32);
        }
        Self { cdf, pdf, integral, guide }
    }

    /// The cell of `u`: the last whose cumulative start is at most `u` (the first for
    /// `u` below 0 or NaN, the last for `u` at or above 1).
    #[cfg(test)]
    fn cell(&self, u: f32) -> usize {
        self.search(self.start(u), u)
    }

    /// The guide table's slot for `u` (`None` below 0 or NaN: the first cell).
    #[inline]
    fn slot(&self, u: f32) -> Option<usize> {
        let n = self.pdf.len();
        (!u.is_nan() && u >= 0.0).then(|| ((u * n as f32) as usize).min(n - 1))
    }

    /// Where the search for `u`'s cell starts: the guide table's cell (see
    /// [`Distribution1D::sample_from`]).
    #[inline]
    #[must_use]
    pub fn start(&self, u: f32) -> usize {
        self.slot(u).map_or(0, |j| self.guide[j] as usize)
    }

    /// Asks for the guide table's line that [`Distribution1D::start`] of `u` reads (a
    /// hint: batches of samples ask for every lane's lines before reading any).
    #[inline]
    pub fn prefetch_start(&self, u: f32) {
        if let Some(g) = self.slot(u).and_then(|j| self.guide.get(j)) {
            prefetch(g);
        }
    }

    /// Asks for the lines of cell `i` that [`Distribution1D::sample_from`] reads.
    #[inline]
    pub fn prefetch_cell(&self, i: usize) {
        if let (Some(c), Some(p)) = (self.cdf.get(i + 1), self.pdf.get(i)) {
            prefetch(c);
            prefetch(p);
        }
    }

    /// The cell of `u`, searched from cell `i` (back where rounding put the guide's
    /// slot one too far; then forward).
    #[inline]
    fn search(&self, mut i: usize, u: f32) -> usize {
        let n = self.pdf.len();
        while i > 0 && self.cdf[i] > u {
            i -= 1;
        }
        while i + 1 < n && self.cdf[i + 1] <= u {
            i += 1;
        }
        i
    }

    /// A point in [0, 1) for `u`, the density there and its cell.
    #[must_use]
    pub fn sample(&self, u: f32) -> (f32, f32, usize) {
        self.sample_from(self.start(u), u)
    }

    /// [`Distribution1D::sample`], its search started at `start` (that of
    /// [`Distribution1D::start`]: the same bits).
    #[inline]
    #[must_use]
    pub fn sample_from(&self, start: usize, u: f32) -> (f32, f32, usize) {
        let n = self.pdf.len();
        let i = self.search(start.min(n - 1), u);
        let (lo, hi) = (self.cdf[i], self.cdf[i + 1]);
        let t = if hi > lo { (u - lo) / (hi - lo) } else { 0.5 };
        (((i as f32 + t) / n as f32).min(1.0 - f32::EPSILON), self.pdf[i], i)
    }

    /// The density at `x` in [0, 1).
    #[must_use]
    pub fn pdf_at(&self, x: f32) -> f32 {
        self.pdf[self.index(x)]
    }

    /// The cell `x` in [0, 1) lies in.
    #[inline]
    fn index(&self, x: f32) -> usize {
        let n = self.pdf.len();
        ((x * n as f32) as usize).min(n - 1)
    }
}

/// A piecewise-constant 2D distribution over [0, 1)²: rows (v) by their totals, then a
/// column (u) within the row (pbrt's marginal and conditional densities).
#[derive(Clone, Debug, Default)]
pub struct Distribution2D {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// The distribution of a `w` × `h` grid of cells with values `f` (row-major).
    #[must_use]
    pub fn new(f: &[f32], w: usize, h: usize) -> Self {
        let rows: Vec<Distribution1D> = (0..h).map(|y| Distribution1D::new(&f[y * w..(y + 1) * w])).collect();
        let marginal = Distribution1D::new(&rows.iter().map(|r| r.integral as f32).collect::<Vec<_>>());
        Self { rows, marginal }
    }

    /// The marginal's sample of `v`: the point along v, its density, and its row.
    #[inline]
    #[must_use]
    pub fn sample_row(&self, v: f32) -> (f32, f32, usize) {
        self.marginal.sample(v)
    }

    /// Row `r` (of [`Distribution2D::sample_row`]), its distribution along u.
    #[inline]
    #[must_use]
    pub fn row(&self, r: usize) -> &Distribution1D {
        &self.rows[r.min(self.rows.len() - 1)]
    }

    /// A point in [0, 1)² for `u` and the density there.
    #[must_use]
    pub fn sample(&self, u: (f32, f32)) -> (Vec2, f32) {
        let (v, pv, row) = self.marginal.sample(u.1);
        let (x, pu, _) = self.rows[row].sample(u.0);
        (Vec2::new(x, v), pv * pu)
    }

    /// Asks for the line [`Distribution2D::pdf`] at `uv` reads in its row.
    #[inline]
    pub fn prefetch(&self, uv: Vec2) {
        let row = &self.rows[self.marginal.index(uv.y)];
        if let Some(p) = row.pdf.get(row.index(uv.x)) {
            prefetch(p);
        }
    }

    /// The density at `uv`.
    #[must_use]
    pub fn pdf(&self, uv: Vec2) -> f32 {
        // (The marginal has a cell per row.)
        self.marginal.pdf_at(uv.y) * self.rows[self.marginal.index(uv.y)].pdf_at(uv.x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The guide table's search finds the binary search's cell for every number, on
    /// distributions with empty cells, spikes and one cell.
    #[test]
    fn the_guided_search_finds_the_binary_searchs_cell() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let mut shapes: Vec<Vec<f32>> = vec![vec![1.0], vec![0.0, 0.0, 3.0], vec![5.0, 0.0, 0.0, 0.0], vec![0.0; 9]];
        for n in [2usize, 7, 64, 257, 1000] {
            shapes.push((0..n).map(|_| if rng.random::<f32>() < 0.3 { 0.0 } else { rng.random::<f32>().powi(8) * 100.0 }).collect());
            shapes.push((0..n).map(|i| if i == n / 3 { 1e6 } else { 1e-3 }).collect());
        }
        for f in &shapes {
            let d = Distribution1D::new(f);
            let n = d.pdf.len();
            let binary = |u: f32| d.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
            let mut us: Vec<f32> = (0..20_000).map(|_| rng.random::<f32>()).collect();
            us.extend(d.cdf.iter().flat_map(|&c| [c, f32::from_bits(c.to_bits().saturating_sub(1)), f32::from_bits(c.to_bits() + 1)]));
            us.extend([0.0, 1.0 - f32::EPSILON / 2.0, 1.0, 2.0, -1.0]);
            for u in us {
                assert_eq!(d.cell(u), binary(u), "u = {u} of {n} cells");
            }
        }
    }

    #[test]
    fn distribution_2d_density_integrates_to_one_and_matches_samples() {
        let (w, h) = (7, 5);
        let f: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32 + 0.5).collect();
        let d = Distribution2D::new(&f, w, h);
        // ∫ pdf = 1 (cells of area 1 / (w h)).
        let s: f32 =
            (0..w * h).map(|i| d.pdf(Vec2::new(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32))).sum::<f32>()
                / (w * h) as f32;
        assert!((s - 1.0).abs() < 1e-4, "{s}");
        // A sample's density is the density at its point.
        for k in 0..50 {
            let u = (((k * 13) % 50) as f32 / 50.0 + 0.01, (k as f32 + 0.5) / 50.0);
            let (p, pdf) = d.sample(u);
            assert!((d.pdf(p) - pdf).abs() < 1e-3 * pdf, "{p} {pdf} {}", d.pdf(p));
        }
    }
}
