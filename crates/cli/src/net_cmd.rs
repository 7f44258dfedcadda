//! `lucent serve`, `lucent send` and `lucent bench net`.

use crate::stats::median;
use anyhow::{Context, Result};
use lucent_net::client::{batches, save_frame, udp_exchange};
use lucent_net::protocol::{Hello, Input, PixelFormat, WireMode};
use lucent_net::{Client, Event, Server, ServerConfig};
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
        if cfg.mode == lucent_engine::Mode::Raster { "raster" } else { "raytrace" },
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
            if a.camera_table_old { lucent_isa::CameraTable::Old } else { lucent_isa::CameraTable::Final },
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
    lucent_isa::assemble_words(src, lucent_isa::AsmOptions::default()).unwrap_or_default()
}

/// One frame's batch: move sphere 1 on a circle, then `nf`.
fn bench_move(i: u64) -> Vec<u32> {
    let a = i as f64 * 0.1;
    let src = format!("sp 1, xloc, yloc, {:.3}, {:.3}\nnf\n", 3.0 * a.cos(), 2.0 * a.sin());
    lucent_isa::assemble_words(&src, lucent_isa::AsmOptions::default()).unwrap_or_default()
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
        batch.extend(lucent_isa::assemble_words(&src, lucent_isa::AsmOptions::default()).unwrap_or_default());
        k += 1;
    }
    batch.extend(lucent_isa::assemble_words("er\ner", lucent_isa::AsmOptions::default()).unwrap_or_default());
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
