//! # rend3r_isa
//!
//! REND3R's 32-bit instruction set as a pure language, independent of any renderer
//! (SPEC.md in `shared/rend3r`):
//! - [`table`]: the one table of opcodes and property names everything derives from;
//! - [`Instr`], [`encode`], [`decode`]: instructions as values and as words;
//! - [`assemble`]: REND3R's assembly language, with `line:column` errors;
//! - [`disassemble`]: words back to assembly, such that assembling it gives the same words.
//!
//! # Example
//! ```
//! use rend3r_isa::{assemble_words, AsmOptions};
//! let words = assemble_words("nr\nsp 0, zloc, type, -2, 1\nnf\ner\ner\n", AsmOptions::default()).unwrap();
//! assert_eq!(words, [0x200, 0x1B45, 0xC000_0001, 0x400, 0, 0]);
//! ```
#![deny(missing_docs)]

mod asm;
mod disasm;
mod instr;
pub mod number;
pub mod table;

pub use asm::{assemble, assemble_words, from_bin, from_mem, to_bin, to_mem, AsmError, AsmOptions};
pub use disasm::{disassemble, DisasmOptions, SetTable};
pub use instr::{decode, decode_lenient, decode_one, encode, looks_legacy, DecodeError, Flow, Instr};
pub use table::CameraTable;
