//! Fuzz target `cluster`: the harness `lucent_fuzzing::cluster` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::cluster(data));
