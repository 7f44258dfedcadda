//! REND3R programs with NaN and infinite half floats, zero scales and zero quaternions
//! (shapes, triangles, lights, the camera) never break a frame: every frame renders, in
//! both modes, with finite pixels. The assembler refuses `nan` (a clear error at its line
//! and column), but binary programs (`.mem`, the network) can hold any bits: the programs
//! here are assembled with placeholders (1000 for NaN, ±2000 for ±infinity) whose half-float
//! bits are then replaced.

use rend3r_isa::{assemble_words, AsmOptions, CameraTable};
use rend3r_machine::*;

fn frames(src: &str, mode: Mode, sets: SetKind) -> usize {
    let src = src.replace("nan", "1000").replace("inf", "2000");
    let half = |x: f32| half::f16::from_f32(x).to_bits() as u32;
    let swap = [(half(1000.0), 0x7E00), (half(2000.0), 0x7C00), (half(-2000.0), 0xFC00)];
    let words: Vec<u32> = assemble_words(&src, AsmOptions::default())
        .expect("asm")
        .into_iter()
        .map(|w| {
            let (mut hi, mut lo) = (w >> 16, w & 0xFFFF);
            for (from, to) in swap {
                hi = if hi == from { to } else { hi };
                lo = if lo == from { to } else { lo };
            }
            hi << 16 | lo
        })
        .collect();
    assert_ne!(words, assemble_words(&src, AsmOptions::default()).expect("asm"), "no placeholder was replaced");
    let mut p = Processor::new(words, CameraTable::Final).expect("proc");
    let mut n = 0;
    while p.run_to_frame(100_000) == Step::Frame {
        let (film, _) =
            render_frame(&p.state, &FrameSettings { width: 64, height: 48, mode, sets, painter: false, spp: 1 }).expect("frame");
        for y in 0..film.height {
            for x in 0..film.width {
                assert!(film.get(x, y).is_finite(), "{mode:?} frame {n}: pixel {x},{y} {:?}", film.get(x, y));
            }
        }
        n += 1;
    }
    n
}

const SHAPES: &str = "nr
cam xloc, nan
cam yloc, 0
cam zloc, 0
lt 0, xfor, nan
lt 0, yfor, inf
lt 0, zfor, -1
sp 0, xloc, yloc, nan, 0
sp 0, zloc, type, -2, 1
sp 0, col, zscl, 0b00000_000000_11111, 0
sp 0, xscl, yscl, 0, 0
sp 0, rrot, irot, 0, 0
sp 0, jrot, krot, 0, 0
sp 1, xloc, yloc, inf, -inf
sp 1, zloc, type, -5, 1
sp 1, col, zscl, 0b11111_111111_00000, 1
sp 1, xscl, yscl, nan, 1
sp 1, rrot, irot, nan, nan
sp 1, jrot, krot, 0, 0.383
sp 2, xloc, yloc, 0, 0
sp 2, zloc, type, -4, 1
sp 2, col, zscl, 0b11111_000000_11111, 65504
sp 2, xscl, yscl, 65504, -65504
sp 2, rrot, irot, 1, 0
sp 2, jrot, krot, 0, 0
nf
cam zloc, inf
nf
cam zloc, 0
cam xloc, 0
nf
er
er
";

const TRIANGLES: &str = "nr
tr 0, x1, y1, nan, -100.0
tr 0, z1, x2, -600.0, inf
tr 0, y2, z2, 300.0, -600.0
tr 0, x3, y3, -500.0, -100.0
tr 0, z3, col, -600.0, 0b0000_1111_0000_1111
tr 1, x1, y1, 0, 0
tr 1, z1, x2, -600.0, 0
tr 1, y2, z2, 0, -600.0
tr 1, x3, y3, 0, 0
tr 1, z3, col, -600.0, 0b0000_0000_1111_0000
tr 2, x1, y1, -100, 300
tr 2, z1, x2, -600.0, -500.0
tr 2, y2, z2, 300.0, -600.0
tr 2, x3, y3, -100.0, -100.0
tr 2, z3, col, -inf, 0b0000_0000_1111_0000
nf
er
er
";

#[test]
fn the_assembler_refuses_nan_where_it_is() {
    let e = assemble_words("nr\ncam xloc, nan\n", AsmOptions::default()).expect_err("nan refused");
    assert_eq!((e.line, e.column), (2, 11), "{e:?}");
}

#[test]
fn hostile_shapes_render_in_both_modes() {
    assert_eq!(frames(SHAPES, Mode::Raytrace, SetKind::Shapes), 3);
    assert_eq!(frames(SHAPES, Mode::Raster, SetKind::Shapes), 3);
}

#[test]
fn hostile_triangles_render_in_both_modes() {
    assert_eq!(frames(TRIANGLES, Mode::Raytrace, SetKind::Triangles), 1);
    assert_eq!(frames(TRIANGLES, Mode::Raster, SetKind::Triangles), 1);
}
