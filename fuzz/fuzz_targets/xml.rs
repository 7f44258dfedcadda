//! Fuzz target `xml`: the harness `lucent_fuzzing::mitsuba` (Mitsuba 3 XML scenes).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| lucent_fuzzing::mitsuba(data));
