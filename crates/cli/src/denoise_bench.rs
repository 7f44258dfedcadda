//! `lucent bench denoise`: the denoisers on the scenes their settings were tuned on and on
//! scenes they were never given (issue 55's method: the settings may not change after the
//! held-out figures are seen). Per scene, at the given size, against a path-traced
//! reference (cached in target/bench-cache/): the relMSE of 4 samples per pixel denoised
//! against 64 raw, and of 16 denoised against 256 raw (each the median of three seeds;
//! the goal is a ratio of at most 1.0), for the à-trous filter (the noise from the
//! neighbourhood, and from the samples' halves) and the regression denoiser (over the
//! halves), and the mean's drift; then each denoiser's time per frame at 512x384 and
//! 1024x768 on two threads.

use crate::stats::median;
use anyhow::{bail, Context, Result};
use lucent_accel::MeshOptions;
use lucent_render::denoise::regression::{denoise_halves, RegressionSettings};
use lucent_render::integrator::guides::render_features;
use lucent_render::{
    denoise, denoise_with_variance, render_aovs, render_two_halves, Camera, DenoiseSettings, Film, Integrator, PathSettings,
    RenderSettings, World,
};

use lucent_scene::CameraDesc;
use std::path::PathBuf;
use std::time::Instant;

/// What to measure.
pub struct DenoiseOptions {
    /// The shared scenes folder.
    pub dir: PathBuf,
    /// The reference scenes' folder (the held-out Mitsuba scenes).
    pub data: PathBuf,
    /// Image size of the quality figures.
    pub size: (u32, u32),
    /// Samples per pixel of the references.
    pub reference_spp: u32,
    /// Only these scenes (default: all).
    pub only: Vec<String>,
}

/// The scenes the denoiser's settings were swept on.
const TUNED: [&str; 3] = ["cornell", "sponza", "kitchen"];
/// Scenes it was never tuned on: glass and mirrors in view (demo, studio), delta lights
/// (demo, materials, bunny), textures (demo's floor), fine geometry (the 69k-triangle
/// bunny), an environment map (envmap).
const HELD_OUT: [&str; 5] = ["demo", "studio", "envmap", "materials", "bunny"];

/// The seed of the references (not the images').
const REFERENCE_SEED: u32 = 0x7e5e_ed03;
/// Seeds of the images.
const SEEDS: u32 = 3;

fn load(o: &DenoiseOptions, name: &str) -> Result<(World, CameraDesc)> {
    let mitsuba = |rel: &str| -> Result<(World, CameraDesc)> {
        let p = o.data.join(rel).join("scene.xml");
        let shared = o.dir.canonicalize().with_context(|| format!("{}", o.dir.display()))?;
        let scene = lucent_scene::load_mitsuba_with(&p, &[("scenes".into(), shared.display().to_string())])
            .with_context(|| format!("{}", p.display()))?;
        let cam = scene.camera.with_context(|| format!("{}: no camera", p.display()))?;
        Ok((World::new(scene, MeshOptions::default())?, cam))
    };
    let built_in = |scene: lucent_scene::Scene| -> Result<(World, CameraDesc)> {
        let (lo, hi) = scene.bounds().context("empty scene")?;
        let cam = scene.camera.unwrap_or_else(|| lucent_render::framing_camera(lo, hi));
        Ok((World::new(scene, MeshOptions::default())?, cam))
    };
    match name {
        "demo" => built_in(lucent_scene::demo_scene()),
        "studio" => built_in(lucent_scene::studio_scene()),
        "envmap" | "materials" | "bunny" => mitsuba(name),
        "cornell" | "sponza" | "kitchen" => crate::vpl_bench::load(
            &crate::vpl_bench::VplOptions {
                dir: o.dir.clone(),
                size: o.size,
                frames: 0,
                reference_spp: 0,
                speed_only: false,
                only: vec![],
            },
            name,
        ),
        _ => bail!("unknown scene '{name}' (tuned on: {}; held out: {})", TUNED.join(", "), HELD_OUT.join(", ")),
    }
}

/// The scene's reference (cached).
fn reference(o: &DenoiseOptions, name: &str, w: &World, cam: &Camera) -> Result<Film> {
    crate::stats::cached_path_image(&format!("denoise_{name}"), w, cam, o.size, o.reference_spp, REFERENCE_SEED)
}

/// The median of `v`.
fn med(v: &[f64]) -> f64 {
    median(&mut v.to_vec())
}

pub fn run(o: &DenoiseOptions) -> Result<()> {
    if let Some(bad) = o.only.iter().find(|n| !TUNED.contains(&n.as_str()) && !HELD_OUT.contains(&n.as_str())) {
        bail!("--only: unknown scene '{bad}' (tuned on: {}; held out: {})", TUNED.join(", "), HELD_OUT.join(", "));
    }
    let pool = crate::threads::pool(2, true)?;
    let (wd, ht) = o.size;
    println!("denoiser: {wd}x{ht}, 2 threads, references of {} samples per pixel, median of {SEEDS} seeds", o.reference_spp);
    println!(
        "Denoised: the à-trous filter with the noise estimated from each pixel's neighbourhood (spatial) and from the two halves of its samples (halves); the regression denoiser over the two halves (regression)."
    );
    println!("| set | scene | 4 spp denoised: spatial, halves, regression | 64 spp raw | ratios | 16 spp denoised: spatial, halves, regression | 256 spp raw | ratios | mean drift %: à-trous, regression |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let sets = [("tuned", &TUNED[..]), ("held out", &HELD_OUT[..])];
    let regression = RegressionSettings::default();
    for (set, names) in sets {
        for &name in names.iter().filter(|n| o.only.is_empty() || o.only.iter().any(|x| x == *n)) {
            let (world, desc) = load(o, name)?;
            let cam = Camera::new(&desc, wd, ht);
            let reference = pool.install(|| reference(o, name, &world, &cam))?;
            let rel = |f: &Film| f.rel_mse(&reference).unwrap_or(f64::NAN);
            let aovs = pool.install(|| render_aovs(&world, &cam, wd, ht));
            let feats = pool.install(|| render_features(&world, &cam, wd, ht, lucent_render::denoise::regression::FEATURE_GRID));
            let mean = |f: &Film| f.pixels.iter().map(|p| f64::from(p.x + p.y + p.z)).sum::<f64>();
            // Per sample count (4, 16): relMSE of the three denoised images and of the raw
            // one with 16 times the samples, per seed.
            let mut rows = [[vec![], vec![], vec![], vec![]], [vec![], vec![], vec![], vec![]]];
            let (mut drift, mut drift_regression) = (0f64, 0f64);
            for k in 0..SEEDS {
                let seed = PathSettings::default().seed.wrapping_add(k);
                for (row, few) in rows.iter_mut().zip([4u32, 16]) {
                    let rs = RenderSettings {
                        spp: few,
                        integrator: Integrator::Path(PathSettings { seed, ..PathSettings::default() }),
                        ..RenderSettings::new(wd, ht)
                    };
                    let two = pool.install(|| render_two_halves(&world, &cam, &rs, &|_| {})).ok().context("two halves")?;
                    let img = &two.whole;
                    let var = two.luminance_variance();
                    let d = pool.install(|| denoise(img, &aovs, &DenoiseSettings::default()));
                    let dv = pool.install(|| denoise_with_variance(img, &aovs, &DenoiseSettings::default(), &var));
                    let dr = pool.install(|| denoise_halves(&two.a, &two.b, &aovs, &feats, &regression));
                    for x in [&d, &dv] {
                        drift = drift.max((mean(x) / mean(img) - 1.0).abs());
                    }
                    drift_regression = drift_regression.max((mean(&dr) / mean(img) - 1.0).abs());
                    let raw = pool.install(|| crate::stats::path_image(&world, &cam, o.size, 16 * few, seed));
                    for (v, f) in row.iter_mut().zip([&d, &dv, &dr, &raw]) {
                        v.push(rel(f));
                    }
                }
            }
            let m = rows.clone().map(|r| r.map(|v| med(&v)));
            let cell = |r: &[f64; 4]| {
                format!("{:.4}, {:.4}, {:.4} | {:.4} | {:.2}, {:.2}, {:.2}", r[0], r[1], r[2], r[3], r[0] / r[3], r[1] / r[3], r[2] / r[3])
            };
            println!("| {set} | {name} | {} | {} | {:.2}, {:.2} |", cell(&m[0]), cell(&m[1]), drift * 100.0, drift_regression * 100.0);
            let [[d4, h4, g4, r64], [d16, h16, g16, r256]] = &rows;
            println!(
                "{}",
                serde_json::json!({"kind": "denoise_quality", "set": set, "scene": name, "width": wd, "height": ht, "reference_spp": o.reference_spp,
                    "denoised4": d4, "denoised4_halves": h4, "denoised4_regression": g4, "raw64": r64,
                    "denoised16": d16, "denoised16_halves": h16, "denoised16_regression": g16, "raw256": r256,
                    "ratio_4_64": m[0][0] / m[0][3], "ratio_4_64_halves": m[0][1] / m[0][3], "ratio_4_64_regression": m[0][2] / m[0][3],
                    "ratio_16_256": m[1][0] / m[1][3], "ratio_16_256_halves": m[1][1] / m[1][3], "ratio_16_256_regression": m[1][2] / m[1][3],
                    "mean_drift": drift, "mean_drift_regression": drift_regression})
            );
        }
    }
    // The denoiser's time per frame (its guides apart), on Sponza.
    let (world, desc) = load(o, "sponza")?;
    println!();
    println!("| size | à-trous ms (2 threads, median of 5) | its guides ms | regression ms (one run) | its guides ms |");
    println!("|---|---|---|---|---|");
    for (w, h) in [(512u32, 384u32), (1024, 768)] {
        let cam = Camera::new(&desc, w, h);
        let t = Instant::now();
        let aovs = pool.install(|| render_aovs(&world, &cam, w, h));
        let guides = t.elapsed().as_secs_f64();
        let img = pool.install(|| crate::stats::path_image(&world, &cam, (w, h), 1, 1));
        let mut times: Vec<f64> = (0..5)
            .map(|_| {
                let t = Instant::now();
                std::hint::black_box(pool.install(|| denoise(&img, &aovs, &DenoiseSettings::default())));
                t.elapsed().as_secs_f64()
            })
            .collect();
        let ms = median(&mut times) * 1e3;
        // The regression denoiser, once (seconds), on the halves of 4 samples.
        let t = Instant::now();
        let feats = pool.install(|| render_features(&world, &cam, w, h, lucent_render::denoise::regression::FEATURE_GRID));
        let feature_ms = t.elapsed().as_secs_f64() * 1e3;
        let rs = RenderSettings { spp: 4, ..RenderSettings::new(w, h) };
        let two = pool.install(|| render_two_halves(&world, &cam, &rs, &|_| {})).ok().context("two halves")?;
        let t = Instant::now();
        std::hint::black_box(pool.install(|| denoise_halves(&two.a, &two.b, &aovs, &feats, &regression)));
        let regression_ms = t.elapsed().as_secs_f64() * 1e3;
        println!("| {w}x{h} | {ms:.1} | {:.1} | {regression_ms:.0} | {feature_ms:.0} |", guides * 1e3);
        println!(
            "{}",
            serde_json::json!({"kind": "denoise_time", "width": w, "height": h, "denoise_ms": ms, "guides_ms": guides * 1e3,
                "regression_ms": regression_ms, "regression_guides_ms": feature_ms})
        );
    }
    Ok(())
}
