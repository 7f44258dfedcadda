//! Rendering on many processes: a master hands out image regions (pixels × sample ranges)
//! from a dynamic work queue to workers, which render them with
//! [`lucent_render::render_region`] and send back their sums; the master merges them in a
//! [`lucent_render::FilmAccumulator`], so the image is bit for bit the one a single process
//! renders, whatever the number of workers and the order regions come back in.
//!
//! The same master and worker run over two transports: threads of one process
//! ([`link::Hub::attach_local`], used for rank 0's own share of the work and by the tests)
//! and, with the `mpi` feature, the ranks of an `mpirun` (`mpi`; replicated data, as
//! OSPRay's `mpi_offload` device: every rank loads the same scene).
//!
//! Faults end a run, never hang it: every worker sends a heartbeat four times a second
//! while it loads, renders or idles; a rank silent for longer than the timeout, a rank
//! whose render failed, and a termination request (mpirun's SIGTERM when a rank died) end
//! the run with a [`ClusterError`] that names the rank and the regions it held.

#![deny(missing_docs)]

mod error;
pub mod link;
pub mod master;
#[cfg(feature = "mpi")]
pub mod mpi;
mod scene;
pub mod wire;
pub mod worker;

pub use error::ClusterError;
pub use link::{ChannelLink, Hub, Link, Remote};
pub use master::{Master, MasterOptions, RunStats};
pub use scene::{scene_digest, tiles, SceneRenderer, WorldRef};
pub use wire::{DecodeError, FrameSpec, Msg};
pub use worker::{serve, Fault, Renderer, WorkerOptions, WorkerStats};
