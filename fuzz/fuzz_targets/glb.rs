//! Fuzz target `glb`: the harness `lucent_fuzzing::glb` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::glb(data));
