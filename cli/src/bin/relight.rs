//! `relight`: opens a bake file and writes an image for edited materials, without tracing.
//!
//!     relight out/cornell.prtbake --set bunny.kd=0.8,0.2,0.2 --set bunny.shininess=120 --out bunny.png
//!
//! A per-vertex bake (docs/vertex.md) also takes a new environment, its rotation, a camera and
//! an image size:
//!
//!     relight out/gallery.prtbake --env sky.exr --env-rotate 90 \
//!         --camera "eye=0,1.2,3.5 target=0,0.4,0 fov=40" --width 800 --height 600 --out g.exr
//!
//! The kind of bake is read from the file; a per-pixel bake has its light and view frozen, so
//! those flags are refused for it.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::Parser;
use prt_bake::units::human_bytes;
use prt_formats::family::reflectance_warning;
use prt_formats::view::CameraSpec;
use prt_formats::{MaterialOverride, ToneCurve};
use prt_runtime::{
    Image, MaterialInfo, OverrideValue, PixelRelighter, Relighter, Variant, VertexRelighter,
};

#[derive(Parser, Debug)]
#[command(
    name = "relight",
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
    /// Output image: .exr (linear) or .png (tone-mapped), written atomically (nothing is
    /// written on error). Default: next to the bake file.
    #[arg(long, visible_alias = "output")]
    out: Option<PathBuf>,
    /// Relight from the low-rank variant (bake with --compress-rank).
    #[arg(long)]
    compressed: bool,
    /// Exposure multiplier for PNG output.
    #[arg(long, default_value_t = 1.0)]
    exposure: f32,
    /// Tone curve for PNG output, after the exposure: clamp (clip at 1), reinhard or aces.
    #[arg(long, default_value_t = ToneCurve::Clamp)]
    tone: ToneCurve,
    /// Relight this many times and report the median time per frame.
    #[arg(long, default_value_t = 1)]
    repeat: u32,
    /// List the materials (editable ones and their parameters) and exit.
    #[arg(long)]
    list: bool,
    /// Print one JSON object with the figures (time per frame, bytes read per frame; per-stage
    /// times for a per-vertex bake).
    #[arg(long)]
    json: bool,
    /// Per-vertex bakes: light with this lat-long environment map (.exr or .hdr) instead of
    /// the baked one.
    #[arg(long, value_name = "FILE")]
    env: Option<PathBuf>,
    /// Per-vertex bakes: multiply the environment (the --env map, or the baked one) by this
    /// factor [default: 1].
    #[arg(long, value_name = "X")]
    env_intensity: Option<f32>,
    /// Per-vertex bakes: turn the environment this many degrees about +Y (right-hand rule)
    /// [default: 0 with --env, else the baked rotation].
    #[arg(long, value_name = "DEGREES", allow_negative_numbers = true)]
    env_rotate: Option<f32>,
    /// Per-vertex bakes: the view, e.g. "eye=0,1.2,3.5 target=0,0.4,0 fov=40" (vertical field
    /// of view in degrees) [default: the bake's camera].
    #[arg(long, value_name = "\"eye=X,Y,Z target=X,Y,Z fov=DEG\"")]
    camera: Option<CameraSpec>,
    /// Per-vertex bakes: image width in pixels [default: 512].
    #[arg(long)]
    width: Option<u32>,
    /// Per-vertex bakes: image height in pixels [default: 512].
    #[arg(long)]
    height: Option<u32>,
    /// Per-vertex bakes, with --repeat: a moving camera. Frame k is seen from the camera
    /// turned k times this many degrees about the world's +Y axis (right-hand rule), so every
    /// repeat is a view-only change; the image written is the last frame's.
    #[arg(long, value_name = "DEGREES", allow_negative_numbers = true)]
    orbit: Option<f32>,
    /// Per-vertex bakes, with --repeat: a turning light. Frame k has the environment turned k
    /// times this many degrees further about +Y, so every repeat runs the light, material and
    /// view stages (with --orbit as well: the camera moves too).
    #[arg(long, value_name = "DEGREES", allow_negative_numbers = true)]
    turn: Option<f32>,
    /// Per-vertex bakes: leave the environment's compact lights (a sun, a studio lamp) to the
    /// shading basis instead of reflecting them per pixel through each glossy material's true
    /// lobe: cheaper glossy pixels, broader and less accurate highlights (docs/vertex.md,
    /// "Compact lights").
    #[arg(long)]
    no_compact_lights: bool,
    /// Per-vertex bakes: shade every pixel at its centre alone, silhouettes and creases
    /// included, instead of sampling those pixels 16 times (docs/vertex.md, "Silhouettes are
    /// antialiased"): slightly faster, jagged outlines.
    #[arg(long)]
    no_antialias: bool,
    /// Render on a GPU (wgpu: Vulkan, Metal or DX12; docs/gpu.md) instead of the CPU.
    /// Needs a build with `--features gpu`.
    #[arg(long)]
    gpu: bool,
    /// With --gpu: use the software fallback adapter (lavapipe) even when a GPU is present.
    #[arg(long, requires = "gpu")]
    gpu_fallback: bool,
}

/// Words users type for this tool's flags (clap suggests only flags spelt alike: it offers
/// `--camera` for `--material`).
const SYNONYMS: &[(&str, &str)] = &[
    ("material", "set"),
    ("materials", "set"),
    ("edit", "set"),
    ("param", "set"),
    ("environment", "env"),
    ("envmap", "env"),
    ("rotate", "env-rotate"),
];

fn main() -> ExitCode {
    prt_cli::exit_code(run(prt_cli::parse_args(SYNONYMS)))
}

fn run(args: Args) -> Result<()> {
    if args.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    let mut r = prt_runtime::open(&args.bake)?;
    match &r {
        Relighter::Pixel(_) => refuse_vertex_flags(&args)?,
        Relighter::Vertex(_) if args.compressed => bail!(
            "{}: --compressed reads the low-rank variant of a per-pixel bake; this is a \
             per-vertex bake",
            args.bake.display()
        ),
        Relighter::Vertex(_) => {}
    }
    if args.list {
        return list_materials(&r);
    }
    for o in &args.set {
        r.set_params(&o.material, &[o.value])?;
    }
    let clamped = warn_about_edits(&args.set, &r.materials());
    if args.gpu {
        return run_gpu(args, r, clamped);
    }
    match r {
        Relighter::Pixel(p) => run_pixel(args, p, clamped),
        Relighter::Vertex(v) => run_vertex(args, v, clamped),
    }
}

/// `--gpu` in a build without the `gpu` feature.
#[cfg(not(feature = "gpu"))]
fn run_gpu(_: Args, _: Relighter, _: bool) -> Result<()> {
    bail!(
        "--gpu needs a relight built with the GPU backend: cargo build --release -p prt-cli \
         --features gpu --bin relight (docs/gpu.md)"
    )
}

/// `--gpu`: the same settings as on the CPU, rendered on the device `--repeat` times (with
/// `--orbit` and `--turn` as on the CPU); the median frame time.
#[cfg(feature = "gpu")]
fn run_gpu(args: Args, mut r: Relighter, clamped: bool) -> Result<()> {
    let ctx = prt_gpu::GpuContext::new(&prt_gpu::GpuOptions {
        fallback: args.gpu_fallback,
        ..Default::default()
    })?;
    let mut camera = None;
    match &mut r {
        Relighter::Pixel(p) if args.compressed => p.set_variant(Variant::Compressed)?,
        Relighter::Pixel(_) => {}
        Relighter::Vertex(v) => camera = Some(set_up_vertex(&args, v)?),
    }
    let rotation0 = match &r {
        Relighter::Vertex(v) => v.environment_rotation(),
        Relighter::Pixel(_) => 0.0,
    };
    let mut g = prt_gpu::GpuRelighter::new(&ctx, r)?;
    if let Some(why) = g.vertex_stages_on_cpu() {
        eprintln!("note: the light and material stages run on the CPU: {why}");
    }
    let (width, height) = g.relighter().size();
    let mut image = Image::new(width, height);
    let mut times = Vec::new();
    for k in 0..args.repeat {
        if let (Relighter::Vertex(v), Some(camera)) = (g.relighter_mut(), camera) {
            if let Some(deg) = args.orbit {
                v.set_camera(camera.orbited(deg * k as f32))?;
            }
            if let Some(deg) = args.turn {
                v.set_environment_rotation(rotation0 + deg * k as f32)?;
            }
        }
        let stats = g.render_into(image.pixels.as_flattened_mut())?;
        times.push(stats.seconds);
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let (out, _) = write_out(&args, &image)?;
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "bake": args.bake,
                "out": out,
                "adapter": ctx.adapter_name(),
                "width": width,
                "height": height,
                "frames": times.len(),
                "seconds_per_frame_median": median,
                "seconds_per_frame_min": times[0],
                "clamped": clamped,
            })
        );
    } else {
        eprintln!(
            "relit {width}x{height} on {} in {:.2} ms per frame; wrote {}",
            ctx.adapter_name(),
            median * 1e3,
            out.display()
        );
    }
    Ok(())
}

/// A per-pixel bake has its light and view frozen: the per-vertex flags are refused for it.
fn refuse_vertex_flags(args: &Args) -> Result<()> {
    let vertex_only: Vec<&str> = [
        ("--env", args.env.is_some()),
        ("--env-intensity", args.env_intensity.is_some()),
        ("--env-rotate", args.env_rotate.is_some()),
        ("--camera", args.camera.is_some()),
        ("--width", args.width.is_some()),
        ("--height", args.height.is_some()),
        ("--orbit", args.orbit.is_some()),
        ("--turn", args.turn.is_some()),
        ("--no-compact-lights", args.no_compact_lights),
        ("--no-antialias", args.no_antialias),
    ]
    .into_iter()
    .filter_map(|(flag, given)| given.then_some(flag))
    .collect();
    if !vertex_only.is_empty() {
        bail!(
            "{} is a per-pixel bake: its light and view are frozen into the file, so {} \
             cannot be used (they need a per-vertex bake, `mode = \"vertex\"`); only --set \
             edits materials",
            args.bake.display(),
            vertex_only.join(", ")
        );
    }
    Ok(())
}

/// A per-pixel bake: the image, relit `--repeat` times.
fn run_pixel(args: Args, mut r: PixelRelighter, clamped: bool) -> Result<()> {
    if args.compressed {
        r.set_variant(Variant::Compressed)?;
    }
    let (width, height) = r.size();
    let mut image = Image::new(width, height);
    let mut times = Vec::new();
    let mut bytes_read = 0;
    for _ in 0..args.repeat {
        let stats = r.render_into(image.pixels.as_flattened_mut())?;
        times.push(stats.seconds);
        bytes_read = stats.bytes_read.unwrap_or(0);
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let (out, existed) = write_out(&args, &image)?;
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "bake": args.bake,
                "out": out,
                "width": width,
                "height": height,
                "variant": if args.compressed { "compressed" } else { "full" },
                "frames": times.len(),
                "seconds_per_frame_median": median,
                "seconds_per_frame_min": times[0],
                "bytes_read_per_frame": bytes_read,
                "read_bandwidth_gb_per_s": bytes_read as f64 / median.max(1e-12) / 1e9,
                "threads": rayon::current_num_threads(),
                "clamped": clamped,
                "replaced": existed,
            })
        );
    } else {
        eprintln!(
            "relit {width}x{height} in {:.2} ms ({} read per frame); wrote {}{}",
            median * 1e3,
            human_bytes(bytes_read),
            out.display(),
            prt_cli::replaced(existed)
        );
    }
    Ok(())
}

/// Writes the image to `--out` (default: next to the bake file); returns where, and whether
/// it replaced a file.
fn write_out(args: &Args, image: &Image) -> Result<(PathBuf, bool)> {
    let out = args.out.clone().unwrap_or_else(|| default_out(&args.bake));
    let existed = out.exists();
    prt_formats::write_image_with(
        &out,
        image.width as usize,
        image.height as usize,
        &image.pixels,
        args.exposure,
        args.tone,
    )
    .with_context(|| format!("writing {}", out.display()))?;
    Ok((out, existed))
}

/// The default output: next to the bake file, `<name>.relit.png`.
fn default_out(bake: &Path) -> PathBuf {
    bake.with_extension("").with_extension("relit.png")
}

/// One line per material: name, family, editable or fixed, and its parameters by name (`ks`
/// and the lobe parameter only for a family that has them), with the range of the lobe
/// parameter's basis when it has one (values outside it are clamped to it).
fn list_materials(r: &Relighter) -> Result<()> {
    for m in r.materials() {
        let params: Vec<String> = m
            .params
            .iter()
            .map(|p| {
                let value = match p.value {
                    OverrideValue::Kd(c) | OverrideValue::Ks(c) => format!("{c:?}"),
                    OverrideValue::Shininess(v) | OverrideValue::Alpha(v) => v.to_string(),
                    // A parameter added later: its debug form until it gets its own.
                    other => format!("{other:?}"),
                };
                match p.sampled {
                    Some(range) => format!("{}={value} (basis range {range})", p.param()),
                    None => format!("{}={value}", p.param()),
                }
            })
            .collect();
        println!(
            "{:<20} {:<12} {} {}{}",
            m.name,
            m.family,
            if m.editable { "editable" } else { "fixed   " },
            params.join(" "),
            if m.varying {
                " (varies over its surface by its metallicRoughnessTexture; these are the mean)"
            } else {
                ""
            }
        );
    }
    Ok(())
}

/// Warns about the values being rendered: a lobe parameter outside the range its basis was
/// built over (named, with the value, the range and what is rendered), and an edited material
/// that reflects more light than it receives. Returns whether any parameter is clamped.
fn warn_about_edits(set: &[MaterialOverride], materials: &[MaterialInfo]) -> bool {
    let mut clamped = false;
    for m in materials {
        for p in m.params.iter().filter(|p| p.clamped()) {
            clamped = true;
            if let (Some(range), OverrideValue::Shininess(v) | OverrideValue::Alpha(v)) =
                (p.sampled, p.value)
            {
                eprintln!(
                    "warning: {}.{} = {v} lies outside {range}, the range the bake's {} basis \
                     was built over; relit as {}",
                    m.name,
                    p.param(),
                    p.param(),
                    v.clamp(range.min, range.max)
                );
            }
        }
    }
    for m in materials
        .iter()
        .filter(|m| set.iter().any(|o| o.material == m.name))
    {
        let colour = |want: fn(&OverrideValue) -> Option<[f32; 3]>| {
            m.params
                .iter()
                .find_map(|p| want(&p.value))
                .unwrap_or([0.0; 3])
        };
        let kd = colour(|v| match v {
            OverrideValue::Kd(c) => Some(*c),
            _ => None,
        });
        let ks = colour(|v| match v {
            OverrideValue::Ks(c) => Some(*c),
            _ => None,
        });
        if let Some(w) = reflectance_warning(&m.name, m.family, kd, ks) {
            eprintln!("warning: {w}");
        }
    }
    clamped
}

/// Applies the per-vertex flags (environment, its rotation and intensity, size, camera) and
/// checks --orbit and --turn; returns the camera.
fn set_up_vertex(args: &Args, r: &mut VertexRelighter) -> Result<prt_formats::view::CameraFrame> {
    if let Some(path) = &args.env {
        let report = r.load_environment(path)?;
        if report.clamped_texels > 0 {
            eprintln!(
                "warning: {}: {} texel(s) with negative channels were clamped to 0",
                path.display(),
                report.clamped_texels
            );
        }
        // The baked rotation belongs to the baked map.
        r.set_environment_rotation(args.env_rotate.unwrap_or(0.0))?;
    } else if let Some(rotation) = args.env_rotate {
        r.set_environment_rotation(rotation)?;
    }
    if let Some(intensity) = args.env_intensity {
        r.set_environment_intensity(intensity)
            .context("--env-intensity")?;
    }
    r.set_compact_lights(!args.no_compact_lights);
    r.set_antialias(!args.no_antialias);
    let (default_width, default_height) = r.size();
    let (width, height) = (
        args.width.unwrap_or(default_width),
        args.height.unwrap_or(default_height),
    );
    r.set_size(width, height)?;
    let camera = match &args.camera {
        Some(spec) => spec.frame()?,
        None => r.default_camera(),
    };
    r.set_camera(camera)?;
    if args.orbit.is_some_and(|d| !d.is_finite()) {
        bail!("--orbit must be a finite number of degrees");
    }
    if args.turn.is_some_and(|d| !d.is_finite()) {
        bail!("--turn must be a finite number of degrees");
    }
    Ok(camera)
}

/// A per-vertex bake: environment, camera and image size, then the image (the materials are
/// set by the caller).
fn run_vertex(args: Args, mut r: VertexRelighter, clamped: bool) -> Result<()> {
    let camera = set_up_vertex(&args, &mut r)?;
    let (width, height) = r.size();
    let rotation0 = r.environment_rotation();
    let mut image = Image::new(width, height);
    let first = r.render_into(image.pixels.as_flattened_mut())?;
    let first_view = first.view_s.unwrap_or(0.0);
    // Repeats change nothing but the camera (with --orbit; then they measure the view stage
    // alone) and the light's turn (with --turn: all three stages).
    // A frame's wall-clock time also counts what it does besides the stages (the check that a
    // new eye is not inside an object, made when the camera is set).
    let mut views = vec![first_view];
    let mut rasters = vec![first.raster_s.unwrap_or(0.0)];
    let mut lights = Vec::new();
    let mut frames = Vec::new();
    for k in 1..args.repeat {
        let cam = match args.orbit {
            Some(deg) => camera.orbited(deg * k as f32),
            None => camera,
        };
        if let Some(deg) = args.turn {
            r.set_environment_rotation(rotation0 + deg * k as f32)?;
        }
        let start = std::time::Instant::now();
        r.set_camera(cam)
            .with_context(|| format!("frame {k} of the orbit"))?;
        let stats = r.render_into(image.pixels.as_flattened_mut())?;
        frames.push(start.elapsed().as_secs_f64());
        views.push(stats.view_s.unwrap_or(0.0));
        rasters.push(stats.raster_s.unwrap_or(0.0));
        if let Some(l) = stats.light_s {
            lights.push(l + stats.material_s.unwrap_or(0.0));
        }
    }
    lights.sort_by(f64::total_cmp);
    views.sort_by(f64::total_cmp);
    frames.sort_by(f64::total_cmp);
    rasters.sort_by(f64::total_cmp);
    let view_median = views[views.len() / 2];
    let frame_median = frames.get(frames.len() / 2).copied();
    let (out, existed) = write_out(&args, &image)?;
    let (light_s, material_s) = (
        first.light_s.unwrap_or(0.0),
        first.material_s.unwrap_or(0.0),
    );
    if args.json {
        let rotation = r.environment_rotation();
        println!(
            "{}",
            serde_json::json!({
                "bake": args.bake,
                "kind": "vertex",
                "out": out,
                "width": width,
                "height": height,
                "env": args.env,
                "env_rotate": rotation,
                "camera": args.camera.map(|c| c.to_string()),
                "stages": {
                    "light_s": light_s,
                    "material_s": material_s,
                    "view_s": first_view,
                },
                "seconds_first_frame": light_s + material_s + first_view,
                "frames": views.len(),
                "view_s_median": view_median,
                "view_s_min": views[0],
                "raster_s_median": rasters[rasters.len() / 2],
                "antialiased_pixels": first.antialiased_pixels,
                "orbit_deg": args.orbit,
                "turn_deg": args.turn,
                "light_and_material_s_median": lights.get(lights.len() / 2),
                "frame_s_median": frame_median,
                "ns_per_pixel_view": view_median * 1e9 / (f64::from(width) * f64::from(height)),
                "threads": rayon::current_num_threads(),
                "clamped": clamped,
                "replaced": existed,
            })
        );
    } else {
        eprintln!(
            "relit {width}x{height}: light {:.1} ms, materials {:.1} ms, view {:.1} ms; wrote \
             {}{}",
            light_s * 1e3,
            material_s * 1e3,
            view_median * 1e3,
            out.display(),
            prt_cli::replaced(existed)
        );
    }
    Ok(())
}
