//! `lucent serve`, `lucent send` and `lucent bench net`.

use crate::stats::median;
use anyhow::{Context, Result};
use rend3r_net::client::{batches, save_frame, udp_exchange};
use rend3r_net::protocol::{Hello, Input, PixelFormat, WireMode};
use rend3r_net::{Client, Event, Server, ServerConfig};
use std::net::{SocketAddr, ToSocketAddrs};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The examples folder used when `--examples` is not given: REND3R's programs beside the
/// project, if they are there.
pub fn default_examples() -> Option<PathBuf> {
    ["../shared/rend3r/programs", "shared/rend3r/programs"].iter().map(PathBuf::from).find(|p| p.is_dir())
}

pub fn serve(cfg: ServerConfig) -> Result<()> {
    let server = Server::start(cfg.clone()).with_context(|| format!("cannot listen on {}", cfg.listen))?;
    println!("lucent serve: REND3R device protocol on tcp://{} (docs/protocol.md)", server.tcp_addr);
    if let Some(a) = server.udp_addr {
        println!("              UDP batches on udp://{a}");
    }
    if let Some(a) = server.http_addr {
        println!("              live page on http://{a}/");
    }
    println!(
        "              {}x{} {}, {}; limits: {} connections, {} B messages, {} shapes, {} lights; Ctrl-C stops",
        cfg.width,
        cfg.height,
        if cfg.mode == rend3r_machine::Mode::Raster { "raster" } else { "raytrace" },
        if cfg.shared { "one shared device" } else { "one device per connection" },
        cfg.max_connections,
        cfg.max_message,
        cfg.device.max_shapes,
        cfg.device.max_lights
    );
    server.wait();
    Ok(())
}

pub struct SendArgs {
    pub program: PathBuf,
    pub to: String,
    pub format: PixelFormat,
    pub frames: u64,
    pub size: Option<(u32, u32)>,
    pub mode: WireMode,
    pub udp: bool,
    pub camera_table_old: bool,
    pub output: PathBuf,
}

fn resolve(to: &str) -> Result<SocketAddr> {
    to.to_socket_addrs().with_context(|| format!("cannot resolve {to}"))?.next().ok_or_else(|| anyhow::anyhow!("{to}: no address"))
}

pub fn send(a: &SendArgs) -> Result<()> {
    let ext = a.program.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
    let addr = resolve(&a.to)?;
    std::fs::create_dir_all(&a.output).with_context(|| format!("cannot create {}", a.output.display()))?;
    if a.udp {
        return send_udp(a, addr, &ext);
    }
    let size = a.size.unwrap_or((0, 0));
    let hello = Hello {
        input: if ext == "rdr" { Input::Assembly } else { Input::Words },
        format: a.format,
        old_camera_table: a.camera_table_old,
        width: u16::try_from(size.0).context("--size: width over 65535")?,
        height: u16::try_from(size.1).context("--size: height over 65535")?,
        mode: a.mode,
    };
    let mut c = Client::connect(addr, &hello, Duration::from_secs(60)).with_context(|| format!("cannot connect to {}", a.to))?;
    let w = c.welcome;
    println!("connected to {addr}: {}x{} frames, {}", w.width, w.height, a.format.name());
    let mut sent = 0usize;
    if ext == "rdr" {
        let src = std::fs::read(&a.program).with_context(|| format!("cannot read {}", a.program.display()))?;
        if src.len() > w.max_message as usize {
            anyhow::bail!(
                "{}: {} bytes of assembly, over the server's {} byte message limit (send the assembled .mem instead)",
                a.program.display(),
                src.len(),
                w.max_message
            );
        }
        c.send(&src)?;
        sent += 1;
    } else {
        let words = crate::isa_cmd::read_words(&a.program)?;
        for b in batches(&words, w.max_message as usize) {
            c.send_words(b)?;
            sent += 1;
        }
    }
    let (mut frames, mut dones, mut errors) = (0u64, 0usize, 0usize);
    let start = Instant::now();
    while dones < sent && frames < a.frames {
        match c.recv()? {
            Event::Frame(h, px) => {
                frames += 1;
                let p = save_frame(&a.output, &h, &px).with_context(|| format!("cannot write into {}", a.output.display()))?;
                println!(
                    "frame {}: {} shapes, {} lights, rendered in {:.1} ms -> {}",
                    h.number,
                    h.shapes,
                    h.lights,
                    f64::from(h.render_us) / 1e3,
                    p.display()
                );
            }
            Event::Error(e) => {
                errors += 1;
                eprintln!("server error in {}: {e}", a.program.display());
                if e.fatal {
                    break;
                }
            }
            Event::Done(d) => {
                dones += 1;
                tracing::debug!(?d, "batch done");
            }
            Event::Closed => break,
        }
    }
    if frames >= a.frames && dones < sent {
        println!("stopped after {frames} frames (--frames); the program was still running");
    }
    println!("{frames} frames in {:.2} s", start.elapsed().as_secs_f64());
    if errors > 0 {
        anyhow::bail!("the server reported {errors} error(s)");
    }
    Ok(())
}

fn send_udp(a: &SendArgs, addr: SocketAddr, ext: &str) -> Result<()> {
    let words = if ext == "rdr" {
        crate::run_cmd::load_program(
            &a.program,
            if a.camera_table_old { rend3r_isa::CameraTable::Old } else { rend3r_isa::CameraTable::Final },
        )?
        .0
    } else {
        crate::isa_cmd::read_words(&a.program)?
    };
    let r = udp_exchange(addr, &words, 60_000, Duration::from_secs(5))?;
    for (n, png) in &r.frames {
        let p = a.output.join(format!("frame-{n:04}.png"));
        std::fs::write(&p, png).with_context(|| format!("cannot write {}", p.display()))?;
        println!("frame {n} -> {}", p.display());
    }
    for e in &r.errors {
        eprintln!("server error in {}: {e}", a.program.display());
    }
    if r.incomplete > 0 {
        eprintln!("{} frame(s) lost datagrams and were dropped (UDP does not retransmit)", r.incomplete);
    }
    if !r.errors.is_empty() {
        anyhow::bail!("the server reported {} error(s)", r.errors.len());
    }
    Ok(())
}

/// The scene of the network benchmark: `raytrace.rdr`'s sphere and light plus a second
/// sphere that moves every frame.
fn bench_setup() -> Vec<u32> {
    let src = "nr\ncam xloc, 0\ncam yloc, 0\ncam zloc, 0\nlt 0, xfor, 1\nlt 0, yfor, 1\nlt 0, zfor, -1\n\
               sp 0, xloc, yloc, 0, 0\nsp 0, zloc, type, -2, 1\nsp 0, col, zscl, 0b00000_000000_11111, 1\nsp 0, xscl, yscl, 1, 1\n\
               sp 1, xloc, yloc, 3, 0\nsp 1, zloc, type, -5, 1\nsp 1, col, zscl, 0b11111_111111_00000, 1\nsp 1, xscl, yscl, 0.5, 1\n";
    rend3r_isa::assemble_words(src, rend3r_isa::AsmOptions::default()).unwrap_or_default()
}

/// One frame's batch: move sphere 1 on a circle, then `nf`.
fn bench_move(i: u64) -> Vec<u32> {
    let a = i as f64 * 0.1;
    let src = format!("sp 1, xloc, yloc, {:.3}, {:.3}\nnf\n", 3.0 * a.cos(), 2.0 * a.sin());
    rend3r_isa::assemble_words(&src, rend3r_isa::AsmOptions::default()).unwrap_or_default()
}

fn pct(v: &[f64], p: f64) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v[((v.len() - 1) as f64 * p).round() as usize]
    }
}

pub fn bench(clients: &[usize], seconds: f64, size: (u32, u32), format: PixelFormat) -> Result<()> {
    let cfg = ServerConfig {
        listen: SocketAddr::from(([127, 0, 0, 1], 0)),
        width: size.0,
        height: size.1,
        max_connections: clients.iter().copied().max().unwrap_or(1) + 8,
        ..ServerConfig::default()
    };
    let server = Server::start(cfg)?;
    let addr = server.tcp_addr;
    let rss0 = crate::stats::proc_status_kib("VmRSS:").unwrap_or(0);
    println!(
        "{:>8} {:>10} {:>12} {:>14} {:>14} {:>12}",
        "clients", "fps/client", "fps total", "latency p50 ms", "latency p95 ms", "server MB"
    );
    for &n in clients {
        let deadline = Instant::now() + Duration::from_secs_f64(seconds);
        let hello = Hello { input: Input::Words, format, old_camera_table: false, width: 0, height: 0, mode: WireMode::Default };
        let threads: Vec<_> = (0..n)
            .map(|k| {
                std::thread::spawn(move || -> Result<Vec<f64>> {
                    let mut c = Client::connect(addr, &hello, Duration::from_secs(120))?;
                    c.send_words(&bench_setup())?;
                    wait_done(&mut c)?;
                    let mut lat = Vec::new();
                    let mut i = k as u64;
                    while Instant::now() < deadline {
                        let t = Instant::now();
                        c.send_words(&bench_move(i))?;
                        let mut got = false;
                        loop {
                            match c.recv()? {
                                Event::Frame(..) if !got => {
                                    lat.push(t.elapsed().as_secs_f64() * 1e3);
                                    got = true;
                                }
                                Event::Done(_) => break,
                                Event::Error(e) => anyhow::bail!("server error: {e}"),
                                Event::Closed => anyhow::bail!("server closed the connection"),
                                Event::Frame(..) => {}
                            }
                        }
                        i += 1;
                    }
                    Ok(lat)
                })
            })
            .collect();
        let peak = std::thread::spawn(move || {
            let mut peak = 0u64;
            while Instant::now() < deadline {
                peak = peak.max(crate::stats::proc_status_kib("VmRSS:").unwrap_or(0));
                std::thread::sleep(Duration::from_millis(50));
            }
            peak
        });
        let mut all = Vec::new();
        let mut per_client = Vec::new();
        for t in threads {
            let lat = t.join().map_err(|_| anyhow::anyhow!("a client thread panicked"))??;
            per_client.push(lat.len() as f64 / seconds);
            all.extend(lat);
        }
        let peak_mb = peak.join().unwrap_or(0).saturating_sub(rss0) as f64 / 1024.0;
        let total = all.len() as f64 / seconds;
        let p50 = median(&mut all);
        let p95 = pct(&all, 0.95);
        let fpc = median(&mut per_client);
        println!("{n:>8} {fpc:>10.1} {total:>12.1} {p50:>14.2} {p95:>14.2} {peak_mb:>12.1}");
        println!(
            "{}",
            serde_json::json!({"kind": "net_frames", "clients": n, "size": format!("{}x{}", size.0, size.1), "format": format.name(),
                "fps_per_client_median": fpc, "fps_total": total, "latency_p50_ms": p50, "latency_p95_ms": p95, "server_rss_growth_mb": peak_mb})
        );
    }
    // Words per second accepted: big batches of shape updates, no frames.
    let hello = Hello { input: Input::Words, format, old_camera_table: false, width: 0, height: 0, mode: WireMode::Default };
    let mut c = Client::connect(addr, &hello, Duration::from_secs(120))?;
    let max = c.welcome.max_message as usize / 4;
    let mut batch = Vec::with_capacity(max);
    let mut k = 0u32;
    while batch.len() + 4 <= max {
        let src = format!("sp {}, xloc, yloc, {}, 1", k % 4096, k % 7);
        batch.extend(rend3r_isa::assemble_words(&src, rend3r_isa::AsmOptions::default()).unwrap_or_default());
        k += 1;
    }
    batch.extend(rend3r_isa::assemble_words("er\ner", rend3r_isa::AsmOptions::default()).unwrap_or_default());
    let t = Instant::now();
    let mut words = 0u64;
    while t.elapsed().as_secs_f64() < seconds.min(3.0) {
        c.send_words(&batch)?;
        wait_done(&mut c)?;
        words += batch.len() as u64;
    }
    let wps = words as f64 / t.elapsed().as_secs_f64();
    println!("words accepted: {:.1} M words/s ({} words per batch, one connection)", wps / 1e6, batch.len());
    println!("{}", serde_json::json!({"kind": "net_words", "words_per_s": wps, "batch_words": batch.len()}));
    server.stop();
    Ok(())
}

fn wait_done(c: &mut Client) -> Result<()> {
    loop {
        match c.recv()? {
            Event::Done(_) => return Ok(()),
            Event::Error(e) => anyhow::bail!("server error: {e}"),
            Event::Closed => anyhow::bail!("server closed the connection"),
            Event::Frame(..) => {}
        }
    }
}

/// Frames the soak's well-formed clients cycle through (sphere 1 at one of this many
/// places), each rendered once locally as `lucent run` would.
const SOAK_POSES: u64 = 16;
/// The soak's frame size: small, so that the protocol and the server, not rendering, are
/// what is exercised.
const SOAK_SIZE: (u32, u32) = (48, 32);

/// The frame `lucent run` makes after the setup and pose `k` (RGB8, as sent with
/// `PixelFormat::Rgb8`).
fn soak_reference(k: u64) -> Result<Vec<u8>> {
    use rend3r_machine::{render_frame, FrameSettings, Mode, Processor, SetKind, Step};
    let mut words = bench_setup();
    words.extend(bench_move(k));
    let mut p = Processor::new(words, rend3r_isa::CameraTable::Final)?;
    anyhow::ensure!(p.run_to_frame(1_000_000) == Step::Frame, "the soak program has no frame");
    let fs = FrameSettings {
        width: SOAK_SIZE.0,
        height: SOAK_SIZE.1,
        mode: Mode::Raytrace,
        sets: SetKind::for_mode(Mode::Raytrace),
        painter: false,
        spp: 1,
    };
    Ok(render_frame(&p.state, &fs)?.0.to_srgb8())
}

/// What one hostile client does, again and again, until the soak ends.
#[derive(Clone, Copy, Debug)]
enum Hostile {
    Garbage,
    Truncated,
    Oversize,
    StalledReader,
    AbruptDisconnect,
    SlowWriter,
}

const HOSTILE: [Hostile; 6] =
    [Hostile::Garbage, Hostile::Truncated, Hostile::Oversize, Hostile::StalledReader, Hostile::AbruptDisconnect, Hostile::SlowWriter];

fn hostile_round(kind: Hostile, addr: SocketAddr, round: u64, stop: &std::sync::atomic::AtomicBool) {
    use std::io::Write;
    use std::sync::atomic::Ordering;
    let hello =
        Hello { input: Input::Words, format: PixelFormat::Rgb8, old_camera_table: false, width: 0, height: 0, mode: WireMode::Raytrace };
    let Ok(mut s) = std::net::TcpStream::connect(addr) else { return };
    let _ = s.set_write_timeout(Some(Duration::from_secs(2)));
    let mut x = round.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut noise = |n: usize| -> Vec<u8> {
        (0..n)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                x as u8
            })
            .collect()
    };
    match kind {
        Hostile::Garbage => {
            let _ = s.write_all(&noise(64 + (round % 4000) as usize));
        }
        Hostile::Truncated => {
            let _ = s.write_all(&hello.encode());
            let _ = s.write_all(&[rend3r_net::protocol::MSG_DATA, 0, 0, 0x10, 0]); // 4096 bytes announced
            let _ = s.write_all(&noise(100));
        }
        Hostile::Oversize => {
            let _ = s.write_all(&hello.encode());
            let _ = s.write_all(&[rend3r_net::protocol::MSG_DATA, 0x7F, 0xFF, 0xFF, 0xFF]);
            let _ = s.write_all(&noise(4096));
        }
        Hostile::StalledReader => {
            // Asks for many frames and never reads them.
            let _ = s.write_all(&hello.encode());
            let mut words = bench_setup();
            for i in 0..200 {
                words.extend(bench_move(i));
            }
            let _ =
                rend3r_net::protocol::write_message(&mut s, rend3r_net::protocol::MSG_DATA, &rend3r_net::protocol::words_to_bytes(&words));
            for _ in 0..40 {
                if stop.load(Ordering::Relaxed) {
                    break;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        }
        Hostile::AbruptDisconnect => {
            let _ = s.write_all(&hello.encode()[..7]);
        }
        Hostile::SlowWriter => {
            for b in hello.encode() {
                if s.write_all(&[b]).is_err() || stop.load(Ordering::Relaxed) {
                    break;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        }
    }
    drop(s);
}

/// `lucent bench net --soak`.
pub fn soak(clients: usize, frames: u64) -> Result<()> {
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::Arc;
    let panics = Arc::new(AtomicU64::new(0));
    {
        let panics = panics.clone();
        let old = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            panics.fetch_add(1, Ordering::Relaxed);
            old(info);
        }));
    }
    let refs: Arc<Vec<Vec<u8>>> = Arc::new((0..SOAK_POSES).map(soak_reference).collect::<Result<_>>()?);
    let cfg = ServerConfig {
        listen: SocketAddr::from(([127, 0, 0, 1], 0)),
        udp: None,
        http: None,
        width: SOAK_SIZE.0,
        height: SOAK_SIZE.1,
        max_connections: clients + 16,
        idle_timeout: Duration::from_secs(3),
        write_timeout: Duration::from_secs(2),
        ..ServerConfig::default()
    };
    let per_session = u64::from(cfg.max_message) + 3 * u64::from(SOAK_SIZE.0 * SOAK_SIZE.1 * 4);
    let server = Arc::new(Server::start(cfg.clone())?);
    let addr = server.tcp_addr;
    let n_hostile = clients.div_ceil(10).min(clients.saturating_sub(1));
    let n_good = clients - n_hostile;
    println!(
        "soak: {n_good} well-formed clients × {frames} frames, {n_hostile} hostile clients, {}x{} raytraced, loopback {addr}",
        SOAK_SIZE.0, SOAK_SIZE.1
    );
    let stop = Arc::new(AtomicBool::new(false));
    let done_frames = Arc::new(AtomicU64::new(0));
    let rss0 = crate::stats::proc_status_kib("VmRSS:").unwrap_or(0);
    let bar = indicatif::ProgressBar::new(n_good as u64 * frames);
    bar.set_style(indicatif::ProgressStyle::with_template("soak {bar:40} {pos}/{len} frames ({eta})")?);
    let hostile: Vec<_> = (0..n_hostile)
        .map(|h| {
            let stop = stop.clone();
            let kind = HOSTILE[h % HOSTILE.len()];
            std::thread::spawn(move || {
                let mut round = 0u64;
                while !stop.load(Ordering::Relaxed) {
                    hostile_round(kind, addr, round * 64 + h as u64, &stop);
                    round += 1;
                }
                (kind, round)
            })
        })
        .collect();
    let good: Vec<_> = (0..n_good)
        .map(|k| {
            let (refs, done_frames, bar) = (refs.clone(), done_frames.clone(), bar.clone());
            std::thread::spawn(move || -> Result<(u64, u64, Vec<f64>, u64)> {
                let hello = Hello {
                    input: Input::Words,
                    format: PixelFormat::Rgb8,
                    old_camera_table: false,
                    width: 0,
                    height: 0,
                    mode: WireMode::Raytrace,
                };
                // A busy server refuses a connection (hostile clients may hold every slot for
                // a moment): a well-formed client waits and tries again, as a real one would.
                let mut refused = 0u64;
                let mut c = loop {
                    match Client::connect(addr, &hello, Duration::from_secs(60)) {
                        Ok(c) => break c,
                        Err(rend3r_net::client::ClientError::Refused(e))
                            if e.code == rend3r_net::protocol::ErrorCode::Busy && refused < 1000 =>
                        {
                            refused += 1;
                            std::thread::sleep(Duration::from_millis(5 + 5 * refused.min(20)));
                        }
                        Err(e) => anyhow::bail!("client {k}: {e}"),
                    }
                };
                c.send_words(&bench_setup())?;
                wait_done(&mut c)?;
                let (mut lost, mut wrong, mut lat) = (0u64, 0u64, Vec::with_capacity(frames as usize));
                for i in 0..frames {
                    let pose = (i + k as u64) % SOAK_POSES;
                    let t = Instant::now();
                    c.send_words(&bench_move(pose))?;
                    let mut got = 0;
                    loop {
                        match c.recv()? {
                            Event::Frame(_, px) => {
                                got += 1;
                                lat.push(t.elapsed().as_secs_f64() * 1e3);
                                wrong += u64::from(px != refs[pose as usize]);
                            }
                            Event::Done(_) => break,
                            Event::Error(e) => anyhow::bail!("client {k}: server error: {e}"),
                            Event::Closed => anyhow::bail!("client {k}: the server closed the connection at frame {i}"),
                        }
                    }
                    lost += u64::from(got != 1);
                    done_frames.fetch_add(1, Ordering::Relaxed);
                    bar.inc(1);
                }
                Ok((lost, wrong, lat, refused))
            })
        })
        .collect();
    // The server's memory (this process's RSS) over time.
    let sampler = {
        let (stop, done_frames, server) = (stop.clone(), done_frames.clone(), server.clone());
        std::thread::spawn(move || {
            let t0 = Instant::now();
            let mut series = Vec::new();
            while !stop.load(Ordering::Relaxed) {
                let rss = crate::stats::proc_status_kib("VmRSS:").unwrap_or(0);
                series.push((t0.elapsed().as_secs_f64(), done_frames.load(Ordering::Relaxed), rss, server.connections()));
                std::thread::sleep(Duration::from_millis(if std::env::var_os("LUCENT_SOAK_TRACE").is_some() { 5 } else { 250 }));
            }
            series
        })
    };
    let t0 = Instant::now();
    let (mut lost, mut wrong, mut lat, mut failed, mut refused) = (0u64, 0u64, Vec::new(), Vec::new(), 0u64);
    for g in good {
        match g.join() {
            Ok(Ok((l, w, v, r))) => {
                lost += l;
                wrong += w;
                lat.extend(v);
                refused += r;
            }
            Ok(Err(e)) => failed.push(e.to_string()),
            Err(_) => failed.push("a client thread panicked".into()),
        }
    }
    let secs = t0.elapsed().as_secs_f64();
    stop.store(true, Ordering::Relaxed);
    bar.finish_and_clear();
    let rounds: Vec<(Hostile, u64)> = hostile.into_iter().filter_map(|h| h.join().ok()).collect();
    let series = sampler.join().unwrap_or_default();
    server.stop();
    let expected = n_good as u64 * frames;
    // Frames of a failed client count as lost.
    let received = lat.len() as u64;
    let lost = lost + expected.saturating_sub(done_frames.load(Ordering::Relaxed));
    let p50 = median(&mut lat);
    let p95 = pct(&lat, 0.95);
    let mb = |kib: u64| kib as f64 / 1024.0;
    let peak = series.iter().map(|s| s.2).max().unwrap_or(rss0);
    println!("time {secs:.1} s, {:.0} frames/s", received as f64 / secs);
    println!("frames: expected {expected}, received {received}, lost {lost}, wrong {wrong}");
    println!("latency per frame: p50 {p50:.2} ms, p95 {p95:.2} ms");
    println!("connections of well-formed clients refused as busy (then retried): {refused}");
    println!("hostile rounds: {}", rounds.iter().map(|(k, n)| format!("{k:?} {n}")).collect::<Vec<_>>().join(", "));
    println!(
        "server RSS: start {:.1} MB, peak {:.1} MB (bound from the limits: {} sessions × {:.1} MB = {:.1} MB above the start)",
        mb(rss0),
        mb(peak),
        cfg.max_connections,
        per_session as f64 / 1048576.0,
        (cfg.max_connections as u64 * per_session) as f64 / 1048576.0
    );
    let step = (series.len() / 10).max(1);
    for s in series.iter().step_by(step) {
        println!("  t {:>7.2} s  frames {:>9}  RSS {:>7.1} MB  connections {:>4}", s.0, s.1, mb(s.2), s.3);
    }
    let n_panics = panics.load(Ordering::Relaxed);
    println!("panics: {n_panics}");
    println!(
        "{}",
        serde_json::json!({"kind": "net_soak", "clients": clients, "hostile": n_hostile, "frames_per_client": frames,
            "expected": expected, "received": received, "lost": lost, "wrong": wrong, "latency_p50_ms": p50, "latency_p95_ms": p95,
            "rss_start_mb": mb(rss0), "rss_peak_mb": mb(peak), "panics": n_panics, "seconds": secs, "busy_refusals": refused})
    );
    for f in &failed {
        eprintln!("soak: {f}");
    }
    let bound = rss0 + cfg.max_connections as u64 * per_session / 1024;
    anyhow::ensure!(
        failed.is_empty() && lost == 0 && wrong == 0 && n_panics == 0,
        "soak failed: {lost} lost, {wrong} wrong, {n_panics} panics"
    );
    anyhow::ensure!(peak <= bound, "server memory {:.1} MB above the documented bound {:.1} MB", mb(peak), mb(bound));
    Ok(())
}
