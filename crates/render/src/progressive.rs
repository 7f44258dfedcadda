//! Progressive rendering: an image refined pass after pass, each pass a range of sample
//! indices of the whole image, merged into the image so far. One driver for every place
//! that renders this way: `lucent render --time` ([`Passes::timed`] on this process),
//! the same over MPI (each pass's tiles over the ranks), and the viewer (one sample per
//! frame while still, starting over when the view moves: [`Progressive::add`]).
//!
//! Merging is exact: a pass's [`RegionFilm`]s go into a [`FilmAccumulator`], so the image
//! after passes of samples `0..n` is bit for bit the one-pass image of `n` samples,
//! whatever the passes were.

use crate::film::{Film, FilmAccumulator, MergeError, RegionFilm};
use glam::Vec3;
use std::ops::Range;
use std::time::Instant;

/// Errors of a progressive render's settings.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ProgressiveError {
    /// The time budget is not a positive number of seconds.
    #[error("the time budget must be a positive number of seconds (got {0})")]
    Budget(f64),
}

/// The passes of a render for a time budget: one sample first, then each pass twice as
/// many samples as the one before while a pass takes under a sixteenth of the budget (so
/// a pass that would outlast the budget is rare, and short passes cost little
/// bookkeeping); passes until the budget is spent (at least one) or `cap` samples are in.
#[derive(Clone, Debug)]
pub struct Passes {
    budget: f64,
    cap: u32,
    start: Instant,
    s0: u32,
    chunk: u32,
}

impl Passes {
    /// Passes for `budget` seconds, up to `cap` samples per pixel (`cap` ≤ 1: unbounded).
    pub fn timed(budget: f64, cap: u32) -> Result<Self, ProgressiveError> {
        if !(budget.is_finite() && budget > 0.0) {
            return Err(ProgressiveError::Budget(budget));
        }
        Ok(Self { budget, cap: if cap > 1 { cap } else { u32::MAX }, start: Instant::now(), s0: 0, chunk: 1 })
    }

    /// The samples per pixel of the image the passes take samples of (its samples are
    /// jittered from the first, as an image of many samples is): the cap, at least 2.
    #[must_use]
    pub fn image_spp(&self) -> u32 {
        self.cap.max(2)
    }

    /// The next pass's sample indices, or `None` when the budget is spent or the cap
    /// reached (the first pass always comes).
    #[must_use]
    pub fn next(&self) -> Option<Range<u32>> {
        if self.s0 >= self.cap || (self.s0 > 0 && self.elapsed() >= self.budget) {
            return None;
        }
        Some(self.s0..self.s0.saturating_add(self.chunk).min(self.cap))
    }

    /// Records that the pass of samples `done` took `seconds`.
    pub fn took(&mut self, done: Range<u32>, seconds: f64) {
        self.s0 = done.end;
        if seconds < self.budget / 16.0 {
            self.chunk = self.chunk.saturating_mul(2);
        }
    }

    /// Samples per pixel rendered so far.
    #[must_use]
    pub fn samples(&self) -> u32 {
        self.s0
    }

    /// Seconds since the first pass was planned.
    #[must_use]
    pub fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// The budget, in seconds.
    #[must_use]
    pub fn budget(&self) -> f64 {
        self.budget
    }
}

/// The image so far: passes merged in order of their samples, and their mean.
#[derive(Clone, Debug)]
pub struct Progressive {
    acc: FilmAccumulator,
    /// The mean so far (resolved after each pass, for display).
    image: Film,
    passes: u32,
    background: Vec3,
}

impl Default for Progressive {
    fn default() -> Self {
        Self::new(0, 0, Vec3::ZERO)
    }
}

impl Progressive {
    /// An empty `width` × `height` image; pixels no pass has reached show `background`.
    #[must_use]
    pub fn new(width: u32, height: u32, background: Vec3) -> Self {
        Self { acc: FilmAccumulator::new(width, height), image: Film::new(0, 0), passes: 0, background }
    }

    /// Merges a part of a pass (any order: parts whose samples come later wait for those
    /// before them). The mean is resolved when asked for ([`Progressive::resolve`]).
    pub fn merge(&mut self, part: RegionFilm) -> Result<(), MergeError> {
        self.acc.merge(part)
    }

    /// Counts a pass as done and resolves the mean (for display).
    pub fn end_pass(&mut self) {
        self.passes += 1;
        self.image = self.acc.resolve(self.background);
    }

    /// Adds a whole-image pass and resolves the mean; starts over with it when
    /// `accumulate` is false, its size differs, or its samples are not the ones that come
    /// next (the viewer: a moved view, a new size). Returns whether it was added.
    pub fn add(&mut self, part: RegionFilm, accumulate: bool) -> bool {
        let r = part.region;
        // Passes are whole images, so pixel (0, 0) tells which samples are in.
        if !accumulate || (r.x1, r.y1) != self.acc.size() || self.acc.samples_at(0, 0) != r.s0 {
            self.acc = FilmAccumulator::new(r.x1, r.y1);
            self.passes = 0;
        }
        if let Err(e) = self.acc.merge(part) {
            tracing::debug!("a pass was not added: {e}");
            return false;
        }
        self.end_pass();
        true
    }

    /// The mean of every sample merged, resolved now.
    #[must_use]
    pub fn resolve(&self) -> Film {
        self.acc.resolve(self.background)
    }

    /// The mean at the last [`Progressive::end_pass`], borrowed.
    #[must_use]
    pub fn image(&self) -> &Film {
        &self.image
    }

    /// Passes added.
    #[must_use]
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// Size of the image.
    #[must_use]
    pub fn size(&self) -> (u32, u32) {
        self.acc.size()
    }

    /// The accumulator (for what the image holds where).
    #[must_use]
    pub fn accumulator(&self) -> &FilmAccumulator {
        &self.acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::Region;

    /// A pass of constant value `v` over a `w` × `h` image, samples `s`.
    fn pass(w: u32, h: u32, s: Range<u32>, v: f32) -> RegionFilm {
        let mut f = RegionFilm::new(Region::full(w, h, s.start, s.end));
        for y in 0..h {
            for x in 0..w {
                for _ in s.clone() {
                    f.add(x, y, Vec3::splat(v), 1.0);
                }
            }
        }
        f
    }

    #[test]
    fn passes_double_while_short_and_stop_at_the_cap() {
        let mut p = Passes::timed(100.0, 20).expect("a budget");
        assert_eq!(p.image_spp(), 20);
        let mut ranges = Vec::new();
        while let Some(r) = p.next() {
            ranges.push(r.clone());
            p.took(r, 0.0);
        }
        assert_eq!(ranges, vec![0..1, 1..3, 3..7, 7..15, 15..20]);
        assert_eq!(p.samples(), 20);
        // A slow pass keeps the next one as long.
        let mut p = Passes::timed(16.0, 0).expect("a budget");
        assert_eq!(p.image_spp(), u32::MAX);
        let r = p.next().expect("a first pass");
        p.took(r, 2.0);
        assert_eq!(p.next(), Some(1..2));
        assert_eq!(Passes::timed(0.0, 4).err(), Some(ProgressiveError::Budget(0.0)));
        assert!(Passes::timed(f64::NAN, 4).is_err());
    }

    #[test]
    fn passes_merge_to_their_mean_and_a_moved_view_starts_over() {
        let mut img = Progressive::default();
        assert!(img.add(pass(2, 1, 0..1, 1.0), false));
        assert!(img.add(pass(2, 1, 1..4, 0.0), true));
        assert_eq!(img.passes(), 2);
        assert_eq!(img.image().pixels[0], Vec3::splat(0.25));
        // A new size starts over, and so does a sample added twice.
        assert!(img.add(pass(3, 3, 0..1, 0.0), true));
        assert_eq!((img.passes(), img.size()), (1, (3, 3)));
        assert!(img.add(pass(3, 3, 0..1, 1.0), true));
        assert_eq!((img.passes(), img.image().pixels[0]), (1, Vec3::ONE));
    }
}
