//! `bake`: the offline baker.
//!
//!     bake scenes/cornell/bake.toml            bake the config (writes its output file)
//!     bake scenes/cornell                      the same: a folder means its bake.toml
//!     bake model.glb [--print-config]          bake a glTF with defaults (or print them)
//!     bake CONFIG --shard I/N                  bake shard I of N into a shard file
//!     bake merge SHARD... --out FILE           merge shard files into the bake file
//!
//! The config's `mode` picks the baker: per pixel (`run_pixel`) or per vertex (`run_vertex`;
//! `--spp` is then N1, the directions traced from each vertex). A per-vertex bake saves its
//! finished units in `<output>.partial/` as it goes; `--resume` continues a killed one, and
//! with `--keep-traced` recompresses a finished one with other `[vertex]` compression keys.
//! Shards (docs/shards.md): `--shard I/N`, or a scheduler's job-array variables.
//!
//! A bake replaces an existing file at its output path (written atomically when the bake is
//! done); `bake` says so when it starts and in its summary (`"replaced": true` with `--json`).
//!
//! Measurements and reports are the `bench` binary's (crate `prt-bench`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};
use prt_bake::config::{BakeConfig, Mode};
use prt_bake::pixel::Precision;
use prt_bake::progress::Progress;
use prt_bake::run::{
    load_scene, run_merge, run_pixel, run_vertex, CheckpointMode, PixelRunSettings,
    VertexRunSettings,
};
use prt_bake::scene::Scene;
use prt_bake::shard::ShardSpec;
use prt_bake::units::human_bytes;
use prt_cli::{parse_size, Stderr};

#[derive(Parser, Debug)]
#[command(
    name = "bake",
    version,
    about = "PRT baker: bakes transfer tensors for editable-material relighting"
)]
#[command(args_conflicts_with_subcommands = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    bake: BakeArgs,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Merge the shard files of one bake (`bake CONFIG --shard I/N`) into the bake file:
    /// byte-identical to the unsharded bake. A missing, duplicated, truncated or foreign shard
    /// is refused by name, and nothing is written.
    Merge {
        /// The shard files, every one of the bake's, in any order.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// The bake file to write.
        #[arg(long)]
        out: PathBuf,
        /// No progress on stderr.
        #[arg(long)]
        quiet: bool,
        /// Print one JSON object with the figures of the merge.
        #[arg(long)]
        json: bool,
    },
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
    /// Continue a killed per-vertex bake or shard from its checkpoint (`<output>.partial/`);
    /// the file is the same bytes as an uninterrupted bake's. Refused, naming what changed,
    /// when the config, scene, flags or program differ from the interrupted bake's.
    #[arg(long, conflicts_with = "no_checkpoint")]
    resume: bool,
    /// Do not keep a per-vertex bake's finished units for a resume (they are still written to
    /// `<output>.partial/` as the bake's working storage, and removed if it fails; a killed
    /// bake then starts over).
    #[arg(long)]
    no_checkpoint: bool,
    /// Keep every unit's traced tensors before compression (about the f32 size of the dense
    /// tensors on disk) and the checkpoint after the file is written: `--resume` with other
    /// `[vertex]` compression keys then compresses again without tracing a ray.
    #[arg(long, alias = "keep-checkpoint", conflicts_with = "no_checkpoint")]
    keep_traced: bool,
    /// Bake shard I of N (0-based, e.g. 0/4 .. 3/4) into a shard file (default name:
    /// `<output>.shard-I-of-N`); `bake merge` makes the bake from all N. Without it, the
    /// shard is read from a scheduler's job-array variables when set (Slurm
    /// SLURM_ARRAY_TASK_ID/COUNT, Kubernetes JOB_COMPLETION_INDEX with PRT_SHARD_COUNT, AWS
    /// Batch AWS_BATCH_JOB_ARRAY_INDEX/SIZE; docs/shards.md).
    #[arg(long, value_parser = parse_shard)]
    shard: Option<ShardSpec>,
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

fn parse_shard(text: &str) -> Result<ShardSpec, String> {
    ShardSpec::parse(text).map_err(|e| e.to_string())
}

fn run(cli: Cli) -> Result<()> {
    if let Some(Command::Merge {
        shards,
        out,
        quiet,
        json,
    }) = cli.command
    {
        let progress = Stderr::new(quiet || json);
        let existed = out.exists();
        let summary = run_merge(&shards, &out, &progress)?;
        if json {
            print_json(&summary, existed)?;
        } else {
            eprintln!(
                "merged {} {} shards ({} units) into {}{} in {:.2} s: {}",
                summary.shards,
                summary.mode,
                summary.units,
                summary.output.display(),
                prt_cli::replaced(existed),
                summary.seconds,
                human_bytes(summary.file_bytes)
            );
        }
        return Ok(());
    }
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
    let shard = match a.shard {
        Some(s) => Some(s),
        None => match ShardSpec::from_scheduler(|k| std::env::var(k).ok())? {
            Some((spec, from)) => {
                progress.note(&format!("shard {spec} from the job array ({from})"));
                Some(spec)
            }
            None => None,
        },
    };
    let output = a.out.clone().unwrap_or_else(|| config.output.clone());
    let output = match shard {
        Some(spec) => prt_bake::run::shard_output(&output, spec),
        None => output,
    };
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
        Mode::Pixel => bake_pixel(&config, &scene, a, precision, shard, &progress, existed),
        Mode::Vertex => bake_vertex(&config, &scene, a, precision, shard, &progress, existed),
    }
}

fn bake_pixel(
    config: &BakeConfig,
    scene: &Scene,
    a: &BakeArgs,
    precision: Option<Precision>,
    shard: Option<ShardSpec>,
    progress: &Stderr,
    existed: bool,
) -> Result<()> {
    for (given, flag) in [
        (a.resume && shard.is_none(), "--resume"),
        (a.no_checkpoint, "--no-checkpoint"),
        (a.keep_traced, "--keep-traced"),
    ] {
        if given {
            bail!(
                "{flag} applies to per-vertex bakes and per-pixel shards (a whole per-pixel bake \
                 keeps no checkpoint); {} has mode = \"pixel\"",
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
        shard,
        resume: a.resume,
    };
    let summary = run_pixel(config, scene, &settings, progress)?;
    if a.json {
        print_json(&summary, existed)?;
    } else {
        eprintln!(
            "baked {}{}{} in {:.2} s ({:.2} Mrays/s): {}",
            summary.output.display(),
            summary
                .shard
                .map_or(String::new(), |s| format!(" (shard {s})")),
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
    shard: Option<ShardSpec>,
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
        keep_traced: a.keep_traced,
        shard,
    };
    let summary = run_vertex(config, scene, &settings, progress)?;
    if a.json {
        print_json(&summary, existed)?;
    } else {
        eprintln!(
            "baked {}{}{} in {:.2} s ({} vertices, {:.0} vertices/s, {:.2} Mrays/s): {}",
            summary.output.display(),
            summary
                .shard
                .map_or(String::new(), |s| format!(" (shard {s})")),
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
