//! `bake`: the offline baker.
//!
//!     bake scenes/cornell/bake.toml            bake the config (writes its output file)
//!     bake scenes/cornell                      the same: a folder means its bake.toml
//!     bake model.glb [--print-config]          bake a glTF with defaults (or print them)
//!
//! The config's `mode` picks the baker: per pixel (`run_pixel`) or per vertex (`run_vertex`;
//! `--spp` is then N1, the directions traced from each vertex). A per-vertex bake saves its
//! traced vertices in `<output>.partial/` as it goes; `--resume` continues a killed one, and
//! with `--keep-checkpoint` recompresses a finished one with other `[vertex]` compression keys.
//!
//! A bake replaces an existing file at its output path (written atomically when the bake is
//! done); `bake` says so when it starts and in its summary (`"replaced": true` with `--json`).
//!
//! Measurements and reports are the `bench` binary's (crate `prt-bench`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args, Parser, ValueEnum};
use prt_bake::config::{BakeConfig, Mode};
use prt_bake::pixel::Precision;
use prt_bake::progress::Progress;
use prt_bake::run::{
    load_scene, run_pixel, run_vertex, CheckpointMode, PixelRunSettings, VertexRunSettings,
};
use prt_bake::scene::Scene;
use prt_bake::units::human_bytes;
use prt_cli::{parse_size, Stderr};

#[derive(Parser, Debug)]
#[command(
    name = "bake",
    version,
    about = "PRT baker: bakes transfer tensors for editable-material relighting"
)]
struct Cli {
    #[command(flatten)]
    bake: BakeArgs,
}

/// `--precision` (the library's `Precision` has no clap derive: the libraries stay CLI-free).
#[derive(Clone, Copy, Debug, ValueEnum)]
enum PrecisionArg {
    F32,
    F16,
}

#[derive(Args, Debug)]
struct BakeArgs {
    /// What to bake: a bake config (.toml), a scene folder holding bake.toml, or a glTF scene
    /// (.gltf/.glb) baked with defaults (docs/config.md).
    input: Option<PathBuf>,
    /// Print the config (TOML) that INPUT resolves to on stdout and exit without baking.
    #[arg(long)]
    print_config: bool,
    /// Samples per pixel, or per vertex in vertex mode (default: the config's `spp`; 64 when
    /// it has none).
    #[arg(long)]
    spp: Option<u32>,
    /// Image width (pixel mode only).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (pixel mode only).
    #[arg(long)]
    height: Option<u32>,
    /// Output bake file (default: the config's `output`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Storage of the transfer tensors: f32 (exact relighting) or f16 (half the size, with a
    /// per-group scale; its rounding is amplified by cancellation for sharp lobes, see
    /// docs/pixel.md). Default: f32 in pixel mode, f16 in vertex mode.
    #[arg(long, value_enum)]
    precision: Option<PrecisionArg>,
    /// Refuse to bake when the estimated memory exceeds this (e.g. 4G).
    #[arg(long, value_parser = parse_size)]
    max_memory: Option<u64>,
    /// Also store a low-rank (PCA over pixels) variant with this many components per group
    /// (pixel mode only).
    #[arg(long)]
    compress_rank: Option<usize>,
    /// Basis BRDFs per editable glossy family (default: the config's [basis] count or
    /// error_target, else 6 for blinn-phong and 8 for ggx).
    #[arg(long)]
    basis_count: Option<usize>,
    /// Continue a killed per-vertex bake from its checkpoint (`<output>.partial/`); the file is
    /// the same bytes as an uninterrupted bake's. Refused, naming what changed, when the
    /// config, scene, flags or program differ from the interrupted bake's.
    #[arg(long, conflicts_with = "no_checkpoint")]
    resume: bool,
    /// Do not save a per-vertex bake's traced vertices as it goes (saves the checkpoint's disk
    /// space, about the f32 size of the transfer tensors; a killed bake then starts over).
    #[arg(long)]
    no_checkpoint: bool,
    /// Keep a per-vertex bake's checkpoint after the file is written. The checkpoint holds the
    /// traced vertices before compression and its inputs leave out the `[vertex]` compression
    /// keys, so `--resume` with other compression keys then recompresses without tracing.
    #[arg(long, conflicts_with = "no_checkpoint")]
    keep_checkpoint: bool,
    /// No progress or allocation report on stderr.
    #[arg(long)]
    quiet: bool,
    /// Print one JSON object with the figures of the bake.
    #[arg(long)]
    json: bool,
}

/// Words users type for this tool's flags (clap suggests only flags spelt alike).
const SYNONYMS: &[(&str, &str)] = &[("sample", "spp"), ("samples", "spp"), ("output", "out")];

fn main() -> ExitCode {
    prt_cli::exit_code(run(prt_cli::parse_args(SYNONYMS)))
}

fn run(cli: Cli) -> Result<()> {
    let Some(input) = cli.bake.input.clone() else {
        bail!(
            "give a bake config, a scene folder or a glTF scene, e.g. `bake scenes/cornell` \
             (see --help)"
        );
    };
    bake(&input, &cli.bake)
}

fn bake(input: &std::path::Path, a: &BakeArgs) -> Result<()> {
    use prt_bake::config::input::{self, InputKind};
    let resolved = input::resolve(input)?;
    let progress = Stderr::new(a.quiet || a.json);
    for w in &resolved.warnings {
        progress.warn(w);
    }
    if a.print_config {
        print!("{}", resolved.config.to_toml());
        return Ok(());
    }
    if resolved.kind == InputKind::Gltf {
        progress.note(&format!(
            "{}: baking with this config (save it with --print-config):\n{}",
            input.display(),
            resolved.config.to_toml()
        ));
    }
    let config = resolved.config;
    let output = a.out.clone().unwrap_or_else(|| config.output.clone());
    let existed = output.exists();
    if existed {
        progress.note(&format!(
            "{} exists; this bake replaces it when it is done (until then it stays as it is)",
            output.display()
        ));
    }
    let scene = load_scene(&config, &progress)?;
    let precision = a.precision.map(|p| match p {
        PrecisionArg::F32 => Precision::F32,
        PrecisionArg::F16 => Precision::F16,
    });
    match config.mode {
        Mode::Pixel => bake_pixel(&config, &scene, a, precision, &progress, existed),
        Mode::Vertex => bake_vertex(&config, &scene, a, precision, &progress, existed),
    }
}

fn bake_pixel(
    config: &BakeConfig,
    scene: &Scene,
    a: &BakeArgs,
    precision: Option<Precision>,
    progress: &Stderr,
    existed: bool,
) -> Result<()> {
    for (given, flag) in [
        (a.resume, "--resume"),
        (a.no_checkpoint, "--no-checkpoint"),
        (a.keep_checkpoint, "--keep-checkpoint"),
    ] {
        if given {
            bail!(
                "{flag} applies to per-vertex bakes (a per-pixel bake keeps no checkpoint); {} \
                 has mode = \"pixel\"",
                config.config_path.display()
            );
        }
    }
    let settings = PixelRunSettings {
        spp: a.spp,
        width: a.width,
        height: a.height,
        output: a.out.clone(),
        precision: Some(precision.unwrap_or(Precision::F32)),
        max_memory: a.max_memory,
        compress_rank: a.compress_rank,
        basis_count: a.basis_count,
    };
    let summary = run_pixel(config, scene, &settings, progress)?;
    if a.json {
        print_json(&summary, existed)?;
    } else {
        eprintln!(
            "baked {}{} in {:.2} s ({:.2} Mrays/s): {}",
            summary.output.display(),
            prt_cli::replaced(existed),
            summary.seconds,
            summary.timings.rays_per_second / 1e6,
            human_bytes(summary.file_bytes)
        );
    }
    Ok(())
}

fn bake_vertex(
    config: &BakeConfig,
    scene: &Scene,
    a: &BakeArgs,
    precision: Option<Precision>,
    progress: &Stderr,
    existed: bool,
) -> Result<()> {
    // Flags of the per-pixel image have no meaning here: refuse rather than ignore them.
    for (given, flag) in [
        (a.width.is_some(), "--width"),
        (a.height.is_some(), "--height"),
        (a.compress_rank.is_some(), "--compress-rank"),
    ] {
        if given {
            bail!(
                "{flag} applies to per-pixel bakes; {} has mode = \"vertex\"",
                config.config_path.display()
            );
        }
    }
    let checkpoint = if a.resume {
        CheckpointMode::Resume
    } else if a.no_checkpoint {
        CheckpointMode::Off
    } else {
        CheckpointMode::Save
    };
    let settings = VertexRunSettings {
        spp: a.spp,
        output: a.out.clone(),
        precision,
        max_memory: a.max_memory,
        basis_count: a.basis_count,
        checkpoint,
        keep_checkpoint: a.keep_checkpoint,
    };
    let summary = run_vertex(config, scene, &settings, progress)?;
    if a.json {
        print_json(&summary, existed)?;
    } else {
        eprintln!(
            "baked {}{} in {:.2} s ({} vertices, {:.0} vertices/s, {:.2} Mrays/s): {}",
            summary.output.display(),
            prt_cli::replaced(existed),
            summary.seconds,
            summary.vertices,
            summary.timings.vertices_per_second,
            summary.timings.rays_per_second / 1e6,
            human_bytes(summary.file_bytes)
        );
    }
    Ok(())
}

/// The summary as one JSON object, with the process's peak resident memory and whether the
/// bake replaced an existing file.
fn print_json(summary: &impl serde::Serialize, replaced: bool) -> Result<()> {
    let mut out = serde_json::to_value(summary)?;
    if let Some(o) = out.as_object_mut() {
        o.insert(
            "peak_resident_bytes".into(),
            prt_cli::peak_resident_bytes().into(),
        );
        o.insert("replaced".into(), replaced.into());
    }
    println!("{out}");
    Ok(())
}
