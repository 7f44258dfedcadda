//! The lane integrator's stage clocks (`lucent bench path`'s cost table). In a file of its
//! own: collection is process-wide, and other tests' renders would be counted.

use lucent_accel::MeshOptions;
use lucent_render::{render, Camera, Film, Integrator, PathSettings, RenderSettings, World};
use std::path::PathBuf;

fn bits(f: &Film) -> Vec<[u32; 3]> {
    f.pixels.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// The stage clocks (`lucent bench path`'s cost table) count every sample once, every
/// part of the time, lanes no fuller than the wave, and leave the image as it was.
#[test]
fn the_profile_counts_the_render_and_leaves_it_alone() {
    use lucent_render::integrator::wave_profile::{self, Part};
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba/materials/scene.xml");
    let s = lucent_scene::load_mitsuba_with(&dir, &[]).expect("scene");
    let cam = Camera::new(&s.camera.expect("camera"), 40, 30);
    let w = World::new(s, MeshOptions::default()).expect("world");
    let st = RenderSettings {
        spp: 6,
        integrator: Integrator::Path(PathSettings { max_depth: 8, ..PathSettings::default() }),
        ..RenderSettings::new(40, 30)
    };
    let plain = render(&w, &cam, &st, &|_| {}).0;
    wave_profile::begin();
    let profiled = render(&w, &cam, &st, &|_| {}).0;
    let p = wave_profile::end();
    assert_eq!(bits(&plain), bits(&profiled));
    assert_eq!(p.samples, 40 * 30 * 6);
    let cap = lucent_render::integrator::wave::CAP as f64;
    assert!(p.steps > 0 && p.mean_lanes() > 1.0 && p.mean_lanes() <= cap, "{p:?}");
    assert!(p.packed_loops > 0 && p.mean_packed() >= 1.0 && p.mean_packed() <= cap, "{p:?}");
    let shares: f64 = Part::ALL.iter().map(|&q| p.share(q)).sum();
    assert!((shares - 1.0).abs() < 1e-9, "{shares}");
    for q in Part::ALL {
        assert!(p.time[q as usize] > 0, "{q:?} was never timed: {p:?}");
    }
    // Off again: nothing more is counted.
    let _ = render(&w, &cam, &st, &|_| {});
    assert_eq!(wave_profile::end(), Default::default());
}
