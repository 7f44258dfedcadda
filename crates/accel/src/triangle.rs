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
//! **Nine numbers per map.** The map is fixed by the three vertices up to the choice of the
//! world vector that goes to (0,0,1). We send the coordinate axis `k` along which the
//! triangle's normal is largest there (Baldwin & Weber, "Fast Ray-Triangle Intersections
//! by Coordinate Transformation", JCGT 2016). The map's column `k` is then (0, 0, 1), so a
//! map is nine floats and the axis: with the components taken in the order `k, k+1, k+2`
//! (mod 3; a cyclic order keeps cross products), `O'x = a1·O1 + a2·O2 + a3`,
//! `O'y = b1·O1 + b2·O2 + b3`, `O'z = O0 + c1·O1 + c2·O2 + c3`, and the same without the
//! constants for `D'`. `D'z = n·D / n_k` is the cosine scaled by `|n| / n_k`. PERF: 36
//! bytes per triangle instead of 48, and 13 products per triangle instead of 18.
//!
//! The **watertight** test (Woop, Benthin & Wald, "Watertight Ray/Triangle Intersection",
//! JCGT 2013) is the selectable alternative: no gaps or double hits on shared edges.
//!
//! PERF: the test is evaluated without a division: with `s = sign(D'z)` the conditions are
//! multiplied through by `|D'z|` (`U = (O'x D'z − O'z D'x)·s ≥ 0`, `V = (O'y D'z − O'z D'y)·s ≥ 0`,
//! `U + V ≤ |D'z|`, `tmin |D'z| ≤ −O'z s < tmax |D'z|`), and `t, u, v` are divided out only
//! when a lane hits. `t = (−O'z s)/|D'z|` equals `−O'z/D'z` to the bit.
//!
//! The products are fused multiply-adds in one fixed order, which every version (scalar,
//! SIMD, the packet kernels) follows, so all return bit-identical answers (tested):
//! `O'x = fma(a1, O1, fma(a2, O2, a3·1))`, `D'x = fma(a1, D1, fma(a2, D2, a3·0))`,
//! `O'z = fma(c1, O1, fma(c2, O2, fma(c3, 1, O0)))`, `D'z = fma(c1, D1, fma(c2, D2,
//! fma(c3, 0, D0)))`, `U = fma(O'x, D'z, −O'z·D'x)`. (The products with 1 and 0 are what
//! lets the SIMD test compute `O'` and `D'` of four triangles in one 8-lane register.)

use glam::{DVec3, Vec3};

/// Bits of a [`Tri4`] lane's `prim` above the primitive id: the lane's axis.
pub const AXIS_SHIFT: u32 = 30;
/// The primitive id bits of a [`Tri4`] lane's `prim`.
pub const ID_MASK: u32 = (1 << AXIS_SHIFT) - 1;
/// The axis bits of a padding lane (its `prim` is `u32::MAX`): the SIMD test reads its
/// components as the zero that follows x, y, z, so `D'z = 0`.
pub const NO_AXIS: u32 = 3;
/// For axis `k`, the components in the order `k, k+1, k+2` (mod 3); [`NO_AXIS`] reads the
/// zero that follows x, y, z.
pub const ROTATION: [[usize; 3]; 4] = [[0, 1, 2], [1, 2, 0], [2, 0, 1], [3, 3, 3]];

/// The affine map into unit-triangle space in nine numbers (see the module notes):
/// `m = [a1, a2, a3, b1, b2, b3, c1, c2, c3]` for the rows of `O'x`, `O'y`, `O'z`, each
/// over components `k+1`, `k+2` of the ray and a constant, and the axis `k`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnitTriangle {
    /// The rows' free entries.
    pub m: [f32; 9],
    /// The axis `k` whose column is (0, 0, 1) ([`NO_AXIS`] for a padding lane's).
    pub axis: u32,
}

/// The map used for a padding lane or a degenerate triangle, which no ray hits whatever
/// axis it is read with: `O'x = O'y = −1` and `D'x = D'y = ±0`, so `U = V = −D'z`, below zero
/// after the sign flip unless `D'z = 0`, and then no `t` satisfies `tmin·0 ≤ T < tmax·0`
/// (NaN for infinite bounds or rays fails every comparison). Any axis serves, so the
/// packet kernels test a degenerate lane like any other, without a branch.
pub const NEVER_HIT: UnitTriangle = UnitTriangle { m: [0.0, 0.0, -1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0], axis: 0 };

/// The axis along which `n` is largest (the first of equals).
#[inline(always)]
fn largest_axis(n: DVec3) -> usize {
    let a = n.abs();
    if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    }
}

/// The largest vertex coordinate (in absolute value) lucent traces: 2^60, about 1.15e18. A
/// triangle with a corner beyond it (or a non-finite one) is left out of every build, like a
/// degenerate one, and the reference kernels skip it too. Beyond it the unit-triangle map of
/// a triangle with another corner near the origin has entries near f32's denormals, and the
/// test reports points far outside the triangle (a corner at 3.4e38 gave hits 50 units off
/// it); box arithmetic near f32's range overflows. No scene needs such coordinates.
pub const MAX_COORD: f32 = (1u64 << 60) as f32;

/// Whether every coordinate of `v` is finite and within [`MAX_COORD`].
#[inline(always)]
#[must_use]
pub fn in_range(v: Vec3) -> bool {
    v.abs().cmple(Vec3::splat(MAX_COORD)).all()
}

impl UnitTriangle {
    /// The map for triangle (v0, v1, v2), computed in f64; `None` when the triangle is
    /// degenerate (zero area) or has a corner out of range ([`in_range`]).
    #[must_use]
    pub fn new(v0: Vec3, v1: Vec3, v2: Vec3) -> Option<Self> {
        if !(in_range(v0) && in_range(v1) && in_range(v2)) {
            return None;
        }
        let (a, b, c) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
        let e1 = b - a;
        let e2 = c - a;
        let n = e1.cross(e2);
        let det = n.length_squared();
        if det.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || !det.is_finite() || !a.is_finite() {
            return None;
        }
        let k = largest_axis(n);
        let r = ROTATION[k];
        let rot = |p: DVec3| DVec3::new(p[r[0]], p[r[1]], p[r[2]]);
        let (a, e1, e2, n) = (rot(a), rot(e1), rot(e2), rot(n));
        // Rows of [e1 e2 X]^-1 in the rotated frame, X the first axis: (e2 × X)/n.x,
        // (X × e1)/n.x and n/n.x. PERF: one division, then products.
        let inv = 1.0 / n.x;
        let (a1, a2) = (e2.z * inv, -e2.y * inv);
        let (b1, b2) = (-e1.z * inv, e1.y * inv);
        let (c1, c2) = (n.y * inv, n.z * inv);
        let rows = [a1, a2, -(a1 * a.y + a2 * a.z), b1, b2, -(b1 * a.y + b2 * a.z), c1, c2, -(a.x + (c1 * a.y + c2 * a.z))];
        let m = rows.map(|v| v as f32);
        m.iter().all(|x| x.is_finite()).then_some(Self { m, axis: k as u32 })
    }

    /// The map for a triangle, or [`NEVER_HIT`] when it is degenerate.
    #[must_use]
    pub fn or_never(v0: Vec3, v1: Vec3, v2: Vec3) -> Self {
        Self::new(v0, v1, v2).unwrap_or(NEVER_HIT)
    }

    /// The map applied to point `p` (for tests and tools; the kernels never form it).
    #[must_use]
    pub fn apply(&self, p: Vec3) -> Vec3 {
        let r = ROTATION[self.axis as usize & 3];
        let c = [p.x, p.y, p.z, 0.0];
        let (p0, p1, p2) = (c[r[0]], c[r[1]], c[r[2]]);
        let m = &self.m;
        Vec3::new(m[0] * p1 + m[1] * p2 + m[2], m[3] * p1 + m[4] * p2 + m[5], p0 + m[6] * p1 + m[7] * p2 + m[8])
    }
}

/// Whether [`UnitTriangle::new`] finds the triangle non-degenerate: the same f64
/// arithmetic up to its determinant, which must be positive and finite, with a finite
/// first corner. (`new` also refuses maps that overflow f32, which only triangles of
/// extreme size make; the build keeps such a triangle as a lane that never hits.)
#[inline]
#[must_use]
pub fn unit_map_possible(v0: Vec3, v1: Vec3, v2: Vec3) -> bool {
    if !(in_range(v0) && in_range(v1) && in_range(v2)) {
        return false;
    }
    let (a, b, c) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
    let det = (b - a).cross(c - a).length_squared();
    det > 0.0 && det.is_finite() && a.is_finite()
}

/// The maps of four triangles in SoA form, as a [`Tri4`] holds them (`m[entry][lane]`),
/// their axes, and which are proper: lane `l` is `UnitTriangle::new(tris[l])` bit for bit,
/// or [`NEVER_HIT`] (and false) for a degenerate triangle. PERF: four triangles per AVX
/// register of f64 (the build computed every map alone: 30 ns a triangle, a tenth of a
/// 12k-triangle build).
#[must_use]
pub fn unit_maps4_soa(tris: &[[Vec3; 3]; 4]) -> ([[f32; 4]; 9], [u32; 4], [bool; 4]) {
    #[cfg(target_arch = "x86_64")]
    if crate::simd::avx() {
        // SAFETY: AVX was just detected.
        return unsafe { unit_maps4_soa_avx(tris) };
    }
    let mut m = [[0.0f32; 4]; 9];
    let mut axes = [0; 4];
    let mut ok = [false; 4];
    for (l, t) in tris.iter().enumerate() {
        let u = UnitTriangle::new(t[0], t[1], t[2]);
        ok[l] = u.is_some();
        let u = u.unwrap_or(NEVER_HIT);
        axes[l] = u.axis;
        for (e, v) in u.m.into_iter().enumerate() {
            m[e][l] = v;
        }
    }
    (m, axes, ok)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn unit_maps4_soa_avx(tris: &[[Vec3; 3]; 4]) -> ([[f32; 4]; 9], [u32; 4], [bool; 4]) {
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
    let mul = _mm256_mul_pd;
    let e1 = sub(b, a);
    let e2 = sub(c, a);
    let n = cross(e1, e2);
    // glam's `length_squared`: (x x + y y) + z z.
    let det = _mm256_add_pd(_mm256_add_pd(mul(n[0], n[0]), mul(n[1], n[1])), mul(n[2], n[2]));
    // The axis of each lane, as `largest_axis` picks it, then every vector in the order
    // k, k+1, k+2: a lane with axis 1 takes (y, z, x), one with axis 2 (z, x, y).
    let abs = |v: __m256d| _mm256_andnot_pd(_mm256_set1_pd(-0.0), v);
    let (ax, ay, az) = (abs(n[0]), abs(n[1]), abs(n[2]));
    let is_x = _mm256_and_pd(_mm256_cmp_pd::<_CMP_GE_OQ>(ax, ay), _mm256_cmp_pd::<_CMP_GE_OQ>(ax, az));
    let is_y = _mm256_andnot_pd(is_x, _mm256_cmp_pd::<_CMP_GE_OQ>(ay, az));
    let is_z = _mm256_andnot_pd(_mm256_or_pd(is_x, is_y), _mm256_castsi256_pd(_mm256_set1_epi32(-1)));
    let rot = |v: [__m256d; 3]| {
        let pick = |j: usize| {
            // Component j of the rotated vector: x,y,z → index (k + j) % 3.
            let on_y = _mm256_blendv_pd(v[j], v[(j + 1) % 3], is_y);
            _mm256_blendv_pd(on_y, v[(j + 2) % 3], is_z)
        };
        [pick(0), pick(1), pick(2)]
    };
    let (a, e1, e2, n) = (rot(a), rot(e1), rot(e2), rot(n));
    let inv = _mm256_div_pd(_mm256_set1_pd(1.0), n[0]);
    let neg = |v: __m256d| _mm256_xor_pd(v, _mm256_set1_pd(-0.0));
    let (a1, a2) = (mul(e2[2], inv), mul(neg(e2[1]), inv));
    let (b1, b2) = (mul(neg(e1[2]), inv), mul(e1[1], inv));
    let (c1, c2) = (mul(n[1], inv), mul(n[2], inv));
    let add = _mm256_add_pd;
    let rows = [
        a1,
        a2,
        neg(add(mul(a1, a[1]), mul(a2, a[2]))),
        b1,
        b2,
        neg(add(mul(b1, a[1]), mul(b2, a[2]))),
        c1,
        c2,
        neg(add(a[0], add(mul(c1, a[1]), mul(c2, a[2])))),
    ];
    let mut m = [[0.0f32; 4]; 9]; // m[entry][lane]
    for (e, v) in rows.into_iter().enumerate() {
        // Round to nearest, as `as f32` does.
        // SAFETY: `m[e]` holds four f32.
        unsafe { _mm_storeu_ps(m[e].as_mut_ptr(), _mm256_cvtpd_ps(v)) };
    }
    let mut dets = [0.0f64; 4];
    // SAFETY: `dets` holds four f64.
    unsafe { _mm256_storeu_pd(dets.as_mut_ptr(), det) };
    let on_y = _mm256_movemask_pd(is_y);
    let on_z = _mm256_movemask_pd(is_z);
    let mut axes = [0u32; 4];
    let mut ok = [false; 4];
    for l in 0..4 {
        let good = dets[l] > 0.0 && dets[l].is_finite() && tris[l].iter().all(|&v| in_range(v)) && m.iter().all(|col| col[l].is_finite());
        ok[l] = good;
        axes[l] = if on_z >> l & 1 == 1 { 2 } else { (on_y >> l & 1) as u32 };
        if !good {
            axes[l] = NEVER_HIT.axis;
            for (col, v) in m.iter_mut().zip(NEVER_HIT.m) {
                col[l] = v;
            }
        }
    }
    (m, axes, ok)
}

/// Unit-triangle test of one ray against one map: `Some((t, u, v))` when `t` is in
/// `[tmin, tmax)` and the point lies inside the triangle.
#[inline(always)]
#[must_use]
pub fn unit_triangle_hit(tri: &UnitTriangle, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
    let r = ROTATION[tri.axis as usize & 3];
    let (oc, dc) = ([o.x, o.y, o.z, 0.0], [d.x, d.y, d.z, 0.0]);
    let (o0, o1, o2) = (oc[r[0]], oc[r[1]], oc[r[2]]);
    let (d0, d1, d2) = (dc[r[0]], dc[r[1]], dc[r[2]]);
    let m = &tri.m;
    let dir = |i: usize| m[i].mul_add(d1, m[i + 1].mul_add(d2, m[i + 2] * 0.0));
    let org = |i: usize| m[i].mul_add(o1, m[i + 1].mul_add(o2, m[i + 2]));
    let dz = m[6].mul_add(d1, m[7].mul_add(d2, m[8].mul_add(0.0, d0)));
    let oz = m[6].mul_add(o1, m[7].mul_add(o2, m[8] + o0));
    let (dx, ox, dy, oy) = (dir(0), org(0), dir(3), org(3));
    let s = dz.to_bits() & 0x8000_0000;
    let sgn = |x: f32| f32::from_bits(x.to_bits() ^ s);
    let adz = sgn(dz);
    let uu = sgn(ox.mul_add(dz, -(oz * dx)));
    let vv = sgn(oy.mul_add(dz, -(oz * dy)));
    let tt = sgn(-oz);
    let ok = uu >= 0.0 && vv >= 0.0 && uu + vv <= adz && tt >= tmin * adz && tt < tmax * adz;
    ok.then(|| (tt / adz, uu / adz, vv / adz))
}

/// Four unit triangles in SoA form (component-major): 160 bytes, 40 a triangle.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Tri4 {
    /// `m[c][lane]`: entry `c` of the map of lane `lane` ([`UnitTriangle::m`]).
    pub m: [[f32; 4]; 9],
    /// Per lane: the primitive id in the low 30 bits ([`ID_MASK`]) and the map's axis above
    /// them ([`AXIS_SHIFT`]); `u32::MAX` for a padding lane.
    pub prim: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Tri4>() == 160);

impl Tri4 {
    /// A group whose lanes never hit.
    pub const EMPTY: Self = {
        let mut m = [[0.0f32; 4]; 9];
        let mut c = 0;
        while c < 9 {
            m[c] = [NEVER_HIT.m[c]; 4];
            c += 1;
        }
        Self { m, prim: [u32::MAX; 4] }
    };

    /// A lane's `prim`: primitive `id` (below 2^30) with the map's `axis` above it.
    #[inline(always)]
    #[must_use]
    pub const fn prim_of(id: u32, axis: u32) -> u32 {
        id & ID_MASK | axis << AXIS_SHIFT
    }

    /// Puts a map into a lane, for primitive `id` (below 2^30).
    pub fn set(&mut self, lane: usize, t: &UnitTriangle, id: u32) {
        for (c, v) in t.m.iter().enumerate() {
            self.m[c][lane] = *v;
        }
        self.prim[lane] = Self::prim_of(id, t.axis);
    }

    /// Makes a lane padding: never hit, no primitive.
    pub fn pad(&mut self, lane: usize) {
        self.set(lane, &NEVER_HIT, ID_MASK);
        self.prim[lane] = u32::MAX;
    }

    /// The map of one lane.
    #[must_use]
    pub fn lane(&self, lane: usize) -> UnitTriangle {
        UnitTriangle { m: std::array::from_fn(|c| self.m[c][lane]), axis: self.axis(lane) }
    }

    /// The primitive id of a lane (`ID_MASK` for padding).
    #[inline(always)]
    #[must_use]
    pub fn id(&self, lane: usize) -> u32 {
        self.prim[lane] & ID_MASK
    }

    /// The axis of a lane's map ([`NO_AXIS`] for padding).
    #[inline(always)]
    #[must_use]
    pub fn axis(&self, lane: usize) -> u32 {
        self.prim[lane] >> AXIS_SHIFT
    }

    /// The primitive ids of the lanes that are not padding.
    pub fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        (0..4).filter(|&l| !self.is_pad(l)).map(|l| self.id(l))
    }

    /// Whether a lane is padding (padding lanes come last).
    #[inline(always)]
    #[must_use]
    pub fn is_pad(&self, lane: usize) -> bool {
        self.prim[lane] == u32::MAX
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
    //! The four-triangle test with AVX2 and FMA (run only where they were detected).
    use super::{LaneHit, Tri4, AXIS_SHIFT};
    use glam::Vec3;
    use std::arch::x86_64::*;

    // PERF: these are `inline(always)` without `target_feature`: they inline into the AVX2
    // kernels, and the intrinsics then inline there. With `target_feature(enable = "fma")`
    // and a plain `inline`, LLVM kept `intersect` out of line, one call per triangle group,
    // and single primary rays were 15% slower.

    // PERF: the helpers below are `inline(always)` functions, not closures: a closure does
    // not take the `target_feature` of its caller, so one left out of line by LLVM turns
    // every intrinsic in it into a call.

    /// Row `c` of a group's maps in both halves of a register.
    ///
    /// # Safety
    /// AVX, as the callers below.
    #[inline(always)]
    unsafe fn row(t4: &Tri4, c: usize) -> __m256 {
        // SAFETY: `Tri4` is 16-byte aligned, so its 16-byte rows are; the caller's AVX.
        unsafe { _mm256_broadcast_ps(&*t4.m[c].as_ptr().cast::<__m128>()) }
    }

    /// Lane `at` (the same index in every lane) of `x`.
    ///
    /// # Safety
    /// AVX, as the callers below.
    #[inline(always)]
    unsafe fn pick(x: __m128, at: __m128i) -> f32 {
        // SAFETY: the caller's AVX.
        unsafe { _mm_cvtss_f32(_mm_permutevar_ps(x, at)) }
    }

    /// The lane mask of hits and the scaled `T, U, V` and `|D'z|` of all lanes.
    ///
    /// The origin's and the direction's terms share one 8-lane register: lanes 0..4 hold
    /// `O'` of the four triangles, lanes 4..8 `D'`. Each lane picks its ray components in
    /// its axis' order with an in-lane permute of `(O, 0 | D, 0)` (`vpermilps` reads an
    /// index's low two bits, so the axis bits of `prim` serve without masking), and the
    /// constant column is multiplied by `(1 | 0)`.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[inline(always)]
    unsafe fn eval(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> (i32, [__m128; 4]) {
        // SAFETY: `Tri4` is 16-byte aligned, so the 16-byte rows and ids are aligned and in
        // bounds; the caller guarantees AVX2 and FMA.
        unsafe {
            let ray = _mm256_setr_ps(o.x, o.y, o.z, 0.0, d.x, d.y, d.z, 0.0);
            let k = _mm256_srli_epi32::<{ AXIS_SHIFT as i32 }>(_mm256_broadcastsi128_si256(_mm_load_si128(t4.prim.as_ptr().cast())));
            let next = _mm256_castsi256_ps(_mm256_setr_epi32(1, 2, 0, 3, 1, 2, 0, 3));
            let after = _mm256_castsi256_ps(_mm256_setr_epi32(2, 0, 1, 3, 2, 0, 1, 3));
            let k1 = _mm256_castps_si256(_mm256_permutevar_ps(next, k));
            let k2 = _mm256_castps_si256(_mm256_permutevar_ps(after, k));
            let (p0, p1, p2) = (_mm256_permutevar_ps(ray, k), _mm256_permutevar_ps(ray, k1), _mm256_permutevar_ps(ray, k2));
            let one_zero = _mm256_setr_ps(1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0);
            let x = _mm256_fmadd_ps(row(t4, 0), p1, _mm256_fmadd_ps(row(t4, 1), p2, _mm256_mul_ps(row(t4, 2), one_zero)));
            let y = _mm256_fmadd_ps(row(t4, 3), p1, _mm256_fmadd_ps(row(t4, 4), p2, _mm256_mul_ps(row(t4, 5), one_zero)));
            let z = _mm256_fmadd_ps(row(t4, 6), p1, _mm256_fmadd_ps(row(t4, 7), p2, _mm256_fmadd_ps(row(t4, 8), one_zero, p0)));
            let (oxp, dxp) = (_mm256_castps256_ps128(x), _mm256_extractf128_ps::<1>(x));
            let (oyp, dyp) = (_mm256_castps256_ps128(y), _mm256_extractf128_ps::<1>(y));
            let (ozp, dzp) = (_mm256_castps256_ps128(z), _mm256_extractf128_ps::<1>(z));
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
    /// The CPU must support AVX2 and FMA.
    #[inline(always)]
    pub(crate) unsafe fn intersect_scaled(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32, f32, f32, usize)> {
        // SAFETY: the caller guarantees AVX2 and FMA.
        let (mask, [tt, uu, vv, adz]) = unsafe { eval(t4, o, d, tmin, tmax) };
        // PERF: every lane's distance is divided out before the mask is looked at, so the
        // division overlaps the mask's tests instead of following the lane's choice on the
        // path to `hit.t` (which the next box tests wait for).
        // SAFETY: SSE is implied by the FMA the caller guarantees.
        let t = unsafe { _mm_div_ps(tt, adz) };
        if mask == 0 {
            return None;
        }
        // SAFETY: SSE4.1 and AVX (`vpermilps`) are implied by the AVX2 and FMA the caller
        // guarantees.
        unsafe {
            // PERF: one lane hits (the common case): it is the lowest set bit, with no scan
            // over the lanes (whose branches on the mask a random lane mispredicted).
            let lane = if mask & (mask - 1) == 0 {
                mask.trailing_zeros() as usize & 3
            } else {
                // Several: the nearest, the first of equals (a horizontal minimum).
                let lanes = _mm_castsi128_ps(_mm_set_epi32(-(mask >> 3 & 1), -(mask >> 2 & 1), -(mask >> 1 & 1), -(mask & 1)));
                let ts = _mm_blendv_ps(_mm_set1_ps(f32::INFINITY), t, lanes);
                let m = _mm_min_ps(ts, _mm_shuffle_ps::<0b10_11_00_01>(ts, ts));
                let m = _mm_min_ps(m, _mm_shuffle_ps::<0b01_00_11_10>(m, m));
                ((_mm_movemask_ps(_mm_cmpeq_ps(ts, m)) & mask) as u32).trailing_zeros() as usize & 3
            };
            // PERF: the lane's values are moved to lane 0 in registers (`vpermilps`). Stored
            // to an array and read back, they were loaded by one masked 32-byte load across
            // the four 16-byte stores, which defeats store forwarding: a stall at every
            // group that hits.
            let at = _mm_set1_epi32(lane as i32);
            Some((pick(t, at), pick(uu, at), pick(vv, at), pick(adz, at), lane))
        }
    }

    /// [`intersect_scaled`] with the barycentrics divided out.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[inline(always)]
    pub(crate) unsafe fn intersect(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<LaneHit> {
        // SAFETY: the caller guarantees AVX2 and FMA.
        let h = unsafe { intersect_scaled(t4, o, d, tmin, tmax) };
        h.map(|(t, u, v, den, lane)| LaneHit { t, u: u / den, v: v / den, lane })
    }

    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[inline(always)]
    pub(crate) unsafe fn occluded(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> bool {
        // SAFETY: the caller guarantees AVX2 and FMA.
        unsafe { eval(t4, o, d, tmin, tmax).0 != 0 }
    }
}

/// Four-triangle closest-hit test with the fastest code this CPU has (identical answers).
#[inline]
#[must_use]
pub fn tri4_intersect(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<LaneHit> {
    #[cfg(target_arch = "x86_64")]
    if crate::simd::avx2_fma() {
        // SAFETY: AVX2 and FMA were just detected.
        return unsafe { sse::intersect(t4, o, d, tmin, tmax) };
    }
    tri4_intersect_scalar(t4, o, d, tmin, tmax)
}

/// Four-triangle any-hit test with the fastest code this CPU has.
#[inline]
#[must_use]
pub fn tri4_occluded(t4: &Tri4, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> bool {
    #[cfg(target_arch = "x86_64")]
    if crate::simd::avx2_fma() {
        // SAFETY: AVX2 and FMA were just detected.
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
        if !(crate::simd::avx2_fma()) {
            return;
        }
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let mut seen = [0usize; 5];
        let mut axes = [0usize; 4];
        for i in 0..20_000 {
            // The whole case turned by i % 3 (components cycled), so that the triangles'
            // normals lie along every axis.
            let turn = |p: Vec3| Vec3::from_array(std::array::from_fn(|c| p[(c + i) % 3]));
            let (o, d) = (turn(Vec3::new(0.1, 0.2, 10.0)), turn(Vec3::new(0.01, -0.02, -1.0)));
            let mut t4 = Tri4::EMPTY;
            let mut hits = 0;
            for lane in 0..4 {
                // Planes at a few depths (ties are common), each triangle shifted so that
                // the ray passes through or beside it.
                let z = [0.0f32, 1.0, 2.5, -3.0][rng.random_range(0..4usize)] + if i % 3 == 0 { rng.random::<f32>() } else { 0.0 };
                let s = Vec3::new(rng.random_range(-1.5..0.5), rng.random_range(-1.5..0.5), z);
                let (a, b, c) = (turn(s), turn(s + Vec3::new(2.0, 0.0, 0.3)), turn(s + Vec3::new(0.0, 2.0, -0.2)));
                // Sometimes an earlier lane's triangle again: the same distance exactly.
                let m = if lane > 0 && rng.random_range(0..4) == 0 {
                    Some(t4.lane(rng.random_range(0..lane))).filter(|m| *m != NEVER_HIT)
                } else {
                    UnitTriangle::new(a, b, c)
                };
                if let Some(m) = m {
                    axes[m.axis as usize] += 1;
                    t4.set(lane, &m, lane as u32);
                    hits += unit_triangle_hit(&m, o, d, 0.0, f32::INFINITY).is_some() as usize;
                }
            }
            seen[hits] += 1;
            // SAFETY: AVX2 and FMA were detected above.
            let got = unsafe { sse::intersect_scaled(&t4, o, d, 0.0, f32::INFINITY) };
            let want = tri4_intersect_scalar(&t4, o, d, 0.0, f32::INFINITY);
            let bits = |t: f32, u: f32, v: f32, l: usize| (t.to_bits(), u.to_bits(), v.to_bits(), l);
            assert_eq!(got.map(|(t, u, v, den, l)| bits(t, u / den, v / den, l)), want.map(|h| bits(h.t, h.u, h.v, h.lane)), "case {i}");
        }
        assert!(seen.iter().all(|&n| n > 100), "every number of hit lanes is covered: {seen:?}");
        assert!(axes[..3].iter().all(|&n| n > 1000), "every axis is covered: {axes:?}");
    }

    /// The batched maps (AVX, four at a time) are the bits of `UnitTriangle::new`, on
    /// ordinary, tiny, huge (near [`MAX_COORD`] and beyond it), degenerate and non-finite
    /// triangles.
    #[test]
    fn batched_unit_maps_match_one_by_one() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut tris = Vec::new();
        for i in 0..4000 {
            let scale = [1.0f32, 1e-3, 1e-19, 1e-30, 1e18, 1e37][i % 6];
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
        let mut out = vec![NEVER_HIT; tris.len()];
        let mut ok = vec![false; tris.len()];
        for ((t, o), k) in tris.chunks_exact(4).zip(out.chunks_exact_mut(4)).zip(ok.chunks_exact_mut(4)) {
            let (m, axes, good) = unit_maps4_soa(&[t[0], t[1], t[2], t[3]]);
            for l in 0..4 {
                o[l] = UnitTriangle { m: std::array::from_fn(|e| m[e][l]), axis: axes[l] };
                k[l] = good[l];
            }
        }
        let mut valid = 0;
        let mut axes = [0; 4];
        for ((t, o), k) in tris.iter().zip(&out).zip(&ok) {
            let want = UnitTriangle::new(t[0], t[1], t[2]);
            assert_eq!(*k, want.is_some(), "{t:?}");
            let want = want.unwrap_or(NEVER_HIT);
            assert_eq!((o.m.map(f32::to_bits), o.axis), (want.m.map(f32::to_bits), want.axis), "{t:?}");
            valid += usize::from(*k);
            axes[o.axis as usize] += 1;
        }
        assert!(axes[..3].iter().all(|&n| n > 100), "every axis is covered: {axes:?}");
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

    /// The map sends the corners to the unit triangle's, whichever axis the normal is
    /// largest along, and the axis it keeps to (0, 0, 1).
    #[test]
    fn unit_triangle_maps_vertices() {
        let (a, b, c) = (Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 2.5, 3.0), Vec3::new(1.5, 6.0, 3.5));
        for k in 0..3 {
            // The triangle turned so its normal is largest along x, y, then z.
            let turn = |p: Vec3| Vec3::from_array(std::array::from_fn(|i| p[(i + 1 + k) % 3]));
            let (a, b, c) = (turn(a), turn(b), turn(c));
            let u = UnitTriangle::new(a, b, c).expect("not degenerate");
            let want = largest_axis((b - a).cross(c - a).as_dvec3()) as u32;
            assert_eq!(u.axis, want);
            assert!(u.apply(a).abs_diff_eq(Vec3::ZERO, 1e-5));
            assert!(u.apply(b).abs_diff_eq(Vec3::X, 1e-5));
            assert!(u.apply(c).abs_diff_eq(Vec3::Y, 1e-5));
            let mut axis = Vec3::ZERO;
            axis[u.axis as usize] = 1.0;
            assert!((u.apply(a + axis) - u.apply(a)).abs_diff_eq(Vec3::Z, 1e-5));
        }
    }

    #[test]
    fn hit_and_barycentrics() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let m = UnitTriangle::new(a, b, c).expect("ok");
        let (t, u, v) = unit_triangle_hit(&m, Vec3::new(0.25, 0.5, 2.0), Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY).expect("hit");
        assert_eq!((t, u, v), (2.0, 0.25, 0.5));
        let w = WatertightRay::new(Vec3::new(0.25, 0.5, 2.0), Vec3::new(0.0, 0.0, -1.0));
        let (t2, u2, v2) = w.hit(a, b, c, 0.0, f32::INFINITY).expect("hit");
        assert!((t2 - 2.0).abs() < 1e-6 && (u2 - 0.25).abs() < 1e-6 && (v2 - 0.5).abs() < 1e-6);
        assert!(unit_triangle_hit(&m, Vec3::new(0.8, 0.8, 2.0), Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY).is_none());
    }

    /// The never-hit map misses every ray read with any axis (the packet kernels test a
    /// degenerate lane like any other), and padding lanes miss in every kernel: rays along
    /// the axes, through the origin, with zero, infinite and NaN parts.
    #[test]
    fn degenerate_never_hits() {
        use rand::{Rng, SeedableRng};
        assert!(UnitTriangle::new(Vec3::ZERO, Vec3::X, Vec3::X * 2.0).is_none());
        assert!(UnitTriangle::new(Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)).is_none());
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let odd = [0.0, -0.0, 1.0, -1.0, 1e-30, 1e30, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        let mut rays: Vec<(Vec3, Vec3)> = Vec::new();
        for _ in 0..5000 {
            let pick = |rng: &mut rand_pcg::Pcg64| {
                if rng.random_range(0..3) == 0 {
                    odd[rng.random_range(0..odd.len())]
                } else {
                    rng.random_range(-10.0..10.0)
                }
            };
            let o = Vec3::new(pick(&mut rng), pick(&mut rng), pick(&mut rng));
            let d = Vec3::new(pick(&mut rng), pick(&mut rng), pick(&mut rng));
            rays.push((o, d));
        }
        for d in [Vec3::X, Vec3::Y, Vec3::Z, Vec3::NEG_Z, Vec3::ONE] {
            rays.push((Vec3::ZERO, d));
        }
        for axis in 0..4 {
            let never = UnitTriangle { axis, ..NEVER_HIT };
            let mut t4 = Tri4::EMPTY;
            t4.set(0, &never, 7);
            for &(o, d) in &rays {
                for (lo, hi) in [(0.0, f32::INFINITY), (-f32::INFINITY, f32::INFINITY), (0.0, 1.0)] {
                    assert!(unit_triangle_hit(&never, o, d, lo, hi).is_none(), "axis {axis}: {o} {d}");
                    assert!(tri4_intersect(&t4, o, d, lo, hi).is_none(), "axis {axis}: {o} {d}");
                    assert!(!tri4_occluded(&t4, o, d, lo, hi), "axis {axis}: {o} {d}");
                    assert!(tri4_intersect_scalar(&t4, o, d, lo, hi).is_none());
                }
            }
        }
    }

    #[test]
    fn tiny_and_huge_scales_agree() {
        // The same configuration at scale 1e-3 and 1e3 gives the same hit/miss answers.
        for scale in [1e-3f32, 1.0, 1e3] {
            let (a, b, c) = (Vec3::ZERO, Vec3::X * scale, Vec3::Y * scale);
            let m = UnitTriangle::new(a, b, c).expect("ok");
            let o = Vec3::new(0.3, 0.3, 1.0) * scale;
            assert!(unit_triangle_hit(&m, o, -Vec3::Z, 0.0, f32::INFINITY).is_some());
            let o2 = Vec3::new(0.6, 0.6, 1.0) * scale;
            assert!(unit_triangle_hit(&m, o2, -Vec3::Z, 0.0, f32::INFINITY).is_none());
        }
    }
}
