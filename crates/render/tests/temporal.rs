//! Temporal accumulation of moving frames (issue 55), by content: a still camera's frames
//! average exactly; a moving camera's frames, carried to where their surfaces are seen
//! now, come far closer to the converged image than one frame; a view of somewhere else
//! keeps no history; frames whose sizes disagree start afresh.

use glam::Vec3;
use lucent_accel::MeshOptions;
use lucent_render::{
    render_aovs, render_region, Camera, Film, FilmAccumulator, Integrator, PathSettings, Region, RenderSettings, Temporal, World,
};
use lucent_scene::CameraDesc;
use std::path::PathBuf;

fn world() -> (World, CameraDesc) {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba/cornell_box/scene.xml");
    let scene = lucent_scene::load_mitsuba_with(&p, &[]).expect("scene");
    let desc = scene.camera.expect("camera");
    (World::new(scene, MeshOptions::default()).expect("world"), desc)
}

/// Sample `k` (one per pixel) of the image of `of` samples per pixel.
fn frame(w: &World, cam: &Camera, k: u32, of: u32) -> Film {
    let (wd, ht) = cam.size();
    let rs = RenderSettings { spp: of, integrator: Integrator::Path(PathSettings::default()), ..RenderSettings::new(wd, ht) };
    let r = render_region(w, cam, &rs, Region::full(wd, ht, k, k + 1), &|_| {}).0;
    let mut acc = FilmAccumulator::new(wd, ht);
    acc.merge(r).expect("a region of the whole image");
    acc.resolve(w.scene().background)
}

/// `desc` turned by `deg` degrees about the vertical through its look-at point.
fn orbit(desc: &CameraDesc, deg: f32) -> CameraDesc {
    let (s, c) = deg.to_radians().sin_cos();
    let d = desc.eye - desc.look_at;
    CameraDesc { eye: desc.look_at + Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z), ..*desc }
}

#[test]
fn a_still_cameras_frames_average_exactly() {
    let (w, desc) = world();
    let cam = Camera::new(&desc, 32, 32);
    let aovs = render_aovs(&w, &cam, 32, 32);
    let mut t = Temporal::new(16.0);
    let frames: Vec<Film> = (0..6).map(|k| frame(&w, &cam, k, 6)).collect();
    let finite = aovs.depth.iter().filter(|d| d.is_finite()).count() as f64 / aovs.depth.len() as f64;
    let mut out = None;
    for (k, f) in frames.iter().enumerate() {
        let (o, stats) = t.add(&cam, f, &aovs);
        if k > 0 {
            // (Every pixel that sees a surface: the box is open toward the camera.)
            assert!((stats.kept - finite).abs() < 1e-9, "frame {k}: kept {} of {finite}", stats.kept);
        }
        out = Some(o);
    }
    let out = out.expect("frames");
    for (i, p) in out.pixels.iter().enumerate() {
        if !aovs.depth[i].is_finite() {
            continue;
        }
        let mean = frames.iter().map(|f| f.pixels[i]).fold(Vec3::ZERO, |a, b| a + b) / frames.len() as f32;
        // (Pixels that see the sky keep no history; the box is closed.)
        assert!((*p - mean).abs().max_element() <= 1e-4 * (1.0 + mean.max_element()), "pixel {i}: {p} against the mean {mean}");
    }
}

#[test]
fn moving_frames_come_closer_to_the_converged_image() {
    let (w, desc) = world();
    let size = 48;
    let mut t = Temporal::new(16.0);
    let (mut one, mut blended, mut last_desc) = (None, None, desc);
    for f in 0..12u32 {
        let d = orbit(&desc, 0.4 * f as f32);
        let cam = Camera::new(&d, size, size);
        let aovs = render_aovs(&w, &cam, size, size);
        let fresh = frame(&w, &cam, f, 12);
        let (o, stats) = t.add(&cam, &fresh, &aovs);
        if f > 0 {
            assert!(stats.kept > 0.8, "frame {f}: kept {}", stats.kept);
        }
        (one, blended, last_desc) = (Some(fresh), Some(o), d);
    }
    let cam = Camera::new(&last_desc, size, size);
    let rs = RenderSettings {
        spp: 256,
        integrator: Integrator::Path(PathSettings { seed: 99, ..PathSettings::default() }),
        ..RenderSettings::new(size, size)
    };
    let reference = lucent_render::render(&w, &cam, &rs, &|_| {}).0;
    let (e1, e2) = (one.expect("frame").rel_mse(&reference).expect("size"), blended.expect("frame").rel_mse(&reference).expect("size"));
    // (Twelve frames at a 0.4 degree step: about 12x fewer samples' noise where the
    // history holds, plus the blur of resampling it.)
    eprintln!("one frame {e1}, blended {e2}");
    assert!(e2 < 0.3 * e1, "one frame {e1}, blended {e2}");
}

#[test]
fn somewhere_else_keeps_no_history_and_sizes_may_change() {
    let (w, desc) = world();
    let cam = Camera::new(&desc, 32, 32);
    let mut t = Temporal::new(8.0);
    let a = frame(&w, &cam, 0, 2);
    t.add(&cam, &a, &render_aovs(&w, &cam, 32, 32));
    // Behind the box, looking at its back wall from outside: what the first frame saw of
    // that wall was its other side.
    let behind = CameraDesc { eye: Vec3::new(0.0, 0.0, -3.9), look_at: Vec3::new(0.0, 0.0, -2.9), ..desc };
    let cam2 = Camera::new(&behind, 32, 32);
    let b = frame(&w, &cam2, 1, 2);
    let (o, stats) = t.add(&cam2, &b, &render_aovs(&w, &cam2, 32, 32));
    assert_eq!(stats.kept, 0.0);
    assert_eq!(o.pixels, b.pixels);
    // Back at the first view at half the size (the planner's resolution changes while
    // moving): the history behind the box does not hold; the next frame's does.
    let cam3 = Camera::new(&desc, 16, 16);
    let aovs3 = render_aovs(&w, &cam3, 16, 16);
    let c = frame(&w, &cam3, 2, 4);
    let (o, stats) = t.add(&cam3, &c, &aovs3);
    assert_eq!(stats.kept, 0.0);
    assert_eq!(o.pixels, c.pixels);
    let (_, stats) = t.add(&cam, &a, &render_aovs(&w, &cam, 32, 32));
    assert!(stats.kept > 0.7, "kept {}", stats.kept);
    // Guides of another size than the frame: afresh, no panic.
    let (o, stats) = t.add(&cam, &a, &render_aovs(&w, &cam3, 16, 16));
    assert_eq!((stats.kept, o.pixels.len()), (0.0, a.pixels.len()));
}
