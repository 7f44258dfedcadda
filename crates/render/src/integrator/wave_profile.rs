//! Where the lane integrator's time goes: a clock around each of its stages, and how full
//! its lanes are, collected while [`begin`] has turned it on (`lucent bench path` prints
//! the table). Off, the integrator reads one flag per block and times nothing.
//!
//! Times are counted in the processor's time-stamp counter where it has one (a few cycles
//! per reading; each closest-hit query is timed by itself, so traversal carries two
//! readings per ray) and in nanoseconds elsewhere; what they mean is their share of the
//! total, which the caller turns into nanoseconds per sample with its own wall clock.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// The parts of a sample's time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// New paths: the camera ray of each new lane (its pixel's sampler, the lens).
    Camera,
    /// Closest hits: camera packets and single rays, in the kernels.
    ClosestHits,
    /// Shadow rays, in the kernels.
    ShadowRays,
    /// Surfaces met: their geometry, material, BSDF and shading frame, emission and MIS
    /// weights of what the rays met (stage 1 besides its traversal).
    Surfaces,
    /// The sampler's numbers of a bounce (stage 2).
    Numbers,
    /// Light samples, the BSDF toward them, MIS (stage 3 besides its shadow rays).
    Lights,
    /// The BSDF's sample, throughput, roulette and the next ray (stage 4).
    Scatter,
    /// Ended paths leaving their lanes, and their values added to the pixels.
    Film,
}

impl Part {
    /// Every part, in the order of [`WaveProfile::time`].
    pub const ALL: [Part; 8] =
        [Part::Camera, Part::ClosestHits, Part::ShadowRays, Part::Surfaces, Part::Numbers, Part::Lights, Part::Scatter, Part::Film];

    /// Whether the part is ray traversal.
    #[must_use]
    pub fn is_traversal(self) -> bool {
        matches!(self, Part::ClosestHits | Part::ShadowRays)
    }
}

/// What a profiled render did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WaveProfile {
    /// Samples (paths) rendered.
    pub samples: u64,
    /// Steps (one bounce of every lane in flight).
    pub steps: u64,
    /// The lanes in flight, summed over the steps.
    pub lanes: u64,
    /// BSDF loops on packed lanes (one model each, in stages 3 and 4).
    pub packed_loops: u64,
    /// The lanes those loops ran.
    pub packed_lanes: u64,
    /// The lanes shaded one by one instead (thin sheets, user BSDFs).
    pub alone_lanes: u64,
    /// Clock counts per [`Part`] (see [`Part::ALL`]).
    pub time: [u64; 8],
}

impl WaveProfile {
    /// Mean paths in flight per step.
    #[must_use]
    pub fn mean_lanes(&self) -> f64 {
        self.lanes as f64 / self.steps.max(1) as f64
    }

    /// Mean lanes per BSDF loop.
    #[must_use]
    pub fn mean_packed(&self) -> f64 {
        self.packed_lanes as f64 / self.packed_loops.max(1) as f64
    }

    /// `part`'s share of the time counted.
    #[must_use]
    pub fn share(&self, part: Part) -> f64 {
        let total: u64 = self.time.iter().sum();
        self.time[part as usize] as f64 / total.max(1) as f64
    }

    fn add(&mut self, o: &WaveProfile) {
        self.samples += o.samples;
        self.steps += o.steps;
        self.lanes += o.lanes;
        self.packed_loops += o.packed_loops;
        self.packed_lanes += o.packed_lanes;
        self.alone_lanes += o.alone_lanes;
        for (t, o) in self.time.iter_mut().zip(o.time) {
            *t += o;
        }
    }
}

static ON: AtomicBool = AtomicBool::new(false);
static TOTAL: Mutex<Option<WaveProfile>> = Mutex::new(None);

/// Starts collecting (process-wide), from zero.
pub fn begin() {
    *TOTAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(WaveProfile::default());
    ON.store(true, Ordering::Relaxed);
}

/// Stops collecting and returns what was collected since [`begin`].
pub fn end() -> WaveProfile {
    ON.store(false, Ordering::Relaxed);
    TOTAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner).take().unwrap_or_default()
}

/// Whether collection is on.
pub(crate) fn on() -> bool {
    ON.load(Ordering::Relaxed)
}

/// The clock's count now.
#[inline(always)]
pub(crate) fn now() -> u64 {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: every x86-64 processor has the time-stamp counter.
        unsafe { core::arch::x86_64::_rdtsc() }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        use std::sync::OnceLock;
        static START: OnceLock<std::time::Instant> = OnceLock::new();
        START.get_or_init(std::time::Instant::now).elapsed().as_nanos() as u64
    }
}

/// A stopwatch over parts, on or off for a whole block.
pub(crate) struct Watch {
    pub(crate) p: Option<WaveProfile>,
    last: u64,
}

impl Watch {
    pub(crate) fn new() -> Self {
        let p = on().then(WaveProfile::default);
        Self { last: if p.is_some() { now() } else { 0 }, p }
    }

    /// Counts the time since the last lap toward `part`.
    #[inline(always)]
    pub(crate) fn lap(&mut self, part: Part) {
        if let Some(p) = &mut self.p {
            let t = now();
            p.time[part as usize] += t.wrapping_sub(self.last);
            self.last = t;
        }
    }

    /// Moves `ticks` counted toward `from` to `to` (a part timed inside another).
    #[inline(always)]
    pub(crate) fn moved(&mut self, ticks: u64, from: Part, to: Part) {
        if let Some(p) = &mut self.p {
            p.time[from as usize] = p.time[from as usize].wrapping_sub(ticks);
            p.time[to as usize] += ticks;
        }
    }

    /// Whether it is on.
    #[inline(always)]
    pub(crate) fn is_on(&self) -> bool {
        self.p.is_some()
    }

    /// Adds this block's counts to the total.
    pub(crate) fn finish(self) {
        if let Some(p) = &self.p {
            if let Some(t) = TOTAL.lock().unwrap_or_else(std::sync::PoisonError::into_inner).as_mut() {
                t.add(p);
            }
        }
    }
}
