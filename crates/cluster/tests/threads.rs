//! The master and workers over threads of one process (the MPI transport is tested under
//! `mpirun` by the CLI's tests): images bit for bit the one-process render's, whatever the
//! rank count and the order results arrive in; faults end the run with the rank named.

use lucent_accel::MeshOptions;
use lucent_cluster::{
    scene_digest, serve, tiles, ClusterError, Fault, FrameSpec, Hub, Master, MasterOptions, Renderer, SceneRenderer, WorkerOptions,
    WorldRef,
};
use lucent_render::{render, Camera, FilmAccumulator, Integrator, PathSettings, Region, RegionFilm, RenderSettings, VplSettings, World};
use std::time::{Duration, Instant};

fn world(scene: lucent_scene::Scene) -> World {
    World::new(scene, MeshOptions::default()).expect("world")
}

/// Renders `work` of one frame on `ranks` local ranks (rank k's renderer from
/// `renderer(k)`), merging into an image.
fn cluster_render<'w>(
    ranks: usize,
    opts: MasterOptions,
    digest: u64,
    frame: FrameSpec,
    work: &[Region],
    renderer: &(dyn Fn(usize) -> (Box<dyn Renderer + 'w>, WorkerOptions) + Sync),
) -> Result<(FilmAccumulator, lucent_cluster::RunStats), ClusterError> {
    let mut hub = Hub::new(None);
    let links: Vec<_> = (0..ranks).map(|r| hub.attach_local(r)).collect();
    std::thread::scope(|s| {
        for (k, mut link) in links.into_iter().enumerate() {
            s.spawn(move || {
                let (mut r, o) = renderer(k);
                let _ = serve(&mut link, r.as_mut(), &o);
            });
        }
        let mut master = Master::new(hub, digest, opts)?;
        let (w, h) = (frame.settings.width, frame.settings.height);
        let mut acc = FilmAccumulator::new(w, h);
        let work: Vec<(usize, Region)> = work.iter().map(|r| (0, *r)).collect();
        let r = master.run(&mut [frame], &work, &|| false, &mut |_, film, _| acc.merge(film).map_err(ClusterError::from));
        match r {
            Ok(stats) => {
                master.stop();
                Ok((acc, stats))
            }
            Err(e) => {
                master.stop();
                Err(e)
            }
        }
    })
}

/// A pool of its own for each worker (a worker keeps one of its pool's threads).
fn pool() -> std::sync::Arc<rayon::ThreadPool> {
    std::sync::Arc::new(rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("pool"))
}

fn bits(f: &lucent_render::Film) -> Vec<[u32; 3]> {
    f.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

#[test]
fn images_over_ranks_are_the_one_process_image() {
    let (w, h) = (96, 72);
    for (scene, integrator, spp) in [
        (lucent_scene::demo_scene(), Integrator::default(), 1),
        (lucent_scene::demo_scene(), Integrator::default(), 3),
        (lucent_scene::studio_scene(), Integrator::Path(PathSettings::default()), 4),
        (lucent_scene::studio_scene(), Integrator::Vpl(VplSettings { count: 32, ..VplSettings::default() }), 2),
    ] {
        let desc = scene.camera.expect("camera");
        let wld = world(scene);
        let cam = Camera::new(&desc, w, h);
        let settings = RenderSettings { spp, integrator, ..RenderSettings::new(w, h) };
        let one = render(&wld, &cam, &settings, &|_| {}).0;
        let digest = scene_digest(&wld);
        let frame = FrameSpec { id: 0, time: None, settings, camera: Some(cam) };
        for (ranks, tile) in [(1usize, 32u32), (3, 16), (4, 48)] {
            let work = tiles(w, h, tile, 0, spp);
            let mk = |_: usize| -> (Box<dyn Renderer + '_>, WorkerOptions) {
                (
                    Box::new(SceneRenderer::new(WorldRef::Shared(&wld), None, desc)),
                    WorkerOptions { digest, pool: Some(pool()), ..WorkerOptions::default() },
                )
            };
            let (acc, stats) = cluster_render(ranks, MasterOptions::default(), digest, frame, &work, &mk).expect("run");
            assert_eq!(stats.jobs, work.len());
            assert_eq!(stats.jobs_per_rank.iter().sum::<usize>(), work.len());
            let img = acc.resolve(wld.scene().background);
            assert!(bits(&img) == bits(&one), "{} spp {spp}, {ranks} ranks, tiles {tile}: not the one-process image", integrator.name());
        }
        // Sample ranges split across ranks too (the --time passes): the same image as the
        // whole range in one region, merged in order of the first sample.
        if spp > 1 {
            let mut work = tiles(w, h, 32, 0, 1);
            work.extend(tiles(w, h, 32, 1, spp));
            let mk = |_: usize| -> (Box<dyn Renderer + '_>, WorkerOptions) {
                (
                    Box::new(SceneRenderer::new(WorldRef::Shared(&wld), None, desc)),
                    WorkerOptions { digest, pool: Some(pool()), ..WorkerOptions::default() },
                )
            };
            let (a, _) = cluster_render(3, MasterOptions::default(), digest, frame, &work, &mk).expect("run");
            let (b, _) = cluster_render(2, MasterOptions::default(), digest, frame, &work, &mk).expect("run");
            let bg = wld.scene().background;
            assert!(bits(&a.resolve(bg)) == bits(&b.resolve(bg)), "sample ranges: the same bits whatever the rank count");
        }
    }
}

/// A renderer that fails, or sleeps, on a chosen region.
struct Faulty {
    fail_at: Option<Region>,
    sleep: Duration,
}

impl Renderer for Faulty {
    fn render(&mut self, _: &FrameSpec, region: Region) -> Result<(RegionFilm, u64), String> {
        std::thread::sleep(self.sleep);
        if Some(region) == self.fail_at {
            return Err("out of memory (injected)".into());
        }
        Ok((RegionFilm::new(region), 0))
    }
}

fn faulty_frame() -> FrameSpec {
    let s = lucent_scene::demo_scene();
    let cam = Camera::new(&s.camera.expect("camera"), 64, 64);
    FrameSpec { id: 0, time: None, settings: RenderSettings::new(64, 64), camera: Some(cam) }
}

#[test]
fn a_rank_that_stops_answering_is_named_with_its_regions() {
    let work = tiles(64, 64, 16, 0, 1);
    let opts = MasterOptions { timeout: Duration::from_millis(600), ..MasterOptions::default() };
    let mk = |k: usize| -> (Box<dyn Renderer + Send>, WorkerOptions) {
        let fault = (k == 2).then_some(Fault::Hang { after: 2 });
        (
            Box::new(Faulty { fail_at: None, sleep: Duration::from_millis(20) }),
            WorkerOptions { fault, pool: Some(pool()), ..WorkerOptions::default() },
        )
    };
    // The workers run on threads of their own (the hung one never returns; the test
    // leaves it behind).
    let mut hub = Hub::new(None);
    for k in 0..3 {
        let mut link = hub.attach_local(k);
        let (mut r, o) = mk(k);
        std::thread::spawn(move || {
            let _ = serve(&mut link, r.as_mut(), &o);
        });
    }
    let t = Instant::now();
    let mut master = Master::new(hub, 0, opts).expect("hello");
    let work: Vec<(usize, Region)> = work.iter().map(|r| (0, *r)).collect();
    let e = master.run(&mut [faulty_frame()], &work, &|| false, &mut |_, _, _| Ok(())).expect_err("a rank hung");
    let waited = t.elapsed();
    match &e {
        ClusterError::Silent { rank, regions, .. } => {
            assert_eq!(*rank, 2);
            // It held the region it hung on (its second), and perhaps one queued behind it.
            assert!(!regions.is_empty() && regions.len() <= 2, "{regions:?}");
        }
        e => panic!("{e}"),
    }
    let text = e.to_string();
    assert!(text.starts_with("rank 2 stopped answering (no message for 0.6 s); it held"), "{text}");
    assert!(waited < Duration::from_secs(5), "ended after {waited:?}");
}

#[test]
fn a_failed_render_ends_the_run_with_the_rank_and_region() {
    let work = tiles(64, 64, 16, 0, 1);
    let bad = work[9];
    let mk = move |_: usize| -> (Box<dyn Renderer>, WorkerOptions) {
        (Box::new(Faulty { fail_at: Some(bad), sleep: Duration::ZERO }), WorkerOptions { pool: Some(pool()), ..WorkerOptions::default() })
    };
    let e = cluster_render(3, MasterOptions::default(), 0, faulty_frame(), &work, &mk).expect_err("a render failed");
    let text = e.to_string();
    assert!(matches!(e, ClusterError::Failed { region: Some(r), .. } if r == bad), "{text}");
    assert!(text.contains("failed on region 16..32 x 32..48 samples 0..1: out of memory (injected)"), "{text}");
}

#[test]
fn a_rank_with_another_scene_is_refused() {
    let work = tiles(64, 64, 16, 0, 1);
    let mk = |k: usize| -> (Box<dyn Renderer>, WorkerOptions) {
        (
            Box::new(Faulty { fail_at: None, sleep: Duration::ZERO }),
            WorkerOptions { digest: if k == 1 { 7 } else { 5 }, pool: Some(pool()), ..WorkerOptions::default() },
        )
    };
    let e = cluster_render(2, MasterOptions::default(), 5, faulty_frame(), &work, &mk).expect_err("digest");
    assert!(matches!(e, ClusterError::Digest { rank: 1, theirs: 7, ours: 5 }), "{e}");
}

#[test]
fn tiles_cover_the_image_once() {
    let t = tiles(100, 37, 32, 2, 5);
    assert_eq!(t.len(), 4 * 2);
    assert_eq!(t.iter().map(Region::pixels).sum::<usize>(), 3700);
    assert!(t.iter().all(|r| r.s0 == 2 && r.s1 == 5 && r.x1 <= 100 && r.y1 <= 37));
    for (i, a) in t.iter().enumerate() {
        assert!(t[i + 1..].iter().all(|b| !a.overlaps(b)));
    }
}
