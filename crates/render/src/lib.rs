//! # lucent_render
//!
//! Turns a scene into pixels: [`World`] builds the two-level index from a
//! `lucent_scene::Scene`, [`Camera`] makes primary rays, an [`Integrator`] shades them
//! (path tracing, Whitted, virtual point lights, or a debug view), [`render()`] renders a
//! whole image on all cores ([`render_region`] one rectangle × sample range of it, which a
//! [`FilmAccumulator`] merges), and [`Film`] writes PNG or EXR.
//!
//! The crate's floors, from the bottom (no module imports one above its floor):
//! 1. the floor: [`color`], [`sampling`], [`sampler`], `lanes`, [`aov`], [`texture`],
//!    [`camera`];
//! 2. the scene as rendered: [`bsdf`], [`lights`], [`materials`], [`world`], `coverage`,
//!    [`film`], [`mod@denoise`], [`temporal`];
//! 3. the tile loop, [`tiles`];
//! 4. the [`integrator`]s;
//! 5. the driver: [`render()`], [`render_region`], [`progressive`], [`setup`].
//!
//! # Example
//! ```
//! use lucent_render::{render, Camera, Integrator, PathSettings, RenderSettings, World};
//! let scene = lucent_scene::demo_scene();
//! let camera = Camera::new(&scene.camera.expect("the demo has a camera"), 32, 24);
//! let world = World::new(scene, lucent_accel::MeshOptions::default()).expect("a world");
//! let settings = RenderSettings { spp: 4, integrator: Integrator::Path(PathSettings::default()), ..RenderSettings::new(32, 24) };
//! let (image, rays) = render(&world, &camera, &settings, &|_| {});
//! assert_eq!(image.pixels.len(), 32 * 24);
//! assert!(rays > 0 && image.pixels.iter().any(|p| p.max_element() > 0.0));
//! ```
#![deny(missing_docs)]

pub mod aov;
pub mod bsdf;
pub mod camera;
pub mod color;
mod coverage;
pub mod denoise;
pub mod film;
pub mod integrator;
pub mod lanes;
pub mod lights;
pub mod materials;
pub mod progressive;
mod render;
pub mod sampler;
pub mod sampling;
pub mod setup;
pub mod temporal;
pub mod texture;
pub mod tiles;
pub mod world;

pub use bsdf::{Bsdf, BsdfModel, BsdfSample};
pub use camera::{framing_camera, Camera};
pub use coverage::{Coverage, BLOCK_EDGE};
pub use denoise::{denoise, denoise_with_variance, DenoiseSettings};
pub use film::{Aovs, Film, FilmAccumulator, MergeError, OutputError, Region, RegionFilm};
pub use integrator::guides::render_aovs;
pub use integrator::{Integrator, LightSampling, PathSettings, VplSettings, WhittedSettings};
pub use lights::{EmissionSample, LightModel, LightSample};
pub use render::{render, render_halves, render_pixel, render_region, render_two_halves, Halves, RenderSettings};
pub use sampler::{filter_offset, jitter, pcg_hash, CameraSamples, PixelSampler, Sampler};
pub use temporal::{Temporal, TemporalStats};
pub use tiles::{Block, Job, Traversal, TILE};
pub use world::pose::vertex_normals;
pub use world::record::{record_rays, RecordedRays};
pub use world::surface::Surface;
pub use world::{shape_of, World, WorldError};
