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
    /// Per-vertex bakes at scale: time and peak memory against the vertex count (10K to 1M) on
    /// generated yards, and the shard balance for N = 4 and 16 (docs/report-vertex.md, "Scale").
    Scale(prt_bench::vertex::scale::ScaleArgs),
    /// The per-vertex error budget: relit images against converged ground truth (independent
    /// reference seeds averaged, their noise measured), split by region and by part of the
    /// method (compression, bake noise, T0's Haar truncation, the rest) (docs/report-vertex.md,
    /// "Error budget").
    Budget(prt_bench::vertex::budget::BudgetArgs),
    /// Compares linear images (EXR): relative L2 of each against the last, and the ratio of
    /// their means (a bias shows as a ratio away from 1).
    Diff {
        /// Images; the last is the reference.
        #[arg(required = true, num_args = 2..)]
        images: Vec<PathBuf>,
        #[arg(long)]
        json: bool,
        /// Also split the figures by region: what each pixel's camera ray meets first in this
        /// config's scene from its camera (every material, and the background). The images
        /// must be renders of that view.
        #[arg(long, value_name = "CONFIG")]
        regions: Option<PathBuf>,
    },
    /// Writes the generated outdoor scene "the yard" (a ground grid, an editable GGX sphere,
    /// Blinn-Phong torus and diffuse box; `prt_bake::testing::Yard`) as glTF plus a per-vertex
    /// bake.toml, at any size, with or without NORMAL attributes.
    Yard {
        /// Folder to write yard.gltf, yard.bin and bake.toml into.
        #[arg(long)]
        out: PathBuf,
        /// Leave the NORMAL attributes out (the loader then makes every mesh faceted).
        #[arg(long)]
        no_normals: bool,
        /// Quads per side of the ground grid.
        #[arg(long, default_value_t = 120)]
        ground_quads: u32,
        /// Subdivisions of the sphere (faces: 20 * 4^n).
        #[arg(long, default_value_t = 5)]
        sphere_subdivisions: u32,
        /// The environment map the config names (absolute, or relative to --out).
        #[arg(long)]
        environment: Option<PathBuf>,
    },
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
        Command::Scale(args) => {
            let section = prt_bench::vertex::scale::run(&args)?;
            print!("{section}");
            Ok(())
        }
        Command::Budget(args) => {
            let section = prt_bench::vertex::budget::run(&args)?;
            print!("{section}");
            Ok(())
        }
        Command::Yard {
            out,
            no_normals,
            ground_quads,
            sphere_subdivisions,
            environment,
        } => {
            let yard = prt_bake::testing::Yard {
                ground_quads,
                sphere_subdivisions,
                normals: !no_normals,
                ..Default::default()
            };
            let env = match environment {
                Some(e) => e,
                None => std::fs::canonicalize("scenes/envmaps/sky.exr")?,
            };
            let config = yard.write(&out, &env)?;
            eprintln!(
                "wrote {} ({} vertices in the glTF)",
                config.display(),
                yard.gltf_vertices()
            );
            Ok(())
        }
        Command::Diff {
            images,
            json,
            regions,
        } => {
            let read = |p: &PathBuf| -> Result<(usize, usize, Vec<[f32; 3]>)> {
                prt_formats::read_exr_rgb(p).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))
            };
            let Some((last, rest)) = images.split_last() else {
                bail!("give at least two images");
            };
            let (w, h, reference) = read(last)?;
            let masks: Vec<(String, Vec<bool>)> = match &regions {
                Some(c) => {
                    let (_, scene) = prt_bake::run::load(c, &prt_bake::progress::Silent)?;
                    let first = prt_bake::view::first_hit_materials(&scene, w as u32, h as u32);
                    let mut m: Vec<(String, Vec<bool>)> = scene
                        .materials
                        .iter()
                        .enumerate()
                        .map(|(i, mat)| {
                            let mask = first.iter().map(|f| *f == Some(i as u32)).collect();
                            (mat.name.clone(), mask)
                        })
                        .collect();
                    m.push((
                        "background".into(),
                        first.iter().map(Option::is_none).collect(),
                    ));
                    m.retain(|(_, mask)| mask.iter().any(|&x| x));
                    m
                }
                None => Vec::new(),
            };
            let mean = |v: &[[f32; 3]]| {
                v.iter().map(|p| f64::from(p[0] + p[1] + p[2])).sum::<f64>()
                    / (3 * v.len().max(1)) as f64
            };
            let mut rows = Vec::new();
            for p in rest {
                let (w2, h2, img) = read(p)?;
                if (w2, h2) != (w, h) {
                    bail!(
                        "{} is {w2}x{h2}, {} is {w}x{h}",
                        p.display(),
                        last.display()
                    );
                }
                let rel = prt_bake::metrics::relative_l2(&img, &reference);
                let ratio = mean(&img) / mean(&reference);
                if !json {
                    println!("{}: rel. L2 {rel:.4}, mean ratio {ratio:.4}", p.display());
                }
                let mut by_region = serde_json::Map::new();
                for (name, mask) in &masks {
                    let e = prt_bake::metrics::region_error(&img, &reference, mask);
                    if !json {
                        println!(
                            "  {name} ({} pixels): rel. L2 {:.4}, mean ratio {:.4}, share of the squared error {:.3}",
                            e.pixels,
                            e.relative_l2,
                            e.mean_ratio,
                            e.squared_share / (rel * rel).max(1e-300)
                        );
                    }
                    by_region.insert(
                        name.clone(),
                        serde_json::json!({"pixels": e.pixels, "relative_l2": e.relative_l2, "mean_ratio": e.mean_ratio}),
                    );
                }
                rows.push(serde_json::json!({"image": p, "relative_l2": rel, "mean_ratio": ratio, "regions": by_region}));
            }
            if json {
                println!("{}", serde_json::Value::Array(rows));
            }
            Ok(())
        }
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
