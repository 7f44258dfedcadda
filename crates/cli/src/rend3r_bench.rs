//! `lucent bench rend3r`: REND3R's Table IV scenes (1, 16, 256, 4096 spheres; 0 and 1
//! lights) at 512×384, and words per second through the assembler and the processor.

use anyhow::Result;
use rend3r_isa::{assemble_words, AsmOptions, CameraTable};
use rend3r_machine::{render_frame, FrameSettings, Mode, Processor, SetKind, Step};
use std::fmt::Write as _;
use std::time::Instant;

/// A program with `n` spheres of radius min(1.5, 0.4 × grid step) on a grid over the view
/// at depth 20–22, and `lights` lights (a directional light toward (1, −1, −1)).
#[must_use]
pub fn spheres_program(n: usize, lights: usize) -> String {
    let mut s = String::from("nr\n");
    if lights == 0 {
        s += "lt 0, src, 0\n";
    } else {
        s += "lt 0, src, 1\nlt 0, xfor, 1\nlt 0, yfor, -1\nlt 0, zfor, -1\n";
    }
    let side = (n as f64).sqrt().ceil() as usize;
    // The viewport is 10 × 7.5 at distance 1: at depth 20 the view is 200 × 150 wide.
    let step = 180.0 / side as f64;
    for i in 0..n {
        let (gx, gy) = (i % side, i / side);
        let x = -90.0 + step * (gx as f64 + 0.5);
        let y = -67.5 + step * 0.75 * (gy as f64 + 0.5);
        let z = -20.0 - (i % 3) as f64;
        let r = (step * 0.4).min(1.5);
        let col = (i * 2654435761) as u16 | 0x0841;
        let _ = writeln!(s, "sp {i}, xloc, yloc, {x:.3}, {y:.3}");
        let _ = writeln!(s, "sp {i}, zloc, type, {z:.3}, 1");
        let _ = writeln!(s, "sp {i}, xscl, yscl, {:.4}, {:.4}", 1.0 / r, 1.0 / r);
        let _ = writeln!(s, "sp {i}, zscl, col, {:.4}, {col:#06x}", 1.0 / r);
        let _ = writeln!(s, "sp {i}, rrot, mat, 1, 0");
    }
    s += "nf\ner\ner\n";
    s
}

/// REND3R's estimated frame time for `n` spheres and `lights` lights, in seconds: its
/// Table IV's row where it has one (1, 16, 256 and 4,096 spheres; 0 or 1 light), else
/// its cycle formula, (spheres + 205) × (lights + 1) cycles a pixel at 100 MHz, which
/// gives every row of the table to its printed digits.
#[must_use]
pub fn rend3r_estimate_s(n: usize, lights: usize) -> f64 {
    use rend3r_machine::cycles::{ray_traced, PAPER_ROWS};
    match PAPER_ROWS.iter().find(|r| r.0 == n as u64 && r.1 == lights as u64) {
        Some(r) => r.2,
        None => ray_traced(n as u64, lights as u64, 512 * 384, 512 * 384).seconds().0,
    }
}

pub fn run(frames: usize, size: (u32, u32), spheres: &[usize], light_counts: &[usize]) -> Result<()> {
    if let Some(l) = light_counts.iter().find(|&&l| l > 1) {
        anyhow::bail!("--lights {l}: Table IV's rows have 0 or 1 lights");
    }
    if let Some(n) = spheres.iter().find(|&&n| n == 0 || n > rend3r_machine::MAX_SETS) {
        anyhow::bail!("--spheres {n}: give 1 to {} spheres", rend3r_machine::MAX_SETS);
    }
    println!("REND3R Table IV scenes at {}x{}, {} threads, median of {frames} frames", size.0, size.1, rayon::current_num_threads());
    println!("| spheres | lights | frame ms (process + render) | REND3R's estimate, s | x faster |");
    println!("|---|---|---|---|---|");
    for &lights in light_counts {
        for &n in spheres {
            let src = spheres_program(n, lights);
            let words = assemble_words(&src, AsmOptions::default()).map_err(|e| anyhow::anyhow!("generated program: {e}"))?;
            let fs = FrameSettings { width: size.0, height: size.1, mode: Mode::Raytrace, sets: SetKind::Shapes, painter: false, spp: 1 };
            let frame = || -> Result<f64> {
                let t = Instant::now();
                let mut p = Processor::new(words.clone(), CameraTable::Final)?;
                if p.run_to_frame(u64::MAX) != Step::Frame {
                    anyhow::bail!("generated program did not reach nf");
                }
                let (_film, _) = render_frame(&p.state, &fs)?;
                Ok(t.elapsed().as_secs_f64())
            };
            // Warm-up, untimed: at least 5 frames and 50 ms. (The first rows of a run, a few
            // milliseconds of frames each, read up to twice as slow as the same rows later:
            // the worker threads and the allocator settle first.)
            let warm = Instant::now();
            let mut n_warm = 0;
            while n_warm < 5 || warm.elapsed().as_secs_f64() < 0.05 {
                frame()?;
                n_warm += 1;
            }
            let mut times = Vec::new();
            for _ in 0..frames.max(1) {
                times.push(frame()?);
            }
            let ms = crate::stats::median(&mut times) * 1e3;
            let model = rend3r_estimate_s(n, lights);
            println!("| {n} | {lights} | {ms:.2} | {model:.3} | {:.0} |", model * 1e3 / ms);
            eprintln!(
                "{{\"kind\":\"rend3r_frame\",\"spheres\":{n},\"lights\":{lights},\"width\":{},\"height\":{},\"median_ms\":{ms:.3}}}",
                size.0, size.1
            );
        }
    }
    // Words per second: assembler and processor on the largest program.
    let src = spheres_program(4096, 1);
    let t = Instant::now();
    let mut words = Vec::new();
    for _ in 0..5 {
        words = assemble_words(&src, AsmOptions::default()).map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    let asm_wps = 5.0 * words.len() as f64 / t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mut executed = 0u64;
    for _ in 0..20 {
        let mut p = Processor::new(words.clone(), CameraTable::Final)?;
        while p.step() != Step::Halt {}
        executed += p.executed;
    }
    let proc_wps = executed as f64 / t.elapsed().as_secs_f64();
    println!("assembler: {:.1} M words/s; processor: {:.1} M words/s ({} words per program)", asm_wps * 1e-6, proc_wps * 1e-6, words.len());
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn estimates_are_the_table_s_rows() {
        let e = super::rend3r_estimate_s;
        assert_eq!([e(1, 0), e(16, 0), e(256, 0), e(4096, 0)], [0.405, 0.435, 0.906, 8.456]);
        assert_eq!([e(1, 1), e(16, 1), e(256, 1), e(4096, 1)], [0.810, 0.869, 1.813, 16.912]);
        // Off the table: the paper's formula, (64 + 205) cycles a pixel.
        assert!((e(64, 0) - 269.0 * 512.0 * 384.0 / 1e8).abs() < 1e-9);
    }
}
