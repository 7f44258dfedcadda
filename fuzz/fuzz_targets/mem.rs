//! Fuzz target `mem`: the harness `lucent_fuzzing::mem` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::mem(data));
