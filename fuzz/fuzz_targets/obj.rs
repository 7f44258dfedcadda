//! Fuzz target `obj`: the harness `lucent_fuzzing::obj` (see that crate for what it reads).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::obj(data));
