//! The disassembler (SPEC.md §3.6): readable assembly whose assembly gives back the same
//! words. Float-kind values print as the shortest decimal that round-trips through
//! f64→f16; int-kind values in hex; unknown properties as `aN`; words that are no
//! instruction (and values with no decimal form, i.e. NaN payloads) as `.word`.

use crate::instr::{decode_lenient, DecodeError, Instr};
use crate::number::f16_to_text;
use crate::table::{prop_at, CameraTable, Kind, Prop, LIGHT, SHAPE, TRIANGLE};

/// Which table `SE` words are shown with (`sp` and `tr` encode identically).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SetTable {
    /// Shapes (`sp`, ray-tracing build).
    #[default]
    Shape,
    /// Triangles (`tr`, rasterization build).
    Triangle,
}

/// Disassembler options.
#[derive(Clone, Copy, Debug, Default)]
pub struct DisasmOptions {
    /// Camera table for names.
    pub camera_table: CameraTable,
    /// `sp` or `tr`.
    pub set_table: SetTable,
}

fn name(p: Prop) -> String {
    if p.name.is_empty() {
        format!("a{}", p.index)
    } else {
        p.name.to_string()
    }
}

fn val(p: Prop, data: u16) -> Option<String> {
    match p.kind {
        Kind::Int => Some(format!("{data:#06x}")),
        Kind::Float => f16_to_text(data),
    }
}

/// Disassembles words into assembly text (one instruction per line).
pub fn disassemble(words: &[u32], opts: DisasmOptions) -> Result<String, DecodeError> {
    let prog = decode_lenient(words)?;
    let mut s = String::new();
    let mut at = 0usize;
    for i in &prog {
        let line = match *i {
            Instr::Flow(f) => Some(f.mnemonic().to_string()),
            Instr::Camera { prop, data } => {
                let p = prop_at(opts.camera_table.props(), prop);
                val(p, data).map(|v| format!("cam {}, {v}", name(p)))
            }
            Instr::Light { index, prop, data } => {
                let p = prop_at(LIGHT, prop);
                val(p, data).map(|v| format!("lt {index}, {}, {v}", name(p)))
            }
            Instr::Set { index, p1, p2, d1, d2 } => {
                let (mn, table) = match opts.set_table {
                    SetTable::Shape => ("sp", SHAPE),
                    SetTable::Triangle => ("tr", TRIANGLE),
                };
                let (a, b) = (prop_at(table, p1), prop_at(table, p2));
                match (val(a, d1), val(b, d2)) {
                    (Some(x), Some(y)) => Some(format!("{mn} {index}, {}, {}, {x}, {y}", name(a), name(b))),
                    _ => None,
                }
            }
            Instr::Raw(_) => None,
        };
        match line {
            Some(l) => {
                s.push_str(&l);
                s.push('\n');
            }
            None => {
                for w in &words[at..at + i.len()] {
                    s.push_str(&format!(".word {w:#010x}\n"));
                }
            }
        }
        at += i.len();
    }
    Ok(s)
}
