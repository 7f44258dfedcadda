//! What ends a distributed run, and how it names the regions in flight.

use crate::wire::DecodeError;
use lucent_render::{MergeError, Region};
use std::time::Duration;

/// What ends a distributed run.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    /// A message could not be read.
    #[error("a message from rank {rank} is broken: {cause}")]
    Wire {
        /// The sender.
        rank: usize,
        /// What is wrong (in the message, so not also a `source()`).
        cause: DecodeError,
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

pub(crate) fn region_text(r: &Region) -> String {
    format!("{}..{} x {}..{} samples {}..{}", r.x0, r.x1, r.y0, r.y1, r.s0, r.s1)
}

pub(crate) fn regions_text(v: &[Region]) -> String {
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
