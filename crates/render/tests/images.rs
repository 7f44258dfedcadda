//! Rendered images, checked by content: pixel probes and known answers.

mod common;
use common::scene;
use glam::{Affine3A, Vec3};
use lucent_accel::MeshOptions;
use lucent_render::integrator::{fresnel_dielectric, refract};
use lucent_render::{render, render_region, Camera, Film, FilmAccumulator, Region, RenderSettings, Traversal, World};
use lucent_scene::{demo_scene, load, CameraDesc, Geom, Instance, Light, LightKind, Material, Scene, ShapeKind};

fn settings(w: u32, h: u32) -> RenderSettings {
    RenderSettings::new(w, h)
}

fn avg(f: &Film, x0: u32, y0: u32, x1: u32, y1: u32) -> Vec3 {
    let mut s = Vec3::ZERO;
    for y in y0..y1 {
        for x in x0..x1 {
            s += f.get(x, y);
        }
    }
    s / ((x1 - x0) * (y1 - y0)) as f32
}

fn render_scene(s: Scene, cam: CameraDesc, w: u32, h: u32) -> Film {
    let mut world = World::new(s, MeshOptions::default()).expect("world");
    world.ensure_light(cam.eye);
    render(&world, &Camera::new(&cam, w, h), &settings(w, h), &|_| {}).0
}

/// The Cornell box's published camera.
fn cornell_camera() -> CameraDesc {
    CameraDesc {
        eye: Vec3::new(278.0, 273.0, -800.0),
        look_at: Vec3::new(278.0, 273.0, 0.0),
        up: Vec3::Y,
        vfov_deg: 39.3,
        ortho_height: None,
    }
}

#[test]
fn cornell_box_probes() {
    let s = load(&scene("cornell_box/cornell_box.obj")).expect("load");
    let cam = cornell_camera();
    let f = render_scene(s, cam, 128, 128);
    // The light on the ceiling: the brightest patch, white, at the top centre.
    let light = avg(&f, 58, 16, 70, 18);
    assert!(light.min_element() > 0.95, "ceiling light {light}");
    // Red left wall, green right wall.
    let left = avg(&f, 8, 50, 14, 70);
    let right = avg(&f, 114, 50, 120, 70);
    assert!(left.x > 0.3 && left.x > 3.0 * left.y && left.x > 3.0 * left.z, "left wall {left}");
    assert!(right.y > 0.3 && right.y > 3.0 * right.x && right.y > 3.0 * right.z, "right wall {right}");
    // Shadows: the floor beside the short box's base (in its shadow, lit only by ambient) is far
    // darker than the open floor near the front.
    let open = avg(&f, 28, 118, 34, 124);
    let shadowed = avg(&f, 40, 84, 44, 88);
    assert!(open.length() > 0.5, "open floor {open}");
    assert!(shadowed.length() < 0.5 * open.length(), "shadow {shadowed} vs open floor {open}");
}

/// A glass slab in front of a red/green split wall: the refracted view is shifted sideways
/// by the thickness·sin(θi − θt)/cos θt of Snell's law.
#[test]
fn refraction_through_a_slab_shifts_the_view() {
    // Analytic pieces first.
    assert!((fresnel_dielectric(1.0, 1.0 / 1.5) - 0.04).abs() < 1e-4, "normal incidence 4%");
    assert_eq!(fresnel_dielectric(0.1, 1.5), 1.0, "total internal reflection");
    assert!(refract(Vec3::new(0.8, -0.6, 0.0), Vec3::Y, 1.5).is_none(), "TIR from glass at 53°");
    let t = refract(Vec3::new(0.6, -0.8, 0.0), Vec3::Y, 1.0 / 1.5).expect("refracts");
    assert!((t.x - 0.6 / 1.5).abs() < 1e-5, "Snell: sin θt = sin θi / n");

    // Scene: a wall at z = -11, red for x < 0 and green for x >= 0 (two boxes), and a glass
    // slab 2 thick, turned 45° about y, that every camera ray crosses obliquely.
    let mut s = Scene { ambient: Vec3::ONE, ..Scene::default() };
    s.materials.push(Material { diffuse: Vec3::ZERO, ambient: Vec3::new(1.0, 0.0, 0.0), ..Material::default() });
    s.materials.push(Material { diffuse: Vec3::ZERO, ambient: Vec3::new(0.0, 1.0, 0.0), ..Material::default() });
    s.materials.push(Material { diffuse: Vec3::ZERO, transmit: Vec3::ONE, ior: 1.5, fresnel: false, ..Material::default() });
    let bx = |t: Vec3, sc: Vec3| Affine3A::from_scale_rotation_translation(sc, glam::Quat::IDENTITY, t);
    s.instances.push(Instance {
        geom: Geom::Shape { kind: ShapeKind::Box, material: 0 },
        world_from_object: bx(Vec3::new(-50.0, 0.0, -11.0), Vec3::new(50.0, 50.0, 1.0)),
    });
    s.instances.push(Instance {
        geom: Geom::Shape { kind: ShapeKind::Box, material: 1 },
        world_from_object: bx(Vec3::new(50.0, 0.0, -11.0), Vec3::new(50.0, 50.0, 1.0)),
    });
    let slab = Affine3A::from_rotation_translation(glam::Quat::from_rotation_y(std::f32::consts::FRAC_PI_4), Vec3::new(0.0, 0.0, -5.0))
        * Affine3A::from_scale(Vec3::new(3.0, 20.0, 1.0));
    s.instances.push(Instance { geom: Geom::Shape { kind: ShapeKind::Box, material: 2 }, world_from_object: slab });
    s.lights.push(Light { kind: LightKind::Directional { direction: -Vec3::Z }, color: Vec3::ZERO, inverse_square: false });
    // Orthographic camera, rays along -z, 4 units wide (pixel x ↔ world x = (px + 0.5) / 100 - 2).
    // θi = 45°, θt = asin(sin 45° / 1.5) = 28.13°; the ray leaves parallel to itself, displaced
    // sideways (along x) by d = T sin(θi - θt) / cos θt = 0.658 towards -x, so the red/green
    // edge appears at x = +d.
    let cam = CameraDesc {
        eye: Vec3::new(0.0, 0.0, 0.0),
        look_at: Vec3::new(0.0, 0.0, -1.0),
        up: Vec3::Y,
        vfov_deg: 45.0,
        ortho_height: Some(0.04),
    };
    let f = render_scene(s, cam, 400, 4);
    // Find where red turns green.
    let row: Vec<Vec3> = (0..400).map(|x| f.get(x, 2)).collect();
    // Within the slab's face (|x| < 1.5; its rim refracts through the side faces).
    assert!(row[100].x > 0.99 && row[100].y == 0.0, "x = -1 sees red through the slab: {}", row[100]);
    let edge = (100 + row[100..350].iter().position(|c| c.y > c.x).expect("green somewhere")) as f32;
    let world_x = (edge + 0.5) / 100.0 - 2.0;
    let ti = std::f32::consts::FRAC_PI_4;
    let tt = (ti.sin() / 1.5).asin();
    let shift = 2.0 * (ti - tt).sin() / tt.cos();
    assert!((world_x - shift).abs() < 0.015, "edge seen at x = {world_x}, Snell predicts {shift}");
}

#[test]
fn mirror_shows_what_it_faces() {
    // A mirror disk facing the camera at 45° reflects a blue wall placed to the side.
    let mut s = Scene { ambient: Vec3::ONE, background: Vec3::ZERO, ..Scene::default() };
    s.materials.push(Material { diffuse: Vec3::ZERO, reflect: Vec3::ONE, ..Material::default() });
    s.materials.push(Material { diffuse: Vec3::ZERO, ambient: Vec3::new(0.0, 0.0, 1.0), ..Material::default() });
    let mirror = Affine3A::from_rotation_translation(glam::Quat::from_rotation_y(std::f32::consts::FRAC_PI_4), Vec3::new(0.0, 0.0, -5.0));
    s.instances.push(Instance { geom: Geom::Shape { kind: ShapeKind::Disk, material: 0 }, world_from_object: mirror });
    s.instances.push(Instance {
        geom: Geom::Shape { kind: ShapeKind::Box, material: 1 },
        world_from_object: Affine3A::from_scale_rotation_translation(
            Vec3::new(1.0, 10.0, 10.0),
            glam::Quat::IDENTITY,
            Vec3::new(8.0, 0.0, -5.0),
        ),
    });
    s.lights.push(Light { kind: LightKind::Directional { direction: -Vec3::Z }, color: Vec3::ZERO, inverse_square: false });
    let cam = CameraDesc { eye: Vec3::ZERO, look_at: -Vec3::Z, up: Vec3::Y, vfov_deg: 20.0, ortho_height: None };
    let f = render_scene(s, cam, 32, 32);
    let c = f.get(16, 16);
    assert!(c.z > 0.99 && c.x < 0.01, "mirror centre shows the blue wall: {c}");
    assert_eq!(f.get(0, 0), Vec3::ZERO, "corner sees the background");
}

#[test]
fn demo_scene_shows_its_parts() {
    let s = demo_scene();
    let cam = s.camera.expect("demo camera");
    let f = render_scene(s, cam, 256, 192);
    let sky = avg(&f, 0, 0, 256, 20);
    assert!(sky.z > sky.x, "blue background {sky}");
    // Red capped cylinder on the left.
    let cyl = avg(&f, 36, 80, 56, 100);
    assert!(cyl.x > 2.0 * cyl.y && cyl.x > 0.2, "red cylinder {cyl}");
    // Checkered floor: both dark and light squares in the foreground.
    let lum: Vec<f32> = (0..256).map(|x| f.get(x, 180).dot(Vec3::splat(1.0 / 3.0))).collect();
    let (lo, hi) = lum.iter().fold((f32::MAX, 0.0f32), |(a, b), &v| (a.min(v), b.max(v)));
    assert!(hi > 0.4 && hi > 4.0 * lo, "checker contrast {lo}..{hi}");
}

#[test]
fn images_do_not_depend_on_thread_count() {
    let s = demo_scene();
    let cam = s.camera.expect("demo camera");
    let world = World::new(s, MeshOptions::default()).expect("world");
    let st = RenderSettings { spp: 3, ..RenderSettings::new(96, 64) };
    let c = Camera::new(&cam, 96, 64);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool").install(|| render(&world, &c, &st, &|_| {}).0);
    let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("pool").install(|| render(&world, &c, &st, &|_| {}).0);
    assert_eq!(one.pixels, two.pixels);
}

#[test]
fn png_and_exr_round_trip() {
    let mut f = Film::new(4, 2);
    f.pixels[1] = Vec3::new(1.0, 0.5, 0.0);
    f.pixels[6] = Vec3::new(2.5, 0.0, 0.25);
    let dir = tempfile::tempdir().expect("tmp");
    let png = dir.path().join("a.png");
    let exr = dir.path().join("a.exr");
    f.save(&png).expect("png");
    f.save(&exr).expect("exr");
    let p = image::open(&png).expect("read png").to_rgb8();
    assert_eq!(p.get_pixel(1, 0).0, [255, 188, 0]);
    let e = image::open(&exr).expect("read exr").to_rgb32f();
    assert_eq!(e.get_pixel(2, 1).0, [2.5, 0.0, 0.25]);
    assert!(f.save(&dir.path().join("a.bmp2")).is_err());
}

#[test]
fn coverage_never_changes_the_picture() {
    // render() traces only the pixels the coverage marks; every pixel must equal the pixel
    // traced on its own (no coverage). The demo's sky is not covered.
    let s = demo_scene();
    let desc = s.camera.expect("camera");
    let world = World::new(s, MeshOptions::default()).expect("world");
    let (w, h) = (160, 120);
    let cam = Camera::new(&desc, w, h);
    let st = settings(w, h);
    let (film, _) = render(&world, &cam, &st, &|_| {});
    for y in 0..h {
        for x in 0..w {
            assert_eq!(film.get(x, y), lucent_render::render_pixel(&world, &cam, &st, x, y), "pixel {x},{y}");
        }
    }
    let cover = lucent_render::Coverage::of(&world, &cam).expect("the demo has bounds");
    let covered = cover.count();
    assert!(covered < u64::from(w * h) * 9 / 10 && covered > u64::from(w * h) / 4, "{covered} of {} pixels covered", w * h);
    // Blocks that list their few instances test those directly (no top-level walk): the
    // comparison above covered that path too.
    let listed = (0..h / 8)
        .flat_map(|by| (0..w / 8).map(move |bx| (bx, by)))
        .filter(|&(bx, by)| cover.block(bx, by) != 0 && cover.candidates(bx, by).is_some())
        .count();
    assert!(listed > 20, "only {listed} blocks list their instances");
}

/// One sample as a whole-image region merged alone (a pass of the viewer).
fn pass(world: &World, c: &Camera, integrator: lucent_render::Integrator, index: u32) -> (Film, u64) {
    let (w, h) = c.size();
    let st = RenderSettings { spp: if index == 0 { 1 } else { 16 }, integrator, ..RenderSettings::new(w, h) };
    let (part, rays) = render_region(world, c, &st, Region::full(w, h, index, index + 1), &|_| {});
    let mut acc = FilmAccumulator::new(w, h);
    acc.merge(part).expect("one region");
    (acc.resolve(world.scene().background), rays)
}

#[test]
fn sample_passes_match_the_renderer_and_the_integrators_differ() {
    use lucent_render::Integrator;
    let s = demo_scene();
    let cam = s.camera.expect("demo camera");
    let mut world = World::new(s, MeshOptions::default()).expect("world");
    world.ensure_light(cam.eye);
    let st = settings(96, 64);
    let c = Camera::new(&cam, 96, 64);
    // Pass 0 of the Whitted integrator is exactly the 1-sample image.
    let whole = render(&world, &c, &st, &|_| {}).0;
    let (p0, rays) = pass(&world, &c, Integrator::default(), 0);
    assert_eq!(p0.pixels, whole.pixels);
    assert!(rays > 96 * 64 / 2);
    // Later passes are jittered: different, but close on average.
    let p1 = pass(&world, &c, Integrator::default(), 1).0;
    assert_ne!(p1.pixels, whole.pixels);
    let mean = |f: &Film| f.pixels.iter().copied().sum::<Vec3>() / f.pixels.len() as f32;
    assert!((mean(&p1) - mean(&whole)).length() < 0.02);
    // Normals: unit-length directions mapped to colours; the sky keeps the background.
    let n = pass(&world, &c, Integrator::Normals, 0).0;
    let floor = n.get(48, 60);
    assert!(floor.y > 0.9, "the floor faces up: {floor}");
    assert_eq!(n.get(48, 0), whole.get(48, 0), "background");
    // Eye light: no shadows, so never darker than ambient-only shading on lit geometry.
    let e = pass(&world, &c, Integrator::EyeLight, 0).0;
    assert_ne!(e.pixels, whole.pixels);
    assert!(e.pixels.iter().all(|p| p.is_finite()));
}

/// An image cut into regions of any shape (rectangles not aligned to tiles or blocks),
/// rendered on one thread or two and merged in a shuffled order, is the image `render`
/// makes: the same bits on every traced pixel, and the background (within a rounding, as a
/// sum of samples over their count) elsewhere. Split into sample ranges too, the sums are
/// added in another order (range by range), so the image is the same bits whatever the
/// threads and arrival order, and `render`'s within a rounding.
///
/// The same for filters wider than the pixel, whose samples are splatted over the pixels
/// around (every tile traces a border of its neighbours' samples).
#[test]
fn regions_merged_in_any_order_are_the_rendered_image() {
    for filter in [
        lucent_scene::PixelFilter::Box,
        lucent_scene::PixelFilter::Gaussian { stddev: 0.5 },
        lucent_scene::PixelFilter::Lanczos { lobes: 3.0 },
    ] {
        regions_merge_with(filter);
    }
}

fn regions_merge_with(filter: lucent_scene::PixelFilter) {
    let s = demo_scene();
    let desc = s.camera.expect("demo camera");
    let world = World::new(s, MeshOptions::default()).expect("world");
    let (w, h, spp) = (77, 45, 4);
    let cam = Camera::new(&desc, w, h);
    let st = RenderSettings { spp, filter, ..RenderSettings::new(w, h) };
    let whole = render(&world, &cam, &st, &|_| {}).0;
    let cut = |samples: &[(u32, u32)]| {
        let mut regions = Vec::new();
        for &(s0, s1) in samples {
            for (y0, y1) in [(0, 13), (13, 30), (30, 45)] {
                for (x0, x1) in [(0, 5), (5, 40), (40, 77)] {
                    regions.push(Region { x0, y0, x1, y1, s0, s1 });
                }
            }
        }
        regions
    };
    let merged = |regions: &[Region], threads: usize, seed: u64| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
        let mut parts: Vec<_> = pool.install(|| regions.iter().map(|r| render_region(&world, &cam, &st, *r, &|_| {}).0).collect());
        // A seeded shuffle (later sample ranges often arrive first).
        let mut x = seed;
        for i in (1..parts.len()).rev() {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            parts.swap(i, (x >> 33) as usize % (i + 1));
        }
        let mut acc = FilmAccumulator::new(w, h);
        for p in parts {
            acc.merge(p).expect("regions are disjoint");
        }
        assert!((0..h).all(|y| (0..w).all(|x| acc.samples_at(x, y) == spp)), "every sample was added");
        acc.resolve(Vec3::ONE)
    };
    let bits = |f: &Film| f.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    // (Signed weights cancel: their sums' roundings weigh more.)
    let tol = if filter.signed() { 1e-5 } else { 1e-6 };
    let close = |a: Vec3, b: Vec3| (a - b).abs().max_element() <= tol * b.abs().max_element().max(1.0);
    for (threads, seed) in [(1usize, 3u64), (2, 11)] {
        let img = merged(&cut(&[(0, spp)]), threads, seed);
        // Every pixel, the background's too (MPI renders promise the one-process image).
        for (i, (a, b)) in img.pixels.iter().zip(&whole.pixels).enumerate() {
            assert_eq!(a.to_array().map(f32::to_bits), b.to_array().map(f32::to_bits), "{filter:?}: pixel {i} ({threads} threads)");
        }
    }
    let ranges = cut(&[(0, 1), (1, 4)]);
    let first = merged(&ranges, 1, 5);
    assert_eq!(bits(&first), bits(&merged(&ranges, 2, 17)), "{filter:?}, sample ranges: the same bits whatever the order");
    let worst = first
        .pixels
        .iter()
        .zip(&whole.pixels)
        .map(|(a, b)| (*a - *b).abs().max_element() / b.abs().max_element().max(1.0))
        .fold(0.0, f32::max);
    assert!(first.pixels.iter().zip(&whole.pixels).all(|(a, b)| close(*a, *b)), "{filter:?}: {worst}");
}

#[test]
fn sunflower_field_is_instanced_and_shows_flowers() {
    let s = lucent_scene::sunflower_scene();
    let cam = s.camera.expect("camera");
    let mut w = World::new(s, MeshOptions::default()).expect("world");
    // Memory follows the unique geometry: one plant BVH, one transform per flower.
    let (top, bottom) = w.accel().stats();
    assert!(bottom.bytes < 8 << 20 && top.bytes < 4 << 20, "BLAS {} B, TLAS {} B", bottom.bytes, top.bytes);
    let f = render(&w, &Camera::new(&cam, 128, 96), &settings(128, 96), &|_| {}).0;
    let sky = avg(&f, 0, 0, 128, 10);
    assert!(sky.z > sky.x + 0.2, "sky {sky}");
    let yellow = f.pixels.iter().filter(|p| p.x > 0.3 && p.y > 0.2 && p.z < 0.5 * p.y).count();
    assert!(yellow > 128 * 96 / 10, "{yellow} yellow petal pixels");
    // Swaying: the flowers move between times.
    w.set_time(0.0).expect("pose");
    let a = render(&w, &Camera::new(&cam, 128, 96), &settings(128, 96), &|_| {}).0;
    w.set_time(1.0).expect("pose");
    let b = render(&w, &Camera::new(&cam, 128, 96), &settings(128, 96), &|_| {}).0;
    let changed = a.pixels.iter().zip(&b.pixels).filter(|(p, q)| (**p - **q).length() > 0.05).count();
    assert!(changed > 100, "{changed} pixels changed as the field sways");
}

/// Packets (8×8 primary blocks, then each light's shadow rays) render the same picture as
/// ray-by-ray tracing: on the demo (shapes, glass, mirror, textures), on the kitchen with its
/// six lights and on the Cornell box, with several samples per pixel and odd image sizes
/// (partial blocks at the edges). Only ties between coincident surfaces may differ.
#[test]
fn packets_render_the_same_image_as_single_rays() {
    let kitchen = load(&scene("bart/kitchen/kitchen.gltf")).expect("kitchen");
    let kcam = kitchen.camera.expect("kitchen camera");
    let cornell = load(&scene("cornell_box/cornell_box.obj")).expect("cornell");
    let ccam = cornell_camera();
    let demo = demo_scene();
    let dcam = demo.camera.expect("demo camera");
    for (name, s, cam, (w, h), spp) in
        [("demo", demo, dcam, (101, 67), 2), ("kitchen", kitchen, kcam, (96, 72), 1), ("cornell", cornell, ccam, (64, 64), 1)]
    {
        let mut world = World::new(s, MeshOptions::default()).expect("world");
        world.ensure_light(cam.eye);
        let c = Camera::new(&cam, w, h);
        let mut st = settings(w, h);
        st.spp = spp;
        let (packed, rays_p) = render(&world, &c, &st, &|_| {});
        st.traversal = Traversal { packets: false };
        let (single, rays_s) = render(&world, &c, &st, &|_| {});
        assert_eq!(rays_p, rays_s, "{name}: the same rays are traced");
        let differ = packed.pixels.iter().zip(&single.pixels).filter(|(a, b)| a != b).count();
        assert!(differ * 500 <= packed.pixels.len(), "{name}: {differ} of {} pixels differ", packed.pixels.len());
    }
}

/// A crop window takes samples inside itself only (as Mitsuba's film): with a Gaussian
/// filter (reach 2 pixels), pixels 2 or more inside its edge keep the whole image's bits,
/// the edge pixels average fewer samples (and differ), pixels beyond the filter's reach
/// of it get no weight,
/// and a window over the whole image is no window. Its region rendered alone (as the CLI
/// renders a crop) gives the same window.
#[test]
fn a_crop_window_takes_samples_inside_itself_only() {
    let s = demo_scene();
    let desc = s.camera.expect("demo camera");
    let world = World::new(s, MeshOptions::default()).expect("world");
    let (w, h) = (48, 32);
    let cam = Camera::new(&desc, w, h);
    let filter = lucent_scene::PixelFilter::Gaussian { stddev: 0.5 };
    let st = RenderSettings { spp: 4, filter, ..RenderSettings::new(w, h) };
    let whole = render(&world, &cam, &st, &|_| {}).0;
    let [x, y, cw, ch] = [10, 6, 20, 16];
    let windowed = RenderSettings { window: Some([x, y, cw, ch]), ..st };
    let cropped = render(&world, &cam, &windowed, &|_| {}).0;
    let (mut inner, mut edge_differs) = (0, 0);
    for py in 0..h {
        for px in 0..w {
            let (a, b) = (cropped.get(px, py), whole.get(px, py));
            let inside = (x..x + cw).contains(&px) && (y..y + ch).contains(&py);
            let near = px + 2 >= x && px < x + cw + 2 && py + 2 >= y && py < y + ch + 2;
            if !near {
                assert_eq!(a, Vec3::ZERO, "({px}, {py}) lies beyond the filter's reach of the window");
            } else if !inside {
                continue;
            } else if px >= x + 2 && px + 2 < x + cw && py >= y + 2 && py + 2 < y + ch {
                assert_eq!(a.to_array().map(f32::to_bits), b.to_array().map(f32::to_bits), "({px}, {py})");
                inner += 1;
            } else if a != b {
                edge_differs += 1;
            }
        }
    }
    assert_eq!(inner, (cw - 4) * (ch - 4));
    assert!(edge_differs > (cw + ch), "only {edge_differs} edge pixels changed");
    // The window's region alone: the same pixels.
    let region = Region { x0: x, y0: y, x1: x + cw, y1: y + ch, s0: 0, s1: 4 };
    let (part, _) = render_region(&world, &cam, &windowed, region, &|_| {});
    let mut acc = FilmAccumulator::new(w, h);
    acc.merge(part).expect("a region");
    let alone = acc.resolve(Vec3::ZERO);
    for py in y..y + ch {
        for px in x..x + cw {
            let (a, b) = (alone.get(px, py), cropped.get(px, py));
            assert!((a - b).abs().max_element() <= 1e-6 * b.abs().max_element().max(1.0), "({px}, {py}): {a} vs {b}");
        }
    }
    // A region beyond the filter's reach of the window (as an MPI rank may get): no
    // sample at all, no weight.
    let far = Region { x0: 40, y0: 0, x1: 48, y1: 4, s0: 0, s1: 4 };
    let (part, rays) = render_region(&world, &cam, &windowed, far, &|_| {});
    assert_eq!(rays, 0);
    let mut acc = FilmAccumulator::new(w, h);
    acc.merge(part).expect("a region");
    let none = acc.resolve(Vec3::ZERO);
    assert!((0..4).all(|py| (40..48).all(|px| none.get(px, py) == Vec3::ZERO)));
    let all = RenderSettings { window: Some([0, 0, w, h]), ..st };
    assert_eq!(render(&world, &cam, &all, &|_| {}).0.pixels, whole.pixels);
}
