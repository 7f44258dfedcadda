//! The packet itself: loading rays (and carrying them into an instance's space), the
//! direction and origin bounds, splitting by direction spread, the interval of the live
//! rays, and the hit records.

use super::core::*;

impl Packet {
    /// A packet with no rays, and its hits.
    #[inline(always)]
    pub(crate) fn empty() -> (Self, PacketHits) {
        let z = F8::splat(0.0);
        let p = Packet {
            groups: 0,
            valid: [M8::NONE; GROUPS],
            o: [[z; CYCLIC]; GROUPS],
            d: [[z; CYCLIC]; GROUPS],
            inv: [[z; 3]; GROUPS],
            tmin: [z; GROUPS],
            common: None,
            cull: None,
        };
        let h = PacketHits {
            t: [F8::splat(f32::NEG_INFINITY); GROUPS],
            u: [z; GROUPS],
            v: [z; GROUPS],
            prim: [[INVALID; LANES]; GROUPS],
            inst: [[INVALID; LANES]; GROUPS],
        };
        (p, h)
    }

    /// Loads up to [`GROUPS`] blocks of eight rays into this packet and resets `h` to
    /// "nothing within `tmax`" (invalid lanes at `-inf`). PERF: in place, so the chunk
    /// loops reuse one packet (returning it by value cost four copies of 4 KB per packet).
    #[inline(always)]
    pub(crate) fn load_blocks_into(&mut self, blocks: &[RayBlock], h: &mut PacketHits) {
        let groups = blocks.len().min(GROUPS);
        let z = F8::splat(0.0);
        let p = self;
        p.groups = groups;
        for g in groups..GROUPS {
            p.valid[g] = M8::NONE;
            h.t[g] = F8::splat(f32::NEG_INFINITY);
        }
        for (g, b) in blocks[..groups].iter().enumerate() {
            // PERF: written out, not `array::map`: its closure shim stayed an out-of-line
            // call compiled without AVX2 (a twentieth of a sparse REND3R frame).
            p.o[g] = [F8(b.org[0]), F8(b.org[1]), F8(b.org[2]), F8(b.org[0]), F8(b.org[1])];
            p.d[g] = [F8(b.dir[0]), F8(b.dir[1]), F8(b.dir[2]), F8(b.dir[0]), F8(b.dir[1])];
            p.tmin[g] = F8(b.tmin);
            let tmax = F8(b.tmax);
            p.inv[g] = recip3(&p.d[g]);
            // A ray counts when its origin and direction are finite (x·0 = 0), its direction
            // is not zero and its range is not empty (false for a NaN bound).
            let mut ok = p.tmin[g].lt(tmax);
            let mut nonzero = M8::NONE;
            for k in 0..3 {
                ok = ok.and(p.o[g][k].mul(z).eq(z)).and(p.d[g][k].mul(z).eq(z));
                nonzero = nonzero.or(p.d[g][k].ne(z));
            }
            p.valid[g] = ok.and(nonzero);
            h.t[g] = F8::splat(f32::NEG_INFINITY).blend(p.valid[g], tmax);
            h.u[g] = z;
            h.v[g] = z;
            h.prim[g] = [INVALID; LANES];
            h.inst[g] = [INVALID; LANES];
        }
        p.common = p.find_common_origin();
        p.cull = p.cull_bounds(&p.valid);
    }

    /// [`Packet::cull`] for the rays of `set`: their direction bounds when they share an
    /// origin and the packet is large enough to use them (PERF: the bounds cost 6% of an
    /// 8-ray packet).
    #[inline(always)]
    pub(super) fn cull_bounds(&self, set: &Masks) -> Option<DirBounds> {
        if self.common.is_some() && self.groups >= CULL_GROUPS {
            self.dir_bounds(set)
        } else {
            None
        }
    }

    /// Bounds of the directions of the rays in `set` (and whether all their `tmin` are at
    /// least 0); `None` when the set is empty.
    #[inline(always)]
    pub(super) fn dir_bounds(&self, set: &Masks) -> Option<DirBounds> {
        let inf = f32::INFINITY;
        let (mut lo, mut hi) = ([F8::splat(inf); 3], [F8::splat(-inf); 3]);
        let mut tmin = F8::splat(inf);
        let mut any = 0;
        for g in 0..self.groups {
            let m = set[g].and(self.valid[g]);
            if m.bits() == 0 {
                continue;
            }
            any |= m.bits();
            for k in 0..3 {
                lo[k] = lo[k].min(F8::splat(inf).blend(m, self.d[g][k]));
                hi[k] = hi[k].max(F8::splat(-inf).blend(m, self.d[g][k]));
            }
            tmin = tmin.min(F8::splat(inf).blend(m, self.tmin[g]));
        }
        if any == 0 {
            return None;
        }
        let hmin = |v: F8| -(v.neg().hmax());
        Some(DirBounds { lo: lo.map(hmin), hi: hi.map(F8::hmax), forward: hmin(tmin) >= 0.0 })
    }

    /// The origin every valid ray shares, bit for bit, if there is one.
    #[inline(always)]
    pub(super) fn find_common_origin(&self) -> Option<[f32; 3]> {
        let (g0, l0) = self.first_lane(&self.valid)?;
        let first: [u32; 3] = std::array::from_fn(|k| self.o[g0][k].0[l0].to_bits());
        let mut differ = 0u32;
        for g in g0..self.groups {
            // Lane by lane on the bits (a loop the compiler turns into vector compares).
            let mut d = [0i32; LANES];
            for (l, dl) in d.iter_mut().enumerate() {
                // PERF: `&`, not a short-circuiting `all` (whose early exit kept the loop
                // scalar: 50 instructions a group).
                let o = &self.o[g];
                let same = (o[0].0[l].to_bits() == first[0]) & (o[1].0[l].to_bits() == first[1]) & (o[2].0[l].to_bits() == first[2]);
                *dl = -(!same as i32);
            }
            differ |= M8(d).and(self.valid[g]).bits();
        }
        (differ == 0).then(|| first.map(f32::from_bits))
    }

    /// The first lane of `set` (group, lane), if it has any.
    #[inline(always)]
    pub(super) fn first_lane(&self, set: &Masks) -> Option<(usize, usize)> {
        let g = (0..self.groups).find(|&g| set[g].bits() != 0)?;
        Some((g, set[g].bits().trailing_zeros() as usize))
    }

    /// The direction of the ray in lane `l` of group `g`.
    #[inline(always)]
    pub(super) fn dir(&self, g: usize, l: usize) -> Vec3 {
        Vec3::new(self.d[g][0].0[l], self.d[g][1].0[l], self.d[g][2].0[l])
    }

    /// The ray in lane `l` of group `g`, its range ending at `tmax`.
    #[inline(always)]
    pub(crate) fn ray(&self, g: usize, l: usize, tmax: f32) -> Ray {
        Ray { org: Vec3::new(self.o[g][0].0[l], self.o[g][1].0[l], self.o[g][2].0[l]), dir: self.dir(g, l), tmin: self.tmin[g].0[l], tmax }
    }

    /// The rays of `active` in the object space of `inst`, as the single-ray path sees
    /// them: the packet itself for an instance whose transform is the identity (see
    /// [`crate::tlas::Instance::is_identity`]), else [`Packet::transformed`].
    #[inline(always)]
    pub(super) fn in_object_space(&self, inst: &crate::tlas::Instance, active: &Masks) -> std::borrow::Cow<'_, Self> {
        if inst.is_identity() {
            std::borrow::Cow::Borrowed(self)
        } else {
            std::borrow::Cow::Owned(self.transformed(&inst.object_from_world, active))
        }
    }

    /// The rays of `active` carried by `m` (object space of an instance), computed as
    /// `Ray::transformed` does, so the single-ray kernels see the same rays.
    #[inline(always)]
    pub(crate) fn transformed(&self, m: &Affine3A, active: &Masks) -> Self {
        let mut p = *self;
        let c = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
        let tr = m.translation;
        for g in 0..self.groups {
            if active[g].bits() == 0 {
                continue;
            }
            let [ox, oy, oz, ..] = self.o[g];
            let [dx, dy, dz, ..] = self.d[g];
            for r in 0..3 {
                let (a, b, cc) = (F8::splat(c[0][r]), F8::splat(c[1][r]), F8::splat(c[2][r]));
                p.o[g][r] = a.mul(ox).add(b.mul(oy)).add(cc.mul(oz)).add(F8::splat(tr[r]));
                p.d[g][r] = a.mul(dx).add(b.mul(dy)).add(cc.mul(dz));
            }
            (p.o[g][3], p.o[g][4], p.d[g][3], p.d[g][4]) = (p.o[g][0], p.o[g][1], p.d[g][0], p.d[g][1]);
            p.inv[g] = recip3(&p.d[g]);
        }
        // The same arithmetic on the same origin gives the same point in every lane.
        p.common = self.common.map(|o| {
            let r = |k: usize| c[0][k] * o[0] + c[1][k] * o[1] + c[2][k] * o[2] + tr[k];
            [r(0), r(1), r(2)]
        });
        p.cull = p.cull_bounds(active);
        p
    }

    /// Interval bounds of the rays in `active`; `None` when there are none or their
    /// direction signs disagree on some axis.
    #[inline(always)]
    pub(crate) fn interval(&self, active: &Masks) -> Option<Interval> {
        let inf = f32::INFINITY;
        let (mut olo, mut ohi) = ([F8::splat(inf); 3], [F8::splat(-inf); 3]);
        let (mut rlo, mut rhi) = (olo, ohi);
        let mut tmin = F8::splat(inf);
        let mut any = 0;
        for g in 0..self.groups {
            let m = active[g];
            if m.bits() == 0 {
                continue;
            }
            any |= m.bits();
            let (pinf, ninf) = (F8::splat(inf), F8::splat(-inf));
            for k in 0..3 {
                olo[k] = olo[k].min(pinf.blend(m, self.o[g][k]));
                ohi[k] = ohi[k].max(ninf.blend(m, self.o[g][k]));
                rlo[k] = rlo[k].min(pinf.blend(m, self.inv[g][k]));
                rhi[k] = rhi[k].max(ninf.blend(m, self.inv[g][k]));
            }
            tmin = tmin.min(pinf.blend(m, self.tmin[g]));
        }
        if any == 0 {
            return None;
        }
        let lo = |v: F8| -(v.neg().hmax());
        let mut iv = Interval {
            near: [0; 3],
            far: [0; 3],
            inear: [0; 3],
            ifar: [0; 3],
            olo: [0.0; 3],
            ohi: [0.0; 3],
            rlo: [0.0; 3],
            rhi: [0.0; 3],
            tmin: lo(tmin),
            narrow: true,
            pad: [0.0; 3],
        };
        // The length of one ray's direction, taken for all (PERF: lengths ray by ray, each
        // with a square root and a division, cost more; even so, this check costs 8-ray
        // packets of primary rays 7-10%, and 64-ray packets nothing measurable).
        let q = self.first_lane(active).map_or(f32::NAN, |(g, l)| self.dir(g, l).length());
        for k in 0..3 {
            iv.olo[k] = lo(olo[k]);
            iv.ohi[k] = ohi[k].hmax();
            iv.rlo[k] = lo(rlo[k]);
            iv.rhi[k] = rhi[k].hmax();
            let neg = iv.rhi[k] < 0.0;
            if !neg && iv.rlo[k] < 0.0 {
                return None; // mixed signs
            }
            iv.narrow &= iv.narrow_on(k, q);
            iv.pad[k] = if iv.rlo[k].abs().max(iv.rhi[k].abs()) >= PARALLEL_INV { f32::INFINITY } else { 0.0 };
            iv.near[k] = k + 3 * neg as usize;
            iv.far[k] = k + 3 * (!neg) as usize;
            iv.inear[k] = iv.near[k];
            iv.ifar[k] = iv.far[k];
        }
        Some(iv)
    }
}

impl Packet {
    /// Interval bounds for an any-hit query: those of the rays, or of the same segments
    /// walked backwards from their far ends when those ends are closer together (shadow rays
    /// of a tile start on many surfaces but all end at one light). Both bound every point of
    /// every segment, so culling with either is conservative; the exact per-ray tests stay
    /// on the forward rays.
    #[inline(always)]
    pub(crate) fn occlusion_interval(&self, active: &Masks, h: &PacketHits) -> Option<Interval> {
        let fwd = self.interval(active)?;
        if fwd.tmin < 0.0 {
            return Some(fwd);
        }
        let inf = f32::INFINITY;
        let mut elo = [F8::splat(inf); 3];
        let mut ehi = [F8::splat(-inf); 3];
        for g in 0..self.groups {
            let m = active[g];
            if m.bits() == 0 {
                continue;
            }
            for k in 0..3 {
                let e = self.o[g][k].add(self.d[g][k].mul(h.t[g]));
                elo[k] = elo[k].min(F8::splat(inf).blend(m, e));
                ehi[k] = ehi[k].max(F8::splat(-inf).blend(m, e));
            }
        }
        let mut rev = fwd;
        let (mut ext_f, mut ext_r) = (0.0f32, 0.0f32);
        for k in 0..3 {
            let (lo, hi) = (-(elo[k].neg().hmax()), ehi[k].hmax());
            // Widened by a few ulps of the coordinates: the ends are rounded.
            let pad = lo.abs().max(hi.abs()) * (1.0 / (1u32 << 20) as f32);
            rev.olo[k] = lo - pad;
            rev.ohi[k] = hi + pad;
            // Reversed directions: 1/(−d) = −(1/d) exactly.
            rev.rlo[k] = -fwd.rhi[k];
            rev.rhi[k] = -fwd.rlo[k];
            rev.inear[k] = fwd.far[k];
            rev.ifar[k] = fwd.near[k];
            ext_f += fwd.ohi[k] - fwd.olo[k];
            ext_r += rev.ohi[k] - rev.olo[k];
        }
        // The walk back covers [0, tmax − tmin] ⊂ [0, tmax] (the ends are padded above).
        rev.tmin = 0.0;
        Some(if ext_r.is_finite() && ext_r < ext_f { rev } else { fwd })
    }
}

/// Bounds of a set of ray origins.
#[derive(Clone, Copy)]
pub(crate) struct OriginBounds {
    pub(super) lo: [f32; 3],
    pub(super) hi: [f32; 3],
}

impl OriginBounds {
    /// The widest axis and its extent.
    #[inline(always)]
    pub(super) fn widest(&self) -> (usize, f32) {
        let mut best = (0, self.hi[0] - self.lo[0]);
        for k in 1..3 {
            if self.hi[k] - self.lo[k] > best.1 {
                best = (k, self.hi[k] - self.lo[k]);
            }
        }
        best
    }
}

impl Packet {
    /// Bounds of the origins of the lanes of `set`.
    #[inline(always)]
    pub(super) fn origin_bounds(&self, set: &Masks) -> OriginBounds {
        let inf = f32::INFINITY;
        let (mut lo, mut hi) = ([F8::splat(inf); 3], [F8::splat(-inf); 3]);
        for g in 0..self.groups {
            if set[g].bits() == 0 {
                continue;
            }
            for k in 0..3 {
                lo[k] = lo[k].min(F8::splat(inf).blend(set[g], self.o[g][k]));
                hi[k] = hi[k].max(F8::splat(-inf).blend(set[g], self.o[g][k]));
            }
        }
        // PERF: written out, not `array::map` (see `load_blocks_into`).
        let low = |v: F8| -(v.neg().hmax());
        OriginBounds { lo: [low(lo[0]), low(lo[1]), low(lo[2])], hi: [hi[0].hmax(), hi[1].hmax(), hi[2].hmax()] }
    }

    /// The lanes of `set` split at the middle of the widest axis of their origins' bounds
    /// `b`: those below it and the rest (both non-empty when the origins differ).
    #[inline(always)]
    pub(super) fn split_at(&self, set: &Masks, b: OriginBounds) -> (Masks, Masks) {
        let (axis, _) = b.widest();
        let mid = F8::splat(0.5 * b.lo[axis] + 0.5 * b.hi[axis]);
        let mut below = [M8::NONE; GROUPS];
        let mut above = [M8::NONE; GROUPS];
        for g in 0..self.groups {
            let m = self.o[g][axis].lt(mid);
            below[g] = m.and(set[g]);
            above[g] = m.andnot(set[g]);
        }
        (below, above)
    }

    /// The lanes of `set` split by the sign of their direction on the first axis where
    /// it differs (the sign of the reciprocal, which the interval tests go by): `None` when
    /// every lane has the same signs. Rays toward a light straight above a tile, or primary
    /// rays through the image's centre column, mix signs; each half is coherent again.
    #[inline(always)]
    pub(super) fn sign_split(&self, set: &Masks) -> Option<(Masks, Masks)> {
        let z = F8::splat(0.0);
        for k in 0..3 {
            let mut neg = [M8::NONE; GROUPS];
            let mut pos = [M8::NONE; GROUPS];
            let (mut any_neg, mut any_pos) = (0, 0);
            for g in 0..self.groups {
                let m = self.inv[g][k].lt(z);
                neg[g] = m.and(set[g]);
                pos[g] = m.andnot(set[g]);
                any_neg |= neg[g].bits();
                any_pos |= pos[g].bits();
            }
            if any_neg != 0 && any_pos != 0 {
                return Some((neg, pos));
            }
        }
        None
    }
}

/// [`recip`] of three rows (PERF: not `array::map`, see `load_blocks_into`).
#[inline(always)]
pub(super) fn recip3(d: &[F8; CYCLIC]) -> [F8; 3] {
    [recip(d[0]), recip(d[1]), recip(d[2])]
}

/// Lane-wise `1/d`, with |d| clamped to ≥ 1e-18 as in the single-ray kernel.
#[inline(always)]
pub(super) fn recip(d: F8) -> F8 {
    let tiny = 1e-18f32;
    let mut r = [0f32; LANES];
    for i in 0..LANES {
        let x = d.0[i];
        r[i] = 1.0 / if x.abs() < tiny { tiny.copysign(x) } else { x };
    }
    F8(r)
}

impl Interval {
    /// Whether the unit directions' component `k` spreads at most [`MAX_DIR_SPREAD`], for
    /// directions of length about `q` (one ray's; rays here are unit, or scaled alike by an
    /// instance's map). The components lie in `[1/rb, 1/rs]` in magnitude (the
    /// reciprocals' smallest and largest magnitudes `rs` and `rb`, all of one sign), so the
    /// unit components spread about `(1/rs − 1/rb)/q`, compared here without a division.
    /// False on NaN (a zero or overflowing length).
    #[inline(always)]
    pub(super) fn narrow_on(&self, k: usize, q: f32) -> bool {
        let (r1, r2) = (self.rlo[k].abs(), self.rhi[k].abs());
        let (rs, rb) = (r1.min(r2), r1.max(r2));
        rb - rs <= MAX_DIR_SPREAD * q * rs * rb
    }

    /// True when tracing `lanes` rays together pays: at least three of them, their unit
    /// directions within [`MAX_DIR_SPREAD`] of each other, and their origins within
    /// `extent` of each other on every axis. Scattered origins (the shadow
    /// rays toward a distant light of a tile that spans near and far surfaces) make the
    /// interval bound a large prism that many boxes meet; such rays go alone.
    #[inline(always)]
    pub(crate) fn worth(&self, lanes: u32, extent: f32) -> bool {
        lanes >= 3 && self.narrow && (0..3).all(|k| self.ohi[k] - self.olo[k] <= extent)
    }
}

/// The largest spread of unit directions (the range of one component) a packet may have.
/// Rays scattered over a whole octant (diffuse bounces) bound an interval that meets most
/// of the tree: walked together they were 10 to 80 times slower than one by one. Chosen
/// from `lucent bench rays` on the five presets (64-ray packets, 2 threads): against no
/// limit, 0.1 took Conference's shadow rays from 43 to 61 Mrays/s and Sponza's from 58 to
/// 73, diffuse rays from 0.1–1.5 to 7–8; primary rays stayed within noise. (0.25: shadows
/// 53 and diffuse 7 on Conference; 0.05: no better than 0.1.)
pub(super) const MAX_DIR_SPREAD: f32 = 0.1;

/// The largest origin spread a packet may have over geometry of bounds `b`: 4% of the
/// diagonal. Chosen from A/B runs with packet splitting on (`lucent bench dynamic`, `bench
/// rend3r`, `bench frame`): against 1%, the sphere field of REND3R's Table IV with a light
/// went from 16.1 to 13.9 ms and the sunflowers from 45.6 to 45.0 ms; the kitchen and the
/// mesh presets moved within noise (±3%).
#[inline(always)]
pub(super) fn max_spread(b: &crate::geom::Aabb) -> f32 {
    let d = (b.max - b.min).length();
    if d.is_finite() {
        0.04 * d
    } else {
        f32::INFINITY
    }
}

impl PacketHits {
    /// Largest `t` over the lanes of `active` (−inf when none).
    #[inline(always)]
    pub(super) fn max_t<K: KernelSet>(&self, groups: usize, active: &Masks) -> f32 {
        #[cfg(target_arch = "x86_64")]
        if K::SIMD {
            // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
            return unsafe { super::avx::max_t(self, groups, active) };
        }
        let mut m = F8::splat(f32::NEG_INFINITY);
        for g in 0..groups {
            m = m.max(F8::splat(f32::NEG_INFINITY).blend(active[g], self.t[g]));
        }
        m.hmax()
    }

    /// The hit of lane `l` of group `g`.
    #[inline(always)]
    pub(crate) fn get(&self, g: usize, l: usize) -> Hit {
        Hit { t: self.t[g].0[l], u: self.u[g].0[l], v: self.v[g].0[l], prim: self.prim[g][l], inst: self.inst[g][l] }
    }

    /// Sets lane `l` of group `g`.
    #[inline(always)]
    pub(crate) fn put(&mut self, g: usize, l: usize, h: &Hit) {
        self.t[g].0[l] = h.t;
        self.u[g].0[l] = h.u;
        self.v[g].0[l] = h.v;
        self.prim[g][l] = h.prim;
        self.inst[g][l] = h.inst;
    }
}
