//! A worker: says hello, then renders the jobs its master sends, in order, on a thread of
//! their own while this one keeps talking (results, and a heartbeat four times a second,
//! so the master can tell a busy rank from a dead one).

use crate::error::ClusterError;
use crate::link::Link;
use crate::wire::{FrameSpec, Msg};
use lucent_render::{Region, RegionFilm};
use std::panic::AssertUnwindSafe;
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::time::{Duration, Instant};

/// What renders a worker's regions.
pub trait Renderer: Send {
    /// The sums of `region` of `frame`, and the rays traced.
    ///
    /// # Errors
    /// A message for the master (the run ends with it).
    fn render(&mut self, frame: &FrameSpec, region: Region) -> Result<(RegionFilm, u64), String>;
}

/// A fault a worker injects into itself (for tests of the master's fault handling).
#[derive(Clone, Copy, Debug)]
pub enum Fault {
    /// Stop answering (this thread sleeps for ever) on receiving job number `after` (1 is
    /// the first).
    Hang {
        /// Jobs received before.
        after: u32,
    },
    /// Call `action` (kill the process, stop it) on receiving job number `after`.
    Call {
        /// Jobs received before.
        after: u32,
        /// What to do.
        action: fn(),
    },
}

/// How a worker runs.
#[derive(Clone, Debug)]
pub struct WorkerOptions {
    /// Its scene's digest (the master checks it).
    pub digest: u64,
    /// Its threads (for the master's report).
    pub threads: u32,
    /// How often it says it is alive.
    pub heartbeat: Duration,
    /// A fault to inject, if any.
    pub fault: Option<Fault>,
    /// The rayon pool that renders (default: the global one). The worker's job loop keeps
    /// one of its threads for as long as it serves, so two workers in one process need a
    /// pool each.
    pub pool: Option<std::sync::Arc<rayon::ThreadPool>>,
}

impl Default for WorkerOptions {
    fn default() -> Self {
        Self { digest: 0, threads: 1, heartbeat: Duration::from_millis(250), fault: None, pool: None }
    }
}

/// What a worker did.
#[derive(Clone, Copy, Debug, Default)]
pub struct WorkerStats {
    /// Jobs rendered.
    pub jobs: u64,
    /// Seconds spent rendering.
    pub render_seconds: f64,
}

/// A finished job: id, result, seconds.
type Finished = (u32, Result<(RegionFilm, u64), String>, f32);

/// Serves a master over `link` until it says stop.
///
/// # Errors
/// A broken message or a gone master ([`ClusterError`]), or a failed render (after telling
/// the master).
pub fn serve(link: &mut dyn Link, renderer: &mut dyn Renderer, opts: &WorkerOptions) -> Result<WorkerStats, ClusterError> {
    let (job_tx, job_rx) = channel::<(FrameSpec, u32, Region)>();
    let pool = opts.pool.clone();
    let (res_tx, res_rx) = channel::<Finished>();
    std::thread::scope(|s| {
        s.spawn(move || {
            // PERF: the loop runs on a thread of rayon's pool, so each region's parallel
            // tiles start there; called from a thread outside the pool, every region was
            // handed to the pool and its thread woken: Conference's 192 regions of 64×64
            // took 70-94 ms on one thread instead of 30.
            let jobs = |_: &rayon::Scope| {
                for (frame, id, region) in job_rx {
                    let t = Instant::now();
                    let r = std::panic::catch_unwind(AssertUnwindSafe(|| renderer.render(&frame, region)))
                        .unwrap_or_else(|p| Err(format!("the render panicked: {}", panic_text(&p))));
                    if res_tx.send((id, r, t.elapsed().as_secs_f32())).is_err() {
                        break;
                    }
                }
            };
            match &pool {
                Some(p) => p.scope(jobs),
                None => rayon::scope(jobs),
            }
        });
        let r = pump(link, &job_tx, &res_rx, opts);
        drop(job_tx);
        r
    })
}

fn panic_text(p: &Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<&str>().map(|s| (*s).to_string()).or_else(|| p.downcast_ref::<String>().cloned()).unwrap_or_else(|| "?".into())
}

/// The talking thread: messages in, jobs to the render thread, results and heartbeats out.
fn pump(
    link: &mut dyn Link,
    jobs: &std::sync::mpsc::Sender<(FrameSpec, u32, Region)>,
    results: &std::sync::mpsc::Receiver<Finished>,
    opts: &WorkerOptions,
) -> Result<WorkerStats, ClusterError> {
    let mut stats = WorkerStats::default();
    link.send(Msg::Hello { digest: opts.digest, threads: opts.threads }.encode())?;
    let mut last_sent = Instant::now();
    let mut frame: Option<FrameSpec> = None;
    let mut received = 0u32;
    let mut failed: Option<String> = None;
    loop {
        while let Some(bytes) = link.try_recv()? {
            match Msg::decode(&bytes).map_err(|cause| ClusterError::Wire { rank: 0, cause })? {
                Msg::Frame(f) => frame = Some(f),
                Msg::Job { id, region } => {
                    received += 1;
                    match opts.fault {
                        Some(Fault::Hang { after }) if received >= after => loop {
                            std::thread::sleep(Duration::from_secs(3600));
                        },
                        Some(Fault::Call { after, action }) if received == after => action(),
                        _ => {}
                    }
                    let f = frame.ok_or_else(|| ClusterError::Protocol { rank: 0, what: "a job before any frame".into() })?;
                    jobs.send((f, id, region)).map_err(|_| ClusterError::Gone { rank: 0 })?;
                }
                Msg::Stop => {
                    return match failed {
                        Some(message) => Err(ClusterError::Failed { rank: 0, region: None, message }),
                        None => Ok(stats),
                    }
                }
                Msg::Heartbeat => {}
                m => return Err(ClusterError::Protocol { rank: 0, what: format!("the master sent {m:?}") }),
            }
        }
        // (A job that arrives while this waits waits too: the master keeps enough queued.)
        match results.recv_timeout(Duration::from_micros(250)) {
            Ok((id, Ok((film, rays)), seconds)) => {
                stats.jobs += 1;
                stats.render_seconds += f64::from(seconds);
                link.send(Msg::Done { id, rays, seconds, film }.encode())?;
                last_sent = Instant::now();
            }
            Ok((id, Err(message), _)) => {
                // The master ends the run; this rank keeps answering until it says stop.
                link.send(Msg::Failed { id: Some(id), message: message.clone() }.encode())?;
                failed.get_or_insert(message);
                last_sent = Instant::now();
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return Err(ClusterError::Gone { rank: 0 }),
        }
        if last_sent.elapsed() >= opts.heartbeat {
            link.send(Msg::Heartbeat.encode())?;
            last_sent = Instant::now();
        }
    }
}
