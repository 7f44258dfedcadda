//! Where the shared scenes are: `$LUCENT_SCENES`, else `shared/scenes` beside the checkout.
#![allow(dead_code)]
use std::path::PathBuf;

pub fn scenes_dir() -> PathBuf {
    if let Ok(d) = std::env::var("LUCENT_SCENES") {
        return PathBuf::from(d);
    }
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes");
    assert!(d.is_dir(), "shared scenes not found at {} (set LUCENT_SCENES)", d.display());
    d
}

pub fn scene(rel: &str) -> PathBuf {
    scenes_dir().join(rel)
}
