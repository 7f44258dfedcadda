//! Fuzz target `gltf`: the harness `lucent_fuzzing::gltf` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::gltf(data));
