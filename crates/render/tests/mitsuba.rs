//! The path tracer against Mitsuba 3, the light-transport reference (issue 34's measure):
//! relMSE = mean((x − ref)² / (ref² + 0.01)) over pixels and channels against a reference
//! Mitsuba rendered at 4,096 samples per pixel, committed with the scene it rendered
//! (`tests/data/mitsuba/<scene>/`: `scene.xml`, written by `tools/mitsuba/obj_scene.py`
//! from the same OBJ, and `reference_4096spp.exr`, by `tools/mitsuba/render.py`, seed
//! 100). At equal samples, lucent's relMSE must be at most 1.1× Mitsuba's own (its 64- and
//! 1,024-sample renders, seeds 0 and 1, measured once against the same reference and
//! recorded below): the 1,024-sample case is where a bias would show. The test needs no
//! Mitsuba.

mod common;
use common::scene;
use lucent_accel::MeshOptions;
use lucent_render::{render, Camera, Film, Integrator, PathSettings, RenderSettings, World};
use lucent_scene::CameraDesc;
use std::path::PathBuf;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba").join(rel)
}

/// The Cornell box OBJ (`shared/scenes/cornell_box`), 64×64, path traced with Mitsuba's
/// defaults (unlimited depth, roulette from depth 5, box filter).
#[test]
fn cornell_box_converges_to_mitsuba() {
    let reference = Film::load(&data("cornell_obj/reference_4096spp.exr")).expect("reference EXR");
    let (w, h) = (reference.width, reference.height);
    let world =
        World::new(lucent_scene::load(&scene("cornell_box/cornell_box.obj")).expect("cornell"), MeshOptions::default()).expect("world");
    let cam = Camera::new(&CameraDesc::from_view(&[278.0, 273.0, -800.0, 278.0, 273.0, 0.0, 0.0, 1.0, 0.0, 39.3]), w, h);
    // Mitsuba 3.9.1 llvm_ad_rgb against its own reference (tools/mitsuba/render.py).
    for (spp, mitsuba) in [(64, 0.02456), (1024, 0.00185)] {
        let st = RenderSettings { spp, integrator: Integrator::Path(PathSettings::default()), ..RenderSettings::new(w, h) };
        let img = render(&world, &cam, &st, &|_| {}).0;
        let e = img.rel_mse(&reference).expect("same size");
        assert!(e <= 1.1 * mitsuba, "{spp} spp: relMSE {e:.5}, Mitsuba's {mitsuba:.5}");
        // The means agree within 1% (no overall bias).
        for k in 0..3 {
            let sum = |f: &Film| f.pixels.iter().map(|p| f64::from(p[k])).sum::<f64>();
            let (m, r) = (sum(&img), sum(&reference));
            assert!((m / r - 1.0).abs() < 0.01, "{spp} spp, channel {k}: mean {m} against {r}");
        }
    }
}
