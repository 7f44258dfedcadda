//! `lucent bench vpl`: issue 35's figures. VPL frames per second at 512×384 on 2 threads
//! (Conference with the Embree harness's point light, and the animated BART kitchen with
//! its own lights, posed and its VPLs made anew every frame), the rays per second of the
//! frame's shadow rays toward the VPLs against its camera rays (each kind traced alone,
//! as the renderer groups them), and quality: relMSE against a converged path-traced
//! image (cached under `target/bench-cache/`) of the VPL image with and without the
//! discontinuity buffer, and of 4 samples + denoiser against the raw 64-sample image.

use crate::stats::median;
use anyhow::{bail, Context, Result};
use lucent_accel::glam::Vec3;
use lucent_accel::MeshOptions;
use lucent_render::integrator::vpl::{frame_rays, VplSet};
use lucent_render::{
    denoise, render, render_aovs, Camera, DenoiseSettings, Film, Integrator, PathSettings, RenderSettings, VplSettings, World,
};
use lucent_scene::{CameraDesc, Light, LightKind};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `bench vpl`.
pub struct VplOptions {
    pub dir: PathBuf,
    pub size: (u32, u32),
    pub frames: usize,
    /// Samples per pixel of the path-traced references.
    pub reference_spp: u32,
    /// Skip the quality figures (they need the references).
    pub speed_only: bool,
}

/// A scene of the benchmark: its world and camera.
fn load(o: &VplOptions, name: &str) -> Result<(World, CameraDesc)> {
    match name {
        "cornell" => {
            let p = Path::new("crates/render/tests/data/mitsuba/cornell_box/scene.xml");
            let scene = lucent_scene::load_mitsuba_with(p, &[]).with_context(|| format!("{}", p.display()))?;
            let cam = scene.camera.context("the Cornell box has a camera")?;
            Ok((World::new(scene, MeshOptions::default())?, cam))
        }
        "kitchen" => {
            let p = o.dir.join("bart/kitchen/kitchen.gltf");
            let scene = lucent_scene::load(&p).with_context(|| format!("{}", p.display()))?;
            let mut world = World::new(scene, MeshOptions::default())?;
            let cam = world.set_time(0.0)?.or(world.scene().camera).context("the kitchen has a camera")?;
            Ok((world, cam))
        }
        _ => {
            let Some(p) = crate::frame_bench::PRESETS.iter().find(|p| p.name == name) else {
                bail!("unknown scene '{name}' (cornell, kitchen, conference, sponza)");
            };
            let path = o.dir.join(p.file);
            let scene = lucent_scene::load(&path).with_context(|| format!("{}", path.display()))?;
            let (lo, hi) = scene.bounds().context("empty scene")?;
            let mut world = World::new(scene, MeshOptions::default())?;
            // The Embree harness's light (with the inverse square law, so that light falls
            // off as physically based light does).
            let light = crate::frame_bench::harness_light(lo, hi);
            let power = (hi - lo).length_squared() * 0.05;
            world.set_lights(vec![Light { kind: LightKind::Point { position: light }, color: Vec3::splat(power), inverse_square: true }]);
            Ok((world, CameraDesc::from_view(&p.cam)))
        }
    }
}

fn settings(size: (u32, u32), spp: u32, integrator: Integrator) -> RenderSettings {
    RenderSettings { spp, integrator, ..RenderSettings::new(size.0, size.1) }
}

/// The path-traced reference of a scene (cached).
fn reference(o: &VplOptions, name: &str, w: &World, cam: &Camera) -> Result<Film> {
    let cache = PathBuf::from("target/bench-cache");
    std::fs::create_dir_all(&cache)?;
    let file = cache.join(format!("{name}_{}x{}_{}spp.exr", o.size.0, o.size.1, o.reference_spp));
    if let Ok(f) = Film::load(&file) {
        return Ok(f);
    }
    eprintln!("{name}: path tracing the reference ({} spp, cached in {})", o.reference_spp, file.display());
    let f = render(w, cam, &settings(o.size, o.reference_spp, Integrator::Path(PathSettings::default())), &|_| {}).0;
    f.save(&file)?;
    Ok(f)
}

/// Rays per second of packets traced one after another (`occluded`: shadow rays).
fn rays_per_s(w: &World, packets: &[Vec<lucent_accel::Ray>], occluded: bool, single: bool) -> f64 {
    let n: usize = packets.iter().map(Vec::len).sum();
    let mut times: Vec<f64> = (0..3)
        .map(|_| {
            let t = Instant::now();
            let mut hits = [None; 64];
            let mut blocked = [false; 64];
            let mut sink = 0usize;
            for p in packets {
                for c in p.chunks(64) {
                    match (occluded, single) {
                        (true, false) => {
                            w.occluded_packet(c, &mut blocked[..c.len()]);
                            sink += blocked[..c.len()].iter().filter(|&&b| b).count();
                        }
                        (true, true) => sink += c.iter().filter(|r| w.occluded(r)).count(),
                        (false, false) => {
                            w.intersect_packet(c, &mut hits[..c.len()]);
                            sink += hits[..c.len()].iter().flatten().count();
                        }
                        (false, true) => sink += c.iter().filter_map(|r| w.intersect(r)).count(),
                    }
                }
            }
            std::hint::black_box(sink);
            t.elapsed().as_secs_f64()
        })
        .collect();
    n as f64 / median(&mut times)
}

pub fn run(o: &VplOptions) -> Result<()> {
    let pool = crate::threads::pool(2, true)?;
    let vs = VplSettings::default();
    let (wd, ht) = o.size;
    println!("machine: 2 threads, {wd}x{ht}, {} VPLs, {}x{} interleaving, clamp {}", vs.count, vs.interleave, vs.interleave, vs.clamp);
    // Speed: VPL frames, and the rays of one frame by kind.
    for name in ["conference", "kitchen"] {
        let (mut world, desc) = load(o, name)?;
        let animated = world.scene().animation.is_some();
        let mut cam = Camera::new(&desc, wd, ht);
        let st = settings(o.size, 1, Integrator::Vpl(vs));
        let mut times = Vec::new();
        let mut rays = 0;
        for f in 0..=o.frames {
            let t = Instant::now();
            if animated {
                if let Some(d) = world.set_time(f as f32 / 25.0)? {
                    cam = Camera::new(&d, wd, ht);
                }
            }
            let (_, r) = pool.install(|| render(&world, &cam, &st, &|_| {}));
            if f > 0 {
                times.push(t.elapsed().as_secs_f64());
                rays = r;
            }
        }
        let med = median(&mut times);
        // The rays of one frame, by kind, each traced alone on one thread.
        let set = VplSet::generate(&world, &vs, 0);
        let (primary, shadow) = frame_rays(&world, &cam, &st, &set);
        let (p_pk, p_1) = (rays_per_s(&world, &primary, false, false), rays_per_s(&world, &primary, false, true));
        let (s_pk, s_1) = (rays_per_s(&world, &shadow, true, false), rays_per_s(&world, &shadow, true, true));
        let nshadow: usize = shadow.iter().map(Vec::len).sum();
        println!(
            "{name:<10} VPL frame {:7.1} ms = {:5.2} fps ({}{rays} rays, {:.1} Mrays/s) | one thread: camera rays {:.1} M/s packets, {:.1} single; VPL shadow rays ({nshadow}, {:.1} per packet) {:.1} M/s packets, {:.1} single",
            med * 1e3,
            1.0 / med,
            if animated { "posed every frame, " } else { "" },
            rays as f64 / med * 1e-6,
            p_pk * 1e-6,
            p_1 * 1e-6,
            nshadow as f64 / shadow.len().max(1) as f64,
            s_pk * 1e-6,
            s_1 * 1e-6
        );
        println!(
            "{}",
            serde_json::json!({"kind": "vpl_speed", "scene": name, "width": wd, "height": ht, "threads": 2, "vpls": vs.count,
                "median_ms": med * 1e3, "fps": 1.0 / med, "rays": rays, "animated": animated,
                "camera_mrays_s_packet": p_pk * 1e-6, "camera_mrays_s_single": p_1 * 1e-6,
                "shadow_mrays_s_packet": s_pk * 1e-6, "shadow_mrays_s_single": s_1 * 1e-6, "shadow_rays": nshadow})
        );
    }
    if o.speed_only {
        return Ok(());
    }
    // Quality against converged path tracing.
    for name in ["cornell", "sponza", "kitchen"] {
        let (world, desc) = load(o, name)?;
        let cam = Camera::new(&desc, wd, ht);
        let reference = pool.install(|| reference(o, name, &world, &cam))?;
        let rel = |f: &Film| f.rel_mse(&reference).unwrap_or(f64::NAN);
        let vpl = |v: VplSettings| pool.install(|| render(&world, &cam, &settings(o.size, 1, Integrator::Vpl(v)), &|_| {}).0);
        let e_vpl = rel(&vpl(vs));
        let e_raw = rel(&vpl(VplSettings { discontinuity: false, ..vs }));
        let path =
            |spp| pool.install(|| render(&world, &cam, &settings(o.size, spp, Integrator::Path(PathSettings::default())), &|_| {}).0);
        let p4 = path(4);
        let e64 = rel(&path(64));
        let t = Instant::now();
        let aovs = pool.install(|| render_aovs(&world, &cam, wd, ht));
        let t_aovs = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let d4 = pool.install(|| denoise(&p4, &aovs, &DenoiseSettings::default()));
        let t_den = t.elapsed().as_secs_f64();
        let (e4, e4d) = (rel(&p4), rel(&d4));
        let mean = |f: &Film| f.pixels.iter().map(|p| f64::from(p.x + p.y + p.z)).sum::<f64>();
        println!(
            "{name:<10} relMSE against path tracing at {} spp: VPL {e_vpl:.4} (without the discontinuity buffer {e_raw:.4}); path 4 spp {e4:.4}, denoised {e4d:.4} (mean {:+.2}%), 64 spp {e64:.4}; denoiser {:.0} ms + guides {:.0} ms",
            o.reference_spp,
            (mean(&d4) / mean(&p4) - 1.0) * 100.0,
            t_den * 1e3,
            t_aovs * 1e3
        );
        println!(
            "{}",
            serde_json::json!({"kind": "vpl_quality", "scene": name, "width": wd, "height": ht, "reference_spp": o.reference_spp,
                "vpl_relmse": e_vpl, "vpl_relmse_no_discontinuity": e_raw, "path4_relmse": e4, "path4_denoised_relmse": e4d,
                "path64_relmse": e64, "denoise_ms": t_den * 1e3, "guides_ms": t_aovs * 1e3})
        );
    }
    Ok(())
}
