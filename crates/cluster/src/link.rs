//! Transports: how the master reaches its ranks ([`Hub`]) and a worker its master
//! ([`Link`]). Ranks below [`Hub::attach_local`]'s count are threads of this process
//! (channels); the others are reached through a [`Remote`] (MPI).

use crate::error::ClusterError;
use std::sync::mpsc::{channel, Receiver, Sender, TryRecvError};

/// Ranks of another process (MPI): the master's side.
pub trait Remote {
    /// Ranks in all, the master's own (0) included.
    fn size(&self) -> usize;
    /// Sends `bytes` to `rank` (1 or more).
    ///
    /// # Errors
    /// [`ClusterError::Mpi`] when the library refuses.
    fn send(&mut self, rank: usize, bytes: &[u8]) -> Result<(), ClusterError>;
    /// A message that has arrived from any rank, if one has.
    ///
    /// # Errors
    /// [`ClusterError::Mpi`] when the library refuses.
    fn try_recv(&mut self) -> Result<Option<(usize, Vec<u8>)>, ClusterError>;
}

/// A worker's way to its master.
pub trait Link {
    /// Sends `bytes` to the master.
    ///
    /// # Errors
    /// [`ClusterError::Gone`] or [`ClusterError::Mpi`].
    fn send(&mut self, bytes: Vec<u8>) -> Result<(), ClusterError>;
    /// A message from the master, if one has arrived.
    ///
    /// # Errors
    /// [`ClusterError::Gone`] or [`ClusterError::Mpi`].
    fn try_recv(&mut self) -> Result<Option<Vec<u8>>, ClusterError>;
}

/// The master's side: every rank, local (threads) or remote.
pub struct Hub {
    local: Vec<Option<Sender<Vec<u8>>>>,
    inbox_tx: Sender<(usize, Vec<u8>)>,
    inbox: Receiver<(usize, Vec<u8>)>,
    remote: Option<Box<dyn Remote>>,
    /// Alternates which side is asked first.
    flip: bool,
}

impl Hub {
    /// A hub of no rank yet, reaching `remote`'s ranks (1..size) if given.
    #[must_use]
    pub fn new(remote: Option<Box<dyn Remote>>) -> Self {
        let (inbox_tx, inbox) = channel();
        Self { local: Vec::new(), inbox_tx, inbox, remote, flip: false }
    }

    /// Ranks in all (0..size).
    #[must_use]
    pub fn size(&self) -> usize {
        self.remote.as_ref().map_or(0, |r| r.size()).max(self.local.len())
    }

    /// Whether `rank` is another process.
    #[must_use]
    pub fn is_remote(&self, rank: usize) -> bool {
        rank >= self.local.len()
    }

    /// Makes `rank` (below every remote rank: 0 under MPI) a thread of this process, and
    /// returns the worker's end. A rank attached again gets a new channel (the old end's
    /// messages are dropped as they come).
    pub fn attach_local(&mut self, rank: usize) -> ChannelLink {
        if self.local.len() <= rank {
            self.local.resize_with(rank + 1, || None);
        }
        let (tx, rx) = channel();
        self.local[rank] = Some(tx);
        ChannelLink { rank, to_master: self.inbox_tx.clone(), from_master: rx }
    }

    /// Sends `bytes` to `rank`.
    ///
    /// # Errors
    /// [`ClusterError::Gone`] for a local rank whose thread ended, [`ClusterError::Mpi`].
    pub fn send(&mut self, rank: usize, bytes: Vec<u8>) -> Result<(), ClusterError> {
        match self.local.get(rank) {
            Some(Some(tx)) => tx.send(bytes).map_err(|_| ClusterError::Gone { rank }),
            Some(None) => Err(ClusterError::Gone { rank }),
            None => match self.remote.as_mut() {
                Some(r) if rank < r.size() => r.send(rank, &bytes),
                _ => Err(ClusterError::Gone { rank }),
            },
        }
    }

    /// A message from any rank, if one has arrived.
    ///
    /// # Errors
    /// [`ClusterError::Mpi`].
    pub fn try_recv(&mut self) -> Result<Option<(usize, Vec<u8>)>, ClusterError> {
        self.flip = !self.flip;
        for side in [self.flip, !self.flip] {
            if side {
                match self.inbox.try_recv() {
                    Ok(m) => return Ok(Some(m)),
                    Err(TryRecvError::Empty | TryRecvError::Disconnected) => {}
                }
            } else if let Some(r) = self.remote.as_mut() {
                if let Some(m) = r.try_recv()? {
                    return Ok(Some(m));
                }
            }
        }
        Ok(None)
    }
}

/// A worker thread's end of a local rank.
pub struct ChannelLink {
    rank: usize,
    to_master: Sender<(usize, Vec<u8>)>,
    from_master: Receiver<Vec<u8>>,
}

impl ChannelLink {
    /// The rank this end serves.
    #[must_use]
    pub fn rank(&self) -> usize {
        self.rank
    }
}

impl Link for ChannelLink {
    fn send(&mut self, bytes: Vec<u8>) -> Result<(), ClusterError> {
        self.to_master.send((self.rank, bytes)).map_err(|_| ClusterError::Gone { rank: 0 })
    }
    fn try_recv(&mut self) -> Result<Option<Vec<u8>>, ClusterError> {
        match self.from_master.try_recv() {
            Ok(m) => Ok(Some(m)),
            Err(TryRecvError::Empty) => Ok(None),
            Err(TryRecvError::Disconnected) => Err(ClusterError::Gone { rank: 0 }),
        }
    }
}
