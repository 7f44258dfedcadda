//! One REND3R device on the network: a thread that owns a [`Processor`], executes the
//! batches its clients send, renders a frame for every `nf`, and hands each frame to its
//! subscribers. A session (one connection) has its own device; with `--shared` every
//! client joins one device and receives all of its frames.
//!
//! Streaming semantics (docs/protocol.md): a batch continues the current program, so
//! `lr` jumps back to word 1 of it; after `er` the next batch starts a new program while
//! the device state (camera, lights, shapes) stays. A program that loops renders frames
//! until the next batch arrives, which stops the loop at a frame boundary.

use crate::protocol::{Done, ErrorCode, ErrorMessage, Input, Location};
use crossbeam_channel::{Receiver, Sender, TrySendError};
use rend3r_isa::{assemble_words, decode, AsmOptions, CameraTable, Instr};
use rend3r_machine::{render_frame, FrameSettings, Processor, SetKind, Step};
use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

/// Limits of one device (per session, or the shared one).
#[derive(Clone, Copy, Debug)]
pub struct DeviceLimits {
    /// Shape/triangle records: indices `0..max_shapes`.
    pub max_shapes: u32,
    /// Lights: indices `0..max_lights` (at most 64).
    pub max_lights: u16,
    /// Words a program may hold (the words since the last `er`).
    pub max_program_words: usize,
    /// Words a batch may execute between two frames before it counts as a runaway loop.
    pub loop_budget: u64,
}

impl Default for DeviceLimits {
    fn default() -> Self {
        Self { max_shapes: 65_536, max_lights: 64, max_program_words: 1 << 20, loop_budget: 50_000_000 }
    }
}

/// A rendered frame, shared by every subscriber (each encodes it in its own format).
#[derive(Debug)]
pub struct DeviceFrame {
    /// Frame number on this device, from 1.
    pub number: u32,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// 8-bit sRGB, RGB, row-major (exactly what `lucent run` writes to its PNGs).
    pub rgb8: Vec<u8>,
    /// Render time.
    pub render_us: u32,
    /// Shapes or triangles drawn.
    pub shapes: u32,
    /// Lights used.
    pub lights: u16,
}

/// What a device sends a subscriber.
#[derive(Clone, Debug)]
pub enum Out {
    /// A frame.
    Frame(Arc<DeviceFrame>),
    /// An error (to the client whose batch caused it).
    Error(ErrorMessage),
    /// The client's batch has run to its end.
    Done(Done),
}

/// What a device receives.
pub enum In {
    /// A subscriber joins; `pace` means the device waits for it when its queue is full
    /// (a session's own client) instead of dropping frames for it (a viewer of a shared
    /// device).
    Join {
        /// Client id.
        id: u64,
        /// Its queue.
        tx: Sender<Out>,
    },
    /// A batch from client `from`.
    Data {
        /// Client id.
        from: u64,
        /// Words or assembly.
        input: Input,
        /// Assembly uses the old camera table.
        old_table: bool,
        /// Payload.
        bytes: Vec<u8>,
    },
    /// A client left (its queue is dropped once everything before this is done).
    Leave(u64),
}

/// Starts a device thread; it ends when every sender of its input is dropped.
pub fn spawn(fs: FrameSettings, limits: DeviceLimits, name: String) -> std::io::Result<Sender<In>> {
    // Two batches in flight: the reader of a connection blocks beyond that, which pushes
    // back on the client through TCP.
    let (tx, rx) = crossbeam_channel::bounded(2);
    std::thread::Builder::new().name(name).spawn(move || Device::new(fs, limits).run(&rx))?;
    Ok(tx)
}

struct Device {
    p: Processor,
    fs: FrameSettings,
    /// SE/SD records are read as triangles or shapes: fixed by the first assembly that
    /// says which, else by the mode (as `lucent run` does for `.mem` files).
    sets_from_source: Option<SetKind>,
    limits: DeviceLimits,
    subs: Vec<(u64, Sender<Out>)>,
    received: u64,
    frames: u32,
    backlog: VecDeque<In>,
}

impl Device {
    fn new(fs: FrameSettings, limits: DeviceLimits) -> Self {
        let p = Processor::new(Vec::new(), CameraTable::Final).unwrap_or_else(|_| unreachable!("an empty program is valid"));
        Self { p, fs, sets_from_source: None, limits, subs: Vec::new(), received: 0, frames: 0, backlog: VecDeque::new() }
    }

    fn run(mut self, rx: &Receiver<In>) {
        loop {
            let msg = match self.backlog.pop_front() {
                Some(m) => m,
                None => match rx.recv() {
                    Ok(m) => m,
                    Err(_) => return,
                },
            };
            match msg {
                In::Join { id, tx } => self.subs.push((id, tx)),
                In::Leave(id) => self.subs.retain(|s| s.0 != id),
                In::Data { from, input, old_table, bytes } => self.batch(from, input, old_table, &bytes, rx),
            }
        }
    }

    fn send(&mut self, to: u64, out: Out) {
        if let Some(i) = self.subs.iter().position(|s| s.0 == to) {
            if self.subs[i].1.send(out).is_err() {
                self.subs.remove(i);
            }
        }
    }

    fn error(&mut self, to: u64, code: ErrorCode, at: Location, message: String) {
        tracing::debug!(client = to, ?code, "{message}");
        self.send(to, Out::Error(ErrorMessage { code, fatal: false, at, message }));
    }

    /// Validates a batch and runs it; then tells the client with DONE (every batch gets
    /// exactly one DONE, after its frames and errors).
    fn batch(&mut self, from: u64, input: Input, old_table: bool, bytes: &[u8], rx: &Receiver<In>) {
        self.validate_and_run(from, input, old_table, bytes, rx);
        let done = Done { words: self.received, frames: self.frames, halted: self.p.halted() };
        self.send(from, Out::Done(done));
    }

    fn validate_and_run(&mut self, from: u64, input: Input, old_table: bool, bytes: &[u8], rx: &Receiver<In>) {
        let base = self.received;
        let words = match input {
            Input::Words => {
                if !bytes.len().is_multiple_of(4) {
                    let at = Location::Word(base + (bytes.len() / 4) as u64);
                    return self.error(
                        from,
                        ErrorCode::Decode,
                        at,
                        format!("the batch has {} bytes, not a whole number of 4-byte words", bytes.len()),
                    );
                }
                crate::protocol::words_from_bytes(bytes)
            }
            Input::Assembly => {
                let Ok(src) = std::str::from_utf8(bytes) else {
                    return self.error(from, ErrorCode::Assembly, Location::None, "the assembly text is not UTF-8".into());
                };
                let table = if old_table { CameraTable::Old } else { CameraTable::Final };
                match assemble_words(src, AsmOptions { camera_table: table }) {
                    Ok(w) => {
                        if self.sets_from_source.is_none() {
                            self.sets_from_source = rend3r_machine::set_kind_of_source(src);
                        }
                        w
                    }
                    Err(e) => {
                        let at = Location::Text { line: to_u32(e.line), column: to_u32(e.column) };
                        return self.error(from, ErrorCode::Assembly, at, e.msg);
                    }
                }
            }
        };
        // Strict decoding: the whole batch is refused, with the offending word's offset in
        // the session's stream, and nothing of it runs.
        let instrs = match decode(&words) {
            Ok(i) => i,
            Err(e) => {
                let text = e.to_string();
                let reason = text.split_once(": ").map_or(text.as_str(), |x| x.1).to_string();
                return self.error(from, ErrorCode::Decode, Location::Word(base + e.offset() as u64), reason);
            }
        };
        let mut at = base;
        for i in &instrs {
            let bad = match *i {
                Instr::Set { index, .. } if index >= self.limits.max_shapes => Some(format!(
                    "shape/triangle record {index} is beyond this session's limit of {} (--max-shapes)",
                    self.limits.max_shapes
                )),
                Instr::Light { index, .. } if u16::from(index) >= self.limits.max_lights => {
                    Some(format!("light {index} is beyond this session's limit of {} (--max-lights)", self.limits.max_lights))
                }
                _ => None,
            };
            if let Some(m) = bad {
                return self.error(from, ErrorCode::Limit, Location::Word(at), m);
            }
            at += if matches!(i, Instr::Set { .. }) { 2 } else { 1 };
        }
        let program = if self.p.halted() { 0 } else { self.p.program_len() };
        if program + words.len() > self.limits.max_program_words {
            let m = format!(
                "the program would hold {} words, over this session's limit of {} (--max-program-words); end it with er er",
                program + words.len(),
                self.limits.max_program_words
            );
            return self.error(from, ErrorCode::Limit, Location::Word(base), m);
        }
        self.received += words.len() as u64;
        if let Err(e) = self.p.push(&words) {
            return self.error(from, ErrorCode::Decode, Location::Word(base + e.offset() as u64), e.to_string());
        }
        self.execute(from, rx);
    }

    /// Runs the program until it halts or needs more words.
    fn execute(&mut self, from: u64, rx: &Receiver<In>) {
        let loops_before = self.p.loops;
        loop {
            match self.p.run_to_frame(self.limits.loop_budget) {
                Step::Frame => {
                    self.frame(from);
                    if self.subs.is_empty() {
                        self.p.stop();
                        break;
                    }
                    if self.p.loops > loops_before && self.interrupted(rx) {
                        // A looping program: the next batch replaces it.
                        self.p.stop();
                        break;
                    }
                }
                Step::Busy => {
                    let m = format!("the program ran {} words without nf (a loop with no nf?); it was stopped", self.limits.loop_budget);
                    self.error(from, ErrorCode::Runaway, Location::None, m);
                    self.p.stop();
                    break;
                }
                Step::Halt | Step::Continue => break,
            }
        }
    }

    /// Takes joins and leaves that arrived while a loop ran; true when a batch is waiting.
    fn interrupted(&mut self, rx: &Receiver<In>) -> bool {
        while let Ok(m) = rx.try_recv() {
            match m {
                In::Join { id, tx } => self.subs.push((id, tx)),
                In::Leave(id) => {
                    self.subs.retain(|s| s.0 != id);
                }
                data @ In::Data { .. } => {
                    self.backlog.push_back(data);
                    return true;
                }
            }
        }
        !self.backlog.is_empty()
    }

    fn frame(&mut self, from: u64) {
        let fs = FrameSettings { sets: self.sets_from_source.unwrap_or(self.fs.sets), ..self.fs };
        let t = Instant::now();
        let ticket = GATE.enter();
        let rendered = render_frame(&self.p.state, &fs).map(|(film, info)| (film.to_srgb8(), film.width, film.height, info));
        drop(ticket);
        let (rgb8, width, height, info) = match rendered {
            Ok(x) => x,
            Err(e) => return self.error(from, ErrorCode::Render, Location::None, format!("frame could not be rendered: {e}")),
        };
        self.frames += 1;
        let frame = Arc::new(DeviceFrame {
            number: self.frames,
            width,
            height,
            rgb8,
            render_us: to_u32(t.elapsed().as_micros()),
            shapes: to_u32(info.shapes),
            lights: u16::try_from(info.lights).unwrap_or(u16::MAX),
        });
        // The client whose batch this is gets every frame (the device waits for it: that
        // paces a looping program); other viewers of a shared device skip frames when their
        // queue is full, so a slow viewer never stalls the others.
        let mut gone = Vec::new();
        for (id, tx) in &self.subs {
            let out = Out::Frame(Arc::clone(&frame));
            let ok = if *id == from { tx.send(out).is_ok() } else { !matches!(tx.try_send(out), Err(TrySendError::Disconnected(_))) };
            if !ok {
                gone.push(*id);
            }
        }
        self.subs.retain(|s| !gone.contains(&s.0));
    }
}

/// Admits at most twice as many frames into rendering at once as there are worker
/// threads, first come first served. A frame already spreads over every core (tiles on
/// rayon); more at once only adds memory (a film each) and unfairness between sessions.
/// (`lucent bench net`, 64 clients: without the gate 317 MB and p95 latency 453 ms; with
/// one frame per thread 79 MB but 12% fewer frames; with two, 85-111 MB and p95 155-164 ms.)
struct Gate {
    state: Mutex<(u64, u64)>,
    cv: Condvar,
}

static GATE: Gate = Gate { state: Mutex::new((0, 0)), cv: Condvar::new() };

impl Gate {
    fn enter(&'static self) -> GateTicket {
        let limit = 2 * rayon::current_num_threads().max(1) as u64;
        let mut g = self.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let ticket = g.0;
        g.0 += 1;
        while ticket >= g.1 + limit {
            g = self.cv.wait(g).unwrap_or_else(std::sync::PoisonError::into_inner);
        }
        GateTicket(self)
    }
}

struct GateTicket(&'static Gate);

impl Drop for GateTicket {
    fn drop(&mut self) {
        self.0.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner).1 += 1;
        self.0.cv.notify_all();
    }
}

fn to_u32<T: TryInto<u32>>(x: T) -> u32 {
    x.try_into().unwrap_or(u32::MAX)
}
