//! Mitsuba's `aov` integrator and a film's alpha (issue 54): each layer lucent renders
//! (`Integrator::Aov`) against the layers Mitsuba 3.9.1 wrote for the same scene
//! (`tests/data/mitsuba/aov/`, by `tools/mitsuba/aov_reference.py`: 1,024 samples per
//! pixel, box filter). Pixels inside one surface agree to rounding; where a pixel straddles
//! an edge its mean depends on where the samples fell, so a few per cent of pixels may
//! differ there, and the channel means agree closely.

use lucent_accel::MeshOptions;
use lucent_render::{render, Camera, Integrator, RenderSettings, World};
use lucent_scene::AovKind;
use std::collections::HashMap;
use std::path::PathBuf;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba/aov").join(rel)
}

/// Every channel of an EXR, by name.
fn channels(path: &PathBuf) -> HashMap<String, Vec<f32>> {
    use exr::prelude::*;
    let img =
        read().no_deep_data().largest_resolution_level().all_channels().first_valid_layer().all_attributes().from_file(path).expect("EXR");
    img.layer_data.channel_data.list.iter().map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect())).collect()
}

#[test]
fn aov_layers_match_mitsuba() {
    let scene = lucent_scene::load_mitsuba_with(&data("scene.xml"), &[]).expect("scene");
    let outputs = scene.outputs.clone().expect("the aov integrator's outputs");
    assert_eq!(outputs.inner.as_deref(), Some("my_image"));
    assert!(outputs.alpha);
    let names: Vec<&str> = outputs.aovs.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["dd", "pos", "tex", "ng", "nn", "alb", "prim"]);
    let hints = scene.hints.expect("hints");
    let cam = Camera::new(&scene.camera.expect("camera"), hints.width, hints.height);
    let world = World::new(scene, MeshOptions::default()).expect("world");
    let want = channels(&data("layers_1024spp.exr"));
    let mut layers: Vec<(String, AovKind)> = outputs.aovs.clone();
    layers.push(("".into(), AovKind::Alpha));
    for (name, kind) in layers {
        // (Primitive indices are each renderer's own numbering of its shapes' parts.)
        if kind == AovKind::PrimIndex {
            continue;
        }
        let st = RenderSettings {
            spp: 256,
            integrator: Integrator::Aov(kind),
            filter: hints.filter,
            ..RenderSettings::new(hints.width, hints.height)
        };
        let film = render(&world, &cam, &st, &|_| {}).0;
        for (k, c) in kind.channels().iter().enumerate() {
            let key = if name.is_empty() { c.to_string() } else { format!("{name}.{c}") };
            let reference = want.get(&key).unwrap_or_else(|| panic!("the reference has no channel {key}"));
            let got: Vec<f32> = film.pixels.iter().map(|p| p[k]).collect();
            assert_eq!(got.len(), reference.len(), "{key}");
            let off = got.iter().zip(reference).filter(|(g, r)| (*g - *r).abs() > 0.02 * r.abs().max(1.0)).count();
            let frac = off as f64 / got.len() as f64;
            assert!(frac < 0.08, "{key}: {off} of {} pixels differ", got.len());
            let mean = |v: &[f32]| v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64;
            let (g, r) = (mean(&got), mean(reference));
            assert!((g - r).abs() <= 0.01 * r.abs().max(0.1), "{key}: mean {g} against Mitsuba's {r}");
        }
    }
}
