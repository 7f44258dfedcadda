//! AVX2 versions of the hot loops: the same operations in the same order as the
//! portable ones (so the same answers), one instruction per eight lanes.
use super::core::{Interval, Packet, PacketHits, RayBlock, F8, FAR_SCALE, LANES, M8};
use crate::geom::Ray;

/// Up to eight rays into the SoA block `b` (lanes past `rays.len()` get
/// [`RayBlock::EMPTY`]'s empty ray): each ray's eight floats (origin, direction, tmin,
/// tmax) are one row of an 8×8 matrix, transposed with unpacks, shuffles and lane
/// permutes.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn transpose_rays(rays: &[Ray], b: &mut RayBlock) {
    let row = |i: usize| {
        let r = rays.get(i).copied().unwrap_or(Ray { org: glam::Vec3::ZERO, dir: glam::Vec3::ZERO, tmin: 0.0, tmax: f32::NEG_INFINITY });
        let a = [r.org.x, r.org.y, r.org.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax];
        // SAFETY: `a` holds eight floats.
        unsafe { _mm256_loadu_ps(a.as_ptr()) }
    };
    let r: [__m256; 8] = std::array::from_fn(row);
    let t0 = _mm256_unpacklo_ps(r[0], r[1]);
    let t1 = _mm256_unpackhi_ps(r[0], r[1]);
    let t2 = _mm256_unpacklo_ps(r[2], r[3]);
    let t3 = _mm256_unpackhi_ps(r[2], r[3]);
    let t4 = _mm256_unpacklo_ps(r[4], r[5]);
    let t5 = _mm256_unpackhi_ps(r[4], r[5]);
    let t6 = _mm256_unpacklo_ps(r[6], r[7]);
    let t7 = _mm256_unpackhi_ps(r[6], r[7]);
    let u0 = _mm256_shuffle_ps::<0x44>(t0, t2);
    let u1 = _mm256_shuffle_ps::<0xee>(t0, t2);
    let u2 = _mm256_shuffle_ps::<0x44>(t1, t3);
    let u3 = _mm256_shuffle_ps::<0xee>(t1, t3);
    let u4 = _mm256_shuffle_ps::<0x44>(t4, t6);
    let u5 = _mm256_shuffle_ps::<0xee>(t4, t6);
    let u6 = _mm256_shuffle_ps::<0x44>(t5, t7);
    let u7 = _mm256_shuffle_ps::<0xee>(t5, t7);
    let rows = [
        _mm256_permute2f128_ps::<0x20>(u0, u4),
        _mm256_permute2f128_ps::<0x20>(u1, u5),
        _mm256_permute2f128_ps::<0x20>(u2, u6),
        _mm256_permute2f128_ps::<0x20>(u3, u7),
        _mm256_permute2f128_ps::<0x31>(u0, u4),
        _mm256_permute2f128_ps::<0x31>(u1, u5),
        _mm256_permute2f128_ps::<0x31>(u2, u6),
        _mm256_permute2f128_ps::<0x31>(u3, u7),
    ];
    let mut out = [[0.0f32; LANES]; 8];
    for (o, v) in out.iter_mut().zip(rows) {
        // SAFETY: `o` holds eight floats.
        unsafe { _mm256_storeu_ps(o.as_mut_ptr(), v) };
    }
    *b = RayBlock { org: [out[0], out[1], out[2]], dir: [out[3], out[4], out[5]], tmin: out[6], tmax: out[7] };
}
use super::core::cyclic;
use crate::triangle::Tri4;
use crate::wide::WideNode;
use std::arch::x86_64::*;

#[inline]
#[target_feature(enable = "avx2,fma")]
fn ld(a: &F8) -> __m256 {
    // SAFETY: `F8` is 32 bytes, 32-byte aligned.
    unsafe { _mm256_load_ps(a.0.as_ptr()) }
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn ldm(a: &M8) -> __m256 {
    // SAFETY: `M8` is 32 bytes, 32-byte aligned.
    unsafe { _mm256_castsi256_ps(_mm256_load_si256(a.0.as_ptr().cast())) }
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn st(v: __m256) -> F8 {
    let mut r = F8([0.0; LANES]);
    // SAFETY: as in `ld`.
    unsafe { _mm256_store_ps(r.0.as_mut_ptr(), v) };
    r
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn stm(v: __m256) -> M8 {
    let mut r = M8([0; LANES]);
    // SAFETY: as in `ldm`.
    unsafe { _mm256_store_si256(r.0.as_mut_ptr().cast(), _mm256_castps_si256(v)) };
    r
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn ldu(a: &[u32; LANES]) -> __m256 {
    // SAFETY: 32 bytes, unaligned load.
    unsafe { _mm256_castsi256_ps(_mm256_loadu_si256(a.as_ptr().cast())) }
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn stu(v: __m256, a: &mut [u32; LANES]) {
    // SAFETY: 32 bytes, unaligned store.
    unsafe { _mm256_storeu_si256(a.as_mut_ptr().cast(), _mm256_castps_si256(v)) };
}

/// `super::interval_test`.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn interval_test(node: &WideNode<8>, iv: &Interval, tmax: f32, dist: &mut [f32; 8]) -> u32 {
    let row = |r: usize| {
        // SAFETY: rows are 32 bytes at 32-byte aligned offsets of a 64-byte aligned node.
        unsafe { _mm256_load_ps(node.bounds[r].as_ptr()) }
    };
    let mut tn = _mm256_set1_ps(iv.tmin);
    let mut tf = _mm256_set1_ps(tmax);
    for k in 0..3 {
        let (bn, bf) = (row(iv.inear[k]), row(iv.ifar[k]));
        let (olo, ohi) = (_mm256_set1_ps(iv.olo[k]), _mm256_set1_ps(iv.ohi[k]));
        let (rlo, rhi) = (_mm256_set1_ps(iv.rlo[k]), _mm256_set1_ps(iv.rhi[k]));
        let (n0, n1) = (_mm256_sub_ps(bn, olo), _mm256_sub_ps(bn, ohi));
        let lo = _mm256_min_ps(
            _mm256_min_ps(_mm256_mul_ps(n0, rlo), _mm256_mul_ps(n0, rhi)),
            _mm256_min_ps(_mm256_mul_ps(n1, rlo), _mm256_mul_ps(n1, rhi)),
        );
        let (f0, f1) = (_mm256_sub_ps(bf, olo), _mm256_sub_ps(bf, ohi));
        let hi = _mm256_add_ps(
            _mm256_max_ps(
                _mm256_max_ps(_mm256_mul_ps(f0, rlo), _mm256_mul_ps(f0, rhi)),
                _mm256_max_ps(_mm256_mul_ps(f1, rlo), _mm256_mul_ps(f1, rhi)),
            ),
            _mm256_set1_ps(iv.pad[k]),
        );
        tn = _mm256_max_ps(lo, tn);
        tf = _mm256_min_ps(hi, tf);
    }
    // SAFETY: `dist` is 32 bytes.
    unsafe { _mm256_storeu_ps(dist.as_mut_ptr(), tn) };
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, _mm256_mul_ps(tf, _mm256_set1_ps(FAR_SCALE)))) as u32
}

/// `PacketHits::max_t`.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn max_t(h: &PacketHits, groups: usize, active: &super::core::Masks) -> f32 {
    let ninf = _mm256_set1_ps(f32::NEG_INFINITY);
    let mut m = ninf;
    for g in 0..groups {
        m = _mm256_max_ps(m, _mm256_blendv_ps(ninf, ld(&h.t[g]), ldm(&active[g])));
    }
    let m4 = _mm_max_ps(_mm256_castps256_ps128(m), _mm256_extractf128_ps::<1>(m));
    let m2 = _mm_max_ps(m4, _mm_movehl_ps(m4, m4));
    let m1 = _mm_max_ss(m2, _mm_shuffle_ps::<1>(m2, m2));
    _mm_cvtss_f32(m1)
}

/// `super::group_box`.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn group_box(rows: &[f32; 6], p: &Packet, iv: &Interval, g: usize, t: &F8) -> M8 {
    let mut tn = ld(&p.tmin[g]);
    let mut tf = ld(t);
    for k in 0..3 {
        let (o, inv) = (ld(&p.o[g][k]), ld(&p.inv[g][k]));
        let a = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(rows[iv.near[k]]), o), inv);
        let b = _mm256_add_ps(_mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(rows[iv.far[k]]), o), inv), _mm256_set1_ps(iv.pad[k]));
        tn = _mm256_max_ps(a, tn);
        tf = _mm256_min_ps(b, tf);
    }
    stm(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, _mm256_mul_ps(tf, _mm256_set1_ps(FAR_SCALE))))
}

/// `super::tri_eval` for all four lanes of `t4`, rays of group `g`.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn eval(t4: &Tri4, lane: usize, p: &Packet, g: usize, tmax: __m256, org: Option<&[[f32; 4]; 3]>) -> (__m256, [__m256; 4]) {
    let m = |c: usize| _mm256_set1_ps(t4.m[c][lane]);
    let k = t4.axis(lane) as usize;
    let d = cyclic(&p.d[g], k);
    let (d0, d1, d2) = (ld(&d[0]), ld(&d[1]), ld(&d[2]));
    let zero = _mm256_setzero_ps();
    let dir = |i: usize| _mm256_fmadd_ps(m(i), d1, _mm256_fmadd_ps(m(i + 1), d2, _mm256_mul_ps(m(i + 2), zero)));
    let dzp = _mm256_fmadd_ps(m(6), d1, _mm256_fmadd_ps(m(7), d2, _mm256_fmadd_ps(m(8), zero, d0)));
    let dxp = dir(0);
    let dyp = dir(3);
    let (oxp, oyp, ozp) = match org {
        // The origin's terms, computed once per triangle (`origin_terms`), broadcast.
        Some(o) => (_mm256_set1_ps(o[0][lane]), _mm256_set1_ps(o[1][lane]), _mm256_set1_ps(o[2][lane])),
        None => {
            let o = cyclic(&p.o[g], k);
            let (o0, o1, o2) = (ld(&o[0]), ld(&o[1]), ld(&o[2]));
            let org = |i: usize| _mm256_fmadd_ps(m(i), o1, _mm256_fmadd_ps(m(i + 1), o2, m(i + 2)));
            let oz = _mm256_fmadd_ps(m(6), o1, _mm256_fmadd_ps(m(7), o2, _mm256_add_ps(m(8), o0)));
            (org(0), org(3), oz)
        }
    };
    let signbit = _mm256_set1_ps(-0.0);
    let s = _mm256_and_ps(dzp, signbit);
    let adz = _mm256_xor_ps(dzp, s);
    let uu = _mm256_xor_ps(_mm256_fmsub_ps(oxp, dzp, _mm256_mul_ps(ozp, dxp)), s);
    let vv = _mm256_xor_ps(_mm256_fmsub_ps(oyp, dzp, _mm256_mul_ps(ozp, dyp)), s);
    let tt = _mm256_xor_ps(_mm256_xor_ps(ozp, signbit), s);
    let zero = _mm256_setzero_ps();
    let ok = _mm256_and_ps(
        _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(uu, zero), _mm256_cmp_ps::<_CMP_GE_OQ>(vv, zero)),
        _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_add_ps(uu, vv), adz),
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(tt, _mm256_mul_ps(ld(&p.tmin[g]), adz)),
                _mm256_cmp_ps::<_CMP_LT_OQ>(tt, _mm256_mul_ps(tmax, adz)),
            ),
        ),
    );
    (ok, [tt, uu, vv, adz])
}

/// `O'x, O'y, O'z` of the four triangles of `t4` for the common origin `o`, with the
/// same operations in the same order as the per-lane test (so the same values).
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn origin_terms(t4: &Tri4, o: &[f32; 3]) -> [[f32; 4]; 3] {
    // SAFETY: `Tri4` rows are 16-byte aligned `[f32; 4]`s.
    let row = |c: usize| unsafe { _mm_load_ps(t4.m[c].as_ptr()) };
    let [p0, p1, p2] = rotated(t4, _mm_setr_ps(o[0], o[1], o[2], 0.0));
    let ox = _mm_fmadd_ps(row(0), p1, _mm_fmadd_ps(row(1), p2, row(2)));
    let oy = _mm_fmadd_ps(row(3), p1, _mm_fmadd_ps(row(4), p2, row(5)));
    let oz = _mm_fmadd_ps(row(6), p1, _mm_fmadd_ps(row(7), p2, _mm_add_ps(row(8), p0)));
    let mut out = [[0f32; 4]; 3];
    for (slot, v) in out.iter_mut().zip([ox, oy, oz]) {
        // SAFETY: `slot` is 16 bytes.
        unsafe { _mm_storeu_ps(slot.as_mut_ptr(), v) };
    }
    out
}

/// Components `k, k+1, k+2` of `v = (x, y, z, 0)` for each lane of `t4`, `k` being the
/// lane's axis (a lane without one gets the zero).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn rotated(t4: &Tri4, v: __m128) -> [__m128; 3] {
    // SAFETY: `Tri4` is 16-byte aligned, its ids 16 bytes.
    let k = _mm_srli_epi32::<{ crate::triangle::AXIS_SHIFT as i32 }>(unsafe { _mm_load_si128(t4.prim.as_ptr().cast()) });
    let next = _mm_permutevar_ps(_mm_castsi128_ps(_mm_setr_epi32(1, 2, 0, 3)), k);
    let after = _mm_permutevar_ps(_mm_castsi128_ps(_mm_setr_epi32(2, 0, 1, 3)), k);
    [_mm_permutevar_ps(v, k), _mm_permutevar_ps(v, _mm_castps_si128(next)), _mm_permutevar_ps(v, _mm_castps_si128(after))]
}

/// The lanes of `t4` that some ray of a packet with common origin and directions within
/// `c` may hit (bit `i` for lane `i`); `org` holds the lanes' origin terms
/// ([`origin_terms`]). With the origin fixed, the triangle test's `U = O'x·D'z − O'z·D'x`,
/// `V` and `U + V − D'z` are linear in the direction, so their ranges over the
/// direction box bound them for every ray of the packet (interval arithmetic, as the
/// packet's box culling): a lane is dropped when, for every ray, `D'z` has one sign and
/// `U`, `V` or `U + V − D'z` has the wrong one, or the plane lies behind the origin. The
/// ranges must clear zero by a margin ten thousand times the rounding of the exact
/// test, so no lane that test would hit is dropped.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn frustum_keep(t4: &Tri4, org: &[[f32; 4]; 3], c: &super::core::DirBounds) -> i32 {
    // SAFETY: `Tri4` rows and `org` rows are 16-byte aligned / 16-byte `[f32; 4]`s.
    let row = |r: usize| unsafe { _mm_load_ps(t4.m[r].as_ptr()) };
    let o = |k: usize| unsafe { _mm_loadu_ps(org[k].as_ptr()) };
    let (ox, oy, oz) = (o(0), o(1), o(2));
    let abs = |v: __m128| _mm_andnot_ps(_mm_set1_ps(-0.0), v);
    // The direction box in each lane's own component order, as its map reads it.
    let lo = rotated(t4, _mm_setr_ps(c.lo[0], c.lo[1], c.lo[2], 0.0));
    let hi = rotated(t4, _mm_setr_ps(c.hi[0], c.hi[1], c.hi[2], 0.0));
    let mag: [__m128; 3] = std::array::from_fn(|k| _mm_max_ps(abs(lo[k]), abs(hi[k])));
    // Range of a·d over the box.
    let range = |a: [__m128; 3]| {
        let (mut l, mut h) = (_mm_setzero_ps(), _mm_setzero_ps());
        for k in 0..3 {
            let (x, y) = (_mm_mul_ps(a[k], lo[k]), _mm_mul_ps(a[k], hi[k]));
            l = _mm_add_ps(l, _mm_min_ps(x, y));
            h = _mm_add_ps(h, _mm_max_ps(x, y));
        }
        (l, h)
    };
    // Σ|a_k|·max|d_k|: the scale a·d's rounding goes with.
    let scale = |a: [__m128; 3]| (0..3).fold(_mm_setzero_ps(), |s, k| _mm_fmadd_ps(abs(a[k]), mag[k], s));
    // The maps' direction rows over those components: the axis' column is (0, 0, 1).
    let (zero, one) = (_mm_setzero_ps(), _mm_set1_ps(1.0));
    let mx = [zero, row(0), row(1)];
    let my = [zero, row(3), row(4)];
    let mz = [one, row(6), row(7)];
    let au: [__m128; 3] = std::array::from_fn(|k| _mm_fmsub_ps(ox, mz[k], _mm_mul_ps(oz, mx[k])));
    let av: [__m128; 3] = std::array::from_fn(|k| _mm_fmsub_ps(oy, mz[k], _mm_mul_ps(oz, my[k])));
    let aw: [__m128; 3] = std::array::from_fn(|k| _mm_sub_ps(_mm_add_ps(au[k], av[k]), mz[k]));
    let (zl, zh) = range(mz);
    let (ul, uh) = range(au);
    let (vl, vh) = range(av);
    let (wl, wh) = range(aw);
    let (xs, ys, zs) = (scale(mx), scale(my), scale(mz));
    // One margin for all four forms: 1e-4 of the magnitudes their terms can reach.
    let e = _mm_mul_ps(
        _mm_set1_ps(1e-4),
        _mm_add_ps(_mm_fmadd_ps(_mm_add_ps(abs(ox), abs(oy)), zs, _mm_mul_ps(abs(oz), _mm_add_ps(xs, ys))), zs),
    );
    let ez = _mm_mul_ps(_mm_set1_ps(1e-4), zs);
    let ne = _mm_sub_ps(_mm_setzero_ps(), e);
    let zero = _mm_setzero_ps();
    let fwd = if c.forward { _mm_castsi128_ps(_mm_set1_epi32(-1)) } else { zero };
    // D'z > 0 for every ray: a hit needs U ≥ 0, V ≥ 0, U + V ≤ D'z and O'z ≤ 0.
    let pos = _mm_cmpgt_ps(zl, ez);
    let pos_out = _mm_or_ps(
        _mm_or_ps(_mm_cmplt_ps(uh, ne), _mm_cmplt_ps(vh, ne)),
        _mm_or_ps(_mm_cmpgt_ps(wl, e), _mm_and_ps(fwd, _mm_cmpgt_ps(oz, zero))),
    );
    // D'z < 0 for every ray: the same with the signs turned.
    let neg = _mm_cmplt_ps(zh, _mm_sub_ps(zero, ez));
    let neg_out = _mm_or_ps(
        _mm_or_ps(_mm_cmpgt_ps(ul, e), _mm_cmpgt_ps(vl, e)),
        _mm_or_ps(_mm_cmplt_ps(wh, ne), _mm_and_ps(fwd, _mm_cmplt_ps(oz, zero))),
    );
    let out = _mm_or_ps(_mm_and_ps(pos, pos_out), _mm_and_ps(neg, neg_out));
    !_mm_movemask_ps(out) & 0xF
}

/// The closest-hit leaf step of one group against one `Tri4` (see the portable loop),
/// for the lanes of `keep` only.
#[allow(clippy::too_many_arguments)] // the leaf loop's state, passed as it is
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn tri4_intersect(
    t4: &Tri4,
    p: &Packet,
    g: usize,
    m: &M8,
    h: &mut PacketHits,
    inst: u32,
    org: Option<&[[f32; 4]; 3]>,
    keep: i32,
) {
    let limit = ld(&h.t[g]);
    let mask = ldm(m);
    let mut found = _mm256_setzero_ps();
    let mut bt = _mm256_set1_ps(f32::INFINITY);
    let (mut bu, mut bv) = (bt, bt);
    let mut bp = _mm256_setzero_ps();
    for lane in 0..4 {
        // Padding lanes come last and never hit.
        if t4.is_pad(lane) {
            break;
        }
        if keep & (1 << lane) == 0 {
            continue;
        }
        let (ok, [tt, uu, vv, adz]) = eval(t4, lane, p, g, limit, org);
        let ok = _mm256_and_ps(ok, mask);
        if _mm256_movemask_ps(ok) == 0 {
            continue;
        }
        let t = _mm256_div_ps(tt, adz);
        let take = _mm256_and_ps(
            ok,
            _mm256_or_ps(_mm256_andnot_ps(found, _mm256_castsi256_ps(_mm256_set1_epi32(-1))), _mm256_cmp_ps::<_CMP_LT_OQ>(t, bt)),
        );
        bt = _mm256_blendv_ps(bt, t, take);
        bu = _mm256_blendv_ps(bu, _mm256_div_ps(uu, adz), take);
        bv = _mm256_blendv_ps(bv, _mm256_div_ps(vv, adz), take);
        bp = _mm256_blendv_ps(bp, _mm256_castsi256_ps(_mm256_set1_epi32(t4.id(lane) as i32)), take);
        found = _mm256_or_ps(found, take);
    }
    if _mm256_movemask_ps(found) != 0 {
        h.t[g] = st(_mm256_blendv_ps(limit, bt, found));
        h.u[g] = st(_mm256_blendv_ps(ld(&h.u[g]), bu, found));
        h.v[g] = st(_mm256_blendv_ps(ld(&h.v[g]), bv, found));
        let prim = _mm256_blendv_ps(ldu(&h.prim[g]), bp, found);
        stu(prim, &mut h.prim[g]);
        let ids = _mm256_blendv_ps(ldu(&h.inst[g]), _mm256_castsi256_ps(_mm256_set1_epi32(inst as i32)), found);
        stu(ids, &mut h.inst[g]);
    }
}

/// [`crate::shape::Shape::intersect_local`] of the unit sphere for the eight rays of
/// group `g` carried by `m` into object space, with the same operations in the same
/// order (the transform as [`Packet::transformed`], the quadric in f64 as
/// `shape::quadric`), so the same answers bit for bit. Returns the lanes that hit within
/// `[tmin, hi)`, their distances, and the lanes whose object-space direction is zero
/// (`a = 0`: the caller tests those one by one).
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn sphere8(p: &Packet, g: usize, m: &glam::Affine3A, hi: &F8, active: u32) -> (u32, F8, u32) {
    let c = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
    let tr = m.translation;
    let (ox, oy, oz) = (ld(&p.o[g][0]), ld(&p.o[g][1]), ld(&p.o[g][2]));
    let (dx, dy, dz) = (ld(&p.d[g][0]), ld(&p.d[g][1]), ld(&p.d[g][2]));
    let mut lo = [_mm256_setzero_ps(); 3];
    let mut ld_ = [_mm256_setzero_ps(); 3];
    for r in 0..3 {
        let (a, b, cc) = (_mm256_set1_ps(c[0][r]), _mm256_set1_ps(c[1][r]), _mm256_set1_ps(c[2][r]));
        lo[r] = _mm256_add_ps(
            _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(a, ox), _mm256_mul_ps(b, oy)), _mm256_mul_ps(cc, oz)),
            _mm256_set1_ps(tr[r]),
        );
        ld_[r] = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(a, dx), _mm256_mul_ps(b, dy)), _mm256_mul_ps(cc, dz));
    }
    let (tmin, tmax) = (ld(&p.tmin[g]), ld(hi));
    // PERF: lanes that start outside the sphere (c > 0) and run away from its centre
    // (b > 0) have both roots negative, so no hit at t >= tmin >= 0: the shadow rays
    // leaving a sphere's lit side, tested against that sphere. Decided in f32 with a
    // margin of four times the dot products' rounding (the f64 code uses the same
    // f32 inputs), so a lane is dropped only where the f64 test would find no hit.
    let away = {
        let abs = |v: __m256| _mm256_andnot_ps(_mm256_set1_ps(-0.0), v);
        let (px, py, pz) = (_mm256_mul_ps(ld_[0], lo[0]), _mm256_mul_ps(ld_[1], lo[1]), _mm256_mul_ps(ld_[2], lo[2]));
        let b = _mm256_add_ps(_mm256_add_ps(px, py), pz);
        let eb = _mm256_mul_ps(_mm256_set1_ps(1e-6), _mm256_add_ps(_mm256_add_ps(abs(px), abs(py)), abs(pz)));
        let oo = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(lo[0], lo[0]), _mm256_mul_ps(lo[1], lo[1])), _mm256_mul_ps(lo[2], lo[2]));
        let one = _mm256_set1_ps(1.0);
        let c = _mm256_sub_ps(oo, one);
        let ec = _mm256_mul_ps(_mm256_set1_ps(1e-6), _mm256_add_ps(oo, one));
        let m = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(b, eb), _mm256_cmp_ps::<_CMP_GT_OQ>(c, ec)),
            _mm256_cmp_ps::<_CMP_GE_OQ>(tmin, _mm256_setzero_ps()),
        );
        _mm256_movemask_ps(m) as u32
    };
    let mut hit = 0u32;
    let mut odd = 0u32;
    let mut t = [_mm_setzero_ps(); 2];
    for half in 0..2 {
        // PERF: a half with no active lane, or whose active lanes all run away from the
        // sphere, costs nothing more.
        if ((active & !away) >> (4 * half)) & 15 == 0 {
            continue;
        }
        let wide = |v: __m256| _mm256_cvtps_pd(if half == 0 { _mm256_castps256_ps128(v) } else { _mm256_extractf128_ps::<1>(v) });
        let (ox, oy, oz) = (wide(lo[0]), wide(lo[1]), wide(lo[2]));
        let (dx, dy, dz) = (wide(ld_[0]), wide(ld_[1]), wide(ld_[2]));
        let dot = |ax: __m256d, ay: __m256d, az: __m256d, bx: __m256d, by: __m256d, bz: __m256d| {
            _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(ax, bx), _mm256_mul_pd(ay, by)), _mm256_mul_pd(az, bz))
        };
        let a = dot(dx, dy, dz, dx, dy, dz);
        let b = dot(dx, dy, dz, ox, oy, oz);
        let cq = _mm256_sub_pd(dot(ox, oy, oz, ox, oy, oz), _mm256_set1_pd(1.0));
        let zero = _mm256_setzero_pd();
        odd |= (_mm256_movemask_pd(_mm256_cmp_pd::<_CMP_EQ_OQ>(a, zero)) as u32) << (4 * half);
        // A negative discriminant gives NaN roots, which no range test accepts (the
        // scalar code returns no roots: the same outcome).
        let disc = _mm256_sub_pd(_mm256_mul_pd(b, b), _mm256_mul_pd(a, cq));
        // PERF: four misses (the common case at a sphere's box corners) skip the square
        // root and the divisions. `disc < 0` is exactly the scalar code's "no roots".
        if _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(disc, zero)) == 15 {
            continue;
        }
        let sign = _mm256_blendv_pd(_mm256_set1_pd(-1.0), _mm256_set1_pd(1.0), _mm256_cmp_pd::<_CMP_GE_OQ>(b, zero));
        let q = _mm256_xor_pd(_mm256_add_pd(b, _mm256_mul_pd(sign, _mm256_sqrt_pd(disc))), _mm256_set1_pd(-0.0));
        let qnz = _mm256_cmp_pd::<_CMP_NEQ_UQ>(q, zero);
        let t0 = _mm256_and_pd(_mm256_div_pd(q, a), qnz);
        let t1 = _mm256_and_pd(_mm256_div_pd(cq, q), qnz);
        let swap = _mm256_cmp_pd::<_CMP_GT_OQ>(t0, t1);
        let (t0, t1) = (_mm256_blendv_pd(t0, t1, swap), _mm256_blendv_pd(t1, t0, swap));
        let (lo, hi) = (wide(tmin), wide(tmax));
        let inr = |t| _mm256_and_pd(_mm256_cmp_pd::<_CMP_GE_OQ>(t, lo), _mm256_cmp_pd::<_CMP_LT_OQ>(t, hi));
        let in0 = inr(t0);
        // The second root replaces the first when the first is out of range or farther.
        let all = _mm256_castsi256_pd(_mm256_set1_epi32(-1));
        let in1 = _mm256_and_pd(inr(t1), _mm256_or_pd(_mm256_xor_pd(in0, all), _mm256_cmp_pd::<_CMP_LT_OQ>(t1, t0)));
        hit |= (_mm256_movemask_pd(_mm256_or_pd(in0, in1)) as u32) << (4 * half);
        t[half] = _mm256_cvtpd_ps(_mm256_blendv_pd(t0, t1, in1));
    }
    (hit & !odd, st(_mm256_set_m128(t[1], t[0])), odd)
}

/// The lanes of group `g` that hit any triangle of `t4` within `[tmin, limit)`; stops
/// once every lane of `active` is hit (PERF: shadow rays that start beside their
/// blocker, most of the kitchen's, are all blocked by a group's first triangle, and
/// the other three were tested for nothing).
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn tri4_any(t4: &Tri4, p: &Packet, g: usize, limit: &F8, active: &M8) -> M8 {
    let lim = ld(limit);
    let want = ldm(active);
    let mut hit = _mm256_setzero_ps();
    for lane in 0..4 {
        if t4.is_pad(lane) {
            break;
        }
        hit = _mm256_or_ps(hit, eval(t4, lane, p, g, lim, None).0);
        // All wanted lanes hit: `want & !hit` is empty.
        if _mm256_testc_ps(hit, want) != 0 {
            break;
        }
    }
    stm(hit)
}
