//! Fuzz target `decode`: the harness `lucent_fuzzing::decode` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::decode(data));
