//! lucent: a real-time CPU ray tracer.
use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

mod bench;
mod isa_cmd;
mod rend3r_bench;
mod render_cmd;
mod run_cmd;

#[derive(Parser)]
#[command(
    name = "lucent",
    version,
    about = "lucent: a real-time CPU ray tracer",
    long_about = "lucent: a real-time CPU ray tracer.\n\nRender a scene to an image:   lucent render scene.obj -o out.png\nRender the built-in demo:     lucent render -o demo.png\nDescribe a scene:             lucent info scene.gltf\nCompare speed with Embree:    ../shared/bench/compare.sh (calls `lucent bench rays`)\n\nScenes: Wavefront OBJ (+MTL, also .obj.gz), PLY, glTF 2.0 (.gltf, .glb).\nSet RUST_LOG=debug for more messages."
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Render a scene (or the built-in demo) to a PNG or EXR image with Whitted ray tracing.
    Render {
        /// Scene file (.obj, .obj.gz, .ply, .gltf, .glb). Without it: the built-in demo scene.
        scene: Option<PathBuf>,
        /// Camera as EX,EY,EZ,LX,LY,LZ,UX,UY,UZ,FOV: eye, look-at point, up vector, vertical
        /// field of view in degrees. Default: the scene's camera, else one framing the scene.
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1)]
        camera: Option<Vec<f32>>,
        /// Orthographic projection (same view height as the perspective view at the look-at point).
        #[arg(long)]
        ortho: bool,
        /// Image size WIDTHxHEIGHT.
        #[arg(long, default_value = "1024x768", value_parser = render_cmd::parse_size)]
        size: (u32, u32),
        /// Samples per pixel (jittered, deterministic per pixel and sample).
        #[arg(long, default_value_t = 1)]
        spp: u32,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Output image: .png (8-bit sRGB) or .exr (linear float).
        #[arg(short, long, default_value = "out.png")]
        output: PathBuf,
        /// Most reflection/refraction generations.
        #[arg(long, default_value_t = 6)]
        max_depth: u32,
        /// Turn shadow rays off.
        #[arg(long)]
        no_shadows: bool,
        /// Use the watertight triangle test instead of the unit-triangle test.
        #[arg(long)]
        watertight: bool,
    },
    /// Assemble a REND3R program (.rdr) into instruction words (.mem text or raw binary).
    Asm {
        /// REND3R assembly source.
        program: PathBuf,
        /// Output file (default: the program with .mem, or .bin with --format bin).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// mem: 8 hex digits per line, as REND3R wrote them; bin: u32 words, network byte order.
        /// Default: from the output's extension.
        #[arg(long, value_enum)]
        format: Option<isa_cmd::WordFormat>,
        /// Camera property table: `final` (quaternion, raytracing branch) or `old`
        /// (forward/up vectors, main and taping branches).
        #[arg(long, default_value = "final", value_parser = ["final", "old"])]
        camera_table: String,
    },
    /// Turn REND3R instruction words (.mem/.hex text, or raw big-endian .bin) back into assembly.
    Disasm {
        /// Word file.
        file: PathBuf,
        /// Camera property table (final or old).
        #[arg(long, default_value = "final", value_parser = ["final", "old"])]
        camera_table: String,
        /// Show shape/triangle sets as `tr` (rasterization) instead of `sp`.
        #[arg(long)]
        triangles: bool,
    },
    /// Run a REND3R program (.rdr source, .mem words or raw .bin) and write one PNG per `nf`.
    Run {
        /// The program.
        program: PathBuf,
        /// raytrace: lucent's ray tracer over the shapes (what REND3R's paper intends);
        /// raster: the edge-function rasterizer over triangles.
        #[arg(long, default_value = "raytrace", value_parser = ["raytrace", "raster"])]
        mode: String,
        /// Read shape/triangle sets as shapes or triangles (sp and tr encode alike). Default:
        /// from the source's mnemonics, else from --mode.
        #[arg(long, value_parser = ["shapes", "triangles"])]
        sets: Option<String>,
        /// Frame size WIDTHxHEIGHT.
        #[arg(long, default_value = "512x384", value_parser = render_cmd::parse_size)]
        size: (u32, u32),
        /// Stop after this many frames (looping programs render until a limit).
        #[arg(long, default_value_t = 100)]
        frames: u64,
        /// Stop after this many seconds.
        #[arg(long)]
        seconds: Option<f64>,
        /// Rasterizer: painter's order (farthest first) instead of a z-buffer.
        #[arg(long)]
        painter: bool,
        /// Samples per pixel (ray tracing).
        #[arg(long, default_value_t = 1)]
        spp: u32,
        /// Camera property table (final or old).
        #[arg(long, default_value = "final", value_parser = ["final", "old"])]
        camera_table: String,
        /// Output folder for frame-0001.png, frame-0002.png, ...
        #[arg(short, long, default_value = "frames")]
        output: PathBuf,
        /// `board`: show what REND3R's FPGA board would have shown (its 32/128-word program
        /// memory, 2 shapes/2 lights/8 triangles, binary16 datapath, one shadow ray, fixed-point
        /// shading, RGB444 display and documented bugs). See lucent_engine::board.
        #[arg(long, value_parser = ["board"])]
        compat: Option<String>,
        /// With --compat board: the 16 board switches, shown as background (RGB565 bits).
        #[arg(long, default_value = "0", value_parser = parse_u16)]
        switches: u16,
    },
    /// Print a scene's counts, bounds, camera and acceleration-structure size.
    Info {
        /// Scene file. Without it: the built-in demo scene.
        scene: Option<PathBuf>,
    },
    /// Speed reports.
    #[command(subcommand)]
    Bench(BenchCmd),
}

#[derive(Subcommand)]
enum BenchCmd {
    /// REND3R's Table IV scenes (1..4096 spheres, 0/1 lights): frame times, and words per
    /// second through the assembler and the processor.
    Rend3r {
        /// Timed frames per scene (median reported).
        #[arg(long, default_value_t = 5)]
        frames: usize,
        /// Frame size.
        #[arg(long, default_value = "512x384", value_parser = render_cmd::parse_size)]
        size: (u32, u32),
    },
    /// Trace the rays dumped by the Embree harness (shared/bench) and print JSON lines.
    Rays {
        /// Folder with mesh.bin, rays_*.bin and ref_ids.bin.
        dir: PathBuf,
        /// Scene name for the JSON lines.
        #[arg(long, default_value = "scene")]
        name: String,
        /// Comma-separated thread counts.
        #[arg(long, default_value = "1,2", value_delimiter = ',')]
        threads: Vec<usize>,
        /// Timed passes (the median is reported).
        #[arg(long, default_value_t = 7)]
        frames: usize,
        /// Untimed passes first.
        #[arg(long, default_value_t = 2)]
        warmup: usize,
        /// Ray kinds.
        #[arg(long, default_value = "primary,shadow,diffuse", value_delimiter = ',')]
        kinds: Vec<String>,
        /// Node width: 4 or 8.
        #[arg(long, default_value_t = 8)]
        width: u32,
        /// Use the watertight triangle test.
        #[arg(long)]
        watertight: bool,
        /// Force the scalar kernel.
        #[arg(long)]
        scalar: bool,
        /// Write the primary hit id of every pixel to this file (i32 little-endian, -1 = miss).
        #[arg(long)]
        dump_ids: Option<PathBuf>,
    },
}

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // User errors: one clear message (with its causes), no backtrace.
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    match cli.cmd {
        Cmd::Render { scene, camera, ortho, size, spp, threads, output, max_depth, no_shadows, watertight } => {
            render_cmd::run(render_cmd::RenderArgs { scene, camera, ortho, size, spp, threads, output, max_depth, no_shadows, watertight })
        }
        Cmd::Info { scene } => render_cmd::info(scene.as_deref()),
        Cmd::Asm { program, output, format, camera_table } => isa_cmd::asm(&program, output, format, isa_cmd::table(camera_table == "old")),
        Cmd::Run { program, mode, sets, size, frames, seconds, painter, spp, camera_table, output, compat, switches } => {
            run_cmd::run(run_cmd::RunArgs {
                program,
                mode: if mode == "raster" { lucent_engine::Mode::Raster } else { lucent_engine::Mode::Raytrace },
                sets: sets.map(|s| if s == "triangles" { lucent_engine::SetKind::Triangles } else { lucent_engine::SetKind::Shapes }),
                size,
                frames,
                seconds,
                painter,
                spp,
                camera_table: isa_cmd::table(camera_table == "old"),
                output,
                board: compat.map(|_| switches),
            })
        }
        Cmd::Disasm { file, camera_table, triangles } => isa_cmd::disasm(&file, isa_cmd::table(camera_table == "old"), triangles),
        Cmd::Bench(BenchCmd::Rend3r { frames, size }) => rend3r_bench::run(frames, size),
        Cmd::Bench(BenchCmd::Rays { dir, name, threads, frames, warmup, kinds, width, watertight, scalar, dump_ids }) => bench::rays(
            &dir,
            &bench::RaysOptions {
                name,
                threads,
                frames,
                warmup,
                kinds,
                width: if width == 4 { lucent_accel::Width::W4 } else { lucent_accel::Width::W8 },
                test: if watertight { lucent_accel::TriangleTest::Watertight } else { lucent_accel::TriangleTest::UnitTriangle },
                kernel: if scalar { lucent_accel::Kernel::Scalar } else { lucent_accel::Kernel::detect() },
                dump_ids,
            },
        ),
    }
}

fn parse_u16(s: &str) -> Result<u16, String> {
    lucent_isa::number::parse_uint(&s.to_lowercase())
        .and_then(|v| u16::try_from(v).ok())
        .ok_or_else(|| format!("'{s}' is not a 16-bit unsigned number (e.g. 0x001f)"))
}
