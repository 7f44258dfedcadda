//! The Whitted integrator's Phong shading, written once over [`Real`] and used two ways:
//! ray by ray on `f32`s ([`super::li`]), and on a packet's hits in structure-of-arrays
//! form, eight hits at a time ([`HitLanes`], for [`super::li_packet`]): [`orient`],
//! [`light_lane`] (Lambert diffuse plus Phong specular from one light, and its shadow ray).

// Lane loops index several arrays by the lane number; written so, they vectorize.
#![allow(clippy::needless_range_loop)]

use crate::lanes::{finite, max, pow_needs_slow, Real, V3};
use glam::Vec3;
use lucent_accel::simd::{F8, LANES as W, M8};
use lucent_accel::{RayBlock, MAX_PACKET};
use lucent_scene::{Light, LightKind, Material};

/// Hits per packet.
pub(crate) const N: usize = MAX_PACKET;

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
pub(crate) struct PhongTerm<T: Real> {
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
pub(crate) fn light_lane<T: Real, const K: u8>(lc: &LightConst, h: &LitPoint<T>) -> PhongTerm<T> {
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
    let spec = V3::select(use_spec, h.specular.scale(T::powu(x, h.shininess)), V3::zero());
    let term = rad.mul(h.kd.scale(cos).scale(h.opaque).add(spec));
    PhongTerm { term, ldir, tmax, valid, slow: use_spec & pow_needs_slow(x, h.shininess) }
}

/// [`light_lane`] on one hit for any light, with the exact power (the ray-by-ray form).
#[inline(always)]
pub(crate) fn light_sample(lc: &LightConst, h: &LitPoint<f32>) -> PhongTerm<f32> {
    match lc.kind {
        POINT => light_lane::<f32, POINT>(lc, h),
        DIRECTIONAL => light_lane::<f32, DIRECTIONAL>(lc, h),
        _ => light_lane::<f32, SPOT>(lc, h),
    }
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
}
