//! Fuzz target `ws`: the harness `lucent_fuzzing::websocket` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::websocket(data));
