//! Fuzz target `ply`: the harness `lucent_fuzzing::ply` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::ply(data));
