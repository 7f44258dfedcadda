//! `lucent bench path`: the path tracer against Mitsuba 3 on the reference scenes
//! (`crates/render/tests/data/mitsuba/<scene>/`: Mitsuba's XML, its 4,096-spp reference,
//! and `lucent.txt`, the same scene for lucent: a path under the shared scenes folder and
//! the camera). Per scene: samples per second, relMSE at 64 spp, the samples and seconds
//! lucent needs to reach Mitsuba's 64-spp relMSE, and, when `tools/mitsuba/python` runs
//! here, Mitsuba's own 64-spp render timed in the same run (its second render, after JIT
//! compilation) and the speed ratio at equal error.

use anyhow::{bail, Context, Result};
use lucent_accel::MeshOptions;
use lucent_render::{render, Camera, Film, Integrator, PathSettings, RenderSettings, World};
use lucent_scene::CameraDesc;
use std::path::Path;
use std::time::Instant;

/// Mitsuba's 64-spp render of `xml` (seconds of the second render, relMSE), when its
/// environment is here.
fn mitsuba(xml: &Path, reference: &Film) -> Option<(f64, f64)> {
    let out = std::env::temp_dir().join(format!("lucent-bench-path-{}.exr", std::process::id()));
    let o = std::process::Command::new("tools/mitsuba/python")
        .args(["tools/mitsuba/render.py"])
        .arg(xml)
        .arg(&out)
        .args(["--spp", "64"])
        .output()
        .ok()?;
    if !o.status.success() {
        tracing::warn!("Mitsuba did not run: {}", String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or(""));
        return None;
    }
    let text = String::from_utf8_lossy(&o.stdout);
    let secs: f64 = text.split("second ").nth(1)?.split(' ').next()?.parse().ok()?;
    let img = Film::load(&out).ok()?;
    let _ = std::fs::remove_file(&out);
    Some((secs, img.rel_mse(reference)?))
}

pub fn run(data: &Path, scenes_dir: &Path) -> Result<()> {
    let mut dirs: Vec<_> = std::fs::read_dir(data)
        .with_context(|| format!("{}", data.display()))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.join("lucent.txt").is_file())
        .collect();
    dirs.sort();
    if dirs.is_empty() {
        bail!("no reference scenes under {} (each needs lucent.txt, scene.xml, reference_4096spp.exr)", data.display());
    }
    println!("| scene | lucent samples/s | relMSE 64 spp (lucent / Mitsuba) | lucent spp and s to Mitsuba's 64-spp error | Mitsuba 64 spp s | x faster at equal error |");
    println!("|---|---|---|---|---|---|");
    for dir in dirs {
        let name = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let spec = std::fs::read_to_string(dir.join("lucent.txt"))?;
        let mut lines = spec.lines();
        let (Some(rel), Some(cam)) = (lines.next(), lines.next()) else {
            bail!("{}: lucent.txt needs a scene path and a camera", dir.display())
        };
        let view: Vec<f32> =
            cam.split(',').map(|v| v.trim().parse()).collect::<Result<_, _>>().with_context(|| format!("{}: camera", dir.display()))?;
        let view: [f32; 10] = view.try_into().map_err(|_| anyhow::anyhow!("{}: the camera needs ten numbers", dir.display()))?;
        let reference = Film::load(&dir.join("reference_4096spp.exr"))?;
        let (w, h) = (reference.width, reference.height);
        let world = World::new(lucent_scene::load(&scenes_dir.join(rel))?, MeshOptions::default())?;
        let camera = Camera::new(&CameraDesc::from_view(&view), w, h);
        // The median of three renders' times (the image is the same each time).
        let shot = |spp: u32| {
            let st = RenderSettings { spp, integrator: Integrator::Path(PathSettings::default()), ..RenderSettings::new(w, h) };
            let mut times = Vec::new();
            let mut f = None;
            for _ in 0..3 {
                let t = Instant::now();
                f = Some(render(&world, &camera, &st, &|_| {}).0);
                times.push(t.elapsed().as_secs_f64());
            }
            times.sort_by(f64::total_cmp);
            (times[1], f.and_then(|f| f.rel_mse(&reference)).unwrap_or(f64::INFINITY))
        };
        let _ = shot(4); // warm-up
        let (t64, e64) = shot(64);
        let rate = f64::from(w * h) * 64.0 / t64;
        let m = mitsuba(&dir.join("scene.xml"), &reference);
        let target = m.map_or(e64, |(_, e)| e);
        // The fewest samples (in steps of 4) whose relMSE reaches the target.
        let mut found = None;
        for spp in (4..=256).step_by(4) {
            let (t, e) = shot(spp);
            if e <= target {
                found = Some((spp, t));
                break;
            }
        }
        let (reach, faster) = match (found, m) {
            (Some((spp, t)), Some((ms, _))) => (format!("{spp} spp, {t:.3} s"), format!("{:.2}", ms / t)),
            (Some((spp, t)), None) => (format!("{spp} spp, {t:.3} s"), "no Mitsuba here".into()),
            (None, _) => ("not within 256 spp".into(), "-".into()),
        };
        let (ms, me) = m.map_or(("-".to_string(), "-".to_string()), |(s, e)| (format!("{s:.3}"), format!("{e:.5}")));
        println!("| {name} ({w}x{h}) | {:.3e} | {e64:.5} / {me} | {reach} | {ms} | {faster} |", rate);
        std::io::Write::flush(&mut std::io::stdout())?;
        eprintln!(
            "{}",
            serde_json::json!({"kind": "path", "scene": name, "samples_per_s": rate, "rel_mse_64": e64, "mitsuba_rel_mse_64": m.map(|x| x.1), "mitsuba_s_64": m.map(|x| x.0), "spp_to_mitsuba_64": found.map(|x| x.0), "s_to_mitsuba_64": found.map(|x| x.1)})
        );
    }
    Ok(())
}
