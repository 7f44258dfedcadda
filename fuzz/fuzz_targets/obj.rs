//! Any text through the OBJ importer: a scene or an error, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = lucent_scene::parse_obj(std::path::Path::new("fuzz.obj"), std::path::Path::new("/nonexistent"), text);
    }
});
