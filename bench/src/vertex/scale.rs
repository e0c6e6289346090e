//! The per-vertex bake at scale (`bench scale`; its section of docs/report-vertex.md): bake
//! time and peak resident memory against the vertex count on generated yards
//! (`prt_bake::testing::Yard`, the ground grid grown), from 10K to 1M vertices, to show the
//! time linear and the memory bounded; and the balance of shards (the slowest shard's time
//! over the mean) for N = 4 and 16.
//!
//! Each bake is the `bake` binary as a user runs it (a child process, so its peak resident set
//! is its own: the `peak_resident_bytes` of its `--json`), one after another on the same
//! machine. The shards of one bake run one after another too: on a cluster they run at once on
//! separate machines, and what decides the wall time is the slowest.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context as _, Result};
use prt_bake::testing::Yard;
use serde_json::Value;

use crate::util::{cpu_model, git_head, load_average, utc_now};

/// Where the section starts and ends in the report (the rest of the report is `bench vertex`'s).
const BEGIN: &str = "<!-- bench scale: begin -->";
const END: &str = "<!-- bench scale: end -->";

/// Arguments of `bench scale`.
#[derive(clap::Args, Debug)]
pub struct ScaleArgs {
    /// Vertex counts to bake (approximate: the ground grid is sized to reach them).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "10000,30000,100000,300000,1000000"
    )]
    pub vertices: Vec<u64>,
    /// Vertex count of the scene the shard balance is measured on.
    #[arg(long, default_value_t = 100_000)]
    pub shard_vertices: u64,
    /// Shard counts whose balance is measured.
    #[arg(long, value_delimiter = ',', default_value = "4,16")]
    pub shards: Vec<u32>,
    /// N1, the first directions per vertex (the defaults' 64 makes a 1M-vertex bake take hours
    /// on two cores; the memory does not depend on it, the time is proportional to it).
    #[arg(long, default_value_t = 4)]
    pub spp: u32,
    /// The environment map the yards are lit by.
    #[arg(long, default_value = "scenes/envmaps/sunset.exr")]
    pub environment: PathBuf,
    /// The report whose scale section is replaced (appended when it has none).
    #[arg(long, default_value = "docs/report-vertex.md")]
    pub out: PathBuf,
    /// Scratch folder for the scenes and bake files (emptied after each bake) and for each
    /// measurement's figures (`yard-<vertices>-n1-<spp>.json`, `shards-...json`).
    #[arg(long, default_value = "target/report/scale")]
    pub work_dir: PathBuf,
    /// Take a measurement from the work folder when an earlier run left its figures there
    /// (same vertex count, shard count and N1) instead of baking again: a 1M-vertex bake
    /// takes over an hour, so the rows can be measured one run at a time. Each row says when
    /// and at which commit it was measured.
    #[arg(long)]
    pub reuse: bool,
}

/// One bake's figures from its `--json`, and when and where they were measured.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct Baked {
    vertices: u64,
    loaded: u64,
    seconds: f64,
    trace_seconds: f64,
    peak_bytes: u64,
    estimated_bytes: u64,
    file_bytes: u64,
    /// UTC time, commit and load average when the bake finished.
    measured: String,
}

/// The shard balance of one shard count: each shard's time, and whether the merge equals the
/// unsharded bake.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct Balance {
    shards: u32,
    times: Vec<f64>,
    identical: bool,
    measured: String,
}

fn measured_now() -> String {
    format!(
        "{}, commit {}, load {}",
        utc_now(),
        git_head().unwrap_or_else(|| "unknown".into()),
        load_average()
    )
}

/// Figures an earlier run left at `path` (with `--reuse`), or what `measure` gives, saved
/// there for a later run.
fn cached<T: serde::Serialize + serde::de::DeserializeOwned>(
    path: &Path,
    reuse: bool,
    measure: impl FnOnce() -> Result<T>,
) -> Result<T> {
    if reuse {
        if let Ok(bytes) = std::fs::read(path) {
            let t = serde_json::from_slice(&bytes)
                .with_context(|| format!("reading earlier figures {}", path.display()))?;
            eprintln!("bench scale: reusing {}", path.display());
            return Ok(t);
        }
    }
    let t = measure()?;
    crate::util::write_atomically(path, serde_json::to_string_pretty(&t)?.as_bytes())?;
    Ok(t)
}

/// The `bake` binary beside this one (`cargo build --release` builds both).
fn bake_binary() -> Result<PathBuf> {
    let exe = std::env::current_exe()?;
    let bake = exe.with_file_name(format!("bake{}", std::env::consts::EXE_SUFFIX));
    if !bake.exists() {
        bail!(
            "{} not found: build it first (cargo build --release --bin bake)",
            bake.display()
        );
    }
    Ok(bake)
}

/// A yard whose ground grid brings it to about `vertices`.
fn yard(vertices: u64) -> Yard {
    let others = Yard {
        ground_quads: 0,
        ..Yard::small()
    };
    let rest = others.gltf_vertices() as u64 - 1;
    let ground = vertices.saturating_sub(rest).max(4);
    Yard {
        ground_quads: ((ground as f64).sqrt() as u32).saturating_sub(1).max(1),
        ..others
    }
}

fn run_bake(bake: &Path, config: &Path, out: &Path, spp: u32, extra: &[&str]) -> Result<Baked> {
    let o = Command::new(bake)
        .arg(config)
        .args(["--spp", &spp.to_string(), "--json", "--quiet", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .with_context(|| format!("running {}", bake.display()))?;
    if !o.status.success() {
        bail!(
            "bake {} failed: {}",
            config.display(),
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let j: Value = serde_json::from_slice(&o.stdout).context("bake --json")?;
    let u = |k: &str| j[k].as_u64().unwrap_or(0);
    Ok(Baked {
        vertices: u("vertices"),
        loaded: u("loaded_vertices"),
        seconds: j["seconds"].as_f64().unwrap_or(0.0),
        trace_seconds: j["timings"]["trace_seconds"].as_f64().unwrap_or(0.0),
        peak_bytes: u("peak_resident_bytes"),
        estimated_bytes: u("estimated_bytes"),
        file_bytes: u("file_bytes"),
        measured: measured_now(),
    })
}

fn gb(bytes: u64) -> String {
    format!("{:.2} GB", bytes as f64 / 1e9)
}

/// Runs the measurements and writes the section; returns it.
pub fn run(args: &ScaleArgs) -> Result<String> {
    let bake = bake_binary()?;
    let env = std::fs::canonicalize(&args.environment)
        .with_context(|| format!("environment {}", args.environment.display()))?;
    std::fs::create_dir_all(&args.work_dir)?;
    let mut rows: Vec<Baked> = Vec::new();
    for &v in &args.vertices {
        let figures = args.work_dir.join(format!("yard-{v}-n1-{}.json", args.spp));
        let dir = args.work_dir.join(format!("yard-{v}"));
        let b = cached(&figures, args.reuse, || {
            let config = yard(v).write(&dir, &env)?;
            let out = dir.join("yard.prtbake");
            eprintln!("bench scale: baking about {v} vertices");
            let b = run_bake(&bake, &config, &out, args.spp, &[]);
            let _ = std::fs::remove_dir_all(&dir);
            b
        })?;
        eprintln!(
            "  {} vertices in {:.1} s, peak {} (estimate {})",
            b.vertices,
            b.seconds,
            gb(b.peak_bytes),
            gb(b.estimated_bytes)
        );
        rows.push(b);
    }

    let mut balance: Vec<Balance> = Vec::new();
    for &n in &args.shards {
        let figures = args.work_dir.join(format!(
            "shards-{n}-of-{}-n1-{}.json",
            args.shard_vertices, args.spp
        ));
        let dir = args.work_dir.join(format!("shards-{n}"));
        let b = cached(&figures, args.reuse, || {
            let b = shard_balance(&bake, &dir, &env, args, n);
            let _ = std::fs::remove_dir_all(&dir);
            b
        })?;
        balance.push(b);
    }

    let section = section(args, &rows, &balance);
    crate::util::write_section(&args.out, &section, BEGIN, END)?;
    Ok(section)
}

/// Bakes a yard of `args.shard_vertices` whole and as `n` shards one after another, merges
/// the shards and compares the merge with the whole.
fn shard_balance(bake: &Path, dir: &Path, env: &Path, args: &ScaleArgs, n: u32) -> Result<Balance> {
    let config = yard(args.shard_vertices).write(dir, env)?;
    let whole = dir.join("whole.prtbake");
    run_bake(bake, &config, &whole, args.spp, &[])?;
    let out = dir.join("sharded.prtbake");
    let mut times = Vec::new();
    let mut files = Vec::new();
    for i in 0..n {
        eprintln!("bench scale: shard {i}/{n}");
        let b = run_bake(
            bake,
            &config,
            &out,
            args.spp,
            &["--shard", &format!("{i}/{n}")],
        )?;
        times.push(b.seconds);
        files.push(PathBuf::from(format!("{}.shard-{i}-of-{n}", out.display())));
    }
    let o = Command::new(bake)
        .arg("merge")
        .args(&files)
        .arg("--out")
        .arg(&out)
        .arg("--quiet")
        .output()?;
    if !o.status.success() {
        bail!("merge failed: {}", String::from_utf8_lossy(&o.stderr));
    }
    let identical = std::fs::read(&out)? == std::fs::read(&whole)?;
    Ok(Balance {
        shards: n,
        times,
        identical,
        measured: measured_now(),
    })
}

fn section(args: &ScaleArgs, rows: &[Baked], balance: &[Balance]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{BEGIN}");
    let _ = writeln!(s, "## Scale\n");
    let _ = writeln!(
        s,
        "Generated by `cargo run --release -p prt-bench -- scale` on {} ({}, load {}, \
         commit {}; with `--reuse`, rows an earlier run measured are taken from its figures, \
         each row says when). Yards (`prt_bake::testing::Yard`: the small yard's editable GGX sphere, \
         Blinn-Phong torus and box on a ground grid grown to the vertex count) under \
         `{}`, three reflections, compressed at the defaults, N1 = {} (the default is 64: \
         time grows in proportion, memory does not). Each bake is the `bake` binary on its \
         own; peak = its peak resident set (`VmHWM`), estimate = what it printed before \
         tracing.\n",
        utc_now(),
        cpu_model(),
        load_average(),
        git_head().unwrap_or_else(|| "unknown".into()),
        args.environment.display(),
        args.spp
    );
    let _ = writeln!(
        s,
        "| vertices | loaded | bake | trace | per 1K vertices | peak resident | estimate | file | measured |"
    );
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    for b in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} s | {:.1} s | {:.3} s | {} | {} | {:.1} MB | {} |",
            b.vertices,
            b.loaded,
            b.seconds,
            b.trace_seconds,
            b.seconds / (b.vertices.max(1) as f64 / 1000.0),
            gb(b.peak_bytes),
            gb(b.estimated_bytes),
            b.file_bytes as f64 / 1e6,
            b.measured
        );
    }
    if let (Some(first), Some(last)) = (rows.first(), rows.last()) {
        let _ = writeln!(
            s,
            "\nFrom {} to {} vertices ({:.0}x): time {:.1}x, peak resident {:.2}x.\n",
            first.vertices,
            last.vertices,
            last.vertices as f64 / first.vertices.max(1) as f64,
            last.seconds / first.seconds.max(1e-9),
            last.peak_bytes as f64 / first.peak_bytes.max(1) as f64
        );
    }
    if !balance.is_empty() {
        let _ = writeln!(
            s,
            "Shard balance on a yard of about {} vertices (each shard baked on its own; the \
             wall time of a sharded bake on a cluster is the slowest shard's):\n",
            args.shard_vertices
        );
        let _ = writeln!(
            s,
            "| shards | mean | slowest | slowest / mean | merged = unsharded | measured |"
        );
        let _ = writeln!(s, "|---:|---:|---:|---:|:---:|---|");
        for b in balance {
            let t = &b.times;
            let mean = t.iter().sum::<f64>() / t.len().max(1) as f64;
            let max = t.iter().cloned().fold(0.0, f64::max);
            let _ = writeln!(
                s,
                "| {} | {mean:.1} s | {max:.1} s | {:.2} | {} | {} |",
                b.shards,
                max / mean.max(1e-9),
                if b.identical {
                    "byte-identical"
                } else {
                    "DIFFERS"
                },
                b.measured
            );
        }
    }
    let _ = writeln!(s, "\n{END}");
    s
}
