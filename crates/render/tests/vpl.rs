//! Virtual point lights (issue 35), by content: the estimate converges to the path
//! tracer's light on the Cornell box as VPLs grow (against the converged reference the
//! path tracer is held to), clamping darkens corners only, the discontinuity buffer
//! removes the interleaving pattern and never averages across a depth or normal edge, the
//! tiled renderer gives the ray-by-ray reference's pixels, and images do not depend on the
//! thread count.

mod common;
use lucent_accel::MeshOptions;
use lucent_render::aov::Layers;
use lucent_render::integrator::vpl::{discontinuity, VplSet};
use lucent_render::{render, render_pixel, render_region, Camera, Film, Integrator, Region, RenderSettings, VplSettings, World};
use std::path::PathBuf;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba").join(rel)
}

/// Mitsuba's Cornell box (`mi.cornell_box()`, 64 × 64), its camera, and the converged
/// reference (4,096 samples per pixel; lucent's path tracer matches it, tests/mitsuba.rs).
/// (VPLs made for paths of at most 8 segments, as the scene's path integrator says.)
fn cornell() -> (World, Camera, Film) {
    let scene = lucent_scene::load_mitsuba_with(&data("cornell_box/scene.xml"), &[]).expect("scene");
    let hints = scene.hints.expect("hints");
    let cam = Camera::new(&scene.camera.expect("camera"), hints.width, hints.height);
    let reference = Film::load(&data("cornell_box/reference_4096spp.exr")).expect("reference");
    (World::new(scene, MeshOptions::default()).expect("world"), cam, reference)
}

fn vpl(w: &World, cam: &Camera, spp: u32, v: VplSettings) -> Film {
    let (width, height) = cam.size();
    let v = VplSettings { max_depth: 8, ..v };
    render(w, cam, &RenderSettings { spp, integrator: Integrator::Vpl(v), ..RenderSettings::new(width, height) }, &|_| {}).0
}

/// Pixels that see no emitter (the light's own pixels are the same in every method).
fn lit_mask(reference: &Film) -> Vec<bool> {
    reference.pixels.iter().map(|p| p.max_element() < 1.0).collect()
}

fn rel_mse_masked(img: &Film, reference: &Film, mask: &[bool]) -> f64 {
    let mut s = 0.0;
    let mut n = 0.0;
    for ((a, r), &m) in img.pixels.iter().zip(&reference.pixels).zip(mask) {
        if !m {
            continue;
        }
        for k in 0..3 {
            let (a, r) = (f64::from(a[k]), f64::from(r[k]));
            s += (a - r) * (a - r) / (r * r + 0.01);
            n += 1.0;
        }
    }
    s / n
}

fn mean(img: &Film, mask: &[bool]) -> f64 {
    let v: Vec<f64> = img.pixels.iter().zip(mask).filter(|(_, &m)| m).map(|(p, _)| f64::from(p.x + p.y + p.z) / 3.0).collect();
    v.iter().sum::<f64>() / v.len() as f64
}

/// Without clamping, more VPLs bring the image to the path tracer's: relMSE (against the
/// converged reference) falls as the VPLs grow from 32 to 512 per frame, ends below
/// 0.02, and the mean is within 2% (interleaving off, so that no filter's bias shows).
#[test]
fn unclamped_vpls_converge_to_the_path_tracer() {
    let (w, cam, reference) = cornell();
    let mask = lit_mask(&reference);
    let base = VplSettings { clamp: 0.0, interleave: 1, discontinuity: false, ..VplSettings::default() };
    let mut errs = Vec::new();
    for count in [32, 128, 512] {
        let img = vpl(&w, &cam, 4, VplSettings { count, ..base });
        errs.push(rel_mse_masked(&img, &reference, &mask));
        if count == 512 {
            let (m, r) = (mean(&img, &mask), mean(&reference, &mask));
            assert!((m / r - 1.0).abs() < 0.02, "mean {m} against the path tracer's {r}");
        }
    }
    assert!(errs[0] > errs[1] && errs[1] > errs[2], "relMSE must fall with more VPLs: {errs:?}");
    assert!(errs[2] < 0.02, "512 VPLs x 4 frames: relMSE {errs:?}");
}

/// Clamping removes light only near VPLs: on the back wall's centre (far from the other
/// surfaces) the clamped image equals the unclamped one within 3%, while a corner where
/// three walls meet is darker by more than that.
#[test]
fn clamping_darkens_corners_only() {
    let (w, cam, _) = cornell();
    let base = VplSettings { count: 512, interleave: 1, discontinuity: false, ..VplSettings::default() };
    let clamped = vpl(&w, &cam, 8, VplSettings { clamp: 0.08, ..base });
    let free = vpl(&w, &cam, 8, VplSettings { clamp: 0.0, ..base });
    // 3 × 3 means around a probe.
    let probe = |f: &Film, x: u32, y: u32| {
        let mut s = 0.0;
        for dy in 0..3 {
            for dx in 0..3 {
                let p = f.get(x + dx - 1, y + dy - 1);
                s += f64::from(p.x + p.y + p.z);
            }
        }
        s
    };
    let (wall_c, wall_f) = (probe(&clamped, 32, 20), probe(&free, 32, 20));
    assert!((wall_c / wall_f - 1.0).abs() < 0.03, "back wall: clamped {wall_c} against {wall_f}");
    // The top left corner of the back wall (ceiling, red wall and back wall meet).
    let (corner_c, corner_f) = (probe(&clamped, 12, 11), probe(&free, 12, 11));
    assert!(corner_c < 0.97 * corner_f, "corner: clamped {corner_c} against {corner_f}");
}

/// The interleaving pattern: the pixels of the back wall above the boxes grouped by
/// (x mod p, y mod p); the largest deviation of a group's mean from the region's, for the
/// interleaving period p = 4 against p = 3 (noise alone, the control). Without the
/// discontinuity buffer the 4-periodic groups differ far more than the control's; with
/// it, no more than noise does (the M-pixel period's energy is gone).
#[test]
fn discontinuity_buffer_removes_the_interleaving_pattern() {
    let (w, _, _) = cornell();
    let desc = w.scene().camera.expect("camera");
    let cam = Camera::new(&desc, 128, 128);
    let spread = |img: &Film, p: u32| {
        let mut groups = vec![(0.0f64, 0u32); (p * p) as usize];
        for y in 24..48 {
            for x in 52..92 {
                let c = img.get(x, y);
                let g = &mut groups[((y % p) * p + x % p) as usize];
                g.0 += f64::from(c.x + c.y + c.z);
                g.1 += 1;
            }
        }
        let means: Vec<f64> = groups.iter().map(|g| g.0 / f64::from(g.1)).collect();
        let m = means.iter().sum::<f64>() / means.len() as f64;
        means.iter().map(|s| (s / m - 1.0).abs()).fold(0.0, f64::max)
    };
    let raw = vpl(&w, &cam, 1, VplSettings { discontinuity: false, ..VplSettings::default() });
    let filtered = vpl(&w, &cam, 1, VplSettings::default());
    let (raw4, raw3) = (spread(&raw, 4), spread(&raw, 3));
    let (f4, f3) = (spread(&filtered, 4), spread(&filtered, 3));
    assert!(raw4 > 3.0 * raw3, "the raw image should show the 4-pixel pattern: {raw4} against {raw3}");
    assert!(f4 < 1.5 * f3.max(0.01), "the filtered image still shows it: {f4} against the control's {f3} (raw {raw4})");
}

/// The discontinuity buffer never averages across an edge: layers of two surfaces side by
/// side (a depth step, then a normal step), one lit and one dark, filtered: every pixel
/// keeps its own surface's value.
#[test]
fn discontinuity_buffer_keeps_edges() {
    let (wd, ht) = (16u32, 8u32);
    let r = Region::full(wd, ht, 0, 1);
    for case in 0..2 {
        let layers: Vec<Layers> = (0..wd * ht)
            .map(|i| {
                let left = i % wd < 7;
                let (depth, normal) = match (case, left) {
                    (0, true) => (2.0, glam::Vec3::Z),
                    (0, false) => (2.5, glam::Vec3::Z),
                    (_, true) => (2.0, glam::Vec3::Z),
                    (_, false) => (2.0, glam::Vec3::X),
                };
                // The lit side alternates, as interleaved sets do.
                let lit = if left { glam::Vec3::splat(if i % 2 == 0 { 0.5 } else { 1.5 }) } else { glam::Vec3::ZERO };
                Layers { lit, albedo: glam::Vec3::ONE, normal, depth, ..Layers::default() }
            })
            .collect();
        for y in 0..ht {
            for x in 0..wd {
                let v = discontinuity(&layers, r, 4, x, y);
                if x < 7 {
                    assert!(v.x > 0.4, "case {case}: lit pixel ({x}, {y}) got {v}");
                    // Away from the image's border the average is the two values' mean.
                    if (2..5).contains(&x) && (2..6).contains(&y) {
                        assert!((v.x - 1.0).abs() < 1e-5, "case {case}: ({x}, {y}) {v}");
                    }
                } else {
                    assert_eq!(v, glam::Vec3::ZERO, "case {case}: dark pixel ({x}, {y}) took light across the edge");
                }
            }
        }
    }
}

/// Dark surfaces (albedo below the filter's floor) are averaged too, in radiance, among
/// themselves: beside a bright surface of the same depth and normal, each side's
/// interleaving pattern is removed and neither side takes the other's light.
#[test]
fn discontinuity_buffer_filters_dark_surfaces_among_themselves() {
    let (wd, ht) = (16u32, 8u32);
    let r = Region::full(wd, ht, 0, 1);
    let layers: Vec<Layers> = (0..wd * ht)
        .map(|i| {
            let left = i % wd < 8;
            // Left: a black glossy surface (albedo 0.005) reflecting 0.3 on average; right:
            // albedo 0.8, demodulated light 2. Both alternate as interleaved sets do.
            let (albedo, mean) = if left { (0.005, 0.3) } else { (0.8, 2.0) };
            let lit = glam::Vec3::splat(mean * if i % 2 == 0 { 0.5 } else { 1.5 });
            Layers { lit, albedo: glam::Vec3::splat(albedo), normal: glam::Vec3::Z, depth: 2.0, ..Layers::default() }
        })
        .collect();
    for y in 2..6 {
        for x in 2..14 {
            if (6..10).contains(&x) {
                continue;
            }
            let v = discontinuity(&layers, r, 4, x, y);
            let want = if x < 8 { 0.3 } else { 2.0 };
            assert!((v.x - want).abs() < 1e-5, "({x}, {y}): {v} against {want}");
        }
    }
}

/// The tiled renderer (camera packets, shadow-ray packets from each VPL) gives the
/// ray-by-ray reference's pixels ([`render_pixel`], which makes the frame's VPLs and
/// traces every ray alone), with the discontinuity buffer off.
#[test]
fn tiled_vpl_frames_match_the_ray_by_ray_reference() {
    let (w, cam, _) = cornell();
    let v = VplSettings { discontinuity: false, ..VplSettings::default() };
    let st = RenderSettings { spp: 2, integrator: Integrator::Vpl(v), ..RenderSettings::new(64, 64) };
    let img = render(&w, &cam, &st, &|_| {}).0;
    let mut worst = 0.0f32;
    for (x, y) in [(5, 5), (32, 32), (20, 50), (50, 12), (63, 63), (40, 58), (10, 33)] {
        let a = img.get(x, y);
        let b = render_pixel(&w, &cam, &st, x, y);
        worst = worst.max(((a - b).abs() / (b.abs() + glam::Vec3::splat(1e-3))).max_element());
    }
    assert!(worst < 1e-4, "tiled and reference pixels differ by {worst}");
    // Every set gets the same number of light paths, and the VPLs are there.
    let set = VplSet::generate(&w, &v, 0);
    assert!(set.all().len() >= 256, "{} VPLs", set.all().len());
    assert!(set.paths_per_set > 0);
}

/// Regions rendered apart and merged give the whole frame's pixels, the discontinuity
/// buffer included (each region reads a margin of its neighbours' layers); and frames do
/// not depend on the thread count.
#[test]
fn vpl_regions_and_thread_counts_give_the_same_image() {
    let (w, cam, _) = cornell();
    let st = RenderSettings { spp: 2, integrator: Integrator::Vpl(VplSettings::default()), ..RenderSettings::new(64, 64) };
    let whole = render(&w, &cam, &st, &|_| {}).0;
    let mut acc = lucent_render::FilmAccumulator::new(64, 64);
    for (x0, y0) in [(0, 0), (27, 0), (0, 30), (27, 30)] {
        let r = Region { x0, y0, x1: if x0 == 0 { 27 } else { 64 }, y1: if y0 == 0 { 30 } else { 64 }, s0: 0, s1: 2 };
        acc.merge(render_region(&w, &cam, &st, r, &|_| {}).0).expect("merge");
    }
    let merged = acc.resolve(glam::Vec3::ZERO);
    let worst = whole.pixels.iter().zip(&merged.pixels).map(|(a, b)| (*a - *b).abs().max_element()).fold(0.0, f32::max);
    assert!(worst < 1e-5, "regions differ from the whole image by {worst}");
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
        let img = pool.install(|| render(&w, &cam, &st, &|_| {}).0);
        assert!(img.pixels == whole.pixels, "{threads} threads gave another image");
    }
}

/// Every build of the VPL terms' lane loops (AVX-512, AVX2, the baseline) gives the same
/// bits: the BART kitchen (MTL's Lambertian plus Beckmann lobes on lanes) and the
/// materials scene (rough plastics, conductors and others one by one), with the shadow
/// roulette and the discontinuity buffer on.
#[test]
fn every_build_of_the_vpl_terms_gives_the_same_bits() {
    use lucent_render::lanes::Level;
    let mut kitchen = World::new(lucent_scene::load(&common::scene("bart/kitchen/kitchen.gltf")).expect("kitchen"), MeshOptions::default())
        .expect("world");
    let desc = kitchen.set_time(5.0).expect("pose").expect("the kitchen has a camera");
    let kitchen_cam = Camera::new(&desc, 96, 64);
    let sc = lucent_scene::load_mitsuba_with(&data("materials/scene.xml"), &[]).expect("materials");
    let materials_cam = Camera::new(&sc.camera.expect("camera"), 96, 64);
    let materials = World::new(sc, MeshOptions::default()).expect("world");
    let st = RenderSettings {
        spp: 2,
        integrator: Integrator::Vpl(VplSettings { count: 64, ..VplSettings::default() }),
        ..RenderSettings::new(96, 64)
    };
    for (name, w, cam) in [("kitchen", &kitchen, &kitchen_cam), ("materials", &materials, &materials_cam)] {
        let mut images = Vec::new();
        for level in [Level::Portable, Level::Avx2, Level::Avx512] {
            Level::force(level);
            let img = render(w, cam, &st, &|_| {}).0;
            images.push((level, Level::current(), img.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>()));
        }
        Level::unforce();
        assert!(images[0].2.iter().any(|p| p.iter().any(|&b| f32::from_bits(b) > 0.0)), "{name}: a black image");
        for (level, ran, img) in &images[1..] {
            assert_eq!(img, &images[0].2, "{name}: {level:?} (ran as {ran:?}) against the portable build");
        }
    }
}
