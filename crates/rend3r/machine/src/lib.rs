//! # rend3r_machine
//!
//! Where everything meets: the REND3R device. [`Processor`] executes instruction words
//! (from `rend3r_isa`) into a [`DeviceState`]; [`render_frame`] turns the state into a
//! frame, ray traced by lucent's engine ([`Mode::Raytrace`]) or rasterized
//! ([`Mode::Raster`]). `frame` documents every decision lucent takes where REND3R's paper
//! is silent.
#![deny(missing_docs)]

pub mod board;
pub mod cycles;
pub mod frame;
mod processor;
pub mod raster;
mod render;

pub use frame::{camera, rgb565, scene, set_kind_of_source, FrameInfo, FrameSettings, Mode, SetKind};
pub use processor::{DeviceState, Processor, Record, Sets, Step, LIGHTS, MAX_SETS};
pub use render::render_frame;
