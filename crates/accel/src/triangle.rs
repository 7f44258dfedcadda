//! Ray/triangle tests.
//!
//! The default is SaarCOR's **unit-triangle test** (Woop, Schmittler & Slusallek, "RPU: A
//! Programmable Ray Processing Unit for Realtime Ray Tracing", SIGGRAPH 2005; Woop's 2004
//! thesis): every triangle gets an affine map into the space where it is the unit triangle
//! (1,0,0), (0,1,0), (0,0,0). For a ray mapped into that space, `t = -O'z / D'z`,
//! `u = O'x + t D'x`, `v = O'y + t D'y`, and the ray hits when `u, v >= 0` and `u + v <= 1`.
//! There is no absolute epsilon anywhere, so a millimetre bunny and a kilometre room are
//! treated alike.
//!
//! We map vertex 1 to (1,0,0), vertex 2 to (0,1,0) and vertex 0 to the origin, so `u` and `v`
//! are the usual barycentric weights of vertices 1 and 2.
//!
//! The **watertight** test (Woop, Benthin & Wald, "Watertight Ray/Triangle Intersection",
//! JCGT 2013) is the selectable alternative: no gaps or double hits on shared edges.
//!
//! PERF: the test is evaluated without a division: with `s = sign(D'z)` the conditions are
//! multiplied through by `|D'z|` (`U = (O'x D'z − O'z D'x)·s ≥ 0`, `V = (O'y D'z − O'z D'y)·s ≥ 0`,
//! `U + V ≤ |D'z|`, `tmin |D'z| ≤ −O'z s < tmax |D'z|`), and `t, u, v` are divided out only
//! when a lane hits. `t = (−O'z s)/|D'z|` equals `−O'z/D'z` to the bit.
//!
//! The products are fused multiply-adds, in one fixed order
//! (`D'r = fma(m_r0, dx, fma(m_r1, dy, m_r2·dz))`, `O'r = fma(m_r0, ox, fma(m_r1, oy,
//! fma(m_r2, oz, m_r3)))`, `U = fma(O'x, D'z, −O'z·D'x)`), which every version (scalar, SSE,
//! the packet kernels) follows, so all return bit-identical answers (tested). PERF: the
//! fused form is 21 operations per triangle instead of 36 in the 4-wide single-ray test.

use glam::{DVec3, Vec3};

/// The 3×4 affine map into unit-triangle space, row-major: rows 0..2 are
/// `(m[4r], m[4r+1], m[4r+2], m[4r+3])`, the last entry of each row being the translation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnitTriangle {
    /// Row-major 3×4 matrix.
    pub m: [f32; 12],
}

/// The map used for a padding lane or a degenerate triangle: `O'z = 1`, `D'z = 0`, so `t` is
/// `-inf` (or NaN) and no ray ever hits it.
pub const NEVER_HIT: [f32; 12] = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];

impl UnitTriangle {
    /// The map for triangle (v0, v1, v2), computed in f64; `None` when the triangle is
    /// degenerate (zero area) or not finite.
    #[must_use]
    pub fn new(v0: Vec3, v1: Vec3, v2: Vec3) -> Option<Self> {
        let (a, b, c) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
        let e1 = b - a;
        let e2 = c - a;
        let n = e1.cross(e2);
        let det = n.length_squared(); // det [e1 e2 n] = (e1 x e2) . n
        if det.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || !det.is_finite() || !a.is_finite() {
            return None;
        }
        // Rows of [e1 e2 n]^-1 (n is orthogonal to e1 and e2). PERF: one division, then
        // products, not nine f64 divisions (2-3% of a 12k-triangle build); the rounding
        // differs from dividing by at most an f64 ulp, far below the f32 the rows are
        // stored in.
        let inv = 1.0 / det;
        let r0 = e2.cross(n) * inv;
        let r1 = n.cross(e1) * inv;
        let r2 = n * inv;
        let row = |r: DVec3| [r.x, r.y, r.z, -r.dot(a)];
        let rows = [row(r0), row(r1), row(r2)];
        let mut m = [0.0f32; 12];
        for (i, v) in rows.iter().flatten().enumerate() {
            m[i] = *v as f32;
        }
        if m.iter().all(|x| x.is_finite()) {
            Some(Self { m })
        } else {
            None
        }
    }

    /// The raw map for a triangle, or [`NEVER_HIT`] when it is degenerate.
    #[must_use]
    pub fn or_never(v0: Vec3, v1: Vec3, v2: Vec3) -> [f32; 12] {
        Self::new(v0, v1, v2).map_or(NEVER_HIT, |u| u.m)
    }
}

/// Whether [`UnitTriangle::new`] finds the triangle non-degenerate: the same f64
/// arithmetic up to its determinant, which must be positive and finite, with a finite
/// first corner. (`new` also refuses maps that overflow f32, which only triangles of
/// extreme size make; the build keeps such a triangle as a lane that never hits.)
#[inline]
#[must_use]
pub fn unit_map_possible(v0: Vec3, v1: Vec3, v2: Vec3) -> bool {
    let (a, b, c) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
    let det = (b - a).cross(c - a).length_squared();
    det > 0.0 && det.is_finite() && a.is_finite()
}

/// The maps of four triangles in SoA form, as a [`Tri4`] holds them (`m[entry][lane]`),
/// and which are proper: lane `l` is `UnitTriangle::new(tris[l])`'s map bit for bit, or
/// [`NEVER_HIT`] (and false) for a degenerate triangle. PERF: four triangles per AVX
/// register of f64 (the build computed every map alone: 30 ns a triangle, a tenth of a
/// 12k-triangle build).
#[must_use]
pub fn unit_maps4_soa(tris: &[[Vec3; 3]; 4]) -> ([[f32; 4]; 12], [bool; 4]) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx") {
        // SAFETY: AVX was just detected.
        return unsafe { unit_maps4_soa_avx(tris) };
    }
    let mut m = [[0.0f32; 4]; 12];
    let mut ok = [false; 4];
    for (l, t) in tris.iter().enumerate() {
        let u = UnitTriangle::new(t[0], t[1], t[2]);
        ok[l] = u.is_some();
        for (e, v) in u.map_or(NEVER_HIT, |u| u.m).into_iter().enumerate() {
            m[e][l] = v;
        }
    }
    (m, ok)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn unit_maps4_soa_avx(tris: &[[Vec3; 3]; 4]) -> ([[f32; 4]; 12], [bool; 4]) {
    use std::arch::x86_64::*;
    // Component `k` of vertex `v` of the four triangles.
    let comp = |v: usize, k: usize| _mm256_setr_pd(tris[0][v][k] as f64, tris[1][v][k] as f64, tris[2][v][k] as f64, tris[3][v][k] as f64);
    let a = [comp(0, 0), comp(0, 1), comp(0, 2)];
    let b = [comp(1, 0), comp(1, 1), comp(1, 2)];
    let c = [comp(2, 0), comp(2, 1), comp(2, 2)];
    let sub = |x: [__m256d; 3], y: [__m256d; 3]| [_mm256_sub_pd(x[0], y[0]), _mm256_sub_pd(x[1], y[1]), _mm256_sub_pd(x[2], y[2])];
    // glam's `cross`: (s.y r.z − r.y s.z, s.z r.x − r.z s.x, s.x r.y − r.x s.y).
    let cross = |s: [__m256d; 3], r: [__m256d; 3]| {
        [
            _mm256_sub_pd(_mm256_mul_pd(s[1], r[2]), _mm256_mul_pd(r[1], s[2])),
            _mm256_sub_pd(_mm256_mul_pd(s[2], r[0]), _mm256_mul_pd(r[2], s[0])),
            _mm256_sub_pd(_mm256_mul_pd(s[0], r[1]), _mm256_mul_pd(r[0], s[1])),
        ]
    };
    // glam's `dot`: (s.x r.x + s.y r.y) + s.z r.z.
    let dot = |s: [__m256d; 3], r: [__m256d; 3]| {
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(s[0], r[0]), _mm256_mul_pd(s[1], r[1])), _mm256_mul_pd(s[2], r[2]))
    };
    let e1 = sub(b, a);
    let e2 = sub(c, a);
    let n = cross(e1, e2);
    let det = dot(n, n);
    let inv = _mm256_div_pd(_mm256_set1_pd(1.0), det);
    let scale = |r: [__m256d; 3]| [_mm256_mul_pd(r[0], inv), _mm256_mul_pd(r[1], inv), _mm256_mul_pd(r[2], inv)];
    let rows = [scale(cross(e2, n)), scale(cross(n, e1)), scale(n)];
    let neg = _mm256_set1_pd(-0.0);
    let mut m = [[0.0f32; 4]; 12]; // m[entry][lane]
    for (r, row) in rows.iter().enumerate() {
        let w = _mm256_xor_pd(dot(*row, a), neg);
        for (k, v) in [row[0], row[1], row[2], w].into_iter().enumerate() {
            // Round to nearest, as `as f32` does.
            // SAFETY: `m[4r + k]` holds four f32.
            unsafe { _mm_storeu_ps(m[4 * r + k].as_mut_ptr(), _mm256_cvtpd_ps(v)) };
        }
    }
    let mut dets = [0.0f64; 4];
    // SAFETY: `dets` holds four f64.
    unsafe { _mm256_storeu_pd(dets.as_mut_ptr(), det) };
    let mut ok = [false; 4];
    for l in 0..4 {
        let good = dets[l] > 0.0 && dets[l].is_finite() && tris[l][0].is_finite() && m.iter().all(|col| col[l].is_finite());
        ok[l] = good;
        if !good {
            for (col, v) in m.iter_mut().zip(NEVER_HIT) {
                col[l] = v;
            }
        }
    }
    (m, ok)
}

/// Unit-triangle test of one ray against one map: `Some((t, u, v))` when `t` is in
/// `[tmin, tmax)` and the point lies inside the triangle.
#[inline(always)]
#[must_use]
pub fn unit_triangle_hit(m: &[f32; 12], o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
    let dir = |r: usize| m[r].mul_add(d.x, m[r + 1].mul_add(d.y, m[r + 2] * d.z));
    let org = |r: usize| m[r].mul_add(o.x, m[r + 1].mul_add(o.y, m[r + 2].mul_add(o.z, m[r + 3])));
    let (dz, oz, dx, ox, dy, oy) = (dir(8), org(8), dir(0), org(0), dir(4), org(4));
    let s = dz.to_bits() & 0x8000_0000;
    let sgn = |x: f32| f32::from_bits(x.to_bits() ^ s);
    let adz = sgn(dz);
    let uu = sgn(ox.mul_add(dz, -(oz * dx)));
    let vv = sgn(oy.mul_add(dz, -(oz * dy)));
    let tt = sgn(-oz);
    let ok = uu >= 0.0 && vv >= 0.0 && uu + vv <= adz && tt >= tmin * adz && tt < tmax * adz;
    ok.then(|| (tt / adz, uu / adz, vv / adz))
}

/// Four unit triangles in SoA form (component-major): 208 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Tri4 {
    /// `m[c][lane]`: component `c` of the 3×4 map of lane `lane`.
    pub m: [[f32; 4]; 12],
    /// Primitive id per lane (`u32::MAX` for a padding lane).
    pub prim: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Tri4>() == 208);

impl Tri4 {
    /// A group whose lanes never hit.
    pub const EMPTY: Self = {
        let mut m = [[0.0f32; 4]; 12];
        m[11] = [1.0; 4];
        Self { m, prim: [u32::MAX; 4] }
    };

    /// Puts a map into a lane.
    pub fn set(&mut self, lane: usize, m: &[f32; 12], prim: u32) {
        for (c, v) in m.iter().enumerate() {
            self.m[c][lane] = *v;
        }
        self.prim[lane] = prim;
    }

    /// The map of one lane.
    #[must_use]
    pub fn lane(&self, lane: usize) -> [f32; 12] {
        std::array::from_fn(|c| self.m[c][lane])
    }
}

/// Result of testing a ray against a [`Tri4`]: the nearest lane that hits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaneHit {
    /// Distance.
    pub t: f32,
    /// Barycentric u.
    pub u: f32,
    /// Barycentric v.
    pub v: f32,
    /// The lane (0..4).
    pub lane: usize,
}

/// Scalar test of a ray against four triangles: the nearest hit in `[tmin, tmax)`, first lane
/// winning ties.
#[inline(always)]
#[must_use]
pub fn tri4_intersect_scalar(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<LaneHit> {
    // Every lane against the same range, as the SIMD test: narrowing the range lane by lane
    // compared a later lane's scaled distance with the product of a divided-out one, and
    // could take a later lane at the same distance (two copies of a triangle in a group).
    let mut best: Option<LaneHit> = None;
    for lane in 0..4 {
        if let Some((t, u, v)) = unit_triangle_hit(&t4.lane(lane), o, d, tmin, tmax) {
            if best.is_none_or(|b| t < b.t) {
                best = Some(LaneHit { t, u, v, lane });
            }
        }
    }
    best
}

/// Scalar any-hit test against four triangles.
#[inline(always)]
#[must_use]
pub fn tri4_occluded_scalar(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> bool {
    (0..4).any(|lane| unit_triangle_hit(&t4.lane(lane), o, d, tmin, tmax).is_some())
}

#[cfg(target_arch = "x86_64")]
pub(crate) mod sse {
    //! The four-triangle test in SSE registers with FMA (run only where FMA was detected).
    use super::{LaneHit, Tri4};
    use glam::Vec3;
    use std::arch::x86_64::*;

    // PERF: these are `inline(always)` without `target_feature`: they inline into the AVX2
    // kernels, and the FMA intrinsics then inline there. With `target_feature(enable =
    // "fma")` and a plain `inline`, LLVM kept `intersect` out of line, one call per
    // triangle group, and single primary rays were 15% slower.

    /// The lane mask of hits and the scaled `T, U, V` and `|D'z|` of all lanes.
    ///
    /// # Safety
    /// The CPU must support FMA.
    #[inline(always)]
    unsafe fn eval(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> (i32, [__m128; 4]) {
        // SAFETY: `Tri4` is 16-byte aligned so the aligned loads are in bounds and aligned;
        // the caller guarantees FMA.
        unsafe {
            let ld = |c: usize| _mm_load_ps(t4.m[c].as_ptr());
            let (ox, oy, oz) = (_mm_set1_ps(o.x), _mm_set1_ps(o.y), _mm_set1_ps(o.z));
            let (dx, dy, dz) = (_mm_set1_ps(d.x), _mm_set1_ps(d.y), _mm_set1_ps(d.z));
            let dir = |r: usize| _mm_fmadd_ps(ld(r), dx, _mm_fmadd_ps(ld(r + 1), dy, _mm_mul_ps(ld(r + 2), dz)));
            let org = |r: usize| _mm_fmadd_ps(ld(r), ox, _mm_fmadd_ps(ld(r + 1), oy, _mm_fmadd_ps(ld(r + 2), oz, ld(r + 3))));
            let (dzp, ozp, dxp, oxp, dyp, oyp) = (dir(8), org(8), dir(0), org(0), dir(4), org(4));
            let signbit = _mm_set1_ps(-0.0);
            let s = _mm_and_ps(dzp, signbit);
            let adz = _mm_xor_ps(dzp, s);
            let uu = _mm_xor_ps(_mm_fmsub_ps(oxp, dzp, _mm_mul_ps(ozp, dxp)), s);
            let vv = _mm_xor_ps(_mm_fmsub_ps(oyp, dzp, _mm_mul_ps(ozp, dyp)), s);
            let tt = _mm_xor_ps(_mm_xor_ps(ozp, signbit), s);
            let zero = _mm_setzero_ps();
            let m = _mm_and_ps(
                _mm_and_ps(_mm_cmpge_ps(uu, zero), _mm_cmpge_ps(vv, zero)),
                _mm_and_ps(
                    _mm_cmple_ps(_mm_add_ps(uu, vv), adz),
                    _mm_and_ps(_mm_cmpge_ps(tt, _mm_mul_ps(_mm_set1_ps(tmin), adz)), _mm_cmplt_ps(tt, _mm_mul_ps(_mm_set1_ps(tmax), adz))),
                ),
            );
            (_mm_movemask_ps(m), [tt, uu, vv, adz])
        }
    }

    /// The nearest lane that hits (the first of equals), as `(t, U, V, |D'z|, lane)`: the
    /// barycentrics still scaled by `|D'z|` (`U / |D'z|` is the `u` of [`intersect`]), for a
    /// caller that divides once, for the final hit only.
    ///
    /// # Safety
    /// The CPU must support FMA.
    #[inline(always)]
    pub(crate) unsafe fn intersect_scaled(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32, f32, f32, usize)> {
        // SAFETY: the caller guarantees FMA.
        let (mask, [tt, uu, vv, adz]) = unsafe { eval(t4, o, d, tmin, tmax) };
        if mask == 0 {
            return None;
        }
        // SAFETY: SSE/SSE4.1 are implied by the FMA the caller guarantees; the arrays hold
        // exactly four f32.
        unsafe {
            let mut a = [[0f32; 4]; 4];
            _mm_storeu_ps(a[1].as_mut_ptr(), uu);
            _mm_storeu_ps(a[2].as_mut_ptr(), vv);
            _mm_storeu_ps(a[3].as_mut_ptr(), adz);
            // PERF: one lane hits (the common case): it is the lowest set bit, with no scan
            // over the lanes (whose branches on the mask a random lane mispredicted).
            let lane = if mask & (mask - 1) == 0 {
                _mm_storeu_ps(a[0].as_mut_ptr(), tt);
                let l = mask.trailing_zeros() as usize & 3;
                a[0][l] /= a[3][l];
                l
            } else {
                // Several: the nearest, the first of equals (a horizontal minimum).
                let t = _mm_div_ps(tt, adz);
                _mm_storeu_ps(a[0].as_mut_ptr(), t);
                let lanes = _mm_castsi128_ps(_mm_set_epi32(-(mask >> 3 & 1), -(mask >> 2 & 1), -(mask >> 1 & 1), -(mask & 1)));
                let ts = _mm_blendv_ps(_mm_set1_ps(f32::INFINITY), t, lanes);
                let m = _mm_min_ps(ts, _mm_shuffle_ps::<0b10_11_00_01>(ts, ts));
                let m = _mm_min_ps(m, _mm_shuffle_ps::<0b01_00_11_10>(m, m));
                ((_mm_movemask_ps(_mm_cmpeq_ps(ts, m)) & mask) as u32).trailing_zeros() as usize & 3
            };
            Some((a[0][lane], a[1][lane], a[2][lane], a[3][lane], lane))
        }
    }

    /// [`intersect_scaled`] with the barycentrics divided out.
    ///
    /// # Safety
    /// The CPU must support FMA.
    #[inline(always)]
    pub(crate) unsafe fn intersect(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<LaneHit> {
        // SAFETY: the caller guarantees FMA.
        let h = unsafe { intersect_scaled(t4, o, d, tmin, tmax) };
        h.map(|(t, u, v, den, lane)| LaneHit { t, u: u / den, v: v / den, lane })
    }

    /// # Safety
    /// The CPU must support FMA.
    #[inline(always)]
    pub(crate) unsafe fn occluded(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> bool {
        // SAFETY: the caller guarantees FMA.
        unsafe { eval(t4, o, d, tmin, tmax).0 != 0 }
    }
}

/// Four-triangle closest-hit test with the fastest code this CPU has (identical answers).
#[inline]
#[must_use]
pub fn tri4_intersect(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<LaneHit> {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("fma") {
        // SAFETY: FMA was just detected.
        return unsafe { sse::intersect(t4, o, d, tmin, tmax) };
    }
    tri4_intersect_scalar(t4, o, d, tmin, tmax)
}

/// Four-triangle any-hit test with the fastest code this CPU has.
#[inline]
#[must_use]
pub fn tri4_occluded(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> bool {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("fma") {
        // SAFETY: FMA was just detected.
        return unsafe { sse::occluded(t4, o, d, tmin, tmax) };
    }
    tri4_occluded_scalar(t4, o, d, tmin, tmax)
}

/// Per-ray constants of the watertight test (Woop, Benthin & Wald 2013, §3).
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
    org: Vec3,
}

impl WatertightRay {
    /// Precomputes the shear for direction `d`.
    #[must_use]
    pub fn new(o: Vec3, d: Vec3) -> Self {
        let a = d.abs();
        let kz = if a.x > a.y {
            if a.x > a.z {
                0
            } else {
                2
            }
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Self { kx, ky, kz, sx: d[kx] / d[kz], sy: d[ky] / d[kz], sz: 1.0 / d[kz], org: o }
    }

    /// Tests triangle (v0, v1, v2); returns `(t, u, v)` with u, v the weights of v1 and v2.
    #[must_use]
    pub fn hit(&self, v0: Vec3, v1: Vec3, v2: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let a = v0 - self.org;
        let b = v1 - self.org;
        let c = v2 - self.org;
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            // Fall back to double precision on edges, as the paper does.
            let (cxd, cyd, bxd, byd, axd, ayd) = (cx as f64, cy as f64, bx as f64, by as f64, ax as f64, ay as f64);
            u = (cxd * byd - cyd * bxd) as f32;
            v = (axd * cyd - ayd * cxd) as f32;
            w = (bxd * ayd - byd * axd) as f32;
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 {
            return None;
        }
        let az = self.sz * a[kz];
        let bz = self.sz * b[kz];
        let cz = self.sz * c[kz];
        let tn = u * az + v * bz + w * cz;
        let inv = 1.0 / det;
        let t = tn * inv;
        if !(t >= tmin && t < tmax) {
            return None;
        }
        // u, v, w here are the weights of v0, v1, v2.
        Some((t, v * inv, w * inv))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SIMD test that leaves the barycentrics scaled picks the scalar test's lane, with
    /// its `t`, `u`, `v` to the bit once divided: one lane, several lanes (nearest first),
    /// and several at the same distance (the first of them).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn scaled_test_picks_the_scalar_lane() {
        use rand::{Rng, SeedableRng};
        if !std::is_x86_feature_detected!("fma") {
            return;
        }
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let (o, d) = (Vec3::new(0.1, 0.2, 10.0), Vec3::new(0.01, -0.02, -1.0));
        let mut seen = [0usize; 5];
        for i in 0..20_000 {
            let mut t4 = Tri4::EMPTY;
            let mut hits = 0;
            for lane in 0..4 {
                // Planes at a few depths (ties are common), each triangle shifted so that
                // the ray passes through or beside it.
                let z = [0.0f32, 1.0, 2.5, -3.0][rng.random_range(0..4usize)] + if i % 3 == 0 { rng.random::<f32>() } else { 0.0 };
                let s = Vec3::new(rng.random_range(-1.5..0.5), rng.random_range(-1.5..0.5), z);
                let (a, b, c) = (s, s + Vec3::new(2.0, 0.0, 0.3), s + Vec3::new(0.0, 2.0, -0.2));
                // Sometimes an earlier lane's triangle again: the same distance exactly.
                let m = if lane > 0 && rng.random_range(0..4) == 0 {
                    Some(t4.lane(rng.random_range(0..lane)))
                } else {
                    UnitTriangle::new(a, b, c).map(|u| u.m)
                };
                if let Some(m) = m {
                    t4.set(lane, &m, lane as u32);
                    hits += unit_triangle_hit(&m, o, d, 0.0, f32::INFINITY).is_some() as usize;
                }
            }
            seen[hits] += 1;
            // SAFETY: FMA was detected above.
            let got = unsafe { sse::intersect_scaled(&t4, o, d, 0.0, f32::INFINITY) };
            let want = tri4_intersect_scalar(&t4, o, d, 0.0, f32::INFINITY);
            let bits = |t: f32, u: f32, v: f32, l: usize| (t.to_bits(), u.to_bits(), v.to_bits(), l);
            assert_eq!(got.map(|(t, u, v, den, l)| bits(t, u / den, v / den, l)), want.map(|h| bits(h.t, h.u, h.v, h.lane)), "case {i}");
        }
        assert!(seen.iter().all(|&n| n > 100), "every number of hit lanes is covered: {seen:?}");
    }

    /// The batched maps (AVX, four at a time) are the bits of `UnitTriangle::new`, on
    /// ordinary, tiny, huge, degenerate and non-finite triangles.
    #[test]
    fn batched_unit_maps_match_one_by_one() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut tris = Vec::new();
        for i in 0..4000 {
            let scale = [1.0f32, 1e-3, 1e-19, 1e-30, 1e19, 1e37][i % 6];
            let mut v =
                [0; 3].map(|_| Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)) * scale);
            match i % 11 {
                0 => v[2] = v[1],
                1 => v[2] = v[0] * 2.0 - v[1], // collinear up to rounding
                2 => v[1].x = f32::NAN,
                3 => v[0].y = f32::INFINITY,
                _ => {}
            }
            tris.push(v);
        }
        // The maps four at a time, in the SoA form the leaves take, turned back to one per
        // triangle.
        let mut out = vec![[0.0; 12]; tris.len()];
        let mut ok = vec![false; tris.len()];
        for ((t, o), k) in tris.chunks_exact(4).zip(out.chunks_exact_mut(4)).zip(ok.chunks_exact_mut(4)) {
            let (m, good) = unit_maps4_soa(&[t[0], t[1], t[2], t[3]]);
            for l in 0..4 {
                o[l] = std::array::from_fn(|e| m[e][l]);
                k[l] = good[l];
            }
        }
        let mut valid = 0;
        for ((t, o), k) in tris.iter().zip(&out).zip(&ok) {
            let want = UnitTriangle::new(t[0], t[1], t[2]);
            assert_eq!(*k, want.is_some(), "{t:?}");
            let want = want.map_or(NEVER_HIT, |u| u.m);
            assert_eq!(o.map(f32::to_bits), want.map(f32::to_bits), "{t:?}");
            valid += usize::from(*k);
        }
        assert!(valid > 2000 && valid < 3900, "{valid} valid: the cases should mix");
        // The build's cheap test keeps every triangle that has a map; it may keep more
        // (maps that overflow f32), never fewer.
        let mut extra = 0;
        for (t, k) in tris.iter().zip(&ok) {
            let possible = unit_map_possible(t[0], t[1], t[2]);
            assert!(possible || !k, "{t:?}");
            extra += usize::from(possible && !k);
        }
        assert!(extra < 1000, "{extra} kept without a map");
    }

    #[test]
    fn unit_triangle_maps_vertices() {
        let (a, b, c) = (Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 2.5, 3.0), Vec3::new(1.5, 6.0, 3.5));
        let m = UnitTriangle::new(a, b, c).expect("not degenerate").m;
        let map = |p: Vec3| {
            Vec3::new(
                m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3],
                m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
                m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11],
            )
        };
        assert!(map(a).abs_diff_eq(Vec3::ZERO, 1e-5));
        assert!(map(b).abs_diff_eq(Vec3::X, 1e-5));
        assert!(map(c).abs_diff_eq(Vec3::Y, 1e-5));
    }

    #[test]
    fn hit_and_barycentrics() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let m = UnitTriangle::new(a, b, c).expect("ok").m;
        let (t, u, v) = unit_triangle_hit(&m, Vec3::new(0.25, 0.5, 2.0), Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY).expect("hit");
        assert_eq!((t, u, v), (2.0, 0.25, 0.5));
        let w = WatertightRay::new(Vec3::new(0.25, 0.5, 2.0), Vec3::new(0.0, 0.0, -1.0));
        let (t2, u2, v2) = w.hit(a, b, c, 0.0, f32::INFINITY).expect("hit");
        assert!((t2 - 2.0).abs() < 1e-6 && (u2 - 0.25).abs() < 1e-6 && (v2 - 0.5).abs() < 1e-6);
        assert!(unit_triangle_hit(&m, Vec3::new(0.8, 0.8, 2.0), Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn degenerate_never_hits() {
        assert!(UnitTriangle::new(Vec3::ZERO, Vec3::X, Vec3::X * 2.0).is_none());
        assert!(UnitTriangle::new(Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)).is_none());
        let t4 = Tri4::EMPTY;
        for d in [Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE] {
            assert!(tri4_intersect(&t4, Vec3::ZERO, d, 0.0, f32::INFINITY).is_none());
            assert!(tri4_intersect_scalar(&t4, Vec3::ZERO, d, 0.0, f32::INFINITY).is_none());
        }
    }

    #[test]
    fn tiny_and_huge_scales_agree() {
        // The same configuration at scale 1e-3 and 1e3 gives the same hit/miss answers.
        for scale in [1e-3f32, 1.0, 1e3] {
            let (a, b, c) = (Vec3::ZERO, Vec3::X * scale, Vec3::Y * scale);
            let m = UnitTriangle::new(a, b, c).expect("ok").m;
            let o = Vec3::new(0.3, 0.3, 1.0) * scale;
            assert!(unit_triangle_hit(&m, o, -Vec3::Z, 0.0, f32::INFINITY).is_some());
            let o2 = Vec3::new(0.6, 0.6, 1.0) * scale;
            assert!(unit_triangle_hit(&m, o2, -Vec3::Z, 0.0, f32::INFINITY).is_none());
        }
    }
}
