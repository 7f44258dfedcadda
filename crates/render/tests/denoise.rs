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

/// Uniform numbers in [0, 1) from a seed (a hash chain).
fn uniform(mut state: u32) -> impl FnMut() -> f32 {
    move || {
        state = lucent_render::pcg_hash(state);
        (state >> 8) as f32 / (1u32 << 24) as f32
    }
}

/// The reference Cornell box: its world, camera, Mitsuba's converged image and its size.
fn cornell_box() -> (World, Camera, Film, (u32, u32)) {
    let scene = lucent_scene::load_mitsuba_with(&data("cornell_box/scene.xml"), &[]).expect("scene");
    let hints = scene.hints.expect("hints");
    let (wd, ht) = (hints.width, hints.height);
    let cam = Camera::new(&scene.camera.expect("camera"), wd, ht);
    let reference = Film::load(&data("cornell_box/reference_4096spp.exr")).expect("reference");
    (World::new(scene, MeshOptions::default()).expect("world"), cam, reference, (wd, ht))
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

/// The noise measured from the samples' two halves: `render_halves` gives `render`'s image
/// (to the rounding of its sums' order, with a box and a Gaussian filter) and a variance whose mean is the pixels'
/// (from independent images: half the squared difference of two 4-sample images); the
/// Cornell box at 16 samples denoised with it keeps its mean and comes closer to the
/// converged image than the raw image and than the neighbourhood's estimate does.
#[test]
fn the_samples_own_variance() {
    let (w, cam, reference, (wd, ht)) = cornell_box();
    for filter in [lucent_scene::PixelFilter::Box, lucent_scene::PixelFilter::Gaussian { stddev: 0.5 }] {
        let st = RenderSettings { spp: 8, filter, integrator: Integrator::Path(PathSettings::default()), ..RenderSettings::new(wd, ht) };
        let (img, var, _) = lucent_render::render_halves(&w, &cam, &st, &|_| {});
        // (The same samples; the halves' sums are added at the end, so the last bits may
        // differ from one sum over all samples.)
        let whole = render(&w, &cam, &st, &|_| {}).0;
        let worst = img
            .pixels
            .iter()
            .zip(&whole.pixels)
            .map(|(a, b)| ((*a - *b).abs() / (b.abs() + Vec3::splat(1e-6))).max_element())
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "{filter:?}: relative difference {worst}");
        assert_eq!(var.expect("halves").len(), img.pixels.len());
    }
    // The estimate's mean against the pixels' true variance of an 8-sample mean, from two
    // independent 8-sample images: E[(x - y)²] / 2.
    let lum = |v: Vec3| 0.2126 * v.x + 0.7152 * v.y + 0.0722 * v.z;
    let st = |spp, seed| RenderSettings {
        spp,
        integrator: Integrator::Path(PathSettings { seed, ..PathSettings::default() }),
        ..RenderSettings::new(wd, ht)
    };
    let (a, var, _) = lucent_render::render_halves(&w, &cam, &st(8, 1), &|_| {});
    let b = render(&w, &cam, &st(8, 2), &|_| {}).0;
    let est: f64 = var.expect("halves").iter().map(|&v| f64::from(v)).sum();
    let truth: f64 = a.pixels.iter().zip(&b.pixels).map(|(x, y)| f64::from((lum(*x) - lum(*y)).powi(2)) / 2.0).sum();
    assert!((est / truth - 1.0).abs() < 0.25, "variance estimate {est} against {truth}");
    // Denoised with it.
    let aovs = render_aovs(&w, &cam, wd, ht);
    let (img, var, _) = lucent_render::render_halves(&w, &cam, &st(16, 3), &|_| {});
    let var = var.expect("halves");
    let den = lucent_render::denoise_with_variance(&img, &aovs, &DenoiseSettings::default(), &var);
    let spatial = denoise(&img, &aovs, &DenoiseSettings::default());
    assert!((mean(&den) / mean(&img) - 1.0).abs() < 0.01, "mean {} against {}", mean(&den), mean(&img));
    let (e_raw, e_sp, e_var) =
        (img.rel_mse(&reference).expect("size"), spatial.rel_mse(&reference).expect("size"), den.rel_mse(&reference).expect("size"));
    assert!(e_var < e_raw && e_var < e_sp, "relMSE raw {e_raw}, neighbourhood {e_sp}, samples' variance {e_var}");
    // A variance of another size is not used.
    assert_eq!(lucent_render::denoise_with_variance(&img, &aovs, &DenoiseSettings::default(), &var[1..]).pixels, spatial.pixels);
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
    let mut rnd = uniform(0x1234_5678u32);
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

/// A flat surface (albedo 0.5, light 1, ±10% noise) beside a farther one: one firefly
/// (100 times its value) on the near surface.
fn firefly_picture() -> (Film, Aovs, usize) {
    let (w, h) = (48u32, 32u32);
    let n = (w * h) as usize;
    let mut rnd = uniform(0x9e37_79b9u32);
    let mut noisy: Vec<Vec3> = (0..n).map(|_| Vec3::splat(0.5 * (0.9 + 0.2 * rnd()))).collect();
    let depth = (0..n).map(|i| if (i as u32 % w) >= 32 { 5.0 } else { 2.0 }).collect();
    let firefly = (16 * w + 24) as usize;
    noisy[firefly] *= 100.0;
    let film = |pixels| Film { width: w, height: h, pixels };
    let aovs = Aovs { albedo: film(vec![Vec3::splat(0.5); n]), normal: film(vec![Vec3::Z; n]), depth, emission: film(vec![Vec3::ZERO; n]) };
    (film(noisy), aovs, firefly)
}

/// A firefly's light is spread over its surface, not dropped: the image's sum is kept,
/// the firefly is gone (no pixel above twice the surface's value), and the farther
/// surface beyond the depth edge receives none of it.
#[test]
fn a_firefly_is_spread_over_its_surface_and_its_light_kept() {
    let (noisy, aovs, firefly) = firefly_picture();
    let den = denoise(&noisy, &aovs, &DenoiseSettings::default());
    let sum = |f: &Film| f.pixels.iter().map(|p| f64::from(p.x)).sum::<f64>();
    assert!((sum(&den) / sum(&noisy) - 1.0).abs() < 1e-4, "sum {} against {}", sum(&den), sum(&noisy));
    let top = den.pixels.iter().map(|p| p.x).fold(0.0f32, f32::max);
    assert!(top < 1.0, "brightest pixel {top} (the firefly was {})", noisy.pixels[firefly].x);
    for y in 0..32 {
        for x in 32..48 {
            let (d, o) = (den.get(x, y).x, noisy.get(x, y).x);
            assert!(d < 0.56, "({x}, {y}) beyond the edge took the firefly's light: {d} (was {o})");
        }
    }
    // Off, the firefly stays.
    let off = denoise(&noisy, &aovs, &DenoiseSettings { outlier_sigmas: 0.0, ..DenoiseSettings::default() });
    assert!(off.pixels[firefly].x > 5.0, "without outlier spreading: {}", off.pixels[firefly].x);
}

/// Dark surfaces (albedo below the filter's floor: black glossy plastic) are filtered in
/// radiance, among themselves: their noise falls, and the bright surface beside them
/// (same normal and depth) neither gives them light nor takes theirs.
#[test]
fn dark_surfaces_are_filtered_among_themselves() {
    let (w, h) = (32u32, 24u32);
    let n = (w * h) as usize;
    let mut rnd = uniform(0x0bad_cafeu32);
    // Left half: albedo 0.005 but reflecting 0.3 (a glossy highlight); right: albedo 0.8, light 0.8.
    let dark = |i: usize| (i as u32 % w) < 16;
    let clean: Vec<Vec3> = (0..n).map(|i| Vec3::splat(if dark(i) { 0.3 } else { 0.8 })).collect();
    let noisy: Vec<Vec3> = clean.iter().map(|c| *c * (0.5 + rnd())).collect();
    let film = |pixels| Film { width: w, height: h, pixels };
    let aovs = Aovs {
        albedo: film((0..n).map(|i| Vec3::splat(if dark(i) { 0.005 } else { 0.8 })).collect()),
        normal: film(vec![Vec3::Z; n]),
        depth: vec![2.0; n],
        emission: film(vec![Vec3::ZERO; n]),
    };
    let den = denoise(&film(noisy.clone()), &aovs, &DenoiseSettings::default());
    let err = |f: &[Vec3], side: bool| {
        (0..n).filter(|&i| dark(i) == side).map(|i| f64::from(((f[i] - clean[i]) / clean[i]).x.abs())).sum::<f64>()
    };
    assert!(
        err(&den.pixels, true) * 3.0 < err(&noisy, true),
        "dark side: {} denoised, {} noisy",
        err(&den.pixels, true),
        err(&noisy, true)
    );
    // Nothing crosses: each side's mean stays within its noise (±5%) of its true value.
    for side in [true, false] {
        let (s, k) = (0..n).filter(|&i| dark(i) == side).fold((0.0, 0), |(s, k), i| (s + f64::from(den.pixels[i].x), k + 1));
        let truth = if side { 0.3 } else { 0.8 };
        assert!((s / f64::from(k) / truth - 1.0).abs() < 0.05, "side {side}: mean {} against {truth}", s / f64::from(k));
    }
}

/// The guides see through mirrors and glass (issue 55): a camera looking at a smooth
/// mirror tilted 45° sees a red wall in it, so the guides of the mirror's pixels are the
/// wall's (its normal, its red albedo times the mirror's reflectance, the distance along
/// the reflected ray), not the mirror's; a pixel past the mirror's edge sees the grey
/// floor behind it directly. A nearly smooth metal (α 0.05) counts as a mirror; a glossy
/// one (α 0.3) is a surface of its own.
#[test]
fn guides_follow_mirrors_to_what_they_show() {
    let mirror = r#"<bsdf type="conductor"><string name="material" value="none"/></bsdf>"#;
    let near = r#"<bsdf type="roughconductor"><float name="alpha" value="0.05"/><string name="material" value="none"/></bsdf>"#;
    let glossy = r#"<bsdf type="roughconductor"><float name="alpha" value="0.3"/><string name="material" value="none"/></bsdf>"#;
    for bsdf in [mirror, near] {
        let aovs = mirror_scene(bsdf);
        let c = 16 * 32 + 16;
        let n = aovs.normal.pixels[c];
        assert!((n - Vec3::new(-1.0, 0.0, 0.0)).length() < 1e-3, "normal through {bsdf}: {n}");
        let a = aovs.albedo.pixels[c];
        assert!((a - Vec3::new(0.8, 0.1, 0.1)).abs().max_element() < 1e-3, "albedo through {bsdf}: {a}");
    }
    let aovs = mirror_scene(glossy);
    let n = aovs.normal.pixels[16 * 32 + 16];
    assert!((n - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-3, "a glossy metal's own normal: {n}");
    let aovs = mirror_scene(mirror);
    let at = |x: u32, y: u32| (y * 32 + x) as usize;
    let c = at(16, 16);
    // 5 to the mirror's centre, then 3 to the wall.
    let d = aovs.depth[c];
    assert!((d - 8.0).abs() < 0.05, "distance along the reflection: {d}");
    // A corner pixel misses the mirror: the grey floor straight behind, 9 away.
    let e = at(1, 1);
    let a = aovs.albedo.pixels[e];
    assert!((a - Vec3::splat(0.3)).abs().max_element() < 1e-3, "albedo past the mirror: {a}");
    assert!((aovs.normal.pixels[e] - Vec3::Z).length() < 1e-3);
}

/// The guides of a 32 × 32 view of a mirror of BSDF `bsdf` (Mitsuba XML) tilted 45° toward
/// a red wall, in front of a grey floor.
fn mirror_scene(bsdf: &str) -> Aovs {
    let dir = tempfile::tempdir().expect("tmp");
    let xml = r#"<scene version="3.0.0">
        <sensor type="perspective">
            <float name="fov" value="30"/>
            <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
            <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
        </sensor>
        <shape type="rectangle">
            <transform name="to_world"><scale value="0.8"/><rotate y="1" angle="45"/></transform>
            BSDF
        </shape>
        <shape type="rectangle">
            <transform name="to_world"><scale value="20"/><rotate y="1" angle="-90"/><translate x="3"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
        </shape>
        <shape type="rectangle">
            <transform name="to_world"><scale value="20"/><translate z="-4"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.3, 0.3, 0.3"/></bsdf>
        </shape>
        <emitter type="constant"><rgb name="radiance" value="1, 1, 1"/></emitter>
    </scene>"#
        .replace("BSDF", bsdf);
    let path = dir.path().join("mirror.xml");
    std::fs::write(&path, xml).expect("write");
    let scene = lucent_scene::load_mitsuba_with(&path, &[]).expect("scene");
    let cam = Camera::new(&scene.camera.expect("camera"), 32, 32);
    let w = World::new(scene, MeshOptions::default()).expect("world");
    render_aovs(&w, &cam, 32, 32)
}

/// The regression denoiser on the two halves of 4 samples of the 64 × 64 Cornell box: the
/// mean within 1% of the input's, the relMSE against the converged reference at most 0.6×
/// the à-trous filter's on the same samples and a sixth of the raw image's (measured:
/// 0.0041, à-trous 0.0091, raw 0.04; on so small an image the window spans a third of it;
/// at 256 × 192, `lucent bench denoise` measures 0.5× the error of 64 raw samples).
#[test]
fn regression_on_halves_beats_the_atrous_filter() {
    use lucent_render::denoise::regression::{denoise_halves, RegressionSettings};
    let (w, cam, reference, (wd, ht)) = cornell_box();
    let aovs = render_aovs(&w, &cam, wd, ht);
    let feats = lucent_render::integrator::guides::render_features(&w, &cam, wd, ht, 4);
    let st = |spp, seed| RenderSettings {
        spp,
        integrator: Integrator::Path(PathSettings { max_depth: 8, seed, ..PathSettings::default() }),
        ..RenderSettings::new(wd, ht)
    };
    let halves = lucent_render::render_two_halves(&w, &cam, &st(4, 5), &|_| {}).expect("halves");
    let den = denoise_halves(&halves.a, &halves.b, &aovs, &feats, &RegressionSettings::default());
    let atrous = denoise(&halves.whole, &aovs, &DenoiseSettings::default());
    assert!((mean(&den) / mean(&halves.whole) - 1.0).abs() < 0.01, "mean {} against {}", mean(&den), mean(&halves.whole));
    let rel = |f: &Film| f.rel_mse(&reference).expect("size");
    let (e_den, e_atrous, e_raw) = (rel(&den), rel(&atrous), rel(&halves.whole));
    assert!(e_den < 0.6 * e_atrous && e_den * 6.0 < e_raw, "relMSE regression {e_den}, à-trous {e_atrous}, raw {e_raw}");
    // The halves are the whole's samples: their mean is the whole image.
    let worst = halves
        .a
        .pixels
        .iter()
        .zip(&halves.b.pixels)
        .zip(&halves.whole.pixels)
        .map(|((a, b), c)| ((*a + *b) * 0.5 - *c).abs().max_element())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-4, "halves' mean differs from the whole by {worst}");
}
