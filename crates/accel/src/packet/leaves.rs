//! Triangle leaves for packets: eight rays against one triangle at a time, with the
//! single-ray test's arithmetic, and the leaf-level frustum cull for common origins.

use super::core::*;
use super::walk::*;

/// The unit-triangle test of one group of rays against lane `lane` of `t4`, exactly as
/// [`crate::triangle::unit_triangle_hit`] computes it: the hit mask and scaled `T, U, V, |D'z|`.
/// The lane must not be padding.
#[inline(always)]
pub(super) fn tri_eval(t4: &Tri4, lane: usize, p: &Packet, g: usize, tmax: F8) -> (M8, [F8; 4]) {
    let m = |c: usize| F8::splat(t4.m[c][lane]);
    let k = t4.axis(lane) as usize;
    let ([o0, o1, o2], [d0, d1, d2]) = (*cyclic(&p.o[g], k), *cyclic(&p.d[g], k));
    let dir = |i: usize| m(i).mul_add(d1, m(i + 1).mul_add(d2, F8::splat(t4.m[i + 2][lane] * 0.0)));
    let org = |i: usize| m(i).mul_add(o1, m(i + 1).mul_add(o2, m(i + 2)));
    let dzp = m(6).mul_add(d1, m(7).mul_add(d2, m(8).mul_add(F8::splat(0.0), d0)));
    let ozp = m(6).mul_add(o1, m(7).mul_add(o2, m(8).add(o0)));
    let (dxp, oxp, dyp, oyp) = (dir(0), org(0), dir(3), org(3));
    let adz = dzp.xor_sign(dzp);
    let uu = oxp.mul_add(dzp, ozp.mul(dxp).neg()).xor_sign(dzp);
    let vv = oyp.mul_add(dzp, ozp.mul(dyp).neg()).xor_sign(dzp);
    let tt = ozp.neg().xor_sign(dzp);
    let z = F8::splat(0.0);
    let ok = uu.ge(z).and(vv.ge(z)).and(uu.add(vv).le(adz)).and(tt.ge(p.tmin[g].mul(adz))).and(tt.lt(tmax.mul(adz)));
    (ok, [tt, uu, vv, adz])
}

/// Unit-triangle leaves for packets.
pub(crate) struct UnitPacketLeaves<'a, K> {
    pub tris: &'a [Tri4],
    /// Written into the `inst` of every hit.
    pub inst: u32,
    pub k: std::marker::PhantomData<K>,
    /// Triangles put to the whole-packet cull in this walk, and how many it dropped.
    pub culled: std::cell::Cell<[u32; 2]>,
}

/// Triangles the whole-packet cull is tried on before it must earn its keep.
pub(super) const CULL_TRIAL: u32 = 4;

impl<K: KernelSet> PacketLeaves for UnitPacketLeaves<'_, K> {
    #[inline(always)]
    fn prefetch(&self, first: u32) {
        if let Some(t4) = self.tris.get(first as usize) {
            crate::traverse::prefetch(t4);
        }
    }

    #[inline(always)]
    fn intersect<C: Counters>(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
        // PERF: the whole-packet culling of triangles only where several groups would test
        // them (one group's test costs about what the culling does), and only while it drops
        // at least two fifths of the triangles it is tried on. It drops 83% of those tried in
        // the museum, 54-58% in Conference, the kitchen and Sponza, but 31% of the Stanford
        // bunny's (triangles small next to the packet's footprint), where it cost 5-10%.
        #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
        let [mut tried, mut dropped] = self.culled.get();
        let cull = p
            .cull
            .as_ref()
            .filter(|_| tried < CULL_TRIAL || 5 * dropped >= 2 * tried)
            .filter(|_| m[..p.groups].iter().filter(|mg| mg.bits() != 0).count() >= CULL_GROUPS);
        #[cfg(not(target_arch = "x86_64"))]
        let _ = cull;
        for gi in first..first + count {
            // SAFETY: leaf ranges are in range of `tris` (built so, checked by `validate`).
            let t4 = unsafe { self.tris.get_unchecked(gi as usize) };
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
            let org = if K::SIMD { p.common.map(|o| unsafe { super::avx::origin_terms(t4, &o) }) } else { None };
            // Triangles that no ray of the packet can hit are dropped for all groups at once.
            #[cfg(target_arch = "x86_64")]
            let keep = match (&org, cull) {
                (Some(o), Some(c)) => {
                    // SAFETY: as above.
                    let keep = unsafe { super::avx::frustum_keep(t4, o, c) };
                    tried += 4;
                    dropped += 4 - keep.count_ones();
                    keep
                }
                _ => 0xF,
            };
            #[cfg(target_arch = "x86_64")]
            if keep == 0 {
                continue;
            }
            // Triangles each ray of a tested group is tested against (as the single-ray
            // kernel counts, a group's four unless the whole-packet cull dropped some).
            #[cfg(target_arch = "x86_64")]
            let tested = keep.count_ones();
            #[cfg(not(target_arch = "x86_64"))]
            let tested = 4;
            for g in 0..p.groups {
                if m[g].bits() == 0 {
                    continue;
                }
                count_rays(c, m[g], t4, tested);
                #[cfg(target_arch = "x86_64")]
                if K::SIMD {
                    // SAFETY: as above.
                    unsafe { super::avx::tri4_intersect(t4, p, g, &m[g], h, self.inst, org.as_ref(), keep) };
                    continue;
                }
                // As the four-lane single-ray test: all lanes against the same limit, then
                // the nearest, the first lane winning ties.
                let limit = h.t[g];
                let mut found = M8::NONE;
                let mut bt = F8::splat(f32::INFINITY);
                let mut bu = bt;
                let mut bv = bt;
                let mut bp = [INVALID; LANES];
                for lane in 0..4 {
                    // Padding lanes come last and never hit.
                    if t4.is_pad(lane) {
                        break;
                    }
                    let (ok, [tt, uu, vv, adz]) = tri_eval(t4, lane, p, g, limit);
                    let ok = ok.and(m[g]);
                    if ok.bits() == 0 {
                        continue;
                    }
                    let t = tt.div(adz);
                    let take = ok.and(found.andnot(M8([-1; LANES])).or(t.lt(bt)));
                    bt = bt.blend(take, t);
                    bu = bu.blend(take, uu.div(adz));
                    bv = bv.blend(take, vv.div(adz));
                    bp = M8::blend_u32(take, bp, [t4.id(lane); LANES]);
                    found = found.or(take);
                }
                if found.bits() != 0 {
                    h.t[g] = h.t[g].blend(found, bt);
                    h.u[g] = h.u[g].blend(found, bu);
                    h.v[g] = h.v[g].blend(found, bv);
                    h.prim[g] = M8::blend_u32(found, h.prim[g], bp);
                    h.inst[g] = M8::blend_u32(found, h.inst[g], [self.inst; LANES]);
                }
            }
        }
        self.culled.set([tried, dropped]);
    }

    #[inline(always)]
    fn occluded<C: Counters>(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
        let mut m = *m;
        for gi in first..first + count {
            // SAFETY: as above.
            let t4 = unsafe { self.tris.get_unchecked(gi as usize) };
            let mut left = 0;
            for g in 0..p.groups {
                if m[g].bits() == 0 {
                    continue;
                }
                count_rays(c, m[g], t4, 4);
                let limit = h.t[g];
                let mut hit = M8::NONE;
                #[cfg(target_arch = "x86_64")]
                if K::SIMD {
                    // SAFETY: as above.
                    hit = unsafe { super::avx::tri4_any(t4, p, g, &limit, &m[g]) };
                }
                if !K::SIMD {
                    for lane in 0..4 {
                        if t4.is_pad(lane) {
                            break;
                        }
                        hit = hit.or(tri_eval(t4, lane, p, g, limit).0);
                    }
                }
                let hit = hit.and(m[g]);
                h.t[g] = h.t[g].blend(hit, F8::splat(f32::NEG_INFINITY));
                m[g] = hit.andnot(m[g]);
                left |= m[g].bits();
            }
            if left == 0 {
                return;
            }
        }
    }
}

/// Reports to `c` that each ray of `m` tested `n` triangles of `t4` (one report per ray,
/// as the single-ray kernels make; nothing is left of this with `()` counters).
#[inline(always)]
fn count_rays<C: Counters>(c: &mut C, m: M8, t4: &Tri4, n: u32) {
    for _ in 0..m.bits().count_ones() {
        c.triangles(std::ptr::from_ref(t4) as usize, std::mem::size_of::<Tri4>(), n);
    }
}

/// Lanes of `m` as `(group, lane)` pairs.
#[inline(always)]
pub(crate) fn for_lanes(groups: usize, m: &Masks, mut f: impl FnMut(usize, usize)) {
    for (g, mg) in m.iter().enumerate().take(groups) {
        let mut b = mg.bits();
        while b != 0 {
            let l = b.trailing_zeros() as usize;
            b &= b - 1;
            f(g, l);
        }
    }
}
