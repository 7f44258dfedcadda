//! Property tests: decode(encode(p)) == p, and asm(disasm(words)) == words for every
//! stream that decodes (leniently: any words at all, as long as an SE word has its SD).

use proptest::prelude::*;
use rend3r_isa::*;

fn instr() -> impl Strategy<Value = Instr> {
    prop_oneof![
        (0u32..4).prop_map(|f| Instr::Flow([Flow::End, Flow::NewRender, Flow::NewFrame, Flow::Loop][f as usize])),
        (0u8..32, any::<u16>()).prop_map(|(prop, data)| Instr::Camera { prop, data }),
        (0u8..64, 0u8..32, any::<u16>()).prop_map(|(index, prop, data)| Instr::Light { index, prop, data }),
        (0u32..(1 << 19), 0u8..32, 0u8..32, any::<u16>(), any::<u16>()).prop_map(|(index, p1, p2, d1, d2)| Instr::Set {
            index,
            p1,
            p2,
            d1,
            d2
        }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn encode_decode(prog in proptest::collection::vec(instr(), 0..40)) {
        let words = encode(&prog);
        prop_assert_eq!(decode(&words).expect("valid"), prog);
    }

    #[test]
    fn asm_disasm_any_words(mut words in proptest::collection::vec(any::<u32>(), 0..60), old in any::<bool>(), tri in any::<bool>()) {
        // Make the stream valid: an SE word at the very end gets an SD word.
        if decode_lenient(&words).is_err() {
            words.push(0);
        }
        let camera_table = if old { CameraTable::Old } else { CameraTable::Final };
        let set_table = if tri { SetTable::Triangle } else { SetTable::Shape };
        let text = disassemble(&words, DisasmOptions { camera_table, set_table }).expect("disasm");
        let again = assemble_words(&text, AsmOptions { camera_table }).map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        prop_assert_eq!(again, words);
    }

    #[test]
    fn assembler_never_panics(src in "\\PC{0,200}") {
        let _ = assemble(&src, AsmOptions::default());
    }

    #[test]
    fn decoder_never_panics(words in proptest::collection::vec(any::<u32>(), 0..64)) {
        let _ = decode(&words);
        let _ = decode_lenient(&words);
    }
}
