//! Fuzz target `net`: the harness `lucent_fuzzing::net` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::net(data));
