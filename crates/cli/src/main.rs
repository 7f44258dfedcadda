//! lucent: a real-time CPU ray tracer.
use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

mod bench;

#[derive(Parser)]
#[command(name = "lucent", version, about = "lucent: a real-time CPU ray tracer", long_about = None)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Speed reports.
    #[command(subcommand)]
    Bench(BenchCmd),
}

#[derive(Subcommand)]
enum BenchCmd {
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
    },
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.cmd {
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
        }) => bench::rays(
            &dir,
            &bench::RaysOptions {
                name,
                threads,
                frames,
                warmup,
                kinds,
                width: if width == 4 {
                    lucent_accel::Width::W4
                } else {
                    lucent_accel::Width::W8
                },
                test: if watertight {
                    lucent_accel::TriangleTest::Watertight
                } else {
                    lucent_accel::TriangleTest::UnitTriangle
                },
                kernel: if scalar {
                    lucent_accel::Kernel::Scalar
                } else {
                    lucent_accel::Kernel::detect()
                },
            },
        ),
    }
}
