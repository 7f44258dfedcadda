//! The per-hit arithmetic of the Whitted integrator, written once and used two ways: ray by
//! ray on `f32`s ([`crate::integrator::li`]), and on a packet's hits in
//! structure-of-arrays form, eight hits at a time ([`HitLanes`], for
//! [`crate::integrator::li_packet`]).
//!
//! The functions ([`orient`], [`light_lane`], [`pow_fast`]) are generic over [`Real`]:
//! `f32`, or [`F8`], eight lanes whose operations are loops the compiler turns into one AVX2
//! instruction each (in functions compiled with AVX2, chosen at run time; the baseline
//! build of the same loops is the fallback). They are branch-free (selects only) and use no
//! fused multiply-adds, so every width gives bit for bit the same answers: IEEE add,
//! multiply, divide and square root are correctly rounded whatever the width.

// Lane loops index several arrays by the lane number; written so, they vectorize.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;
use lucent_accel::{RayBlock, MAX_PACKET};
use lucent_scene::{Light, LightKind, Material};
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// Hits per packet.
pub(crate) const N: usize = MAX_PACKET;
/// Lanes of an [`F8`] and of a shadow-ray block.
const W: usize = 8;

/// A number the shading arithmetic runs on: one `f32`, or eight ([`F8`]).
pub(crate) trait Real:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
{
    /// Lane-wise truth values.
    type Mask: Copy + BitAnd<Output = Self::Mask> + BitOr<Output = Self::Mask> + Not<Output = Self::Mask>;
    fn splat(v: f32) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    /// `a` where `m`, else `b`.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// The unbiased exponent field (as a float) and the significand with a zero exponent
    /// (in `[1, 2)`) of positive normal numbers.
    fn exponent_mantissa(self) -> (Self, Self);
    /// `2^n` for integral `n` in `[-126, 127]`.
    fn exp2i(self) -> Self;
    /// `x^y` for the Phong term: [`pow_unit`] on `f32`, [`pow_fast`] on lanes (whose
    /// out-of-range lanes are redone one by one).
    fn phong_pow(x: Self, y: Self) -> Self;
}

/// `self > o ? self : o` (`maxps`: `o` when either is NaN).
#[inline(always)]
fn max<T: Real>(a: T, b: T) -> T {
    T::select(a.gt(b), a, b)
}

/// Neither infinite nor NaN.
#[inline(always)]
fn finite<T: Real>(a: T) -> T::Mask {
    a.abs().lt(T::splat(f32::INFINITY))
}

/// `1.5·2^23`: adding and taking it away rounds to an integer; `2^23 + 127` biases one.
pub(crate) const ROUND: f32 = 12_582_912.0;
const BIAS: f32 = 8_388_735.0;

impl Real for f32 {
    type Mask = bool;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> bool {
        self < o
    }
    #[inline(always)]
    fn le(self, o: Self) -> bool {
        self <= o
    }
    #[inline(always)]
    fn gt(self, o: Self) -> bool {
        self > o
    }
    #[inline(always)]
    fn ge(self, o: Self) -> bool {
        self >= o
    }
    #[inline(always)]
    fn select(m: bool, a: Self, b: Self) -> Self {
        if m {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn exponent_mantissa(self) -> (Self, Self) {
        let bits = self.to_bits();
        (((bits >> 23) & 0xff) as i32 as f32 - 127.0, f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000))
    }
    #[inline(always)]
    fn phong_pow(x: Self, y: Self) -> Self {
        pow_unit(x, y)
    }
    #[inline(always)]
    fn exp2i(self) -> Self {
        // 2^23 + 127 + n holds n + 127 in its low significand bits; shifting them into the
        // exponent field drops the rest.
        f32::from_bits((self + BIAS).to_bits() << 23)
    }
}

use lucent_accel::simd::{F8, M8};

macro_rules! compare {
    ($name:ident, $op:tt) => {
        #[inline(always)]
        fn $name(self, o: Self) -> M8 {
            let mut r = [0i32; W];
            for i in 0..W {
                r[i] = -((self.0[i] $op o.0[i]) as i32);
            }
            M8(r)
        }
    };
}

impl Real for F8 {
    type Mask = M8;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        F8([v; W])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        F8(self.0.map(f32::sqrt))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        F8(self.0.map(|x| f32::from_bits(x.to_bits() & 0x7fff_ffff)))
    }
    compare!(lt, <);
    compare!(le, <=);
    compare!(gt, >);
    compare!(ge, >=);
    #[inline(always)]
    fn select(m: M8, a: Self, b: Self) -> Self {
        let mut r = [0f32; W];
        for i in 0..W {
            let k = m.0[i] as u32;
            r[i] = f32::from_bits((a.0[i].to_bits() & k) | (b.0[i].to_bits() & !k));
        }
        F8(r)
    }
    #[inline(always)]
    fn exponent_mantissa(self) -> (Self, Self) {
        let mut e = [0f32; W];
        let mut m = [0f32; W];
        for i in 0..W {
            let bits = self.0[i].to_bits();
            e[i] = ((bits >> 23) & 0xff) as i32 as f32 - 127.0;
            m[i] = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
        }
        (F8(e), F8(m))
    }
    #[inline(always)]
    fn phong_pow(x: Self, y: Self) -> Self {
        pow_fast(x, y)
    }
    #[inline(always)]
    fn exp2i(self) -> Self {
        F8(self.0.map(|n| f32::from_bits((n + BIAS).to_bits() << 23)))
    }
}

/// A 3-vector of [`Real`]s (glam's `Vec3` arithmetic, in the same order of operations).
#[derive(Clone, Copy, Debug)]
pub(crate) struct V3<T> {
    pub x: T,
    pub y: T,
    pub z: T,
}

impl<T: Real> V3<T> {
    #[inline(always)]
    fn splat3(v: Vec3) -> Self {
        V3 { x: T::splat(v.x), y: T::splat(v.y), z: T::splat(v.z) }
    }
    #[inline(always)]
    fn zero() -> Self {
        Self::splat3(Vec3::ZERO)
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        V3 { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        V3 { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        V3 { x: self.x * o.x, y: self.y * o.y, z: self.z * o.z }
    }
    #[inline(always)]
    fn scale(self, k: T) -> Self {
        V3 { x: self.x * k, y: self.y * k, z: self.z * k }
    }
    #[inline(always)]
    fn div(self, k: T) -> Self {
        V3 { x: self.x / k, y: self.y / k, z: self.z / k }
    }
    #[inline(always)]
    fn neg(self) -> Self {
        V3 { x: -self.x, y: -self.y, z: -self.z }
    }
    #[inline(always)]
    fn dot(self, o: Self) -> T {
        (self.x * o.x) + (self.y * o.y) + (self.z * o.z)
    }
    #[inline(always)]
    fn length(self) -> T {
        self.dot(self).sqrt()
    }
    #[inline(always)]
    fn normalize(self) -> Self {
        self.scale(T::splat(1.0) / self.length())
    }
    #[inline(always)]
    fn max_element(self) -> T {
        max(self.x, max(self.y, self.z))
    }
    #[inline(always)]
    fn select(m: T::Mask, a: Self, b: Self) -> Self {
        V3 { x: T::select(m, a.x, b.x), y: T::select(m, a.y, b.y), z: T::select(m, a.z, b.z) }
    }
}

impl From<Vec3> for V3<f32> {
    #[inline(always)]
    fn from(v: Vec3) -> Self {
        V3 { x: v.x, y: v.y, z: v.z }
    }
}

impl From<V3<f32>> for Vec3 {
    #[inline(always)]
    fn from(v: V3<f32>) -> Self {
        Vec3::new(v.x, v.y, v.z)
    }
}

impl V3<F8> {
    #[inline(always)]
    fn load(rows: &[[f32; N]; 3], j: usize) -> Self {
        V3 { x: F8::load(&rows[0], j), y: F8::load(&rows[1], j), z: F8::load(&rows[2], j) }
    }
    #[inline(always)]
    fn store(self, rows: &mut [[f32; N]; 3], j: usize) {
        self.x.store(&mut rows[0], j);
        self.y.store(&mut rows[1], j);
        self.z.store(&mut rows[2], j);
    }
}

/// `p` moved off its surface along the unit normal `n` by `off`, the hit's error bound
/// projected on the normal with the margin for rounding this sum
/// ([`crate::Surface::offset`]).
#[inline(always)]
pub(crate) fn offset<T: Real>(p: V3<T>, n: V3<T>, off: T) -> V3<T> {
    p.add(n.scale(off))
}

/// A hit seen from its ray.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Oriented<T: Real> {
    /// Unit ray direction.
    pub d: V3<T>,
    /// The ray meets the side the geometric normal points to.
    pub front: T::Mask,
    /// Geometric and shading normals turned toward the ray's origin.
    pub ng: V3<T>,
    pub ns: V3<T>,
    /// Origin of rays leaving on the ray's side, and how far along the normal it lies from
    /// the hit point.
    pub p_out: V3<T>,
    pub off: T,
}

/// Orients a hit at `p` with normals `ng`, `ns` (as the geometry is wound) toward the ray
/// `dir` came along; rays leaving it start `off` (its [`crate::Surface::offset`]) along
/// the oriented normal.
#[inline(always)]
pub(crate) fn orient<T: Real>(dir: V3<T>, ng: V3<T>, ns: V3<T>, p: V3<T>, off: T) -> Oriented<T> {
    let d = dir.normalize();
    let front = d.dot(ng).lt(T::splat(0.0));
    let ng = V3::select(front, ng, ng.neg());
    let ns = V3::select(front, ns, ns.neg());
    let p_out = offset(p, ng, off);
    Oriented { d, front, ng, ns, p_out, off }
}

/// What a light is, with its per-light constants worked out once.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LightConst {
    kind: u8,
    position: Vec3,
    /// Directional: the unit direction toward the light. Spot: the unit direction it shines.
    dir: Vec3,
    cos_inner: f32,
    cos_outer: f32,
    color: Vec3,
    inverse_square: bool,
}

const POINT: u8 = 0;
const DIRECTIONAL: u8 = 1;
const SPOT: u8 = 2;

/// The unit direction toward a directional light that shines along `direction`: the
/// direction of its shadow rays, bit for bit (the top level's shadow grids match on it).
pub(crate) fn toward_directional(direction: Vec3) -> Vec3 {
    -direction.normalize()
}

impl LightConst {
    pub(crate) fn new(l: &Light) -> Self {
        let (kind, position, dir, cos_inner, cos_outer) = match l.kind {
            LightKind::Point { position } => (POINT, position, Vec3::ZERO, 0.0, 0.0),
            LightKind::Directional { direction } => (DIRECTIONAL, Vec3::ZERO, toward_directional(direction), 0.0, 0.0),
            LightKind::Spot { position, direction, inner, outer } => (SPOT, position, direction.normalize(), inner.cos(), outer.cos()),
        };
        Self { kind, position, dir, cos_inner, cos_outer, color: l.color, inverse_square: l.inverse_square }
    }
}

/// What shading a hit needs from its material and the light-independent part of its
/// orientation, for [`light_lane`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct LitPoint<T: Real> {
    pub p: V3<T>,
    pub d: V3<T>,
    pub ng: V3<T>,
    pub ns: V3<T>,
    pub off: T,
    pub kd: V3<T>,
    pub opaque: T,
    pub specular: V3<T>,
    /// `specular` has a positive component.
    pub spec_any: T::Mask,
    pub shininess: T,
}

/// One light at one hit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LightSample<T: Real> {
    /// Light reflected toward the eye when nothing blocks the light.
    pub term: V3<T>,
    /// Unit direction toward the light, and how far a shadow ray from `p_out` must be clear.
    pub ldir: V3<T>,
    pub tmax: T,
    /// The light reaches the front of the surface at all.
    pub valid: T::Mask,
    /// The specular power was out of [`pow_fast`]'s range (redo with [`pow_unit`]).
    pub slow: T::Mask,
}

/// Light `lc` (of kind `K`) at hit `h`: Lambert diffuse plus Phong specular, and the shadow
/// ray's extent.
#[inline(always)]
pub(crate) fn light_lane<T: Real, const K: u8>(lc: &LightConst, h: &LitPoint<T>) -> LightSample<T> {
    let zero = T::splat(0.0);
    let inf = T::splat(f32::INFINITY);
    let (ldir, dist, rad) = match K {
        DIRECTIONAL => (V3::splat3(lc.dir), inf, V3::splat3(lc.color)),
        _ => {
            let to = V3::splat3(lc.position).sub(h.p);
            let dist = to.length();
            let ldir = to.div(dist);
            if K == POINT {
                (ldir, dist, V3::splat3(lc.color))
            } else {
                let cos = ldir.neg().dot(V3::splat3(lc.dir));
                let (ci, co) = (lc.cos_inner, lc.cos_outer);
                let f = if ci > co {
                    let f = (cos - T::splat(co)) / T::splat(ci - co);
                    let f = T::select(f.lt(zero), zero, f);
                    T::select(f.gt(T::splat(1.0)), T::splat(1.0), f)
                } else {
                    T::select(cos.ge(T::splat(co)), T::splat(1.0), zero)
                };
                (ldir, dist, V3::splat3(lc.color).scale(f).scale(f))
            }
        }
    };
    let rad = if lc.inverse_square {
        // Dividing by one leaves the values as they were.
        let q = T::select(finite(dist), max(dist * dist, T::splat(1e-12)), T::splat(1.0));
        rad.div(q)
    } else {
        rad
    };
    let cos = h.ns.dot(ldir);
    let valid = !(cos.le(zero) | h.ng.dot(ldir).le(zero) | rad.max_element().le(zero) | !finite(cos));
    let tmax = T::select(finite(dist), (dist - h.off) * T::splat(1.0 - 1e-4), inf);
    let v = h.d.neg();
    let l = ldir.neg();
    let r = l.sub(h.ns.scale(T::splat(2.0) * l.dot(h.ns)));
    let rv = r.dot(v);
    // 0^shininess is 0 for a positive exponent, so the power is only needed where the
    // mirror direction faces the eye.
    let use_spec = h.spec_any & (rv.gt(zero) | h.shininess.le(zero));
    let x = max(rv, zero);
    let spec = V3::select(use_spec, h.specular.scale(T::phong_pow(x, h.shininess)), V3::zero());
    let term = rad.mul(h.kd.scale(cos).scale(h.opaque).add(spec));
    LightSample { term, ldir, tmax, valid, slow: use_spec & pow_needs_slow(x, h.shininess) }
}

/// [`light_lane`] on one hit for any light, with the exact power (the ray-by-ray form).
#[inline(always)]
pub(crate) fn light_sample(lc: &LightConst, h: &LitPoint<f32>) -> LightSample<f32> {
    match lc.kind {
        POINT => light_lane::<f32, POINT>(lc, h),
        DIRECTIONAL => light_lane::<f32, DIRECTIONAL>(lc, h),
        _ => light_lane::<f32, SPOT>(lc, h),
    }
}

/// `x^y` needs `powf`: outside `x` in `(0, 1]`, `y` in `(0, 4096]`, or `x` subnormal.
#[inline(always)]
fn pow_needs_slow<T: Real>(x: T, y: T) -> T::Mask {
    !(x.gt(T::splat(0.0)) & x.le(T::splat(1.0)) & y.gt(T::splat(0.0)) & y.le(T::splat(4096.0))) | x.lt(T::splat(f32::MIN_POSITIVE))
}

/// `x^y` for the Phong term: `x` in `(0, 1]` and `y` in `(0, 4096]` by `exp2(y·log2 x)`
/// with short series (relative error below 2e-5 for these arguments, against `powf`'s
/// exactly rounded result; PERF: `powf` was 5–7% of a shaded frame of the BART kitchen and
/// of the sunflowers); anything else goes to `powf`.
#[inline]
pub(crate) fn pow_unit(x: f32, y: f32) -> f32 {
    if pow_needs_slow(x, y) {
        x.powf(y)
    } else {
        pow_fast(x, y)
    }
}

/// [`pow_unit`]'s series, branch-free; meaningful only where [`pow_needs_slow`] is false.
#[inline(always)]
pub(crate) fn pow_fast<T: Real>(x: T, y: T) -> T {
    // log2 x = e + log2 m with m in [√½, √2): log2 m = 2/ln 2 · atanh((m − 1)/(m + 1)),
    // an odd series in s = (m − 1)/(m + 1), |s| ≤ 0.172 (next term below 2e-8).
    let one = T::splat(1.0);
    let (e, m) = x.exponent_mantissa();
    let big = m.gt(T::splat(std::f32::consts::SQRT_2));
    let m = T::select(big, m * T::splat(0.5), m);
    let e = T::select(big, e + one, e);
    let s = (m - one) / (m + one);
    let s2 = s * s;
    // PERF: the series in Estrin's form (two short chains rather than one long one).
    let atanh = s * ((one + s2 * T::splat(1.0 / 3.0)) + (s2 * s2) * (T::splat(1.0 / 5.0) + s2 * T::splat(1.0 / 7.0)));
    let z = y * (e + T::splat(2.0 * std::f32::consts::LOG2_E) * atanh);
    // 2^z = 2^n · 2^f with n = z rounded to nearest, so f is in [−½, ½]: e^(f ln 2) by its
    // Taylor series to the 5th power (next term below 2.5e-6), in Estrin's form. x ≤ 1 and
    // y > 0 make z ≤ 0; below 2^-126 the answer is 0.
    let r = (z + T::splat(ROUND)) - T::splat(ROUND);
    let g = (z - r) * T::splat(std::f32::consts::LN_2);
    let g2 = g * g;
    let p = (one + g) + g2 * ((T::splat(0.5) + g * T::splat(1.0 / 6.0)) + g2 * (T::splat(1.0 / 24.0) + g * T::splat(1.0 / 120.0)));
    T::select(z.lt(T::splat(-126.0)), T::splat(0.0), p * r.exp2i())
}

/// The hits of a packet in structure-of-arrays form: hit `j` (of `m`, in the order of their
/// rays) sits in lane `j` of every row. The gather (the integrator) fills `slot`, `p`,
/// `dir`, `ng`, `ns` and the material rows; [`HitLanes::orient`] turns the ray and normal
/// rows into [`Oriented`]'s; [`HitLanes::light`] evaluates one light at every hit.
#[derive(Clone)]
pub(crate) struct HitLanes {
    /// Hits held.
    pub m: usize,
    /// Which ray of the packet each hit belongs to.
    pub slot: [u8; N],
    /// Hit points.
    pub p: [[f32; N]; 3],
    /// Ray directions as traced; unit after `orient`.
    pub dir: [[f32; N]; 3],
    /// Normals as wound; toward the ray's origin after `orient`.
    pub ng: [[f32; N]; 3],
    pub ns: [[f32; N]; 3],
    /// Diffuse reflectance (textured), opacity, Phong specular and exponent.
    pub kd: [[f32; N]; 3],
    pub opaque: [f32; N],
    pub specular: [[f32; N]; 3],
    /// Lanes whose `specular` has a positive component (one bit each).
    pub spec_any: u64,
    pub shininess: [f32; N],
    /// Filled by `orient`: the rays meeting the front side (one bit each) and the exit
    /// points; `off` is given (each hit's [`crate::Surface::offset`]).
    pub front: u64,
    pub p_out: [[f32; N]; 3],
    pub off: [f32; N],
}

/// One light's contribution at every hit of a [`HitLanes`].
pub(crate) struct LightLanes {
    pub term: [[f32; N]; 3],
    /// Lanes the light reaches (one bit each).
    pub valid: u64,
    /// Shadow rays, lane `j` of the hits in lane `j % 8` of block `j / 8` (empty where the
    /// light does not count).
    pub blocks: [RayBlock; N / W],
    /// Lanes whose specular power is out of [`pow_fast`]'s range.
    slow: u64,
}

impl LightLanes {
    pub(crate) fn new() -> Self {
        Self { term: [[0.0; N]; 3], valid: 0, blocks: [RayBlock::EMPTY; N / W], slow: 0 }
    }
}

/// Lane `j` of three rows.
#[inline(always)]
pub(crate) fn v3(rows: &[[f32; N]; 3], j: usize) -> Vec3 {
    Vec3::new(rows[0][j], rows[1][j], rows[2][j])
}

/// Sets lane `j` of three rows.
#[inline(always)]
pub(crate) fn put3(rows: &mut [[f32; N]; 3], j: usize, v: Vec3) {
    rows[0][j] = v.x;
    rows[1][j] = v.y;
    rows[2][j] = v.z;
}

/// The eight bits of a mask.
#[inline(always)]
fn bits8(m: M8) -> u64 {
    let mut b = 0u64;
    for (i, &k) in m.0.iter().enumerate() {
        b |= u64::from(k as u32 >> 31) << i;
    }
    b
}

/// A mask from eight bits.
#[inline(always)]
fn mask8(b: u64) -> M8 {
    M8::from_bits((b & 0xff) as u32)
}

impl HitLanes {
    pub(crate) fn new() -> Self {
        let z = [[0.0; N]; 3];
        Self {
            m: 0,
            slot: [0; N],
            p: z,
            dir: z,
            ng: z,
            ns: z,
            kd: z,
            opaque: [0.0; N],
            specular: z,
            spec_any: 0,
            shininess: [0.0; N],
            front: 0,
            p_out: z,
            off: [0.0; N],
        }
    }

    /// Blocks of eight lanes holding the `m` hits.
    fn blocks(&self) -> usize {
        self.m.div_ceil(W)
    }

    /// Lanes that hold hits.
    fn held(&self) -> u64 {
        if self.m >= 64 {
            u64::MAX
        } else {
            (1u64 << self.m) - 1
        }
    }

    /// The light-independent part of hit `j`, for the ray-by-ray form.
    #[inline(always)]
    pub(crate) fn lit_point(&self, j: usize) -> LitPoint<f32> {
        LitPoint {
            p: v3(&self.p, j).into(),
            d: v3(&self.dir, j).into(),
            ng: v3(&self.ng, j).into(),
            ns: v3(&self.ns, j).into(),
            off: self.off[j],
            kd: v3(&self.kd, j).into(),
            opaque: self.opaque[j],
            specular: v3(&self.specular, j).into(),
            spec_any: (self.spec_any >> j) & 1 == 1,
            shininess: self.shininess[j],
        }
    }

    /// Lanes `j..j + 8`.
    #[inline(always)]
    fn lit_point8(&self, j: usize) -> LitPoint<F8> {
        LitPoint {
            p: V3::load(&self.p, j),
            d: V3::load(&self.dir, j),
            ng: V3::load(&self.ng, j),
            ns: V3::load(&self.ns, j),
            off: F8::load(&self.off, j),
            kd: V3::load(&self.kd, j),
            opaque: F8::load(&self.opaque, j),
            specular: V3::load(&self.specular, j),
            spec_any: mask8(self.spec_any >> j),
            shininess: F8::load(&self.shininess, j),
        }
    }

    /// [`orient`] on every hit (in place: `dir` becomes the unit direction, the normals face
    /// the rays' origins).
    pub(crate) fn orient(&mut self) {
        #[cfg(target_arch = "x86_64")]
        if lucent_accel::simd::avx2_fma() {
            // SAFETY: AVX2 and FMA were detected on this CPU.
            unsafe { self.orient_avx2() };
            return;
        }
        self.orient_lanes();
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn orient_avx2(&mut self) {
        self.orient_lanes();
    }

    #[inline(always)]
    fn orient_lanes(&mut self) {
        self.front = 0;
        for b in 0..self.blocks() {
            let j = b * W;
            let off = F8::load(&self.off, j);
            let o = orient(V3::load(&self.dir, j), V3::load(&self.ng, j), V3::load(&self.ns, j), V3::load(&self.p, j), off);
            o.d.store(&mut self.dir, j);
            o.ng.store(&mut self.ng, j);
            o.ns.store(&mut self.ns, j);
            o.p_out.store(&mut self.p_out, j);
            o.off.store(&mut self.off, j);
            self.front |= bits8(o.front) << j;
        }
    }

    /// Light `l` at every hit, into `out`: the terms, which lanes the light reaches, and the
    /// shadow rays (in blocks) that must be clear for them to count. Returns the number of
    /// shadow rays.
    pub(crate) fn light(&self, l: &Light, out: &mut LightLanes) -> usize {
        let lc = LightConst::new(l);
        #[cfg(target_arch = "x86_64")]
        if lucent_accel::simd::avx2_fma() {
            // SAFETY: AVX2 and FMA were detected on this CPU.
            unsafe {
                match lc.kind {
                    POINT => self.light_avx2::<POINT>(&lc, out),
                    DIRECTIONAL => self.light_avx2::<DIRECTIONAL>(&lc, out),
                    _ => self.light_avx2::<SPOT>(&lc, out),
                }
            }
            return self.light_fixup(&lc, out);
        }
        match lc.kind {
            POINT => self.light_lanes::<POINT>(&lc, out),
            DIRECTIONAL => self.light_lanes::<DIRECTIONAL>(&lc, out),
            _ => self.light_lanes::<SPOT>(&lc, out),
        }
        self.light_fixup(&lc, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn light_avx2<const K: u8>(&self, lc: &LightConst, out: &mut LightLanes) {
        self.light_lanes::<K>(lc, out);
    }

    /// Eight lanes at a time, straight into the shadow-ray blocks; lanes whose power is out
    /// of [`pow_fast`]'s range are marked in `out.slow` for [`HitLanes::light_fixup`].
    #[inline(always)]
    fn light_lanes<const K: u8>(&self, lc: &LightConst, out: &mut LightLanes) {
        let held = self.held();
        out.valid = 0;
        out.slow = 0;
        for b in 0..self.blocks() {
            let j = b * W;
            let s = light_lane::<F8, K>(lc, &self.lit_point8(j));
            let ok = s.valid & mask8(held >> j);
            s.term.store(&mut out.term, j);
            let blk = &mut out.blocks[b];
            blk.org = [0, 1, 2].map(|k| F8::load(&self.p_out[k], j).0);
            blk.dir = [s.ldir.x.0, s.ldir.y.0, s.ldir.z.0];
            blk.tmin = [0.0; W];
            blk.tmax = F8::select(ok, s.tmax, F8::splat(f32::NEG_INFINITY)).0;
            out.valid |= bits8(ok) << j;
            out.slow |= bits8(s.slow & ok) << j;
        }
    }

    /// Redoes the lanes whose specular power needs `powf`, one by one; returns the number of
    /// lanes the light reaches.
    fn light_fixup(&self, lc: &LightConst, out: &mut LightLanes) -> usize {
        let mut bits = out.slow;
        while bits != 0 {
            let j = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let s = light_sample(lc, &self.lit_point(j));
            put3(&mut out.term, j, s.term.into());
        }
        out.valid.count_ones() as usize
    }
}

/// Lane buffers for shading one packet.
pub(crate) struct Scratch {
    pub h: HitLanes,
    pub ll: LightLanes,
}

thread_local! {
    /// Each thread's free lane buffers (one set per level of recursion in use).
    static LANE_POOL: std::cell::RefCell<Vec<Box<Scratch>>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Runs `f` with lane buffers of this thread's (PERF: zeroing 13 KB of fresh buffers per
/// packet was a twentieth of a sparse REND3R frame). The buffers hold the last packet's
/// values: every field a packet reads is written first, except `spec_any`, which the
/// gather clears.
pub(crate) fn with_scratch<R>(f: impl FnOnce(&mut Scratch) -> R) -> R {
    let mut sc =
        LANE_POOL.with(|v| v.borrow_mut().pop()).unwrap_or_else(|| Box::new(Scratch { h: HitLanes::new(), ll: LightLanes::new() }));
    let r = f(&mut sc);
    LANE_POOL.with(|v| v.borrow_mut().push(sc));
    r
}

/// The specular and diffuse part of a material at a hit (`kd` already textured).
#[derive(Clone, Copy, Debug)]
pub(crate) struct MatTerms {
    pub kd: Vec3,
    pub transmit: f32,
    pub opaque: f32,
    /// Emitted plus ambient light.
    pub c: Vec3,
}

/// [`MatTerms`] of material `mat` with textured diffuse `kd`, under ambient light `ambient`.
#[inline(always)]
pub(crate) fn mat_terms(mat: &Material, kd: Vec3, ambient: Vec3) -> MatTerms {
    let transmit = mat.transmit.max_element().clamp(0.0, 1.0);
    let opaque = 1.0 - transmit;
    let ka = if mat.ambient != Vec3::ZERO { mat.ambient } else { kd };
    let c = mat.emission.min(Vec3::ONE) + ambient * ka * opaque;
    MatTerms { kd, transmit, opaque, c }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The Phong power against `powf` over the range it serves (relative error, with an
    /// absolute floor far below one 8-bit step), and `powf`'s answers outside it.
    #[test]
    fn pow_unit_matches_powf() {
        let mut worst = 0.0f64;
        for i in 1..=2000 {
            let x = i as f32 / 2000.0;
            for y in [0.01f32, 0.5, 1.0, 2.0, 5.0, 10.0, 32.0, 64.0, 96.078, 128.0, 500.0, 1000.0, 4096.0] {
                let (got, want) = (pow_unit(x, y) as f64, (x as f64).powf(y as f64));
                let err = (got - want).abs() / want.max(1e-30);
                if want > 1e-30 {
                    worst = worst.max(err);
                }
                assert!(err < 2e-5 || (got - want).abs() < 1e-12, "{x}^{y}: {got} against {want}");
            }
        }
        assert!(worst > 0.0, "the series is not exact");
        for (x, y) in [(0.0f32, 2.0f32), (0.5, 0.0), (0.5, -1.0), (1.5, 2.0), (0.5, 1e5), (1e-40, 0.5), (f32::NAN, 2.0)] {
            let (got, want) = (pow_unit(x, y), x.powf(y));
            assert!(got == want || (got.is_nan() && want.is_nan()), "{x}^{y}: {got} against {want}");
        }
    }

    fn random_lanes(rng: &mut rand_pcg::Pcg64, m: usize) -> HitLanes {
        let mut h = HitLanes::new();
        h.m = m;
        let mut f = |lo: f32, hi: f32| rng.random_range(lo..hi);
        for j in 0..m {
            for k in 0..3 {
                h.p[k][j] = f(-10.0, 10.0);
                h.dir[k][j] = f(-1.0, 1.0);
                h.ng[k][j] = f(-1.0, 1.0);
                h.kd[k][j] = f(0.0, 1.0);
                h.specular[k][j] = if j % 5 == 0 { 0.0 } else { f(0.0, 1.0) };
            }
            let ng = v3(&h.ng, j).normalize();
            put3(&mut h.ng, j, ng);
            // A shading normal near the geometric one, now and then on the other side.
            let ns = (ng + Vec3::new(f(-0.5, 0.5), f(-0.5, 0.5), f(-0.5, 0.5))).normalize();
            put3(&mut h.ns, j, ns);
            h.opaque[j] = f(0.0, 1.0);
            h.off[j] = f(0.0, 1e-4);
            h.spec_any |= u64::from(v3(&h.specular, j).max_element() > 0.0) << j;
            // Exponents in and out of the series' range (0 and above 4096 go to powf).
            h.shininess[j] = [0.0, 1.0, 10.0, 96.0, 5000.0, f(0.5, 300.0)][j % 6];
        }
        h
    }

    /// The lane loops, with AVX2 and in the baseline build, give bit for bit what the
    /// ray-by-ray functions give, for every kind of light, on random hits (partial last
    /// blocks included).
    #[test]
    fn lanes_match_ray_by_ray_shading() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let lights = [
            Light { kind: LightKind::Point { position: Vec3::new(1.0, 8.0, 2.0) }, color: Vec3::new(0.9, 0.8, 0.7), inverse_square: false },
            Light { kind: LightKind::Point { position: Vec3::new(-3.0, 2.0, 5.0) }, color: Vec3::splat(40.0), inverse_square: true },
            Light { kind: LightKind::Directional { direction: Vec3::new(0.3, -1.0, 0.2) }, color: Vec3::ONE, inverse_square: false },
            Light {
                kind: LightKind::Spot { position: Vec3::new(0.0, 9.0, 0.0), direction: -Vec3::Y, inner: 0.4, outer: 0.9 },
                color: Vec3::splat(2.0),
                inverse_square: false,
            },
        ];
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        let (mut lit, mut slow) = (0, 0);
        for m in [1, 7, 8, 13, 64] {
            let raw = random_lanes(&mut rng, m);
            let mut h = raw.clone();
            h.orient();
            let mut base = raw.clone();
            base.orient_lanes();
            for j in 0..m {
                let v = |rows: &[[f32; N]; 3]| V3::<f32>::from(v3(rows, j));
                let o = orient(v(&raw.dir), v(&raw.ng), v(&raw.ns), v(&raw.p), raw.off[j]);
                for g in [&h, &base] {
                    for (got, want) in [(&g.dir, o.d), (&g.ng, o.ng), (&g.ns, o.ns), (&g.p_out, o.p_out)] {
                        assert_eq!(bits(v3(got, j)), bits(want.into()), "orient, lane {j} of {m}");
                    }
                    assert_eq!(((g.front >> j) & 1 == 1, g.off[j].to_bits()), (o.front, o.off.to_bits()));
                }
            }
            for l in &lights {
                let lc = LightConst::new(l);
                let mut out = LightLanes::new();
                let rays = h.light(l, &mut out);
                let mut out_base = LightLanes::new();
                match lc.kind {
                    POINT => h.light_lanes::<POINT>(&lc, &mut out_base),
                    DIRECTIONAL => h.light_lanes::<DIRECTIONAL>(&lc, &mut out_base),
                    _ => h.light_lanes::<SPOT>(&lc, &mut out_base),
                }
                slow += out_base.slow.count_ones();
                h.light_fixup(&lc, &mut out_base);
                assert_eq!(rays, out.valid.count_ones() as usize);
                for j in 0..m {
                    let s = light_sample(&lc, &h.lit_point(j));
                    assert_eq!((out.valid >> j) & 1 == 1, s.valid, "lane {j} of {m}");
                    assert_eq!(out_base.valid, out.valid);
                    if !s.valid {
                        assert_eq!(out.blocks[j / 8].tmax[j % 8], f32::NEG_INFINITY);
                        continue;
                    }
                    lit += 1;
                    for t in [&out, &out_base] {
                        assert_eq!(bits(v3(&t.term, j)), bits(s.term.into()), "term, lane {j}");
                        let blk = &t.blocks[j / 8];
                        assert_eq!(blk.tmax[j % 8].to_bits(), s.tmax.to_bits());
                        assert_eq!(blk.tmin[j % 8].to_bits(), 0);
                        assert_eq!([0, 1, 2].map(|k| blk.dir[k][j % 8]), Vec3::from(s.ldir).to_array());
                        assert_eq!([0, 1, 2].map(|k| blk.org[k][j % 8]), v3(&h.p_out, j).to_array());
                    }
                }
                for j in m..m.next_multiple_of(8) {
                    assert!((out.valid >> j) & 1 == 0 && out.blocks[j / 8].tmax[j % 8] == f32::NEG_INFINITY, "padding lane {j}");
                }
            }
        }
        assert!(lit > 100 && slow > 5, "only {lit} lit lanes, {slow} with powf");
    }

    /// The power's lane form is the scalar one, lane for lane.
    #[test]
    fn pow_lanes_match_scalar() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for _ in 0..2000 {
            let x: [f32; W] = std::array::from_fn(|_| rng.random_range(1e-6f32..1.0));
            let y: [f32; W] = std::array::from_fn(|_| rng.random_range(0.01f32..2000.0));
            let got = pow_fast(F8(x), F8(y));
            for i in 0..W {
                assert_eq!(got.0[i].to_bits(), pow_unit(x[i], y[i]).to_bits(), "{}^{}", x[i], y[i]);
            }
        }
    }
}
