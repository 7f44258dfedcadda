//! The network device over loopback: frames identical to `lucent run`'s, errors with
//! their places, hostile clients, limits, shared sessions, UDP and the HTTP side.
#![allow(clippy::unwrap_used)]

use rend3r_isa::{assemble_words, AsmOptions, CameraTable};
use rend3r_machine::{render_frame, FrameSettings, Mode, Processor, SetKind, Step};
use rend3r_net::client::{udp_exchange, Event};
use rend3r_net::protocol::{self, ErrorCode, Hello, Input, Location, PixelFormat, WireMode};
use rend3r_net::{Client, Server, ServerConfig};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::PathBuf;
use std::time::{Duration, Instant};

fn rend3r(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../../shared/rend3r/programs").join(rel)
}

fn loopback() -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], 0))
}

fn server(f: impl FnOnce(&mut ServerConfig)) -> Server {
    let mut cfg = ServerConfig { listen: loopback(), udp: Some(loopback()), http: Some(loopback()), ..ServerConfig::default() };
    f(&mut cfg);
    Server::start(cfg).unwrap()
}

fn hello(input: Input, format: PixelFormat) -> Hello {
    Hello { input, format, old_camera_table: false, width: 0, height: 0, mode: WireMode::Default }
}

fn connect(s: &Server, input: Input, format: PixelFormat) -> Client {
    Client::connect(s.tcp_addr, &hello(input, format), Duration::from_secs(60)).unwrap()
}

/// Events until the next DONE (inclusive).
fn until_done(c: &mut Client) -> Vec<Event> {
    let mut v = Vec::new();
    loop {
        let e = c.recv().unwrap();
        let stop = matches!(e, Event::Done(_) | Event::Closed);
        v.push(e);
        if stop {
            return v;
        }
    }
}

fn frames(ev: &[Event]) -> Vec<(protocol::FrameHeader, Vec<u8>)> {
    ev.iter().filter_map(|e| if let Event::Frame(h, p) = e { Some((*h, p.clone())) } else { None }).collect()
}

fn errors(ev: &[Event]) -> Vec<rend3r_net::ErrorMessage> {
    ev.iter().filter_map(|e| if let Event::Error(x) = e { Some(x.clone()) } else { None }).collect()
}

/// What `lucent run` renders for a program: the sRGB bytes of every frame.
fn run_locally(words: &[u32], sets: SetKind, mode: Mode) -> Vec<Vec<u8>> {
    let mut p = Processor::new(words.to_vec(), CameraTable::Final).unwrap();
    let fs = FrameSettings { width: 512, height: 384, mode, sets, painter: false, spp: 1 };
    let mut out = Vec::new();
    // Looping programs: the first 5 frames.
    while out.len() < 5 && p.run_to_frame(1_000_000) == Step::Frame {
        out.push(render_frame(&p.state, &fs).unwrap().0.to_srgb8());
    }
    out
}

fn decode_png(b: &[u8]) -> Vec<u8> {
    image::load_from_memory_with_format(b, image::ImageFormat::Png).unwrap().to_rgb8().into_raw()
}

#[test]
fn tcp_frames_are_identical_to_lucent_run() {
    let s = server(|_| {});
    for rel in ["raytracing/sw/raytrace.rdr", "raytracing/sw/rt_spheres.rdr", "raytracing/sw/raytrace2.rdr"] {
        let src = std::fs::read_to_string(rend3r(rel)).unwrap();
        let words = assemble_words(&src, AsmOptions::default()).unwrap();
        let want = run_locally(&words, SetKind::Shapes, Mode::Raytrace);
        assert!(!want.is_empty(), "{rel} renders frames");
        // Assembly text, PNG frames.
        let mut c = connect(&s, Input::Assembly, PixelFormat::Png);
        c.send(src.as_bytes()).unwrap();
        let got = frames(&until_done(&mut c));
        assert_eq!(got.len(), want.len(), "{rel}: frame count");
        for ((h, png), w) in got.iter().zip(&want) {
            assert_eq!((h.width, h.height, h.format), (512, 384, PixelFormat::Png as u8));
            assert!(decode_png(png) == *w, "{rel}: PNG frame {} differs from lucent run's", h.number);
        }
        // Words, RGB8 and RGB565.
        for format in [PixelFormat::Rgb8, PixelFormat::Rgb565] {
            let mut c = connect(&s, Input::Words, format);
            c.send_words(&words).unwrap();
            let got = frames(&until_done(&mut c));
            assert_eq!(got.len(), want.len());
            for ((_, px), w) in got.iter().zip(&want) {
                let expect: Vec<u8> = if format == PixelFormat::Rgb8 {
                    w.clone()
                } else {
                    w.chunks(3)
                        .flat_map(|p| (u16::from(p[0] >> 3) << 11 | u16::from(p[1] >> 2) << 5 | u16::from(p[2] >> 3)).to_be_bytes())
                        .collect()
                };
                assert!(*px == expect, "{rel}: {format:?} pixels differ");
            }
        }
    }
    // A looping program (sphere.rdr ends in `lr`): its first frames, then the client hangs up.
    let src = std::fs::read_to_string(rend3r("raytracing/sw/sphere.rdr")).unwrap();
    // It uses `tr`: its sets are triangles, ray traced (as `lucent run` reads it).
    assert_eq!(rend3r_machine::set_kind_of_source(&src), Some(SetKind::Triangles));
    let want = run_locally(&assemble_words(&src, AsmOptions::default()).unwrap(), SetKind::Triangles, Mode::Raytrace);
    let mut c = connect(&s, Input::Assembly, PixelFormat::Rgb8);
    c.send(src.as_bytes()).unwrap();
    for w in &want {
        let Event::Frame(_, px) = c.recv().unwrap() else { panic!("a frame") };
        assert!(px == *w, "sphere.rdr frame differs");
    }
    drop(c);
    // Rasterization, requested in the hello; the .mem words of cube.rdr's branch.
    let src = std::fs::read_to_string(rend3r("main/sw/cube.rdr")).unwrap();
    let words = assemble_words(&src, AsmOptions { camera_table: CameraTable::Old }).unwrap();
    let want = run_locally_old(&words);
    let h = Hello { old_camera_table: true, mode: WireMode::Raster, ..hello(Input::Assembly, PixelFormat::Rgb8) };
    let mut c = Client::connect(s.tcp_addr, &h, Duration::from_secs(60)).unwrap();
    c.send(src.as_bytes()).unwrap();
    let got = frames(&until_done(&mut c));
    assert_eq!(got.len(), want.len());
    assert!(got.iter().zip(&want).all(|((_, a), b)| a == b), "raster frames differ from lucent run's");
}

fn run_locally_old(words: &[u32]) -> Vec<Vec<u8>> {
    let mut p = Processor::new(words.to_vec(), CameraTable::Old).unwrap();
    let fs = FrameSettings { width: 512, height: 384, mode: Mode::Raster, sets: SetKind::Triangles, painter: false, spp: 1 };
    let mut out = Vec::new();
    while p.run_to_frame(1_000_000) == Step::Frame {
        out.push(render_frame(&p.state, &fs).unwrap().0.to_srgb8());
    }
    out
}

#[test]
fn errors_name_the_word_or_line_and_the_connection_survives() {
    let s = server(|c| c.device.max_shapes = 8);
    let mut c = connect(&s, Input::Words, PixelFormat::Rgb565);
    // 3 good words, then a batch whose last word is an SE with no SD word.
    let good = assemble_words("nr\ncam xloc, 1\ncam yloc, 2", AsmOptions::default()).unwrap();
    c.send_words(&good).unwrap();
    assert!(errors(&until_done(&mut c)).is_empty());
    let mut bad = assemble_words("cam zloc, 0\nsp 1, xloc, yloc, 1, 2", AsmOptions::default()).unwrap();
    bad.pop();
    c.send_words(&bad).unwrap();
    let e = errors(&until_done(&mut c));
    assert_eq!(e.len(), 1);
    assert_eq!((e[0].code, e[0].at, e[0].fatal), (ErrorCode::Decode, Location::Word(4), false), "{}", e[0]);
    assert!(e[0].message.contains("no SD data word"), "{}", e[0].message);
    // An unknown opcode at stream word 3 + 1 (the refused batch does not count).
    c.send_words(&[good[1], 0x0000_0002]).unwrap();
    let e = errors(&until_done(&mut c));
    assert_eq!((e[0].code, e[0].at), (ErrorCode::Decode, Location::Word(4)), "{}", e[0]);
    // A shape index over the session's limit.
    let over = assemble_words("nf\nsp 9, type, col, 1, 0", AsmOptions::default()).unwrap();
    c.send_words(&over).unwrap();
    let e = errors(&until_done(&mut c));
    assert_eq!((e[0].code, e[0].at), (ErrorCode::Limit, Location::Word(4)), "{}", e[0]);
    assert!(e[0].message.contains("--max-shapes"));
    // Not whole words.
    c.send(&[0, 0, 0, 0, 1]).unwrap();
    assert_eq!(errors(&until_done(&mut c))[0].code, ErrorCode::Decode);
    // Still alive: a good frame.
    let prog = assemble_words("sp 0, type, col, 1, 0xffff\nsp 0, zloc, zscl, -3, 1\nnf", AsmOptions::default()).unwrap();
    c.send_words(&prog).unwrap();
    let ev = until_done(&mut c);
    assert!(errors(&ev).is_empty(), "{:?}", errors(&ev));
    assert_eq!(frames(&ev).len(), 1);

    // Assembly: line and column of the mistake.
    let mut c = connect(&s, Input::Assembly, PixelFormat::Png);
    c.send(b"nr\ncam xloc, 0\ncam yloc, nan\nnf\n").unwrap();
    let e = errors(&until_done(&mut c));
    assert_eq!(e[0].code, ErrorCode::Assembly);
    assert!(matches!(e[0].at, Location::Text { line: 3, .. }), "{}", e[0]);
    c.send(&[0xff, 0xfe]).unwrap();
    assert!(errors(&until_done(&mut c))[0].message.contains("UTF-8"));
}

#[test]
fn a_looping_program_streams_frames_until_the_next_batch() {
    let s = server(|_| {});
    let mut c = connect(&s, Input::Assembly, PixelFormat::Rgb565);
    c.send(b"nr\nsp 0, type, col, 1, 0xf800\nsp 0, zloc, zscl, -3, 1\nnf\nlr\n").unwrap();
    let mut n = 0;
    while n < 5 {
        match c.recv().unwrap() {
            Event::Frame(..) => n += 1,
            e => panic!("expected frames, got {e:?}"),
        }
    }
    // A new program stops the loop at a frame boundary; its own frame and DONE follow.
    c.send(b"nr\nsp 0, type, col, 1, 0x07e0\nsp 0, zloc, zscl, -3, 1\nnf\ner\ner\n").unwrap();
    let ev = until_done(&mut c);
    let Some(Event::Done(d)) = ev.last() else { panic!("no DONE") };
    assert!(d.halted, "the interrupted loop counts as halted: the next batch is a new program");
    let ev = until_done(&mut c);
    let Some(Event::Done(d)) = ev.last() else { panic!("no DONE") };
    assert!(d.halted);
    let f = frames(&ev);
    let (h, px) = f.last().unwrap();
    let centre = (usize::from(h.height) / 2 * usize::from(h.width) + usize::from(h.width) / 2) * 2;
    let p = u16::from_be_bytes([px[centre], px[centre + 1]]);
    assert!(p >> 5 & 63 > 40 && p >> 11 < 16 && p & 31 < 16, "the new program's green sphere is in the centre: {p:#06x}");
    // A loop without nf is stopped with an error, and the session goes on.
    let s2 = server(|c| c.device.loop_budget = 100_000);
    let mut c = connect(&s2, Input::Assembly, PixelFormat::Rgb565);
    c.send(b"nr\ncam xloc, 1\nlr\n").unwrap();
    let e = errors(&until_done(&mut c));
    assert_eq!(e[0].code, ErrorCode::Runaway);
}

#[test]
fn hostile_clients_do_not_disturb_a_good_one() {
    let s = server(|c| {
        c.max_message = 4096;
        c.write_timeout = Duration::from_millis(500);
    });
    let addr = s.tcp_addr;
    let good = || {
        let mut c = connect(&s, Input::Words, PixelFormat::Rgb565);
        let w = assemble_words("nr\nsp 0, type, col, 1, 0xffff\nsp 0, zloc, zscl, -3, 1\nnf\ner\ner", AsmOptions::default()).unwrap();
        c.send_words(&w).unwrap();
        assert_eq!(frames(&until_done(&mut c)).len(), 1, "the good client gets its frame");
    };
    good();
    // Garbage instead of a hello: a fatal protocol error, then the server closes.
    let mut g = TcpStream::connect(addr).unwrap();
    g.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
    let (kind, payload) = protocol::read_message(&mut g, 1 << 16).unwrap().unwrap();
    let e = protocol::ErrorMessage::decode(&payload).unwrap();
    assert_eq!((kind, e.code, e.fatal), (protocol::MSG_ERROR, ErrorCode::Protocol, true));
    assert!(e.message.contains("R3DH"), "{}", e.message);
    good();
    // Random bytes after a valid hello: an unknown message type is fatal.
    let mut c = connect(&s, Input::Words, PixelFormat::Png);
    c.stream().write_all(&[0x7f, 0xde, 0xad, 0xbe, 0xef, 1, 2, 3]).unwrap();
    assert!(matches!(c.recv().unwrap(), Event::Error(e) if e.code == ErrorCode::Protocol && e.fatal));
    // An SE word with no SD word, then a hang-up.
    let mut c = connect(&s, Input::Words, PixelFormat::Png);
    c.send_words(&[0x0000_0005]).unwrap();
    drop(c);
    good();
    // A message over the size limit.
    let mut c = connect(&s, Input::Words, PixelFormat::Png);
    c.send(&vec![0u8; 8192]).unwrap_or(());
    match c.recv().unwrap() {
        Event::Error(e) => assert!(e.code == ErrorCode::Limit && e.fatal && e.message.contains("--max-message"), "{e}"),
        e => panic!("expected a limit error, got {e:?}"),
    }
    // A client that streams a looping program and never reads: dropped after the write
    // timeout, while the good client is served.
    let mut slow = connect(&s, Input::Assembly, PixelFormat::Rgb8);
    slow.send(b"nr\nsp 0, type, col, 1, 0xffff\nsp 0, zloc, zscl, -3, 1\nnf\nlr\n").unwrap();
    good();
    // 1,000 connections opened and dropped (half of them mid-hello): memory stays bounded.
    let rss_before = rss_kib();
    for i in 0..1000 {
        let mut t = TcpStream::connect(addr).unwrap();
        if i % 2 == 0 {
            let _ = t.write_all(&Hello { width: 0, ..hello(Input::Words, PixelFormat::Png) }.encode()[..7]);
        }
    }
    good();
    let t = Instant::now();
    while s.connections() > 1 && t.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(Duration::from_millis(50));
    }
    // Only the slow client may still be open (until its write timeout).
    assert!(s.connections() <= 1, "{} connections still open", s.connections());
    let growth = rss_kib().saturating_sub(rss_before);
    assert!(growth < 64 * 1024, "resident memory grew by {growth} KiB over 1,000 dropped connections");
    let t = Instant::now();
    while s.connections() > 0 && t.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(Duration::from_millis(50));
    }
    assert_eq!(s.connections(), 0, "the client that stopped reading was dropped");
    good();
    drop(slow);
}

fn rss_kib() -> u64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines().find(|l| l.starts_with("VmRSS:")).and_then(|l| l.split_whitespace().nth(1)?.parse().ok()).unwrap_or(0)
}

#[test]
fn connection_cap_and_idle_timeout() {
    let s = server(|c| {
        c.max_connections = 2;
        c.idle_timeout = Duration::from_secs(1);
    });
    let a = connect(&s, Input::Words, PixelFormat::Png);
    let mut b = connect(&s, Input::Words, PixelFormat::Png);
    match Client::connect(s.tcp_addr, &hello(Input::Words, PixelFormat::Png), Duration::from_secs(10)) {
        Err(rend3r_net::client::ClientError::Refused(e)) => assert_eq!(e.code, ErrorCode::Busy),
        Err(e) => panic!("expected a busy refusal, got {e}"),
        Ok(_) => panic!("a third connection was admitted over the cap of 2"),
    }
    drop(a);
    // Idle: no traffic for a second closes the connection with an error.
    match b.recv().unwrap() {
        Event::Error(e) => assert_eq!((e.code, e.fatal), (ErrorCode::Idle, true)),
        e => panic!("expected an idle error, got {e:?}"),
    }
    let t = Instant::now();
    while s.connections() > 0 && t.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(20));
    }
    let _c = connect(&s, Input::Words, PixelFormat::Png);
}

#[test]
fn shared_sessions_send_every_frame_to_every_client() {
    let s = server(|c| c.shared = true);
    let mut viewer = connect(&s, Input::Words, PixelFormat::Rgb8);
    let mut driver = connect(&s, Input::Assembly, PixelFormat::Png);
    assert_eq!(viewer.welcome.shared, 1);
    driver.send(b"nr\nsp 0, type, col, 1, 0x001f\nsp 0, zloc, zscl, -3, 1\nnf\n").unwrap();
    let d = frames(&until_done(&mut driver));
    assert_eq!(d.len(), 1);
    let Event::Frame(h, px) = viewer.recv().unwrap() else { panic!("the viewer gets the frame") };
    assert_eq!(h.number, d[0].0.number);
    assert_eq!(px, decode_png(&d[0].1), "same frame in both formats");
    // The viewer's words change the same scene.
    viewer.send_words(&assemble_words("sp 1, type, col, 1, 0xf800\nsp 1, xloc, zloc, 1, -3\nnf", AsmOptions::default()).unwrap()).unwrap();
    let v = frames(&until_done(&mut viewer));
    assert_eq!(v[0].0.shapes, 2, "both clients' shapes are in one scene");
    let Event::Frame(h, _) = driver.recv().unwrap() else { panic!("the driver sees the viewer's frame") };
    assert_eq!(h.shapes, 2);
}

#[test]
fn udp_batches_and_chunked_png_frames() {
    let s = server(|c| c.udp_chunk = 1024);
    let src = std::fs::read_to_string(rend3r("raytracing/sw/rt_spheres.rdr")).unwrap();
    let words = assemble_words(&src, AsmOptions::default()).unwrap();
    let want = run_locally(&words, SetKind::Shapes, Mode::Raytrace);
    let r = udp_exchange(s.udp_addr.unwrap(), &words, 60_000, Duration::from_secs(10)).unwrap();
    assert!(r.errors.is_empty(), "{:?}", r.errors);
    assert_eq!(r.frames.len(), want.len());
    assert_eq!(decode_png(&r.frames[0].1), want[0]);
    // A datagram that is not whole words gets an error datagram.
    let sock = std::net::UdpSocket::bind(loopback()).unwrap();
    sock.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    sock.send_to(&[1, 2, 3], s.udp_addr.unwrap()).unwrap();
    let mut b = [0u8; 2048];
    let n = sock.recv(&mut b).unwrap();
    assert_eq!(b[0], protocol::MSG_ERROR);
    assert!(protocol::ErrorMessage::decode(&b[1..n]).unwrap().message.contains("whole 4-byte words"));
}

fn http_get(addr: SocketAddr, path: &str) -> (String, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
    let mut b = Vec::new();
    s.read_to_end(&mut b).unwrap();
    let i = b.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    (String::from_utf8_lossy(&b[..i]).into_owned(), b[i + 4..].to_vec())
}

#[test]
fn http_page_examples_and_websocket() {
    let s = server(|c| c.examples = Some(rend3r("")));
    let http = s.http_addr.unwrap();
    let (head, body) = http_get(http, "/");
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    let page = String::from_utf8(body).unwrap();
    assert!(page.contains("<canvas") && page.contains("/ws") && !page.contains("https://"), "self-contained page");
    let (_, body) = http_get(http, "/programs");
    let names: Vec<String> = serde_json::from_slice(&body).unwrap();
    assert_eq!(names[0], "lucent/three-spheres.rdr");
    assert!(names.iter().any(|n| n == "raytracing/sw/rt_spheres.rdr"), "{names:?}");
    assert!(!names.iter().any(|n| n.contains("legacy-isa")));
    let (head, body) = http_get(http, "/programs/raytracing/sw/raytrace.rdr");
    assert!(head.starts_with("HTTP/1.1 200") && String::from_utf8_lossy(&body).contains("nf"));
    assert!(http_get(http, "/programs/../../../../etc/passwd").0.starts_with("HTTP/1.1 404"));
    assert!(http_get(http, "/nothing").0.starts_with("HTTP/1.1 404"));
    // The WebSocket: assembly in, JSON header and PNG frame out.
    let stream = TcpStream::connect(http).unwrap();
    let (mut ws, _) = tungstenite::client(format!("ws://{http}/ws"), stream).unwrap();
    let welcome = ws.read().unwrap();
    assert!(welcome.to_text().unwrap().contains("\"welcome\""));
    ws.send(tungstenite::Message::text(std::fs::read_to_string(rend3r("raytracing/sw/raytrace.rdr")).unwrap())).unwrap();
    let header = ws.read().unwrap();
    assert!(header.to_text().unwrap().contains("\"frame\""), "{header:?}");
    let png = ws.read().unwrap().into_data();
    let want = run_locally(
        &assemble_words(&std::fs::read_to_string(rend3r("raytracing/sw/raytrace.rdr")).unwrap(), AsmOptions::default()).unwrap(),
        SetKind::Shapes,
        Mode::Raytrace,
    );
    assert_eq!(decode_png(&png), want[0]);
    let done = ws.read().unwrap();
    assert!(done.to_text().unwrap().contains("\"done\""));
    ws.send(tungstenite::Message::text("nr\nbogus 1\n")).unwrap();
    let err = ws.read().unwrap();
    assert!(err.to_text().unwrap().contains("\"error\"") && err.to_text().unwrap().contains("\"line\":2"), "{err:?}");
}
