//! The ranks of an `mpirun` (rsmpi over the system's MPI library). Rank 0 is the master
//! (and renders too, on a thread of its own through a local rank); the others are workers.
//! Only the thread that initialised MPI calls it (`MPI_THREAD_FUNNELED`).

use crate::error::ClusterError;
use crate::link::{Link, Remote};
use mpi::point_to_point::MatchedReceiveVec;
use mpi::topology::{Communicator, SimpleCommunicator};
use mpi::traits::{Destination, Source};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// The MPI environment of this process (finalised when dropped).
pub struct Mpi {
    universe: mpi::environment::Universe,
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
        Ok(Self { universe, world })
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

    /// The master's transport to ranks 1.. (for [`crate::Hub::new`]). It must not outlive
    /// this value (MPI is finalised when it is dropped).
    #[must_use]
    pub fn remote(&self) -> Box<dyn Remote> {
        Box::new(MpiRemote { world: self.universe.world() })
    }

    /// A worker's link to rank 0 (not to outlive this value either).
    #[must_use]
    pub fn link(&self) -> MpiLink {
        MpiLink { world: self.universe.world() }
    }
}

/// Ends the whole run after a fatal error on this rank: writes `message` (and a newline) to
/// stderr in one write, so that mpirun's forwarding cannot cut it, and leaves with `code`
/// without finalising MPI. mpirun then ends every other rank and exits with `code`,
/// naming this rank.
///
/// Not `MPI_Abort`: under Debian's Open MPI 4.1, mpirun deadlocked in its own teardown
/// after an `MPI_Abort` in 2 of 20 runs of a silent-rank fault (it ignored SIGTERM from
/// then on: CI waited 90 minutes), and crashed in `PMIx_server_finalize` in 3 more; after
/// an exit without finalising, it never hung in 20 runs and crashed once.
pub fn end_run(message: &str, code: i32) -> ! {
    use std::io::Write;
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().lock().write_all(format!("{message}\n").as_bytes());
    // SAFETY: `_exit` ends the process at once; nothing after it runs, and no Rust value is
    // observed half-dropped (the other threads simply stop). MPI is deliberately not
    // finalised (see above).
    unsafe { libc::_exit(code) }
}

struct MpiRemote {
    world: SimpleCommunicator,
}

fn rank_of(r: usize) -> Result<i32, ClusterError> {
    i32::try_from(r).map_err(|_| ClusterError::Mpi(format!("rank {r} is out of range")))
}

impl Remote for MpiRemote {
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
pub struct MpiLink {
    world: SimpleCommunicator,
}

impl Link for MpiLink {
    fn send(&mut self, bytes: Vec<u8>) -> Result<(), ClusterError> {
        self.world.process_at_rank(0).send(&bytes[..]);
        Ok(())
    }
    fn try_recv(&mut self) -> Result<Option<Vec<u8>>, ClusterError> {
        Ok(self.world.process_at_rank(0).immediate_matched_probe().map(|probed| probed.matched_receive_vec::<u8>().0))
    }
}

static TERMINATED: AtomicBool = AtomicBool::new(false);

/// What each rank holds, as the master last said ([`note_held`]).
static HELD: Mutex<String> = Mutex::new(String::new());

extern "C" fn on_terminate(_signal: libc::c_int) {
    TERMINATED.store(true, Ordering::SeqCst);
    // mpirun sends SIGKILL a second after SIGTERM: say what was in flight now, and leave.
    // Only a lock that is free is taken (`try_lock`: an atomic exchange, no allocation), and
    // only write(2) and _exit(2) are called, both async-signal-safe.
    let head = b"error: the run was terminated (mpirun ends every rank when one dies: see its message for which); regions in flight: ";
    // SAFETY: write(2) of valid buffers to stderr, then _exit(2).
    unsafe {
        libc::write(2, head.as_ptr().cast(), head.len());
        match HELD.try_lock() {
            Ok(held) if !held.is_empty() => {
                libc::write(2, held.as_ptr().cast(), held.len());
            }
            _ => {
                let s = b"unknown";
                libc::write(2, s.as_ptr().cast(), s.len());
            }
        }
        libc::write(2, b"\n".as_ptr().cast(), 1);
        libc::_exit(143);
    }
}

/// Records what each rank holds, for the SIGTERM handler to say.
pub fn note_held(text: &str) {
    if let Ok(mut h) = HELD.lock() {
        h.clear();
        h.push_str(text);
    }
}

/// Notes SIGTERM (what mpirun sends every rank when one dies, a second before it kills
/// them): rank 0 says at once which regions were in flight (as [`note_held`] last recorded
/// them) and exits; [`terminated`] tells the master's loop, for a handler that could not.
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
