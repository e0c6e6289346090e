//! `prt-fuzz`: fuzzing on the stable toolchain (docs/fuzzing.md).
//!
//! ```text
//! prt-fuzz TARGET [--seconds N | --runs N] [--seed S] [--corpus DIR]
//! ```
//!
//! Targets: `bake-file` (the bake-file reader and the runtime on top of it), `config` (the
//! bake-config parser and its resolution against a scene), `gltf` (the glTF loader), `all`.
//! Each execution must not panic, must finish within `--hang-seconds`, and must keep the live
//! heap under `--memory-limit-mib`. Failing inputs are saved under `target/fuzz-failures/`;
//! the exit status is non-zero when anything failed.

mod alloc;
mod engine;
mod json_mut;
mod mutate;
mod targets;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, ValueEnum};

use engine::{Budget, Report, Settings, Target};

#[global_allocator]
static GLOBAL: alloc::Counting = alloc::Counting;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Which {
    BakeFile,
    Config,
    Gltf,
    All,
}

impl Which {
    fn name(self) -> &'static str {
        match self {
            Which::BakeFile => "bake-file",
            Which::Config => "config",
            Which::Gltf => "gltf",
            Which::All => "all",
        }
    }
}

/// Fuzz the bake-file reader, the config parser and the glTF loader (docs/fuzzing.md).
#[derive(Parser, Debug)]
#[command(name = "prt-fuzz")]
struct Args {
    /// What to fuzz.
    target: Which,
    /// Seconds of fuzzing per target (default 60 when neither this nor --runs is given).
    #[arg(long, conflicts_with = "runs")]
    seconds: Option<f64>,
    /// Executions per target (seeds included), instead of a time budget: the run is then
    /// exactly reproducible.
    #[arg(long)]
    runs: Option<u64>,
    /// Seed of the mutations; the same seed and --runs repeat a run input for input.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Extra seed inputs: a folder of inputs, or (with `all`) a folder holding one such folder
    /// per target, named like the target. fuzz/corpus/<target> is always used.
    #[arg(long)]
    corpus: Option<PathBuf>,
    /// An execution running longer than this is a hang.
    #[arg(long, default_value_t = 5.0)]
    hang_seconds: f64,
    /// Live heap limit in MiB; an allocation past it is a failure.
    #[arg(long, default_value_t = 2048)]
    memory_limit_mib: usize,
    /// Print every outcome seen and how often.
    #[arg(long)]
    verbose: bool,
    /// Run one saved input (a file, or for `gltf` a folder holding scene.gltf) under the same
    /// checks instead of fuzzing, e.g. one from target/fuzz-failures/.
    #[arg(long, conflicts_with_all = ["seconds", "runs"])]
    replay: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    if args.replay.is_some() && args.target == Which::All {
        eprintln!("prt-fuzz: --replay needs one target (bake-file, config or gltf)");
        return ExitCode::from(2);
    }
    engine::install_hooks();
    alloc::set_limit(args.memory_limit_mib.saturating_mul(1 << 20));
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let workspace = root.parent().unwrap_or(root);
    let scenes = workspace.join("scenes");
    let budget = match (args.seconds, args.runs) {
        _ if args.replay.is_some() => Budget::Runs(1),
        (_, Some(r)) => Budget::Runs(r),
        (Some(s), None) => Budget::Seconds(s),
        (None, None) => Budget::Seconds(60.0),
    };
    let settings = Settings {
        budget,
        seed: args.seed,
        hang: Duration::from_secs_f64(args.hang_seconds.max(0.01)),
        failures_dir: workspace.join("target").join("fuzz-failures"),
        status_every: match budget {
            Budget::Seconds(s) if s > 60.0 => Some(Duration::from_secs(30)),
            _ => None,
        },
    };
    let which = match args.target {
        Which::All => vec![Which::BakeFile, Which::Config, Which::Gltf],
        one => vec![one],
    };
    let mut reports = Vec::new();
    for w in which {
        let name = w.name();
        let mut extra = vec![root.join("corpus").join(name)];
        if let Some(c) = &args.corpus {
            extra.push(if args.target == Which::All {
                c.join(name)
            } else {
                c.clone()
            });
        }
        let target: anyhow::Result<Box<dyn Target>> = match w {
            Which::BakeFile => {
                targets::bake_file::BakeFileTarget::new(&scenes, extra).map(|t| Box::new(t) as _)
            }
            Which::Config => {
                targets::config::ConfigTarget::new(&scenes, extra).map(|t| Box::new(t) as _)
            }
            _ => targets::gltf::GltfTarget::new(&scenes, extra).map(|t| Box::new(t) as _),
        };
        let target = match (target, &args.replay) {
            (Ok(t), Some(path)) => Box::new(engine::Replay {
                inner: t,
                path: path.clone(),
            }) as Box<dyn Target>,
            (Ok(t), None) => t,
            (Err(e), _) => {
                eprintln!("prt-fuzz: target {name}: {e:#}");
                return ExitCode::from(2);
            }
        };
        let doing = if args.replay.is_some() {
            "replaying"
        } else {
            "fuzzing"
        };
        eprintln!("prt-fuzz: {doing} {name} ...");
        // Each target draws from its own stream, so `all` and a single target agree.
        let report = engine::run_target(target, &settings, w as u64);
        print_report(&report, args.verbose || args.replay.is_some());
        reports.push(report);
    }
    let failures: usize = reports.iter().map(|r| r.failures.len()).sum();
    println!(
        "prt-fuzz: {} executions in {:.1} s, {} failure(s), peak live heap {} MiB",
        reports.iter().map(|r| r.execs).sum::<u64>(),
        reports
            .iter()
            .map(|r| r.seconds + r.setup_seconds)
            .sum::<f64>(),
        failures,
        alloc::peak() >> 20
    );
    if failures > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}

fn print_report(r: &Report, verbose: bool) {
    let ok = r
        .outcomes
        .iter()
        .filter(|(k, _)| k.starts_with("ok"))
        .map(|(_, n)| n)
        .sum::<u64>();
    println!(
        "{:<10} {:>9} executions in {:>5.1} s ({:>6.0}/s; seeds made in {:.1} s), {} seeds, \
         {} distinct outcomes, corpus {}, {} accepted, {} failure(s)",
        r.target,
        r.execs,
        r.seconds,
        r.execs as f64 / r.seconds.max(1e-9),
        r.setup_seconds,
        r.seeds,
        r.outcomes.len(),
        r.corpus,
        ok,
        r.failures.len()
    );
    for f in &r.failures {
        println!(
            "  FAILURE ({}) at execution {}: {}\n    input: {}",
            f.kind, f.exec, f.message, f.saved
        );
    }
    for f in &r.caught {
        println!(
            "  note: a library caught a panic at execution {}: {}\n    input: {}",
            f.exec, f.message, f.saved
        );
    }
    if verbose {
        for (o, n) in &r.outcomes {
            println!("  {n:>9}  {o}");
        }
    }
}
