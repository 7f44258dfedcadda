//! `lucent bench path`: the path tracer against Mitsuba 3 on the reference scenes
//! (`crates/render/tests/data/mitsuba/<scene>/`: `scene.xml`, the file both renderers
//! read; Mitsuba's 4,096-spp reference; `mitsuba.json`, Mitsuba's own relMSE, the median
//! over seeds, from `tools/mitsuba/references.py`).
//!
//! Per scene: lucent's samples per second and its relMSE at 64 spp (the median of sixteen
//! seeds, as Mitsuba's recorded one: one render's relMSE swings with its few brightest
//! pixels; on the envmap scene eight seeds' median was 1.13× Mitsuba's where 32 seeds'
//! is 1.05×), the samples lucent needs to reach Mitsuba's 64-spp relMSE (relMSE falls as
//! 1/spp for an unbiased estimator: 64 × lucent's / Mitsuba's) and the seconds that many
//! take, measured;
//! Mitsuba's own 64-spp render timed in the same run when `tools/mitsuba/python` works
//! here (its second render, after JIT compilation), else its time recorded in
//! `mitsuba.json`; and how many times faster lucent is at equal error.
//!
//! And the ceiling of that figure with lucent's ray kernels: the rays of the equal-error
//! render (recorded on one thread) traced again alone, as they were traced (one by one or
//! in their packets), on all threads with nothing else between them. An integrator that
//! shaded, sampled and accumulated for free would still take that long; Mitsuba's time
//! over it is the most times faster lucent could be at equal error without faster
//! traversal or fewer rays.
//!
//! Then a cost table per scene, in thread-nanoseconds per sample (wall time × threads /
//! samples) of the equal-error render: the scalar path tracer (one path after another,
//! the reference) whole and less its rays alone; the lane integrator whole and part by
//! part (its stage clocks, `lucent_render::integrator::wave_profile`, shares of its own
//! profiled render scaled to its unprofiled time), with its lanes' occupancy: paths in
//! flight per step (of 64) and lanes per BSDF loop.

use crate::stats::{median, rays_alone};
use anyhow::{bail, Context, Result};
use lucent_accel::MeshOptions;
use lucent_render::integrator::wave_profile::{self, Part, WaveProfile};
use lucent_render::{render, Camera, Film, Integrator, PathSettings, RenderSettings, World};
use std::path::Path;
use std::time::Instant;

/// Seconds of Mitsuba's second 64-spp render of `xml`, when its environment runs here.
fn mitsuba_seconds(xml: &Path, defines: &[(String, String)]) -> Option<f64> {
    let out = std::env::temp_dir().join(format!("lucent-bench-path-{}.exr", std::process::id()));
    let mut cmd = std::process::Command::new("tools/mitsuba/python");
    cmd.args(["tools/mitsuba/render.py"]).arg(xml).arg(&out).args(["--spp", "64"]);
    for (k, v) in defines {
        cmd.arg("-D").arg(format!("{k}={v}"));
    }
    let o = cmd.output().ok()?;
    let _ = std::fs::remove_file(&out);
    if !o.status.success() {
        tracing::warn!("Mitsuba did not run: {}", String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or(""));
        return None;
    }
    let text = String::from_utf8_lossy(&o.stdout);
    text.split("second ").nth(1)?.split(' ').next()?.parse().ok()
}

pub fn run(data: &Path, scenes_dir: &Path, only: &[String]) -> Result<()> {
    let mut dirs: Vec<_> = std::fs::read_dir(data)
        .with_context(|| format!("{}", data.display()))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.join("scene.xml").is_file() && p.join("mitsuba.json").is_file())
        .filter(|p| only.is_empty() || p.file_name().is_some_and(|n| only.iter().any(|o| n == o.as_str())))
        .collect();
    dirs.sort();
    if dirs.is_empty() {
        bail!(
            "no reference scenes under {} (each needs scene.xml, mitsuba.json, reference_4096spp.exr){}",
            data.display(),
            if only.is_empty() { String::new() } else { format!(" named {}", only.join(", ")) }
        );
    }
    println!(
        "machine: {} threads, lane loops {:?} (LUCENT_LANES=avx512|avx2|portable to choose)",
        rayon::current_num_threads(),
        lucent_render::lanes::Level::current()
    );
    println!(
        "| scene | lucent samples/s | relMSE 64 spp, median (lucent / Mitsuba) | lucent spp, s to Mitsuba's 64-spp error | Mitsuba 64 spp s | x faster at equal error | rays/sample, their s alone | ceiling x |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut costs = Vec::new();
    for dir in dirs {
        let name = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let xml = dir.join("scene.xml");
        let text = std::fs::read_to_string(&xml).with_context(|| format!("{}", xml.display()))?;
        // (The scene resolves files against its own folder: the shared scenes, absolute.)
        let shared = std::fs::canonicalize(scenes_dir).with_context(|| format!("the shared scenes at {}", scenes_dir.display()))?;
        let defines: Vec<(String, String)> =
            if text.contains("$scenes") { vec![("scenes".into(), shared.display().to_string())] } else { Vec::new() };
        let scene = lucent_scene::load_mitsuba_with(&xml, &defines)?;
        let recorded: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("mitsuba.json"))?)?;
        let m_err = recorded["relmse_64"].as_f64().context("mitsuba.json: relmse_64")?;
        let hints = scene.hints.context("a Mitsuba scene has render hints")?;
        if hints.crop.is_some() {
            // (A test of the film's crop window, not a scene to time.)
            println!("| {name} | (a crop-window test scene: not timed) | | | | | | |");
            continue;
        }
        let desc = scene.camera.context("the scene has no sensor")?;
        let reference = Film::load(&dir.join("reference_4096spp.exr"))?;
        let (w, h) = (hints.width, hints.height);
        let world = World::new(scene, MeshOptions::default())?;
        let camera = Camera::new(&desc, w, h).with_clip(hints.clip.0, hints.clip.1);
        let settings_with = |spp: u32, seed: u32, lanes: bool| RenderSettings {
            spp,
            integrator: Integrator::Path(PathSettings {
                max_depth: hints.max_depth.unwrap_or(u32::MAX),
                rr_depth: hints.rr_depth,
                hide_emitters: hints.hide_emitters,
                seed,
                lanes,
                ..PathSettings::default()
            }),
            // (The film's filter, as Mitsuba's film reconstructs with it.)
            filter: hints.filter,
            ..RenderSettings::new(w, h)
        };
        let settings = |spp: u32, seed: u32| settings_with(spp, seed, true);
        // One render's seconds and relMSE, with the lane integrator or the scalar one.
        let shot_with = |spp: u32, seed: u32, lanes: bool| {
            let t = Instant::now();
            let f = render(&world, &camera, &settings_with(spp, seed, lanes), &|_| {}).0;
            (t.elapsed().as_secs_f64(), f.rel_mse(&reference).unwrap_or(f64::INFINITY))
        };
        let shot = |spp: u32, seed: u32| shot_with(spp, seed, true);
        let _ = shot(4, 0); // warm-up
        let runs: Vec<(f64, f64)> = (1..=16).map(|seed| shot(64, seed)).collect();
        let (t64, e64) =
            (median(&mut runs.iter().map(|r| r.0).collect::<Vec<_>>()), median(&mut runs.iter().map(|r| r.1).collect::<Vec<_>>()));
        let rate = f64::from(w * h) * 64.0 / t64;
        // Equal error: relMSE ∝ 1/spp.
        let spp_eq = ((64.0 * e64 / m_err).ceil() as u32).max(1);
        let t_eq = median(&mut (1..=3).map(|seed| shot(spp_eq, seed).0).collect::<Vec<_>>());
        // The equal-error render's rays, then those rays alone.
        let (rays, t_rays) = rays_alone(&world, || render(&world, &camera, &settings(spp_eq, 1), &|_| {}))?;
        let per_sample = rays.rays() as f64 / (f64::from(w * h) * f64::from(spp_eq));
        let live = mitsuba_seconds(&xml, &defines);
        let ms = live.or(recorded["seconds_64"].as_f64()).unwrap_or(f64::NAN);
        let source = if live.is_some() { "" } else { " (recorded)" };
        println!(
            "| {name} ({w}x{h}) | {rate:.3e} | {e64:.5} / {m_err:.5} | {spp_eq} spp, {t_eq:.3} s | {ms:.3}{source} | {:.2} | {per_sample:.2}, {t_rays:.3} s | {:.2} |",
            ms / t_eq,
            ms / t_rays
        );
        std::io::Write::flush(&mut std::io::stdout())?;
        // The cost table's figures: the scalar integrator at the equal-error spp, as the
        // lane one was timed above (`t_eq`, medians of three seeds), then one profiled lane
        // render for the shares.
        let samples = f64::from(w * h) * f64::from(spp_eq);
        let thread_ns = |s: f64| s * 1e9 * rayon::current_num_threads() as f64 / samples;
        let t_scalar = median(&mut (1..=3).map(|seed| shot_with(spp_eq, seed, false).0).collect::<Vec<_>>());
        wave_profile::begin();
        std::hint::black_box(render(&world, &camera, &settings(spp_eq, 1), &|_| {}));
        let profile = wave_profile::end();
        costs.push(Cost {
            name: format!("{name} ({spp_eq} spp)"),
            scalar: thread_ns(t_scalar),
            rays: thread_ns(t_rays),
            lanes: thread_ns(t_eq),
            profile,
        });
        eprintln!(
            "{}",
            serde_json::json!({"kind": "path", "scene": name, "samples_per_s": rate, "rel_mse_64": e64, "mitsuba_rel_mse_64": m_err,
                "spp_to_mitsuba_64": spp_eq, "s_to_mitsuba_64": t_eq, "mitsuba_s_64": ms, "mitsuba_live": live.is_some(),
                "rays_per_sample": per_sample, "rays_alone_s": t_rays, "ceiling": ms / t_rays})
        );
    }
    print_costs(&costs);
    Ok(())
}

/// One scene's line of the cost table.
struct Cost {
    name: String,
    /// Thread-nanoseconds per sample: the scalar integrator, the render's rays alone, the
    /// lane integrator.
    scalar: f64,
    rays: f64,
    lanes: f64,
    profile: WaveProfile,
}

fn print_costs(costs: &[Cost]) {
    println!();
    println!("Cost per sample, thread-ns (wall time x threads / samples), equal-error renders:");
    println!(
        "| scene | scalar: whole, less its rays alone | lanes: whole | traversal (closest, shadow) | shading (surfaces, numbers, lights, scatter) | elsewhere (camera, film) | paths in flight of {} | lanes per BSDF loop, one by one % |",
        lucent_render::integrator::wave::CAP
    );
    println!("|---|---|---|---|---|---|---|---|");
    for c in costs {
        let p = &c.profile;
        let ns = |part: Part| p.share(part) * c.lanes;
        let sum = |parts: &[Part]| parts.iter().map(|&q| ns(q)).sum::<f64>();
        let shading = [Part::Surfaces, Part::Numbers, Part::Lights, Part::Scatter];
        let alone = 100.0 * p.alone_lanes as f64 / (p.alone_lanes + p.packed_lanes).max(1) as f64;
        println!(
            "| {} | {:.0}, {:.0} | {:.0} | {:.0} ({:.0}, {:.0}) | {:.0} ({:.0}, {:.0}, {:.0}, {:.0}) | {:.0} ({:.0}, {:.0}) | {:.1} | {:.1}, {alone:.1} |",
            c.name,
            c.scalar,
            c.scalar - c.rays,
            c.lanes,
            ns(Part::ClosestHits) + ns(Part::ShadowRays),
            ns(Part::ClosestHits),
            ns(Part::ShadowRays),
            sum(&shading),
            ns(Part::Surfaces),
            ns(Part::Numbers),
            ns(Part::Lights),
            ns(Part::Scatter),
            ns(Part::Camera) + ns(Part::Film),
            ns(Part::Camera),
            ns(Part::Film),
            p.mean_lanes(),
            p.mean_packed(),
        );
        eprintln!(
            "{}",
            serde_json::json!({"kind": "path_cost", "scene": c.name, "scalar_ns": c.scalar, "rays_alone_ns": c.rays, "lanes_ns": c.lanes,
                "parts_ns": Part::ALL.iter().map(|&q| (format!("{q:?}"), ns(q))).collect::<std::collections::BTreeMap<_, _>>(),
                "samples_profiled": p.samples, "mean_lanes": p.mean_lanes(), "mean_packed": p.mean_packed(), "alone_pct": alone})
        );
    }
}
