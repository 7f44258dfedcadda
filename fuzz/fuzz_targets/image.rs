//! Fuzz target `image`: the harness `lucent_fuzzing::image` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::image(data));
