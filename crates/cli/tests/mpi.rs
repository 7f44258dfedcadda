//! `--mpi` under `mpirun` (issue 37): images and animations bit for bit those of one
//! process, faults that end the run clearly. Built with `--features mpi`; needs OpenMPI's
//! `mpirun` (Debian: openmpi-bin), which `scripts/install-test-deps` installs.
#![cfg(feature = "mpi")]

use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const LUCENT: &str = env!("CARGO_BIN_EXE_lucent");

/// `mpirun -np N lucent ARGS` (as root too, more ranks than cores), with `env` passed to
/// every rank: what it printed, and how long the attempt that counted took (see
/// [`run_mpirun`]).
fn mpirun(n: u32, args: &[&str], env: &[(&str, &str)]) -> (Output, Duration) {
    let mut c = Command::new("mpirun");
    c.args(["--allow-run-as-root", "--oversubscribe", "-np", &n.to_string()]);
    for (k, v) in env {
        c.env(k, v).args(["-x", k]);
    }
    c.arg(LUCENT).args(args);
    run_mpirun(c)
}

/// Runs an mpirun command to its end and returns what it printed.
///
/// Debian's Open MPI 4.1 mpirun has a teardown race of its own (open-mpi/ompi#13650 and
/// the PMIx issues it links): after a rank ends abnormally it sometimes crashes in
/// `PMIx_server_finalize`, or deadlocks and ignores SIGTERM. Neither is lucent's doing
/// (lucent has printed its error and exited by then), but a deadlock would hang the test
/// run for good. So mpirun runs in a process group of its own under a watchdog, and an
/// attempt that ends in either of mpirun's own failures is repeated (at most three). The
/// time returned is that of the attempt whose output is returned: a test of how fast lucent
/// ends a broken run must not count the minute a hung mpirun was given before it was killed.
fn run_mpirun(mut c: Command) -> (Output, Duration) {
    use std::os::unix::process::{CommandExt, ExitStatusExt};
    use std::process::Stdio;
    c.process_group(0).stdout(Stdio::piped()).stderr(Stdio::piped());
    let mut last = String::new();
    for attempt in 1..=3 {
        let mut child = c.spawn().expect("mpirun (Debian package openmpi-bin) must be installed");
        let pid = child.id();
        let readers = (drain(child.stdout.take().expect("piped")), drain(child.stderr.take().expect("piped")));
        let t = Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().expect("wait for mpirun") {
                break Some(s);
            }
            if t.elapsed() > Duration::from_secs(60) {
                break None;
            }
            std::thread::sleep(Duration::from_millis(50));
        };
        if status.is_none() {
            // Kill the whole group (mpirun and any rank left) so the pipes close.
            let _ = Command::new("kill").args(["-KILL", "--", &format!("-{pid}")]).status();
            let _ = child.wait();
        }
        let o = Output {
            status: status.unwrap_or_else(|| ExitStatusExt::from_raw(9)),
            stdout: readers.0.join().expect("reader").unwrap_or_default(),
            stderr: readers.1.join().expect("reader").unwrap_or_default(),
        };
        let e = text(&o);
        let torn = o.status.signal() == Some(11) && e.contains("PMIx_server_finalize");
        match status {
            Some(_) if !torn => return (o, t.elapsed()),
            Some(_) => eprintln!("attempt {attempt}: mpirun crashed in its own teardown (PMIx_server_finalize); again"),
            None => eprintln!("attempt {attempt}: mpirun did not end within 60 s (killed); again"),
        }
        last = e;
    }
    panic!("mpirun failed three times in its own teardown or hung; last output:\n{last}");
}

/// Reads `r` to its end on a thread of its own (so that neither of a child's pipes fills
/// while the other is read).
fn drain(mut r: impl std::io::Read + Send + 'static) -> std::thread::JoinHandle<std::io::Result<Vec<u8>>> {
    std::thread::spawn(move || {
        let mut v = Vec::new();
        r.read_to_end(&mut v).map(|_| v)
    })
}

fn lucent(args: &[&str]) -> Output {
    Command::new(LUCENT).args(args).output().expect("lucent")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn pixels(p: &Path) -> Vec<[u32; 3]> {
    let f = lucent_render::Film::load(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    f.pixels.iter().map(|v| v.to_array().map(f32::to_bits)).collect()
}

fn shared(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes").join(rel).display().to_string()
}

#[test]
fn render_over_ranks_is_the_one_process_image() {
    let d = tempfile::tempdir().expect("tmp");
    for (integrator, spp, ranks, tile) in
        [("whitted", "1", 3, "32"), ("whitted", "3", 2, "64"), ("path", "4", 3, "48"), ("vpl", "2", 3, "32")]
    {
        let one = d.path().join(format!("one-{integrator}-{spp}.exr"));
        let many = d.path().join(format!("many-{integrator}-{spp}.exr"));
        let base = ["render", "--size", "150x100", "--integrator", integrator, "--spp", spp, "--threads", "1"];
        let o = lucent(&[&base[..], &["-o", &one.display().to_string()]].concat());
        assert!(o.status.success(), "{}", text(&o));
        let (o, _) = mpirun(ranks, &[&base[..], &["--mpi", "--mpi-tile", tile, "-o", &many.display().to_string()]].concat(), &[]);
        let t = text(&o);
        assert!(o.status.success(), "{t}");
        assert!(t.contains(&format!("mpi: {ranks} ranks")), "{t}");
        assert!(pixels(&one) == pixels(&many), "{integrator} at {spp} spp on {ranks} ranks: not the one-process image");
    }
    // A time budget holds over the cluster: samples keep coming until it is spent.
    let out = d.path().join("timed.png");
    let (o, _) = mpirun(3, &["render", "--size", "64x48", "--time", "0.5", "--mpi", "-o", &out.display().to_string()], &[]);
    let t = text(&o);
    assert!(o.status.success() && out.exists(), "{t}");
    let spp: u32 = t.split(" spp,").next().and_then(|s| s.rsplit(' ').next()).and_then(|s| s.parse().ok()).unwrap_or(0);
    assert!(spp >= 2, "samples per pixel in half a second on three ranks: {t}");
}

#[test]
fn animate_over_ranks_gives_animates_frames() {
    let d = tempfile::tempdir().expect("tmp");
    let scene = shared("gltf_animated/CesiumMan.glb");
    let base = ["animate", &scene, "--to", "0.4", "--fps", "10", "--size", "96x72", "--spp", "2", "--integrator", "path"];
    let one = d.path().join("one");
    let o = lucent(&[&base[..], &["-o", &one.display().to_string()]].concat());
    assert!(o.status.success(), "{}", text(&o));
    for mode in ["frames", "tiles"] {
        let dir = d.path().join(mode);
        let (o, _) =
            mpirun(3, &[&base[..], &["--mpi", "--mpi-mode", mode, "--mpi-tile", "32", "-o", &dir.display().to_string()]].concat(), &[]);
        let t = text(&o);
        assert!(o.status.success(), "{t}");
        assert!(t.contains(&format!("on 3 ranks ({})", if mode == "frames" { "Frames" } else { "Tiles" })), "{t}");
        for k in 1..=5 {
            let name = format!("frame-{k:04}.png");
            let (a, b) = (std::fs::read(one.join(&name)).expect("frame"), std::fs::read(dir.join(&name)).expect("frame"));
            assert!(a == b, "{mode}: {name} differs from lucent animate's");
        }
    }
}

#[test]
fn a_killed_rank_ends_the_run_with_a_clear_error() {
    let d = tempfile::tempdir().expect("tmp");
    let out = d.path().join("k.png");
    let args = ["render", "--size", "256x192", "--integrator", "path", "--spp", "16", "--mpi", "--mpi-tile", "16", "-o"];
    let (o, took) = mpirun(3, &[&args[..], &[&out.display().to_string()]].concat(), &[("LUCENT_MPI_FAULT", "2:kill:3")]);
    let e = text(&o);
    assert!(!o.status.success(), "{e}");
    assert!(took < Duration::from_secs(30), "took {took:?}");
    // mpirun names the rank that died; rank 0 says what was in flight.
    assert!(e.contains("process rank 2") && e.contains("signal 9"), "{e}");
    assert!(e.contains("error: the run was terminated") && e.contains("rank 2:"), "{e}");
    assert!(!out.exists(), "no image from a broken run");
}

#[test]
fn a_rank_that_stops_answering_ends_the_run_with_a_clear_error() {
    let d = tempfile::tempdir().expect("tmp");
    let out = d.path().join("s.png");
    let args =
        ["render", "--size", "256x192", "--integrator", "path", "--spp", "16", "--mpi", "--mpi-tile", "16", "--mpi-timeout", "2", "-o"];
    let (o, took) = mpirun(3, &[&args[..], &[&out.display().to_string()]].concat(), &[("LUCENT_MPI_FAULT", "1:stop:2")]);
    let e = text(&o);
    assert_eq!(o.status.code(), Some(3), "{e}");
    assert!(took < Duration::from_secs(30), "took {took:?}");
    assert!(e.contains("error: rank 1 stopped answering (no message for 2.0 s); it held 2 regions: "), "{e}");
    assert!(!out.exists(), "no image from a broken run");
}

#[test]
fn ranks_with_different_scenes_are_refused() {
    // Rank 0 and the others see different files: give every rank a path that names a
    // different scene through its rank (OpenMPI sets OMPI_COMM_WORLD_RANK).
    let d = tempfile::tempdir().expect("tmp");
    let (a, b) = (shared("gltf_animated/BoxAnimated.glb"), shared("gltf_animated/CesiumMan.glb"));
    let script = d.path().join("rank.sh");
    std::fs::write(&script, format!("#!/bin/sh\nif [ \"$OMPI_COMM_WORLD_RANK\" = 0 ]; then s={a}; else s={b}; fi\nexec {LUCENT} render \"$s\" --size 32x32 --mpi -o {}\n", d.path().join("x.png").display())).expect("script");
    let mut c = Command::new("mpirun");
    c.args(["--allow-run-as-root", "--oversubscribe", "-np", "2", "sh"]).arg(&script);
    let (o, _) = run_mpirun(c);
    let e = text(&o);
    assert_eq!(o.status.code(), Some(3), "{e}");
    assert!(e.contains("error: rank 1 loaded a different scene"), "{e}");
}
