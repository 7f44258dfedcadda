//! `lucent serve`: the TCP and UDP device endpoints and the HTTP page, one thread per
//! connection (bounded by `max_connections`), each guarded by its limits and timeouts.

use crate::context::{frame_settings, Activity, ConnGuard, Ctx, ServerConfig, HELLO_TIMEOUT};
use crate::device::{self, In, Out};
use crate::encode::{chunk_frame, frame_payload};
use crate::http::handle as handle_http;
use crate::protocol::{
    self, ErrorCode, ErrorMessage, Hello, Input, Location, Welcome, HEADER_LEN, HELLO_LEN, MSG_DATA, MSG_DONE, MSG_ERROR, MSG_FRAME,
    MSG_WELCOME,
};
use crossbeam_channel::Sender;
use rend3r_machine::Mode;
use std::collections::HashMap;
use std::io::{self, Read};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How often blocked reads wake up to check timeouts.
const POLL: Duration = Duration::from_millis(250);

/// A running server.
pub struct Server {
    ctx: Arc<Ctx>,
    /// The bound TCP address (useful with port 0).
    pub tcp_addr: SocketAddr,
    /// The bound UDP address.
    pub udp_addr: Option<SocketAddr>,
    /// The bound HTTP address.
    pub http_addr: Option<SocketAddr>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Server {
    /// Binds every endpoint and starts serving in background threads.
    pub fn start(cfg: ServerConfig) -> io::Result<Self> {
        let shared = if cfg.shared {
            Some(device::spawn(frame_settings(cfg.width, cfg.height, cfg.mode), cfg.device, "device-shared".into())?)
        } else {
            None
        };
        let tcp = TcpListener::bind(cfg.listen)?;
        let udp = cfg.udp.map(UdpSocket::bind).transpose()?;
        let http = cfg.http.map(TcpListener::bind).transpose()?;
        let ctx = Arc::new(Ctx {
            cfg,
            conns: AtomicUsize::new(0),
            next_id: AtomicU64::new(1),
            shared,
            stop: AtomicBool::new(false),
            epoch: Instant::now(),
            words_in: AtomicU64::new(0),
        });
        let tcp_addr = tcp.local_addr()?;
        let udp_addr = udp.as_ref().map(UdpSocket::local_addr).transpose()?;
        let http_addr = http.as_ref().map(TcpListener::local_addr).transpose()?;
        let mut threads = Vec::new();
        let c = Arc::clone(&ctx);
        threads.push(std::thread::Builder::new().name("tcp-accept".into()).spawn(move || accept_loop(&c, &tcp, handle_tcp))?);
        if let Some(u) = udp {
            let c = Arc::clone(&ctx);
            threads.push(std::thread::Builder::new().name("udp".into()).spawn(move || udp_loop(&c, &u))?);
        }
        if let Some(h) = http {
            let c = Arc::clone(&ctx);
            threads.push(std::thread::Builder::new().name("http-accept".into()).spawn(move || accept_loop(&c, &h, handle_http))?);
        }
        Ok(Self { ctx, tcp_addr, udp_addr, http_addr, threads })
    }

    /// Open connections right now.
    #[must_use]
    pub fn connections(&self) -> usize {
        self.ctx.conns.load(Ordering::SeqCst)
    }

    /// Instruction words accepted so far (all devices).
    #[must_use]
    pub fn words_accepted(&self) -> u64 {
        self.ctx.words_in.load(Ordering::Relaxed)
    }

    /// Blocks until the server stops (it does not on its own).
    pub fn wait(self) {
        for t in self.threads {
            let _ = t.join();
        }
    }

    /// Stops accepting; open connections finish on their own.
    pub fn stop(&self) {
        self.ctx.stop.store(true, Ordering::SeqCst);
        let _ = TcpStream::connect(self.tcp_addr);
        if let Some(a) = self.http_addr {
            let _ = TcpStream::connect(a);
        }
    }
}

fn accept_loop(ctx: &Arc<Ctx>, listener: &TcpListener, handler: fn(Arc<Ctx>, TcpStream, ConnGuard)) {
    for stream in listener.incoming() {
        if ctx.stop.load(Ordering::SeqCst) {
            return;
        }
        let Ok(s) = stream else { continue };
        let Some(guard) = ctx.admit() else {
            refuse_busy(s, ctx.cfg.max_connections);
            continue;
        };
        let c = Arc::clone(ctx);
        if let Err(e) = std::thread::Builder::new().name("conn".into()).spawn(move || handler(c, s, guard)) {
            tracing::warn!("cannot start a connection thread: {e}");
        }
    }
}

/// Tells a client over the cap why it is refused, without waiting for it.
fn refuse_busy(mut s: TcpStream, cap: usize) {
    let _ = s.set_write_timeout(Some(Duration::from_millis(100)));
    let e = ErrorMessage {
        code: ErrorCode::Busy,
        fatal: true,
        at: Location::None,
        message: format!("server busy: {cap} connections open (--max-connections)"),
    };
    let _ = protocol::write_message(&mut s, MSG_ERROR, &e.encode());
    let _ = s.shutdown(Shutdown::Both);
}

/// Reads exactly `buf.len()` bytes, riding out read timeouts while `alive()` holds.
/// `Ok(false)`: the peer closed before the first byte.
pub(crate) fn read_full(s: &mut impl Read, buf: &mut [u8], act: &Activity, alive: &dyn Fn() -> bool) -> io::Result<bool> {
    let mut got = 0;
    while got < buf.len() {
        match s.read(&mut buf[got..]) {
            Ok(0) if got == 0 => return Ok(false),
            Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => {
                got += n;
                act.touch();
            }
            Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                if !alive() {
                    return Err(io::ErrorKind::TimedOut.into());
                }
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(true)
}

fn fatal(s: &mut TcpStream, code: ErrorCode, message: String) {
    tracing::debug!("closing a connection: {message}");
    let e = ErrorMessage { code, fatal: true, at: Location::None, message };
    let _ = protocol::write_message(s, MSG_ERROR, &e.encode());
    let _ = s.shutdown(Shutdown::Both);
}

fn handle_tcp(ctx: Arc<Ctx>, mut s: TcpStream, _guard: ConnGuard) {
    let _ = s.set_nodelay(true);
    let _ = s.set_write_timeout(Some(ctx.cfg.write_timeout));
    let _ = s.set_read_timeout(Some(POLL));
    let act = Activity::new(&ctx);
    let mut hb = [0u8; HELLO_LEN];
    match read_full(&mut s, &mut hb, &act, &|| act.idle() < HELLO_TIMEOUT) {
        Ok(true) => {}
        Ok(false) => return,
        Err(e) if e.kind() == io::ErrorKind::TimedOut => return fatal(&mut s, ErrorCode::Idle, "no hello within 10 s".into()),
        Err(_) => return,
    }
    let hello = match Hello::parse(&hb) {
        Ok(h) => h,
        Err(e) => return fatal(&mut s, ErrorCode::Protocol, e.to_string()),
    };
    let (w, h, mode) = match ctx.resolve(hello.width, hello.height, hello.mode) {
        Ok(x) => x,
        Err(m) => return fatal(&mut s, ErrorCode::Limit, m),
    };
    let id = ctx.id();
    let dev = match ctx.device(ctx.frame_settings(w, h, mode), id) {
        Ok(d) => d,
        Err(e) => return fatal(&mut s, ErrorCode::Render, format!("cannot start a device: {e}")),
    };
    let welcome = Welcome {
        width: u16::try_from(w).unwrap_or(u16::MAX),
        height: u16::try_from(h).unwrap_or(u16::MAX),
        mode: if mode == Mode::Raster { 2 } else { 1 },
        format: hello.format as u8,
        shared: u8::from(ctx.shared.is_some()),
        max_message: ctx.cfg.max_message,
        max_shapes: ctx.cfg.device.max_shapes,
        max_lights: ctx.cfg.device.max_lights,
    };
    if protocol::write_message(&mut s, MSG_WELCOME, &welcome.encode()).is_err() {
        return;
    }
    let (out_tx, out_rx) = crossbeam_channel::bounded::<Out>(2);
    if dev.send(In::Join { id, tx: out_tx.clone() }).is_err() {
        return;
    }
    let writer = {
        let Ok(mut ws) = s.try_clone() else { return };
        let act = act.clone();
        let format = hello.format;
        std::thread::Builder::new().name("conn-writer".into()).spawn(move || {
            for out in out_rx {
                let (kind, payload, close) = match out {
                    Out::Frame(f) => (MSG_FRAME, frame_payload(&f, format), false),
                    Out::Error(e) => (MSG_ERROR, e.encode(), e.fatal),
                    Out::Done(d) => (MSG_DONE, d.encode(), false),
                };
                if protocol::write_message(&mut ws, kind, &payload).is_err() || close {
                    break;
                }
                act.touch();
            }
            let _ = ws.shutdown(Shutdown::Both);
        })
    };
    let reason = read_loop(&ctx, &mut s, &act, &dev, id, hello);
    if let Some((code, message)) = reason {
        let _ = out_tx.send(Out::Error(ErrorMessage { code, fatal: true, at: Location::None, message }));
    }
    drop(out_tx);
    let _ = dev.send(In::Leave(id));
    drop(dev);
    if let Ok(w) = writer {
        let _ = w.join();
    }
}

/// Reads DATA messages and hands them to the device; returns why it stopped when the
/// client should be told.
fn read_loop(ctx: &Ctx, s: &mut TcpStream, act: &Activity, dev: &Sender<In>, id: u64, hello: Hello) -> Option<(ErrorCode, String)> {
    let idle = ctx.cfg.idle_timeout;
    let alive = || act.idle() < idle;
    loop {
        let mut h = [0u8; HEADER_LEN];
        match read_full(s, &mut h, act, &alive) {
            Ok(true) => {}
            Ok(false) => return None,
            Err(e) if e.kind() == io::ErrorKind::TimedOut => {
                return Some((ErrorCode::Idle, format!("no traffic for {} s (--idle-timeout)", idle.as_secs())));
            }
            Err(_) => return None,
        }
        let (kind, len) = protocol::parse_header(&h);
        if kind != MSG_DATA {
            return Some((ErrorCode::Protocol, protocol::ProtocolError::Type(kind).to_string()));
        }
        if len > ctx.cfg.max_message {
            return Some((ErrorCode::Limit, protocol::ProtocolError::TooLong { len, max: ctx.cfg.max_message }.to_string()));
        }
        let mut payload = vec![0u8; len as usize];
        match read_full(s, &mut payload, act, &alive) {
            Ok(true) => {}
            Ok(false) if len == 0 => {}
            _ => return None,
        }
        if hello.input == Input::Words {
            ctx.words_in.fetch_add(u64::from(len / 4), Ordering::Relaxed);
        }
        let msg = In::Data { from: id, input: hello.input, old_table: hello.old_camera_table, bytes: payload };
        if dev.send(msg).is_err() {
            return None;
        }
    }
}

struct UdpSession {
    dev: Sender<In>,
    id: u64,
    last: Instant,
    _guard: ConnGuard,
}

fn udp_error(sock: &UdpSocket, peer: SocketAddr, code: ErrorCode, message: String) {
    let e = ErrorMessage { code, fatal: false, at: Location::None, message };
    let mut d = vec![MSG_ERROR];
    d.extend_from_slice(&e.encode());
    let _ = sock.send_to(&d, peer);
}

fn udp_loop(ctx: &Arc<Ctx>, sock: &UdpSocket) {
    let _ = sock.set_read_timeout(Some(Duration::from_secs(1)));
    let mut sessions: HashMap<SocketAddr, UdpSession> = HashMap::new();
    let mut buf = vec![0u8; 65_536];
    while !ctx.stop.load(Ordering::SeqCst) {
        let now = Instant::now();
        sessions.retain(|_, s| {
            let keep = now.duration_since(s.last) < ctx.cfg.idle_timeout;
            if !keep {
                let _ = s.dev.try_send(In::Leave(s.id));
            }
            keep
        });
        let (n, peer) = match sock.recv_from(&mut buf) {
            Ok(x) => x,
            Err(_) => continue,
        };
        let data = &buf[..n];
        if !n.is_multiple_of(4) || n as u64 > u64::from(ctx.cfg.max_message) {
            udp_error(
                sock,
                peer,
                ErrorCode::Protocol,
                format!("a datagram must hold whole 4-byte words, at most {} bytes; got {n} bytes", ctx.cfg.max_message),
            );
            continue;
        }
        if let std::collections::hash_map::Entry::Vacant(v) = sessions.entry(peer) {
            match new_udp_session(ctx, sock, peer) {
                Ok(s) => {
                    v.insert(s);
                }
                Err((code, m)) => {
                    udp_error(sock, peer, code, m);
                    continue;
                }
            }
        }
        let Some(sess) = sessions.get_mut(&peer) else { continue };
        sess.last = now;
        ctx.words_in.fetch_add((n / 4) as u64, Ordering::Relaxed);
        let msg = In::Data { from: sess.id, input: Input::Words, old_table: false, bytes: data.to_vec() };
        // Fire and forget: a datagram that finds the device's queue full is dropped, and
        // the client is told.
        if sess.dev.try_send(msg).is_err() {
            udp_error(sock, peer, ErrorCode::Busy, "device busy: datagram dropped (send slower or wait for DONE)".into());
        }
    }
}

fn new_udp_session(ctx: &Arc<Ctx>, sock: &UdpSocket, peer: SocketAddr) -> Result<UdpSession, (ErrorCode, String)> {
    let guard =
        ctx.admit().ok_or((ErrorCode::Busy, format!("server busy: {} sessions open (--max-connections)", ctx.cfg.max_connections)))?;
    let id = ctx.id();
    let (w, h, mode) = (ctx.cfg.width, ctx.cfg.height, ctx.cfg.mode);
    let dev = ctx.device(ctx.frame_settings(w, h, mode), id).map_err(|e| (ErrorCode::Render, e.to_string()))?;
    let (tx, rx) = crossbeam_channel::bounded::<Out>(4);
    dev.send(In::Join { id, tx }).map_err(|_| (ErrorCode::Render, "device ended".to_string()))?;
    let out = sock.try_clone().map_err(|e| (ErrorCode::Render, e.to_string()))?;
    let chunk = ctx.cfg.udp_chunk.clamp(1024, 65_000);
    std::thread::Builder::new()
        .name("udp-writer".into())
        .spawn(move || {
            for o in rx {
                match o {
                    Out::Frame(f) => {
                        for d in chunk_frame(&f, chunk) {
                            let _ = out.send_to(&d, peer);
                        }
                    }
                    Out::Error(e) => {
                        let mut d = vec![MSG_ERROR];
                        d.extend_from_slice(&e.encode());
                        let _ = out.send_to(&d, peer);
                    }
                    Out::Done(d) => {
                        let mut b = vec![MSG_DONE];
                        b.extend_from_slice(&d.encode());
                        let _ = out.send_to(&b, peer);
                    }
                }
            }
        })
        .map_err(|e| (ErrorCode::Render, e.to_string()))?;
    Ok(UdpSession { dev, id, last: Instant::now(), _guard: guard })
}
