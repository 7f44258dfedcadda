//! Fuzz target `serialized`: the harness `lucent_fuzzing::serialized` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::serialized(data));
