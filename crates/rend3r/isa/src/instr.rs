//! Instructions as values, and their binary encoding and decoding.

use crate::table::{opcode, FLOW, MAX_LIGHT, MAX_SHAPE};

/// A flow instruction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Flow {
    /// `er`: end render (two in a row halt).
    End,
    /// `nr`: new render (start marker; clears the scene in lucent's processor).
    NewRender,
    /// `nf`: render one frame from the state so far.
    NewFrame,
    /// `lr`: loop: jump back to word 1.
    Loop,
}

impl Flow {
    /// The two-bit func field.
    #[must_use]
    pub fn func(self) -> u32 {
        self as u32
    }
    /// The mnemonic.
    #[must_use]
    pub fn mnemonic(self) -> &'static str {
        FLOW[self as usize].0
    }
    fn from_func(f: u32) -> Self {
        match f & 3 {
            0 => Flow::End,
            1 => Flow::NewRender,
            2 => Flow::NewFrame,
            _ => Flow::Loop,
        }
    }
}

/// One REND3R instruction (an SE word and its SD word are one instruction).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Instr {
    /// F-type.
    Flow(Flow),
    /// C-type: camera property `prop` (0..32) := `data`.
    Camera {
        /// Property index.
        prop: u8,
        /// Raw data bits.
        data: u16,
    },
    /// L-type: light `index` (0..64), property `prop` := `data`.
    Light {
        /// Light index.
        index: u8,
        /// Property index.
        prop: u8,
        /// Raw data bits.
        data: u16,
    },
    /// SE + SD: shape (or triangle) `index` (19 bits): `p1 := d1`, then `p2 := d2`.
    Set {
        /// Shape or triangle index.
        index: u32,
        /// First property.
        p1: u8,
        /// Second property.
        p2: u8,
        /// First value.
        d1: u16,
        /// Second value.
        d2: u16,
    },
    /// A word with no instruction meaning (unused opcodes, SI, non-canonical F/C/L
    /// words): carried as is (`.word` in assembly).
    Raw(u32),
}

impl Instr {
    /// Appends the instruction's words.
    pub fn encode_into(&self, out: &mut Vec<u32>) {
        match *self {
            Instr::Flow(f) => out.push(f.func() << 9),
            Instr::Camera { prop, data } => out.push(((data as u32) << 16) | ((prop as u32 & 31) << 11) | opcode::C),
            Instr::Light { index, prop, data } => {
                out.push(((data as u32) << 16) | ((prop as u32 & 31) << 11) | ((index as u32 & MAX_LIGHT) << 3) | opcode::L)
            }
            Instr::Set { index, p1, p2, d1, d2 } => {
                let index = index & MAX_SHAPE;
                out.push(((index >> 3) << 16) | ((p1 as u32 & 31) << 11) | ((p2 as u32 & 31) << 6) | ((index & 7) << 3) | opcode::SE);
                out.push(((d1 as u32) << 16) | d2 as u32);
            }
            Instr::Raw(w) => out.push(w),
        }
    }

    /// Number of words.
    #[must_use]
    pub fn len(&self) -> usize {
        if matches!(self, Instr::Set { .. }) {
            2
        } else {
            1
        }
    }

    /// Never empty (kept for clippy's `len_without_is_empty`).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        false
    }
}

/// Encodes a program.
#[must_use]
pub fn encode(prog: &[Instr]) -> Vec<u32> {
    let mut out = Vec::with_capacity(prog.len() * 2);
    for i in prog {
        i.encode_into(&mut out);
    }
    out
}

/// What is wrong with a word stream.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// An SE word is the last word: its SD word is missing.
    #[error("word {offset}: shape/triangle set (SE word {word:#010x}) at the end of the program has no SD data word")]
    MissingData {
        /// Word offset.
        offset: usize,
        /// The SE word.
        word: u32,
    },
    /// An opcode with no instruction (010, 100 = shape-init, 110, 111).
    #[error("word {offset}: {word:#010x} has opcode {opcode:#05b}, which is not an instruction (known: 000 flow, 001 camera, 011 light, 101 shape set)")]
    UnknownOpcode {
        /// Word offset.
        offset: usize,
        /// The word.
        word: u32,
        /// Its opcode bits.
        opcode: u32,
    },
    /// Bits the instruction does not use are set.
    #[error("word {offset}: {word:#010x} is a {what} word with bits set that must be zero")]
    NonCanonical {
        /// Word offset.
        offset: usize,
        /// The word.
        word: u32,
        /// Instruction class.
        what: &'static str,
    },
}

impl DecodeError {
    /// The word offset of the problem.
    #[must_use]
    pub fn offset(&self) -> usize {
        match *self {
            DecodeError::MissingData { offset, .. }
            | DecodeError::UnknownOpcode { offset, .. }
            | DecodeError::NonCanonical { offset, .. } => offset,
        }
    }
}

/// Decodes one instruction at `words[at]`; returns it and its length. Strict: unknown
/// opcodes and non-canonical words are errors.
pub fn decode_one(words: &[u32], at: usize) -> Result<(Instr, usize), DecodeError> {
    let w = words[at];
    match w & 7 {
        opcode::F => {
            if w & !(3 << 9) != 0 {
                return Err(DecodeError::NonCanonical { offset: at, word: w, what: "flow" });
            }
            Ok((Instr::Flow(Flow::from_func(w >> 9)), 1))
        }
        opcode::C => {
            if w & 0x7F8 != 0 {
                return Err(DecodeError::NonCanonical { offset: at, word: w, what: "camera" });
            }
            Ok((Instr::Camera { prop: ((w >> 11) & 31) as u8, data: (w >> 16) as u16 }, 1))
        }
        opcode::L => {
            if w & 0x600 != 0 {
                return Err(DecodeError::NonCanonical { offset: at, word: w, what: "light" });
            }
            Ok((Instr::Light { index: ((w >> 3) & 63) as u8, prop: ((w >> 11) & 31) as u8, data: (w >> 16) as u16 }, 1))
        }
        opcode::SE => {
            let Some(&sd) = words.get(at + 1) else {
                return Err(DecodeError::MissingData { offset: at, word: w });
            };
            let index = ((w >> 16) << 3) | ((w >> 3) & 7);
            Ok((Instr::Set { index, p1: ((w >> 11) & 31) as u8, p2: ((w >> 6) & 31) as u8, d1: (sd >> 16) as u16, d2: sd as u16 }, 2))
        }
        op => Err(DecodeError::UnknownOpcode { offset: at, word: w, opcode: op }),
    }
}

/// Decodes a whole stream strictly.
pub fn decode(words: &[u32]) -> Result<Vec<Instr>, DecodeError> {
    let mut out = Vec::with_capacity(words.len());
    let mut at = 0;
    while at < words.len() {
        let (i, n) = decode_one(words, at)?;
        out.push(i);
        at += n;
    }
    Ok(out)
}

/// Decodes leniently, as the board does: words that are not instructions become
/// [`Instr::Raw`] (the board ignores them). Only a missing SD word is an error.
pub fn decode_lenient(words: &[u32]) -> Result<Vec<Instr>, DecodeError> {
    let mut out = Vec::with_capacity(words.len());
    let mut at = 0;
    while at < words.len() {
        match decode_one(words, at) {
            Ok((i, n)) => {
                out.push(i);
                at += n;
            }
            Err(e @ DecodeError::MissingData { .. }) => return Err(e),
            Err(_) => {
                out.push(Instr::Raw(words[at]));
                at += 1;
            }
        }
    }
    Ok(out)
}

/// True when a stream looks like REND3R's *legacy* ISA (raycast branch, before about
/// 2022-12-10), where `nr` was 0x00000000 and `nf` 0x00000200: it starts with a zero word
/// followed by more program. Final-ISA programs start with `nr` = 0x00000200.
#[must_use]
pub fn looks_legacy(words: &[u32]) -> bool {
    words.len() >= 2 && words[0] == 0 && words[1] != 0
}
