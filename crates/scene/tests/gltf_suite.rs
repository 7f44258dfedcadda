//! Khronos's glTF-Validator test files (`../shared/scenes/gltf-validator/`), each with the
//! validator's verdict: every valid file loads (one with nothing to draw loads empty, with a
//! warning), none panics, and a refusal names the file and the JSON pointer (or container
//! part) it is about.

use std::path::{Path, PathBuf};

fn suite() -> PathBuf {
    let d = std::env::var("LUCENT_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|_| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"));
    d.join("gltf-validator/test")
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        if p.is_dir() {
            walk(&p, out);
        } else if p.extension().is_some_and(|x| x == "gltf" || x == "glb") {
            out.push(p);
        }
    }
}

/// `(file, valid, pointers of the validator's errors)` for every test file with a report.
fn cases() -> Vec<(PathBuf, bool, Vec<String>)> {
    let mut files = Vec::new();
    walk(&suite(), &mut files);
    files.sort();
    files
        .into_iter()
        .filter_map(|f| {
            let report = std::fs::read_to_string(format!("{}.report.json", f.display())).ok()?;
            let v: serde_json::Value = serde_json::from_str(&report).ok()?;
            let errors = v["issues"]["messages"]
                .as_array()?
                .iter()
                .filter(|m| m["severity"].as_u64() == Some(0))
                .map(|m| m["pointer"].as_str().unwrap_or("").to_string())
                .collect();
            Some((f, v["issues"]["numErrors"].as_u64()? == 0, errors))
        })
        .collect()
}

#[test]
fn the_validator_suite_loads_as_the_specification_says() {
    let cases = cases();
    assert!(cases.len() >= 370, "found {} cases under {}", cases.len(), suite().display());
    let mut invalid_images = 0;
    let (mut valid_ok, mut valid_bad, mut invalid_refused, mut invalid_loaded) = (0, Vec::new(), 0, Vec::new());
    for (f, valid, errors) in &cases {
        let r = std::panic::catch_unwind(|| lucent_scene::load_with(f, &lucent_scene::LoadOptions { strict: true }));
        let r = r.unwrap_or_else(|_| panic!("{}: the loader panicked", f.display()));
        match (valid, r) {
            (true, Ok(_)) => valid_ok += 1,
            (true, Err(e)) => valid_bad.push(format!("{}: {e}", f.display())),
            (false, Err(e)) => {
                let msg = e.to_string();
                assert!(msg.contains(&*f.file_name().unwrap_or_default().to_string_lossy()), "error does not name the file: {msg}");
                // Where: a JSON pointer, or the part of the container.
                if let lucent_scene::ImportError::Invalid { at, .. } = &e {
                    assert!(at.starts_with('/') || at == "JSON" || at.starts_with("GLB"), "{}: error at {at:?}: {msg}", f.display());
                }
                invalid_refused += 1;
            }
            (false, Ok(_)) => {
                // The one deliberate leniency: an image that cannot be read or decoded
                // (missing file, bad data URI, corrupt PNG) is a warning, and textures
                // using it show their plain colour, so one broken texture does not stop a
                // scene from rendering. Every other error of the validator refuses the file.
                if !errors.iter().all(|p| p.starts_with("/images/")) {
                    invalid_loaded.push(format!("{}: validator errors at {errors:?}", f.display()));
                }
                invalid_images += 1;
            }
        }
    }
    eprintln!(
        "glTF suite: {valid_ok} of {} valid files load; {invalid_refused} invalid refused, {invalid_images} invalid load with an image warning",
        valid_ok + valid_bad.len()
    );
    assert!(valid_bad.is_empty(), "{} valid files refused:\n{}", valid_bad.len(), valid_bad.join("\n"));
    assert!(invalid_loaded.is_empty(), "{} invalid files loaded:\n{}", invalid_loaded.len(), invalid_loaded.join("\n"));
}

/// By default a file that breaks a rule harmlessly still loads (CesiumMan, a Khronos
/// sample, has vertex weights that do not sum to 1); `strict` refuses it, naming where.
/// And no invalid file of the suite panics the default reader either.
#[test]
fn default_loading_reads_what_strict_refuses() {
    let man = suite().join("../../gltf_animated/CesiumMan.glb");
    let scene = lucent_scene::load(&man).expect("CesiumMan loads by default");
    assert!(!scene.instances.is_empty());
    let e = lucent_scene::load_with(&man, &lucent_scene::LoadOptions { strict: true }).expect_err("strict refuses CesiumMan");
    match e {
        lucent_scene::ImportError::Invalid { at, .. } => assert!(at.contains("WEIGHTS_0"), "refused at {at}"),
        e => panic!("unexpected error {e}"),
    }
    for (f, _, _) in cases() {
        let r = std::panic::catch_unwind(|| lucent_scene::load(&f));
        assert!(r.is_ok(), "{}: the default reader panicked", f.display());
    }
}
