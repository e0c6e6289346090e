//! `bench`: measurements and generated reports (run from the repository root).
//!
//! ```text
//! bench pixel                                  docs/report-pixel.md and docs/img/pixel-*
//! bench pixel --quick                          a smoke run of every step in seconds
//! bench basis --report docs/brdf-basis.md      docs/brdf-basis.md and docs/img/brdf-basis-*
//! bench basis --family blinn-phong --count 6   the error table of one family
//! bench rays                                   ray throughput on a ~100K-triangle scene
//! bench container                              bake file write/open/verify throughput
//! bench compare-rays dump                      rays and triangles for the Embree comparison
//! bench compare-rays time --scene 100k         our ray core on those rays (docs/compare.md)
//! ```

mod compare_rays;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::{Parser, Subcommand};
use prt_bench::pixel::{ReportOptions, DEFAULT_CONFIGS};

#[derive(Parser, Debug)]
#[command(
    version,
    about = "PRT measurements and generated reports (figures printed or written, never asserted)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
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
        /// Folder of the plots and pictures (default: docs/img; with --quick,
        /// target/report/quick/img).
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
    /// BRDF basis: error tables per N_b, timings, automatic N_b selection, the report
    /// (docs/brdf-basis.md with --report).
    Basis(prt_bench::basis::BasisArgs),
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
    /// Bake file container: write (with fsync), open, open_unchecked and checksum throughput
    /// on a ~100 MB file.
    Container {
        /// Values per tensor (four tensors: three f32, one f16).
        #[arg(long, default_value_t = 7_000_001)]
        values: usize,
        /// Repetitions (medians are reported).
        #[arg(long, default_value_t = 5)]
        runs: usize,
        /// Folder of the scratch file.
        #[arg(long, default_value = "target/report")]
        work_dir: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// The ray side of the comparison with Embree and Mitsuba 3 (bench/compare/compare.py,
    /// docs/compare.md): dump a scene's triangles and incoherent bounce rays as raw arrays,
    /// or time our ray core on exactly those rays.
    CompareRays(compare_rays::CompareRaysArgs),
    /// The per-vertex report: a scene baked dense and with several compression settings,
    /// errors against the dense relight and the reference, the three runtime paths timed
    /// (docs/report-vertex.md).
    Vertex(prt_bench::vertex::VertexArgs),
    /// The GPU backend's frames against its goals, beside lavapipe and the CPU runtime
    /// (build with `--features gpu`; bench/gpu.sh runs it on baked scenes).
    #[cfg(feature = "gpu")]
    Gpu(prt_bench::gpu::GpuArgs),
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
        Command::Pixel {
            configs,
            out,
            img_dir,
            work_dir,
            quick,
            quiet,
        } => pixel(configs, out, img_dir, work_dir, quick, quiet),
        Command::Basis(args) => prt_bench::basis::run(&args),
        Command::CompareRays(args) => compare_rays::run(&args),
        Command::Vertex(args) => prt_bench::vertex::run(&args),
        #[cfg(feature = "gpu")]
        Command::Gpu(args) => prt_bench::gpu::run(&args),
        Command::Rays { rays, config, json } => {
            let scene = match config {
                Some(c) => prt_bake::run::load(&c, &prt_bake::progress::Silent)?.1,
                None => prt_bench::rays::hundred_k_scene(),
            };
            let figures = prt_bench::rays::ray_throughput(&scene, rays.max(1));
            if json {
                println!(
                    "{}",
                    serde_json::json!({"triangles": scene.triangles.len(), "results": figures})
                );
            } else {
                prt_bench::rays::print(&scene, rays, &figures);
            }
            Ok(())
        }
        Command::Container {
            values,
            runs,
            work_dir,
            json,
        } => {
            let f = prt_bench::container::measure(&work_dir, values.max(1), runs)?;
            if json {
                println!("{}", serde_json::to_string(&f)?);
            } else {
                prt_bench::container::print(&f);
            }
            Ok(())
        }
    }
}

fn pixel(
    configs: Vec<PathBuf>,
    out: Option<PathBuf>,
    img_dir: Option<PathBuf>,
    work_dir: PathBuf,
    quick: bool,
    quiet: bool,
) -> Result<()> {
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
            .fold("bench".to_string(), |a, b| a + " " + &b),
        verbose: !quiet,
    };
    let summary = prt_bench::pixel::run(&opts)?;
    eprintln!(
        "wrote {} and {} images in {:.0} s",
        summary.markdown.display(),
        summary.images.len(),
        summary.seconds
    );
    Ok(())
}
