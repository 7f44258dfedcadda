//! Fuzz target `asm`: the harness `lucent_fuzzing::asm` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::asm(data));
