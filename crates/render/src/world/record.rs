//! Ray counts per thread, and the recording of a piece of work's queries so that they can
//! be traced again alone ([`record_rays`]).

use super::World;
use lucent_accel::Ray;
use rayon::prelude::*;

thread_local! {
    static RAYS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    /// Whether this thread keeps the rays it traces in [`RECORD`] (see [`record_rays`]).
    static RECORDING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
    static RECORD: std::cell::RefCell<RecordedRays> = std::cell::RefCell::new(RecordedRays::default());
}

/// The queries a piece of work sent to a [`World`], kept by [`record_rays`] so that they
/// can be traced again alone: how much of a renderer's time its rays take, with nothing
/// else between them (the ceiling a faster integrator could reach with the same kernels).
#[derive(Clone, Debug, Default)]
pub struct RecordedRays {
    /// Closest-hit rays traced one by one.
    pub closest: Vec<Ray>,
    /// Shadow rays traced one by one.
    pub shadow: Vec<Ray>,
    /// Packets of closest-hit rays, with the instances they were restricted to.
    pub closest_packets: Vec<(Vec<Ray>, Option<Vec<u32>>)>,
    /// Packets of shadow rays.
    pub shadow_packets: Vec<Vec<Ray>>,
    /// Shadow rays in SoA blocks, and how many of their lanes are rays.
    pub shadow_blocks: Vec<(Vec<lucent_accel::RayBlock>, usize)>,
}

impl RecordedRays {
    /// Rays recorded.
    #[must_use]
    pub fn rays(&self) -> u64 {
        (self.closest.len()
            + self.shadow.len()
            + self.closest_packets.iter().map(|p| p.0.len()).sum::<usize>()
            + self.shadow_packets.iter().map(Vec::len).sum::<usize>()
            + self.shadow_blocks.iter().map(|b| b.1).sum::<usize>()) as u64
    }

    /// Traces every recorded query again on `w` (on all of rayon's threads, each query as
    /// it was traced: alone or in its packet), for timing; returns the hits and blocked rays
    /// found, so that the work cannot be optimised away.
    pub fn trace(&self, w: &World) -> u64 {
        /// The sum of `f` over `items`, in chunks on rayon's threads.
        fn par_sum<T: Sync>(items: &[T], chunk: usize, f: impl Fn(&T) -> usize + Sync) -> usize {
            items.par_chunks(chunk).map(|c| c.iter().map(&f).sum::<usize>()).sum()
        }
        let closest = par_sum(&self.closest, 4096, |r| usize::from(w.accel.intersect(r).is_some()));
        let shadow = par_sum(&self.shadow, 4096, |r| usize::from(w.accel.occluded(r)));
        let closest_packets = par_sum(&self.closest_packets, 64, |(rays, ids)| {
            let mut out = [None; lucent_accel::MAX_PACKET];
            let out = &mut out[..rays.len()];
            match ids {
                Some(ids) => w.accel.intersect_packet_among(rays, ids, out),
                None => w.accel.intersect_packet(rays, out),
            }
            out.iter().filter(|h| h.is_some()).count()
        });
        let shadow_packets = par_sum(&self.shadow_packets, 64, |rays| {
            let mut out = [false; lucent_accel::MAX_PACKET];
            let out = &mut out[..rays.len()];
            w.accel.occluded_packet(rays, out);
            out.iter().filter(|&&b| b).count()
        });
        let shadow_blocks = par_sum(&self.shadow_blocks, 64, |(blocks, _)| {
            let mut out = vec![false; blocks.len() * lucent_accel::simd::LANES];
            w.accel.occluded_blocks(blocks, &mut out);
            out.iter().filter(|&&b| b).count()
        });
        (closest + shadow + closest_packets + shadow_packets + shadow_blocks) as u64
    }
}

/// Runs `f` while keeping every ray that this thread sends to a [`World`] (work that `f`
/// hands to other threads is not seen: run it in a one-thread pool), and returns what `f`
/// returned with those rays. When nothing is recorded, a query pays one flag test.
pub fn record_rays<R>(f: impl FnOnce() -> R) -> (R, RecordedRays) {
    /// Stops the recording even when `f` panics.
    struct Stop;
    impl Drop for Stop {
        fn drop(&mut self) {
            RECORDING.set(false);
        }
    }
    RECORD.with_borrow_mut(|q| *q = RecordedRays::default());
    RECORDING.set(true);
    let stop = Stop;
    let r = f();
    drop(stop);
    (r, RECORD.take())
}

/// Counts `n` rays of a query on this thread, and keeps the query with `keep` while
/// [`record_rays`] records.
#[inline]
pub(super) fn count_rays(n: usize, keep: impl FnOnce(&mut RecordedRays)) {
    RAYS.with(|c| c.set(c.get() + n as u64));
    if RECORDING.get() {
        RECORD.with_borrow_mut(keep);
    }
}

/// Rays traced by this thread so far (closest-hit and shadow queries).
#[must_use]
pub fn rays_traced_here() -> u64 {
    RAYS.with(|c| c.get())
}
