//! `lucent bench frame`: shaded frames per second (primary rays, one shadow ray per light,
//! Phong shading; no secondary rays) on the benchmark presets, with the cameras and the
//! light of the Embree harness (`shared/bench`), packets against single rays.

use crate::stats::median;
use anyhow::{bail, Context, Result};
use lucent_accel::glam::Vec3;
use lucent_accel::MeshOptions;
use lucent_render::{render, Camera, Integrator, RenderSettings, Traversal, WhittedSettings, World};
use lucent_scene::{CameraDesc, Light, LightKind};
use std::time::Instant;

/// A benchmark preset: file under the scenes folder, camera (eye, look-at, up, vfov) and
/// SaarCOR's Table 3 frame rate at 512×384 where the paper gives one.
pub(crate) struct Preset {
    pub name: &'static str,
    pub file: &'static str,
    pub cam: [f32; 10],
    saarcor_fps: Option<f32>,
}

/// The presets of `shared/bench/compare.sh` (cameras from `shared/scenes/README.md`).
pub(crate) const PRESETS: &[Preset] = &[
    Preset {
        name: "conference",
        file: "conference/conference.obj.gz",
        cam: [1550.0, 420.0, -150.0, 300.0, 150.0, -200.0, 0.0, 1.0, 0.0, 60.0],
        saarcor_fps: Some(22.1),
    },
    Preset {
        name: "sponza",
        file: "sponza_dabrovic/sponza.obj.gz",
        cam: [-10.0, 2.5, 0.0, 0.0, 4.5, 0.0, 0.0, 1.0, 0.0, 70.0],
        saarcor_fps: None,
    },
    Preset {
        name: "kitchen",
        file: "bart/kitchen/kitchen_t0.obj.gz",
        cam: [3.75, 2.3, 3.6, 3.4365, 1.8802, 2.7482, -0.1270, 0.9074, -0.4005, 40.0],
        saarcor_fps: None,
    },
    Preset {
        name: "bunny",
        file: "stanford/bunny.ply",
        cam: [-0.0168, 0.11, 0.40, -0.0168, 0.11, -0.0015, 0.0, 1.0, 0.0, 30.0],
        saarcor_fps: None,
    },
    Preset {
        name: "museum",
        file: "bart/museum/museum5_t0.obj.gz",
        cam: [0.0, 1.6, -6.0, 0.0, 1.6, 0.0, 0.0, 1.0, 0.0, 45.0],
        saarcor_fps: None,
    },
];

/// Where the Embree harness (`shared/bench`) puts its one point light in a scene of
/// bounds `lo..hi`: above the centre of the bounds.
pub(crate) fn harness_light(lo: Vec3, hi: Vec3) -> Vec3 {
    (lo + hi) * 0.5 + Vec3::new(0.0, 0.45 * (hi - lo).y, 0.0)
}

/// Options of `bench frame`.
pub struct FrameOptions {
    pub scenes: Vec<String>,
    pub dir: std::path::PathBuf,
    pub sizes: Vec<(u32, u32)>,
    pub threads: Vec<usize>,
    pub frames: usize,
    /// Also time ray-by-ray tracing.
    pub single: bool,
    /// Pin each worker to its own CPU.
    pub pin: bool,
}

pub fn run(o: &FrameOptions) -> Result<()> {
    let table = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let mut rows = Vec::new();
    for name in &o.scenes {
        let Some(p) = PRESETS.iter().find(|p| p.name == name) else {
            bail!("unknown scene preset '{name}' (one of: {})", PRESETS.iter().map(|p| p.name).collect::<Vec<_>>().join(", "));
        };
        let path = o.dir.join(p.file);
        let scene = lucent_scene::load(&path).with_context(|| format!("cannot load the {name} preset from {}", path.display()))?;
        let (lo, hi) = scene.bounds().with_context(|| format!("{}: the scene is empty", path.display()))?;
        let mut world = World::new(scene, MeshOptions::default())?;
        let light = harness_light(lo, hi);
        world.set_lights(vec![Light { kind: LightKind::Point { position: light }, color: Vec3::ONE, inverse_square: false }]);
        let desc = CameraDesc::from_view(&p.cam);
        for &(w, h) in &o.sizes {
            let cam = Camera::new(&desc, w, h);
            for &threads in &o.threads {
                let pool = crate::threads::pool(threads, o.pin)?;
                for (api, packets) in [("packet", true), ("single", false)].into_iter().take(1 + o.single as usize) {
                    let s = RenderSettings {
                        integrator: Integrator::Whitted(WhittedSettings { max_depth: 0, shadows: true }),
                        traversal: Traversal { packets },
                        ..RenderSettings::new(w, h)
                    };
                    let (mut times, rays) = pool.install(|| {
                        let (_, rays) = render(&world, &cam, &s, &|_| {});
                        let times: Vec<f64> = (0..o.frames.max(1))
                            .map(|_| {
                                let t = Instant::now();
                                let _ = render(&world, &cam, &s, &|_| {});
                                t.elapsed().as_secs_f64()
                            })
                            .collect();
                        (times, rays)
                    });
                    let med = median(&mut times);
                    let fps = 1.0 / med;
                    let mut j = serde_json::json!({
                        "kind": "frame", "tracer": "lucent", "scene": name, "api": api, "threads": threads,
                        "width": w, "height": h, "lights": 1, "rays": rays,
                        "median_ms": med * 1e3, "fps": fps, "mrays_s": rays as f64 / med * 1e-6,
                    });
                    if let (Some(sc), true) = (p.saarcor_fps, (w, h) == (512, 384)) {
                        j["saarcor_fps"] = sc.into();
                        j["vs_saarcor"] = (fps / sc as f64).into();
                    }
                    println!("{j}");
                    rows.push(format!(
                        "{name:<11} {w}x{h} {threads} thr {api:<6}: {:7.2} ms  {fps:7.1} fps  {:6.1} Mrays/s",
                        med * 1e3,
                        rays as f64 / med * 1e-6
                    ));
                }
            }
        }
    }
    if table {
        for r in rows {
            eprintln!("{r}");
        }
    }
    Ok(())
}
