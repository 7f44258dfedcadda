//! `lucent run`: executes a REND3R program and writes one PNG per `nf`.

use anyhow::{Context, Result};
use rend3r_isa::{assemble_words, AsmOptions, CameraTable};
use rend3r_machine::{render_frame, FrameSettings, Mode, Processor, SetKind, Step};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub struct RunArgs {
    pub program: PathBuf,
    pub mode: Mode,
    pub sets: Option<SetKind>,
    pub size: (u32, u32),
    pub frames: u64,
    pub seconds: Option<f64>,
    pub painter: bool,
    pub spp: u32,
    pub camera_table: CameraTable,
    pub output: PathBuf,
    /// Model the board (`--compat board`), with this switch setting as background.
    pub board: Option<u16>,
    /// Print REND3R's cycle model for each frame.
    pub cycles: bool,
}

/// Words of a program, and whether its source used `tr` (triangles) rather than `sp`.
pub fn load_program(path: &Path, camera_table: CameraTable) -> Result<(Vec<u32>, Option<SetKind>)> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase()).unwrap_or_default();
    if ext == "rdr" {
        let src = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        let words = assemble_words(&src, AsmOptions { camera_table }).map_err(|e| anyhow::anyhow!("{}:{e}", path.display()))?;
        Ok((words, rend3r_machine::set_kind_of_source(&src)))
    } else {
        Ok((crate::isa_cmd::read_words(path)?, None))
    }
}

pub fn run(a: RunArgs) -> Result<()> {
    let (words, from_source) = load_program(&a.program, a.camera_table)?;
    let sets = a.sets.or(from_source).unwrap_or(SetKind::for_mode(a.mode));
    if let Some(switches) = a.board {
        return run_board(&a, &words, switches);
    }
    let mut p = Processor::new(words, a.camera_table).map_err(|e| anyhow::anyhow!("{}: {e}", a.program.display()))?;
    std::fs::create_dir_all(&a.output).with_context(|| format!("cannot create {}", a.output.display()))?;
    let fs = FrameSettings { width: a.size.0, height: a.size.1, mode: a.mode, sets, painter: a.painter, spp: a.spp };
    let start = Instant::now();
    let mut frame = 0u64;
    let mut warned = false;
    while within_limits(&a, start, frame) && reached_frame(&a, p.run_to_frame(WORDS_PER_FRAME), p.executed, frame)? {
        frame += 1;
        let t = Instant::now();
        let (film, info) = render_frame(&p.state, &fs)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        if info.skipped > 0 && !warned {
            tracing::warn!("{} shape records have an undefined type (4-15) or non-finite data: skipped", info.skipped);
            warned = true;
        }
        let out = a.output.join(format!("frame-{frame:04}.png"));
        film.save(&out)?;
        println!(
            "frame {frame}: {} {}, {} lights, {ms:.1} ms -> {}",
            info.shapes,
            if sets == SetKind::Shapes { "shapes" } else { "triangles" },
            info.lights,
            out.display()
        );
        if a.cycles {
            let (c, hits) = rend3r_machine::cycles::frame_cycles(&p.state, &fs)?;
            let (ws, bs) = c.seconds();
            println!(
                "  REND3R cycles: worst case {} ({ws:.4} s at 100 MHz), board {} ({bs:.4} s; {hits} of {} pixels hit); lucent {ms:.1} ms = {:.0}x faster than the board",
                c.worst,
                c.board,
                u64::from(fs.width) * u64::from(fs.height),
                bs * 1e3 / ms.max(1e-6)
            );
        }
    }
    if p.ignored > 0 {
        println!("note: {} words were not instructions and were ignored", p.ignored);
    }
    Ok(())
}

/// Words a program may execute between two frames before it counts as a runaway loop.
const WORDS_PER_FRAME: u64 = 50_000_000;

/// Whether another frame is allowed: false (said on the terminal) once `--frames` frames
/// were made or `--seconds` have passed.
fn within_limits(a: &RunArgs, start: Instant, frame: u64) -> bool {
    let more = frame < a.frames && !a.seconds.is_some_and(|s| start.elapsed().as_secs_f64() >= s);
    if !more {
        println!("stopped after {frame} frames (limit reached)");
    }
    more
}

/// Whether the program reached its next `nf` (`step`); false (said on the terminal) when it
/// halted; an error when it ran `WORDS_PER_FRAME` words without either (the board model
/// and the processor alike).
fn reached_frame(a: &RunArgs, step: Step, executed: u64, frame: u64) -> Result<bool> {
    match step {
        Step::Frame => Ok(true),
        Step::Busy => {
            anyhow::bail!("{}: the program executed {executed} words without reaching nf or er (a loop with no nf?)", a.program.display())
        }
        _ => {
            println!("program halted after {frame} frames ({executed} words executed)");
            Ok(false)
        }
    }
}

fn run_board(a: &RunArgs, words: &[u32], switches: u16) -> Result<()> {
    use rend3r_machine::board::{Board, Build};
    let build = if a.mode == Mode::Raster { Build::Raster } else { Build::Raytracing };
    if words.len() > build.rom_words() {
        println!(
            "note: the board's program memory holds {} words; words {}.. of {} are dropped and the PC wraps",
            build.rom_words(),
            build.rom_words(),
            words.len()
        );
    }
    let mut b = Board::new(words, build, switches).map_err(|e| anyhow::anyhow!("{}: {e}", a.program.display()))?;
    std::fs::create_dir_all(&a.output).with_context(|| format!("cannot create {}", a.output.display()))?;
    let start = Instant::now();
    let mut frame = 0u64;
    while within_limits(a, start, frame) && reached_frame(a, b.processor.run_to_frame(WORDS_PER_FRAME), b.processor.executed, frame)? {
        frame += 1;
        let t = Instant::now();
        let film = b.frame();
        let out = a.output.join(format!("frame-{frame:04}.png"));
        film.save(&out)?;
        println!("frame {frame} (board model): {:.1} ms -> {}", t.elapsed().as_secs_f64() * 1e3, out.display());
    }
    Ok(())
}
