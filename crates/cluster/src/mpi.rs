//! The ranks of an `mpirun` (rsmpi over the system's MPI library). Rank 0 is the master
//! (and renders too, on a thread of its own through a local rank); the others are workers.
//! Only the thread that initialised MPI calls it (`MPI_THREAD_FUNNELED`).

use crate::link::{Link, Remote};
use crate::ClusterError;
use mpi::topology::{Communicator, SimpleCommunicator};
use mpi::point_to_point::MatchedReceiveVec;
use mpi::traits::{Destination, Source};
use std::sync::atomic::{AtomicBool, Ordering};

/// The MPI environment of this process (finalised when dropped).
pub struct Mpi {
    _universe: mpi::environment::Universe,
    world: SimpleCommunicator,
}

impl Mpi {
    /// Initialises MPI (once per process).
    ///
    /// # Errors
    /// [`ClusterError::Mpi`] when it was initialised before, or the library does not offer
    /// the funneled thread level.
    pub fn init() -> Result<Self, ClusterError> {
        let (universe, level) = mpi::initialize_with_threading(mpi::Threading::Funneled)
            .ok_or_else(|| ClusterError::Mpi("MPI was initialised before in this process".into()))?;
        if level < mpi::Threading::Funneled {
            return Err(ClusterError::Mpi(format!("the MPI library offers threads at level {level:?}, lucent needs Funneled")));
        }
        let world = universe.world();
        Ok(Self { _universe: universe, world })
    }

    /// This process's rank.
    #[must_use]
    pub fn rank(&self) -> usize {
        usize::try_from(self.world.rank()).unwrap_or(0)
    }

    /// Ranks in all.
    #[must_use]
    pub fn size(&self) -> usize {
        usize::try_from(self.world.size()).unwrap_or(1)
    }

    /// The master's transport to ranks 1.. (for [`crate::Hub::new`]).
    #[must_use]
    pub fn remote(&self) -> Box<dyn Remote + '_> {
        Box::new(MpiRemote { world: &self.world })
    }

    /// A worker's link to rank 0.
    #[must_use]
    pub fn link(&self) -> MpiLink<'_> {
        MpiLink { world: &self.world }
    }

    /// Ends every rank of the run with `code` (mpirun's exit code).
    pub fn abort(&self, code: i32) -> ! {
        use mpi::topology::Communicator as _;
        self.world.abort(code)
    }
}

struct MpiRemote<'a> {
    world: &'a SimpleCommunicator,
}

fn rank_of(r: usize) -> Result<i32, ClusterError> {
    i32::try_from(r).map_err(|_| ClusterError::Mpi(format!("rank {r} is out of range")))
}

impl Remote for MpiRemote<'_> {
    fn size(&self) -> usize {
        usize::try_from(self.world.size()).unwrap_or(1)
    }
    fn send(&mut self, rank: usize, bytes: &[u8]) -> Result<(), ClusterError> {
        self.world.process_at_rank(rank_of(rank)?).send(bytes);
        Ok(())
    }
    fn try_recv(&mut self) -> Result<Option<(usize, Vec<u8>)>, ClusterError> {
        match self.world.any_process().immediate_matched_probe() {
            Some(probed) => {
                let (bytes, status) = probed.matched_receive_vec::<u8>();
                Ok(Some((usize::try_from(status.source_rank()).unwrap_or(usize::MAX), bytes)))
            }
            None => Ok(None),
        }
    }
}

/// A worker rank's link to rank 0.
pub struct MpiLink<'a> {
    world: &'a SimpleCommunicator,
}

impl Link for MpiLink<'_> {
    fn send(&mut self, bytes: Vec<u8>) -> Result<(), ClusterError> {
        self.world.process_at_rank(0).send(&bytes[..]);
        Ok(())
    }
    fn try_recv(&mut self) -> Result<Option<Vec<u8>>, ClusterError> {
        Ok(self.world.process_at_rank(0).immediate_matched_probe().map(|probed| probed.matched_receive_vec::<u8>().0))
    }
}

static TERMINATED: AtomicBool = AtomicBool::new(false);

extern "C" fn on_terminate(_signal: libc::c_int) {
    TERMINATED.store(true, Ordering::SeqCst);
}

/// Notes SIGTERM (what mpirun sends every rank when one dies, before it kills them) in a
/// flag [`terminated`] reads, so rank 0 can say which regions were in flight.
pub fn watch_termination() {
    // SAFETY: the handler only stores to an atomic (async-signal-safe); `signal` is given a
    // valid handler of the type it expects.
    unsafe {
        libc::signal(libc::SIGTERM, on_terminate as extern "C" fn(libc::c_int) as libc::sighandler_t);
    }
}

/// Whether SIGTERM arrived since [`watch_termination`].
#[must_use]
pub fn terminated() -> bool {
    TERMINATED.load(Ordering::SeqCst)
}

/// Kills this process at once (SIGKILL): a fault for tests (`LUCENT_MPI_FAULT`).
pub fn kill_self() {
    // SAFETY: raising a signal at this process has no memory effects.
    unsafe {
        libc::raise(libc::SIGKILL);
    }
}

/// Stops this process (SIGSTOP): it stays alive but answers nothing; a fault for tests.
pub fn stop_self() {
    // SAFETY: as in `kill_self`.
    unsafe {
        libc::raise(libc::SIGSTOP);
    }
}
