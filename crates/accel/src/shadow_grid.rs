//! Candidate instances for shadow rays toward a directional light: a light buffer in the
//! manner of Haines and Greenberg ("The Light Buffer: A Shadow-Testing Accelerator", IEEE
//! CG&A 6(9), 1986), over instances rather than polygons, and for parallel light.
//!
//! Every ray toward a directional light runs along the same direction `d`, so it can only
//! meet an instance whose world box, seen along `d`, covers the ray's origin. The instances'
//! boxes are projected onto a plane across `d` and listed in the cells of a uniform grid
//! there. A packet of shadow rays whose origins fall into a few cells is tested against the
//! instances those cells list, without the top-level walk (a field of REND3R's spheres has
//! one or two per cell, the packet's own sphere among them).
//!
//! The lists are conservative: each box's footprint grows by a margin that covers the
//! rounding of the projections and the drift of a ray whose direction is not exactly
//! across the plane's axes, and the cell of a coordinate is a monotonic function of it, so
//! a point inside a footprint lands in one of the cells the footprint was listed in. The
//! answers are therefore exactly those of the walk: occlusion is whether any instance
//! blocks the ray, and every instance that can is tested.

use crate::geom::Aabb;
use glam::{DVec3, Vec3};

/// Most candidates a packet is tested against directly; more, and it takes the walk.
pub(crate) const MAX_CANDIDATES: usize = 8;

/// Relative margin of footprints and queries (a hundred times the rounding it covers).
const EPS: f32 = 1e-5;

/// Most list entries per bounded instance (plus a constant) before the grid is given up:
/// instances much larger than a cell would fill every cell.
const MAX_ENTRIES_PER_INSTANCE: usize = 16;

/// The grid of one light direction.
#[derive(Clone, Debug)]
pub(crate) struct DirGrid {
    /// Unit direction toward the light, bit for bit as the shadow rays carry it.
    pub dir: Vec3,
    /// Axes of the plane across `dir`.
    u: Vec3,
    v: Vec3,
    /// Plane coordinates of the grid's lower corner, cells per unit, cell counts.
    lo: [f32; 2],
    hi: [f32; 2],
    inv_cell: [f32; 2],
    n: [u32; 2],
    /// Centre of the instances' bounds and the size that scales the margins.
    center: Vec3,
    scale: f32,
    /// Cell `c` lists `ids[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    ids: Vec<u32>,
}

/// Two unit vectors across unit `d`, and across each other (in f64, so that `d·u` and
/// `d·v` are within rounding of zero).
fn plane_axes(d: Vec3) -> (Vec3, Vec3) {
    let d = d.as_dvec3().normalize();
    let helper = if d.x.abs() < 0.6 { DVec3::X } else { DVec3::Y };
    let u = d.cross(helper).normalize();
    let v = d.cross(u).normalize();
    (u.as_vec3(), v.as_vec3())
}

impl DirGrid {
    /// The grid for rays along unit `dir` over the world boxes `boxes` (instance `i` has
    /// `boxes[i]`; empty and unbounded ones are left out: the caller tests unbounded
    /// instances itself). `None` when there is nothing to list, or when the footprints are
    /// so large that lists would not narrow anything down.
    pub(crate) fn build(dir: Vec3, boxes: &[Aabb], bounds: &Aabb) -> Option<Self> {
        if !dir.is_finite() || bounds.is_empty() || !bounds.is_finite() {
            return None;
        }
        let (u, v) = plane_axes(dir);
        let center = (bounds.min + bounds.max) * 0.5;
        let scale = center.abs().max_element() + (bounds.max - bounds.min).max_element();
        let margin = EPS * scale;
        let footprint = |b: &Aabb| {
            let (c, e) = ((b.min + b.max) * 0.5, (b.max - b.min) * 0.5);
            let (cu, cv) = (c.dot(u), c.dot(v));
            let (hu, hv) = (e.dot(u.abs()) + margin, e.dot(v.abs()) + margin);
            [cu - hu, cu + hu, cv - hv, cv + hv]
        };
        let usable = |b: &Aabb| !b.is_empty() && b.is_finite();
        let mut lo = [f32::INFINITY; 2];
        let mut hi = [f32::NEG_INFINITY; 2];
        let mut prints = Vec::with_capacity(boxes.len());
        for (i, b) in boxes.iter().enumerate().filter(|(_, b)| usable(b)) {
            let f = footprint(b);
            lo = [lo[0].min(f[0]), lo[1].min(f[2])];
            hi = [hi[0].max(f[1]), hi[1].max(f[3])];
            prints.push((i as u32, f));
        }
        let count = prints.len();
        if count == 0 || !(lo[0].is_finite() && lo[1].is_finite() && hi[0].is_finite() && hi[1].is_finite()) {
            return None;
        }
        // About two cells per instance, square in the plane.
        let (w, h) = ((hi[0] - lo[0]).max(margin), (hi[1] - lo[1]).max(margin));
        let cell = (w * h / (2 * count) as f32).sqrt();
        let n = [((w / cell).ceil() as u32).clamp(1, 1024), ((h / cell).ceil() as u32).clamp(1, 1024)];
        let inv_cell = [n[0] as f32 / w, n[1] as f32 / h];
        let mut g = Self { dir, u, v, lo, hi, inv_cell, n, center, scale, start: vec![0; (n[0] * n[1]) as usize + 1], ids: Vec::new() };
        // Counting sort of (cell, instance) pairs: count, prefix sums, fill.
        let mut entries = 0usize;
        for (_, f) in &prints {
            let [x0, x1, y0, y1] = g.cells(f);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    g.start[(y * n[0] + x) as usize + 1] += 1;
                }
            }
            entries += ((x1 - x0 + 1) * (y1 - y0 + 1)) as usize;
            if entries > MAX_ENTRIES_PER_INSTANCE * count + 1024 {
                return None;
            }
        }
        for c in 1..g.start.len() {
            g.start[c] += g.start[c - 1];
        }
        g.ids = vec![0; entries];
        let mut next = g.start.clone();
        for &(i, ref f) in &prints {
            let [x0, x1, y0, y1] = g.cells(f);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = (y * n[0] + x) as usize;
                    g.ids[next[c] as usize] = i;
                    next[c] += 1;
                }
            }
        }
        Some(g)
    }

    /// The cell range `[x0, x1, y0, y1]` of the plane rectangle `[u0, u1, v0, v1]`, clamped
    /// to the grid (a monotonic function of each coordinate).
    #[inline]
    fn cells(&self, r: &[f32; 4]) -> [u32; 4] {
        let at = |x: f32, k: usize| -> u32 {
            // Clamped first, truncation is the floor. (NaN would go to 0; callers reject
            // non-finite input first.)
            ((x - self.lo[k]) * self.inv_cell[k]).clamp(0.0, (self.n[k] - 1) as f32) as u32
        };
        [at(r[0], 0), at(r[1], 0), at(r[2], 1), at(r[3], 1)]
    }

    /// The instances that rays along [`DirGrid::dir`] from origins inside the world box
    /// `[omin, omax]` can meet (besides the unbounded ones), into `out`; `None` when there
    /// are more than [`MAX_CANDIDATES`] or the box is not finite.
    #[inline]
    pub(crate) fn candidates(&self, omin: Vec3, omax: Vec3, out: &mut [u32; MAX_CANDIDATES]) -> Option<usize> {
        if !(omin.is_finite() && omax.is_finite()) {
            return None;
        }
        // The origins' footprint, grown by the margin at their distance from the bounds.
        let (c, e) = ((omin + omax) * 0.5, (omax - omin) * 0.5);
        let far = (c - self.center).abs().max_element() + e.max_element();
        let margin = EPS * (self.scale + far);
        let (cu, cv) = (c.dot(self.u), c.dot(self.v));
        let (hu, hv) = (e.dot(self.u.abs()) + margin, e.dot(self.v.abs()) + margin);
        let r = [cu - hu, cu + hu, cv - hv, cv + hv];
        // Wholly outside the grid: nothing bounded lies along these rays.
        if r[1] < self.lo[0] || r[3] < self.lo[1] || r[0] > self.hi[0] || r[2] > self.hi[1] {
            return Some(0);
        }
        let [x0, x1, y0, y1] = self.cells(&r);
        let mut k = 0;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let c = (y * self.n[0] + x) as usize;
                for &id in &self.ids[self.start[c] as usize..self.start[c + 1] as usize] {
                    if out[..k].contains(&id) {
                        continue;
                    }
                    if k == MAX_CANDIDATES {
                        return None;
                    }
                    out[k] = id;
                    k += 1;
                }
            }
        }
        Some(k)
    }
}
