//! REND3R's assembly language (SPEC.md §3), accepted exactly: lines trimmed, `//` comment
//! lines, everything lowercased, the mnemonic before the first space, operands split on
//! `,`, symbolic or `a<N>` property names, Python number syntax, f64-then-f16 rounding.
//!
//! Extensions (none changes the meaning of a valid REND3R program): empty lines are
//! skipped, and `.word <int>` emits a raw word (what the disassembler prints for words
//! that are not instructions).

use crate::instr::{encode, Flow, Instr};
use crate::number::{parse_f16_operand, parse_uint};
use crate::table::{prop_at, CameraTable, Kind, Prop, FLOW, LIGHT, MAX_LIGHT, MAX_SHAPE, SHAPE, TRIANGLE};

/// An assembly error at a line and column (both 1-based).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{line}:{column}: {msg}")]
pub struct AsmError {
    /// Line.
    pub line: usize,
    /// Column (characters).
    pub column: usize,
    /// What was expected or what is wrong.
    pub msg: String,
}

/// Assembler options.
#[derive(Clone, Copy, Debug, Default)]
pub struct AsmOptions {
    /// Camera property table that names resolve against.
    pub camera_table: CameraTable,
}

/// Assembles REND3R source text into instructions.
pub fn assemble(src: &str, opts: AsmOptions) -> Result<Vec<Instr>, AsmError> {
    let mut out = Vec::new();
    // Where the last instruction started (for the end-of-program check below).
    let mut last_at = (0, 0);
    // Where each instruction of `out` starts.
    let mut starts = Vec::new();
    for (ln, raw) in src.lines().enumerate() {
        let line = ln + 1;
        let lead = raw.len() - raw.trim_start().len();
        let t = raw.trim();
        if t.is_empty() || t.starts_with("//") {
            continue;
        }
        let lower = t.to_lowercase();
        let (mn, rest, rest_col) = match lower.find(' ') {
            Some(i) => (&lower[..i], &lower[i + 1..], lead + i + 2),
            None => (lower.as_str(), "", lead + lower.len() + 1),
        };
        let err = |column: usize, msg: String| AsmError { line, column, msg };
        // Operands with their columns.
        let mut ops: Vec<(&str, usize)> = Vec::new();
        if !rest.trim().is_empty() {
            let mut col = rest_col;
            for piece in rest.split(',') {
                let inner = piece.len() - piece.trim_start().len();
                ops.push((piece.trim(), col + inner));
                col += piece.chars().count() + 1;
            }
        }
        let want = |n: usize, syntax: &str| -> Result<(), AsmError> {
            if ops.len() == n {
                Ok(())
            } else {
                Err(err(
                    rest_col.max(lead + 1),
                    format!("'{mn}' takes {n} operand{}: {syntax} (found {})", if n == 1 { "" } else { "s" }, ops.len()),
                ))
            }
        };
        let instr = match mn {
            "er" | "nr" | "nf" | "lr" => {
                want(0, mn)?;
                let f = FLOW.iter().position(|f| f.0 == mn).unwrap_or(0);
                Instr::Flow([Flow::End, Flow::NewRender, Flow::NewFrame, Flow::Loop][f])
            }
            "cam" => {
                want(2, "cam <prop>, <value>")?;
                let p = prop(opts.camera_table.props(), ops[0], "camera", line)?;
                Instr::Camera { prop: p.index, data: value(p, ops[1], line)? }
            }
            "lt" => {
                want(3, "lt <index>, <prop>, <value>")?;
                let index = uint(ops[0], MAX_LIGHT as u64, "light index", line)? as u8;
                let p = prop(LIGHT, ops[1], "light", line)?;
                Instr::Light { index, prop: p.index, data: value(p, ops[2], line)? }
            }
            "sp" | "tr" => {
                want(5, &format!("{mn} <index>, <prop1>, <prop2>, <value1>, <value2>"))?;
                let table = if mn == "sp" { SHAPE } else { TRIANGLE };
                let what = if mn == "sp" { "shape" } else { "triangle" };
                let index = uint(ops[0], MAX_SHAPE as u64, &format!("{what} index"), line)? as u32;
                let p1 = prop(table, ops[1], what, line)?;
                let p2 = prop(table, ops[2], what, line)?;
                Instr::Set { index, p1: p1.index, p2: p2.index, d1: value(p1, ops[3], line)?, d2: value(p2, ops[4], line)? }
            }
            ".word" => {
                want(1, ".word <32-bit integer>")?;
                Instr::Raw(uint(ops[0], u32::MAX as u64, "word", line)? as u32)
            }
            "spi" => return Err(err(lead + 1, "'spi' (shape init) belongs to REND3R's legacy ISA (raycast branch, before 2022-12-10); lucent assembles the final ISA, where shape init has no mnemonic".into())),
            _ if mn.contains('\t') => return Err(err(lead + 1, format!("unknown mnemonic '{}': separate the mnemonic from its operands with a space (a tab is not a separator)", mn.split('\t').next().unwrap_or(mn)))),
            _ => return Err(err(lead + 1, format!("unknown mnemonic '{mn}' (expected er, nr, nf, lr, cam, lt, sp or tr)"))),
        };
        out.push(instr);
        last_at = (line, lead + 1);
        starts.push(last_at);
    }
    // A `.word` with opcode 101 takes the next word as its data word. As the last word of a
    // program it has none; elsewhere it swallows the next instruction's first word, and
    // the stream may then end in a set instruction without its data word. No decoder could
    // read such a program: refuse it, naming the line whose word is left without data.
    // (A raw data word after a raw SE word is fine whatever its bits: ask the decoder, not
    // the opcode.)
    let words = encode(&out);
    if let Err(crate::instr::DecodeError::MissingData { offset, word }) = crate::instr::decode_lenient(&words) {
        // The instruction that emitted word `offset` (a set instruction is two words).
        let mut first = 0;
        let mut culprit = (last_at, out.last());
        for (ins, &pos) in out.iter().zip(&starts) {
            let n = if matches!(ins, Instr::Set { .. }) { 2 } else { 1 };
            if offset < first + n {
                culprit = (pos, Some(ins));
                break;
            }
            first += n;
        }
        let ((line, column), ins) = culprit;
        let msg = match ins {
            Some(Instr::Raw(w)) => {
                format!(".word {w:#010x} has opcode 101 (shape/triangle set), which needs a data word after it, but the program ends here")
            }
            _ => format!(
                "word {offset} ({word:#010x}) is read as a shape/triangle set (opcode 101) without a data word after it: an earlier `.word` with opcode 101 took the word after it as its data, so the words from there on are read out of step"
            ),
        };
        return Err(AsmError { line, column, msg });
    }
    Ok(out)
}

/// Assembles straight to words.
pub fn assemble_words(src: &str, opts: AsmOptions) -> Result<Vec<u32>, AsmError> {
    assemble(src, opts).map(|p| encode(&p))
}

fn prop(table: &[Prop], (text, col): (&str, usize), what: &str, line: usize) -> Result<Prop, AsmError> {
    if let Some(p) = table.iter().find(|p| p.name == text) {
        return Ok(*p);
    }
    if let Some(n) = text.strip_prefix('a') {
        // `a<N>`: N in decimal, as written by str(N) (no leading zeros, no sign).
        if !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) && (n == "0" || !n.starts_with('0')) {
            if let Ok(i) = n.parse::<u8>() {
                if i < 32 {
                    return Ok(prop_at(table, i));
                }
            }
        }
    }
    let names: Vec<&str> = table.iter().map(|p| p.name).collect();
    Err(AsmError { line, column: col, msg: format!("'{text}' is not a {what} property (expected one of {} or a0..a31)", names.join(", ")) })
}

fn uint((text, col): (&str, usize), max: u64, what: &str, line: usize) -> Result<u64, AsmError> {
    match parse_uint(text) {
        Some(v) if v <= max => Ok(v),
        Some(v) => Err(AsmError { line, column: col, msg: format!("{what} {v} out of range (0..={max})") }),
        None if text.is_empty() => Err(AsmError { line, column: col, msg: format!("expected {what}, found nothing") }),
        None => Err(AsmError { line, column: col, msg: format!("expected an unsigned integer for {what}, found '{text}'") }),
    }
}

fn value(p: Prop, (text, col): (&str, usize), line: usize) -> Result<u16, AsmError> {
    match p.kind {
        Kind::Int => uint((text, col), u16::MAX as u64, if p.name.is_empty() { "value" } else { p.name }, line).map(|v| v as u16),
        Kind::Float => {
            let bits = parse_f16_operand(text).ok_or_else(|| AsmError {
                line,
                column: col,
                msg: format!("expected a number for '{}', found '{text}'", p.name),
            })?;
            if half::f16::from_bits(bits).is_nan() {
                // REND3R's assembler would write 0x7E00; lucent refuses NaN where a number is needed.
                return Err(AsmError { line, column: col, msg: format!("'{}' needs a number, not NaN", p.name) });
            }
            Ok(bits)
        }
    }
}

/// Writes words as REND3R's `.mem`: 8 lowercase hex digits and a newline per word.
#[must_use]
pub fn to_mem(words: &[u32]) -> String {
    let mut s = String::with_capacity(words.len() * 9);
    for w in words {
        s.push_str(&format!("{w:08x}\n"));
    }
    s
}

/// Reads a `.mem` file (hex words, one per line; blank lines ignored).
pub fn from_mem(text: &str) -> Result<Vec<u32>, AsmError> {
    let mut out = Vec::new();
    for (ln, l) in text.lines().enumerate() {
        let t = l.trim();
        if t.is_empty() || t.starts_with("//") {
            continue;
        }
        let v = u32::from_str_radix(t, 16).map_err(|_| AsmError {
            line: ln + 1,
            column: 1,
            msg: format!("expected a 32-bit hex word, found '{t}'"),
        })?;
        if t.len() > 8 {
            return Err(AsmError { line: ln + 1, column: 1, msg: format!("'{t}' has more than 8 hex digits") });
        }
        out.push(v);
    }
    Ok(out)
}

/// Raw binary: big-endian (network order) u32 words.
#[must_use]
pub fn to_bin(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_be_bytes()).collect()
}

/// Reads raw big-endian words; `Err(len)` when the length is not a multiple of 4.
pub fn from_bin(bytes: &[u8]) -> Result<Vec<u32>, usize> {
    if !bytes.len().is_multiple_of(4) {
        return Err(bytes.len());
    }
    Ok(bytes.chunks_exact(4).map(|c| u32::from_be_bytes([c[0], c[1], c[2], c[3]])).collect())
}
