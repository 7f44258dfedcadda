//! `--compat board`: the board model against what SPEC.md says the board does.

use rend3r_isa::{assemble_words, AsmOptions, CameraTable};
use rend3r_machine::board::{directions, Board, Build};
use rend3r_machine::Step;
use std::path::PathBuf;

fn words(rel: &str, table: CameraTable) -> Vec<u32> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../../shared/rend3r/programs").join(rel);
    assemble_words(&std::fs::read_to_string(p).expect("read"), AsmOptions { camera_table: table }).expect("asm")
}

#[test]
fn pixel_directions_step_in_half_precision() {
    let (dx, dy) = directions();
    assert_eq!(dx[0].f(), -4.988_281_3);
    assert_eq!(dy[0].f(), -3.740_234_4);
    assert_eq!(dx[511].f(), 4.992_187_5, "SPEC §5: accumulated Dx[511]");
    assert_eq!(dy[383].f(), 3.740_234_4, "SPEC §5: accumulated Dy[383]");
}

#[test]
fn raytrace_rdr_on_the_board() {
    let mut b = Board::new(&words("raytracing/sw/raytrace.rdr", CameraTable::Final), Build::Raytracing, 0).expect("board");
    assert_eq!(b.processor.run_to_frame(1000), Step::Frame);
    b.frame();
    let fb = b.frame_buffer().to_vec();
    // A blue sphere (RGB565 blue bits only) in the centre. Its lit side faces the light from
    // -x, -y: on the board +y is down the screen, so the upper left is lit, the lower right
    // dark (the centre is on the terminator).
    let c = fb[(192 - 15) * 512 + 256 - 15];
    assert!(c & 0x1F > 0 && c & !0x1F == 0, "lit side {c:#06x}");
    let blue: Vec<usize> = (0..fb.len()).filter(|&i| fb[i] != 0).collect();
    let (sx, sy) = blue.iter().fold((0usize, 0usize), |(a, b), &i| (a + i % 512, b + i / 512));
    let (cx, cy) = (sx / blue.len(), sy / blue.len());
    assert!(cx < 256 && cy < 192 && cx > 200 && cy > 140, "lit region centred up-left of the middle: {cx},{cy}");
    let ul = fb[(192 - 15) * 512 + 256 - 15] & 0x1F;
    let lr = fb[(192 + 15) * 512 + 256 + 15] & 0x1F;
    assert!(ul > lr, "upper left {ul} vs lower right {lr}");
    // Background = the switches.
    assert_eq!(fb[0], 0);
    let mut b = Board::new(&words("raytracing/sw/raytrace.rdr", CameraTable::Final), Build::Raytracing, 0x0F00).expect("board");
    assert_eq!(b.processor.run_to_frame(1000), Step::Frame);
    let shown = b.frame();
    assert_eq!(b.frame_buffer()[0], 0x0F00);
    assert!(shown.get(0, 0).x > 0.9 && shown.get(0, 0).y < 0.01, "RGB444 display of the switches: red");
    assert_eq!(b.processor.run_to_frame(1000), Step::Halt);
}

#[test]
fn programs_longer_than_the_rom_loop() {
    // raytrace2.rdr is 34 words; the board keeps 32, so the final er, er are lost and the
    // PC wraps: it re-renders forever.
    let w = words("raytracing/sw/raytrace2.rdr", CameraTable::Final);
    assert_eq!(w.len(), 34);
    let mut b = Board::new(&w, Build::Raytracing, 0).expect("board");
    for _ in 0..3 {
        assert_eq!(b.processor.run_to_frame(10_000), Step::Frame);
    }
}

#[test]
fn cube_rdr_on_the_raster_board() {
    let w = words("main/sw/cube.rdr", CameraTable::Final);
    let mut b = Board::new(&w, Build::Raster, 0).expect("board");
    assert_eq!(b.processor.run_to_frame(1000), Step::Frame);
    // Eight triangle slots: triangles 8 and 9 overwrote 0 and 1 (SPEC B5).
    assert_eq!(b.processor.state.sets.len(), 8);
    let film = b.frame();
    let fb = b.frame_buffer();
    assert!(fb.contains(&0x0F0F) && fb.contains(&0x00F0), "cube colours drawn");
    assert!(fb.iter().step_by(512).all(|&c| c == 0), "column 0 is never written");
    // RGB444 display: 0x0F0F is magenta, 0x00F0 green.
    let mut seen = (false, false);
    for p in &film.pixels {
        seen.0 |= p.x > 0.9 && p.z > 0.9 && p.y < 0.01;
        seen.1 |= p.y > 0.9 && p.x < 0.01 && p.z < 0.01;
    }
    assert!(seen.0 && seen.1, "magenta and green on the display");
}
