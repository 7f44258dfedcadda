//! The wire protocol (written down in `docs/protocol.md`): a 16-byte hello from the
//! client, then length-prefixed messages both ways. Every integer is big-endian (network
//! byte order). Nothing here does I/O beyond `Read`/`Write`, and every parser takes
//! untrusted bytes (see the fuzz target `net_hello` / `net_message`).

use std::io::{self, Read, Write};

/// First four bytes of a client hello.
pub const HELLO_MAGIC: [u8; 4] = *b"R3DH";
/// Protocol version this build speaks.
pub const VERSION: u8 = 1;
/// Bytes of a client hello.
pub const HELLO_LEN: usize = 16;
/// Bytes of a message header (type, length).
pub const HEADER_LEN: usize = 5;

/// Client → server: a batch of instruction words (u32, big-endian) or assembly text,
/// whichever the hello chose.
pub const MSG_DATA: u8 = 0x01;
/// Server → client: the hello was accepted.
pub const MSG_WELCOME: u8 = 0x81;
/// Server → client: one frame (one `nf`).
pub const MSG_FRAME: u8 = 0x82;
/// Server → client: an error.
pub const MSG_ERROR: u8 = 0x83;
/// Server → client: a batch has been executed; the device waits for more.
pub const MSG_DONE: u8 = 0x84;
/// Server → UDP client: one chunk of a PNG frame.
pub const MSG_FRAME_CHUNK: u8 = 0x85;

/// What the client sends after the hello.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    /// Instruction words, 4 bytes each, big-endian.
    Words = 0,
    /// REND3R assembly text (UTF-8), assembled by the server.
    Assembly = 1,
}

/// Pixel format of frames sent to the client.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelFormat {
    /// 16 bits per pixel, RGB565, big-endian, row-major, top row first.
    Rgb565 = 0,
    /// 8-bit sRGB, 3 bytes per pixel, row-major, top row first.
    Rgb8 = 1,
    /// A PNG file (8-bit sRGB RGB).
    Png = 2,
}

impl PixelFormat {
    /// From the wire code.
    #[must_use]
    pub fn from_code(c: u8) -> Option<Self> {
        match c {
            0 => Some(Self::Rgb565),
            1 => Some(Self::Rgb8),
            2 => Some(Self::Png),
            _ => None,
        }
    }
    /// Name for messages and the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Rgb565 => "rgb565",
            Self::Rgb8 => "rgb8",
            Self::Png => "png",
        }
    }
}

/// Rendering mode requested by a client (0 in the hello = the server's default).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WireMode {
    /// Whatever `lucent serve --mode` says.
    Default = 0,
    /// Ray tracing.
    Raytrace = 1,
    /// Rasterization.
    Raster = 2,
}

/// The client's hello.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Hello {
    /// What DATA messages hold.
    pub input: Input,
    /// Frame pixel format wanted.
    pub format: PixelFormat,
    /// Assembly uses REND3R's older camera property table.
    pub old_camera_table: bool,
    /// Frame size wanted; 0 means the server's default.
    pub width: u16,
    /// Frame height wanted; 0 means the server's default.
    pub height: u16,
    /// Mode wanted.
    pub mode: WireMode,
}

/// A malformed hello or message header.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ProtocolError {
    /// The first four bytes are not `R3DH`.
    #[error("hello: bytes 0..4 are {0:02x?}, expected \"R3DH\" (is this a lucent client?)")]
    Magic([u8; 4]),
    /// Unsupported version.
    #[error("hello: byte 4 (version) is {0}, this server speaks version {VERSION}")]
    Version(u8),
    /// Bad input kind.
    #[error("hello: byte 5 (input) is {0}, expected 0 (words) or 1 (assembly)")]
    Input(u8),
    /// Bad pixel format.
    #[error("hello: byte 6 (pixel format) is {0}, expected 0 (rgb565), 1 (rgb8) or 2 (png)")]
    Format(u8),
    /// Unknown flag bits.
    #[error("hello: byte 7 (flags) is {0:#04x}; only bit 0 (old camera table) is defined")]
    Flags(u8),
    /// Bad mode.
    #[error("hello: byte 12 (mode) is {0}, expected 0 (server default), 1 (raytrace) or 2 (raster)")]
    Mode(u8),
    /// Non-zero reserved bytes.
    #[error("hello: bytes 13..16 are reserved and must be zero")]
    Reserved,
    /// A message type the receiver does not know.
    #[error("message type {0:#04x} is not one a client may send (expected 0x01, data)")]
    Type(u8),
    /// A message longer than the limit.
    #[error("message of {len} bytes exceeds the limit of {max} bytes (--max-message)")]
    TooLong {
        /// Announced length.
        len: u32,
        /// Limit.
        max: u32,
    },
}

impl Hello {
    /// Encodes the hello.
    #[must_use]
    pub fn encode(&self) -> [u8; HELLO_LEN] {
        let mut b = [0u8; HELLO_LEN];
        b[..4].copy_from_slice(&HELLO_MAGIC);
        b[4] = VERSION;
        b[5] = self.input as u8;
        b[6] = self.format as u8;
        b[7] = u8::from(self.old_camera_table);
        b[8..10].copy_from_slice(&self.width.to_be_bytes());
        b[10..12].copy_from_slice(&self.height.to_be_bytes());
        b[12] = self.mode as u8;
        b
    }

    /// Parses a hello.
    pub fn parse(b: &[u8; HELLO_LEN]) -> Result<Self, ProtocolError> {
        let magic = [b[0], b[1], b[2], b[3]];
        if magic != HELLO_MAGIC {
            return Err(ProtocolError::Magic(magic));
        }
        if b[4] != VERSION {
            return Err(ProtocolError::Version(b[4]));
        }
        let input = match b[5] {
            0 => Input::Words,
            1 => Input::Assembly,
            x => return Err(ProtocolError::Input(x)),
        };
        let format = PixelFormat::from_code(b[6]).ok_or(ProtocolError::Format(b[6]))?;
        if b[7] & !1 != 0 {
            return Err(ProtocolError::Flags(b[7]));
        }
        let mode = match b[12] {
            0 => WireMode::Default,
            1 => WireMode::Raytrace,
            2 => WireMode::Raster,
            x => return Err(ProtocolError::Mode(x)),
        };
        if b[13..16] != [0, 0, 0] {
            return Err(ProtocolError::Reserved);
        }
        Ok(Self {
            input,
            format,
            old_camera_table: b[7] & 1 != 0,
            width: u16::from_be_bytes([b[8], b[9]]),
            height: u16::from_be_bytes([b[10], b[11]]),
            mode,
        })
    }
}

/// Parses a message header: (type, payload length).
#[must_use]
pub fn parse_header(b: &[u8; HEADER_LEN]) -> (u8, u32) {
    (b[0], u32::from_be_bytes([b[1], b[2], b[3], b[4]]))
}

/// Writes one message (header and payload) with a single write call.
pub fn write_message(w: &mut impl Write, kind: u8, payload: &[u8]) -> io::Result<()> {
    let len = u32::try_from(payload.len()).map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "message over 4 GiB"))?;
    let mut buf = Vec::with_capacity(HEADER_LEN + payload.len());
    buf.push(kind);
    buf.extend_from_slice(&len.to_be_bytes());
    buf.extend_from_slice(payload);
    w.write_all(&buf)
}

/// Reads one message (any type) of at most `max` payload bytes; `Ok(None)` on a clean end
/// of stream before a header.
pub fn read_message(r: &mut impl Read, max: u32) -> io::Result<Option<(u8, Vec<u8>)>> {
    let mut h = [0u8; HEADER_LEN];
    let mut got = 0;
    while got < HEADER_LEN {
        match r.read(&mut h[got..]) {
            Ok(0) if got == 0 => return Ok(None),
            Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    let (kind, len) = parse_header(&h);
    if len > max {
        return Err(io::Error::new(io::ErrorKind::InvalidData, ProtocolError::TooLong { len, max }));
    }
    let mut payload = vec![0u8; len as usize];
    r.read_exact(&mut payload)?;
    Ok(Some((kind, payload)))
}

/// The WELCOME payload: what the server settled on for this connection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Welcome {
    /// Frame width.
    pub width: u16,
    /// Frame height.
    pub height: u16,
    /// 1 raytrace, 2 raster.
    pub mode: u8,
    /// Pixel format of frames.
    pub format: u8,
    /// 1 when the session is shared with other clients (`--shared`).
    pub shared: u8,
    /// Largest DATA payload accepted.
    pub max_message: u32,
    /// Most shape/triangle records (indices 0..max_shapes).
    pub max_shapes: u32,
    /// Most lights.
    pub max_lights: u16,
}

impl Welcome {
    /// Encodes (18 bytes).
    #[must_use]
    pub fn encode(&self) -> Vec<u8> {
        let mut b = vec![VERSION];
        b.extend_from_slice(&self.width.to_be_bytes());
        b.extend_from_slice(&self.height.to_be_bytes());
        b.extend_from_slice(&[self.mode, self.format, self.shared]);
        b.extend_from_slice(&self.max_message.to_be_bytes());
        b.extend_from_slice(&self.max_shapes.to_be_bytes());
        b.extend_from_slice(&self.max_lights.to_be_bytes());
        b
    }
    /// Decodes.
    #[must_use]
    pub fn decode(b: &[u8]) -> Option<Self> {
        if b.len() < 18 {
            return None;
        }
        Some(Self {
            width: u16::from_be_bytes([b[1], b[2]]),
            height: u16::from_be_bytes([b[3], b[4]]),
            mode: b[5],
            format: b[6],
            shared: b[7],
            max_message: u32::from_be_bytes([b[8], b[9], b[10], b[11]]),
            max_shapes: u32::from_be_bytes([b[12], b[13], b[14], b[15]]),
            max_lights: u16::from_be_bytes([b[16], b[17]]),
        })
    }
}

/// Bytes of a FRAME header before the pixels.
pub const FRAME_HEADER_LEN: usize = 24;

/// A FRAME message's header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameHeader {
    /// Frame number in the session, from 1.
    pub number: u32,
    /// Width.
    pub width: u16,
    /// Height.
    pub height: u16,
    /// Pixel format code.
    pub format: u8,
    /// Render time in microseconds.
    pub render_us: u32,
    /// Shapes or triangles in the frame.
    pub shapes: u32,
    /// Lights in the frame.
    pub lights: u16,
}

impl FrameHeader {
    /// Encodes.
    #[must_use]
    pub fn encode(&self) -> [u8; FRAME_HEADER_LEN] {
        let mut b = [0u8; FRAME_HEADER_LEN];
        b[0..4].copy_from_slice(&self.number.to_be_bytes());
        b[4..6].copy_from_slice(&self.width.to_be_bytes());
        b[6..8].copy_from_slice(&self.height.to_be_bytes());
        b[8] = self.format;
        b[12..16].copy_from_slice(&self.render_us.to_be_bytes());
        b[16..20].copy_from_slice(&self.shapes.to_be_bytes());
        b[20..22].copy_from_slice(&self.lights.to_be_bytes());
        b
    }
    /// Decodes.
    #[must_use]
    pub fn decode(b: &[u8]) -> Option<Self> {
        if b.len() < FRAME_HEADER_LEN {
            return None;
        }
        let u32at = |i: usize| u32::from_be_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        Some(Self {
            number: u32at(0),
            width: u16::from_be_bytes([b[4], b[5]]),
            height: u16::from_be_bytes([b[6], b[7]]),
            format: b[8],
            render_us: u32at(12),
            shapes: u32at(16),
            lights: u16::from_be_bytes([b[20], b[21]]),
        })
    }
}

/// Error codes of ERROR messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u16)]
pub enum ErrorCode {
    /// The hello or a message header was malformed.
    Protocol = 1,
    /// Words that are not a valid instruction stream (an SE word with no SD word, ...).
    Decode = 2,
    /// Assembly that does not assemble.
    Assembly = 3,
    /// A limit was hit (message size, shapes, lights, frame size, program length).
    Limit = 4,
    /// The program ran a loop without `nf`.
    Runaway = 5,
    /// The server is at its connection cap.
    Busy = 6,
    /// No traffic for the idle timeout.
    Idle = 7,
    /// Rendering failed.
    Render = 8,
}

/// Where an error is, in the client's input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// Not tied to a place.
    None,
    /// Word offset in the session's stream (all words received, counted from 0).
    Word(u64),
    /// Line and column (from 1) in the DATA message's assembly text.
    Text {
        /// Line.
        line: u32,
        /// Column.
        column: u32,
    },
}

/// An ERROR message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ErrorMessage {
    /// Code.
    pub code: ErrorCode,
    /// True when the server closes the connection after it.
    pub fatal: bool,
    /// Where.
    pub at: Location,
    /// Readable reason.
    pub message: String,
}

impl ErrorMessage {
    /// Encodes (20-byte fixed part, then UTF-8).
    #[must_use]
    pub fn encode(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(20 + self.message.len());
        b.extend_from_slice(&(self.code as u16).to_be_bytes());
        b.push(u8::from(self.fatal));
        let (kind, off, line, col) = match self.at {
            Location::None => (0u8, 0u64, 0u32, 0u32),
            Location::Word(o) => (1, o, 0, 0),
            Location::Text { line, column } => (2, 0, line, column),
        };
        b.push(kind);
        b.extend_from_slice(&off.to_be_bytes());
        b.extend_from_slice(&line.to_be_bytes());
        b.extend_from_slice(&col.to_be_bytes());
        b.extend_from_slice(self.message.as_bytes());
        b
    }
    /// Decodes; unknown codes become `Protocol`.
    #[must_use]
    pub fn decode(b: &[u8]) -> Option<Self> {
        if b.len() < 20 {
            return None;
        }
        let code = match u16::from_be_bytes([b[0], b[1]]) {
            2 => ErrorCode::Decode,
            3 => ErrorCode::Assembly,
            4 => ErrorCode::Limit,
            5 => ErrorCode::Runaway,
            6 => ErrorCode::Busy,
            7 => ErrorCode::Idle,
            8 => ErrorCode::Render,
            _ => ErrorCode::Protocol,
        };
        let u32at = |i: usize| u32::from_be_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        let at = match b[3] {
            1 => Location::Word(u64::from(u32at(4)) << 32 | u64::from(u32at(8))),
            2 => Location::Text { line: u32at(12), column: u32at(16) },
            _ => Location::None,
        };
        Some(Self { code, fatal: b[2] != 0, at, message: String::from_utf8_lossy(&b[20..]).into_owned() })
    }
}

impl std::fmt::Display for ErrorMessage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.at {
            Location::None => write!(f, "{}", self.message),
            Location::Word(o) => write!(f, "word {o}: {}", self.message),
            Location::Text { line, column } => write!(f, "{line}:{column}: {}", self.message),
        }
    }
}

/// A DONE message: the batch ran to its end (or `er`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Done {
    /// Words received in the session so far.
    pub words: u64,
    /// Frames rendered in the session so far.
    pub frames: u32,
    /// True when `er` halted the program (the next batch starts a new program).
    pub halted: bool,
}

impl Done {
    /// Encodes (13 bytes).
    #[must_use]
    pub fn encode(&self) -> Vec<u8> {
        let mut b = self.words.to_be_bytes().to_vec();
        b.extend_from_slice(&self.frames.to_be_bytes());
        b.push(u8::from(self.halted));
        b
    }
    /// Decodes.
    #[must_use]
    pub fn decode(b: &[u8]) -> Option<Self> {
        if b.len() < 13 {
            return None;
        }
        Some(Self {
            words: u64::from_be_bytes(b[0..8].try_into().ok()?),
            frames: u32::from_be_bytes(b[8..12].try_into().ok()?),
            halted: b[12] != 0,
        })
    }
}

/// Bytes of a UDP frame chunk header.
pub const CHUNK_HEADER_LEN: usize = 13;

/// A UDP FRAME_CHUNK datagram's header (after the type byte).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Chunk {
    /// Frame number in the session.
    pub frame: u32,
    /// Chunk index from 0.
    pub index: u16,
    /// Chunks in the frame.
    pub count: u16,
    /// Bytes of the whole PNG.
    pub total: u32,
}

impl Chunk {
    /// Encodes with the type byte first.
    #[must_use]
    pub fn encode(&self) -> [u8; CHUNK_HEADER_LEN] {
        let mut b = [0u8; CHUNK_HEADER_LEN];
        b[0] = MSG_FRAME_CHUNK;
        b[1..5].copy_from_slice(&self.frame.to_be_bytes());
        b[5..7].copy_from_slice(&self.index.to_be_bytes());
        b[7..9].copy_from_slice(&self.count.to_be_bytes());
        b[9..13].copy_from_slice(&self.total.to_be_bytes());
        b
    }
    /// Decodes a datagram that starts with the type byte.
    #[must_use]
    pub fn decode(b: &[u8]) -> Option<Self> {
        if b.len() < CHUNK_HEADER_LEN || b[0] != MSG_FRAME_CHUNK {
            return None;
        }
        Some(Self {
            frame: u32::from_be_bytes(b[1..5].try_into().ok()?),
            index: u16::from_be_bytes(b[5..7].try_into().ok()?),
            count: u16::from_be_bytes(b[7..9].try_into().ok()?),
            total: u32::from_be_bytes(b[9..13].try_into().ok()?),
        })
    }
}

/// Big-endian words from bytes (the length must be a multiple of 4).
#[must_use]
pub fn words_from_bytes(b: &[u8]) -> Vec<u32> {
    b.chunks_exact(4).map(|c| u32::from_be_bytes([c[0], c[1], c[2], c[3]])).collect()
}

/// Bytes from words, big-endian.
#[must_use]
pub fn words_to_bytes(w: &[u32]) -> Vec<u8> {
    w.iter().flat_map(|x| x.to_be_bytes()).collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn hello_round_trip_and_errors() {
        let h = Hello {
            input: Input::Assembly,
            format: PixelFormat::Rgb565,
            old_camera_table: true,
            width: 640,
            height: 480,
            mode: WireMode::Raster,
        };
        assert_eq!(Hello::parse(&h.encode()), Ok(h));
        let mut b = h.encode();
        b[0] = b'X';
        assert!(matches!(Hello::parse(&b), Err(ProtocolError::Magic(_))));
        let mut b = h.encode();
        b[6] = 9;
        assert_eq!(Hello::parse(&b), Err(ProtocolError::Format(9)));
        let mut b = h.encode();
        b[15] = 1;
        assert_eq!(Hello::parse(&b), Err(ProtocolError::Reserved));
    }

    #[test]
    fn messages_round_trip() {
        let e = ErrorMessage { code: ErrorCode::Decode, fatal: false, at: Location::Word(1 << 33 | 7), message: "bad".into() };
        assert_eq!(ErrorMessage::decode(&e.encode()), Some(e));
        let e = ErrorMessage { code: ErrorCode::Assembly, fatal: true, at: Location::Text { line: 3, column: 9 }, message: "x".into() };
        assert_eq!(ErrorMessage::decode(&e.encode()), Some(e));
        let d = Done { words: 12345678901, frames: 7, halted: true };
        assert_eq!(Done::decode(&d.encode()), Some(d));
        let f = FrameHeader { number: 3, width: 512, height: 384, format: 2, render_us: 1234, shapes: 9, lights: 2 };
        assert_eq!(FrameHeader::decode(&f.encode()), Some(f));
        let w = Welcome { width: 512, height: 384, mode: 1, format: 2, shared: 0, max_message: 1 << 20, max_shapes: 65536, max_lights: 64 };
        assert_eq!(Welcome::decode(&w.encode()), Some(w));
        let c = Chunk { frame: 2, index: 3, count: 9, total: 10000 };
        assert_eq!(Chunk::decode(&c.encode()), Some(c));
        let mut buf = Vec::new();
        write_message(&mut buf, MSG_DATA, &[1, 2, 3]).unwrap();
        assert_eq!(read_message(&mut buf.as_slice(), 3).unwrap(), Some((MSG_DATA, vec![1, 2, 3])));
        assert!(read_message(&mut buf.as_slice(), 2).is_err(), "over the limit");
        assert_eq!(read_message(&mut [].as_slice(), 2).unwrap(), None);
        assert!(read_message(&mut [1u8, 0].as_slice(), 2).is_err(), "truncated header");
    }
}
