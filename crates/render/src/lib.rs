//! # lucent_render
//!
//! Turns a scene into pixels: [`World`] builds the two-level index from a
//! `lucent_scene::Scene`, [`Camera`] makes primary rays, an [`Integrator`] shades them
//! (Whitted, or a debug view), [`render()`] runs tiles on all cores ([`render_region`]
//! one rectangle × sample range of them, which a [`FilmAccumulator`] merges), and [`Film`]
//! writes PNG or EXR.
#![warn(missing_docs)]

pub mod bsdf;
pub mod camera;
mod coverage;
pub mod denoise;
pub mod film;
pub mod integrator;
pub mod lights;
pub mod materials;
mod render;
pub mod sampler;
mod shading;
pub mod texture;
mod world;

pub use bsdf::{Bsdf, BsdfModel, BsdfSample};
pub use camera::{framing_camera, Camera};
pub use coverage::{Coverage, BLOCK_EDGE};
pub use denoise::{denoise, DenoiseSettings};
pub use film::{Aovs, Film, FilmAccumulator, MergeError, OutputError, Region, RegionFilm};
pub use integrator::{Block, Integrator, LightSampling, PathSettings, Traversal, VplSettings, WhittedSettings};
pub use lights::{EmissionSample, LightModel, LightSample};
pub use render::{jitter, pcg_hash, render, render_aovs, render_pixel, render_region, RenderSettings, TILE};
pub use sampler::{PixelSampler, Sampler};
pub use world::{record_rays, shape_of, vertex_normals, RecordedRays, Surface, World, WorldError};
