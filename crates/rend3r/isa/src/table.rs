//! The one table of REND3R's instruction set (SPEC.md §2): opcodes, mnemonics and the
//! property tables. The encoder, decoder, assembler and disassembler all derive from it.

/// How a property's 16 data bits are read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A raw 16-bit unsigned integer (types, colours, material).
    Int,
    /// An IEEE binary16 number.
    Float,
}

/// One property of a record (camera, light, shape or triangle).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Prop {
    /// Index (0..32).
    pub index: u8,
    /// Symbolic name accepted by the assembler.
    pub name: &'static str,
    /// Data kind.
    pub kind: Kind,
}

const fn p(index: u8, name: &'static str, kind: Kind) -> Prop {
    Prop { index, name, kind }
}
use Kind::{Float as F, Int as I};

/// Camera properties of the final ISA (raytracing branch).
pub const CAMERA: &[Prop] = &[
    p(0, "zero", I),
    p(1, "xloc", F),
    p(2, "yloc", F),
    p(3, "zloc", F),
    p(4, "rrot", F),
    p(5, "irot", F),
    p(6, "jrot", F),
    p(7, "krot", F),
    p(8, "nclip", F),
    p(9, "fclip", F),
    p(10, "hfov", F),
    p(11, "vfov", F),
];

/// Camera properties of the older table (main, taping branches): forward and up vectors.
pub const CAMERA_OLD: &[Prop] = &[
    p(0, "zero", I),
    p(1, "xloc", F),
    p(2, "yloc", F),
    p(3, "zloc", F),
    p(4, "xfor", F),
    p(5, "yfor", F),
    p(6, "zfor", F),
    p(7, "xup", F),
    p(8, "yup", F),
    p(9, "zup", F),
    p(10, "nclip", F),
    p(11, "fclip", F),
    p(12, "hfov", F),
    p(13, "vfov", F),
];

/// Light properties.
pub const LIGHT: &[Prop] = &[
    p(0, "src", I),
    p(1, "xloc", F),
    p(2, "yloc", F),
    p(3, "zloc", F),
    p(4, "xfor", F),
    p(5, "yfor", F),
    p(6, "zfor", F),
    p(7, "col", I),
    p(8, "int", F),
];

/// Shape properties (ray-tracing build).
pub const SHAPE: &[Prop] = &[
    p(0, "zero", I),
    p(1, "xloc", F),
    p(2, "yloc", F),
    p(3, "zloc", F),
    p(4, "rrot", F),
    p(5, "irot", F),
    p(6, "jrot", F),
    p(7, "krot", F),
    p(8, "xscl", F),
    p(9, "yscl", F),
    p(10, "zscl", F),
    p(11, "col", I),
    p(12, "mat", I),
    p(13, "type", I),
];

/// Triangle properties (rasterization build).
pub const TRIANGLE: &[Prop] = &[
    p(0, "zero", I),
    p(1, "x1", F),
    p(2, "y1", F),
    p(3, "z1", F),
    p(4, "x2", F),
    p(5, "y2", F),
    p(6, "z2", F),
    p(7, "x3", F),
    p(8, "y3", F),
    p(9, "z3", F),
    p(10, "none", F),
    p(11, "col", I),
    p(12, "mat", I),
];

/// Which camera table names resolve against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum CameraTable {
    /// The final table (quaternion), raytracing branch.
    #[default]
    Final,
    /// The older table (forward and up vectors).
    Old,
}

impl CameraTable {
    /// The property table.
    #[must_use]
    pub fn props(self) -> &'static [Prop] {
        match self {
            CameraTable::Final => CAMERA,
            CameraTable::Old => CAMERA_OLD,
        }
    }
}

/// Looks a property up by index; indices with no entry are no-ops on the board and read as
/// raw integers here (so every bit pattern round-trips).
#[must_use]
pub fn prop_at(table: &[Prop], index: u8) -> Prop {
    table.iter().copied().find(|p| p.index == index).unwrap_or(Prop { index, name: "", kind: Kind::Int })
}

/// Opcodes (bits 2..0).
pub mod opcode {
    /// Flow/frame: er, nr, nf, lr.
    pub const F: u32 = 0b000;
    /// Camera set.
    pub const C: u32 = 0b001;
    /// Light set.
    pub const L: u32 = 0b011;
    /// Shape-init (decoded by the board but without effect; no mnemonic).
    pub const SI: u32 = 0b100;
    /// Shape/triangle set, followed by one SD data word.
    pub const SE: u32 = 0b101;
}

/// The flow instructions: (mnemonic, func, canonical word).
pub const FLOW: [(&str, u32, u32); 4] = [("er", 0, 0x0000_0000), ("nr", 1, 0x0000_0200), ("nf", 2, 0x0000_0400), ("lr", 3, 0x0000_0600)];

/// Largest light index (6 bits).
pub const MAX_LIGHT: u32 = (1 << 6) - 1;
/// Largest shape/triangle index (19 bits).
pub const MAX_SHAPE: u32 = (1 << 19) - 1;
