//! Temporal accumulation for moving frames (issue 55): each new frame of a moving camera
//! is blended with the frames before it, carried to where their surfaces are seen now.
//!
//! For every pixel, its surface point is rebuilt from the frame's guides (the pixel
//! centre's ray and the distance along it, [`crate::render_aovs`]) and projected into the
//! previous frame's camera; the four pixels around that point are its history, each kept
//! only where it saw the same surface (its distance from the previous eye within
//! [`DEPTH_TOLERANCE`] of the point's, its normal within [`NORMAL_COS`] of the pixel's),
//! weighed bilinearly among those kept. The pixel's value is then the mean of its history
//! and its new sample with the history counting as up to [`Temporal::max_frames`] frames
//! (an exponential moving average once that many have been seen), so a still camera
//! averages its frames exactly and a moving one keeps about that many. A pixel whose
//! surface was hidden, off-screen or never met (the sky) starts afresh (the reprojection
//! and rejection of Schied et al., "Spatiotemporal Variance-Guided Filtering", HPG 2017,
//! and of temporal antialiasing, Karis, "High quality temporal supersampling", SIGGRAPH
//! 2014 course).
//!
//! Through a mirror the guides' distance is the unfolded path's, so the point rebuilt is
//! the reflection's virtual image, which a plane mirror moves exactly as its reflection
//! moves.

use crate::camera::Camera;
use crate::film::{Aovs, Film};
use glam::Vec3;
use rayon::prelude::*;

/// How far (relative) the distance from the previous eye to a pixel's surface point may be
/// from what the previous frame saw there for its history to count.
pub const DEPTH_TOLERANCE: f32 = 0.05;
/// The least cosine between a pixel's normal and its history's.
pub const NORMAL_COS: f32 = 0.9;

/// What a frame leaves for the next.
#[derive(Clone, Debug)]
struct Frame {
    camera: Camera,
    color: Vec<Vec3>,
    depth: Vec<f32>,
    normal: Vec<Vec3>,
    /// Frames each pixel's value holds.
    count: Vec<f32>,
}

/// Moving frames blended over time (see the module's documentation).
#[derive(Clone, Debug)]
pub struct Temporal {
    /// The most frames a pixel's history counts as: the new frame weighs at least one
    /// part in this many.
    pub max_frames: f32,
    prev: Option<Frame>,
}

/// Statistics of one [`Temporal::add`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TemporalStats {
    /// The fraction of the pixels that kept some history.
    pub kept: f64,
    /// The mean number of frames a pixel's value holds.
    pub mean_frames: f64,
}

impl Temporal {
    /// No history yet; a pixel's history counts as at most `max_frames` frames (at least 1).
    #[must_use]
    pub fn new(max_frames: f32) -> Self {
        Self { max_frames: max_frames.max(1.0), prev: None }
    }

    /// Forgets every frame (the next one starts afresh).
    pub fn reset(&mut self) {
        self.prev = None;
    }

    /// Adds the frame `fresh`, rendered with `camera` (of its size), whose guides are
    /// `aovs` (of the same size): returns it blended with the frames before it, and how
    /// much history it kept. A frame whose sizes disagree starts afresh.
    pub fn add(&mut self, camera: &Camera, fresh: &Film, aovs: &Aovs) -> (Film, TemporalStats) {
        let (w, h) = (fresh.width, fresh.height);
        let n = w as usize * h as usize;
        let fits = camera.size() == (w, h)
            && fresh.pixels.len() == n
            && aovs.depth.len() == n
            && aovs.normal.pixels.len() == n
            && (aovs.normal.width, aovs.normal.height) == (w, h);
        if !fits {
            self.prev = None;
            return (fresh.clone(), TemporalStats::default());
        }
        // (Blended without what the pixel's surface emits toward the camera, which is
        // known exactly and added back from this frame: resampled, a light's edge would
        // blur onto its dark surroundings frame after frame.)
        let emission = |i: usize| aovs.emission.pixels.get(i).copied().filter(|e| e.is_finite()).unwrap_or(Vec3::ZERO);
        let color: Vec<Vec3> = fresh.pixels.iter().enumerate().map(|(i, p)| *p - emission(i)).collect();
        // Each pixel's surface point (its centre's ray at the guides' distance; `None` where
        // it sees none) and its normal turned toward the camera: a wall's two sides are two
        // surfaces.
        let (points, faced): (Vec<Option<Vec3>>, Vec<Vec3>) = (0..n)
            .into_par_iter()
            .map(|i| {
                let ray = camera.ray((i % w as usize) as f32 + 0.5, (i / w as usize) as f32 + 0.5);
                let (nrm, depth) = (aovs.normal.pixels[i], aovs.depth[i]);
                let faced = if nrm.dot(ray.dir) > 0.0 { -nrm } else { nrm };
                let seen = depth.is_finite() && depth > 0.0 && nrm != Vec3::ZERO;
                (seen.then(|| ray.org + ray.dir.normalize_or_zero() * depth), faced)
            })
            .unzip();
        // Per pixel: its value without emission blended with its history, and the frames
        // that holds (1: none).
        let mut blended: Vec<(Vec3, f32)> = color.iter().map(|&c| (c, 1.0)).collect();
        if let Some(prev) = &self.prev {
            let max_held = self.max_frames - 1.0;
            blended.par_chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
                for (x, out) in row.iter_mut().enumerate() {
                    let i = y * w as usize + x;
                    if let Some((hist, held)) = points[i].and_then(|p| history(prev, p, faced[i])) {
                        let held = held.min(max_held);
                        if held > 0.0 {
                            // The mean of `held` frames of history and the new one.
                            let total = held + 1.0;
                            *out = (hist * (held / total) + out.0 / total, total);
                        }
                    }
                }
            });
        }
        let (color, count): (Vec<Vec3>, Vec<f32>) = blended.into_iter().unzip();
        let kept = count.iter().filter(|&&c| c > 1.0).count();
        let stats = TemporalStats {
            kept: kept as f64 / n.max(1) as f64,
            mean_frames: count.iter().map(|&c| f64::from(c)).sum::<f64>() / n.max(1) as f64,
        };
        // (A pixel without history is this frame's own, bit for bit.)
        let out = color.iter().enumerate().map(|(i, c)| if count[i] > 1.0 { *c + emission(i) } else { fresh.pixels[i] }).collect();
        self.prev = Some(Frame { camera: *camera, color, depth: aovs.depth.clone(), normal: faced, count });
        (Film { width: w, height: h, pixels: out }, stats)
    }
}

/// The history of a pixel whose surface point is `p`, with normal `normal` (turned toward
/// its camera): the previous frame's values around where that point was seen, bilinear
/// over those that saw the same surface, and the frames they held; `None` where none did.
fn history(prev: &Frame, p: Vec3, normal: Vec3) -> Option<(Vec3, f32)> {
    let (pw, ph) = prev.camera.size();
    let (px, py, _) = prev.camera.project(p)?;
    // (The distance along the previous camera's ray through that point, from its origin:
    // the eye, or a point of the view plane when orthographic.)
    let want = (p - prev.camera.ray(px, py).org).length();
    // The four pixel centres around (px, py) and their bilinear weights.
    let (fx, fy) = (px - 0.5, py - 0.5);
    let (x0, y0) = (fx.floor(), fy.floor());
    if !(x0.is_finite() && y0.is_finite()) {
        return None;
    }
    let (tx, ty) = (fx - x0, fy - y0);
    let (mut sum, mut frames, mut wsum) = (Vec3::ZERO, 0.0f32, 0.0f32);
    for (dx, dy, wt) in [(0, 0, (1.0 - tx) * (1.0 - ty)), (1, 0, tx * (1.0 - ty)), (0, 1, (1.0 - tx) * ty), (1, 1, tx * ty)] {
        let (qx, qy) = (x0 as i64 + dx, y0 as i64 + dy);
        if wt <= 0.0 || qx < 0 || qy < 0 || qx >= i64::from(pw) || qy >= i64::from(ph) {
            continue;
        }
        let j = (qy * i64::from(pw) + qx) as usize;
        let pd = prev.depth[j];
        // (Written so that a NaN distance or normal refuses the pixel.)
        let same_depth = (pd - want).abs() <= DEPTH_TOLERANCE * want.max(pd);
        let same_normal = prev.normal[j].dot(normal) >= NORMAL_COS;
        if !(same_depth && same_normal) {
            continue;
        }
        sum += prev.color[j] * wt;
        frames += prev.count[j] * wt;
        wsum += wt;
    }
    if wsum <= 0.0 {
        return None;
    }
    let hist = sum / wsum;
    hist.is_finite().then_some((hist, frames / wsum))
}
