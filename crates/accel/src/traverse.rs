//! Single-ray traversal of wide BVHs: one generic loop, specialised by box-test kernel
//! (scalar, SSE for 4-wide, AVX2 for 8-wide) and by leaf type (triangles or instances).
//!
//! All child boxes of a node are tested at once; hit children are pushed nearest-last so
//! the nearest is visited first, and popped entries farther than the current hit are
//! skipped. The box test follows Williams et al. ("An Efficient and Robust Ray–Box
//! Intersection Algorithm", JGT 2005) in the one-FMA-per-plane form `t = b·(1/d) − o·(1/d)`.
//! It is kept conservative as Ize recommends ("Robust BVH Ray Traversal", JCGT 2013): far
//! distances are scaled up by 1 + 2^-21, and each axis' constant term `o·(1/d)` is moved
//! outwards by 2^-22 of itself on each end, a bound on its rounding (large when the origin
//! is far from the box). Both are folded into the per-ray constants ([`RayPre`]), so a
//! plane is one FMA and nothing stands between the max/min trees and the comparison.

use crate::build::MAX_DEPTH;
use crate::geom::{Hit, Ray};
use crate::wide::{leaf_range, node_at, WideNode, EMPTY, LEAF};
use glam::{Vec3, Vec3A};

/// Far-distance scale for a conservative box test.
const FAR_SCALE: f32 = 1.0 + 1.0 / (1u32 << 21) as f32;
/// Traversal stack size: at most W - 1 entries per level.
pub(crate) const STACK: usize = 8 * (MAX_DEPTH as usize + 1);

/// Per-ray constants of the box test.
#[derive(Clone, Copy, Debug)]
pub struct RayPre {
    /// Origin.
    pub org: Vec3,
    /// Direction.
    pub dir: Vec3,
    /// Reciprocal direction: the near planes' factor.
    ///
    /// PERF: this and the three below are `Vec3A`, each written by one 16-byte store. As
    /// `Vec3` they were written 8 + 4 bytes at a time, and LLVM's later loads of them for the
    /// kernels' broadcasts spanned two stores, which defeats store forwarding (a stall in
    /// every ray).
    pub inv: Vec3A,
    /// `inv` scaled up by `FAR_SCALE`: the far planes' factor.
    pub inv_far: Vec3A,
    /// The near planes' constant term: `−org·inv` moved down by 2^-22 of itself, so that
    /// `b·inv + onear` (one FMA) is a plane's entry distance, widened by more than the
    /// rounding of `org·inv`. PERF: stored negated, so the kernels broadcast it as it is (to
    /// negate them, LLVM loaded the constants 32 bytes at once, across several stores).
    pub onear: Vec3A,
    /// The far planes' constant term: `−FAR_SCALE·org·inv` moved up by 2^-22 of itself, so
    /// that `b·inv_far + ofar` is a plane's exit distance, scaled and widened.
    pub ofar: Vec3A,
    /// Row of `WideNode::bounds` holding the near plane of each axis.
    pub near: [usize; 3],
    /// Row holding the far plane of each axis.
    pub far: [usize; 3],
    /// The same rows as byte offsets into an 8-wide node's `bounds` (near x, y, z, then
    /// far x, y, z), so the AVX2 box test addresses each row directly: turning the row
    /// indices into offsets in every node took 12 of its ~35 instructions. PERF: `u32`,
    /// not `usize`: LLVM vectorised six `usize`s into 512-bit registers in the AVX-512
    /// build, and those 512-bit instructions in every ray's set-up made all single-ray
    /// queries 10-15% slower.
    pub off8: [u32; 6],
    /// Lower end of the accepted range. The box tests' integer maximum with it clamps
    /// every entry distance to it when it is not negative (rays start at `tmin ≥ 0`).
    pub tmin: f32,
}

impl RayPre {
    /// Precomputes the box-test constants of a ray.
    #[inline(always)]
    #[must_use]
    pub fn new(r: &Ray) -> Self {
        // PERF: the ray is read once, float by float. Callers have usually just written it
        // as separate floats, and a wider load of freshly stored floats defeats store
        // forwarding (a ~15-cycle stall, measured at 20% of a two-level query); volatile
        // reads keep LLVM from merging the loads.
        // SAFETY: reads of valid, aligned f32 fields of `r`.
        let f = |x: &f32| unsafe { std::ptr::read_volatile(x) };
        let org = Vec3::new(f(&r.org.x), f(&r.org.y), f(&r.org.z));
        let dir = Vec3::new(f(&r.dir.x), f(&r.dir.y), f(&r.dir.z));
        let tmin = f(&r.tmin);
        // One SIMD division instead of three dependent scalar ones. A zero component would
        // make 1/d infinite and o·(1/d) ∞ or NaN, and NaN slab distances would then either
        // drop that axis from the slab test (a ray along an axis would visit the whole
        // tree) or, under the integer max/min of the box tests, drop boxes the ray enters.
        // As Embree's `rcp_safe`, keep |d| ≥ 1e-18 for the box test.
        let d = Vec3A::from(dir);
        let tiny = Vec3A::splat(1e-18);
        let d = Vec3A::select(d.abs().cmplt(tiny), tiny.copysign(d), d);
        // The sign of each reciprocal is the sign bit of its component (the clamp above
        // keeps it, −0.0 included). PERF: read from the direction, so the rows the box tests
        // load are known (and the root's loads issued) before the division finishes.
        let neg = [dir.x.is_sign_negative(), dir.y.is_sign_negative(), dir.z.is_sign_negative()];
        let near: [usize; 3] = std::array::from_fn(|k| k + 3 * neg[k] as usize);
        let far: [usize; 3] = std::array::from_fn(|k| k + 3 * (!neg[k]) as usize);
        let off8 = [near[0], near[1], near[2], far[0], far[1], far[2]].map(|r| r as u32 * 32);
        // The constant terms, widened: with s = sign(o·inv) = sign(o)·sign(d) (known before
        // the division) and ε = 2^-22, −onear = o(1 + εs)·inv and −ofar = S·o(1 − εs)·inv.
        // Each is rounded twice (the factor, then the product), 2^-24 of |o·inv| at most
        // each time, so −onear ≥ o·inv + 2^-23|o·inv| and −ofar ≤ S·o·inv − 2^-23 S|o·inv|:
        // every plane distance is moved outwards by more than the one rounding of o·inv that
        // it would otherwise carry (the FMA's own rounding is relative, within FAR_SCALE's
        // margin, as is that of inv·S). PERF: the factors are made beside the division, so
        // the constants follow it by one multiplication, as o·inv did; folded in, they leave
        // a box test with no subtraction or scaling between its max/min trees and its
        // comparison, which is on the walk's critical path. Measured, 1 thread, 3 interleaved
        // rounds: single rays 3-10% faster on all five presets (kitchen shadow rays 1.5% slower).
        let o = Vec3A::from(org);
        let inv = Vec3A::ONE / d;
        let eps = 1.0 / (1u32 << 22) as f32;
        let outward = o.abs().copysign(d);
        let onear = inv * outward.mul_add(Vec3A::splat(-eps), -o);
        let ofar = inv * outward.mul_add(Vec3A::splat(eps * FAR_SCALE), o * -FAR_SCALE);
        let inv_far = inv * FAR_SCALE;
        Self { org, dir, inv, inv_far, onear, ofar, near, far, off8, tmin }
    }
}

/// The larger of two floats compared as signed 32-bit integers (`vpmaxsd`). That is the
/// float maximum when either has its sign bit clear; among negatives (−0.0 included, the
/// lowest integer) it takes the one of larger magnitude, so a near distance made this way
/// is never above the float maximum.
#[inline(always)]
pub(crate) fn imax(a: f32, b: f32) -> f32 {
    f32::from_bits((a.to_bits() as i32).max(b.to_bits() as i32) as u32)
}

/// The smaller of two floats compared as signed 32-bit integers (`vpminsd`): the float
/// minimum when neither has its sign bit set, and never below it otherwise.
#[inline(always)]
pub(crate) fn imin(a: f32, b: f32) -> f32 {
    f32::from_bits((a.to_bits() as i32).min(b.to_bits() as i32) as u32)
}

/// A W-wide box test: the mask of children hit within `[tmin, tmax]` and their entry distances.
///
/// PERF: the walk is a chain of dependent loads (a node's mask picks the next node), so
/// the box test's latency counts. The slab distances are combined by integer max/min
/// ([`imax`], [`imin`]: one cycle each, as Embree's `maxi`/`mini`) in trees of depth two
/// instead of chains of three float max/min (four cycles each), and the far limit is one
/// FMA instead of a multiply and an add. Integer order on floats is exact among
/// non-negative values and only ever lowers a near distance or raises a far one
/// otherwise, so the test stays conservative.
pub(crate) trait BoxTest<const W: usize> {
    /// # Safety
    /// The CPU must support the instructions of the implementation.
    unsafe fn test(node: &WideNode<W>, r: &RayPre, tmax: f32, dist: &mut [f32; W]) -> u32;

    /// [`Self::test`], with the codes and entry distances of the first two hit children
    /// in slot order (any values where fewer are hit).
    ///
    /// # Safety
    /// As [`Self::test`].
    #[inline(always)]
    unsafe fn test_hits(node: &WideNode<W>, r: &RayPre, tmax: f32, dist: &mut [f32; W]) -> Hits {
        // SAFETY: forwarded.
        let mask = unsafe { Self::test(node, r, tmax, dist) };
        let i = mask.trailing_zeros() as usize % W;
        let j = (mask & mask.wrapping_sub(1)).trailing_zeros() as usize % W;
        Hits { mask, code: [node.child[i], node.child[j]], dist: [dist[i], dist[j]] }
    }
}

/// A node's box test result: the hit mask and the first two hit children.
#[derive(Clone, Copy)]
pub(crate) struct Hits {
    /// Bit `i` set when child `i` is hit.
    pub mask: u32,
    /// Codes of the lowest two hit slots.
    pub code: [u32; 2],
    /// Their entry distances.
    pub dist: [f32; 2],
}

/// Portable box test; identical answers to the SIMD ones.
pub(crate) struct ScalarBox;

impl<const W: usize> BoxTest<W> for ScalarBox {
    #[inline(always)]
    unsafe fn test(node: &WideNode<W>, r: &RayPre, tmax: f32, dist: &mut [f32; W]) -> u32 {
        let mut mask = 0;
        #[allow(clippy::needless_range_loop)] // lane index into several SoA rows
        for i in 0..W {
            // Fused like vfmadd: b·inv + onear rounded once.
            let a: [f32; 3] = std::array::from_fn(|k| node.bounds[r.near[k]][i].mul_add(r.inv[k], r.onear[k]));
            let b: [f32; 3] = std::array::from_fn(|k| node.bounds[r.far[k]][i].mul_add(r.inv_far[k], r.ofar[k]));
            let tn = imax(imax(a[0], a[1]), imax(a[2], r.tmin));
            let tf = imin(imin(b[0], b[1]), imin(b[2], tmax * FAR_SCALE));
            dist[i] = tn;
            mask |= ((tn <= tf) as u32) << i;
        }
        mask
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use simd::{Avx2Box, Avx512Box, SseBox};

#[cfg(target_arch = "x86_64")]
mod simd {
    use super::{BoxTest, Hits, RayPre, FAR_SCALE};
    use crate::wide::WideNode;
    use std::arch::x86_64::*;

    /// The slab arithmetic of the 8-wide tests: the entry distances (also stored to `dist`)
    /// and the exit distances of the eight children, both widened.
    ///
    /// # Safety
    /// Only for functions with AVX2 and FMA enabled (it inlines into them).
    #[inline(always)]
    unsafe fn slabs8(node: &WideNode<8>, r: &RayPre, tmax: f32, dist: &mut [f32; 8]) -> (__m256, __m256) {
        // SAFETY: `WideNode<8>` is 32-byte aligned and each bounds row is 32 bytes at a
        // multiple of 32, so the aligned loads are valid; the offsets are 32 × a row index
        // below 6 (RayPre::new), so every row read lies inside `bounds`; the caller has
        // AVX2 and FMA enabled.
        unsafe {
            let base = node.bounds.as_ptr().cast::<u8>();
            let (n0, n1, n2) = (
                plane8(base, r.off8[0], r.inv[0], r.onear[0]),
                plane8(base, r.off8[1], r.inv[1], r.onear[1]),
                plane8(base, r.off8[2], r.inv[2], r.onear[2]),
            );
            let (f0, f1, f2) = (
                plane8(base, r.off8[3], r.inv_far[0], r.ofar[0]),
                plane8(base, r.off8[4], r.inv_far[1], r.ofar[1]),
                plane8(base, r.off8[5], r.inv_far[2], r.ofar[2]),
            );
            let tn = imax8(imax8(n0, n1), imax8(n2, _mm256_set1_ps(r.tmin)));
            let tf = imin8(imin8(f0, f1), imin8(f2, _mm256_set1_ps(tmax * FAR_SCALE)));
            _mm256_storeu_ps(dist.as_mut_ptr(), tn);
            (tn, tf)
        }
    }

    // PERF: the helpers of the box tests are `inline(always)` functions, not closures. A
    // closure does not take the `target_feature` of the function it is written in, so when
    // LLVM left one out of line (as it did for `array::from_fn`'s once more callers were
    // compiled), its intrinsics became calls: single rays 4 times slower.

    /// One plane row of an 8-wide node at byte offset `off`: `row·f + c` for all children.
    ///
    /// # Safety
    /// `base + off` must be a 32-byte aligned row of 8 floats; AVX2 and FMA as `slabs8`.
    #[inline(always)]
    unsafe fn plane8(base: *const u8, off: u32, f: f32, c: f32) -> __m256 {
        // SAFETY: the caller's.
        unsafe { _mm256_fmadd_ps(_mm256_load_ps(base.add(off as usize).cast::<f32>()), _mm256_set1_ps(f), _mm256_set1_ps(c)) }
    }

    /// [`super::imax`] on 8 lanes.
    ///
    /// # Safety
    /// AVX2, as `slabs8`.
    #[inline(always)]
    unsafe fn imax8(x: __m256, y: __m256) -> __m256 {
        // SAFETY: the caller's.
        unsafe { _mm256_castsi256_ps(_mm256_max_epi32(_mm256_castps_si256(x), _mm256_castps_si256(y))) }
    }

    /// [`super::imin`] on 8 lanes.
    ///
    /// # Safety
    /// AVX2, as `slabs8`.
    #[inline(always)]
    unsafe fn imin8(x: __m256, y: __m256) -> __m256 {
        // SAFETY: the caller's.
        unsafe { _mm256_castsi256_ps(_mm256_min_epi32(_mm256_castps_si256(x), _mm256_castps_si256(y))) }
    }

    /// [`super::imax`] on 4 lanes.
    ///
    /// # Safety
    /// SSE4.1 (implied by the AVX2 of the callers).
    #[inline(always)]
    unsafe fn imax4(x: __m128, y: __m128) -> __m128 {
        // SAFETY: the caller's.
        unsafe { _mm_castsi128_ps(_mm_max_epi32(_mm_castps_si128(x), _mm_castps_si128(y))) }
    }

    /// [`super::imin`] on 4 lanes.
    ///
    /// # Safety
    /// As [`imax4`].
    #[inline(always)]
    unsafe fn imin4(x: __m128, y: __m128) -> __m128 {
        // SAFETY: the caller's.
        unsafe { _mm_castsi128_ps(_mm_min_epi32(_mm_castps_si128(x), _mm_castps_si128(y))) }
    }

    /// One plane row of a 4-wide node: `row·f + c` for all children.
    ///
    /// # Safety
    /// FMA, as [`SseBox`]'s test.
    #[inline(always)]
    unsafe fn plane4(row: &[f32; 4], f: f32, c: f32) -> __m128 {
        // SAFETY: the caller's; a `[f32; 4]` row of a 16-byte aligned node is 16-byte aligned.
        unsafe { _mm_fmadd_ps(_mm_load_ps(row.as_ptr()), _mm_set1_ps(f), _mm_set1_ps(c)) }
    }

    /// 8-wide AVX2 box test.
    pub(crate) struct Avx2Box;

    impl BoxTest<8> for Avx2Box {
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        unsafe fn test(node: &WideNode<8>, r: &RayPre, tmax: f32, dist: &mut [f32; 8]) -> u32 {
            // SAFETY: AVX2 and FMA are enabled here.
            let (tn, far) = unsafe { slabs8(node, r, tmax, dist) };
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tn, far)) as u32
        }
    }

    /// 8-wide box test for the AVX-512VL kernels: [`Avx2Box`]'s arithmetic with the mask in
    /// a mask register, from which the first two hit children's codes and distances are
    /// compressed out of the node's code row and the distances (after Embree's AVX-512
    /// walk, which orders children by compressed keys). PERF: one or two hit children (most
    /// nodes) are then known without the movemask, bit scans and loads that followed the
    /// mask on the way to the next node: single rays 2-4% faster than with `Avx2Box`.
    pub(crate) struct Avx512Box;

    impl Avx512Box {
        #[inline]
        #[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
        fn eval(node: &WideNode<8>, r: &RayPre, tmax: f32, dist: &mut [f32; 8]) -> (__mmask8, __m256) {
            // SAFETY: AVX2 and FMA are enabled here.
            let (tn, far) = unsafe { slabs8(node, r, tmax, dist) };
            (_mm256_cmp_ps_mask::<_CMP_LE_OQ>(tn, far), tn)
        }
    }

    impl BoxTest<8> for Avx512Box {
        #[inline]
        #[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
        unsafe fn test(node: &WideNode<8>, r: &RayPre, tmax: f32, dist: &mut [f32; 8]) -> u32 {
            u32::from(Self::eval(node, r, tmax, dist).0)
        }

        #[inline]
        #[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
        unsafe fn test_hits(node: &WideNode<8>, r: &RayPre, tmax: f32, dist: &mut [f32; 8]) -> Hits {
            let (k, tn) = Self::eval(node, r, tmax, dist);
            // SAFETY: the code row is 32 bytes at offset 192 of a 64-byte aligned node.
            let codes = unsafe { _mm256_load_si256(node.child.as_ptr().cast::<__m256i>()) };
            let c = _mm256_castsi256_si128(_mm256_maskz_compress_epi32(k, codes));
            let d = _mm256_castps256_ps128(_mm256_maskz_compress_ps(k, tn));
            Hits {
                mask: u32::from(k),
                code: [_mm_cvtsi128_si32(c) as u32, _mm_extract_epi32::<1>(c) as u32],
                dist: [_mm_cvtss_f32(d), _mm_cvtss_f32(_mm_movehdup_ps(d))],
            }
        }
    }

    /// 4-wide box test (SSE registers, FMA; run only where AVX2 and FMA were detected).
    pub(crate) struct SseBox;

    impl BoxTest<4> for SseBox {
        #[inline]
        #[target_feature(enable = "avx2,fma")]
        unsafe fn test(node: &WideNode<4>, r: &RayPre, tmax: f32, dist: &mut [f32; 4]) -> u32 {
            // SAFETY: rows are 16 bytes at 16-byte aligned offsets; FMA is enabled here.
            unsafe {
                // `near`/`far` entries are always < 6 (RayPre::new).
                let b = &node.bounds;
                let (n0, n1, n2) = (
                    plane4(b.get_unchecked(r.near[0]), r.inv[0], r.onear[0]),
                    plane4(b.get_unchecked(r.near[1]), r.inv[1], r.onear[1]),
                    plane4(b.get_unchecked(r.near[2]), r.inv[2], r.onear[2]),
                );
                let (f0, f1, f2) = (
                    plane4(b.get_unchecked(r.far[0]), r.inv_far[0], r.ofar[0]),
                    plane4(b.get_unchecked(r.far[1]), r.inv_far[1], r.ofar[1]),
                    plane4(b.get_unchecked(r.far[2]), r.inv_far[2], r.ofar[2]),
                );
                let tn = imax4(imax4(n0, n1), imax4(n2, _mm_set1_ps(r.tmin)));
                let tf = imin4(imin4(f0, f1), imin4(f2, _mm_set1_ps(tmax * FAR_SCALE)));
                _mm_storeu_ps(dist.as_mut_ptr(), tn);
                _mm_movemask_ps(_mm_cmple_ps(tn, tf)) as u32
            }
        }
    }
}

/// Which level of a two-level index a traversal is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Level {
    /// The top level: the index over instances.
    Top,
    /// The bottom level: one object's index over its triangles.
    Bottom,
}

/// Counters of traversal work: the seam every kernel takes. Kernels are generic over
/// this: the unit type `()` counts nothing and compiles away (every method is an empty
/// inline default), [`TraversalStats`] counts visits, and the hardware study
/// (`saarcor`) records what each ray reads and where, for its cache and unit models.
///
/// Addresses are the addresses of lucent's own data (`bytes` long), so a cache model sees
/// the real layout: nodes, object-list entries, instance matrices, triangle maps.
pub trait Counters {
    /// One inner node's children were box-tested.
    fn node(&mut self);
    /// `n` leaf items (triangle groups, instances) were tested.
    fn items(&mut self, n: u32);
    /// The traversal moved to `level` (a two-level walk entering or leaving an object).
    #[inline(always)]
    fn enter(&mut self, _level: Level) {}
    /// An inner node of `bytes` bytes at `addr` was read.
    #[inline(always)]
    fn node_read(&mut self, _addr: usize, _bytes: usize) {}
    /// An entry of a leaf's object list (SaarCOR's list unit) at `addr` was read.
    #[inline(always)]
    fn list_read(&mut self, _addr: usize, _bytes: usize) {}
    /// A list entry was skipped because the ray had already tested that object (mailbox).
    #[inline(always)]
    fn mailbox_hit(&mut self) {}
    /// The ray was carried into an instance's object space by the matrix at `addr`.
    #[inline(always)]
    fn transform(&mut self, _addr: usize, _bytes: usize) {}
    /// `n` triangles whose maps (`bytes` bytes at `addr`) were read were tested: the ray
    /// carried into each one's unit-triangle space and intersected.
    #[inline(always)]
    fn triangles(&mut self, _addr: usize, _bytes: usize, _n: u32) {}
    /// An analytic shape (`bytes` bytes at `addr`) was intersected.
    #[inline(always)]
    fn shape(&mut self, _addr: usize, _bytes: usize) {}
}

impl Counters for () {
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn items(&mut self, _: u32) {}
}

/// Work done by one or more traversals.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalStats {
    /// Inner nodes visited (each one wide box test).
    pub nodes: u64,
    /// Leaf items tested (4-triangle groups, triangles or instances).
    pub items: u64,
}

impl Counters for TraversalStats {
    #[inline(always)]
    fn node(&mut self) {
        self.nodes += 1;
    }
    #[inline(always)]
    fn items(&mut self, n: u32) {
        self.items += n as u64;
    }
}

/// What sits in the leaves: triangles, shapes or instances.
pub(crate) trait Leaves {
    /// Closest hit among items `first..first+count`; narrows `hit.t` when one is found.
    fn intersect<C: Counters>(&self, first: u32, count: u32, r: &RayPre, hit: &mut Hit, c: &mut C);
    /// Any hit among the items within `[r.tmin, tmax)`.
    fn occluded<C: Counters>(&self, first: u32, count: u32, r: &RayPre, tmax: f32, c: &mut C) -> bool;
}

/// Asks for the cache lines that hold `x` (a hint; no effect off x86-64).
#[inline(always)]
pub fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        let p = (x as *const T).cast::<i8>();
        for line in 0..std::mem::size_of::<T>().div_ceil(64) {
            // SAFETY: a prefetch hint at addresses inside `x` (and it never faults); SSE is
            // part of x86-64.
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.wrapping_add(line * 64)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// Asks for the cache lines of the node with inner child code `code` (a hint; no effect
/// off x86-64).
#[inline(always)]
pub(crate) fn prefetch_node<const W: usize>(nodes: &[WideNode<W>], code: u32) {
    if let Some(n) = nodes.get(WideNode::<W>::index_of(code)) {
        prefetch(n);
    }
}

/// The child to visit next among the hit children `hits.mask` of `node` (the nearest);
/// one or two hit children are taken from `hits` (the box test's), more from `dist` and
/// the node. The closest-hit walk (`LATER_ON_TIE` false) pushes the others farthest
/// first, so they pop nearest first; the any-hit walk (`LATER_ON_TIE` true) pushes them in slot order and
/// without their distances (PERF: single shadow rays 2-4% faster than sorted, kitchen
/// unchanged). Of two children at the same distance (a ray starting inside both boxes),
/// the insertion sort visits the later slot first; `LATER_ON_TIE` makes the two-child
/// shortcut (and the any-hit choice of the nearest) do the same. The any-hit walk wants
/// that (measured: kitchen shadow rays twice as fast), the closest-hit walk keeps the
/// earlier slot.
#[inline(always)]
fn visit_children<const W: usize, const LATER_ON_TIE: bool>(
    nodes: &[WideNode<W>],
    node: &WideNode<W>,
    dist: &[f32; W],
    hits: &Hits,
    st_code: &mut [std::mem::MaybeUninit<u32>; STACK],
    st_t: &mut [std::mem::MaybeUninit<f32>; STACK],
    sp: &mut usize,
) -> u32 {
    let mut mask = hits.mask;
    let i = mask.trailing_zeros() as usize;
    mask &= mask - 1;
    if mask == 0 {
        return hits.code[0];
    }
    if mask & (mask - 1) == 0 {
        // PERF: exactly two (the common case): go to the nearer, push the farther.
        let ([ci, cj], [di, dj]) = (hits.code, hits.dist);
        let near_first = if LATER_ON_TIE { di < dj } else { di <= dj };
        let (cn, cf, df) = if near_first { (ci, cj, dj) } else { (cj, ci, di) };
        // Start loading the farther node: it is likely visited later.
        if cf & LEAF == 0 {
            prefetch_node(nodes, cf);
        }
        if !LATER_ON_TIE {
            // The any-hit walk pops without a distance.
            st_t[*sp].write(df);
        }
        st_code[*sp].write(cf);
        *sp += 1;
        return cn;
    }
    if LATER_ON_TIE {
        // Any hit: the nearest first, the others in slot order (any of them may end the
        // walk, so their order matters less than the sort's cost).
        let mut best = i;
        let mut rest = mask;
        while rest != 0 {
            let k = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            if dist[k] <= dist[best] {
                best = k;
            }
        }
        let mut all = mask | (1 << i);
        all &= !(1 << best);
        while all != 0 {
            let k = all.trailing_zeros() as usize;
            all &= all - 1;
            // (No distance: the any-hit walk pops without one.)
            st_code[*sp].write(node.child[k]);
            *sp += 1;
        }
        return node.child[best];
    }
    // Three or more: push all, nearest on top (insertion sort of at most W).
    let base = *sp;
    let mut push = |code: u32, d: f32, sp: &mut usize| {
        let mut j = *sp;
        // SAFETY: entries base..sp were written by earlier pushes.
        while j > base && unsafe { st_t[j - 1].assume_init() } < d {
            st_t[j] = st_t[j - 1];
            st_code[j] = st_code[j - 1];
            j -= 1;
        }
        st_t[j].write(d);
        st_code[j].write(code);
        *sp += 1;
    };
    push(node.child[i], dist[i], sp);
    while mask != 0 {
        let k = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        push(node.child[k], dist[k], sp);
    }
    *sp -= 1;
    // SAFETY: just pushed.
    unsafe { st_code[*sp].assume_init() }
}

/// Closest-hit traversal. `hit.t` is the current far limit.
///
/// # Safety
/// The CPU must support `B`'s instructions.
#[inline(always)]
pub(crate) unsafe fn intersect<const W: usize, B: BoxTest<W>, L: Leaves, C: Counters>(
    nodes: &[WideNode<W>],
    leaves: &L,
    r: &RayPre,
    hit: &mut Hit,
    c: &mut C,
) {
    if nodes.is_empty() {
        return;
    }
    // PERF: the stack is left uninitialised (zeroing 4.7 KB per ray cost ~5%); entries
    // below `sp` are always written before they are read.
    let mut st_code = [std::mem::MaybeUninit::<u32>::uninit(); STACK];
    let mut st_t = [std::mem::MaybeUninit::<f32>::uninit(); STACK];
    let mut sp = 0usize;
    let mut cur = 0u32;
    let mut dist = [0f32; W];
    loop {
        if cur & LEAF == 0 {
            // SAFETY: inner codes come from the collapse and address nodes of `nodes`
            // (checked by `validate` in tests); the caller guarantees B's CPU features.
            let node = unsafe { node_at(nodes, cur) };
            let hits = unsafe { B::test_hits(node, r, hit.t, &mut dist) };
            c.node();
            c.node_read(std::ptr::from_ref(node) as usize, std::mem::size_of::<WideNode<W>>());
            if hits.mask != 0 {
                cur = visit_children::<W, false>(nodes, node, &dist, &hits, &mut st_code, &mut st_t, &mut sp);
                continue;
            }
        } else if cur != EMPTY {
            let (first, count) = leaf_range(cur);
            c.items(count);
            leaves.intersect(first, count, r, hit, c);
        }
        // Pop the nearest entry that can still hold a closer hit.
        loop {
            if sp == 0 {
                return;
            }
            sp -= 1;
            // SAFETY: every entry below the old `sp` was written by a push.
            let (t, code) = unsafe { (st_t[sp].assume_init(), st_code[sp].assume_init()) };
            if t <= hit.t {
                cur = code;
                break;
            }
        }
    }
}

/// Any-hit traversal within `[r.tmin, tmax)`.
///
/// # Safety
/// The CPU must support `B`'s instructions.
#[inline(always)]
pub(crate) unsafe fn occluded<const W: usize, B: BoxTest<W>, L: Leaves, C: Counters>(
    nodes: &[WideNode<W>],
    leaves: &L,
    r: &RayPre,
    tmax: f32,
    c: &mut C,
) -> bool {
    if nodes.is_empty() {
        return false;
    }
    // PERF: uninitialised, as in `intersect`.
    let mut st_code = [std::mem::MaybeUninit::<u32>::uninit(); STACK];
    let mut st_t = [std::mem::MaybeUninit::<f32>::uninit(); STACK];
    let mut sp = 0usize;
    let mut cur = 0u32;
    let mut dist = [0f32; W];
    loop {
        if cur & LEAF == 0 {
            // SAFETY: as in `intersect`.
            let node = unsafe { node_at(nodes, cur) };
            let hits = unsafe { B::test_hits(node, r, tmax, &mut dist) };
            c.node();
            c.node_read(std::ptr::from_ref(node) as usize, std::mem::size_of::<WideNode<W>>());
            if hits.mask != 0 {
                // Nearest child first: an occluder near the ray's start ends the query soonest.
                cur = visit_children::<W, true>(nodes, node, &dist, &hits, &mut st_code, &mut st_t, &mut sp);
                continue;
            }
        } else if cur != EMPTY {
            let (first, count) = leaf_range(cur);
            c.items(count);
            if leaves.occluded(first, count, r, tmax, c) {
                return true;
            }
        }
        if sp == 0 {
            return false;
        }
        sp -= 1;
        // SAFETY: written by a push.
        cur = unsafe { st_code[sp].assume_init() };
    }
}

#[cfg(test)]
mod tests {
    use super::{imax, imin, BoxTest, Hits, RayPre, ScalarBox};
    use crate::geom::{Aabb, Ray};
    use crate::wide::WideNode;
    use glam::Vec3;
    use rand::{Rng, SeedableRng};

    /// Every SIMD 8-wide box test gives the scalar test's hit mask, entry distances and
    /// first two hit children (codes and distances) on seeded random nodes (some slots
    /// empty, some boxes around the origin) and rays, with random far limits.
    #[test]
    fn simd_box_tests_match_scalar() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut tested = [0usize; 3];
        for _ in 0..20_000 {
            let mut node = WideNode::<8>::EMPTY;
            for i in 0..8 {
                if rng.random_bool(0.15) {
                    continue;
                }
                let c = Vec3::new(rng.random_range(-4.0..4.0), rng.random_range(-4.0..4.0), rng.random_range(-4.0..4.0));
                let h = Vec3::new(rng.random_range(0.0..3.0), rng.random_range(0.0..3.0), rng.random_range(0.0..3.0));
                node.set(i, &Aabb { min: c - h, max: c + h }, rng.random_range(0..1u32 << 20) * 32);
            }
            let dir = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            let ray = Ray::new(Vec3::ZERO, if dir.length() > 1e-3 { dir } else { Vec3::X });
            let pre = RayPre::new(&ray);
            let tmax = if rng.random_bool(0.5) { f32::INFINITY } else { rng.random_range(0.0..6.0) };
            let mut want_d = [0f32; 8];
            // SAFETY: the scalar test runs anywhere.
            let want = unsafe { ScalarBox::test_hits(&node, &pre, tmax, &mut want_d) };
            let check = |name: &str, got: Hits, got_d: [f32; 8]| {
                assert_eq!(got.mask, want.mask, "{name}: mask");
                for i in 0..8 {
                    if want.mask >> i & 1 == 1 {
                        assert_eq!(got_d[i].to_bits(), want_d[i].to_bits(), "{name}: distance of slot {i}");
                    }
                }
                for h in 0..(want.mask.count_ones() as usize).min(2) {
                    assert_eq!(got.code[h], want.code[h], "{name}: code of hit {h}");
                    assert_eq!(got.dist[h].to_bits(), want.dist[h].to_bits(), "{name}: distance of hit {h}");
                }
            };
            tested[(want.mask.count_ones() as usize).min(2)] += 1;
            #[cfg(target_arch = "x86_64")]
            if crate::Kernel::simd_available() {
                let mut d = [0f32; 8];
                // SAFETY: AVX2 and FMA were detected.
                let got = unsafe { super::Avx2Box::test_hits(&node, &pre, tmax, &mut d) };
                check("avx2", got, d);
            }
            #[cfg(target_arch = "x86_64")]
            if crate::Kernel::avx512_available() {
                let mut d = [0f32; 8];
                // SAFETY: AVX-512F/VL (and AVX2, FMA) were detected.
                let got = unsafe { super::Avx512Box::test_hits(&node, &pre, tmax, &mut d) };
                check("avx512", got, d);
            }
        }
        assert!(tested.iter().all(|&n| n > 1000), "nodes with no, one and several hits: {tested:?}");
    }

    /// Integer max/min on float bits: exact where the box test needs it (a non-negative
    /// operand for the max, none negative for the min), and never tighter than the float
    /// max/min anywhere (seeded values of every sign, zeros of both signs, infinities).
    #[test]
    fn integer_min_max_are_exact_or_conservative() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let special = [0.0, -0.0, 1.0, -1.0, 1e-40, -1e-40, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, -f32::MAX];
        let mut pick = || {
            if rng.random_bool(0.25) {
                special[rng.random_range(0..special.len())]
            } else {
                // Any finite float, both signs, every exponent.
                let f = f32::from_bits(rng.random());
                if f.is_finite() {
                    f
                } else {
                    1.5
                }
            }
        };
        for _ in 0..200_000 {
            let (a, b) = (pick(), pick());
            let (hi, lo) = (a.max(b), a.min(b));
            assert!(imax(a, b) <= hi, "imax({a}, {b}) = {} above {hi}", imax(a, b));
            assert!(imin(a, b) >= lo, "imin({a}, {b}) = {} below {lo}", imin(a, b));
            // Exact when a sign bit is clear (−0.0 counts as negative: the lowest integer).
            if a.is_sign_positive() || b.is_sign_positive() {
                assert_eq!(imax(a, b), hi, "imax({a}, {b})");
            }
            if a.is_sign_positive() && b.is_sign_positive() {
                assert_eq!(imin(a, b), lo, "imin({a}, {b})");
            }
        }
    }
}
