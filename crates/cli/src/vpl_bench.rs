//! `lucent bench vpl`: issue 35's figures. VPL frames per second at 512×384 on 2 threads
//! (Conference with the Embree harness's point light, and the animated BART kitchen with
//! its own lights, posed and its VPLs made anew every frame), the rays per second of the
//! frame's shadow rays toward the VPLs against its camera rays (each kind traced alone,
//! as the renderer groups them), the frame's rays (VPL generation included) traced again
//! alone on the same 2 threads (the frame rate an integrator whose every other step were
//! free would reach with these kernels), and quality: relMSE against a converged path-traced
//! image (cached under `target/bench-cache/`) of the VPL image with and without the
//! discontinuity buffer, and of 4 samples + denoiser against the raw 64-sample image, on
//! the Cornell box, Sponza, the kitchen, and the kitchen with every opaque material made
//! Lambertian (the VPL goal is stated for diffuse scenes).

use crate::stats::median;
use anyhow::{bail, Context, Result};
use lucent_accel::glam::Vec3;
use lucent_accel::MeshOptions;
use lucent_render::integrator::vpl::{frame_rays, VplSet};
use lucent_render::{
    denoise, render, render_aovs, Camera, DenoiseSettings, Film, Integrator, PathSettings, RenderSettings, VplSettings, World,
};
use lucent_scene::bsdf::{Bsdf, FloatTex};
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
    /// Only these scenes (empty: all).
    pub only: Vec<String>,
}

impl VplOptions {
    fn wants(&self, name: &str) -> bool {
        self.only.is_empty() || self.only.iter().any(|o| o == name)
    }
}

/// A scene of the benchmark: its world and camera.
pub(crate) fn load(o: &VplOptions, name: &str) -> Result<(World, CameraDesc)> {
    match name {
        "cornell" => {
            let p = Path::new("crates/render/tests/data/mitsuba/cornell_box/scene.xml");
            let scene = lucent_scene::load_mitsuba_with(p, &[]).with_context(|| format!("{}", p.display()))?;
            let cam = scene.camera.context("the Cornell box has a camera")?;
            Ok((World::new(scene, MeshOptions::default())?, cam))
        }
        "kitchen" | "kitchen-diffuse" => {
            let p = o.dir.join("bart/kitchen/kitchen.gltf");
            let mut scene = lucent_scene::load(&p).with_context(|| format!("{}", p.display()))?;
            if name == "kitchen-diffuse" {
                make_diffuse(&mut scene);
            }
            let mut world = World::new(scene, MeshOptions::default())?;
            let cam = world.set_time(0.0)?.or(world.scene().camera).context("the kitchen has a camera")?;
            Ok((world, cam))
        }
        _ => {
            let Some(p) = crate::frame_bench::PRESETS.iter().find(|p| p.name == name) else {
                bail!("unknown scene '{name}' (cornell, kitchen, kitchen-diffuse, conference, sponza)");
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

/// The kitchen as a diffuse scene (issue 35's VPL goal is stated for diffuse scenes; the
/// kitchen's BART materials, imported as [`Bsdf::DiffuseGlossy`], give its floor, tiles and
/// marble a Beckmann lobe of α 0.09-0.16 and a few dark surfaces a near mirror): every
/// glossy lobe is removed, leaving the Lambertian part (textures kept; surfaces that were
/// only glossy turn black); glass stays glass, as specular paths the VPL integrator traces
/// like the path tracer.
fn make_diffuse(scene: &mut lucent_scene::Scene) {
    for m in &mut scene.materials {
        let diffuse = match &m.bsdf {
            Some(Bsdf::DiffuseGlossy { diffuse, .. }) => diffuse.clone(),
            Some(Bsdf::MetallicRoughness { base_color, transmission: FloatTex::Const(t), .. }) if *t <= 0.0 => base_color.clone(),
            _ => continue,
        };
        m.bsdf = Some(Bsdf::Diffuse { reflectance: diffuse });
    }
}

fn settings(size: (u32, u32), spp: u32, integrator: Integrator) -> RenderSettings {
    RenderSettings { spp, integrator, ..RenderSettings::new(size.0, size.1) }
}

/// The seed of the path-traced references: not the images' (the default), so that their
/// errors are independent. With the same seed a 64-sample image is the reference's own
/// first 64 samples, and its relMSE against it comes out at about 3/5 of the true figure
/// (σ²(1/64 − 1/256) instead of σ²(1/64 + 1/256)): until stop 49 the raw 64-sample figures
/// were measured that way.
const REFERENCE_SEED: u32 = 0x7e5e_ed01;

/// Seeds of the path tracer's images (the default seed and the next ones).
const SEEDS: u32 = 3;

/// The scenes of the frame rates, and of the quality figures.
const SPEED_SCENES: [&str; 2] = ["conference", "kitchen"];
const QUALITY_SCENES: [&str; 4] = ["cornell", "sponza", "kitchen", "kitchen-diffuse"];

/// The path-traced reference of a scene (cached).
fn reference(o: &VplOptions, name: &str, w: &World, cam: &Camera) -> Result<Film> {
    crate::stats::cached_path_image(name, w, cam, o.size, o.reference_spp, REFERENCE_SEED)
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
    if let Some(bad) = o.only.iter().find(|n| !SPEED_SCENES.contains(&n.as_str()) && !QUALITY_SCENES.contains(&n.as_str())) {
        bail!("--only: unknown scene '{bad}' (speed: {}; quality: {})", SPEED_SCENES.join(", "), QUALITY_SCENES.join(", "));
    }
    let pool = crate::threads::pool(2, true)?;
    let vs = VplSettings::default();
    let (wd, ht) = o.size;
    println!("machine: 2 threads, {wd}x{ht}, {} VPLs, {}x{} interleaving, clamp {}", vs.count, vs.interleave, vs.interleave, vs.clamp);
    // Speed: VPL frames, and the rays of one frame by kind.
    for name in SPEED_SCENES.into_iter().filter(|n| o.wants(n)) {
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
        let (primary, shadow) = frame_rays(&world, &cam, &st.job(), &set);
        let (p_pk, p_1) = (rays_per_s(&world, &primary, false, false), rays_per_s(&world, &primary, false, true));
        let (s_pk, s_1) = (rays_per_s(&world, &shadow, true, false), rays_per_s(&world, &shadow, true, true));
        let nshadow: usize = shadow.iter().map(Vec::len).sum();
        // The whole frame's rays (VPL generation included), then those rays alone.
        let (_, alone) = pool.install(|| crate::stats::rays_alone(&world, || render(&world, &cam, &st, &|_| {})))?;
        println!(
            "{name:<10} VPL frame {:7.1} ms = {:5.2} fps ({}{rays} rays, {:.1} Mrays/s) | one thread: camera rays {:.1} M/s packets, {:.1} single; VPL shadow rays ({nshadow}, {:.1} per packet) {:.1} M/s packets, {:.1} single | the frame's rays alone, 2 threads: {:.1} ms = {:.2} fps at most",
            med * 1e3,
            1.0 / med,
            if animated { "posed every frame, " } else { "" },
            rays as f64 / med * 1e-6,
            p_pk * 1e-6,
            p_1 * 1e-6,
            nshadow as f64 / shadow.len().max(1) as f64,
            s_pk * 1e-6,
            s_1 * 1e-6,
            alone * 1e3,
            1.0 / alone
        );
        println!(
            "{}",
            serde_json::json!({"kind": "vpl_speed", "scene": name, "width": wd, "height": ht, "threads": 2, "vpls": vs.count,
                "median_ms": med * 1e3, "fps": 1.0 / med, "rays": rays, "animated": animated,
                "camera_mrays_s_packet": p_pk * 1e-6, "camera_mrays_s_single": p_1 * 1e-6,
                "shadow_mrays_s_packet": s_pk * 1e-6, "shadow_mrays_s_single": s_1 * 1e-6, "shadow_rays": nshadow,
                "rays_alone_ms": alone * 1e3, "fps_ceiling": 1.0 / alone})
        );
    }
    if o.speed_only {
        return Ok(());
    }
    // Quality against converged path tracing.
    for name in QUALITY_SCENES.into_iter().filter(|n| o.wants(n)) {
        let (world, desc) = load(o, name)?;
        let cam = Camera::new(&desc, wd, ht);
        let reference = pool.install(|| reference(o, name, &world, &cam))?;
        let rel = |f: &Film| f.rel_mse(&reference).unwrap_or(f64::NAN);
        let vpl = |v: VplSettings| pool.install(|| render(&world, &cam, &settings(o.size, 1, Integrator::Vpl(v)), &|_| {}).0);
        // (Each seed places other VPLs: one image's relMSE moved by a quarter when a light's
        // sampling changed; the median of SEEDS.)
        let (mut e_vpls, mut e_raws) = (vec![], vec![]);
        for k in 0..SEEDS {
            let v = VplSettings { seed: vs.seed.wrapping_add(k), ..vs };
            e_vpls.push(rel(&vpl(v)));
            e_raws.push(rel(&vpl(VplSettings { discontinuity: false, ..v })));
        }
        // The path tracer's images (4 samples denoised, 64 raw) for SEEDS seeds: the
        // kitchen's glossy floor makes rare paths of great weight, so one image's relMSE
        // depends on its seed (64 raw: 0.029-0.064 over four seeds).
        let path = |spp, seed| {
            let p = Integrator::Path(PathSettings { seed, ..PathSettings::default() });
            pool.install(|| render(&world, &cam, &settings(o.size, spp, p), &|_| {}).0)
        };
        let t = Instant::now();
        let aovs = pool.install(|| render_aovs(&world, &cam, wd, ht));
        let t_aovs = t.elapsed().as_secs_f64();
        let (mut e4, mut e4d, mut e64, mut t_den, mut drift) = (vec![], vec![], vec![], vec![], 0f64);
        let mean = |f: &Film| f.pixels.iter().map(|p| f64::from(p.x + p.y + p.z)).sum::<f64>();
        for k in 0..SEEDS {
            let seed = PathSettings::default().seed.wrapping_add(k);
            let p4 = path(4, seed);
            let t = Instant::now();
            let d4 = pool.install(|| denoise(&p4, &aovs, &DenoiseSettings::default()));
            t_den.push(t.elapsed().as_secs_f64());
            drift = drift.max((mean(&d4) / mean(&p4) - 1.0).abs());
            e4.push(rel(&p4));
            e4d.push(rel(&d4));
            e64.push(rel(&path(64, seed)));
        }
        let t_den = median(&mut t_den);
        let range = |v: &[f64]| {
            let (lo, hi) = v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
            format!("{:.4} ({lo:.4}-{hi:.4})", median(&mut v.to_vec()))
        };
        println!(
            "{name:<15} relMSE against path tracing at {} spp, median (range) of {SEEDS} seeds: VPL {} (without the discontinuity buffer {}); path 4 spp {}, denoised {} (mean within {:.2}%), 64 spp {}; denoiser {:.0} ms + guides {:.0} ms",
            o.reference_spp,
            range(&e_vpls),
            range(&e_raws),
            range(&e4),
            range(&e4d),
            drift * 100.0,
            range(&e64),
            t_den * 1e3,
            t_aovs * 1e3
        );
        println!(
            "{}",
            serde_json::json!({"kind": "vpl_quality", "scene": name, "width": wd, "height": ht, "reference_spp": o.reference_spp,
                "vpl_relmse": median(&mut e_vpls.clone()), "vpl_relmse_no_discontinuity": median(&mut e_raws.clone()),
                "vpl_relmse_seeds": e_vpls, "vpl_relmse_no_discontinuity_seeds": e_raws, "path4_relmse": e4, "path4_denoised_relmse": e4d,
                "path64_relmse": e64, "denoise_ms": t_den * 1e3, "guides_ms": t_aovs * 1e3})
        );
    }
    Ok(())
}
