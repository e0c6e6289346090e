//! `relight`: opens a bake file and writes an image for edited materials, without tracing.
//!
//!     relight out/cornell.prtbake --set bunny.kd=0.8,0.2,0.2 --set bunny.shininess=120 --out bunny.png

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Parser;
use prt_formats::MaterialOverride;
use prt_runtime::{Relighter, Variant};

#[derive(Parser, Debug)]
#[command(
    version,
    about = "Relight a PRT bake file for edited materials, in milliseconds"
)]
struct Args {
    /// The bake file written by `bake`.
    bake: PathBuf,
    /// Material edit, e.g. `--set bunny.kd=0.8,0.2,0.2 --set bunny.shininess=50` (params: kd,
    /// ks, shininess, alpha; names and units as in the bake config).
    #[arg(long = "set", value_name = "MATERIAL.PARAM=VALUE")]
    set: Vec<MaterialOverride>,
    /// Output image: .exr (linear) or .png (tone-mapped). Default: next to the bake file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Relight from the low-rank variant (bake with --compress-rank).
    #[arg(long)]
    compressed: bool,
    /// Exposure multiplier for PNG output.
    #[arg(long, default_value_t = 1.0)]
    exposure: f32,
    /// Relight this many times and report the median time per frame.
    #[arg(long, default_value_t = 1)]
    repeat: u32,
    /// List the materials (editable ones and their parameters) and exit.
    #[arg(long)]
    list: bool,
    /// Print one JSON object with the figures (time per frame, bytes read per frame).
    #[arg(long)]
    json: bool,
}

fn main() -> ExitCode {
    prt_cli::exit_code(run(Args::parse()))
}

fn run(args: Args) -> Result<()> {
    let mut r = Relighter::open(&args.bake)?;
    if args.list {
        for m in &r.meta().materials {
            println!(
                "{:<20} {:<12} {} kd={:?} ks={:?} param={}",
                m.name,
                m.family,
                if m.editable { "editable" } else { "fixed   " },
                m.kd,
                m.ks,
                m.param
            );
        }
        return Ok(());
    }
    for o in &args.set {
        r.apply(o)?;
    }
    let (_, clamped) = r.coefficients();
    if clamped {
        eprintln!("warning: a shininess/alpha lies outside its basis' sampled range and was clamped to it");
    }
    if args.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    let variant = if args.compressed {
        Variant::Compressed
    } else {
        Variant::Full
    };
    let mut times = Vec::new();
    let mut frame = r.render(variant)?;
    times.push(frame.seconds);
    for _ in 1..args.repeat {
        frame = r.render(variant)?;
        times.push(frame.seconds);
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let out = args
        .out
        .unwrap_or_else(|| args.bake.with_extension("").with_extension("relit.png"));
    prt_formats::write_image(
        &out,
        frame.width as usize,
        frame.height as usize,
        &frame.pixels,
        args.exposure,
    )
    .with_context(|| format!("writing {}", out.display()))?;
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "bake": args.bake,
                "out": out,
                "width": frame.width,
                "height": frame.height,
                "variant": if args.compressed { "compressed" } else { "full" },
                "frames": times.len(),
                "seconds_per_frame_median": median,
                "seconds_per_frame_min": times[0],
                "bytes_read_per_frame": frame.bytes_read,
                "read_bandwidth_gb_per_s": frame.bytes_read as f64 / median.max(1e-12) / 1e9,
                "threads": rayon::current_num_threads(),
                "clamped": clamped,
            })
        );
    } else {
        eprintln!(
            "relit {}x{} in {:.2} ms ({} read per frame); wrote {}",
            frame.width,
            frame.height,
            median * 1e3,
            frame.bytes_read,
            out.display()
        );
    }
    Ok(())
}
