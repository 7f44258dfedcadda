//! `--mpi`: `lucent render`, `animate` and `view` as ranks of an `mpirun` (issue 37).
//! Every rank runs the same command line and loads the same scene (replicated data, as
//! OSPRay's `mpi_offload` device); rank 0 hands out regions from a dynamic work queue
//! ([`lucent_cluster::Master`]), renders its own share on a thread of its own, merges the
//! results and writes the output; the other ranks serve ([`lucent_cluster::serve`]) until
//! rank 0 says stop. Built only with the `mpi` feature; without it `--mpi` says so.

/// The MPI options every rendering command shares.
#[derive(clap::Args, Clone, Debug)]
pub struct MpiArgs {
    /// Run as one rank of an `mpirun -np N lucent ...` (every rank with the same
    /// arguments; rank 0 writes the output). Needs a lucent built with `--features mpi`.
    #[arg(long)]
    pub mpi: bool,
    /// MPI: edge in pixels of the square regions handed out to ranks.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(8..=4096))]
    pub mpi_tile: u32,
    /// MPI: seconds a rank may send nothing (every rank says it is alive four times a
    /// second, busy or not) before rank 0 ends the run naming it.
    #[arg(long, default_value_t = 5.0)]
    pub mpi_timeout: f64,
}

/// How `lucent animate --mpi` splits the work.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnimateMode {
    /// Each rank renders whole frames.
    Frames,
    /// The ranks share each frame's tiles.
    Tiles,
}

#[cfg(not(feature = "mpi"))]
mod imp {
    //! The same methods as with MPI, on a type that has no value.
    use super::{AnimateMode, MpiArgs};
    use anyhow::{bail, Result};
    use indicatif::ProgressBar;
    use lucent_cluster::RunStats;
    use lucent_render::progressive::Progressive;
    use lucent_render::{Camera, Film, RenderSettings, World};
    use lucent_scene::CameraDesc;

    /// Never made: this lucent has no MPI.
    pub enum Session {}

    impl Session {
        /// Refuses `--mpi`.
        pub fn start(a: &MpiArgs) -> Result<Option<Session>> {
            if a.mpi {
                bail!(
                    "--mpi: this lucent was built without MPI; build it with `cargo build --release --features mpi` \
                     (needs an MPI library and libclang: Debian's libopenmpi-dev, openmpi-bin and libclang-dev)"
                );
            }
            Ok(None)
        }
        pub fn rank(&self) -> usize {
            match *self {}
        }
        pub fn size(&self) -> usize {
            match *self {}
        }
        pub fn serve(&self, _: &mut World, _: Option<CameraDesc>, _: CameraDesc) -> Result<()> {
            match *self {}
        }
        pub fn render(
            &self,
            _: &mut World,
            _: &Camera,
            _: &RenderSettings,
            _: Option<f64>,
            _: u32,
            _: &ProgressBar,
        ) -> Result<(Progressive, u64, u32, RunStats)> {
            match *self {}
        }
        #[allow(clippy::too_many_arguments)]
        pub fn animate(
            &self,
            _: &mut World,
            _: Option<CameraDesc>,
            _: CameraDesc,
            _: &[f32],
            _: &RenderSettings,
            _: AnimateMode,
            _: &mut dyn FnMut(usize, Film) -> Result<()>,
        ) -> Result<RunStats> {
            match *self {}
        }
        pub fn passes(&self, _: &World) -> Result<Box<dyn lucent_viewer::PassRenderer>> {
            match *self {}
        }
    }
}

#[cfg(feature = "mpi")]
mod imp {
    use super::{AnimateMode, MpiArgs};
    use anyhow::{bail, Context, Result};
    use indicatif::ProgressBar;
    use lucent_cluster::mpi::{end_run, Mpi};
    use lucent_cluster::{
        scene_digest, serve, tiles, ClusterError, Fault, FrameSpec, Hub, Master, MasterOptions, RunStats, SceneRenderer, WorkerOptions,
        WorldRef,
    };
    use lucent_render::progressive::{Passes, Progressive};
    use lucent_render::{Camera, Film, FilmAccumulator, Region, RegionFilm, RenderSettings, World};
    use lucent_scene::CameraDesc;
    use std::collections::HashMap;
    use std::time::{Duration, Instant};

    /// This process as a rank of the run.
    pub struct Session {
        mpi: Mpi,
        args: MpiArgs,
    }

    impl Session {
        /// Starts MPI when `--mpi` is given.
        pub fn start(a: &MpiArgs) -> Result<Option<Session>> {
            if !a.mpi {
                return Ok(None);
            }
            if !(a.mpi_timeout.is_finite() && a.mpi_timeout > 0.0) {
                bail!("--mpi-timeout must be a positive number of seconds (got {})", a.mpi_timeout);
            }
            let mpi = Mpi::init().context("cannot start MPI")?;
            if mpi.rank() == 0 {
                lucent_cluster::mpi::watch_termination();
            }
            Ok(Some(Session { mpi, args: a.clone() }))
        }

        /// This process's rank.
        pub fn rank(&self) -> usize {
            self.mpi.rank()
        }

        /// Ranks in all.
        pub fn size(&self) -> usize {
            self.mpi.size()
        }

        fn master_options(&self) -> MasterOptions {
            MasterOptions { timeout: Duration::from_secs_f64(self.args.mpi_timeout), ..MasterOptions::default() }
        }

        fn worker_options(&self, world: &World) -> WorkerOptions {
            WorkerOptions {
                digest: scene_digest(world),
                threads: u32::try_from(rayon::current_num_threads()).unwrap_or(u32::MAX),
                fault: fault_for(self.rank()),
                ..WorkerOptions::default()
            }
        }

        /// Ends the run on every rank after a fatal error on this one.
        fn fail(&self, e: &anyhow::Error) -> ! {
            end_run(&format!("error: {e:#}"), 3)
        }

        /// A worker rank: renders what rank 0 hands out until it says stop. Frames without a
        /// camera use `fixed`, else the scene's animated one, else `fallback`.
        pub fn serve(&self, world: &mut World, fixed: Option<CameraDesc>, fallback: CameraDesc) -> Result<()> {
            let opts = self.worker_options(world);
            let mut link = self.mpi.link();
            let mut r = SceneRenderer::new(WorldRef::Owned(world), fixed, fallback);
            match serve(&mut link, &mut r, &opts) {
                Ok(_) => Ok(()),
                Err(e) => self.fail(&anyhow::Error::from(e).context(format!("rank {}", self.rank()))),
            }
        }

        /// Rank 0: runs `f` with a master over every rank, rank 0's own share rendered by a
        /// thread serving `world` (posed at each frame's time). A cluster error ends every
        /// rank, after saying which rank failed and what it held.
        fn with_master<T>(
            &self,
            world: &mut World,
            fixed: Option<CameraDesc>,
            fallback: CameraDesc,
            f: impl FnOnce(&mut Master) -> Result<T, ClusterError>,
        ) -> Result<T> {
            let opts = self.worker_options(world);
            let digest = opts.digest;
            let mut hub = Hub::new(Some(self.mpi.remote()));
            let mut link = hub.attach_local(0);
            let r = std::thread::scope(|s| {
                let local = s.spawn(move || {
                    let mut r = SceneRenderer::new(WorldRef::Owned(world), fixed, fallback);
                    serve(&mut link, &mut r, &opts)
                });
                let r = Master::new(hub, digest, self.master_options()).and_then(|mut m| {
                    m.on_held(Box::new(lucent_cluster::mpi::note_held));
                    let r = f(&mut m);
                    m.stop();
                    r
                });
                // (On an error the master is gone, so the local rank's link breaks and its
                // thread ends.)
                let local = local.join();
                match (r, local) {
                    (Err(e), _) => Err(e),
                    (Ok(v), Ok(Ok(_))) => Ok(v),
                    (Ok(_), Ok(Err(e))) => Err(e),
                    (Ok(_), Err(_)) => Err(ClusterError::Failed { rank: 0, region: None, message: "its render thread panicked".into() }),
                }
            });
            r.or_else(|e| self.fail(&anyhow::Error::from(e)))
        }

        /// `lucent render --mpi` on rank 0: the image's tiles (all samples at once, or with
        /// `budget` seconds, passes of doubling sample ranges as `--time` renders them) over
        /// every rank. Returns the accumulated image, rays, samples per pixel and what the
        /// run cost.
        pub fn render(
            &self,
            world: &mut World,
            cam: &Camera,
            settings: &RenderSettings,
            budget: Option<f64>,
            cap: u32,
            bar: &ProgressBar,
        ) -> Result<(Progressive, u64, u32, RunStats)> {
            let (w, h) = (settings.width, settings.height);
            let tile = self.args.mpi_tile;
            // (The same schedule as `render --time` alone; checked before any rank works.)
            let mut passes = budget.map(|b| Passes::timed(b, cap)).transpose().map_err(|e| anyhow::anyhow!("--time: {e}"))?;
            let background = world.scene().background;
            self.with_master(world, None, never_used(), |m| {
                let mut image = Progressive::new(w, h, background);
                let mut total = RunStats::default();
                let mut frame = [FrameSpec { id: 0, time: None, settings: *settings, camera: Some(*cam) }];
                let add = |image: &mut Progressive, film: RegionFilm| -> Result<(), ClusterError> {
                    let r = film.region;
                    bar.inc(r.pixels() as u64 * u64::from(r.s1 - r.s0));
                    image.merge(film)?;
                    Ok(())
                };
                let spp = match passes.as_mut() {
                    None => {
                        let work: Vec<(usize, Region)> = tiles(w, h, tile, 0, settings.spp).into_iter().map(|r| (0, r)).collect();
                        total = m.run(&mut frame, &work, &lucent_cluster::mpi::terminated, &mut |_, film, _| add(&mut image, film))?;
                        settings.spp
                    }
                    Some(passes) => {
                        // As `render --time` alone: each pass's tiles over the ranks.
                        frame[0].settings.spp = passes.image_spp();
                        while let Some(samples) = passes.next() {
                            let t = Instant::now();
                            let work: Vec<(usize, Region)> =
                                tiles(w, h, tile, samples.start, samples.end).into_iter().map(|r| (0, r)).collect();
                            let st = m.run(&mut frame, &work, &lucent_cluster::mpi::terminated, &mut |_, film, _| add(&mut image, film))?;
                            total.add(&st);
                            passes.took(samples, t.elapsed().as_secs_f64());
                        }
                        passes.samples()
                    }
                };
                let rays = total.rays;
                Ok((image, rays, spp, total))
            })
        }

        /// `lucent animate --mpi` on rank 0: `frames` (one per time) over every rank, whole
        /// frames to each (`Frames`) or each frame's tiles shared (`Tiles`); `on_frame(k,
        /// image)` as each frame completes (in whatever order).
        #[allow(clippy::too_many_arguments)]
        pub fn animate(
            &self,
            world: &mut World,
            fixed: Option<CameraDesc>,
            fallback: CameraDesc,
            times: &[f32],
            settings: &RenderSettings,
            mode: AnimateMode,
            on_frame: &mut dyn FnMut(usize, Film) -> Result<()>,
        ) -> Result<RunStats> {
            let (w, h) = (settings.width, settings.height);
            let tile = self.args.mpi_tile;
            let bg = world.scene().background;
            self.with_master(world, fixed, fallback, |m| {
                let mut frames: Vec<FrameSpec> =
                    times.iter().map(|&t| FrameSpec { id: 0, time: Some(t), settings: *settings, camera: None }).collect();
                let mut work = Vec::new();
                for k in 0..frames.len() {
                    match mode {
                        AnimateMode::Frames => work.push((k, Region::full(w, h, 0, settings.spp))),
                        AnimateMode::Tiles => work.extend(tiles(w, h, tile, 0, settings.spp).into_iter().map(|r| (k, r))),
                    }
                }
                let per_frame = work.len() / frames.len().max(1);
                // Frames in progress: (image, regions still out).
                let mut open: HashMap<usize, (FilmAccumulator, usize)> = HashMap::new();
                let mut failed: Option<anyhow::Error> = None;
                let st = m.run(&mut frames, &work, &lucent_cluster::mpi::terminated, &mut |i, film, _| {
                    let k = work[i].0;
                    let e = open.entry(k).or_insert_with(|| (FilmAccumulator::new(w, h), per_frame));
                    e.0.merge(film)?;
                    e.1 -= 1;
                    if e.1 == 0 {
                        if let Some((acc, _)) = open.remove(&k) {
                            if let Err(err) = on_frame(k, acc.resolve(bg)) {
                                failed.get_or_insert(err);
                            }
                        }
                    }
                    Ok(())
                })?;
                Ok((st, failed))
            })
            .and_then(|(st, failed)| failed.map_or(Ok(st), Err))
        }

        /// `lucent view --mpi` on rank 0: the viewer's passes over every rank.
        pub fn passes(&self, world: &World) -> Result<Box<dyn lucent_viewer::PassRenderer>> {
            let opts = self.worker_options(world);
            let mut hub = Hub::new(Some(self.mpi.remote()));
            // (Rank 0 is this process: each pass attaches a thread serving the viewer's world.)
            drop(hub.attach_local(0));
            let master = match Master::new(hub, opts.digest, self.master_options()) {
                Ok(mut m) => {
                    m.on_held(Box::new(lucent_cluster::mpi::note_held));
                    m
                }
                Err(e) => self.fail(&e.into()),
            };
            Ok(Box::new(ClusterPasses { master, tile: self.args.mpi_tile, opts }))
        }
    }

    /// The camera of frames that carry their own (`render`, `view`): a placeholder for
    /// [`SceneRenderer`]'s fallback, which such frames never reach.
    fn never_used() -> CameraDesc {
        CameraDesc::from_view(&[0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0, 60.0])
    }

    /// The viewer's passes over every rank: rank 0's share on a thread serving the viewer's
    /// own world for the length of the pass.
    struct ClusterPasses {
        master: Master,
        tile: u32,
        opts: WorkerOptions,
    }

    impl Drop for ClusterPasses {
        fn drop(&mut self) {
            // The window closed: the other ranks leave too.
            self.master.stop();
        }
    }

    impl lucent_viewer::PassRenderer for ClusterPasses {
        fn render(
            &mut self,
            world: &World,
            time: Option<f32>,
            camera: &Camera,
            settings: &RenderSettings,
            region: Region,
        ) -> (RegionFilm, u64) {
            let region = region.clip(settings.width, settings.height);
            let mut out = RegionFilm::new(region);
            let work: Vec<(usize, Region)> = tiles(region.x1 - region.x0, region.y1 - region.y0, self.tile, region.s0, region.s1)
                .into_iter()
                .map(|r| (0, Region { x0: r.x0 + region.x0, x1: r.x1 + region.x0, y0: r.y0 + region.y0, y1: r.y1 + region.y0, ..r }))
                .collect();
            let mut link = self.master.hub_mut().attach_local(0);
            let opts = WorkerOptions { fault: None, ..self.opts.clone() };
            let mut frame = [FrameSpec { id: 0, time, settings: *settings, camera: Some(*camera) }];
            let r = std::thread::scope(|s| {
                s.spawn(move || {
                    let mut r = SceneRenderer::new(WorldRef::Shared(world), None, never_used());
                    let _ = serve(&mut link, &mut r, &opts);
                });
                let width = (region.x1 - region.x0) as usize;
                let r = self.master.run(&mut frame, &work, &lucent_cluster::mpi::terminated, &mut |_, film, _| {
                    // Tiles of one sample range: each pixel's sums are the tile's.
                    let t = film.region;
                    let tw = (t.x1 - t.x0) as usize;
                    for y in t.y0..t.y1 {
                        let dst = (y - region.y0) as usize * width + (t.x0 - region.x0) as usize;
                        let src = (y - t.y0) as usize * tw;
                        out.sum[dst..dst + tw].copy_from_slice(&film.sum[src..src + tw]);
                        out.weight[dst..dst + tw].copy_from_slice(&film.weight[src..src + tw]);
                    }
                    Ok(())
                });
                let _ = self.master.stop_rank(0);
                r
            });
            match r {
                Ok(st) => (out, st.rays),
                Err(e) => end_run(&format!("error: {e}"), 3),
            }
        }
    }

    /// `LUCENT_MPI_FAULT=RANK:kill|stop|hang:N`: rank RANK kills itself (SIGKILL), stops
    /// itself (SIGSTOP) or stops answering (a hung thread) on receiving its N-th region. For
    /// the tests of fault handling.
    fn fault_for(rank: usize) -> Option<Fault> {
        let v = std::env::var("LUCENT_MPI_FAULT").ok()?;
        let mut it = v.split(':');
        let (r, what, n) = (it.next()?.parse::<usize>().ok()?, it.next()?, it.next()?.parse::<u32>().ok()?);
        if r != rank || rank == 0 {
            return None;
        }
        match what {
            "kill" => Some(Fault::Call { after: n, action: lucent_cluster::mpi::kill_self }),
            "stop" => Some(Fault::Call { after: n, action: lucent_cluster::mpi::stop_self }),
            "hang" => Some(Fault::Hang { after: n }),
            _ => None,
        }
    }
}

pub use imp::*;
