//! A client of the device protocol (used by `lucent send`, `lucent bench net` and the
//! tests).

use crate::protocol::{
    self, Done, ErrorMessage, FrameHeader, Hello, Welcome, FRAME_HEADER_LEN, HELLO_LEN, MSG_DATA, MSG_DONE, MSG_ERROR, MSG_FRAME,
    MSG_WELCOME,
};
use std::io::{self, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

/// Errors of the client.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// Network failure.
    #[error("{0}")]
    Io(#[from] io::Error),
    /// The server refused the connection with an error.
    #[error("server refused: {0}")]
    Refused(ErrorMessage),
    /// The server sent something this client cannot read.
    #[error("unexpected reply from the server: {0}")]
    Protocol(String),
}

/// What the server sent.
#[derive(Clone, Debug)]
pub enum Event {
    /// A frame: header and pixels in the negotiated format.
    Frame(FrameHeader, Vec<u8>),
    /// An error.
    Error(ErrorMessage),
    /// A batch finished.
    Done(Done),
    /// The server closed the connection.
    Closed,
}

/// A connection to `lucent serve`.
pub struct Client {
    stream: TcpStream,
    /// What the server settled on.
    pub welcome: Welcome,
}

impl Client {
    /// Connects and says hello.
    pub fn connect(addr: impl ToSocketAddrs, hello: &Hello, timeout: Duration) -> Result<Self, ClientError> {
        let mut stream = TcpStream::connect(addr)?;
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(timeout))?;
        stream.write_all(&hello.encode())?;
        let _ = HELLO_LEN;
        match protocol::read_message(&mut stream, 1 << 20)? {
            Some((MSG_WELCOME, b)) => {
                let welcome = Welcome::decode(&b).ok_or_else(|| ClientError::Protocol("short WELCOME".into()))?;
                Ok(Self { stream, welcome })
            }
            Some((MSG_ERROR, b)) => {
                Err(ClientError::Refused(ErrorMessage::decode(&b).ok_or_else(|| ClientError::Protocol("short ERROR".into()))?))
            }
            Some((k, _)) => Err(ClientError::Protocol(format!("message type {k:#04x} before WELCOME"))),
            None => Err(ClientError::Protocol("the server closed the connection before WELCOME".into())),
        }
    }

    /// Sends a DATA message.
    pub fn send(&mut self, payload: &[u8]) -> io::Result<()> {
        protocol::write_message(&mut self.stream, MSG_DATA, payload)
    }

    /// Sends words.
    pub fn send_words(&mut self, words: &[u32]) -> io::Result<()> {
        self.send(&protocol::words_to_bytes(words))
    }

    /// Closes the sending side: the server finishes what it has, then closes.
    pub fn finish(&mut self) -> io::Result<()> {
        self.stream.shutdown(std::net::Shutdown::Write)
    }

    /// The next event.
    pub fn recv(&mut self) -> Result<Event, ClientError> {
        // Frames can be large: allow the biggest frame the server may send.
        let max = 64 + 4 * u32::from(self.welcome.width) * u32::from(self.welcome.height);
        let msg = match protocol::read_message(&mut self.stream, max.max(1 << 20)) {
            Ok(m) => m,
            Err(e) if matches!(e.kind(), io::ErrorKind::ConnectionReset | io::ErrorKind::BrokenPipe) => return Ok(Event::Closed),
            Err(e) => return Err(e.into()),
        };
        match msg {
            None => Ok(Event::Closed),
            Some((MSG_FRAME, b)) => {
                let h = FrameHeader::decode(&b).ok_or_else(|| ClientError::Protocol("short FRAME".into()))?;
                Ok(Event::Frame(h, b[FRAME_HEADER_LEN..].to_vec()))
            }
            Some((MSG_ERROR, b)) => Ok(Event::Error(ErrorMessage::decode(&b).ok_or_else(|| ClientError::Protocol("short ERROR".into()))?)),
            Some((MSG_DONE, b)) => Ok(Event::Done(Done::decode(&b).ok_or_else(|| ClientError::Protocol("short DONE".into()))?)),
            Some((k, _)) => Err(ClientError::Protocol(format!("unknown message type {k:#04x}"))),
        }
    }

    /// The underlying stream (tests use it to misbehave).
    pub fn stream(&mut self) -> &mut TcpStream {
        &mut self.stream
    }
}

/// Splits words into batches of at most `max_bytes`, never between an SE word and its SD
/// word (a batch must hold whole instructions).
#[must_use]
pub fn batches(words: &[u32], max_bytes: usize) -> Vec<&[u32]> {
    let max = (max_bytes / 4).max(2);
    let mut out = Vec::new();
    let mut start = 0;
    let mut i = 0;
    while i < words.len() {
        let len = if words[i] & 7 == 5 { 2 } else { 1 };
        if i + len - start > max {
            out.push(&words[start..i]);
            start = i;
        }
        i += len;
    }
    if start < words.len() {
        out.push(&words[start..]);
    }
    out
}

/// Saves a received frame: PNG as it came, RGB8 encoded as PNG, RGB565 as raw
/// big-endian 16-bit pixels (`.rgb565`). Returns the path written.
pub fn save_frame(dir: &std::path::Path, h: &FrameHeader, pixels: &[u8]) -> io::Result<std::path::PathBuf> {
    let stem = format!("frame-{:04}", h.number);
    match crate::protocol::PixelFormat::from_code(h.format) {
        Some(crate::protocol::PixelFormat::Png) => {
            let p = dir.join(format!("{stem}.png"));
            std::fs::write(&p, pixels)?;
            Ok(p)
        }
        Some(crate::protocol::PixelFormat::Rgb8) => {
            let p = dir.join(format!("{stem}.png"));
            image::save_buffer(&p, pixels, u32::from(h.width), u32::from(h.height), image::ExtendedColorType::Rgb8)
                .map_err(io::Error::other)?;
            Ok(p)
        }
        _ => {
            let p = dir.join(format!("{stem}.rgb565"));
            std::fs::write(&p, pixels)?;
            Ok(p)
        }
    }
}

/// What a UDP exchange brought back.
#[derive(Debug, Default)]
pub struct UdpResult {
    /// Complete PNG frames, by frame number.
    pub frames: Vec<(u32, Vec<u8>)>,
    /// Errors.
    pub errors: Vec<ErrorMessage>,
    /// DONE messages.
    pub done: Vec<Done>,
    /// Frames of which some chunk never arrived.
    pub incomplete: usize,
}

/// Sends words as UDP datagrams (whole instructions, at most `max_bytes` each) and
/// collects what comes back until `dones` DONE datagrams arrived or nothing arrived for
/// `quiet`.
pub fn udp_exchange(addr: std::net::SocketAddr, words: &[u32], max_bytes: usize, quiet: Duration) -> io::Result<UdpResult> {
    use crate::protocol::{Chunk, CHUNK_HEADER_LEN, MSG_FRAME_CHUNK};
    use std::collections::BTreeMap;
    let bind = if addr.is_ipv4() { "0.0.0.0:0" } else { "[::]:0" };
    let sock = std::net::UdpSocket::bind(bind)?;
    sock.connect(addr)?;
    sock.set_read_timeout(Some(quiet))?;
    let parts = batches(words, max_bytes.min(65_000));
    let mut res = UdpResult::default();
    type Parts = Vec<Option<Vec<u8>>>;
    let mut partial: BTreeMap<u32, (Chunk, Parts)> = BTreeMap::new();
    let mut buf = vec![0u8; 65_536];
    for p in &parts {
        sock.send(&crate::protocol::words_to_bytes(p))?;
        // Wait for this batch's DONE before the next (the server drops datagrams that find
        // the device busy).
        let want = res.done.len() + 1;
        while res.done.len() < want {
            let n = match sock.recv(&mut buf) {
                Ok(n) => n,
                Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                    res.incomplete = partial.len();
                    return Ok(res);
                }
                Err(e) => return Err(e),
            };
            let d = &buf[..n];
            match d.first() {
                Some(&MSG_FRAME_CHUNK) => {
                    let Some(c) = Chunk::decode(d) else { continue };
                    let e = partial.entry(c.frame).or_insert_with(|| (c, vec![None; usize::from(c.count)]));
                    if let Some(slot) = e.1.get_mut(usize::from(c.index)) {
                        *slot = Some(d[CHUNK_HEADER_LEN..].to_vec());
                    }
                    if e.1.iter().all(Option::is_some) {
                        if let Some((_, parts)) = partial.remove(&c.frame) {
                            res.frames.push((c.frame, parts.into_iter().flatten().flatten().collect()));
                        }
                    }
                }
                Some(&MSG_ERROR) => {
                    if let Some(e) = ErrorMessage::decode(&d[1..]) {
                        // Errors of the datagram itself (not of a batch) get no DONE.
                        let batchless = matches!(e.code, crate::protocol::ErrorCode::Protocol | crate::protocol::ErrorCode::Busy);
                        if batchless {
                            res.done.push(Done { words: 0, frames: 0, halted: false });
                        }
                        res.errors.push(e);
                    }
                }
                Some(&MSG_DONE) => {
                    if let Some(x) = Done::decode(&d[1..]) {
                        res.done.push(x);
                    }
                }
                _ => {}
            }
        }
    }
    res.incomplete = partial.len();
    Ok(res)
}
