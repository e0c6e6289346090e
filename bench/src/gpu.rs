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
            let stages = if g.vertex_stages_on_device() == Some(true) {
                "stages on the device"
            } else {
                "stages on the CPU (over a limit)"
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
