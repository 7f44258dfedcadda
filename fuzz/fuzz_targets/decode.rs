//! Any bytes as big-endian words through the decoders and the disassembler.
#![no_main]
use libfuzzer_sys::fuzz_target;
use lucent_isa::*;

fuzz_target!(|data: &[u8]| {
    let words: Vec<u32> = data.chunks_exact(4).map(|c| u32::from_be_bytes([c[0], c[1], c[2], c[3]])).collect();
    let _ = decode(&words);
    if let Ok(text) = disassemble(&words, DisasmOptions::default()) {
        assert_eq!(assemble_words(&text, AsmOptions::default()).expect("disassembly assembles"), words);
    }
});
