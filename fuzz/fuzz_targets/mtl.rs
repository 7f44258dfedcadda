//! Fuzz target `mtl`: the harness `lucent_fuzzing::mtl` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::mtl(data));
