//! Any text through the assembler: an error or words, never a panic; and whatever
//! assembles must disassemble and reassemble to the same words.
#![no_main]
use libfuzzer_sys::fuzz_target;
use lucent_isa::*;

fuzz_target!(|data: &[u8]| {
    if let Ok(src) = std::str::from_utf8(data) {
        if let Ok(words) = assemble_words(src, AsmOptions::default()) {
            let text = disassemble(&words, DisasmOptions::default()).expect("assembled words decode");
            assert_eq!(assemble_words(&text, AsmOptions::default()).expect("disassembly assembles"), words);
        }
    }
});
