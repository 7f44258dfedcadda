//! Rays, hits and axis-aligned boxes: the plain data every kernel shares.

use glam::{Affine3A, Vec3};

/// A ray `org + t * dir` for `t` in `[tmin, tmax)`.
///
/// `dir` need not be normalized: two-level traversal transforms it into object space
/// without renormalizing, so `t` means the same thing in every space.
// `repr(C)`: the eight floats in this order, so a packet loads a ray with one vector load.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Ray {
    /// Origin.
    pub org: Vec3,
    /// Direction (any length but zero).
    pub dir: Vec3,
    /// Smallest accepted hit distance (inclusive).
    pub tmin: f32,
    /// Largest accepted hit distance (exclusive); `f32::INFINITY` for a closest-hit ray.
    pub tmax: f32,
}

impl Ray {
    /// A ray from `org` along `dir` over `[0, inf)`.
    #[must_use]
    pub fn new(org: Vec3, dir: Vec3) -> Self {
        Self { org, dir, tmin: 0.0, tmax: f32::INFINITY }
    }

    /// The same ray restricted to `[tmin, tmax)`.
    #[must_use]
    pub fn with_range(mut self, tmin: f32, tmax: f32) -> Self {
        self.tmin = tmin;
        self.tmax = tmax;
        self
    }

    /// Point at distance `t`.
    #[must_use]
    pub fn at(&self, t: f32) -> Vec3 {
        self.org + self.dir * t
    }

    /// The ray carried into another space by an affine map (direction not renormalized).
    #[must_use]
    pub fn transformed(&self, to_from: &Affine3A) -> Self {
        Self { org: to_from.transform_point3(self.org), dir: to_from.transform_vector3(self.dir), tmin: self.tmin, tmax: self.tmax }
    }
}

/// A closest-hit record: 20 bytes, everything else is rebuilt by shading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray (in units of the ray's direction length).
    pub t: f32,
    /// First barycentric (weight of vertex 1) or surface parameter.
    pub u: f32,
    /// Second barycentric (weight of vertex 2) or surface parameter.
    pub v: f32,
    /// Primitive id inside the instance's geometry (triangle index, or shape part).
    pub prim: u32,
    /// Instance id (`u32::MAX` for a single-level query).
    pub inst: u32,
}

impl Hit {
    /// "No hit yet" with the search limited to `tmax`.
    #[must_use]
    pub fn none(tmax: f32) -> Self {
        Self { t: tmax, u: 0.0, v: 0.0, prim: INVALID, inst: INVALID }
    }

    /// A copy read field by field. PERF: the kernels end with the hit's fields just stored
    /// one or two at a time; a plain copy reads them 16 bytes at once, across those stores,
    /// which defeats store forwarding (a stall at the end of every query that hits).
    #[inline(always)]
    #[must_use]
    pub fn reload(&self) -> Self {
        // SAFETY: reads of valid, aligned f32/u32 fields of `self`.
        unsafe {
            Self {
                t: std::ptr::read_volatile(&self.t),
                u: std::ptr::read_volatile(&self.u),
                v: std::ptr::read_volatile(&self.v),
                prim: std::ptr::read_volatile(&self.prim),
                inst: std::ptr::read_volatile(&self.inst),
            }
        }
    }

    /// True when a primitive was hit.
    #[must_use]
    pub fn is_hit(&self) -> bool {
        self.prim != INVALID
    }
}

/// The id meaning "none".
pub const INVALID: u32 = u32::MAX;

/// An axis-aligned bounding box. The empty box has `min = +inf`, `max = -inf`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box (the identity of `union`).
    pub const EMPTY: Self = Self { min: Vec3::INFINITY, max: Vec3::NEG_INFINITY };

    /// The box spanning the given points.
    #[must_use]
    pub fn from_points(pts: &[Vec3]) -> Self {
        pts.iter().fold(Self::EMPTY, |b, &p| b.grow(p))
    }

    /// This box grown to contain `p`.
    #[must_use]
    pub fn grow(self, p: Vec3) -> Self {
        Self { min: self.min.min(p), max: self.max.max(p) }
    }

    /// The smallest box containing both.
    #[must_use]
    pub fn union(self, o: Self) -> Self {
        Self { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    /// True for the empty box (or any inverted one).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// True when both corners are finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.min.is_finite() && self.max.is_finite()
    }

    /// Size along each axis.
    #[must_use]
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }

    /// Centre.
    #[must_use]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Half the surface area (all the SAH needs); 0 for an empty box.
    #[must_use]
    pub fn half_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// Length of the diagonal.
    #[must_use]
    pub fn diagonal(&self) -> f32 {
        if self.is_empty() {
            0.0
        } else {
            self.extent().length()
        }
    }

    /// The box of this box's eight corners carried by an affine map.
    #[must_use]
    pub fn transformed(&self, m: &Affine3A) -> Self {
        if self.is_empty() {
            return *self;
        }
        // Arvo's method: per output axis, sum the min/max of each matrix column's contribution.
        let mut lo = m.translation;
        let mut hi = lo;
        let cols = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
        let mn = [self.min.x, self.min.y, self.min.z];
        let mx = [self.max.x, self.max.y, self.max.z];
        for k in 0..3 {
            let a = cols[k] * mn[k];
            let b = cols[k] * mx[k];
            lo += a.min(b);
            hi += a.max(b);
        }
        Self { min: lo.into(), max: hi.into() }
    }

    /// True when `p` lies inside or on the box.
    #[must_use]
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
}
