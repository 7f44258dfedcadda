//! The command line end to end.

use std::path::Path;
use std::process::Command;

fn lucent() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lucent"))
}

#[test]
fn render_demo_writes_a_real_picture() {
    let d = tempfile::tempdir().expect("tmp");
    // The default: the path-traced studio.
    let out = d.path().join("studio.png");
    let o = lucent().args(["render", "--size", "160x120", "--spp", "8", "--threads", "2", "-o"]).arg(&out).output().expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("Mrays/s") && text.contains("build") && text.contains("8 spp"), "{text}");
    let img = image::open(&out).expect("png").to_rgb8();
    assert_eq!(img.dimensions(), (160, 120));
    // The red wall on the left, the green one on the right, the light at the top: means
    // over patches (a path-traced image is noisy pixel by pixel).
    let patch = |x0: u32, y0: u32| {
        let mut s = [0f32; 3];
        for y in y0..y0 + 8 {
            for x in x0..x0 + 8 {
                for (k, c) in img.get_pixel(x, y).0.iter().enumerate() {
                    s[k] += f32::from(*c) / 64.0;
                }
            }
        }
        s
    };
    let (left, right, light) = (patch(4, 50), patch(148, 50), patch(76, 0));
    assert!(left[0] > 1.5 * left[1] && left[0] > 1.5 * left[2], "left wall {left:?}");
    assert!(right[1] > 1.3 * right[0] && right[1] > 1.3 * right[2], "right wall {right:?}");
    assert!(light.iter().all(|&c| c > 200.0), "light {light:?}");
    let mut colours: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() > 500, "only {} colours", colours.len());
    // Whitted, one flag away: the feature demo (blue sky on top).
    let out = d.path().join("demo.png");
    let o =
        lucent().args(["render", "--integrator", "whitted", "--size", "160x120", "--threads", "2", "-o"]).arg(&out).output().expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&out).expect("png").to_rgb8();
    let sky = img.get_pixel(80, 2).0;
    assert!(sky[2] > sky[0], "sky {sky:?}");
}

/// The path tracer on the Cornell box for a time budget: samples are added pass by pass
/// until it is spent (or until --spp caps them), the light and the red and green walls
/// show, and the samples per second are reported.
#[test]
fn render_path_for_a_time_budget() {
    let d = tempfile::tempdir().expect("tmp");
    let out = d.path().join("cb.exr");
    let cornell = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes/cornell_box/cornell_box.obj");
    let cam = "278,273,-800,278,273,0,0,1,0,39.3";
    let args = ["--integrator", "path", "--size", "48x48", "--camera", cam, "--threads", "2", "-o"];
    let o = lucent().arg("render").arg(&cornell).args(["--time", "0.5"]).args(args).arg(&out).output().expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let spp: u32 = text.split(" spp").next().and_then(|t| t.rsplit(' ').next()).and_then(|n| n.parse().ok()).expect("spp reported");
    assert!(spp >= 2 && text.contains("M samples/s"), "{text}");
    let img = image::open(&out).expect("exr").to_rgb32f();
    let (left, right, top) = (img.get_pixel(3, 24).0, img.get_pixel(44, 24).0, img.get_pixel(24, 3).0);
    assert!(left[0] > 2.0 * left[1] && right[1] > 2.0 * right[0], "walls: left {left:?}, right {right:?}");
    assert!(top.iter().all(|&c| c > 0.05), "the ceiling is lit: {top:?}");
    // --spp caps the samples a budget may add.
    let o = lucent().arg("render").arg(&cornell).args(["--time", "30", "--spp", "3"]).args(args).arg(&out).output().expect("run");
    assert!(String::from_utf8_lossy(&o.stdout).contains(", 3 spp,"), "{}", String::from_utf8_lossy(&o.stdout));
    let o = lucent().args(["render", "--time", "0", "-o"]).arg(&out).output().expect("run");
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--time"));
}

/// The VPL integrator and the denoiser from the command line, on the Cornell box: the
/// walls show their colours, the ceiling is lit by indirect light only, the denoised
/// image keeps the raw one's mean, and bad VPL options are refused.
#[test]
fn render_vpl_and_denoise() {
    let d = tempfile::tempdir().expect("tmp");
    let cornell = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes/cornell_box/cornell_box.obj");
    let cam = "278,273,-800,278,273,0,0,1,0,39.3";
    let mean = |p: &Path| {
        let img = image::open(p).expect("exr").to_rgb32f();
        (img.pixels().map(|p| f64::from(p.0[0] + p.0[1] + p.0[2])).sum::<f64>(), img)
    };
    let mut means = Vec::new();
    for extra in [&[][..], &["--denoise"][..]] {
        let out = d.path().join(format!("vpl{}.exr", extra.len()));
        let o = lucent()
            .arg("render")
            .arg(&cornell)
            .args(["--integrator", "vpl", "--size", "64x64", "--camera", cam, "--threads", "2", "-o"])
            .arg(&out)
            .args(extra)
            .output()
            .expect("run");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let (m, img) = mean(&out);
        let (left, right, top) = (img.get_pixel(4, 32).0, img.get_pixel(59, 32).0, img.get_pixel(32, 4).0);
        assert!(left[0] > 2.0 * left[1] && right[1] > 2.0 * right[0], "walls: left {left:?}, right {right:?}");
        assert!(top.iter().all(|&c| c > 0.02), "the ceiling is lit: {top:?}");
        means.push(m);
    }
    assert!((means[1] / means[0] - 1.0).abs() < 0.02, "denoising changed the mean: {means:?}");
    let o =
        lucent().arg("render").arg(&cornell).args(["--integrator", "vpl", "--interleave", "0", "-o", "/tmp/x.png"]).output().expect("run");
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--interleave"));
}

/// `--denoise` picks its denoiser: path tracing from 4 samples per pixel gets the
/// regression over the samples' halves (the image's mean kept within 1%), `--denoiser
/// atrous` the à-trous filter, and a request the regression cannot take (2 samples) falls
/// back to the à-trous filter.
#[test]
fn denoise_chooses_its_denoiser() {
    let d = tempfile::tempdir().expect("tmp");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/mitsuba/scenes/cornell_box.xml");
    let run = |extra: &[&str], name: &str| {
        let out = d.path().join(name);
        let o = lucent().arg("render").arg(&scene).args(["--threads", "2", "-o"]).arg(&out).args(extra).output().expect("run");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let img = image::open(&out).expect("exr").to_rgb32f();
        (String::from_utf8_lossy(&o.stdout).into_owned(), img.pixels().map(|p| f64::from(p.0[0] + p.0[1] + p.0[2])).sum::<f64>())
    };
    let (text, m_den) = run(&["--spp", "4", "--denoise"], "r.exr");
    assert!(text.contains("denoised (regression over the samples' halves)"), "{text}");
    let (_, m_raw) = run(&["--spp", "4"], "raw.exr");
    assert!((m_den / m_raw - 1.0).abs() < 0.01, "mean {m_den} denoised against {m_raw}");
    let (text, _) = run(&["--spp", "4", "--denoise", "--denoiser", "atrous"], "a.exr");
    assert!(text.contains("denoised (à-trous) in"), "{text}");
    let (text, _) = run(&["--spp", "2", "--denoise", "--denoiser", "regression"], "f.exr");
    assert!(text.contains("denoised (à-trous) in"), "{text}");
}

/// Output piped into a reader that stops early (`lucent disasm … | head -2`) ends the
/// command quietly, as `cat` does, not with a panic about a broken pipe.
#[cfg(unix)]
#[test]
fn a_closed_output_pipe_ends_quietly() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    // 40,000 `nf` words disassemble to 120 KB, more than a pipe holds: the writer meets the
    // closed pipe whenever the reader goes.
    let d = tempfile::tempdir().expect("tmp");
    let mem = d.path().join("many.mem");
    std::fs::write(&mem, "00000400\n".repeat(40_000)).expect("write");
    let mut child = lucent().arg("disasm").arg(&mem).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("run");
    drop(child.stdout.take());
    let o = child.wait_with_output().expect("wait");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(o.status.signal(), Some(13), "ended by SIGPIPE: {:?} {err}", o.status);
}

#[test]
fn render_errors_are_clear() {
    let o = lucent().args(["render", "/no/such/scene.obj", "-o", "/tmp/x.png"]).output().expect("run");
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("/no/such/scene.obj"), "{e}");
    let o = lucent().args(["render", "--size", "12"]).output().expect("run");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("WIDTHxHEIGHT"));
    let o = lucent().args(["render", "--camera", "1,2,3", "-o", "/tmp/x.png"]).output().expect("run");
    assert!(String::from_utf8_lossy(&o.stderr).contains("10 finite numbers"));
}

/// Without the `mpi` feature, `--mpi` says how to get it (and nothing else changes: the
/// other tests run on this build).
#[cfg(not(feature = "mpi"))]
#[test]
fn mpi_without_the_feature_says_how_to_build_it() {
    for cmd in [&["render", "-o", "/tmp/never.png"][..], &["animate", "-o", "/tmp/never"], &["view"]] {
        let o = lucent().args(cmd).arg("--mpi").output().expect("run");
        assert!(!o.status.success());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains("built without MPI") && e.contains("--features mpi"), "{cmd:?}: {e}");
    }
}

#[test]
fn info_prints_counts() {
    let o = lucent().arg("info").output().expect("run");
    assert!(o.status.success());
    // Building the acceleration structures prints nothing (libraries log through tracing).
    assert!(o.stderr.is_empty(), "unexpected stderr: {}", String::from_utf8_lossy(&o.stderr));
    let t = String::from_utf8_lossy(&o.stdout);
    assert!(t.contains("triangles:  2306") && t.contains("lights:     2") && t.contains("bytes"), "{t}");
}

fn put_u32(b: &mut Vec<u8>, v: u32) {
    b.extend_from_slice(&v.to_le_bytes());
}

/// Writes a dump in the harness's format: the unit square as two triangles and 16 rays down
/// -z at y = 0.5 and x = 0.05, 0.15, ..., 1.55: the first ten hit.
fn write_dump(dir: &Path) {
    let mut m = b"RTBMESH1".to_vec();
    put_u32(&mut m, 4);
    put_u32(&mut m, 2);
    for v in [0f32, 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.] {
        m.extend_from_slice(&v.to_le_bytes());
    }
    for i in [0u32, 1, 2, 0, 2, 3] {
        put_u32(&mut m, i);
    }
    std::fs::write(dir.join("mesh.bin"), m).expect("mesh");
    for kind in ["primary", "shadow", "diffuse"] {
        let mut r = b"RTBRAYS1".to_vec();
        for v in [4u32, 4, 2, 16] {
            put_u32(&mut r, v);
        }
        for blk in 0..2 {
            let lane = |l: usize| (blk * 8 + l) as f32;
            let rows: [[f32; 8]; 7] = [
                std::array::from_fn(|l| 0.05 + lane(l) * 0.1),
                [0.5; 8],
                [1.0; 8],
                [0.0; 8],
                [0.0; 8],
                [-1.0; 8],
                [if kind == "shadow" { 2.0 } else { f32::INFINITY }; 8],
            ];
            for row in rows {
                for v in row {
                    r.extend_from_slice(&v.to_le_bytes());
                }
            }
            for _ in 0..8 {
                r.extend_from_slice(&(-1i32).to_le_bytes());
            }
            for l in 0..8 {
                r.extend_from_slice(&((blk * 8 + l) as i32).to_le_bytes());
            }
        }
        std::fs::write(dir.join(format!("rays_{kind}.bin")), r).expect("rays");
    }
    // Triangle 0 = (0,0),(1,0),(1,1) holds y < x; triangle 1 holds y > x.
    let ids: Vec<u8> = (0..16)
        .flat_map(|i: i32| {
            (match i {
                0..=4 => 1i32,
                5..=9 => 0,
                _ => -1,
            })
            .to_le_bytes()
        })
        .collect();
    std::fs::write(dir.join("ref_ids.bin"), ids).expect("ids");
}

#[test]
fn bench_rays_reads_the_harness_format() {
    let d = tempfile::tempdir().expect("tmp");
    write_dump(d.path());
    let o = lucent()
        .args(["bench", "rays"])
        .arg(d.path())
        .args(["--name", "t", "--threads", "1,2", "--frames", "3", "--warmup", "1"])
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let t = String::from_utf8_lossy(&o.stdout);
    let lines: Vec<&str> = t.lines().filter(|l| l.starts_with('{')).collect();
    assert_eq!(lines.iter().filter(|l| l.contains("\"kind\":\"build\"")).count(), 2, "{t}");
    // One line per kernel (single rays, 8- and 64-ray packets) and thread count, all with
    // the same answers.
    let primary: Vec<&&str> = lines.iter().filter(|l| l.contains("\"kind\":\"primary\"")).collect();
    assert_eq!(primary.len(), 6, "{t}");
    for api in ["single", "packet8", "packet64"] {
        assert_eq!(primary.iter().filter(|l| l.contains(&format!("\"api\":\"{api}-"))).count(), 2, "{api}: {t}");
    }
    for l in &primary {
        assert!(l.contains("\"hits\":10") && l.contains("\"diff_px_vs_ref\":0") && l.contains("\"mrays_s\":"), "{l}");
    }
    let shadow: Vec<&&str> = lines.iter().filter(|l| l.contains("\"kind\":\"shadow\"")).collect();
    assert_eq!(shadow.len(), 6, "{t}");
    for l in shadow {
        assert!(l.contains("\"occluded\":10"), "{l}");
    }
    // SaarCOR's kd-tree on the same rays: single rays and 4-ray packets, the same answers.
    let o = lucent()
        .args(["bench", "rays"])
        .arg(d.path())
        .args(["--name", "t", "--threads", "1", "--frames", "1", "--warmup", "0", "--index", "kd"])
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let t = String::from_utf8_lossy(&o.stdout);
    let kd: Vec<&str> = t.lines().filter(|l| l.starts_with('{')).collect();
    assert!(kd[0].contains("\"kind\":\"build\"") && kd[0].contains("\"bvh\":\"kd\""), "{t}");
    for api in ["single-kd", "packet4-kd"] {
        let l: Vec<&&str> = kd.iter().filter(|l| l.contains(&format!("\"api\":\"{api}\""))).collect();
        assert_eq!(l.len(), 3, "{api}: one line per kind: {t}");
        assert!(l[0].contains("\"hits\":10") && l[0].contains("\"diff_px_vs_ref\":0"), "{}", l[0]);
        assert!(l[1].contains("\"occluded\":10"), "{}", l[1]);
    }
    // Bad input: a truncated file gives a clear error.
    std::fs::write(d.path().join("mesh.bin"), b"RTBMESH1\x05\0\0\0").expect("cut");
    let o = lucent().args(["bench", "rays"]).arg(d.path()).output().expect("run");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("mesh.bin"));
}

fn rend3r(rel: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/rend3r/programs").join(rel)
}

#[test]
fn asm_and_disasm_commands() {
    let d = tempfile::tempdir().expect("tmp");
    let mem = d.path().join("rt.mem");
    let o = lucent().arg("asm").arg(rend3r("raytracing/sw/raytrace.rdr")).arg("-o").arg(&mem).output().expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(&mem).expect("mem"), std::fs::read(rend3r("raytracing/data/main.mem")).expect("ref"));
    // Binary output: network byte order.
    let bin = d.path().join("rt.bin");
    assert!(lucent().arg("asm").arg(rend3r("raytracing/sw/raytrace.rdr")).arg("-o").arg(&bin).status().expect("run").success());
    assert_eq!(&std::fs::read(&bin).expect("bin")[..8], &[0, 0, 2, 0, 0, 0, 8, 1]);
    // Old camera table.
    let old = d.path().join("old.mem");
    assert!(lucent()
        .arg("asm")
        .arg(rend3r("taping/sw/raster.rdr"))
        .args(["--camera-table", "old", "-o"])
        .arg(&old)
        .status()
        .expect("run")
        .success());
    assert_eq!(std::fs::read(&old).expect("mem"), std::fs::read(rend3r("taping-min-dram/data/main.mem")).expect("ref"));
    // Disassembly of both forms reassembles to the same words.
    for f in [&mem, &bin] {
        let o = lucent().arg("disasm").arg(f).output().expect("run");
        assert!(o.status.success());
        let src = d.path().join("back.rdr");
        std::fs::write(&src, &o.stdout).expect("write");
        let again = d.path().join("back.mem");
        assert!(lucent().arg("asm").arg(&src).arg("-o").arg(&again).status().expect("run").success());
        assert_eq!(std::fs::read(&again).expect("again"), std::fs::read(&mem).expect("mem"));
    }
    // Errors: line:column, and no backtrace.
    let bad = d.path().join("bad.rdr");
    std::fs::write(&bad, "nr\nlt 99, xfor, 1\n").expect("write");
    let o = lucent().arg("asm").arg(&bad).env("RUST_BACKTRACE", "1").output().expect("run");
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("bad.rdr:2:4: light index 99 out of range (0..=63)") && !e.contains("backtrace"), "{e}");
    let cut = d.path().join("cut.bin");
    std::fs::write(&cut, [0u8, 0, 0x1b, 0x45]).expect("write");
    let o = lucent().arg("disasm").arg(&cut).output().expect("run");
    assert!(String::from_utf8_lossy(&o.stderr).contains("word 0: shape/triangle set"), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Kills the server when the test ends, whatever happens.
struct Child(std::process::Child);
impl Drop for Child {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn serve_and_send_give_the_frames_of_run() {
    use std::io::BufRead;
    let d = tempfile::tempdir().expect("tmp");
    let mut child = lucent()
        .args(["serve", "--listen", "127.0.0.1:0", "--udp", "127.0.0.1:0", "--no-http"])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("serve");
    let out = child.stdout.take().expect("stdout");
    let _guard = Child(child);
    let mut lines = std::io::BufReader::new(out).lines();
    let mut addr = |scheme: &str| -> String {
        let l = lines.next().expect("a line").expect("utf-8");
        let at = l.find(scheme).unwrap_or_else(|| panic!("{scheme} in {l}"));
        l[at + scheme.len()..].split_whitespace().next().expect("address").to_string()
    };
    let tcp = addr("tcp://");
    let udp = addr("udp://");
    let prog = rend3r("raytracing/sw/rt_spheres.rdr");
    let run = d.path().join("run");
    assert!(lucent().arg("run").arg(&prog).arg("-o").arg(&run).status().expect("run").success());
    let want = image::open(run.join("frame-0001.png")).expect("run png").to_rgb8();
    for (name, extra) in [("tcp", vec!["--to", tcp.as_str()]), ("udp", vec!["--udp", "--to", udp.as_str()])] {
        let dir = d.path().join(name);
        let o = lucent().arg("send").arg(&prog).args(&extra).arg("-o").arg(&dir).output().expect("send");
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        let got = image::open(dir.join("frame-0001.png")).expect("sent png").to_rgb8();
        assert!(got == want, "{name}: the served frame differs from lucent run's");
    }
    // A program with an error: the server's message with line:column, and a failure exit.
    let bad = d.path().join("bad.rdr");
    std::fs::write(&bad, "nr\ncam xloc, 0\nsp 0, xloc, yloc, 1\n").expect("write");
    let o = lucent().arg("send").arg(&bad).args(["--to", tcp.as_str()]).arg("-o").arg(d.path().join("bad")).output().expect("send");
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("bad.rdr: 3:") && e.contains("server reported 1 error"), "{e}");
}

/// `bench frame` times shaded frames on a harness preset (packets and single rays, the
/// same rays traced) and refuses an unknown preset by name.
#[test]
fn bench_frame_reports_shaded_frames() {
    let scenes = std::env::var("LUCENT_SCENES")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|_| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"));
    let o = lucent()
        .args(["bench", "frame", "museum", "--sizes", "64x48", "--frames", "2", "--threads", "1", "--dir"])
        .arg(&scenes)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let t = String::from_utf8_lossy(&o.stdout);
    let lines: Vec<serde_json::Value> = t.lines().filter_map(|l| serde_json::from_str(l).ok()).collect();
    assert_eq!(lines.len(), 2, "{t}");
    for l in &lines {
        assert_eq!(l["kind"], "frame");
        assert!(l["fps"].as_f64().is_some_and(|f| f > 0.0), "{l}");
        // Primary rays for every pixel plus shadow rays toward the one light.
        assert!(l["rays"].as_u64().is_some_and(|r| r > 64 * 48), "{l}");
    }
    assert_eq!(lines[0]["rays"], lines[1]["rays"], "packets and single rays trace the same rays");
    let o = lucent().args(["bench", "frame", "nosuch"]).output().expect("run");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("unknown scene preset 'nosuch'"));
}

#[test]
fn bench_rend3r_times_the_chosen_rows() {
    let o = lucent()
        .args(["bench", "rend3r", "--spheres", "16,256", "--lights", "1", "--frames", "1", "--size", "64x48"])
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let e = String::from_utf8_lossy(&o.stderr);
    let rows: Vec<serde_json::Value> = e.lines().filter_map(|l| serde_json::from_str(l).ok()).collect();
    assert_eq!(rows.len(), 2, "{e}");
    for (r, n) in rows.iter().zip([16, 256]) {
        assert_eq!((r["kind"].as_str(), r["spheres"].as_u64(), r["lights"].as_u64()), (Some("rend3r_frame"), Some(n), Some(1)), "{r}");
        assert!(r["median_ms"].as_f64().is_some_and(|m| m > 0.0), "{r}");
    }
    assert!(String::from_utf8_lossy(&o.stdout).contains("| 256 | 1 |"));
    let o = lucent().args(["bench", "rend3r", "--lights", "2"]).output().expect("run");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--lights 2: Table IV's rows have 0 or 1 lights"));
}

/// `lucent run` ends on a program that loops without `nf`, with the same clear error in the
/// main path and in the board model, and reports where a halting program stopped.
#[test]
fn run_ends_on_a_loop_without_frames() {
    let d = tempfile::tempdir().expect("tmp");
    let looping = d.path().join("loop.rdr");
    std::fs::write(&looping, "nr\nlr\n").expect("write");
    for extra in [&[][..], &["--compat", "board"][..]] {
        let o = lucent().arg("run").arg(&looping).args(extra).arg("-o").arg(d.path().join("out")).output().expect("run");
        assert!(!o.status.success(), "{extra:?}: a runaway loop must fail");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains("loop.rdr") && e.contains("without reaching nf or er"), "{extra:?}: {e}");
    }
    let halting = d.path().join("halt.rdr");
    std::fs::write(&halting, "nr\nnf\ner\n").expect("write");
    for extra in [&[][..], &["--compat", "board"][..]] {
        let o = lucent().arg("run").arg(&halting).args(extra).arg("-o").arg(d.path().join("halt")).output().expect("run");
        assert!(o.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&o.stderr));
        let s = String::from_utf8_lossy(&o.stdout);
        assert!(s.contains("program halted after 1 frames"), "{extra:?}: {s}");
    }
}

/// Every SIMD intrinsic in the release binary is inlined into a kernel compiled with its
/// CPU features. One left as a function of its own means some kernel code was compiled
/// without them (a closure does not take its caller's `target_feature`, and LLVM may leave
/// one out of line), and every intrinsic there is a call: session 25 found single rays 4-5
/// times slower, and incoherent packets' fallbacks 3 times slower, that way. Only
/// `_xgetbv` (the standard library's feature detection) may stand alone. Needs `nm`
/// (binutils); debug builds inline nothing, so it runs in release builds only.
#[test]
#[cfg_attr(debug_assertions, ignore = "inlining is only meaningful in release builds")]
fn no_simd_intrinsic_is_left_out_of_line() {
    let o = Command::new("nm")
        .args(["-C", env!("CARGO_BIN_EXE_lucent")])
        .output()
        .expect("this test reads the binary's symbols with nm (Debian package binutils)");
    assert!(o.status.success(), "nm: {}", String::from_utf8_lossy(&o.stderr));
    let symbols = String::from_utf8_lossy(&o.stdout);
    let outlined: Vec<&str> = symbols.lines().filter(|l| l.contains("core::core_arch::x86::") && !l.contains("_xgetbv")).collect();
    assert!(outlined.is_empty(), "intrinsics compiled as functions of their own:\n{}", outlined.join("\n"));
}

/// Every input that once broke lucent (`../shared/scenes/regressions/`, see its README) goes
/// through the commands a new user runs first, with the default build: `info` and a small
/// `render` succeed, with no panic. The first was `reinsert_root.obj`, whose default build
/// (`--quality high`) panicked in the reinsertion (a move beside the root, undone).
#[test]
fn every_regression_input_loads_and_renders() {
    let scenes = std::env::var("LUCENT_SCENES")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|_| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes"));
    let dir = scenes.join("regressions");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x != "md"))
        .collect();
    files.sort();
    assert!(files.iter().any(|f| f.ends_with("reinsert_root.obj")), "regressions: {files:?}");
    let d = tempfile::tempdir().expect("tmp");
    for f in &files {
        let o = lucent().arg("info").arg(f).output().expect("run");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success() && !err.contains("panicked"), "info {}: {err}", f.display());
        let out = d.path().join("r.png");
        let o = lucent().args(["render", "--size", "64x48", "--threads", "2", "-o"]).arg(&out).arg(f).output().expect("run");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success() && !err.contains("panicked"), "render {}: {err}", f.display());
        // Something of the mesh is in view (the default camera frames the scene).
        let img = image::open(&out).expect("png").to_rgb8();
        let mut colours: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
        colours.sort_unstable();
        colours.dedup();
        assert!(colours.len() > 8, "render {}: only {} colours", f.display(), colours.len());
    }
}

/// The short soak (CI's version of `lucent bench net --soak`): 16 clients on loopback, two
/// of them hostile, the others checking every frame against `lucent run`'s. It fails on a
/// lost or wrong frame, a panic, or server memory above the limits' bound.
#[test]
fn the_server_soak_loses_no_frame() {
    let o = lucent().args(["bench", "net", "--soak", "--soak-clients", "16", "--soak-frames", "60"]).output().expect("run");
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{text}\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("lost 0, wrong 0") && text.contains("panics: 0"), "{text}");
    assert!(text.contains("received 840"), "{text}");
}

/// `lucent report` on a REND3R program: its frames' cycles by the formula, and Table IV.
#[test]
fn report_on_a_rend3r_program() {
    let o = lucent().arg("report").arg(rend3r("raytracing/sw/rt_spheres.rdr")).args(["--frames", "1"]).output().expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = String::from_utf8_lossy(&o.stdout);
    // 2 shapes, 1 light at 512x384: the worst case is the paper's 81,395,712 cycles.
    assert!(s.contains("| 1 | 2 | 1 | 81395712 |"), "{s}");
    assert!(s.contains("| 4096 | 1 | 16.912 | 16.912 s |") && s.contains("| 256 | 0 | 0.906 | 0.906 s |"), "{s}");
    assert!(s.contains("45766350 cycles on the board"), "{s}");
    let o = lucent().arg("report").arg(rend3r("raytracing/sw/rt_spheres.rdr")).args(["--frames", "1", "--json"]).output().expect("run");
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.lines().any(|l| l.contains("\"table\":\"rend3r_frames\"") && l.contains("\"cycles_worst\":81395712")), "{s}");
    // A program is not a scene.
    let o = lucent().arg("report").arg(rend3r("raytracing/sw/rt_spheres.rdr")).args(["--machine", "saarcor"]).output().expect("run");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("is a REND3R program"));
}

/// `lucent report` on a scene: both indices' Table 3 and 4 rows, the precision table and
/// the HTML page with its images.
#[test]
fn report_on_a_scene() {
    let dir = std::env::temp_dir().join(format!("lucent-report-{}", std::process::id()));
    let html = dir.join("r.html");
    let o = lucent()
        .args(["report", "--demo", "sunflowers", "--size", "128x96", "--precision-size", "64x48", "--html"])
        .arg(&html)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = String::from_utf8_lossy(&o.stdout);
    for want in [
        "### Table 3: frames per second (512x384)",
        "| 32.1 | ",
        "| bvh | 128x96 |",
        "| kd | 128x96 |",
        "| f24 |",
        "| f16 |",
        "| fixed |",
        "Modelling assumptions",
        "| the paper | 1024x768 | 8.70 | 46.0 |",
        "### Threads per pipeline (512x384)",
        "| kd | 64 |",
        "| RTDyn1 / RTstatic | 66 |",
        "| Traversal | 4 | 0 | 4 | 13 | 44.5 |",
        "| FLOPs |",
        "| Scene6 | 806 | 1 | not available",
        "| integers, t with 6 fraction bits | 1280x1024 |",
        "| integers, t with 0 fraction bits | 640x512 |",
    ] {
        assert!(s.contains(want), "missing {want}: {s}");
    }
    // The gaps study runs at the paper's size only.
    assert!(!s.contains("Where the kd model and the paper differ"), "{s}");
    let page = std::fs::read_to_string(&html).expect("html");
    assert!(page.contains("<svg") && page.contains("Hit rate against cache size") && page.contains("r-kd-steps.png"));
    assert!(dir.join("r-kd-misses.png").is_file() && dir.join("r-precision-f24-diff.png").is_file());
    let o = lucent()
        .args(["report", "--demo", "sunflowers", "--size", "64x48", "--precision", "none", "--index", "kd", "--json"])
        .output()
        .expect("run");
    let s = String::from_utf8_lossy(&o.stdout);
    let rows: Vec<&str> =
        s.lines().filter(|l| l.contains("\"table\":\"saarcor_table3") || l.contains("\"table\":\"saarcor_table4")).collect();
    assert_eq!(rows.len(), 3, "Table 3, Table 4 and the paper's row: {s}");
    assert_eq!(s.lines().filter(|l| l.contains("\"table\":\"saarcor_threads\"")).count(), 9, "{s}");
    assert!(s.lines().all(|l| l.starts_with('{') && l.ends_with('}')), "{s}");
    for table in ["saarcor_table1", "saarcor_table2", "saarcor_text", "saarcor_scenes", "saarcor_table4_paper"] {
        assert!(s.contains(&format!("\"table\":\"{table}\"")), "{table}: {s}");
    }
    for key in [
        "fps",
        "usage_trav",
        "usage_list",
        "usage_transf",
        "usage_int",
        "hit_trav",
        "hit_list",
        "hit_transf",
        "mb_s_core",
        "mb_s_shading",
        "mb_s_total",
    ] {
        assert!(rows.iter().all(|r| r.contains(&format!("\"{key}\":"))), "{key}: {s}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A texture that makes the JPEG decoder panic (zune-jpeg 0.5.15, a fuzz finding) is a
/// warning naming the image, not a crash report: `info` succeeds.
#[test]
fn a_decoder_panic_is_a_warning() {
    let f = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/regressions/glb/zune_jpeg_avx2_upsampler.glb");
    let o = lucent().arg("info").arg(&f).output().expect("run");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("/images/1: not loaded") && err.contains("the image decoder failed"), "{err}");
}

/// A built-in scene is denoised by default (issue 55), at 8 samples unless --spp says, and
/// says so; --no-denoise shows the raw samples, which are noisier (neighbouring pixels of
/// the back wall differ more); --denoise with --no-denoise is refused.
#[test]
fn the_built_in_scene_is_denoised_by_default() {
    let d = tempfile::tempdir().expect("tmp");
    let run = |extra: &[&str], name: &str| {
        let out = d.path().join(name);
        let o = lucent().args(["render", "--size", "96x72", "--threads", "2"]).args(extra).arg("-o").arg(&out).output().expect("run");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (String::from_utf8_lossy(&o.stdout).into_owned(), image::open(&out).expect("png").to_rgb8())
    };
    let (text, clean) = run(&[], "clean.png");
    assert!(text.contains("denoised (à-trous) in") && text.contains("--no-denoise") && text.contains("8 spp"), "{text}");
    let (text, raw) = run(&["--no-denoise"], "raw.png");
    assert!(!text.contains("denoised"), "{text}");
    // The back wall: the mean absolute difference of horizontal neighbours.
    let roughness = |img: &image::RgbImage| {
        let mut s = 0.0;
        for y in 20..36 {
            for x in 36..60 {
                let (a, b) = (img.get_pixel(x, y).0, img.get_pixel(x + 1, y).0);
                s += a.iter().zip(b).map(|(p, q)| (f32::from(*p) - f32::from(q)).abs()).sum::<f32>();
            }
        }
        s
    };
    assert!(roughness(&clean) * 3.0 < roughness(&raw), "denoised {} against raw {}", roughness(&clean), roughness(&raw));
    let o = lucent().args(["render", "--denoise", "--no-denoise", "-o"]).arg(d.path().join("x.png")).output().expect("run");
    assert!(!o.status.success());
}

/// A Mitsuba film's crop window (issue 54): only the window is rendered and written, its
/// pixels those of the whole film's image (bit for bit: each pixel's samples are its own);
/// --size renders the whole film instead; a window outside the film is refused where it
/// is written.
#[test]
fn a_crop_window_renders_that_part_of_the_film() {
    let d = tempfile::tempdir().expect("tmp");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../render/tests/data/mitsuba/crop_window/scene.xml");
    let (crop, full) = (d.path().join("crop.exr"), d.path().join("full.exr"));
    for (out, extra) in [(&crop, &[][..]), (&full, &["--size", "96x64"][..])] {
        let o =
            lucent().arg("render").arg(&scene).args(["--spp", "3", "--threads", "2"]).args(extra).arg("-o").arg(out).output().expect("run");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (c, f) = (lucent_render::Film::load(&crop).expect("crop"), lucent_render::Film::load(&full).expect("full"));
    assert_eq!((c.width, c.height, f.width, f.height), (40, 36, 96, 64));
    for y in 0..36 {
        for x in 0..40 {
            assert_eq!(c.get(x, y).to_array().map(f32::to_bits), f.get(x + 30, y + 20).to_array().map(f32::to_bits), "({x}, {y})");
        }
    }
    let bad = d.path().join("bad.xml");
    let text =
        std::fs::read_to_string(&scene).expect("scene").replace(r#"name="crop_width" value="40""#, r#"name="crop_width" value="80""#);
    std::fs::write(&bad, text).expect("write");
    let o = lucent().arg("render").arg(&bad).arg("-o").arg(d.path().join("x.exr")).output().expect("run");
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("crop window 80x36 at (30, 20)") && e.contains("bad.xml:"), "{e}");
}

/// A Mitsuba scene with the `aov` integrator and an RGBA film: the EXR has Mitsuba's
/// channels (the film's R, G, B, A, the wrapped integrator's image under its name, each
/// layer with its suffixes), the alpha 0 on the background and 1 on the objects.
#[test]
fn mitsuba_aov_layers_and_alpha_are_written() {
    use exr::prelude::*;
    let d = tempfile::tempdir().expect("tmp");
    let out = d.path().join("aov.exr");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../render/tests/data/mitsuba/aov/scene.xml");
    let o = lucent().args(["render", "--spp", "4", "--threads", "2", "-o"]).arg(&out).arg(&scene).output().expect("run");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img =
        read().no_deep_data().largest_resolution_level().all_channels().first_valid_layer().all_attributes().from_file(&out).expect("EXR");
    let mut names: Vec<String> = img.layer_data.channel_data.list.iter().map(|c| c.name.to_string()).collect();
    names.sort();
    let mut want: Vec<String> =
        ["R", "G", "B", "A", "my_image.R", "my_image.G", "my_image.B", "my_image.A", "dd.T", "pos.X", "pos.Y", "pos.Z", "tex.U", "tex.V"]
            .iter()
            .chain(&["ng.X", "ng.Y", "ng.Z", "nn.X", "nn.Y", "nn.Z", "alb.R", "alb.G", "alb.B", "prim.I"])
            .map(|s| (*s).to_string())
            .collect();
    want.sort();
    assert_eq!(names, want);
    let alpha: Vec<f32> =
        img.layer_data.channel_data.list.iter().find(|c| c.name.to_string() == "A").expect("A").sample_data.values_as_f32().collect();
    assert!(alpha.iter().all(|a| (0.0..=1.0).contains(a)));
    assert!(alpha.contains(&0.0) && alpha.contains(&1.0), "no background or no object in the alpha");
}
