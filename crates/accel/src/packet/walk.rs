//! The packet walk over 8-wide nodes: interval culling of inner nodes, each group's exact
//! box test at leaves, and the traversal loop shared by closest and any hit.

use super::core::*;

/// All eight children of `node` against the packet's intervals: the mask of children some
/// ray may enter before `tmax`, and lower bounds of their entry distances.
#[inline(always)]
pub(super) fn interval_test(node: &WideNode<8>, iv: &Interval, tmax: f32, dist: &mut [f32; 8]) -> u32 {
    let mut tn = F8::splat(iv.tmin);
    let mut tf = F8::splat(tmax);
    for k in 0..3 {
        let bn = F8(node.bounds[iv.inear[k]]);
        let bf = F8(node.bounds[iv.ifar[k]]);
        let (olo, ohi) = (F8::splat(iv.olo[k]), F8::splat(iv.ohi[k]));
        let (rlo, rhi) = (F8::splat(iv.rlo[k]), F8::splat(iv.rhi[k]));
        // (b − o)·r is bilinear in (o, r): its extremes over the box of (o, r) are at corners.
        let (n0, n1) = (bn.sub(olo), bn.sub(ohi));
        let lo = n0.mul(rlo).min(n0.mul(rhi)).min(n1.mul(rlo).min(n1.mul(rhi)));
        let (f0, f1) = (bf.sub(olo), bf.sub(ohi));
        let hi = f0.mul(rlo).max(f0.mul(rhi)).max(f1.mul(rlo).max(f1.mul(rhi))).add(F8::splat(iv.pad[k]));
        tn = lo.max(tn);
        tf = hi.min(tf);
    }
    *dist = tn.0;
    tn.le(tf.mul(F8::splat(FAR_SCALE))).bits()
}

/// [`interval_test`] with the kernel of `K`.
#[inline(always)]
pub(super) fn node_test<K: KernelSet>(node: &WideNode<8>, iv: &Interval, tmax: f32, dist: &mut [f32; 8]) -> u32 {
    if K::SIMD {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
        return unsafe { super::avx::interval_test(node, iv, tmax, dist) };
    }
    interval_test(node, iv, tmax, dist)
}

/// One group of rays against one box (`rows` as in `WideNode::bounds`): the lanes that
/// enter it within `[tmin, t)`.
#[inline(always)]
pub(super) fn group_box(rows: &[f32; 6], p: &Packet, iv: &Interval, g: usize, t: F8) -> M8 {
    let mut tn = p.tmin[g];
    let mut tf = t;
    for k in 0..3 {
        let a = F8::splat(rows[iv.near[k]]).sub(p.o[g][k]).mul(p.inv[g][k]);
        let b = F8::splat(rows[iv.far[k]]).sub(p.o[g][k]).mul(p.inv[g][k]).add(F8::splat(iv.pad[k]));
        tn = a.max(tn);
        tf = b.min(tf);
    }
    tn.le(tf.mul(F8::splat(FAR_SCALE)))
}

/// What sits in the leaves, for packets.
pub(crate) trait PacketLeaves {
    /// Closest hits of the lanes in `m` among items `first..first+count`, reporting the
    /// items read and tested to `c`.
    fn intersect<C: Counters>(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C);
    /// Occlusion of the lanes in `m`: an occluded lane gets `t = -inf`.
    fn occluded<C: Counters>(&self, first: u32, count: u32, p: &Packet, m: &Masks, h: &mut PacketHits, c: &mut C);
    /// Asks for the cache lines of item `first` (a hint).
    #[inline(always)]
    fn prefetch(&self, _first: u32) {}
}

/// A stack entry: a child code, where its box is (its parent's code with the slot in the
/// low three bits) and its entry bound.
#[derive(Clone, Copy)]
pub(super) struct Entry {
    code: u32,
    at: u32,
    dist: f32,
}

/// The masks of the lanes of `active` whose rays enter the box of slot `at`.
#[inline(always)]
pub(super) fn leaf_masks<K: KernelSet>(
    nodes: &[WideNode<8>],
    at: u32,
    p: &Packet,
    iv: &Interval,
    h: &PacketHits,
    active: &Masks,
) -> (Masks, u32) {
    // SAFETY: `at` is a valid inner code (a multiple of `WideNode::<8>::STRIDE`, which is
    // at least 8) with a slot < 8 in its low bits.
    let node = unsafe { node_at(nodes, at & !7) };
    let slot = (at & 7) as usize;
    let rows: [f32; 6] = std::array::from_fn(|r| node.bounds[r][slot]);
    let mut m = [M8::NONE; GROUPS];
    let mut any = 0;
    for g in 0..p.groups {
        if active[g].bits() == 0 {
            continue;
        }
        let b = if K::SIMD {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `K::SIMD` kernels run only where AVX2 and FMA were detected.
            unsafe {
                super::avx::group_box(&rows, p, iv, g, &h.t[g])
            }
            #[cfg(not(target_arch = "x86_64"))]
            group_box(&rows, p, iv, g, h.t[g])
        } else {
            group_box(&rows, p, iv, g, h.t[g])
        };
        m[g] = b.and(active[g]);
        any |= m[g].bits();
    }
    (m, any)
}

/// Closest-hit traversal of the lanes of `active` (rays with the same direction signs:
/// `iv` is their interval).
#[inline(always)]
pub(crate) fn intersect<K: KernelSet, L: PacketLeaves, C: Counters>(
    nodes: &[WideNode<8>],
    leaves: &L,
    p: &Packet,
    iv: &Interval,
    active: &Masks,
    h: &mut PacketHits,
    c: &mut C,
) {
    traverse::<false, K, L, C>(nodes, leaves, p, iv, active, h, c);
}

/// Any-hit traversal of the lanes of `active`: occluded lanes get `t = -inf`.
#[inline(always)]
pub(crate) fn occluded<K: KernelSet, L: PacketLeaves, C: Counters>(
    nodes: &[WideNode<8>],
    leaves: &L,
    p: &Packet,
    iv: &Interval,
    active: &Masks,
    h: &mut PacketHits,
    c: &mut C,
) {
    traverse::<true, K, L, C>(nodes, leaves, p, iv, active, h, c);
}

/// The one packet traversal: children nearest first (along the interval's rays), leaves
/// handed to `leaves.intersect` or, with `ANY`, to `leaves.occluded`, which ends the walk
/// once every lane is occluded. A closest-hit walk skips popped entries that start beyond
/// every lane's current hit; an any-hit walk visits them all.
#[inline(always)]
pub(super) fn traverse<const ANY: bool, K: KernelSet, L: PacketLeaves, C: Counters>(
    nodes: &[WideNode<8>],
    leaves: &L,
    p: &Packet,
    iv: &Interval,
    active: &Masks,
    h: &mut PacketHits,
    c: &mut C,
) {
    if nodes.is_empty() {
        return;
    }
    // PERF: left uninitialised (zeroing 6 KB per packet showed in profiles); entries below
    // `sp` are always written before they are read.
    let mut st = [std::mem::MaybeUninit::<Entry>::uninit(); STACK];
    let mut sp = 0usize;
    let mut cur = Entry { code: 0, at: 0, dist: 0.0 };
    let mut tmax = h.max_t::<K>(p.groups, active);
    let mut dist = [0f32; 8];
    loop {
        if cur.code & LEAF == 0 {
            // SAFETY: inner codes come from the collapse and address nodes of `nodes`.
            let node = unsafe { node_at(nodes, cur.code) };
            let mut mask = node_test::<K>(node, iv, tmax, &mut dist);
            c.node();
            c.node_read(std::ptr::from_ref(node) as usize, std::mem::size_of::<WideNode<8>>());
            // An inner code is a multiple of 32: the slot fits in its low bits.
            let (base, at0) = (sp, cur.code);
            while mask != 0 {
                let k = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                // Insertion: nearest on top.
                let e = Entry { code: node.child[k], at: at0 | k as u32, dist: dist[k] };
                let mut j = sp;
                // SAFETY: entries base..sp were written by earlier pushes.
                while j > base && unsafe { st[j - 1].assume_init() }.dist < e.dist {
                    st[j] = st[j - 1];
                    j -= 1;
                }
                st[j].write(e);
                sp += 1;
                // Start loading what the packet will visit (it visits most of what it pushes):
                // the walk is bound by cache misses more than by its arithmetic.
                if e.code & LEAF == 0 {
                    crate::traverse::prefetch_node(nodes, e.code);
                } else if e.code != EMPTY {
                    leaves.prefetch(leaf_range(e.code).0);
                }
            }
        } else if cur.code != EMPTY {
            let (m, any) = leaf_masks::<K>(nodes, cur.at, p, iv, h, active);
            if any != 0 {
                let (first, count) = leaf_range(cur.code);
                c.items(count);
                if ANY {
                    leaves.occluded(first, count, p, &m, h, c);
                } else {
                    leaves.intersect(first, count, p, &m, h, c);
                }
                tmax = h.max_t::<K>(p.groups, active);
                if ANY && tmax == f32::NEG_INFINITY {
                    return;
                }
            }
        }
        loop {
            if sp == 0 {
                return;
            }
            sp -= 1;
            // SAFETY: every entry below the old `sp` was written by a push.
            let e = unsafe { st[sp].assume_init() };
            if ANY || e.dist <= tmax {
                cur = e;
                break;
            }
        }
    }
}
