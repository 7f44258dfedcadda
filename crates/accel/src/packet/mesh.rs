//! Entry points for one mesh: rays in chunks of up to [`MAX_PACKET`], split into coherent
//! packets, with the AVX2 builds of the kernels.

use super::core::*;
use super::leaves::*;
use super::rays::*;
use super::single::*;
use super::walk::*;

/// Runs `body` on every chunk of at most [`MAX_PACKET`] rays, with the packet loaded.
#[inline(always)]
pub(super) fn chunks(rays: &[Ray], body: impl FnMut(usize, &Packet, &mut PacketHits)) {
    aos_chunks(
        rays,
        |eight, b| {
            for (l, r) in eight.iter().enumerate() {
                b.set(l, r);
            }
        },
        body,
    );
}

/// Runs `body` on every chunk of at most [`MAX_PACKET`] rays, with the packet loaded:
/// `fill(rays, block)` puts up to eight rays into a block, and one packet is reused.
#[inline(always)]
pub(super) fn aos_chunks(rays: &[Ray], mut fill: impl FnMut(&[Ray], &mut RayBlock), mut body: impl FnMut(usize, &Packet, &mut PacketHits)) {
    with_spare_packet(|p, h| {
        for (c, chunk) in rays.chunks(MAX_PACKET).enumerate() {
            let mut blocks = [RayBlock::EMPTY; GROUPS];
            for (b, eight) in blocks.iter_mut().zip(chunk.chunks(LANES)) {
                fill(eight, b);
            }
            p.load_blocks_into(&blocks[..chunk.len().div_ceil(LANES)], h);
            body(c * MAX_PACKET, p, h);
        }
    });
}

thread_local! {
    /// Each thread's packet between calls (see [`with_spare_packet`]).
    static SPARE_PACKET: std::cell::Cell<Option<Box<(Packet, PacketHits)>>> = const { std::cell::Cell::new(None) };
}

/// Runs `body` with a packet and its hits to load rays into: the thread's spare one (left
/// as the previous call left it), or a new one when a call is already using it. PERF: a
/// fresh packet is 4 KB to zero per call, a fiftieth of a sparse REND3R frame.
/// [`Packet::load_blocks_into`] sets everything a kernel reads, whatever was there before.
#[inline(always)]
pub(super) fn with_spare_packet(body: impl FnOnce(&mut Packet, &mut PacketHits)) {
    let mut spare = SPARE_PACKET.with(std::cell::Cell::take).unwrap_or_else(|| Box::new(Packet::empty()));
    let (p, h) = &mut *spare;
    body(p, h);
    SPARE_PACKET.with(|s| s.set(Some(spare)));
}

/// Runs `body` on every run of at most [`GROUPS`] blocks, with the packet loaded. The next
/// packet's blocks are asked for before a packet is traced, so a long stream of blocks
/// does not wait on memory at every load. PERF: 64-ray shadow packets in the BART kitchen
/// mostly end at their first leaf; without the hint a quarter of their time went to
/// loading their 2 KB of rays.
#[inline(always)]
pub(super) fn block_chunks(blocks: &[RayBlock], mut body: impl FnMut(usize, &Packet, &mut PacketHits)) {
    with_spare_packet(|p, h| {
        for (c, chunk) in blocks.chunks(GROUPS).enumerate() {
            p.load_blocks_into(chunk, h);
            let next = (c + 1) * GROUPS;
            prefetch_blocks(blocks.get(next..(next + GROUPS).min(blocks.len())).unwrap_or(&[]));
            body(c * MAX_PACKET, p, h);
        }
    });
}

/// Asks for the cache lines of `blocks` (a hint: nothing changes but how soon they can be
/// read; no effect off x86-64). A caller streaming blocks to [`MeshBvh::intersect_blocks`]
/// or [`MeshBvh::occluded_blocks`] in several calls can hand the next call's first blocks
/// here before the current call: each call already asks for its own later packets.
#[inline(always)]
pub fn prefetch_blocks(blocks: &[RayBlock]) {
    #[cfg(target_arch = "x86_64")]
    {
        // Every line the slice touches (blocks are aligned to 32 bytes, not to lines).
        let base = blocks.as_ptr().cast::<i8>();
        let bytes = std::mem::size_of_val(blocks);
        let mut at = 0;
        while at < bytes + (base as usize & 63) {
            // SAFETY: a prefetch hint (it never faults), at lines that overlap the slice;
            // SSE is part of x86-64.
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(base.wrapping_add(at)) };
            at += 64;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = blocks;
}

/// How many times a packet whose origins spread too far may be halved (up to 16 parts).
pub(super) const SPLIT_DEPTH: usize = 4;

/// Traces the lanes of `active` as one packet when `interval` bounds them and tracing them
/// together pays ([`Interval::worth`] with origin spread `ext`). A packet whose origins
/// spread too far (the shadow rays of a tile that spans several objects) is halved at the
/// middle of its widest origin axis, up to [`SPLIT_DEPTH`] times, and each half tried again:
/// rays that start on one object stay together. Rays that mix direction signs (no interval
/// bounds them: a light straight above the tile, a view along an axis) are halved by sign
/// instead ([`Packet::sign_split`]), also up to [`SPLIT_DEPTH`] times. What is left (fewer
/// than three rays, or still scattered) goes as groups of eight when a group agrees on
/// direction signs, else ray by ray. `split` false turns the halving by origin off: inside
/// an instance the packet was already formed by the top level (splitting there again cost
/// the sunflowers 8%); sign splits stay on, as a rotation can mix the signs of rays that
/// agreed in world space. PERF: before sign splits, such rays went one by one: the BART
/// kitchen's frame with shadows took 6% longer.
///
/// PERF: a macro, not a function taking closures: closures are not compiled with the
/// caller's target features, so the AVX2 kernels would not inline into them.
macro_rules! coherent_parts {
    ($p:expr, $active:expr, $h:expr, $ext:expr, $split:expr, |$m:ident, $hh:ident| $interval:expr, |$iv:ident, $pm:ident, $ph:ident| $packet:expr, |$g:ident, $l:ident, $sh:ident| $single:expr) => {{
        let p: &Packet = $p;
        let h: &mut PacketHits = $h;
        let ext: f32 = $ext;
        let mut work = [([M8::NONE; GROUPS], 0usize); SPLIT_DEPTH + 1];
        work[0] = (*$active, 0);
        let max_depth = if $split { SPLIT_DEPTH } else { 0 };
        let mut n = 1;
        // Lanes no packet took; they go by groups (and rays) afterwards, each group once.
        let mut rest = [M8::NONE; GROUPS];
        while n > 0 {
            n -= 1;
            let (set, depth) = work[n];
            let lanes = lane_count(&set);
            // The parts of a split are bounded by their origins first (cheap), and only
            // those that are close enough get the full interval.
            let bounds = (depth > 0).then(|| p.origin_bounds(&set));
            let close = bounds.is_none_or(|b| b.widest().1 <= ext && lanes >= 3);
            // Whether halving may still help; rays that mix direction signs (no interval) are
            // split by sign instead.
            let mut by_sign = None;
            let splittable = if close {
                let whole = {
                    let ($m, $hh) = (&set, &*h);
                    $interval
                };
                match whole {
                    Some(iv) if iv.worth(lanes, ext) => {
                        let ($iv, $pm, $ph) = (&iv, &set, &mut *h);
                        $packet;
                        continue;
                    }
                    Some(_) => true,
                    None => {
                        by_sign = p.sign_split(&set);
                        by_sign.is_some()
                    }
                }
            } else {
                true
            };
            // Sign splits are made inside instances too (see above).
            let limit = if by_sign.is_some() { SPLIT_DEPTH } else { max_depth };
            if splittable && depth < limit && lanes >= 6 {
                let (below, above) = match by_sign {
                    Some(halves) => halves,
                    None => p.split_at(&set, bounds.unwrap_or_else(|| p.origin_bounds(&set))),
                };
                work[n] = (below, depth + 1);
                work[n + 1] = (above, depth + 1);
                n += 2;
            } else {
                for g in 0..GROUPS {
                    rest[g] = rest[g].or(set[g]);
                }
            }
        }
        for g in 0..p.groups {
            if rest[g].bits() == 0 {
                continue;
            }
            let mut one = [M8::NONE; GROUPS];
            one[g] = rest[g];
            let part = {
                let ($m, $hh) = (&one, &*h);
                $interval
            };
            match part {
                Some(iv) if iv.worth(lane_count(&one), ext) => {
                    let ($iv, $pm, $ph) = (&iv, &one, &mut *h);
                    $packet;
                }
                _ => {
                    let mut b = rest[g].bits();
                    while b != 0 {
                        let l = b.trailing_zeros() as usize;
                        b &= b - 1;
                        let ($g, $l, $sh) = (g, l, &mut *h);
                        $single;
                    }
                }
            }
        }
    }};
}

/// Number of lanes set in `m`.
#[inline(always)]
pub(super) fn lane_count(m: &Masks) -> u32 {
    m.iter().map(|x| x.bits().count_ones()).sum()
}

impl MeshBvh {
    /// Closest hits of the lanes of `active` (packet traversal when the mesh has 8-wide
    /// unit-triangle nodes and the rays agree on direction signs; else ray by ray).
    #[inline(always)]
    pub(crate) fn packet_intersect_k<K: SingleRay, C: Counters>(
        &self,
        p: &Packet,
        active: &Masks,
        h: &mut PacketHits,
        inst: u32,
        split: bool,
        c: &mut C,
    ) {
        let single = |g: usize, l: usize, h: &mut PacketHits, c: &mut C| {
            let mut hit = h.get(g, l);
            // SAFETY: the packet entry points run K only where its features were detected.
            if unsafe { K::mesh_intersect(self, &p.ray(g, l, hit.t), &mut hit, c) } {
                hit.inst = inst;
            }
            h.put(g, l, &hit);
        };
        if let (TriangleTest::UnitTriangle, Nodes::W8(n)) = (self.test, &self.nodes) {
            let leaves = UnitPacketLeaves::<K> { tris: &self.tris, inst, k: std::marker::PhantomData, culled: Default::default() };
            let ext = max_spread(&self.bounds());
            coherent_parts!(
                p,
                active,
                h,
                ext,
                split,
                |m, _hh| p.interval(m),
                |iv, m, h| intersect::<K, _, _>(n, &leaves, p, iv, m, h, c),
                |g, l, h| single(g, l, h, c)
            );
        } else {
            for_lanes(p.groups, active, |g, l| single(g, l, h, c));
        }
    }

    /// Occlusion of the lanes of `active` (occluded lanes get `t = -inf`).
    #[inline(always)]
    pub(crate) fn packet_occluded_k<K: SingleRay, C: Counters>(
        &self,
        p: &Packet,
        active: &Masks,
        h: &mut PacketHits,
        split: bool,
        c: &mut C,
    ) {
        let single = |g: usize, l: usize, h: &mut PacketHits, c: &mut C| {
            let t = h.t[g].0[l];
            // SAFETY: as above.
            if unsafe { K::mesh_occluded(self, &p.ray(g, l, t), t, c) } {
                h.t[g].0[l] = f32::NEG_INFINITY;
            }
        };
        if let (TriangleTest::UnitTriangle, Nodes::W8(n)) = (self.test, &self.nodes) {
            let leaves = UnitPacketLeaves::<K> { tris: &self.tris, inst: INVALID, k: std::marker::PhantomData, culled: Default::default() };
            let ext = max_spread(&self.bounds());
            coherent_parts!(
                p,
                active,
                h,
                ext,
                split,
                |m, hh| p.occlusion_interval(m, hh),
                |iv, m, h| occluded::<K, _, _>(n, &leaves, p, iv, m, h, c),
                |g, l, h| single(g, l, h, c)
            );
        } else {
            for_lanes(p.groups, active, |g, l| single(g, l, h, c));
        }
    }

    /// Closest hits of coherent rays, traced together in packets of up to [`MAX_PACKET`]
    /// (for example the 64 primary rays of an 8×8 pixel tile): the same answers as
    /// [`MeshBvh::intersect`] ray by ray, except which of two triangles at exactly the same
    /// distance is reported. `out` must be as long as `rays`.
    pub fn intersect_packet(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.trace_intersect(Rays::Aos(rays), out);
    }

    /// Occlusion of coherent rays within `[tmin, tmax)`, traced in packets (for example the
    /// shadow rays of a tile toward one light): the same answers as [`MeshBvh::occluded`].
    pub fn occluded_packet(&self, rays: &[Ray], out: &mut [bool]) {
        self.trace_occluded(Rays::Aos(rays), out);
    }

    /// [`MeshBvh::intersect_packet`] counting the work into `stats` (scalar kernel: the
    /// same answers and the same nodes visited as the fast ones): a packet's inner node is
    /// one interval test for all its rays, its items the 4-triangle groups of the leaves
    /// some ray entered; rays traced alone (incoherent ones) count as single rays do.
    pub fn intersect_packet_with_stats(&self, rays: &[Ray], out: &mut [Option<Hit>], stats: &mut TraversalStats) {
        chunks(rays, |base, p, h| {
            self.packet_intersect_k::<ScalarSet, _>(p, &p.valid, h, INVALID, true, stats);
            write_hits(base, p, h, out);
        });
    }

    /// [`MeshBvh::occluded_packet`] counting the work into `stats` (scalar kernel), as
    /// [`MeshBvh::intersect_packet_with_stats`] does.
    pub fn occluded_packet_with_stats(&self, rays: &[Ray], out: &mut [bool], stats: &mut TraversalStats) {
        chunks(rays, |base, p, h| {
            self.packet_occluded_k::<ScalarSet, _>(p, &p.valid, h, true, stats);
            write_occluded(base, p, h, out);
        });
    }

    /// [`MeshBvh::intersect_packet`] on rays already in SoA blocks (eight blocks make one
    /// packet); `out` holds eight entries per block.
    pub fn intersect_blocks(&self, blocks: &[RayBlock], out: &mut [Option<Hit>]) {
        self.trace_intersect(Rays::Soa(blocks), out);
    }

    /// [`MeshBvh::occluded_packet`] on rays in SoA blocks; `out` holds eight entries per block.
    pub fn occluded_blocks(&self, blocks: &[RayBlock], out: &mut [bool]) {
        self.trace_occluded(Rays::Soa(blocks), out);
    }

    #[inline(always)]
    pub(super) fn trace_intersect(&self, rays: Rays, out: &mut [Option<Hit>]) {
        match self.kernel() {
            // SAFETY: the kernel is only Simd/Avx512 when AVX2 and FMA were detected.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd | Kernel::Avx512 => unsafe { avx2_mesh_intersect(self, rays, out) },
            _ => rays.each(|base, p, h| {
                self.packet_intersect_k::<ScalarSet, _>(p, &p.valid, h, INVALID, true, &mut ());
                write_hits(base, p, h, out);
            }),
        }
    }

    #[inline(always)]
    pub(super) fn trace_occluded(&self, rays: Rays, out: &mut [bool]) {
        match self.kernel() {
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Kernel::Simd | Kernel::Avx512 => unsafe { avx2_mesh_occluded(self, rays, out) },
            _ => rays.each(|base, p, h| {
                self.packet_occluded_k::<ScalarSet, _>(p, &p.valid, h, true, &mut ());
                write_occluded(base, p, h, out);
            }),
        }
    }
}

/// Rays handed to a packet entry point, one by one or already in SoA blocks.
#[derive(Clone, Copy)]
pub(super) enum Rays<'a> {
    Aos(&'a [Ray]),
    Soa(&'a [RayBlock]),
}

impl Rays<'_> {
    /// Runs `body` on every packet of at most [`MAX_PACKET`] rays, loaded, with the index of
    /// its first ray. Inlined into the callers (and their target features): loading a packet
    /// is a good part of the cost of a short shadow packet.
    #[inline(always)]
    pub(super) fn each(self, body: impl FnMut(usize, &Packet, &mut PacketHits)) {
        match self {
            Rays::Aos(r) => chunks(r, body),
            Rays::Soa(b) => block_chunks(b, body),
        }
    }

    /// [`Rays::each`] for callers compiled with AVX2: rays given one by one are turned into
    /// SoA blocks eight at a time by an 8×8 transpose (PERF: lane-by-lane stores read back
    /// as vectors were a tenth of a sparse REND3R frame).
    ///
    /// # Safety
    /// AVX2 must be available.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(super) unsafe fn each_avx2(self, body: impl FnMut(usize, &Packet, &mut PacketHits)) {
        match self {
            Rays::Aos(rays) => aos_chunks(
                rays,
                // SAFETY: the caller guarantees AVX2.
                |eight, b| unsafe { super::avx::transpose_rays(eight, b) },
                body,
            ),
            Rays::Soa(b) => block_chunks(b, body),
        }
    }
}

// The closures below are defined inside the `target_feature` functions, so they are
// compiled with AVX2 and FMA too.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(super) fn avx2_mesh_intersect(m: &MeshBvh, rays: Rays, out: &mut [Option<Hit>]) {
    // SAFETY: this function is compiled with AVX2, which its callers checked.
    unsafe {
        rays.each_avx2(|base, p, h| {
            m.packet_intersect_k::<crate::kernel::SimdSet, _>(p, &p.valid, h, INVALID, true, &mut ());
            write_hits(base, p, h, out);
        })
    };
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(super) fn avx2_mesh_occluded(m: &MeshBvh, rays: Rays, out: &mut [bool]) {
    // SAFETY: this function is compiled with AVX2, which its callers checked.
    unsafe {
        rays.each_avx2(|base, p, h| {
            m.packet_occluded_k::<crate::kernel::SimdSet, _>(p, &p.valid, h, true, &mut ());
            write_occluded(base, p, h, out);
        })
    };
}

#[inline(always)]
pub(super) fn write_hits(base: usize, p: &Packet, h: &PacketHits, out: &mut [Option<Hit>]) {
    let out = out.get_mut(base..).unwrap_or_default();
    for (g, chunk) in out.chunks_mut(LANES).take(p.groups).enumerate() {
        for (l, o) in chunk.iter_mut().enumerate() {
            *o = (h.prim[g][l] != INVALID).then(|| h.get(g, l));
        }
    }
}

#[inline(always)]
pub(super) fn write_occluded(base: usize, p: &Packet, h: &PacketHits, out: &mut [bool]) {
    let out = out.get_mut(base..).unwrap_or_default();
    for (g, chunk) in out.chunks_mut(LANES).take(p.groups).enumerate() {
        for (l, o) in chunk.iter_mut().enumerate() {
            *o = p.valid[g].0[l] != 0 && h.t[g].0[l] == f32::NEG_INFINITY;
        }
    }
}
