//! The two-level index's packets: instance leaves (rays carried into each instance,
//! spheres eight rays at a time) and the entry points.

use super::core::*;
use super::leaves::*;
use super::mesh::*;
use super::rays::*;
use super::single::*;
use super::walk::*;

/// Instance leaves for packets.
pub(super) struct InstPacketLeaves<'a, K> {
    tl: &'a TwoLevel,
    k: std::marker::PhantomData<K>,
}

impl<K: SingleRay> InstPacketLeaves<'_, K> {
    /// The lanes `m` against instance `id`, closest hits into `h`.
    #[inline(always)]
    pub(super) fn hit_instance<C: Counters>(&self, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
        #[cfg(target_arch = "x86_64")]
        if K::SIMD {
            // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
            unsafe { avx2_hit_instance(self.tl, id, p, m, h, c) };
            return;
        }
        self.hit_instance_here(id, p, m, h, c);
    }

    /// The lanes `m` against instance `id`, occluded lanes to `-inf` in `h`.
    #[inline(always)]
    pub(super) fn occludes<C: Counters>(&self, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
        #[cfg(target_arch = "x86_64")]
        if K::SIMD {
            // SAFETY: as above.
            unsafe { avx2_occludes(self.tl, id, p, m, h, c) };
            return;
        }
        self.occludes_here(id, p, m, h, c);
    }

    /// Reports the lanes of `m` carried into `inst`'s object space (one report per ray,
    /// as the single-ray kernels make) and, for a shape, intersected with it.
    #[inline(always)]
    fn count_lanes<C: Counters>(&self, inst: &crate::tlas::Instance, p: &Packet, m: &Masks, c: &mut C) {
        let rays: u32 = m[..p.groups].iter().map(|x| x.bits().count_ones()).sum();
        if !inst.is_identity() {
            for _ in 0..rays {
                c.transform(std::ptr::from_ref(&inst.object_from_world) as usize, std::mem::size_of::<Affine3A>());
            }
        }
        if let Geometry::Shape(s) = &self.tl.geometries()[inst.geometry as usize] {
            for _ in 0..rays {
                c.shape(std::ptr::from_ref(s) as usize, std::mem::size_of::<Shape>());
            }
        }
    }

    #[inline(always)]
    pub(super) fn hit_instance_here<C: Counters>(&self, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
        let inst = &self.tl.instances()[id as usize];
        self.count_lanes(inst, p, m, c);
        match &self.tl.geometries()[inst.geometry as usize] {
            Geometry::Mesh(mesh) => {
                // The rays carried into object space exactly as the single-ray path does.
                c.enter(Level::Bottom);
                mesh.packet_intersect_k::<K, C>(&p.in_object_space(inst, m), m, h, id, false, c);
                c.enter(Level::Top);
            }
            Geometry::Shape(shape) => {
                #[cfg(target_arch = "x86_64")]
                if K::SIMD && *shape == Shape::Sphere {
                    for g in 0..p.groups {
                        if m[g].bits() == 0 {
                            continue;
                        }
                        // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
                        let (hit, t) = unsafe { sphere_group(p, g, inst, m[g], &h.t[g]) };
                        if hit.bits() != 0 {
                            // A sphere has one part (0) and no surface parameters here.
                            h.t[g] = h.t[g].blend(hit, t);
                            h.u[g] = h.u[g].blend(hit, F8::splat(0.0));
                            h.v[g] = h.v[g].blend(hit, F8::splat(0.0));
                            h.prim[g] = M8::blend_u32(hit, h.prim[g], [0; LANES]);
                            h.inst[g] = M8::blend_u32(hit, h.inst[g], [id; LANES]);
                        }
                    }
                    return;
                }
                // The same object-space rays as the single-ray path, without its box-test
                // constants (a shape needs none).
                let lp = p.transformed(&inst.object_from_world, m);
                for_lanes(p.groups, m, |g, l| {
                    let r = lp.ray(g, l, h.t[g].0[l]);
                    if let Some(s) = shape.intersect_local(r.org, r.dir, r.tmin, r.tmax) {
                        h.put(g, l, &Hit { t: s.t, u: 0.0, v: 0.0, prim: s.part, inst: id });
                    }
                });
            }
        }
    }

    #[inline(always)]
    pub(super) fn occludes_here<C: Counters>(&self, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
        let inst = &self.tl.instances()[id as usize];
        self.count_lanes(inst, p, m, c);
        match &self.tl.geometries()[inst.geometry as usize] {
            Geometry::Mesh(mesh) => {
                c.enter(Level::Bottom);
                mesh.packet_occluded_k::<K, C>(&p.in_object_space(inst, m), m, h, false, c);
                c.enter(Level::Top);
            }
            Geometry::Shape(shape) => {
                #[cfg(target_arch = "x86_64")]
                if K::SIMD && *shape == Shape::Sphere {
                    for g in 0..p.groups {
                        if m[g].bits() == 0 {
                            continue;
                        }
                        // SAFETY: as above.
                        let (hit, _) = unsafe { sphere_group(p, g, inst, m[g], &h.t[g]) };
                        h.t[g] = h.t[g].blend(hit, F8::splat(f32::NEG_INFINITY));
                    }
                    return;
                }
                let lp = p.transformed(&inst.object_from_world, m);
                for_lanes(p.groups, m, |g, l| {
                    let r = lp.ray(g, l, h.t[g].0[l]);
                    if shape.intersect_local(r.org, r.dir, r.tmin, r.tmax).is_some() {
                        h.t[g].0[l] = f32::NEG_INFINITY;
                    }
                });
            }
        }
    }
}

/// [`InstPacketLeaves::hit_instance`] with AVX2, out of line. Inlined, every kind of
/// instance (mesh walks with their own fallbacks, spheres, other shapes) made the top-level
/// occlusion walk one function of 137 KB of code; now it is 43 KB and this one 24 KB. Frame
/// times did not move either way (BART kitchen, 3 rounds), but profiles tell the two levels
/// apart.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
pub(super) fn avx2_hit_instance<C: Counters>(tl: &TwoLevel, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
    InstPacketLeaves::<crate::kernel::SimdSet> { tl, k: std::marker::PhantomData }.hit_instance_here(id, p, m, h, c);
}

/// [`InstPacketLeaves::occludes`] with AVX2, out of line (see [`avx2_hit_instance`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
pub(super) fn avx2_occludes<C: Counters>(tl: &TwoLevel, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
    InstPacketLeaves::<crate::kernel::SimdSet> { tl, k: std::marker::PhantomData }.occludes_here(id, p, m, h, c);
}

/// The unit-sphere test of the lanes `m` of group `g` against instance `inst` within
/// `[tmin, limit)`: the lanes that hit and their distances, the same as
/// [`Shape::intersect_local`] ray by ray. Lanes whose object-space direction is zero (the
/// SIMD code cannot divide by `a = 0`) are tested one by one.
///
/// # Safety
/// AVX2 and FMA must be available.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) unsafe fn sphere_group(p: &Packet, g: usize, inst: &crate::tlas::Instance, m: M8, limit: &F8) -> (M8, F8) {
    // SAFETY: the caller guarantees AVX2 and FMA.
    let (bits, mut t, odd) = unsafe { super::avx::sphere8(p, g, &inst.object_from_world, limit, m.bits()) };
    let mut hit = bits & m.bits();
    let mut b = odd & m.bits();
    while b != 0 {
        let l = b.trailing_zeros() as usize;
        b &= b - 1;
        let r = p.ray(g, l, limit.0[l]).transformed(&inst.object_from_world);
        if let Some(s) = Shape::Sphere.intersect_local(r.org, r.dir, r.tmin, r.tmax) {
            hit |= 1 << l;
            t.0[l] = s.t;
        }
    }
    (M8::from_bits(hit), t)
}

impl<K: SingleRay> PacketLeaves for InstPacketLeaves<'_, K> {
    #[inline(always)]
    fn intersect<C: Counters>(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
        for i in first..first + count {
            // The list unit reads an entry once for the packet.
            let e = &self.tl.order[i as usize];
            c.list_read(std::ptr::from_ref(e) as usize, 4);
            self.hit_instance(*e, p, m, h, c);
        }
    }
    #[inline(always)]
    fn occluded<C: Counters>(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
        for i in first..first + count {
            // Only the lanes still unoccluded go on.
            let live: Masks = std::array::from_fn(|g| h.t[g].ge(F8::splat(f32::MIN)).and(m[g]));
            if live.iter().all(|x| x.bits() == 0) {
                return;
            }
            let e = &self.tl.order[i as usize];
            c.list_read(std::ptr::from_ref(e) as usize, 4);
            self.occludes(*e, p, &live, h, c);
        }
    }
}

impl TwoLevel {
    #[inline(always)]
    pub(super) fn packet_intersect_k<K: SingleRay, C: Counters>(&self, p: &Packet, h: &mut PacketHits, c: &mut C) {
        let active = p.valid;
        if let Some(mesh) = self.only_mesh() {
            c.enter(Level::Bottom);
            mesh.packet_intersect_k::<K, _>(p, &active, h, 0, true, c);
            return;
        }
        c.enter(Level::Top);
        let leaves = InstPacketLeaves::<K> { tl: self, k: std::marker::PhantomData };
        let ext = max_spread(&self.bounds());
        coherent_parts!(
            p,
            &active,
            h,
            ext,
            true,
            |m, _hh| p.interval(m),
            |iv, m, h| {
                intersect::<K, _, _>(&self.nodes, &leaves, p, iv, m, h, c);
                for &i in &self.unbounded {
                    leaves.hit_instance(i, p, m, h, c);
                }
            },
            |g, l, h| {
                let mut hit = h.get(g, l);
                // SAFETY: the packet entry points run K only where its features were detected.
                unsafe { K::two_level_intersect(self, &p.ray(g, l, hit.t), &mut hit, c) };
                h.put(g, l, &hit);
            }
        );
    }

    #[inline(always)]
    pub(super) fn packet_among_k<K: SingleRay>(&self, ids: &[u32], p: &Packet, h: &mut PacketHits) {
        let leaves = InstPacketLeaves::<K> { tl: self, k: std::marker::PhantomData };
        let n = self.instances().len();
        for &i in ids.iter().filter(|&&i| (i as usize) < n).chain(&self.unbounded) {
            leaves.hit_instance(i, p, &p.valid, h, &mut ());
        }
    }

    #[inline(always)]
    pub(super) fn packet_occluded_k<K: SingleRay, C: Counters>(&self, p: &Packet, h: &mut PacketHits, c: &mut C) {
        let active = p.valid;
        if let Some(mesh) = self.only_mesh() {
            c.enter(Level::Bottom);
            mesh.packet_occluded_k::<K, _>(p, &active, h, true, c);
            return;
        }
        c.enter(Level::Top);
        let leaves = InstPacketLeaves::<K> { tl: self, k: std::marker::PhantomData };
        // Rays toward a directional light: the few instances near their origins, seen
        // from the light, without the walk.
        let mut ids = [0u32; crate::shadow_grid::MAX_CANDIDATES];
        if let Some(n) = self.shadow_candidates(p, &mut ids) {
            for &i in ids[..n].iter().chain(&self.unbounded) {
                leaves.occluded_one(i, p, &active, h, c);
            }
            return;
        }
        let ext = max_spread(&self.bounds());
        coherent_parts!(
            p,
            &active,
            h,
            ext,
            true,
            |m, hh| p.occlusion_interval(m, hh),
            |iv, m, h| {
                for &i in &self.unbounded {
                    leaves.occluded_one(i, p, m, h, c);
                }
                occluded::<K, _, _>(&self.nodes, &leaves, p, iv, m, h, c);
            },
            |g, l, h| {
                let t = h.t[g].0[l];
                // SAFETY: as above.
                if unsafe { K::two_level_occluded(self, &p.ray(g, l, t), t, c) } {
                    h.t[g].0[l] = f32::NEG_INFINITY;
                }
            }
        );
    }

    /// The instances that the valid rays of `p` can meet, besides the unbounded ones, when
    /// they all run along a direction with a shadow grid and there are few (see
    /// [`TwoLevel::set_shadow_directions`]).
    #[inline(always)]
    pub(super) fn shadow_candidates(&self, p: &Packet, out: &mut [u32; crate::shadow_grid::MAX_CANDIDATES]) -> Option<usize> {
        if self.shadow_grids.is_empty() {
            return None;
        }
        let (g0, l0) = p.first_lane(&p.valid)?;
        let d = p.dir(g0, l0).to_array();
        let grid = self.shadow_grids.iter().find(|gr| gr.dir.to_array().map(f32::to_bits) == d.map(f32::to_bits))?;
        // Every valid ray along exactly that direction.
        for g in 0..p.groups {
            let m = p.valid[g];
            if m.bits() == 0 {
                continue;
            }
            let same = p.d[g][0].eq(F8::splat(d[0])).and(p.d[g][1].eq(F8::splat(d[1]))).and(p.d[g][2].eq(F8::splat(d[2])));
            if same.and(m).bits() != m.bits() {
                return None;
            }
        }
        let b = p.origin_bounds(&p.valid);
        grid.candidates(glam::Vec3::from(b.lo), glam::Vec3::from(b.hi), out)
    }

    /// Closest hits of coherent rays over all instances, traced together in packets of up
    /// to [`MAX_PACKET`] (for example the 64 primary rays of an 8×8 pixel tile). The same
    /// answers as [`TwoLevel::intersect`] ray by ray, except which of two surfaces at exactly
    /// the same distance is reported. `out` must be as long as `rays`.
    pub fn intersect_packet(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.trace_intersect(Rays::Aos(rays), out);
    }

    /// Occlusion of coherent rays within `[tmin, tmax)` (for example the shadow rays of a
    /// tile toward one light), traced in packets: the same answers as [`TwoLevel::occluded`].
    pub fn occluded_packet(&self, rays: &[Ray], out: &mut [bool]) {
        self.trace_occluded(Rays::Aos(rays), out);
    }

    /// [`TwoLevel::intersect_packet`] with the portable kernel, reporting every step to `c`
    /// (the hardware study's seam): the same answers and visits as the fast packet
    /// kernels, apart from the whole-packet triangle cull, which only they make. A packet's
    /// inner node is read once for all its rays, as is an instance-list entry; a
    /// transformation or a triangle test is reported once for each ray it serves.
    pub fn intersect_packet_counted<C: Counters>(&self, rays: &[Ray], out: &mut [Option<Hit>], c: &mut C) {
        Rays::Aos(rays).each(|base, p, h| {
            self.packet_intersect_k::<ScalarSet, C>(p, h, c);
            write_hits(base, p, h, out);
        });
    }

    /// [`TwoLevel::occluded_packet`] with the portable kernel, reporting every step to `c`
    /// (as [`TwoLevel::intersect_packet_counted`]).
    pub fn occluded_packet_counted<C: Counters>(&self, rays: &[Ray], out: &mut [bool], c: &mut C) {
        Rays::Aos(rays).each(|base, p, h| {
            self.packet_occluded_k::<ScalarSet, C>(p, h, c);
            write_occluded(base, p, h, out);
        });
    }

    /// [`TwoLevel::intersect_packet`] on rays in SoA blocks; `out` holds eight entries per block.
    pub fn intersect_blocks(&self, blocks: &[RayBlock], out: &mut [Option<Hit>]) {
        self.trace_intersect(Rays::Soa(blocks), out);
    }

    /// [`TwoLevel::intersect_packet`] for rays known to meet no instance but those of
    /// `ids` (and the unbounded ones), for example primary rays of a screen block that only
    /// a few instances cover: those are tested directly, without the top-level walk. The
    /// same answers, except which of two surfaces at exactly the same distance is
    /// reported. Ids out of range are skipped.
    pub fn intersect_packet_among(&self, rays: &[Ray], ids: &[u32], out: &mut [Option<Hit>]) {
        match self.kernel {
            // SAFETY: the kernel is only Simd/Avx512 when AVX2 and FMA were detected.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd | Kernel::Avx512 => unsafe { avx2_tl_intersect_among(self, Rays::Aos(rays), ids, out) },
            _ => Rays::Aos(rays).each(|base, p, h| {
                self.packet_among_k::<ScalarSet>(ids, p, h);
                write_hits(base, p, h, out);
            }),
        }
    }

    /// [`TwoLevel::occluded_packet`] on rays in SoA blocks; `out` holds eight entries per block.
    pub fn occluded_blocks(&self, blocks: &[RayBlock], out: &mut [bool]) {
        self.trace_occluded(Rays::Soa(blocks), out);
    }

    #[inline(always)]
    pub(super) fn trace_intersect(&self, rays: Rays, out: &mut [Option<Hit>]) {
        match self.kernel {
            // SAFETY: the kernel is only Simd/Avx512 when AVX2 and FMA were detected.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd | Kernel::Avx512 => unsafe { avx2_tl_intersect(self, rays, out) },
            _ => rays.each(|base, p, h| {
                self.packet_intersect_k::<ScalarSet, _>(p, h, &mut ());
                write_hits(base, p, h, out);
            }),
        }
    }

    #[inline(always)]
    pub(super) fn trace_occluded(&self, rays: Rays, out: &mut [bool]) {
        match self.kernel {
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd | Kernel::Avx512 => unsafe { avx2_tl_occluded(self, rays, out) },
            _ => rays.each(|base, p, h| {
                self.packet_occluded_k::<ScalarSet, _>(p, h, &mut ());
                write_occluded(base, p, h, out);
            }),
        }
    }
}

impl<K: SingleRay> InstPacketLeaves<'_, K> {
    #[inline(always)]
    pub(super) fn occluded_one<C: Counters>(&self, id: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C) {
        let live: Masks = std::array::from_fn(|g| h.t[g].ge(F8::splat(f32::MIN)).and(m[g]));
        self.occludes(id, p, &live, h, c);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(super) fn avx2_tl_intersect(t: &TwoLevel, rays: Rays, out: &mut [Option<Hit>]) {
    // SAFETY: this function is compiled with AVX2, which its callers checked.
    unsafe {
        rays.each_avx2(|base, p, h| {
            t.packet_intersect_k::<crate::kernel::SimdSet, _>(p, h, &mut ());
            write_hits(base, p, h, out);
        })
    };
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(super) fn avx2_tl_intersect_among(t: &TwoLevel, rays: Rays, ids: &[u32], out: &mut [Option<Hit>]) {
    // SAFETY: this function is compiled with AVX2, which its callers checked.
    unsafe {
        rays.each_avx2(|base, p, h| {
            t.packet_among_k::<crate::kernel::SimdSet>(ids, p, h);
            write_hits(base, p, h, out);
        })
    };
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(super) fn avx2_tl_occluded(t: &TwoLevel, rays: Rays, out: &mut [bool]) {
    // SAFETY: this function is compiled with AVX2, which its callers checked.
    unsafe {
        rays.each_avx2(|base, p, h| {
            t.packet_occluded_k::<crate::kernel::SimdSet, _>(p, h, &mut ());
            write_occluded(base, p, h, out);
        })
    };
}
