//! The HTTP side of `lucent serve`: the page at `/` (everything it needs is in this
//! binary), the example programs at `/programs`, and the frame stream at `/ws` (a
//! WebSocket: text messages are assembly to run, or JSON status from the server; binary
//! messages are instruction words from the client, or PNG frames from the server).

use crate::context::{Activity, ConnGuard, Ctx, HELLO_TIMEOUT};
use crate::device::{In, Out};
use crate::encode::png;
use crate::protocol::{ErrorCode, ErrorMessage, Input, Location};
use std::io::{self, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;
use tungstenite::protocol::{Role, WebSocketConfig};
use tungstenite::{Message, WebSocket};

/// The page.
pub const PAGE: &str = include_str!("../page/index.html");

/// A program of lucent's own, always listed first on the page.
pub const BUILTIN_EXAMPLE: (&str, &str) = ("lucent/three-spheres.rdr", include_str!("../page/three-spheres.rdr"));

/// Largest request head read.
const MAX_HEAD: usize = 16 * 1024;

/// Example programs: lucent's own, then every `.rdr` under the examples folder (sorted,
/// named by their path inside it; the legacy-ISA programs are left out, they do not
/// assemble).
#[must_use]
pub fn examples(dir: Option<&Path>) -> Vec<(String, PathBuf)> {
    fn walk(root: &Path, d: &Path, out: &mut Vec<(String, PathBuf)>) {
        let Ok(rd) = std::fs::read_dir(d) else { return };
        let mut entries: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
        entries.sort();
        for p in entries {
            if p.is_dir() {
                if p.file_name().is_some_and(|n| n != "legacy-isa") {
                    walk(root, &p, out);
                }
            } else if p.extension().is_some_and(|e| e == "rdr") {
                let name = p.strip_prefix(root).unwrap_or(&p).to_string_lossy().replace('\\', "/");
                out.push((name, p));
            }
        }
    }
    let mut out = Vec::new();
    if let Some(d) = dir {
        walk(d, d, &mut out);
    }
    out
}

fn respond(s: &mut TcpStream, status: &str, ctype: &str, body: &[u8]) {
    let head = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    );
    let _ = s.write_all(head.as_bytes());
    let _ = s.write_all(body);
    let _ = s.flush();
}

/// The request line and headers (names lower-cased).
#[derive(Debug)]
pub struct Request {
    /// `GET`, ...
    pub method: String,
    /// The request target.
    pub path: String,
    /// Header names (lower-cased) and values.
    pub headers: Vec<(String, String)>,
}

impl Request {
    /// The value of header `name` (lower case).
    #[must_use]
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|h| h.0 == name).map(|h| h.1.as_str())
    }
}

fn read_head(s: &mut TcpStream, act: &Activity) -> io::Result<Option<Request>> {
    let mut buf = Vec::with_capacity(1024);
    let mut b = [0u8; 1024];
    while !buf.windows(4).any(|w| w == b"\r\n\r\n") {
        if buf.len() > MAX_HEAD {
            return Err(io::Error::new(io::ErrorKind::InvalidData, "request head over 16 KiB"));
        }
        match s.read(&mut b) {
            Ok(0) => return Ok(None),
            Ok(n) => {
                buf.extend_from_slice(&b[..n]);
                act.touch();
            }
            Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                if act.idle() > HELLO_TIMEOUT {
                    return Ok(None);
                }
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(Some(parse_head(&buf)))
}

/// The request line and headers of a request head (any bytes: invalid UTF-8 is replaced,
/// missing parts are empty). Public for the fuzz target `http`.
#[must_use]
pub fn parse_head(buf: &[u8]) -> Request {
    let text = String::from_utf8_lossy(buf);
    let mut lines = text.split("\r\n");
    let mut first = lines.next().unwrap_or("").split(' ');
    let method = first.next().unwrap_or("").to_string();
    let path = first.next().unwrap_or("").to_string();
    let headers = lines
        .take_while(|l| !l.is_empty())
        .filter_map(|l| l.split_once(':').map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string())))
        .collect();
    Request { method, path, headers }
}

pub(crate) fn handle(ctx: Arc<Ctx>, mut s: TcpStream, guard: ConnGuard) {
    let _ = s.set_read_timeout(Some(Duration::from_millis(250)));
    let _ = s.set_write_timeout(Some(ctx.cfg.write_timeout));
    let act = Activity::new(&ctx);
    let req = match read_head(&mut s, &act) {
        Ok(Some(r)) => r,
        Ok(None) => return,
        Err(e) => return respond(&mut s, "400 Bad Request", "text/plain", e.to_string().as_bytes()),
    };
    if req.method != "GET" {
        return respond(&mut s, "405 Method Not Allowed", "text/plain", b"only GET is served\n");
    }
    let path = req.path.split('?').next().unwrap_or("");
    match path {
        "/" | "/index.html" => respond(&mut s, "200 OK", "text/html; charset=utf-8", PAGE.as_bytes()),
        "/programs" => {
            let mut names = vec![BUILTIN_EXAMPLE.0.to_string()];
            names.extend(examples(ctx.cfg.examples.as_deref()).into_iter().map(|e| e.0));
            let body = serde_json::to_vec(&names).unwrap_or_default();
            respond(&mut s, "200 OK", "application/json", &body);
        }
        "/ws" => {
            let upgrade = req.header("upgrade").is_some_and(|u| u.eq_ignore_ascii_case("websocket"));
            match (upgrade, req.header("sec-websocket-key")) {
                (true, Some(key)) => {
                    let key = key.to_string();
                    websocket(&ctx, s, &key, &act, guard);
                }
                _ => respond(&mut s, "400 Bad Request", "text/plain", b"/ws takes a WebSocket upgrade\n"),
            }
        }
        p if p.starts_with("/programs/") => {
            let name = &p["/programs/".len()..];
            if name == BUILTIN_EXAMPLE.0 {
                return respond(&mut s, "200 OK", "text/plain; charset=utf-8", BUILTIN_EXAMPLE.1.as_bytes());
            }
            // Only names from the listing are served: no path is built from the request.
            let found = examples(ctx.cfg.examples.as_deref()).into_iter().find(|e| e.0 == name);
            match found.map(|e| std::fs::read(e.1)) {
                Some(Ok(body)) => respond(&mut s, "200 OK", "text/plain; charset=utf-8", &body),
                _ => respond(&mut s, "404 Not Found", "text/plain", b"no such example\n"),
            }
        }
        _ => respond(&mut s, "404 Not Found", "text/plain", b"not found\n"),
    }
}

fn json_out(out: &Out) -> Option<String> {
    let v = match out {
        Out::Frame(f) => serde_json::json!({"type": "frame", "number": f.number, "width": f.width, "height": f.height,
            "render_ms": f64::from(f.render_us) / 1e3, "shapes": f.shapes, "lights": f.lights}),
        Out::Error(e) => {
            let (word, line, column) = match e.at {
                Location::Word(w) => (Some(w), None, None),
                Location::Text { line, column } => (None, Some(line), Some(column)),
                Location::None => (None, None, None),
            };
            serde_json::json!({"type": "error", "code": e.code as u16, "fatal": e.fatal, "word": word, "line": line,
                "column": column, "message": e.message, "text": e.to_string()})
        }
        Out::Done(d) => serde_json::json!({"type": "done", "words": d.words, "frames": d.frames, "halted": d.halted}),
    };
    Some(v.to_string())
}

fn websocket(ctx: &Arc<Ctx>, mut s: TcpStream, key: &str, act: &Activity, _guard: ConnGuard) {
    let accept = tungstenite::handshake::derive_accept_key(key.as_bytes());
    let head =
        format!("HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: {accept}\r\n\r\n");
    if s.write_all(head.as_bytes()).is_err() {
        return;
    }
    // Short read timeouts: one thread both reads the socket and writes the frames.
    let _ = s.set_read_timeout(Some(Duration::from_millis(5)));
    let _ = s.set_nodelay(true);
    let max = ctx.cfg.max_message as usize;
    let config = WebSocketConfig::default().max_message_size(Some(max)).max_frame_size(Some(max));
    let mut ws = WebSocket::from_raw_socket(s, Role::Server, Some(config));
    let id = ctx.id();
    let (w, h, mode) = (ctx.cfg.width, ctx.cfg.height, ctx.cfg.mode);
    let Ok(dev) = ctx.device(ctx.frame_settings(w, h, mode), id) else { return };
    let (out_tx, out_rx) = crossbeam_channel::bounded::<Out>(2);
    if dev.send(In::Join { id, tx: out_tx }).is_err() {
        return;
    }
    let hello = serde_json::json!({"type": "welcome", "width": w, "height": h, "shared": ctx.cfg.shared,
        "mode": if mode == rend3r_machine::Mode::Raster { "raster" } else { "raytrace" }});
    if ws.send(Message::text(hello.to_string())).is_err() {
        return;
    }
    let mut pending: Option<In> = None;
    loop {
        // Hand the pending batch to the device without blocking (the device may itself
        // be waiting for this thread to take a frame).
        if let Some(m) = pending.take() {
            match dev.try_send(m) {
                Ok(()) => {}
                Err(crossbeam_channel::TrySendError::Full(m)) => pending = Some(m),
                Err(crossbeam_channel::TrySendError::Disconnected(_)) => break,
            }
        }
        let mut wrote = false;
        while let Ok(out) = out_rx.try_recv() {
            let fatal = matches!(&out, Out::Error(e) if e.fatal);
            if let Some(j) = json_out(&out) {
                if ws.send(Message::text(j)).is_err() {
                    return;
                }
            }
            if let Out::Frame(f) = &out {
                if ws.send(Message::binary(png(f))).is_err() {
                    return;
                }
            }
            wrote = true;
            if fatal {
                let _ = ws.close(None);
                return;
            }
        }
        if wrote {
            act.touch();
        }
        if act.idle() > ctx.cfg.idle_timeout {
            let e = ErrorMessage { code: ErrorCode::Idle, fatal: true, at: Location::None, message: "idle".into() };
            if let Some(j) = json_out(&Out::Error(e)) {
                let _ = ws.send(Message::text(j));
            }
            break;
        }
        if pending.is_some() {
            std::thread::sleep(Duration::from_millis(2));
            continue;
        }
        match ws.read() {
            Ok(Message::Text(t)) => {
                act.touch();
                pending = Some(In::Data { from: id, input: Input::Assembly, old_table: false, bytes: t.as_bytes().to_vec() });
            }
            Ok(Message::Binary(b)) => {
                act.touch();
                pending = Some(In::Data { from: id, input: Input::Words, old_table: false, bytes: b.to_vec() });
            }
            Ok(Message::Close(_)) => break,
            Ok(_) => act.touch(),
            Err(tungstenite::Error::Io(e)) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {}
            Err(_) => break,
        }
    }
    drop(out_rx);
    let _ = dev.try_send(In::Leave(id));
}
