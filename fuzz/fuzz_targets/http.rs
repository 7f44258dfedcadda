//! Fuzz target `http`: the harness `lucent_fuzzing::http` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::http(data));
