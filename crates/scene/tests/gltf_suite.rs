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

/// `(file, valid)` for every test file that has a report.
fn cases() -> Vec<(PathBuf, bool)> {
    let mut files = Vec::new();
    walk(&suite(), &mut files);
    files.sort();
    files
        .into_iter()
        .filter_map(|f| {
            let report = std::fs::read_to_string(format!("{}.report.json", f.display())).ok()?;
            let v: serde_json::Value = serde_json::from_str(&report).ok()?;
            Some((f, v["issues"]["numErrors"].as_u64()? == 0))
        })
        .collect()
}

#[test]
fn the_validator_suite_loads_as_the_specification_says() {
    let cases = cases();
    assert!(cases.len() >= 370, "found {} cases under {}", cases.len(), suite().display());
    let (mut valid_ok, mut valid_bad, mut invalid_refused, mut invalid_loaded) = (0, Vec::new(), 0, 0);
    for (f, valid) in &cases {
        let r = std::panic::catch_unwind(|| lucent_scene::load(f));
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
            (false, Ok(_)) => invalid_loaded += 1,
        }
    }
    eprintln!(
        "glTF suite: {valid_ok} of {} valid files load; {invalid_refused} invalid refused, {invalid_loaded} invalid loaded anyway",
        valid_ok + valid_bad.len()
    );
    assert!(valid_bad.is_empty(), "{} valid files refused:\n{}", valid_bad.len(), valid_bad.join("\n"));
    // Not yet every invalid file is refused: lucent checks what it reads (references,
    // sizes, formats, the node forest, key times), not all of the validator's rules
    // (quaternion norms, accessor min/max, MIME types, ...). The count may only grow.
    assert!(invalid_refused >= REFUSED_AT_LEAST, "only {invalid_refused} invalid files refused (was {REFUSED_AT_LEAST})");
}

/// Invalid files refused when this test was last tightened.
const REFUSED_AT_LEAST: usize = 169;
