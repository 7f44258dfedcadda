//! Every shared REND3R program assembles to its committed `.mem` byte for byte, and
//! disassembly round-trips.

use rend3r_isa::*;
use std::path::PathBuf;

fn programs() -> PathBuf {
    let d = std::env::var("LUCENT_REND3R")
        .map(PathBuf::from)
        .unwrap_or_else(|_| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../../shared/rend3r/programs"));
    assert!(d.is_dir(), "REND3R programs not found at {} (set LUCENT_REND3R)", d.display());
    d
}

/// (source, assembled, camera table) pairs from `programs/README.md`.
const PAIRS: &[(&str, &str, CameraTable)] = &[
    ("raytracing/sw/raytrace.rdr", "raytracing/data/main.mem", CameraTable::Final),
    ("main/sw/cube.rdr", "main/data/main.mem", CameraTable::Final),
    ("raytracing/sw/sphere.rdr", "taping/data/main.mem", CameraTable::Final),
    ("taping/sw/raster.rdr", "taping-min-dram/data/main.mem", CameraTable::Old),
    ("raytracing/sw/raytrace2.rdr", "derived/raytrace2.mem", CameraTable::Final),
    ("raytracing/sw/rt_spheres.rdr", "derived/rt_spheres.mem", CameraTable::Final),
    ("raytracing/sw/raster.rdr", "history/1235d11/data/main.mem", CameraTable::Final),
    ("history/8510afc/sw/raster.rdr", "history/8510afc/data/main.mem", CameraTable::Old),
    ("history/6dfc0f4/sw/raster.rdr", "history/6dfc0f4/data/main.mem", CameraTable::Old),
    ("history/afd4869/sw/raster.rdr", "history/afd4869/data/main.mem", CameraTable::Final),
    ("history/c30423a/sw/sphere.rdr", "history/c30423a/data/main.mem", CameraTable::Final),
    ("history/1235d11/sw/raster.rdr", "history/1235d11/data/main.mem", CameraTable::Final),
    ("history/0d668cd/sw/raytrace.rdr", "history/0d668cd/data/main.mem", CameraTable::Final),
    ("history/928f08c/sw/raytrace.rdr", "history/928f08c/data/main.mem", CameraTable::Final),
    ("history/0a96ea1/sw/raytrace.rdr", "history/0a96ea1/data/main.mem", CameraTable::Final),
];

fn read(rel: &str) -> String {
    std::fs::read_to_string(programs().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

#[test]
fn every_program_assembles_byte_for_byte() {
    for &(src, mem, table) in PAIRS {
        let words = assemble_words(&read(src), AsmOptions { camera_table: table }).unwrap_or_else(|e| panic!("{src}: {e}"));
        assert_eq!(to_mem(&words), read(mem), "{src} -> {mem}");
    }
    // The hand-copied file without a final newline holds the same words as c30423a.
    let words = assemble_words(&read("history/c30423a/sw/sphere.rdr"), AsmOptions::default()).expect("asm");
    assert_eq!(from_mem(&read("history/4ad5cac/data/main.mem")).expect("mem"), words);
    assert!(!read("history/4ad5cac/data/main.mem").ends_with('\n'));
}

#[test]
fn worked_example_from_the_spec() {
    let w = assemble_words("sp 0, zloc, type, -2, 1", AsmOptions::default()).expect("asm");
    assert_eq!(w, [0x0000_1B45, 0xC000_0001]);
}

#[test]
fn legacy_isa_is_recognised() {
    // d3c5f2a: the same source text, but assembled by the legacy assembler (nr = 0).
    let legacy = from_mem(&read("legacy-isa/d3c5f2a/data/main.mem")).expect("mem");
    assert!(looks_legacy(&legacy));
    let ours = assemble_words(&read("legacy-isa/d3c5f2a/sw/raster.rdr"), AsmOptions::default()).expect("asm");
    assert_ne!(ours, legacy, "lucent assembles the final ISA");
    assert_eq!(ours[0], 0x200);
    for &(_, mem, _) in PAIRS {
        assert!(!looks_legacy(&from_mem(&read(mem)).expect("mem")), "{mem} is final ISA");
    }
    // The raycast test program uses the legacy `spi` mnemonic: a clear error.
    let e = assemble(&read("legacy-isa/raycast/sw/test.rdr"), AsmOptions::default()).expect_err("legacy");
    assert!(e.msg.contains("legacy ISA"), "{e}");
}

#[test]
fn disassembly_round_trips_every_program() {
    for &(src, _, table) in PAIRS {
        let words = assemble_words(&read(src), AsmOptions { camera_table: table }).expect("asm");
        for set_table in [SetTable::Shape, SetTable::Triangle] {
            let text = disassemble(&words, DisasmOptions { camera_table: table, set_table }).expect("disasm");
            let again = assemble_words(&text, AsmOptions { camera_table: table }).unwrap_or_else(|e| panic!("{src}: {e}\n{text}"));
            assert_eq!(again, words, "{src}");
        }
    }
    let text =
        disassemble(&assemble_words(&read("raytracing/sw/raytrace.rdr"), AsmOptions::default()).expect("asm"), DisasmOptions::default())
            .expect("d");
    assert!(text.contains("sp 0, zloc, type, -2, 0x0001"), "{text}");
    assert!(text.contains("sp 0, col, zscl, 0x001f, 1"), "{text}");
}

#[test]
fn errors_say_where_and_what() {
    let e = |s: &str| assemble(s, AsmOptions::default()).expect_err(s).to_string();
    assert_eq!(e("nr\ncam xloc 1"), "2:5: 'cam' takes 2 operands: cam <prop>, <value> (found 1)");
    assert_eq!(e("lt 64, xfor, 1"), "1:4: light index 64 out of range (0..=63)");
    assert_eq!(e("sp 0, xloc, bogus, 1, 2"), "1:13: 'bogus' is not a shape property (expected one of zero, xloc, yloc, zloc, rrot, irot, jrot, krot, xscl, yscl, zscl, col, mat, type or a0..a31)");
    assert_eq!(e("sp 524288, xloc, yloc, 1, 2"), "1:4: shape index 524288 out of range (0..=524287)");
    assert_eq!(e("cam xloc, abc"), "1:11: expected a number for 'xloc', found 'abc'");
    assert_eq!(e("cam xloc, nan"), "1:11: 'xloc' needs a number, not NaN");
    assert_eq!(e("sp 0, col, type, -1, 1"), "1:18: expected an unsigned integer for col, found '-1'");
    assert_eq!(e("sp 0, col, type, 65536, 1"), "1:18: col 65536 out of range (0..=65535)");
    assert_eq!(e("  frob 1"), "1:3: unknown mnemonic 'frob' (expected er, nr, nf, lr, cam, lt, sp or tr)");
    assert!(e("cam\txloc, 1").contains("a tab is not a separator"));
    assert!(e("nf // inline").contains("'nf' takes 0 operands"));
    // Accepted: comments, case, spaces around commas, a01 is not a1.
    assert_eq!(assemble_words("// c\nNR\nCAM XLOC , 1\ncam a1, 1", AsmOptions::default()).expect("ok"), [0x200, 0x3C00_0801, 0x3C00_0801]);
    assert!(e("cam a01, 1").contains("not a camera property"));
    // Found by the fuzzer: a raw shape-set word at the end has no data word.
    assert_eq!(
        e("nr\n.word 5"),
        "2:1: .word 0x00000005 has opcode 101 (shape/triangle set), which needs a data word after it, but the program ends here"
    );
    assert_eq!(assemble_words(".word 5\n.word 0x3c000000", AsmOptions::default()).expect("SE then its SD"), [5, 0x3C00_0000]);
    // The data word may itself look like a shape set.
    assert_eq!(assemble_words(".word 5\n.word 5", AsmOptions::default()).expect("SE then its SD"), [5, 5]);
    // Found by the fuzzer (fuzz/regressions/asm/): a raw shape-set word swallows the first
    // word of the `tr` after it, whose data word is then read as a set without data.
    let msg = e(".word 5\ntr 0, x1, y1, 5267, 0.3");
    assert!(msg.starts_with("2:1: word 2 (") && msg.contains("read out of step"), "{msg}");
}

#[test]
fn decoder_errors_carry_offsets() {
    assert_eq!(decode(&[0x200, 0x1B45]), Err(DecodeError::MissingData { offset: 1, word: 0x1B45 }));
    assert_eq!(decode(&[0x200, 0x2]).map_err(|e| e.offset()), Err(1));
    assert!(matches!(decode(&[0x208]), Err(DecodeError::NonCanonical { offset: 0, .. })));
    // Leniently, unknown words are carried as raw words; a missing SD word is still an error.
    assert_eq!(decode_lenient(&[0x2, 0x400]).expect("ok"), [Instr::Raw(2), Instr::Flow(Flow::NewFrame)]);
    assert!(decode_lenient(&[0x5]).is_err());
    // The SD word is raw data whatever it looks like.
    assert_eq!(decode(&[0x1B45, 0x0000_0600]).expect("ok").len(), 1);
}
