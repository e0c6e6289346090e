//! `bake`: the offline baker.
//!
//!     bake scenes/cornell/bake.toml            bake the config (writes its output file)
//!     bake scenes/cornell                      the same: a folder means its bake.toml
//!     bake model.glb [--print-config]          bake a glTF with defaults (or print them)
//!     bake basis --family blinn-phong ...      BRDF basis error tables and report
//!     bake bench rays                          ray throughput on a ~100K-triangle scene
//!     bake bench pixel                         the per-pixel speed-vs-error report

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};
use prt_bake::pixel::Precision;
use prt_bake::progress::Progress;
use prt_bake::run::{load, load_scene, run_pixel, PixelRunSettings};
use prt_bake::units::human_bytes;
use prt_cli::{parse_size, Stderr};

#[derive(Parser, Debug)]
#[command(
    version,
    about = "PRT baker: bakes transfer tensors for editable-material relighting",
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    bake: BakeArgs,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// BRDF basis: error tables per N_b, timings, automatic N_b selection, the report.
    Basis(prt_bake::basis::cli::BasisArgs),
    /// Benchmarks (figures printed, never asserted).
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(Subcommand, Debug)]
enum BenchCommand {
    /// Rays per second, coherent and incoherent, one thread and all threads.
    Rays {
        /// Rays per measurement.
        #[arg(long, default_value_t = 2_000_000)]
        rays: usize,
        /// Measure on this config's scene instead of the built-in ~100K-triangle scene.
        #[arg(long)]
        config: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
    /// The per-pixel speed-vs-error report: bake and relight timings, bandwidth bound, errors
    /// vs a true-BRDF reference, plots and pictures (docs/report-pixel.md, docs/img/pixel-*).
    Pixel {
        /// Bake configs; the first is the main scene (default: cornell, then ring).
        #[arg(long = "config")]
        configs: Vec<PathBuf>,
        /// The markdown report (default: docs/report-pixel.md; with --quick,
        /// target/report/quick/report-pixel.md).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Folder of the PNGs (default: docs/img; with --quick, target/report/quick/img).
        #[arg(long)]
        img_dir: Option<PathBuf>,
        /// Scratch folder for bake files (deleted after use).
        #[arg(long, default_value = "target/report")]
        work_dir: PathBuf,
        /// Tiny sizes: a smoke run of every step in seconds.
        #[arg(long)]
        quick: bool,
        /// No progress lines on stderr.
        #[arg(long)]
        quiet: bool,
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
    #[arg(long, value_enum, default_value_t = PrecisionArg::F32)]
    precision: PrecisionArg,
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
    match cli.command {
        Some(Command::Basis(args)) => prt_bake::basis::cli::run(&args),
        Some(Command::Bench(BenchCommand::Rays { rays, config, json })) => {
            bench_rays(rays, config, json)
        }
        Some(Command::Bench(BenchCommand::Pixel {
            configs,
            out,
            img_dir,
            work_dir,
            quick,
            quiet,
        })) => bench_pixel(configs, out, img_dir, work_dir, quick, quiet),
        None => {
            let Some(input) = cli.bake.input.clone() else {
                bail!(
                    "give a bake config, a scene folder or a glTF scene, e.g. \
                     `bake scenes/cornell` (see --help)"
                );
            };
            bake(&input, &cli.bake)
        }
    }
}

fn bake(input: &std::path::Path, a: &BakeArgs) -> Result<()> {
    use prt_bake::config::input::{self, InputKind};
    let resolved = input::resolve(input)?;
    if a.print_config {
        print!("{}", resolved.config.to_toml());
        return Ok(());
    }
    let progress = Stderr::new(a.quiet || a.json);
    if resolved.kind == InputKind::Gltf {
        progress.note(&format!(
            "{}: baking with this config (save it with --print-config):\n{}",
            input.display(),
            resolved.config.to_toml()
        ));
    }
    let config = resolved.config;
    let scene = load_scene(&config, &progress)?;
    let settings = PixelRunSettings {
        spp: a.spp,
        width: a.width,
        height: a.height,
        output: a.out.clone(),
        precision: Some(match a.precision {
            PrecisionArg::F32 => Precision::F32,
            PrecisionArg::F16 => Precision::F16,
        }),
        max_memory: a.max_memory,
        compress_rank: a.compress_rank,
        basis_count: a.basis_count,
    };
    let summary = run_pixel(&config, &scene, &settings, &progress)?;
    if a.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        eprintln!(
            "baked {} in {:.2} s ({:.2} Mrays/s): {}",
            summary.output.display(),
            summary.seconds,
            summary.timings.rays_per_second / 1e6,
            human_bytes(summary.file_bytes)
        );
    }
    Ok(())
}

fn bench_rays(rays: usize, config: Option<PathBuf>, json: bool) -> Result<()> {
    let scene = match config {
        Some(c) => load(&c, &Stderr::new(json))?.1,
        None => prt_bake::bench::hundred_k_scene(),
    };
    let figures = prt_bake::bench::ray_throughput(&scene, rays.max(1));
    if json {
        println!(
            "{}",
            serde_json::json!({"triangles": scene.triangles.len(), "results": figures})
        );
    } else {
        println!(
            "ray throughput, {} triangles, {} rays per measurement",
            scene.triangles.len(),
            rays
        );
        println!("{:<24} {:>8} {:>14}", "kind", "threads", "Mrays/s");
        for f in figures {
            println!(
                "{:<24} {:>8} {:>14.2}",
                f.kind,
                f.threads,
                f.rays_per_second / 1e6
            );
        }
    }
    Ok(())
}

fn bench_pixel(
    configs: Vec<PathBuf>,
    out: Option<PathBuf>,
    img_dir: Option<PathBuf>,
    work_dir: PathBuf,
    quick: bool,
    quiet: bool,
) -> Result<()> {
    use prt_bake::report_pixel::{run, ReportOptions, DEFAULT_CONFIGS};
    let configs = if configs.is_empty() {
        let d: Vec<PathBuf> = DEFAULT_CONFIGS.iter().map(PathBuf::from).collect();
        if let Some(missing) = d.iter().find(|p| !p.is_file()) {
            bail!(
                "{} not found: run from the repository root or give --config",
                missing.display()
            );
        }
        d
    } else {
        configs
    };
    let quick_dir = PathBuf::from("target/report/quick");
    let opts = ReportOptions {
        configs,
        out: out.unwrap_or_else(|| {
            if quick {
                quick_dir.join("report-pixel.md")
            } else {
                PathBuf::from("docs/report-pixel.md")
            }
        }),
        img_dir: img_dir.unwrap_or_else(|| {
            if quick {
                quick_dir.join("img")
            } else {
                PathBuf::from("docs/img")
            }
        }),
        work_dir,
        quick,
        command: std::env::args()
            .skip(1)
            .fold("bake".to_string(), |a, b| a + " " + &b),
        verbose: !quiet,
    };
    let summary = run(&opts)?;
    eprintln!(
        "wrote {} and {} images in {:.0} s",
        summary.markdown.display(),
        summary.images.len(),
        summary.seconds
    );
    Ok(())
}
