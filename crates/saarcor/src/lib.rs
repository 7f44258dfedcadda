//! # saarcor
//!
//! The hardware study behind `lucent report`: lucent's kernels count what they do through
//! the [`lucent_accel::Counters`] seam, and models of the seed papers' machines turn the
//! counts into their tables.
//!
//! - [`cache`]: direct-mapped caches of fixed-size items (SaarCOR's three caches).
//! - [`kd`]: SaarCOR's index, a kd-tree per mesh and one over the instances (Wald and
//!   Havran 2006's SAH sweep), generic over a precision and over counters.
//! - [`dynrtp`]: SaarCOR's DynRTP prototype (units, caches, bandwidth) fed with primary
//!   rays through lucent's BVH or the [`kd`] index: its Table 3 (fps
//!   at 512×384) and Table 4 (fps, unit usage, hit rates, MB/s at 1024×768).
//! - [`objects`]: a one-mesh scene split into movable objects (Conference's 54), equal
//!   ones instances of one geometry.
//! - [`paper`]: what SaarCOR's paper prints (Tables 1-4, its text's figures, its
//!   scenes), and its designs' floating-point units counted to derive Table 1.
//! - [`pp5`]: Pixel-Planes 5's integer sphere tracer (12/24-bit values, 6 fraction bits
//!   on t) at 640x512 and 1280x1024 against f64.
//! - [`precision`]: traversal and intersection in SaarCOR's 24-bit floats, IEEE half and
//!   fixed point: changed hits and PSNR against f32.
//! - [`charts`]: the report page's charts (plotters, SVG).
//! - [`report`]: the tables as terminal text, Markdown, JSON lines and an HTML page with
//!   plots; REND3R's cycle model is `rend3r_machine::cycles`.
#![deny(missing_docs)]

pub mod cache;
pub mod charts;
pub mod dynrtp;
pub mod kd;
pub mod objects;
pub mod paper;
pub mod pp5;
pub mod precision;
pub mod report;

pub use kd::{kd_of_world, kd_of_world_with};
