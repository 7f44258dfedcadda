//! # lucent_viewer
//!
//! `lucent view`: fly through a scene in a window, Pixel-Planes style. While the camera
//! moves, frames are rendered at reduced resolution (a quarter of the pixels to start,
//! then whatever holds `--target-fps`) and scaled up; when it stops, the full-resolution
//! image is refined one sample per pixel per frame until it converges. REND3R programs
//! play one `nf` per frame.
//!
//! This is the only crate with display dependencies (winit + softbuffer, X11 loaded at
//! run time), so nothing else in lucent needs a display. [`control`] holds the logic that
//! is tested without a window.
#![deny(missing_docs)]

mod app;
pub mod control;
pub mod font;

pub use app::{run, run_with, Content, PassRenderer, ViewOptions, ViewerError};
