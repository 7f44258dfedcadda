//! Rendering on many processes: a master hands out image regions (pixels × sample ranges)
//! from a dynamic work queue to workers, which render them with
//! [`lucent_render::render_region`] and send back their sums; the master merges them in a
//! [`lucent_render::FilmAccumulator`], so the image is bit for bit the one a single process
//! renders, whatever the number of workers and the order regions come back in.
//!
//! The same master and worker run over two transports: threads of one process
//! ([`link::Hub::attach_local`], used for rank 0's own share of the work and by the tests)
//! and, with the `mpi` feature, the ranks of an `mpirun` ([`mpi`]; replicated data, as
//! OSPRay's `mpi_offload` device: every rank loads the same scene).
//!
//! Faults end a run, never hang it: every worker sends a heartbeat four times a second
//! while it loads, renders or idles; a rank silent for longer than the timeout, a rank
//! whose render failed, and a termination request (mpirun's SIGTERM when a rank died) end
//! the run with a [`ClusterError`] that names the rank and the regions it held.

pub mod link;
pub mod master;
#[cfg(feature = "mpi")]
pub mod mpi;
pub mod wire;
pub mod worker;

pub use link::{ChannelLink, Hub, Link, Remote};
pub use master::{Master, MasterOptions, RunStats};
pub use wire::{DecodeError, FrameSpec, Msg};
pub use worker::{serve, Fault, Renderer, WorkerOptions, WorkerStats};

use lucent_render::{MergeError, Region, World};
use std::time::Duration;

/// What ends a distributed run.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    /// A message could not be read.
    #[error("a message from rank {rank} is broken: {source}")]
    Wire {
        /// The sender.
        rank: usize,
        /// What is wrong.
        source: DecodeError,
    },
    /// A rank sent nothing (not even a heartbeat) for too long.
    #[error("rank {rank} stopped answering (no message for {:.1} s); it held {}", .silent.as_secs_f64(), regions_text(.regions))]
    Silent {
        /// The rank.
        rank: usize,
        /// How long it was silent.
        silent: Duration,
        /// The regions it was rendering or had queued.
        regions: Vec<Region>,
    },
    /// A rank's render failed.
    #[error("rank {rank} failed{}: {message}", .region.map(|r| format!(" on region {}", region_text(&r))).unwrap_or_default())]
    Failed {
        /// The rank.
        rank: usize,
        /// The region it failed on, if one.
        region: Option<Region>,
        /// Its message.
        message: String,
    },
    /// A rank loaded a different scene.
    #[error("rank {rank} loaded a different scene (digest {theirs:016x}, rank 0 has {ours:016x}): every rank must load the same file")]
    Digest {
        /// The rank.
        rank: usize,
        /// Its digest.
        theirs: u64,
        /// Rank 0's.
        ours: u64,
    },
    /// A rank broke the protocol (a bug, or a process that is not lucent).
    #[error("rank {rank}: {what}")]
    Protocol {
        /// The rank.
        rank: usize,
        /// What it did.
        what: String,
    },
    /// The other side of a channel is gone (a thread of this process ended).
    #[error("rank {rank} is gone (its thread ended)")]
    Gone {
        /// The rank.
        rank: usize,
    },
    /// The run was asked to end (mpirun's SIGTERM: another rank died, or the job was
    /// cancelled).
    #[error("the run was terminated (mpirun ends every rank when one dies: see its message for which); regions in flight: {}", inflight_text(.inflight))]
    Terminated {
        /// Per rank, the regions it held.
        inflight: Vec<(usize, Vec<Region>)>,
    },
    /// A region could not be merged.
    #[error(transparent)]
    Merge(#[from] MergeError),
    /// The MPI library refused something.
    #[error("MPI: {0}")]
    Mpi(String),
}

fn region_text(r: &Region) -> String {
    format!("{}..{} x {}..{} samples {}..{}", r.x0, r.x1, r.y0, r.y1, r.s0, r.s1)
}

fn regions_text(v: &[Region]) -> String {
    if v.is_empty() {
        return "no region".into();
    }
    let list: Vec<String> = v.iter().map(region_text).collect();
    format!("{} region{}: {}", v.len(), if v.len() == 1 { "" } else { "s" }, list.join("; "))
}

pub(crate) fn inflight_text(v: &[(usize, Vec<Region>)]) -> String {
    let held: Vec<String> = v.iter().filter(|(_, r)| !r.is_empty()).map(|(k, r)| format!("rank {k}: {}", regions_text(r))).collect();
    if held.is_empty() {
        "none".into()
    } else {
        held.join(", ")
    }
}

/// A digest of what a world renders (counts and bounds of its geometry, lights and
/// materials): ranks that loaded different files, or the same file differently, differ.
#[must_use]
pub fn scene_digest(w: &World) -> u64 {
    let s = w.scene();
    let st = s.stats();
    let mut words: Vec<u64> = vec![
        st.triangles as u64,
        st.vertices as u64,
        st.meshes as u64,
        st.instances as u64,
        st.materials as u64,
        st.textures as u64,
        w.lights().len() as u64,
        u64::from(s.environment.is_some()),
    ];
    if let Some((lo, hi)) = s.bounds() {
        words.extend(lo.to_array().into_iter().chain(hi.to_array()).map(|x| u64::from(x.to_bits())));
    }
    words.extend(s.background.to_array().map(|x| u64::from(x.to_bits())));
    // FNV-1a over the words' bytes.
    words.iter().flat_map(|w| w.to_le_bytes()).fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// The `tile` × `tile` regions of a `width` × `height` image, samples `s0..s1`, row by row
/// (the last row and column of tiles cut at the image's edge).
#[must_use]
pub fn tiles(width: u32, height: u32, tile: u32, s0: u32, s1: u32) -> Vec<Region> {
    let t = tile.max(1);
    let mut v = Vec::new();
    for y0 in (0..height).step_by(t as usize) {
        for x0 in (0..width).step_by(t as usize) {
            v.push(Region { x0, y0, x1: (x0 + t).min(width), y1: (y0 + t).min(height), s0, s1 });
        }
    }
    v
}

/// The world a [`SceneRenderer`] renders.
pub enum WorldRef<'a> {
    /// Posed by its owner (the viewer poses it before each pass).
    Shared(&'a World),
    /// Posed here, at each frame's time.
    Owned(&'a mut World),
}

/// Renders regions of a world, posing it at each frame's time and choosing the camera as
/// `lucent animate` does when the frame carries none.
pub struct SceneRenderer<'a> {
    world: WorldRef<'a>,
    /// The time the world is posed at.
    posed: Option<f32>,
    /// The camera the world's animation gave at that time.
    animated: Option<lucent_scene::CameraDesc>,
    /// A camera that overrides the animation's (`--camera`).
    pub fixed: Option<lucent_scene::CameraDesc>,
    /// The camera when there is neither.
    pub fallback: lucent_scene::CameraDesc,
}

impl<'a> SceneRenderer<'a> {
    /// A renderer of `world`; frames without a camera use `fixed`, else the animation's,
    /// else `fallback`.
    #[must_use]
    pub fn new(world: WorldRef<'a>, fixed: Option<lucent_scene::CameraDesc>, fallback: lucent_scene::CameraDesc) -> Self {
        Self { world, posed: None, animated: None, fixed, fallback }
    }
}

impl Renderer for SceneRenderer<'_> {
    fn render(&mut self, frame: &FrameSpec, region: Region) -> Result<(lucent_render::RegionFilm, u64), String> {
        if let (Some(t), WorldRef::Owned(w)) = (frame.time, &mut self.world) {
            if self.posed != Some(t) {
                self.animated = w.set_time(t).map_err(|e| format!("cannot pose the scene at {t} s: {e}"))?;
                self.posed = Some(t);
            }
        }
        let world: &World = match &self.world {
            WorldRef::Shared(w) => w,
            WorldRef::Owned(w) => w,
        };
        let s = &frame.settings;
        let camera = frame
            .camera
            .unwrap_or_else(|| lucent_render::Camera::new(&self.fixed.or(self.animated).unwrap_or(self.fallback), s.width, s.height));
        Ok(lucent_render::render_region(world, &camera, s, region, &|_| {}))
    }
}
