//! The master: hands out regions from a dynamic work queue (each rank holds a few at a
//! time, enough to cover the round trip: fast ranks take more), hears every rank, and
//! ends the run with a clear error when one fails or falls silent.

use crate::error::ClusterError;
use crate::link::Hub;
use crate::wire::{FrameSpec, Msg};
use lucent_render::{Region, RegionFilm};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// How the master runs.
#[derive(Clone, Copy, Debug)]
pub struct MasterOptions {
    /// A rank silent (no result, no heartbeat) for this long ends the run.
    pub timeout: Duration,
    /// How long [`Master::new`] waits for every rank to load its scene.
    pub hello_timeout: Duration,
    /// Regions a rank holds at once at least (one rendering, the others queued: hides the
    /// time a result and the next job spend on the way). A rank whose round trip takes
    /// longer than its regions' render time holds more (up to [`MAX_DEPTH`]), as many as
    /// it takes to keep it busy.
    pub depth: usize,
}

impl Default for MasterOptions {
    fn default() -> Self {
        Self { timeout: Duration::from_secs(5), hello_timeout: Duration::from_secs(600), depth: 2 }
    }
}

/// The most regions a rank holds at once.
pub const MAX_DEPTH: usize = 16;

/// What a run cost.
#[derive(Clone, Debug, Default)]
pub struct RunStats {
    /// Regions rendered.
    pub jobs: usize,
    /// Per rank, regions it rendered.
    pub jobs_per_rank: Vec<usize>,
    /// Bytes sent to other processes.
    pub bytes_out: u64,
    /// Bytes received from other processes.
    pub bytes_in: u64,
    /// Rays the ranks traced.
    pub rays: u64,
    /// Σ over regions of the seconds their rank spent rendering them.
    pub render_seconds: f64,
    /// Σ over regions of the seconds from handing a region out to its result being in,
    /// less the time it waited behind others at its rank (the round trip's overhead is
    /// this less `render_seconds`).
    pub turnaround_seconds: f64,
    /// Seconds the master spent merging results (the `on_done` calls).
    pub merge_seconds: f64,
    /// Seconds the run took.
    pub seconds: f64,
}

impl RunStats {
    /// Adds another run's costs (passes of one render).
    pub fn add(&mut self, o: &RunStats) {
        if self.jobs_per_rank.len() < o.jobs_per_rank.len() {
            self.jobs_per_rank.resize(o.jobs_per_rank.len(), 0);
        }
        for (x, y) in self.jobs_per_rank.iter_mut().zip(&o.jobs_per_rank) {
            *x += y;
        }
        self.jobs += o.jobs;
        self.bytes_out += o.bytes_out;
        self.bytes_in += o.bytes_in;
        self.rays += o.rays;
        self.render_seconds += o.render_seconds;
        self.turnaround_seconds += o.turnaround_seconds;
        self.merge_seconds += o.merge_seconds;
        self.seconds += o.seconds;
    }
}

/// Rank 0's side of a distributed render.
pub struct Master {
    hub: Hub,
    opts: MasterOptions,
    digest: u64,
    /// The id the next frame gets.
    next_frame: u32,
    /// Per rank, the frame whose jobs it was sent last.
    current: Vec<Option<u32>>,
    /// Per rank, its thread count (from its hello; 0 before).
    threads: Vec<u32>,
    /// Told what each rank holds (see [`Master::on_held`]).
    observer: Option<Observer>,
    /// Per rank, regions it may hold: enough to cover its round trip with render time,
    /// from its regions' round trips against their render times. PERF: with two, one rank
    /// of one thread spent 1.3 ms per 64×64 Conference region of 0.26 ms waiting for the
    /// next job (258 ms a frame, not 50).
    depth: Vec<usize>,
}

/// Told which regions each rank holds.
type Observer = Box<dyn FnMut(&str)>;

/// A region handed out: (index in the work, when it became the rank's first).
type Held = (usize, Instant);

impl Master {
    /// A master over `hub`'s ranks, once each has loaded its scene and said hello with the
    /// same scene `digest` as rank 0.
    ///
    /// # Errors
    /// [`ClusterError::Digest`] for a rank with another scene, [`ClusterError::Silent`] for
    /// one that does not say hello within [`MasterOptions::hello_timeout`], or what the
    /// transport reports.
    pub fn new(hub: Hub, digest: u64, opts: MasterOptions) -> Result<Self, ClusterError> {
        let n = hub.size();
        let mut m =
            Self { hub, opts, digest, next_frame: 0, current: vec![None; n], threads: vec![0; n], observer: None, depth: Vec::new() };
        let start = Instant::now();
        // (Local ranks are threads of this process, with its world: their hello, checked
        // like any other, comes when they start.)
        while let Some(waiting) = (0..n).find(|&r| m.hub.is_remote(r) && m.threads[r] == 0) {
            match m.hub.try_recv()? {
                Some((rank, bytes)) => {
                    if let Msg::Failed { message, .. } = m.decode(rank, &bytes)? {
                        return Err(ClusterError::Failed { rank, region: None, message });
                    }
                }
                None => {
                    if start.elapsed() > opts.hello_timeout {
                        return Err(ClusterError::Silent { rank: waiting, silent: start.elapsed(), regions: Vec::new() });
                    }
                    std::thread::sleep(Duration::from_micros(200));
                }
            }
        }
        Ok(m)
    }

    /// Has `f` told, at most every 20 ms while a run waits, which regions each rank holds
    /// (the text [`ClusterError::Terminated`] shows): for a signal handler that must say it
    /// without asking this thread.
    pub fn on_held(&mut self, f: Box<dyn FnMut(&str)>) {
        self.observer = Some(f);
    }

    /// Ranks (rank 0 included).
    #[must_use]
    pub fn ranks(&self) -> usize {
        self.hub.size()
    }

    /// Threads of every rank, by rank (known once it said hello).
    #[must_use]
    pub fn threads(&self) -> &[u32] {
        &self.threads
    }

    /// The hub (to attach a local rank between runs).
    pub fn hub_mut(&mut self) -> &mut Hub {
        &mut self.hub
    }

    /// Decodes a message; a hello is checked and recorded here.
    fn decode(&mut self, rank: usize, bytes: &[u8]) -> Result<Msg, ClusterError> {
        let msg = Msg::decode(bytes).map_err(|cause| ClusterError::Wire { rank, cause })?;
        if let Msg::Hello { digest, threads } = msg {
            if digest != self.digest {
                return Err(ClusterError::Digest { rank, theirs: digest, ours: self.digest });
            }
            if let Some(t) = self.threads.get_mut(rank) {
                *t = threads.max(1);
            }
        }
        Ok(msg)
    }

    /// Renders `work` (pairs of an index into `frames` and a region of that frame): hands
    /// the regions out in order, a few per rank (see [`MasterOptions::depth`]), and calls
    /// `on_done(index in work, sums, rays)` for each as it comes back, in whatever order.
    /// `frames` get their ids here. `interrupted` is asked while waiting (a termination
    /// request ends the run).
    ///
    /// # Errors
    /// The first [`ClusterError`]: a failed, silent or broken rank (named, with the regions
    /// it held), a termination, or what `on_done` returns.
    pub fn run(
        &mut self,
        frames: &mut [FrameSpec],
        work: &[(usize, Region)],
        interrupted: &dyn Fn() -> bool,
        on_done: &mut dyn FnMut(usize, RegionFilm, u64) -> Result<(), ClusterError>,
    ) -> Result<RunStats, ClusterError> {
        let start = Instant::now();
        for f in frames.iter_mut() {
            f.id = self.next_frame;
            self.next_frame = self.next_frame.wrapping_add(1);
        }
        let n = self.hub.size();
        self.current.resize(n, None);
        self.threads.resize(n, 0);
        let mut stats = RunStats { jobs_per_rank: vec![0; n], ..RunStats::default() };
        let mut held: Vec<VecDeque<Held>> = vec![VecDeque::new(); n];
        let floor = self.opts.depth.clamp(1, MAX_DEPTH);
        self.depth.resize(n, floor);
        // (Messages that waited since the last run, heartbeats mostly, are read first.)
        let mut heard = vec![start; n];
        let (mut next, mut done) = (0usize, 0usize);
        // Whether what ranks hold changed since the observer was told, and when it was.
        let (mut changed, mut told) = (true, start - Duration::from_secs(1));
        while done < work.len() {
            // Hand out: one more region per rank per sweep, so ranks share the queue's
            // start evenly.
            for _ in 0..MAX_DEPTH {
                #[allow(clippy::needless_range_loop)] // (r also names the rank)
                for r in 0..n {
                    if next >= work.len() || held[r].len() >= self.depth[r] {
                        continue;
                    }
                    let (f, region) = work[next];
                    let frame =
                        frames.get(f).ok_or_else(|| ClusterError::Protocol { rank: 0, what: format!("work {next} names frame {f}") })?;
                    if self.current[r] != Some(frame.id) {
                        self.send(r, &Msg::Frame(*frame), &mut stats)?;
                        self.current[r] = Some(frame.id);
                    }
                    self.send(r, &Msg::Job { id: next as u32, region }, &mut stats)?;
                    held[r].push_back((next, Instant::now()));
                    next += 1;
                    changed = true;
                }
            }
            let Some((rank, bytes)) = self.hub.try_recv()? else {
                if interrupted() {
                    return Err(ClusterError::Terminated { inflight: held_regions(&held, work) });
                }
                let now = Instant::now();
                if let (Some(f), true) = (self.observer.as_mut(), changed && now.duration_since(told) > Duration::from_millis(20)) {
                    f(&crate::error::inflight_text(&held_regions(&held, work)));
                    (changed, told) = (false, now);
                }
                if let Some(r) = (0..n).find(|&r| now.duration_since(heard[r]) > self.opts.timeout) {
                    let regions = regions_of(&held[r], work);
                    return Err(ClusterError::Silent { rank: r, silent: now.duration_since(heard[r]), regions });
                }
                std::thread::sleep(Duration::from_micros(100));
                continue;
            };
            if rank >= n {
                return Err(ClusterError::Protocol { rank, what: format!("a message from rank {rank} of {n}") });
            }
            heard[rank] = Instant::now();
            if self.hub.is_remote(rank) {
                stats.bytes_in += bytes.len() as u64;
            }
            match self.decode(rank, &bytes)? {
                Msg::Hello { .. } | Msg::Heartbeat => {}
                Msg::Done { id, rays, seconds, film } => {
                    let id = id as usize;
                    let Some(k) = held[rank].iter().position(|&(i, _)| i == id) else {
                        return Err(ClusterError::Protocol { rank, what: format!("a result for region {id}, which it did not hold") });
                    };
                    let (_, since) = held[rank].remove(k).unwrap_or((id, heard[rank]));
                    // The next region in this rank's queue starts waiting for it now.
                    if let Some(h) = held[rank].front_mut() {
                        h.1 = h.1.max(heard[rank]);
                    }
                    let turnaround = heard[rank].duration_since(since).as_secs_f64();
                    stats.turnaround_seconds += turnaround;
                    let want = 2.0 + (turnaround - f64::from(seconds)).max(0.0) / f64::from(seconds).max(1e-6);
                    // (Only up: once regions queue, the round trip is hidden and looks short.)
                    self.depth[rank] = self.depth[rank].max((want.ceil() as usize).min(MAX_DEPTH));
                    stats.render_seconds += f64::from(seconds);
                    stats.rays += rays;
                    stats.jobs += 1;
                    stats.jobs_per_rank[rank] += 1;
                    let t = Instant::now();
                    on_done(id, film, rays)?;
                    stats.merge_seconds += t.elapsed().as_secs_f64();
                    done += 1;
                    changed = true;
                }
                Msg::Failed { id, message } => {
                    let region = id.and_then(|i| work.get(i as usize)).map(|w| w.1);
                    return Err(ClusterError::Failed { rank, region, message });
                }
                m @ (Msg::Frame(_) | Msg::Job { .. } | Msg::Stop) => {
                    return Err(ClusterError::Protocol { rank, what: format!("a worker sent {}", kind(&m)) });
                }
            }
        }
        if let Some(f) = self.observer.as_mut() {
            f("none");
        }
        stats.seconds = start.elapsed().as_secs_f64();
        Ok(stats)
    }

    fn send(&mut self, rank: usize, msg: &Msg, stats: &mut RunStats) -> Result<(), ClusterError> {
        let bytes = msg.encode();
        if self.hub.is_remote(rank) {
            stats.bytes_out += bytes.len() as u64;
        }
        self.hub.send(rank, bytes)
    }

    /// Tells `rank` (a local thread, between runs) to leave.
    ///
    /// # Errors
    /// What the transport reports.
    pub fn stop_rank(&mut self, rank: usize) -> Result<(), ClusterError> {
        if let Some(c) = self.current.get_mut(rank) {
            *c = None;
        }
        self.hub.send(rank, Msg::Stop.encode())
    }

    /// Tells every rank to leave (ranks already gone are skipped).
    pub fn stop(&mut self) {
        for r in 0..self.hub.size() {
            let _ = self.hub.send(r, Msg::Stop.encode());
        }
    }
}

/// The regions one rank holds.
fn regions_of(held: &VecDeque<Held>, work: &[(usize, Region)]) -> Vec<Region> {
    held.iter().map(|&(i, _)| work[i].1).collect()
}

/// Per rank, the regions it holds.
fn held_regions(held: &[VecDeque<Held>], work: &[(usize, Region)]) -> Vec<(usize, Vec<Region>)> {
    held.iter().enumerate().map(|(r, h)| (r, regions_of(h, work))).collect()
}

fn kind(m: &Msg) -> &'static str {
    match m {
        Msg::Hello { .. } => "a hello",
        Msg::Frame(_) => "a frame",
        Msg::Job { .. } => "a job",
        Msg::Done { .. } => "a result",
        Msg::Heartbeat => "a heartbeat",
        Msg::Failed { .. } => "a failure",
        Msg::Stop => "a stop",
    }
}
