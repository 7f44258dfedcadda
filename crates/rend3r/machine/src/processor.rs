//! The instruction processor: executes REND3R word streams with the semantics of SPEC.md
//! §4 (update and compute modes, SE/SD pairs, `nr`, `nf`, `lr`, the two-zero-word halt),
//! with lucent's limits instead of the board's (2^19 shapes and triangles, 64 lights, any
//! program length).

use rend3r_isa::{decode_lenient, CameraTable, DecodeError, Flow, Instr};

/// One record (camera, light, or shape/triangle): 32 property slots of raw 16-bit data,
/// and which slots a program has written (a slot never written means "default").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Record {
    /// Raw data per property index.
    pub vals: [u16; 32],
    /// Bit `i` set when property `i` was written.
    pub written: u32,
}

impl Record {
    /// Writes property `p`.
    pub fn set(&mut self, p: u8, v: u16) {
        let p = (p & 31) as usize;
        self.vals[p] = v;
        self.written |= 1 << p;
    }
    /// True when property `p` was written.
    #[must_use]
    pub fn has(&self, p: u8) -> bool {
        self.written & (1 << (p & 31)) != 0
    }
    /// Property `p` as binary16, as f32.
    #[must_use]
    pub fn f(&self, p: u8) -> f32 {
        half::f16::from_bits(self.vals[(p & 31) as usize]).to_f32()
    }
    /// Property `p` raw.
    #[must_use]
    pub fn u(&self, p: u8) -> u16 {
        self.vals[(p & 31) as usize]
    }
    /// True when anything was written.
    #[must_use]
    pub fn used(&self) -> bool {
        self.written != 0
    }
}

/// Number of lights.
pub const LIGHTS: usize = 64;
/// Most shape/triangle records (the 19-bit index).
pub const MAX_SETS: usize = 1 << 19;

/// Shape or triangle records by index: the first `DENSE_SETS` (16,384) in a table that grows to
/// the highest one written, the rest kept sparse, so a program that writes record 524,287
/// alone costs one record, not 2^19 of them (36 MB), and one SE/SD pair from the network
/// cannot make a session allocate the whole index range (at most 1.1 MB of table).
/// PERF: a record lookup per written word was a B-tree search (Table IV's 4,096-sphere
/// program: 6.6% of its frame).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Sets {
    /// Records `0..dense.len()`; the last one written (unwritten ones `UNWRITTEN`).
    dense: Vec<Record>,
    /// Records from `DENSE_SETS` on.
    sparse: std::collections::BTreeMap<u32, Record>,
}

/// Records below this index live in [`Sets`]' table.
pub const DENSE_SETS: usize = 1 << 14;

/// The record every slot holds before a program writes it.
static UNWRITTEN: Record = Record { vals: [0; 32], written: 0 };

impl Sets {
    /// Writes property `p` of record `i`.
    pub fn set(&mut self, i: usize, p: u8, v: u16) {
        if i < DENSE_SETS {
            if i >= self.dense.len() {
                self.dense.resize(i + 1, UNWRITTEN);
            }
            self.dense[i].set(p, v);
        } else {
            self.sparse.entry(i as u32).or_default().set(p, v);
        }
    }
    /// Record `i` (the unwritten record when the program never wrote it).
    #[must_use]
    pub fn get(&self, i: usize) -> &Record {
        match self.dense.get(i) {
            Some(r) => r,
            None => u32::try_from(i).ok().and_then(|i| self.sparse.get(&i)).unwrap_or(&UNWRITTEN),
        }
    }
    /// One past the highest index written (0 when none): the length of the dense table.
    #[must_use]
    pub fn len(&self) -> usize {
        self.sparse.last_key_value().map_or(self.dense.len(), |(&i, _)| i as usize + 1)
    }
    /// True when no record was written.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.dense.is_empty() && self.sparse.is_empty()
    }
    /// The written records in index order.
    pub fn iter(&self) -> impl Iterator<Item = &Record> {
        self.dense.iter().filter(|r| r.used()).chain(self.sparse.values())
    }
    /// Slots `0..n` as a dense table (unwritten slots default), as a board's fixed table.
    #[must_use]
    pub fn dense(&self, n: usize) -> Vec<Record> {
        (0..n).map(|i| *self.get(i)).collect()
    }
}

impl std::ops::Index<usize> for Sets {
    type Output = Record;
    fn index(&self, i: usize) -> &Record {
        self.get(i)
    }
}

/// Everything a program has set.
#[derive(Clone, Debug)]
pub struct DeviceState {
    /// Camera record.
    pub camera: Record,
    /// Camera table the program was written for.
    pub camera_table: CameraTable,
    /// Lights 0..64.
    pub lights: Vec<Record>,
    /// Shape or triangle records set by SE/SD (interpreted at render time).
    pub sets: Sets,
}

impl DeviceState {
    /// The reset state: everything zero, nothing written.
    #[must_use]
    pub fn new(camera_table: CameraTable) -> Self {
        Self { camera: Record::default(), camera_table, lights: vec![Record::default(); LIGHTS], sets: Sets::default() }
    }
    /// Set records written so far.
    #[must_use]
    pub fn used_sets(&self) -> usize {
        self.sets.iter().filter(|r| r.used()).count()
    }
    /// Lights written so far.
    #[must_use]
    pub fn used_lights(&self) -> usize {
        self.lights.iter().filter(|r| r.used()).count()
    }
}

/// What one step of execution produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// An instruction ran; continue.
    Continue,
    /// `nf`: a frame should be rendered from the current state.
    Frame,
    /// The program halted (two zero words, or the end of the words).
    Halt,
    /// `run_to_frame` used up its word budget without reaching `nf` or a halt (a loop
    /// with no `nf`); calling it again continues.
    Busy,
}

/// Executes a word stream.
#[derive(Clone, Debug)]
pub struct Processor {
    words: Vec<u32>,
    pc: usize,
    /// The device state.
    pub state: DeviceState,
    /// Words executed so far.
    pub executed: u64,
    /// Words that are no instruction (ignored, as the board does).
    pub ignored: u64,
    /// Board mode: (shape/triangle records, lights) capacities; the PC wraps and `nr` keeps
    /// the scene.
    board: Option<(usize, usize)>,
    /// True once `er` halted the program (not merely the end of the words).
    halted: bool,
    /// `lr` instructions executed so far.
    pub loops: u64,
}

impl Processor {
    /// A processor for `words`; an SE word with no SD word at the end is an error.
    pub fn new(words: Vec<u32>, camera_table: CameraTable) -> Result<Self, DecodeError> {
        decode_lenient(&words)?;
        Ok(Self { words, pc: 0, state: DeviceState::new(camera_table), executed: 0, ignored: 0, board: None, halted: false, loops: 0 })
    }

    /// A processor with the board's behaviour: `words` is the whole ROM (the PC wraps
    /// around it, an SE in the last word takes word 0 as its SD), `nr` leaves the scene,
    /// and record indices wrap modulo the given capacities.
    pub fn new_board(words: Vec<u32>, camera_table: CameraTable, sets: usize, lights: usize) -> Result<Self, DecodeError> {
        Ok(Self {
            words,
            pc: 0,
            state: DeviceState::new(camera_table),
            executed: 0,
            ignored: 0,
            board: Some((sets.max(1), lights.max(1))),
            halted: false,
            loops: 0,
        })
    }

    /// Appends words to a streamed program (the network device). The words must be whole
    /// instructions (an SE word needs its SD word in the same batch). After `er` halted the
    /// program, the batch starts a new program (the device state is kept); otherwise it
    /// continues the current one, so `lr` jumps back to word 1 of the program.
    pub fn push(&mut self, words: &[u32]) -> Result<(), DecodeError> {
        decode_lenient(words)?;
        if self.halted {
            self.words.clear();
            self.pc = 0;
            self.halted = false;
        }
        self.words.extend_from_slice(words);
        Ok(())
    }

    /// True once `er` (two zero words, or one zero word as the last word) halted the
    /// program; false when execution merely reached the end of the words so far.
    #[must_use]
    pub fn halted(&self) -> bool {
        self.halted
    }

    /// Stops the current program as if it had halted (the network device interrupts a
    /// looping program when new words arrive); the device state is kept.
    pub fn stop(&mut self) {
        self.halted = true;
    }

    /// Words of the current program.
    #[must_use]
    pub fn program_len(&self) -> usize {
        self.words.len()
    }

    /// Runs one instruction.
    pub fn step(&mut self) -> Step {
        let len = self.words.len();
        if self.board.is_some() && len > 0 {
            self.pc %= len;
        }
        let Some(&w) = self.words.get(self.pc) else { return Step::Halt };
        // Validated in `new`: an SE word always has its SD word (on the board, the SD of an
        // SE in the last ROM word is word 0).
        let pair = [w, self.words.get(self.pc + 1).copied().unwrap_or(self.words[0])];
        let (instr, n) = match rend3r_isa::decode_one(&pair, 0) {
            Ok(x) => x,
            Err(_) => (Instr::Raw(w), 1),
        };
        let at = self.pc;
        self.pc += n;
        self.executed += n as u64;
        match instr {
            Instr::Flow(Flow::End) => {
                // Halt only on two zero words in a row (SPEC §4.2); beyond the end reads zero.
                let next = if self.board.is_some() { self.words.get((at + 1) % len) } else { self.words.get(at + 1) };
                if next.is_none_or(|&next| next == 0) {
                    self.halted = true;
                    return Step::Halt;
                }
            }
            Instr::Flow(Flow::NewRender) => {
                // lucent: `nr` clears the scene and the frame; the board changes nothing.
                if self.board.is_none() {
                    self.state = DeviceState::new(self.state.camera_table);
                }
            }
            Instr::Flow(Flow::NewFrame) => return Step::Frame,
            Instr::Flow(Flow::Loop) => {
                self.pc = 1;
                self.loops += 1;
            }
            Instr::Camera { prop, data } => self.state.camera.set(prop, data),
            Instr::Light { index, prop, data } => {
                let cap = self.board.map_or(LIGHTS, |b| b.1.min(LIGHTS));
                self.state.lights[index as usize % cap].set(prop, data);
            }
            Instr::Set { index, p1, p2, d1, d2 } => {
                let i = index as usize % self.board.map_or(MAX_SETS, |b| b.0);
                self.state.sets.set(i, p1, d1);
                self.state.sets.set(i, p2, d2);
            }
            Instr::Raw(_) => self.ignored += 1,
        }
        Step::Continue
    }

    /// Runs until the next frame or halt, or until `max_words` words ran ([`Step::Busy`]),
    /// so a program that loops without `nf` cannot hang the caller.
    pub fn run_to_frame(&mut self, max_words: u64) -> Step {
        let stop = self.executed + max_words;
        while self.executed < stop {
            match self.step() {
                Step::Continue => {}
                s => return s,
            }
        }
        Step::Busy
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Records below and above the table's end answer alike: written ones as written,
    /// others as the unwritten record; the length is one past the highest written; a
    /// record far out costs no table.
    #[test]
    fn sets_table_and_sparse_records() {
        let mut s = Sets::default();
        assert!(s.is_empty());
        assert_eq!(s.len(), 0);
        s.set(3, 2, 7);
        s.set(3, 4, 9);
        s.set(DENSE_SETS + 5, 1, 11);
        assert_eq!((s.get(3).u(2), s.get(3).u(4), s.get(3).has(1)), (7, 9, false));
        assert_eq!(s.get(0), &UNWRITTEN);
        assert_eq!(s.get(DENSE_SETS + 5).u(1), 11);
        assert_eq!(s.get(DENSE_SETS), &UNWRITTEN);
        assert_eq!(s.len(), DENSE_SETS + 6);
        assert_eq!(s.iter().count(), 2);
        assert_eq!(s.dense(5)[3].u(4), 9);
        let mut far = Sets::default();
        far.set(MAX_SETS - 1, 0, 1);
        assert!(far.dense.is_empty() && far.len() == MAX_SETS);
    }
}
