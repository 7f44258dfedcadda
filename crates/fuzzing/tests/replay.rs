//! Every fuzz finding kept in `fuzz/regressions/<target>/` and every shared scene, texture
//! and program file, through its target's harness (the same functions the cargo-fuzz
//! targets call), on stable: none may panic or run longer than the campaign allows.

use lucent_fuzzing::{harness, inputs, target_for, TARGETS, TIMEOUT_S};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn shared() -> PathBuf {
    std::env::var("LUCENT_SHARED").map(PathBuf::from).unwrap_or_else(|_| repo().join("../shared"))
}

fn run(target: &str, file: &Path) -> Duration {
    let h = harness(target).unwrap_or_else(|| panic!("no target {target}"));
    let data = std::fs::read(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let t0 = Instant::now();
    if std::panic::catch_unwind(|| h(&data)).is_err() {
        panic!("{target}: {} panics", file.display());
    }
    t0.elapsed()
}

/// Debug builds run several times slower than the campaign's optimized targets.
fn limit() -> Duration {
    Duration::from_secs(if cfg!(debug_assertions) { 10 * TIMEOUT_S } else { TIMEOUT_S })
}

#[test]
fn every_kept_finding_is_handled() {
    let mut n = 0;
    let dir = repo().join("fuzz/regressions");
    for (t, _) in TARGETS {
        for f in inputs(&dir.join(t)) {
            let took = run(t, &f);
            assert!(took < limit(), "{t}: {} took {took:?}", f.display());
            n += 1;
        }
    }
    // Every folder names a target (a typo would silently skip its inputs).
    for d in std::fs::read_dir(&dir).expect("fuzz/regressions").flatten() {
        let name = d.file_name().to_string_lossy().into_owned();
        assert!(harness(&name).is_some() || name.ends_with(".md"), "fuzz/regressions/{name} is no target");
    }
    eprintln!("replayed {n} kept findings");
    assert!(n > 0, "no kept finding replayed");
}

#[test]
fn every_shared_file_goes_through_its_target() {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else {
                out.push(p);
            }
        }
    }
    let mut files = Vec::new();
    walk(&shared().join("scenes"), &mut files);
    walk(&shared().join("rend3r"), &mut files);
    // The Mitsuba scenes are the repository's own (the references' sources and copies).
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    walk(&repo.join("tools/mitsuba/scenes"), &mut files);
    walk(&repo.join("crates/render/tests/data/mitsuba"), &mut files);
    files.sort();
    let mut per = std::collections::BTreeMap::<&str, usize>::new();
    for f in &files {
        // Large scenes are the scene tests' work; here the small ones, quickly.
        if std::fs::metadata(f).map_or(true, |m| m.len() > 4 << 20) {
            continue;
        }
        if let Some(t) = target_for(f) {
            run(t, f);
            *per.entry(t).or_default() += 1;
        }
    }
    eprintln!("shared files per target: {per:?}");
    for t in ["obj", "mtl", "ply", "gltf", "glb", "image", "asm", "mem", "xml", "serialized"] {
        assert!(per.get(t).is_some_and(|&n| n > 0), "no shared file for {t}: {per:?}");
    }
}
