//! lucent: a real-time CPU ray tracer.
use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

mod animate_cmd;
mod bench;
mod denoise_bench;
mod dynamic_bench;
mod frame_bench;
mod isa_cmd;
mod leaks_bench;
mod mpi_cmd;
mod net_cmd;
mod path_bench;
mod rend3r_bench;
mod render_cmd;
mod report_cmd;
mod run_cmd;
mod stats;
mod threads;
mod view_cmd;
mod viewer_bench;
mod vpl_bench;

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
    /// Render a scene (or a built-in one) to a PNG or EXR image: path traced by default,
    /// or with Whitted ray tracing or a debug view (--integrator).
    Render(render_cmd::RenderArgs),
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
        /// shading, RGB444 display and documented bugs). See rend3r_machine::board.
        #[arg(long, value_parser = ["board"])]
        compat: Option<String>,
        /// With --compat board: the 16 board switches, shown as background (RGB565 bits).
        #[arg(long, default_value = "0", value_parser = parse_u16)]
        switches: u16,
        /// Also print REND3R's cycle model for each frame (rend3r_machine::cycles): the
        /// paper's worst case ((shapes + 205) x (lights + 1) a pixel ray traced; 63 + 4 +
        /// width x height a triangle rasterized), the cycles the board really spends (light
        /// rays only from pixels whose camera ray hit), both as seconds at 100 MHz, beside
        /// lucent's measured time.
        #[arg(long)]
        cycles: bool,
    },
    /// Render a glTF animation (BART kitchen/museum, glTF samples) to numbered PNGs with the
    /// scene's animated camera, printing per-frame update and render times. Rigid motion
    /// rebuilds only the top-level index; morphing meshes rebuild their own.
    Animate(animate_cmd::AnimateArgs),
    /// Open a window and fly through a scene (or watch a REND3R program), Pixel-Planes style:
    /// reduced resolution while moving, full resolution refined sample by sample when still.
    ///
    /// Keys: W/A/S/D/Q/E move (forward/left/back/right/down/up); hold a mouse button and drag
    /// to look (fly) or to orbit (orbit mode); Tab: fly/orbit; scroll: speed; Home: back to
    /// the scene's camera; 1: shadows on/off; 2: reflection depth (0,1,2,4,6,10); 3:
    /// orthographic/perspective; 4: integrator (whitted, path, VPL, eye light, normals); 5:
    /// denoiser on/off (path and VPL: denoised while moving, fading out as a still image
    /// gathers samples); 6: moving frames blended with the frames before (reprojected, up to
    /// 8, on by default with the denoiser); P or F12: screenshot PNG; Space: pause a REND3R program; Esc: quit. Needs an X11 display
    /// (DISPLAY); without one it says so and exits.
    View(view_cmd::ViewArgs),
    /// Serve REND3R as a networked device: clients stream programs over TCP (or UDP, or the
    /// page's WebSocket) and get one frame back per `nf`; a page at --http shows them live.
    ///
    /// Protocol: docs/protocol.md. Try it: `lucent serve`, then in another terminal
    /// `lucent send ../shared/rend3r/programs/raytracing/sw/rt_spheres.rdr -o frames`, or open
    /// http://127.0.0.1:8080/ in a browser.
    Serve(ServeArgs),
    /// Send a REND3R program (.rdr assembly, .mem words or raw .bin) to `lucent serve` and
    /// save the frames it sends back (frame-0001.png, ...).
    Send {
        /// The program.
        program: PathBuf,
        /// Server address.
        #[arg(long, default_value = "127.0.0.1:7878")]
        to: String,
        /// Pixel format to ask for: png, rgb8 (saved as PNG) or rgb565 (saved raw, big-endian).
        #[arg(long, default_value = "png", value_parser = ["png", "rgb8", "rgb565"])]
        format: String,
        /// Stop after this many frames (a looping program renders until then).
        #[arg(long, default_value_t = 100)]
        frames: u64,
        /// Frame size to ask for (default: the server's).
        #[arg(long, value_parser = render_cmd::parse_size)]
        size: Option<(u32, u32)>,
        /// Mode to ask for (default: the server's).
        #[arg(long, value_parser = ["raytrace", "raster"])]
        mode: Option<String>,
        /// Use UDP: whole-word datagrams, PNG frames back in chunks (see docs/protocol.md).
        #[arg(long)]
        udp: bool,
        /// Camera property table of the assembly (final or old).
        #[arg(long, default_value = "final", value_parser = ["final", "old"])]
        camera_table: String,
        /// Output folder.
        #[arg(short, long, default_value = "frames")]
        output: PathBuf,
    },
    /// Print a scene's counts, bounds, camera and acceleration-structure size.
    Info {
        /// Scene file. Without it: the built-in demo scene.
        scene: Option<PathBuf>,
        #[command(flatten)]
        demo: render_cmd::DemoArg,
    },
    /// Speed reports.
    #[command(subcommand)]
    Bench(BenchCmd),
    /// The hardware study: SaarCOR's and REND3R's tables from instrumented runs.
    ///
    /// For a scene: a model of SaarCOR's DynRTP prototype (90 MHz, packets of 4, traversal,
    /// list, transformation and intersection units, 4/2/6 KB direct-mapped caches, 1 GB/s)
    /// fed with the primary rays lucent's kernels count, through lucent's BVH and SaarCOR's
    /// kd-trees: Table 3 (fps at 512x384), Table 4 (fps, unit usage, cache hit rates, MB/s
    /// at 1024x768), and traversal in 24-bit floats, half and fixed point against f32. For
    /// a REND3R program: its cycle model per frame (worst case and what the board spends)
    /// and Table IV. Try: `lucent report --demo sunflowers --html report.html`.
    Report(report_cmd::ReportArgs),
}

#[derive(clap::Args)]
struct ServeArgs {
    /// TCP address of the device protocol (loopback by default; 0.0.0.0:7878 to serve the network).
    #[arg(long, default_value = "127.0.0.1:7878")]
    listen: std::net::SocketAddr,
    /// UDP address for fire-and-forget batches.
    #[arg(long, default_value = "127.0.0.1:7878")]
    udp: std::net::SocketAddr,
    /// Do not listen on UDP.
    #[arg(long)]
    no_udp: bool,
    /// HTTP address of the live page and its WebSocket.
    #[arg(long, default_value = "127.0.0.1:8080")]
    http: std::net::SocketAddr,
    /// Do not serve the page.
    #[arg(long)]
    no_http: bool,
    /// Default frame size (a client may ask for another, up to --max-frame).
    #[arg(long, default_value = "512x384", value_parser = render_cmd::parse_size)]
    size: (u32, u32),
    /// Default mode.
    #[arg(long, default_value = "raytrace", value_parser = ["raytrace", "raster"])]
    mode: String,
    /// One device for all clients: everyone drives the same scene and receives all its frames.
    #[arg(long)]
    shared: bool,
    /// Largest message (bytes of words or assembly in one DATA message or datagram).
    #[arg(long, default_value_t = 1 << 20)]
    max_message: u32,
    /// Most shape/triangle records per session (indices 0..N).
    #[arg(long, default_value_t = 65_536)]
    max_shapes: u32,
    /// Most lights per session (at most 64).
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u16).range(1..=64))]
    max_lights: u16,
    /// Most words a program may hold (words since its last `er`).
    #[arg(long, default_value_t = 1 << 20)]
    max_program_words: usize,
    /// Largest frame a client may ask for, WIDTHxHEIGHT (as a pixel count).
    #[arg(long, default_value = "4096x4096", value_parser = render_cmd::parse_size)]
    max_frame: (u32, u32),
    /// Most open connections (TCP + HTTP) and UDP sessions.
    #[arg(long, default_value_t = 256)]
    max_connections: usize,
    /// Close a connection with no traffic either way for this many seconds.
    #[arg(long, default_value_t = 300)]
    idle_timeout: u64,
    /// Close a connection that does not take a frame within this many seconds.
    #[arg(long, default_value_t = 10)]
    write_timeout: u64,
    /// Payload bytes per UDP frame datagram (1024..65000).
    #[arg(long, default_value_t = 1200)]
    udp_chunk: usize,
    /// Folder of .rdr programs listed on the page (default: ../shared/rend3r/programs when present).
    #[arg(long)]
    examples: Option<PathBuf>,
}

/// The benchmarks' choice of pinned or unpinned worker threads (`threads::pool`).
#[derive(clap::Args)]
struct PinArgs {
    /// Leave the worker threads unpinned (by default each worker is kept on its own
    /// CPU: short parallel jobs then scale steadily; see ARCHITECTURE.md).
    #[arg(long)]
    no_pin: bool,
}

#[derive(Subcommand)]
enum BenchCmd {
    /// Virtual point lights and the denoiser (issue 35): VPL frames per second on
    /// Conference and the animated BART kitchen (2 threads), the rays per second of the
    /// frame's VPL shadow rays against its camera rays, the frame rate the frame's rays
    /// alone would allow (traced again with nothing else), and relMSE against converged path
    /// tracing (Cornell box, Sponza, the kitchen, the kitchen with its glossy lobes
    /// removed) of VPL images with and without the discontinuity buffer and of 4 samples
    /// denoised against 64 raw (three seeds each, median and range). The references are
    /// path traced once and cached in target/bench-cache/ (minutes each).
    Vpl {
        /// The shared scenes folder.
        #[arg(long, default_value = "../shared/scenes")]
        dir: PathBuf,
        /// Frame size.
        #[arg(long, default_value = "512x384", value_parser = render_cmd::parse_size)]
        size: (u32, u32),
        /// Timed frames (the median is reported).
        #[arg(long, default_value_t = 10)]
        frames: usize,
        /// Samples per pixel of the path-traced references.
        #[arg(long, default_value_t = 256)]
        reference_spp: u32,
        /// Frame rates and ray rates only.
        #[arg(long)]
        speed_only: bool,
        /// Only these scenes (comma-separated: conference, kitchen for speed; cornell,
        /// sponza, kitchen, kitchen-diffuse for quality). Default: all.
        #[arg(long, value_delimiter = ',')]
        only: Vec<String>,
    },
    /// The denoisers (the à-trous filter and the regression over the samples' halves) on
    /// the scenes their settings were tuned on (Cornell box, Sponza, the kitchen) and on
    /// scenes they were never given (the feature demo and the studio: glass, mirrors,
    /// textures; Mitsuba's envmap, materials and bunny scenes: an HDR map, delta lights,
    /// 69k triangles): relMSE of 4 samples per pixel denoised against 64 raw and of 16
    /// denoised against 256 raw (median of three seeds; goal: a ratio of at most 1), against
    /// path-traced references cached in target/bench-cache/ (minutes each); then each
    /// denoiser's time per frame at 512x384 and 1024x768. Run from the checkout's root.
    Denoise {
        /// The shared scenes folder.
        #[arg(long, default_value = "../shared/scenes")]
        dir: PathBuf,
        /// The reference scenes' folder.
        #[arg(long, default_value = "crates/render/tests/data/mitsuba")]
        data: PathBuf,
        /// Image size of the quality figures.
        #[arg(long, default_value = "256x192", value_parser = render_cmd::parse_size)]
        size: (u32, u32),
        /// Samples per pixel of the references.
        #[arg(long, default_value_t = 2048)]
        reference_spp: u32,
        /// Only these scenes (comma-separated: cornell, sponza, kitchen, demo, studio,
        /// envmap, materials, bunny). Default: all.
        #[arg(long, value_delimiter = ',')]
        only: Vec<String>,
    },
    /// Shaded frames per second (primary rays, one shadow ray per light, shading; no
    /// reflections) on the benchmark presets at 512x384 and 1024x768, traced in packets and
    /// ray by ray. One JSON line per figure, and SaarCOR's Table 3 rate where it has one.
    Frame {
        /// Scene presets: conference, sponza, kitchen, bunny, museum (the cameras of
        /// shared/bench/compare.sh, one point light where the Embree harness puts it).
        #[arg(value_delimiter = ',', default_value = "conference")]
        scenes: Vec<String>,
        /// The shared scenes folder.
        #[arg(long, default_value = "../shared/scenes")]
        dir: PathBuf,
        /// Frame sizes, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "512x384,1024x768", value_parser = render_cmd::parse_size)]
        sizes: Vec<(u32, u32)>,
        /// Thread counts, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "2")]
        threads: Vec<usize>,
        /// Timed frames per figure (the median is reported).
        #[arg(long, default_value_t = 15)]
        frames: usize,
        /// Time packets only (by default ray-by-ray tracing is timed too, for comparison).
        #[arg(long)]
        packets_only: bool,
        #[command(flatten)]
        pin: PinArgs,
    },
    /// Dynamic scenes: TLAS rebuild for 1k/10k/100k instances, BLAS refit (100k-triangle
    /// grid, the museum's animated mesh, and how its SAH cost decays), and whole animated
    /// frames of the BART kitchen and museum. One JSON line per figure.
    Dynamic {
        /// The shared scenes folder (for the BART scenes).
        #[arg(long, default_value = "../shared/scenes")]
        scenes: PathBuf,
        /// Animation frames timed per scene.
        #[arg(long, default_value_t = 30)]
        frames: usize,
        /// Frame size.
        #[arg(long, default_value = "512x384", value_parser = render_cmd::parse_size)]
        size: (u32, u32),
        #[command(flatten)]
        pin: PinArgs,
    },
    /// Watertightness: rays from inside closed meshes (an icosphere, a torus, a cube with
    /// shared edges; at 1e-4, 1 and 1e4 scale, turned off the axes) aimed at their vertices
    /// and edges, where a ray must hit. Prints, per mesh and triangle test (unit-triangle,
    /// watertight), the rays that met nothing: leaks.
    Leaks {
        /// Rays per triangle test, split evenly over the nine meshes.
        #[arg(long, default_value_t = 100_000_000)]
        rays: u64,
        /// Seed of the ray set.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// The network device: frames per second and latency (batch sent -> frame received) for
    /// 1 and 64 clients streaming moving-sphere programs, server memory, and words per
    /// second accepted. Runs its own server on loopback.
    Net {
        /// Comma-separated client counts.
        #[arg(long, default_value = "1,64", value_delimiter = ',')]
        clients: Vec<usize>,
        /// Seconds per client count.
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
        /// Frame size.
        #[arg(long, default_value = "512x384", value_parser = render_cmd::parse_size)]
        size: (u32, u32),
        /// Pixel format of the frames.
        #[arg(long, default_value = "png", value_parser = ["png", "rgb8", "rgb565"])]
        format: String,
        /// Soak instead: `--soak-clients` concurrent clients on loopback, one in ten of them
        /// hostile (garbage, truncated and oversize messages, stalled readers, abrupt
        /// disconnects, slow writers), while the well-formed ones ask for `--soak-frames`
        /// frames each and check every pixel against what `lucent run` renders. Prints lost
        /// and wrong frames (goal 0), latency, the server's memory over time and panics;
        /// fails when a frame is lost or wrong or anything panicked.
        #[arg(long)]
        soak: bool,
        /// Clients of the soak.
        #[arg(long, default_value_t = 64)]
        soak_clients: usize,
        /// Frames each well-formed client asks for in the soak.
        #[arg(long, default_value_t = 10_000)]
        soak_frames: u64,
    },
    /// The path tracer against Mitsuba 3 on the reference scenes (crates/render/tests/data/
    /// mitsuba): samples per second, relMSE at 64 samples per pixel against Mitsuba's
    /// 4,096-sample reference, the samples and seconds lucent needs to reach Mitsuba's own
    /// 64-sample relMSE, and Mitsuba's 64-sample time (its second render) when
    /// tools/mitsuba/python runs here (tools/mitsuba/setup makes it); and the ceiling:
    /// how many times faster lucent would be if only its rays cost time (the equal-error
    /// render's rays traced again alone). Then a cost table: nanoseconds per sample of the
    /// scalar and the lane path tracer, the lane one split into traversal, shading and the
    /// rest by its stage clocks, with how full its lanes were. Run from the checkout's root.
    Path {
        /// The reference scenes' folder.
        #[arg(long, default_value = "crates/render/tests/data/mitsuba")]
        data: PathBuf,
        /// The shared scenes folder (a reference scene's `$scenes` parameter).
        #[arg(long, default_value = "../shared/scenes")]
        dir: PathBuf,
        /// Only these scenes (folder names under --data, e.g. `--scene envmap`). Repeatable
        #[arg(long = "scene")]
        scenes: Vec<String>,
    },
    /// The viewer's path mode without a window: frames per second while the camera moves
    /// (one sample per pixel at the resolution the viewer's planner picks to hold the
    /// target frame rate) and seconds until the still image has its samples, on the
    /// feature demo and Sponza (point and spot lights, depth 6), with the lane path
    /// tracer and the scalar one. Then what the viewer shows while moving, at half the
    /// size: its frame rate with the guides, the blend with the frames before
    /// (reprojected) and the denoiser, and the last frame's relMSE against 256 samples
    /// per pixel, raw, denoised alone and blended then denoised. Run from the checkout's
    /// root.
    Viewer {
        /// The reference scenes' folder.
        #[arg(long, default_value = "crates/render/tests/data/mitsuba")]
        data: PathBuf,
        /// The shared scenes folder.
        #[arg(long, default_value = "../shared/scenes")]
        dir: PathBuf,
        /// Window size.
        #[arg(long, default_value = "1024x768", value_parser = render_cmd::parse_size)]
        size: (u32, u32),
        /// Frames while moving (the second half is reported).
        #[arg(long, default_value_t = 40)]
        frames: usize,
        /// The frame rate the planner holds while moving.
        #[arg(long, default_value_t = 30.0)]
        target_fps: f64,
        /// Samples per pixel of the still image.
        #[arg(long, default_value_t = 64)]
        spp: u32,
    },
    /// REND3R's Table IV scenes (1..4096 spheres, 0/1 lights): frame times, and words per
    /// second through the assembler and the processor.
    ///
    /// Each frame is timed whole: a new processor runs the program to its `nf`, then the
    /// scene, its acceleration structure and the picture are made. Each row is compared
    /// with its own row of REND3R's Table IV (0.435 / 0.906 / 8.456 s for 16 / 256 /
    /// 4,096 spheres without a light, twice that with one; other counts: the paper's
    /// cycle formula), as "x faster".
    Rend3r {
        /// Timed frames per scene (median reported).
        #[arg(long, default_value_t = 5)]
        frames: usize,
        /// Frame size.
        #[arg(long, default_value = "512x384", value_parser = render_cmd::parse_size)]
        size: (u32, u32),
        /// Sphere counts of the rows to time (Table IV has 1, 16, 256 and 4096).
        #[arg(long, value_delimiter = ',', default_value = "1,16,256,4096")]
        spheres: Vec<usize>,
        /// Light counts of the rows to time (Table IV has 0 and 1).
        #[arg(long, value_delimiter = ',', default_value = "0,1")]
        lights: Vec<usize>,
        #[command(flatten)]
        pin: PinArgs,
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
        /// Kernels to time: single rays, 8-ray packets (4×2-pixel blocks) and 64-ray
        /// packets (8×8-pixel tiles). One JSON line each.
        #[arg(long, value_delimiter = ',', default_value = "single,packet8,packet64")]
        api: Vec<bench::Api>,
        /// BVH quality: `high` (binned SAH, then insertion-based optimization: the
        /// default), `sah` (binned SAH only) or `spatial` (with spatial splits).
        #[arg(long, default_value = "high", value_parser = ["high", "sah", "spatial"])]
        quality: String,
        /// Index to trace: `bvh` (lucent's, the default) or `kd` (SaarCOR's kd-tree,
        /// `saarcor::kd`: single rays, and 4-ray packets for any packet API; the
        /// width, watertight, scalar and quality options do not apply to it).
        #[arg(long, default_value = "bvh", value_parser = ["bvh", "kd"])]
        index: String,
        #[command(flatten)]
        pin: PinArgs,
    },
}

fn main() -> std::process::ExitCode {
    // A panic inside an image decoder is contained by `lucent_scene::decode_image` (the
    // image is skipped with a warning that gives the decoder's message): not a crash report.
    lucent_scene::contain_decoder_panics();
    keep_freed_memory();
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // User errors: one clear message (with its causes), no backtrace.
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Frames are rendered over and over (the device, the viewer, the benches), each making
/// and dropping buffers of megabytes: glibc's allocator maps such buffers fresh each time
/// and gives freed heap back to the system, so every frame paid its pages' faults and
/// zeroing again (8% of a REND3R Table IV frame of 4,096 spheres). Large blocks come from
/// the heap and freed memory stays with the process instead (up to 256 MB kept).
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets allocator parameters; it is called before any other
    // thread exists, and a refused setting (a zero return) leaves the defaults.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 64 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
    }
}

fn run() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn,winit=error,calloop=error")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    // Rust ignores SIGPIPE, so printing into a closed pipe (`lucent info … | head -2`) made
    // `println!` panic. With the default action such a command ends quietly, as `cat` does.
    // Not for the commands that hold connections (the network device and its client, the
    // viewer's X server): a peer that hangs up must be an error they handle, not a signal
    // that ends the process.
    #[cfg(unix)]
    if !matches!(cli.cmd, Cmd::Serve(_) | Cmd::Send { .. } | Cmd::View { .. }) {
        // SAFETY: called before this process starts any thread of its own (the tracing
        // subscriber starts none); it only resets one signal's action to the default.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        }
    }
    match cli.cmd {
        Cmd::Render(args) => render_cmd::run(args),
        Cmd::Info { scene, demo } => render_cmd::info(scene.as_deref(), demo),
        Cmd::Report(args) => report_cmd::run(args),
        Cmd::Animate(args) => animate_cmd::run(args),
        Cmd::View(args) => view_cmd::run(args),
        Cmd::Asm { program, output, format, camera_table } => isa_cmd::asm(&program, output, format, isa_cmd::table(camera_table == "old")),
        Cmd::Run { program, mode, sets, size, frames, seconds, painter, spp, camera_table, output, compat, switches, cycles } => {
            run_cmd::run(run_cmd::RunArgs {
                program,
                mode: if mode == "raster" { rend3r_machine::Mode::Raster } else { rend3r_machine::Mode::Raytrace },
                sets: sets.map(|s| if s == "triangles" { rend3r_machine::SetKind::Triangles } else { rend3r_machine::SetKind::Shapes }),
                size,
                frames,
                seconds,
                painter,
                spp,
                camera_table: isa_cmd::table(camera_table == "old"),
                output,
                board: compat.map(|_| switches),
                cycles,
            })
        }
        Cmd::Disasm { file, camera_table, triangles } => isa_cmd::disasm(&file, isa_cmd::table(camera_table == "old"), triangles),
        Cmd::Bench(BenchCmd::Rend3r { frames, size, spheres, lights, pin }) => {
            threads::global(!pin.no_pin)?;
            rend3r_bench::run(frames, size, &spheres, &lights)
        }
        Cmd::Bench(BenchCmd::Frame { scenes, dir, sizes, threads, frames, packets_only, pin }) => {
            frame_bench::run(&frame_bench::FrameOptions { scenes, dir, sizes, threads, frames, single: !packets_only, pin: !pin.no_pin })
        }
        Cmd::Bench(BenchCmd::Dynamic { scenes, frames, size, pin }) => {
            threads::global(!pin.no_pin)?;
            dynamic_bench::run(&scenes, frames, size)
        }
        Cmd::Bench(BenchCmd::Leaks { rays, seed }) => leaks_bench::run(rays, seed),
        Cmd::Bench(BenchCmd::Path { data, dir, scenes }) => path_bench::run(&data, &dir, &scenes),
        Cmd::Bench(BenchCmd::Viewer { data, dir, size, frames, target_fps, spp }) => {
            viewer_bench::run(&viewer_bench::ViewerOptions { data: &data, dir: &dir, size, frames, target_fps, spp })
        }
        Cmd::Bench(BenchCmd::Vpl { dir, size, frames, reference_spp, speed_only, only }) => {
            vpl_bench::run(&vpl_bench::VplOptions { dir, size, frames, reference_spp, speed_only, only })
        }
        Cmd::Bench(BenchCmd::Denoise { dir, data, size, reference_spp, only }) => {
            denoise_bench::run(&denoise_bench::DenoiseOptions { dir, data, size, reference_spp, only })
        }
        Cmd::Bench(BenchCmd::Net { soak: true, soak_clients, soak_frames, .. }) => net_cmd::soak(soak_clients, soak_frames),
        Cmd::Bench(BenchCmd::Net { clients, seconds, size, format, .. }) => net_cmd::bench(&clients, seconds, size, pixel_format(&format)),
        Cmd::Serve(a) => net_cmd::serve(rend3r_net::ServerConfig {
            listen: a.listen,
            udp: (!a.no_udp).then_some(a.udp),
            http: (!a.no_http).then_some(a.http),
            width: a.size.0,
            height: a.size.1,
            mode: if a.mode == "raster" { rend3r_machine::Mode::Raster } else { rend3r_machine::Mode::Raytrace },
            shared: a.shared,
            max_message: a.max_message,
            max_frame_pixels: u64::from(a.max_frame.0) * u64::from(a.max_frame.1),
            max_connections: a.max_connections.max(1),
            idle_timeout: std::time::Duration::from_secs(a.idle_timeout.max(1)),
            write_timeout: std::time::Duration::from_secs(a.write_timeout.max(1)),
            udp_chunk: a.udp_chunk,
            device: rend3r_net::DeviceLimits {
                max_shapes: a.max_shapes,
                max_lights: a.max_lights,
                max_program_words: a.max_program_words,
                ..rend3r_net::DeviceLimits::default()
            },
            examples: a.examples.or_else(net_cmd::default_examples),
        }),
        Cmd::Send { program, to, format, frames, size, mode, udp, camera_table, output } => net_cmd::send(&net_cmd::SendArgs {
            program,
            to,
            format: pixel_format(&format),
            frames,
            size,
            mode: match mode.as_deref() {
                Some("raster") => rend3r_net::WireMode::Raster,
                Some(_) => rend3r_net::WireMode::Raytrace,
                None => rend3r_net::WireMode::Default,
            },
            udp,
            camera_table_old: camera_table == "old",
            output,
        }),
        Cmd::Bench(BenchCmd::Rays {
            dir,
            name,
            threads,
            frames,
            warmup,
            kinds,
            width,
            watertight,
            scalar,
            dump_ids,
            api,
            quality,
            index,
            pin,
        }) => bench::rays(
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
                apis: api,
                quality: render_cmd::quality_of(&quality),
                pin: !pin.no_pin,
                kd: index == "kd",
            },
        ),
    }
}

fn pixel_format(s: &str) -> rend3r_net::PixelFormat {
    match s {
        "rgb8" => rend3r_net::PixelFormat::Rgb8,
        "rgb565" => rend3r_net::PixelFormat::Rgb565,
        _ => rend3r_net::PixelFormat::Png,
    }
}

fn parse_u16(s: &str) -> Result<u16, String> {
    rend3r_isa::number::parse_uint(&s.to_lowercase())
        .and_then(|v| u16::try_from(v).ok())
        .ok_or_else(|| format!("'{s}' is not a 16-bit unsigned number (e.g. 0x001f)"))
}
