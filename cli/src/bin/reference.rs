//! `reference`: renders a bake config's camera view with the true BRDFs (path tracing, exact
//! reflection count), writing a linear EXR and a tone-mapped PNG.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Parser;
use prt_bake::ground_truth::{run_reference, ReferenceError, ReferenceSettings};
use prt_bake::progress::Progress;
use prt_bake::run::load;
use prt_cli::Stderr;
use prt_formats::envmap::load_latlong;
use prt_formats::view::CameraSpec;
use prt_formats::MaterialOverride;

#[derive(Parser, Debug)]
#[command(
    name = "reference",
    version,
    about = "Reference path tracer: the ground truth a bake is checked against"
)]
struct Args {
    /// The bake config (TOML) naming the scene, a scene folder holding `bake.toml`, or a glTF
    /// (with `bake`'s defaults for it).
    config: PathBuf,
    /// Samples per pixel (default: the config's spp).
    #[arg(long)]
    spp: Option<u32>,
    #[arg(long)]
    width: Option<u32>,
    #[arg(long)]
    height: Option<u32>,
    /// Output image (.exr or .png); the other format is written beside it. Default:
    /// out/<config name>-reference.exr next to the config.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Material override, e.g. `--set bunny.kd=0.8,0.2,0.2 --set bunny.shininess=50`.
    #[arg(long = "set", value_name = "MATERIAL.PARAM=VALUE")]
    set: Vec<MaterialOverride>,
    /// Random seed (default: the config's).
    #[arg(long)]
    seed: Option<u64>,
    /// View instead of the config's camera: `"eye=x,y,z target=x,y,z fov=DEGREES"` (vertical
    /// field of view; +Y up).
    #[arg(long, value_name = "SPEC")]
    camera: Option<CameraSpec>,
    /// Light the scene with this lat-long map (.exr or .hdr) instead of the config's
    /// environment.
    #[arg(long, value_name = "FILE")]
    env: Option<PathBuf>,
    /// Multiplier of `--env`'s texels.
    #[arg(
        long,
        default_value_t = 1.0,
        requires = "env",
        allow_hyphen_values = true
    )]
    env_intensity: f32,
    /// Turn the environment map about +Y by this many degrees (right-hand rule: +90 takes what
    /// was seen towards -Z to -X), on top of the config's `rotation`.
    #[arg(long, value_name = "DEGREES", allow_hyphen_values = true)]
    env_rotate: Option<f32>,
    /// Exposure multiplier for the PNG.
    #[arg(long, default_value_t = 1.0)]
    exposure: f32,
    /// Print one JSON object with the figures of the run.
    #[arg(long)]
    json: bool,
}

/// Words users type for this tool's flags (clap suggests only flags spelt alike).
const SYNONYMS: &[(&str, &str)] = &[
    ("sample", "spp"),
    ("samples", "spp"),
    ("material", "set"),
    ("materials", "set"),
    ("output", "out"),
    ("environment", "env"),
];

fn main() -> ExitCode {
    prt_cli::exit_code(run(prt_cli::parse_args(SYNONYMS)))
}

fn run(args: Args) -> Result<()> {
    let progress = Stderr::new(args.json);
    let (config, scene) = load(&args.config, &progress)?;
    let environment = match &args.env {
        Some(path) => {
            let (map, report) = load_latlong(path, args.env_intensity)
                .with_context(|| format!("--env {}", path.display()))?;
            if report.clamped_texels > 0 {
                progress.warn(&format!(
                    "--env {}: {} texel(s) with negative channels clamped to 0",
                    path.display(),
                    report.clamped_texels
                ));
            }
            Some(map)
        }
        None => None,
    };
    // --env-rotate turns the map given, or the config's on top of its own `rotation`.
    let environment_rotation = match args.env_rotate {
        Some(deg) if !(deg.is_finite() && (-360.0..=360.0).contains(&deg)) => {
            bail!("--env-rotate {deg}: give degrees in [-360, 360]")
        }
        Some(deg) if environment.is_some() => Some(deg),
        Some(deg) => Some(scene.environment_rotation + deg),
        None => None,
    };
    let settings = ReferenceSettings {
        spp: args.spp,
        width: args.width,
        height: args.height,
        seed: args.seed,
        overrides: args.set.clone(),
        environment,
        environment_rotation,
        camera: args.camera.as_ref().map(CameraSpec::frame).transpose()?,
    };
    let names: Vec<String> = scene.materials.iter().map(|m| m.name.clone()).collect();
    let r = run_reference(&config, scene, &settings, &progress).map_err(|e| match e {
        ReferenceError::RotationWithoutMap => anyhow::Error::new(e).context("--env-rotate"),
        e => e.into(),
    })?;
    let (width, height, spp) = (r.width, r.height, r.spp);
    let out = args.out.unwrap_or_else(|| {
        let stem = config
            .config_path
            .file_stem()
            .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
        let folder_name = config
            .folder()
            .file_name()
            .map_or(stem.clone(), |s| s.to_string_lossy().into_owned());
        config
            .folder()
            .join("out")
            .join(format!("{folder_name}-reference.exr"))
    });
    let rgb: Vec<[f32; 3]> = r.pixels.iter().map(|p| p.to_array()).collect();
    let (w, h) = (width as usize, height as usize);
    let exr = out.with_extension("exr");
    let png = out.with_extension("png");
    let existed = exr.exists() || png.exists();
    prt_formats::write_exr(&exr, w, h, &rgb)?;
    prt_formats::write_png(&png, w, h, &rgb, args.exposure)?;
    let mean = r.mean();
    if args.json {
        let materials: serde_json::Map<String, serde_json::Value> = names
            .into_iter()
            .zip(&r.material_means)
            .filter_map(|(name, (v, n))| {
                v.map(|v| {
                    (
                        name,
                        serde_json::json!({"mean_radiance": v.to_array(), "samples": n}),
                    )
                })
            })
            .collect();
        let json = serde_json::json!({
            "config": config.config_path,
            "exr": exr,
            "png": png,
            "width": width,
            "height": height,
            "spp": spp,
            "emission_oversampling": config.emission_oversampling,
            "reflections": config.reflections,
            "samples": width as u64 * height as u64 * spp as u64,
            "seconds": r.seconds,
            "rays": r.rays,
            "rays_per_second": r.rays as f64 / r.seconds.max(1e-9),
            "threads": rayon::current_num_threads(),
            "mean_radiance": mean.to_array(),
            "material_mean_radiance": materials,
            "background_mean_radiance": r.background_mean.0.map(|v| v.to_array()),
            "replaced": existed,
        });
        println!("{json}");
    } else {
        eprintln!(
            "rendered {width}x{height} at {spp} spp in {:.2} s ({:.2} Mrays/s); wrote {} and {}{}",
            r.seconds,
            r.rays as f64 / r.seconds.max(1e-9) / 1e6,
            exr.display(),
            png.display(),
            prt_cli::replaced(existed)
        );
    }
    Ok(())
}
