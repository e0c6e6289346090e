//! `bake`: the offline baker.
//!
//!     bake scenes/cornell/bake.toml            bake the config (writes its output file)
//!
//! Measurements and reports are the `bench` binary's (crate `prt-bench`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args, Parser};
use prt_bake::config::Mode;
use prt_bake::pixel::Precision;
use prt_bake::run::{human_bytes, load, parse_size, run_pixel, PixelRunSettings};

#[derive(Parser, Debug)]
#[command(
    version,
    about = "PRT baker: bakes transfer tensors for editable-material relighting"
)]
struct Cli {
    #[command(flatten)]
    bake: BakeArgs,
}

#[derive(Args, Debug)]
struct BakeArgs {
    /// The bake config (TOML) to bake.
    config: Option<PathBuf>,
    /// Samples per pixel (default: the config's).
    #[arg(long)]
    spp: Option<u32>,
    #[arg(long)]
    width: Option<u32>,
    #[arg(long)]
    height: Option<u32>,
    /// Output bake file (default: the config's `output`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Storage of the transfer tensors: f32 (exact relighting) or f16 (half the size; its
    /// rounding is amplified by cancellation for sharp lobes, see docs/pixel.md).
    #[arg(long, value_parser = ["f16", "f32"], default_value = "f32")]
    precision: String,
    /// Refuse to bake when the estimated memory exceeds this (e.g. 4G).
    #[arg(long, value_parser = parse_size)]
    max_memory: Option<u64>,
    /// Also store a low-rank (PCA over pixels) variant with this many components per group.
    #[arg(long)]
    compress_rank: Option<usize>,
    /// Basis BRDFs per editable glossy family (default: the config's [basis] count or
    /// error_target, else 6 for blinn-phong and 8 for ggx).
    #[arg(long)]
    basis_count: Option<usize>,
    /// No progress or allocation report on stderr.
    #[arg(long)]
    quiet: bool,
    /// Print one JSON object with the figures of the bake.
    #[arg(long)]
    json: bool,
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", prt_formats::describe_error(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    let Some(config) = cli.bake.config.clone() else {
        bail!("give a bake config, e.g. `bake scenes/cornell/bake.toml` (see --help)");
    };
    bake(&config, &cli.bake)
}

fn bake(config_path: &std::path::Path, a: &BakeArgs) -> Result<()> {
    let (config, scene) = load(config_path)?;
    if config.mode == Mode::Vertex {
        bail!(
            "{}: mode = \"vertex\" (per-vertex transfer tensors) is not implemented yet; use mode = \"pixel\"",
            config.config_path.display()
        );
    }
    let settings = PixelRunSettings {
        spp: a.spp,
        width: a.width,
        height: a.height,
        output: a.out.clone(),
        precision: Some(if a.precision == "f16" {
            Precision::F16
        } else {
            Precision::F32
        }),
        max_memory: a.max_memory,
        compress_rank: a.compress_rank,
        basis_count: a.basis_count,
        quiet: a.quiet || a.json,
    };
    let summary = run_pixel(&config, &scene, &settings)?;
    if a.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        eprintln!(
            "baked {} in {:.2} s ({:.2} Mrays/s): {}",
            summary.output.display(),
            summary.seconds,
            summary.stats["rays_per_second"].as_f64().unwrap_or(0.0) / 1e6,
            human_bytes(summary.file_bytes)
        );
    }
    Ok(())
}
