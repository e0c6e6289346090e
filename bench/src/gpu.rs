//! `bench gpu` (feature `gpu`; docs/gpu.md, "Measured"): the GPU backend's frames against its
//! goals, on the default adapter, on the software fallback (lavapipe) when there is one, and
//! on the CPU runtime, side by side.
//!
//! Per vertex (a bake at `--size`, every frame a new camera): view only; view + BRDF (a
//! material edit per frame); view + BRDF + light (the environment turned per frame). Per
//! pixel: the frame on the device (no read-back) against the device's memory-bandwidth bound
//! for the bytes it moves plus a fixed overhead measured with an empty submission; and the
//! whole frame with its read-back. Medians over `--frames` frames; figures printed, never
//! asserted.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use prt_gpu::{GpuContext, GpuOptions, GpuRelighter};
use prt_runtime::{OverrideValue, Relighter, Variant};

/// `bench gpu` arguments.
#[derive(clap::Args, Debug)]
pub struct GpuArgs {
    /// A per-vertex bake (the figures: `scenes/gallery`, 46K vertices).
    #[arg(long)]
    pub vertex: Option<PathBuf>,
    /// Per-pixel bakes (e.g. 512x512 f32 and f16, with a low-rank variant).
    #[arg(long)]
    pub pixel: Vec<PathBuf>,
    /// Frames per measurement (the median is reported).
    #[arg(long, default_value_t = 60)]
    pub frames: usize,
    /// Per-vertex image side.
    #[arg(long, default_value_t = 512)]
    pub size: u32,
    /// Frames on the CPU runtime and on the fallback adapter (slower: fewer).
    #[arg(long, default_value_t = 8)]
    pub slow_frames: usize,
    /// Leave out the CPU runtime.
    #[arg(long)]
    pub no_cpu: bool,
    /// Leave out the fallback adapter.
    #[arg(long)]
    pub no_fallback: bool,
    /// Bakes of either kind to check the GPU's frames against the CPU runtime's (relative L2
    /// per setting: as baked, every editable material edited, and per vertex the map turned
    /// and dimmed and the camera orbited) instead of timing.
    #[arg(long, num_args = 1..)]
    pub agreement: Vec<PathBuf>,
}

/// Where frames are rendered.
enum Renderer {
    Gpu(Box<GpuRelighter>, Vec<f32>),
    Cpu(Box<Relighter>, Vec<f32>),
}

impl Renderer {
    fn relighter(&mut self) -> &mut Relighter {
        match self {
            Renderer::Gpu(g, _) => g.relighter_mut(),
            Renderer::Cpu(r, _) => r,
        }
    }

    /// One frame, read back to the host; the seconds the CPU spent on the light stage, when
    /// it ran (with the device's stages: the part that does not grow with the vertex count).
    fn frame(&mut self) -> Result<Option<f64>> {
        Ok(match self {
            Renderer::Gpu(g, out) => {
                let (w, h) = g.relighter().size();
                out.resize(3 * w as usize * h as usize, 0.0);
                g.render_into(out)?.light_s
            }
            Renderer::Cpu(r, out) => {
                let (w, h) = r.size();
                out.resize(3 * w as usize * h as usize, 0.0);
                r.render_into(out)?.light_s
            }
        })
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The editable material whose parameter the "view + BRDF" frames change, and two values.
fn material_edit(r: &Relighter) -> Option<(String, [OverrideValue; 2])> {
    let m = r.materials().into_iter().find(|m| m.editable)?;
    let p = r.params(&m.name).ok()?;
    let a = OverrideValue::Kd(p.kd.map(|c| (c * 0.8).min(1.0)));
    let b = OverrideValue::Kd(p.kd);
    Some((m.name, [a, b]))
}

/// Per-vertex frame times (seconds, medians): view only, view + BRDF, view + BRDF + light,
/// and of the last the CPU's light stage.
fn vertex_times(r: &mut Renderer, frames: usize, side: u32) -> Result<[f64; 4]> {
    let (camera, rotation0) = match r.relighter() {
        Relighter::Vertex(v) => {
            v.set_size(side, side)?;
            (v.default_camera(), v.environment_rotation())
        }
        Relighter::Pixel(_) => anyhow::bail!("--vertex: not a per-vertex bake"),
    };
    let edit = material_edit(r.relighter());
    r.frame()?;
    let mut out = [0.0; 4];
    let mut light = Vec::with_capacity(frames);
    for (mode, slot) in out.iter_mut().take(3).enumerate() {
        let mut times = Vec::with_capacity(frames);
        for k in 0..frames {
            let rv = r.relighter();
            if let Relighter::Vertex(v) = rv {
                v.set_camera(camera.orbited(0.25 * (k % 40) as f32))?;
                if mode == 2 {
                    v.set_environment_rotation(rotation0 + 1.0 + (k % 90) as f32)?;
                }
            }
            if mode >= 1 {
                if let Some((name, values)) = &edit {
                    rv.set_params(name, &values[k % 2..k % 2 + 1])?;
                }
            }
            let start = Instant::now();
            let light_s = r.frame()?;
            times.push(start.elapsed().as_secs_f64());
            if mode == 2 {
                light.push(light_s.unwrap_or(0.0));
            }
        }
        *slot = median(times);
    }
    out[3] = median(light);
    Ok(out)
}

/// The device's copy bandwidth (bytes read plus written per second) over a buffer of
/// `bytes`, and the time of an empty submission waited for (the fixed overhead of a frame).
fn device_figures(ctx: &GpuContext, bytes: u64) -> Result<(f64, f64)> {
    let device = ctx.device();
    let make = |usage| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench copy"),
            size: bytes,
            usage,
            mapped_at_creation: false,
        })
    };
    let src = make(wgpu::BufferUsages::COPY_SRC);
    let dst = make(wgpu::BufferUsages::COPY_DST);
    let wait = || device.poll(wgpu::PollType::wait_indefinitely()).map(|_| ());
    let mut copies = Vec::new();
    for _ in 0..6 {
        let mut e = device.create_command_encoder(&Default::default());
        e.copy_buffer_to_buffer(&src, 0, &dst, 0, bytes);
        let start = Instant::now();
        ctx.queue().submit([e.finish()]);
        wait()?;
        copies.push(start.elapsed().as_secs_f64());
    }
    let mut empty = Vec::new();
    for _ in 0..20 {
        let e = device.create_command_encoder(&Default::default());
        let start = Instant::now();
        ctx.queue().submit([e.finish()]);
        wait()?;
        empty.push(start.elapsed().as_secs_f64());
    }
    Ok((2.0 * bytes as f64 / median(copies), median(empty)))
}

/// Runs the benchmark (see the module documentation).
pub fn run(args: &GpuArgs) -> Result<()> {
    let gpu = GpuContext::new(&GpuOptions::default()).context("the default adapter")?;
    println!("adapter: {}", gpu.adapter_name());
    if !args.agreement.is_empty() {
        return agreement(&gpu, &args.agreement, args.size);
    }
    let fallback = if args.no_fallback {
        None
    } else {
        match GpuContext::new(&GpuOptions {
            fallback: true,
            ..Default::default()
        }) {
            Ok(c) if c.adapter_name() != gpu.adapter_name() => Some(c),
            Ok(_) => None,
            Err(e) => {
                println!("fallback adapter: none ({e})");
                None
            }
        }
    };
    if let Some(f) = &fallback {
        println!("fallback adapter: {}", f.adapter_name());
    }
    let mut contexts = vec![("gpu", &gpu, args.frames)];
    if let Some(f) = &fallback {
        contexts.push(("fallback", f, args.slow_frames));
    }
    if let Some(path) = &args.vertex {
        println!(
            "\nper-vertex {} at {s}x{s} (median frame, read back to the host; fps in brackets):",
            path.display(),
            s = args.size
        );
        println!(
            "{:<64} {:>22} {:>22} {:>22} {:>16}",
            "renderer", "view", "view + BRDF", "view + BRDF + light", "of which CPU"
        );
        let mut rows = Vec::new();
        for (label, ctx, frames) in &contexts {
            let g = GpuRelighter::new(ctx, prt_runtime::open(path)?)?;
            let stages = match g.vertex_stages_on_cpu() {
                None => "stages on the device",
                Some(why) => {
                    println!("{label}: the stages run on the CPU: {why}");
                    "stages on the CPU (over a limit)"
                }
            };
            rows.push((
                format!("{label}, {stages}: {}", ctx.adapter_name()),
                Renderer::Gpu(Box::new(g), Vec::new()),
                *frames,
            ));
        }
        // The default adapter with the stages' per-vertex work on the CPU, for comparison.
        let cpu_stages = GpuContext::new(&GpuOptions {
            vertex_stages_on_cpu: true,
            ..Default::default()
        })?;
        rows.push((
            format!("gpu, stages on the CPU: {}", cpu_stages.adapter_name()),
            Renderer::Gpu(
                Box::new(GpuRelighter::new(&cpu_stages, prt_runtime::open(path)?)?),
                Vec::new(),
            ),
            args.frames,
        ));
        if !args.no_cpu {
            let r = prt_runtime::open(path)?;
            rows.push((
                format!("cpu: {} threads", rayon::current_num_threads()),
                Renderer::Cpu(Box::new(r), Vec::new()),
                args.slow_frames,
            ));
        }
        for (label, mut r, frames) in rows {
            let t = vertex_times(&mut r, frames.max(1), args.size)?;
            let cell = |s: f64| format!("{:.3} ms ({:.0} fps)", s * 1e3, 1.0 / s);
            let label: String = label.chars().take(64).collect();
            println!(
                "{label:<64} {:>22} {:>22} {:>22} {:>16}",
                cell(t[0]),
                cell(t[1]),
                cell(t[2]),
                format!("{:.3} ms", t[3] * 1e3)
            );
        }
        println!(
            "(\"of which CPU\": the light stage's time on the CPU in a view + BRDF + light frame)"
        );
        println!("goals (the issue): view >= 2000 fps, view + BRDF >= 1000 fps, view + BRDF + light >= 300 fps");
    }
    for path in &args.pixel {
        pixel(path, &contexts, args)?;
    }
    Ok(())
}

fn pixel(path: &PathBuf, contexts: &[(&str, &GpuContext, usize)], args: &GpuArgs) -> Result<()> {
    let probe = prt_runtime::open(path)?;
    let variants: Vec<Variant> = match &probe {
        Relighter::Pixel(p) if p.has_compressed() => vec![Variant::Full, Variant::Compressed],
        Relighter::Pixel(_) => vec![Variant::Full],
        Relighter::Vertex(_) => anyhow::bail!("--pixel {}: not a per-pixel bake", path.display()),
    };
    let (w, h) = probe.size();
    println!("\nper-pixel {} ({w}x{h}):", path.display());
    for (label, ctx, frames) in contexts {
        // The bandwidth of 64 MiB buffer-to-buffer copies (past any cache of a GPU or CPU).
        let (bandwidth, overhead) = device_figures(ctx, 64 << 20)?;
        println!(
            "  {label}: {}: copy bandwidth {:.1} GB/s (read + write), empty submission {:.3} ms",
            ctx.adapter_name(),
            bandwidth / 1e9,
            overhead * 1e3
        );
        for &variant in &variants {
            let mut r = prt_runtime::open(path)?;
            if let Relighter::Pixel(p) = &mut r {
                p.set_variant(variant)?;
            }
            let mut g = GpuRelighter::new(ctx, r)?;
            let mut out = vec![0.0f32; 3 * w as usize * h as usize];
            g.render_into(&mut out)?;
            let (mut device, mut whole) = (Vec::new(), Vec::new());
            let mut bytes = 0;
            for _ in 0..(*frames).max(1) {
                let s = g.render_on_device()?;
                device.push(s.seconds);
                bytes = s.bytes_read.unwrap_or(0);
                let start = Instant::now();
                g.render_into(&mut out)?;
                whole.push(start.elapsed().as_secs_f64());
            }
            // Bytes moved: the stored values read, plus the frame (emission copied in, then
            // each group pixel's three floats read and written once per chunk).
            let meta = match g.relighter() {
                Relighter::Pixel(p) => p.meta().clone(),
                Relighter::Vertex(_) => unreachable!("checked above"),
            };
            let group_pixels: u64 = meta.groups.iter().map(|g| u64::from(g.pixels)).sum();
            let frame_bytes = 24 * u64::from(w) * u64::from(h) + 28 * group_pixels;
            let moved = bytes + frame_bytes;
            let bound = moved as f64 / bandwidth + overhead;
            let dev = median(device);
            println!(
                "    {:<10} device {:.3} ms, with read-back {:.3} ms; moves {:.1} MB: bound {:.3} ms (bandwidth {:.3} + overhead {:.3}); frame / bound {:.2}",
                format!("{variant:?}"),
                dev * 1e3,
                median(whole) * 1e3,
                moved as f64 / 1e6,
                bound * 1e3,
                moved as f64 / bandwidth * 1e3,
                overhead * 1e3,
                dev / bound
            );
        }
    }
    if !args.no_cpu {
        for &variant in &variants {
            let mut r = prt_runtime::open(path)?;
            if let Relighter::Pixel(p) = &mut r {
                p.set_variant(variant)?;
            }
            let mut out = vec![0.0f32; 3 * w as usize * h as usize];
            r.render_into(&mut out)?;
            let mut times = Vec::new();
            for _ in 0..args.slow_frames.max(1) {
                let start = Instant::now();
                r.render_into(&mut out)?;
                times.push(start.elapsed().as_secs_f64());
            }
            println!(
                "  cpu ({} threads) {:<10} {:.3} ms",
                rayon::current_num_threads(),
                format!("{variant:?}"),
                median(times) * 1e3
            );
        }
    }
    println!("goal (the issue): a frame within 2x of the bandwidth bound plus the fixed overhead");
    Ok(())
}

/// `--agreement`: each bake's GPU frames against the CPU runtime's, relative L2 per setting
/// (the bound: 1e-3).
fn agreement(ctx: &GpuContext, paths: &[PathBuf], side: u32) -> Result<()> {
    println!("GPU frame against the CPU runtime's, relative L2 (bound 1e-3):");
    for path in paths {
        let mut g = GpuRelighter::new(ctx, prt_runtime::open(path)?)?;
        if let Relighter::Vertex(v) = g.relighter_mut() {
            v.set_size(side, side)?;
            // The device does not antialias silhouettes (docs/gpu.md): its frames are the CPU
            // runtime's with antialiasing off.
            v.set_antialias(false);
        }
        let (w, h) = g.relighter().size();
        let mut gpu = vec![0.0f32; 3 * w as usize * h as usize];
        let mut cpu = gpu.clone();
        let mut check = |g: &mut GpuRelighter, what: &str| -> Result<()> {
            g.relighter_mut().render_into(&mut cpu)?;
            g.render_into(&mut gpu)?;
            let (mut num, mut den) = (0.0f64, 0.0f64);
            for (a, b) in gpu.iter().zip(&cpu) {
                num += (f64::from(*a) - f64::from(*b)).powi(2);
                den += f64::from(*b).powi(2);
            }
            let d = if den > 0.0 {
                (num / den).sqrt()
            } else {
                f64::NAN
            };
            // Pixels whose values differ by more than a tenth: where the two rasterizers gave
            // a pixel centre within rounding of an edge to different triangles (the GPU's
            // fixed-point edge rule against the CPU's exact one), e.g. a silhouette's front
            // face on one and the side without data (black) on the other. The figure without
            // them isolates the shading.
            let (mut flipped, mut num_rest, mut den_rest) = (0usize, 0.0f64, 0.0f64);
            for (a, b) in gpu.chunks_exact(3).zip(cpu.chunks_exact(3)) {
                let e: f64 = (0..3)
                    .map(|c| (f64::from(a[c]) - f64::from(b[c])).powi(2))
                    .sum();
                let r: f64 = b.iter().map(|&x| f64::from(x).powi(2)).sum();
                let big: f64 = a
                    .iter()
                    .chain(b)
                    .map(|&x| f64::from(x).powi(2))
                    .fold(0.0, f64::max);
                if e > 0.01 * 3.0 * big {
                    flipped += 1;
                } else {
                    num_rest += e;
                    den_rest += r;
                }
            }
            println!(
                "  {} ({w}x{h}): {what}: {d:.2e} ({flipped} pixels differ by more than a tenth; \
                 without them {:.2e})",
                path.display(),
                (num_rest / den_rest.max(f64::MIN_POSITIVE)).sqrt()
            );
            Ok(())
        };
        check(&mut g, "as baked")?;
        // Every editable material: kd times 0.7, its lobe parameter at the middle of its
        // sampled range.
        let mut edited = Vec::new();
        for m in g.relighter().materials().into_iter().filter(|m| m.editable) {
            let mut values = Vec::new();
            for p in &m.params {
                match p.value {
                    OverrideValue::Kd(kd) => values.push(OverrideValue::Kd(kd.map(|c| 0.7 * c))),
                    OverrideValue::Shininess(_) | OverrideValue::Alpha(_) => {
                        let r = p.sampled.unwrap_or(p.range);
                        if r.max.is_finite() {
                            let mid = 0.5 * (r.min + r.max);
                            values.push(match p.value {
                                OverrideValue::Shininess(_) => OverrideValue::Shininess(mid),
                                _ => OverrideValue::Alpha(mid),
                            });
                        }
                    }
                    _ => {}
                }
            }
            g.relighter_mut().set_params(&m.name, &values)?;
            edited.push(m.name);
        }
        check(&mut g, &format!("edited ({})", edited.join(", ")))?;
        if let Relighter::Vertex(v) = g.relighter_mut() {
            let r = v.environment_rotation();
            v.set_environment_rotation(r + 120.0)?;
            v.set_environment_intensity(0.7)?;
        }
        if matches!(g.relighter(), Relighter::Vertex(_)) {
            check(&mut g, "map turned 120 degrees, intensity 0.7")?;
            if let Relighter::Vertex(v) = g.relighter_mut() {
                let c = v.camera().orbited(40.0);
                v.set_camera(c)?;
            }
            check(&mut g, "camera orbited 40 degrees")?;
        }
    }
    Ok(())
}
