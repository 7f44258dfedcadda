//! The denoiser (issue 35 part 2), by content: it keeps the image's mean (creates no
//! energy), brings a 4-sample path-traced Cornell box far closer to the converged
//! reference, keeps texture (albedo demodulation) and never blurs across a depth or
//! normal edge.

use glam::Vec3;
use lucent_accel::MeshOptions;
use lucent_render::{
    denoise, render, render_aovs, Aovs, Camera, DenoiseSettings, Film, Integrator, PathSettings, RenderSettings, VplSettings, World,
};
use std::path::PathBuf;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba").join(rel)
}

fn mean(f: &Film) -> f64 {
    f.pixels.iter().map(|p| f64::from(p.x + p.y + p.z)).sum::<f64>() / (3 * f.pixels.len()) as f64
}

/// The Cornell box at 4 samples per pixel (path traced, and with VPLs), denoised: the
/// mean within 1% of the input's, and the path-traced image's relMSE against the
/// converged reference at least 4× smaller than the raw image's.
#[test]
fn denoised_cornell_box_keeps_its_mean_and_comes_closer() {
    let scene = lucent_scene::load_mitsuba_with(&data("cornell_box/scene.xml"), &[]).expect("scene");
    let hints = scene.hints.expect("hints");
    let cam = Camera::new(&scene.camera.expect("camera"), hints.width, hints.height);
    let reference = Film::load(&data("cornell_box/reference_4096spp.exr")).expect("reference");
    let w = World::new(scene, MeshOptions::default()).expect("world");
    let aovs = render_aovs(&w, &cam, hints.width, hints.height);
    for integrator in [
        Integrator::Path(PathSettings { max_depth: 8, ..PathSettings::default() }),
        Integrator::Vpl(VplSettings { max_depth: 8, ..VplSettings::default() }),
    ] {
        let st = RenderSettings { spp: 4, integrator, ..RenderSettings::new(hints.width, hints.height) };
        let raw = render(&w, &cam, &st, &|_| {}).0;
        let den = denoise(&raw, &aovs, &DenoiseSettings::default());
        let (m0, m1) = (mean(&raw), mean(&den));
        assert!((m1 / m0 - 1.0).abs() < 0.01, "{}: mean {m1} against the input's {m0}", integrator.name());
        if matches!(integrator, Integrator::Path(_)) {
            let (e0, e1) = (raw.rel_mse(&reference).expect("size"), den.rel_mse(&reference).expect("size"));
            assert!(e1 * 4.0 < e0, "relMSE {e1} denoised against {e0} raw");
        }
    }
}

/// Guides of a synthetic picture: a checkerboard albedo (0.2 / 0.8, 4-pixel squares) on
/// a plane facing the camera (left part), and beside it (from column 20) a second surface,
/// farther away (case 0) or turned (case 1), lit ten times as much.
fn synthetic(case: u32) -> (Film, Aovs, Film) {
    let (w, h) = (32u32, 24u32);
    let n = (w * h) as usize;
    let mut albedo = Vec::with_capacity(n);
    let mut normal = Vec::with_capacity(n);
    let mut depth = Vec::with_capacity(n);
    let mut clean = Vec::with_capacity(n);
    let mut noisy = Vec::with_capacity(n);
    let mut state = 0x1234_5678u32;
    let mut rnd = || {
        state = lucent_render::pcg_hash(state);
        (state >> 8) as f32 / (1u32 << 24) as f32
    };
    for y in 0..h {
        for x in 0..w {
            let right = x >= 20;
            let a = if ((x / 4) + (y / 4)) % 2 == 0 { 0.2 } else { 0.8 };
            let light = if right { 10.0 } else { 1.0 };
            albedo.push(Vec3::splat(a));
            normal.push(if right && case == 1 { Vec3::X } else { Vec3::Z });
            depth.push(if right && case == 0 { 4.0 } else { 2.0 });
            clean.push(Vec3::splat(a * light));
            // Noise of ±50% around the true value, mean preserved.
            noisy.push(Vec3::splat(a * light * (0.5 + rnd())));
        }
    }
    let film = |pixels| Film { width: w, height: h, pixels };
    let aovs = Aovs { albedo: film(albedo), normal: film(normal), depth, emission: film(vec![Vec3::ZERO; n]) };
    (film(noisy), aovs, film(clean))
}

/// Texture and edges survive: on the synthetic picture the denoised image is much
/// closer to the clean one than the noisy input (the checkerboard is not blurred: it is
/// divided out and multiplied back), and no pixel of the dim surface takes light from the
/// bright one across the depth or normal edge.
#[test]
fn denoiser_keeps_texture_and_edges() {
    for case in 0..2 {
        let (noisy, aovs, clean) = synthetic(case);
        let den = denoise(&noisy, &aovs, &DenoiseSettings::default());
        let err = |f: &Film| f.pixels.iter().zip(&clean.pixels).map(|(a, b)| f64::from(((*a - *b) / *b).abs().x)).sum::<f64>();
        let (e0, e1) = (err(&noisy), err(&den));
        assert!(e1 * 3.0 < e0, "case {case}: error {e1} denoised against {e0} noisy");
        for y in 0..24 {
            for x in 0..20 {
                let (d, c) = (den.get(x, y).x, clean.get(x, y).x);
                // The dim side stays within its noise's reach: ±50% at most.
                assert!(d <= 1.5 * c, "case {case}: ({x}, {y}) took light across the edge: {d} against {c}");
            }
        }
        // The checkerboard's contrast stays: its squares' means keep their ratio of 4.
        let (mut dark, mut light) = ((0.0, 0), (0.0, 0));
        for y in 0..24 {
            for x in 0..16 {
                let v = f64::from(den.get(x, y).x);
                if ((x / 4) + (y / 4)) % 2 == 0 {
                    dark.0 += v;
                    dark.1 += 1;
                } else {
                    light.0 += v;
                    light.1 += 1;
                }
            }
        }
        let ratio = (light.0 / f64::from(light.1)) / (dark.0 / f64::from(dark.1));
        assert!((ratio - 4.0).abs() < 0.2, "case {case}: checkerboard contrast {ratio}");
    }
}

/// Pixels with nothing behind them, and emitters, pass through unchanged.
#[test]
fn background_and_emitters_pass_through() {
    let (mut noisy, mut aovs, _) = synthetic(0);
    aovs.depth[5] = f32::INFINITY;
    aovs.emission.pixels[40] = Vec3::ONE;
    noisy.pixels[5] = Vec3::new(3.0, 2.0, 1.0);
    noisy.pixels[40] = Vec3::splat(7.0);
    let den = denoise(&noisy, &aovs, &DenoiseSettings::default());
    assert_eq!(den.pixels[5], noisy.pixels[5]);
    assert_eq!(den.pixels[40], noisy.pixels[40]);
}
