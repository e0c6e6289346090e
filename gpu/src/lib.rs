//! The PRT runtime on the GPU (wgpu; WGSL shaders; Vulkan, Metal and DX12 through one API):
//! the same frames as `prt_runtime`'s CPU path (relative L2 under 1e-3), for both kinds of
//! bake (docs/gpu.md).
//!
//! A [`GpuRelighter`] owns a CPU [`prt_runtime::Relighter`] and renders its current settings
//! on the device: materials, environment, camera and size are set through the relighter
//! ([`GpuRelighter::relighter_mut`]), with its own checks and errors, and a render picks them
//! up.
//!
//! - **Per-pixel**: the contraction is a compute shader over the stored tensors (f32 and
//!   f16, full and low-rank), uploaded once; the weights (from the slot coefficients) are
//!   uploaded per frame. A tensor larger than one storage binding is split across bindings.
//! - **Per-vertex**: the view stage is a render pipeline: the rasterizer interpolates each
//!   fragment's barycentric weights, the fragment shader blends the vertex records and shades
//!   the last reflection (Tucker shading with the specular split, the prefiltered cubes from a
//!   texture, the visibility, the Kd textures). The light and material stages run on the CPU
//!   (the runtime's own, through its `gpu-surface` feature) and their results are uploaded
//!   when they change, so a view-only frame uploads one uniform block.
//!
//! ```no_run
//! use prt_gpu::{GpuContext, GpuOptions, GpuRelighter};
//! use prt_runtime::{OverrideValue, Relighter};
//!
//! # fn main() -> Result<(), prt_gpu::GpuError> {
//! let ctx = GpuContext::new(&GpuOptions::default())?;
//! let mut r = GpuRelighter::new(&ctx, prt_runtime::open("out/vitrine.prtbake")?)?;
//! r.relighter_mut().set_params("sphere", &[OverrideValue::Alpha(0.3)])?;
//! if let Relighter::Vertex(v) = r.relighter_mut() {
//!     v.set_camera(v.default_camera().orbited(30.0))?;
//! }
//! let (w, h) = r.relighter().size();
//! let mut frame = vec![0.0f32; 3 * w as usize * h as usize];
//! r.render_into(&mut frame)?; // read back into the caller's memory
//! # Ok(())
//! # }
//! ```

#![warn(missing_docs)]

mod buffers;
mod compute;
mod context;
mod error;
mod pixel;
mod present;
mod readback;
mod vertex;

use std::time::Instant;

pub use context::{GpuContext, GpuOptions};
pub use error::GpuError;
use prt_runtime::{Image, Relighter};

/// What one GPU render cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuStats {
    /// The whole render call (CPU stages, uploads, the device's work and the read-back).
    pub seconds: f64,
    /// Per-vertex: the CPU light stage, when it ran.
    pub light_s: Option<f64>,
    /// Per-vertex: the CPU material stage, when it ran.
    pub material_s: Option<f64>,
    /// Per-pixel: bytes of bake data the frame read on the device.
    pub bytes_read: Option<u64>,
}

/// Runs what the CPU does of a per-vertex frame's stages: the parts that do not grow with the
/// vertex count when the device runs the rest, else the whole stages.
fn prepare_vertex(
    g: &vertex::VertexGpu,
    r: &mut prt_runtime::VertexRelighter,
) -> Result<prt_runtime::gpu_surface::Stages, GpuError> {
    Ok(if g.device_stages() {
        r.prepare_device_stages()?
    } else {
        r.prepare_stages()?
    })
}

/// Each kind's device state, boxed: both are large (about 1-2 KB of handles) and a relighter
/// holds one.
enum Backend {
    Pixel(Box<pixel::PixelGpu>),
    Vertex(Box<vertex::VertexGpu>),
}

/// A bake of either kind relit on a GPU: see the crate documentation.
pub struct GpuRelighter {
    cpu: Relighter,
    gpu: Backend,
}

impl GpuRelighter {
    /// Uploads `relighter`'s bake to `ctx`'s device. A per-vertex bake runs its light and
    /// material stages first (on the CPU). Refused with [`GpuError::Limit`] when a tensor, the
    /// image or a table exceeds a device limit, naming the limit; the relighter is dropped
    /// then (open it again to render on the CPU).
    pub fn new(ctx: &GpuContext, mut relighter: Relighter) -> Result<GpuRelighter, GpuError> {
        let gpu = match &mut relighter {
            Relighter::Pixel(r) => Backend::Pixel(Box::new(pixel::PixelGpu::new(ctx, r)?)),
            Relighter::Vertex(r) => {
                r.prepare_device_stages()?;
                let g = vertex::VertexGpu::new(ctx, r)?;
                prepare_vertex(&g, r)?;
                Backend::Vertex(Box::new(g))
            }
        };
        Ok(GpuRelighter {
            cpu: relighter,
            gpu,
        })
    }

    /// The CPU relighter whose settings are rendered.
    pub fn relighter(&self) -> &Relighter {
        &self.cpu
    }

    /// The CPU relighter, to change materials (and per vertex the environment, camera and
    /// size; per pixel the variant): the next render picks the changes up.
    pub fn relighter_mut(&mut self) -> &mut Relighter {
        &mut self.cpu
    }

    /// Per-vertex: whether the light and material stages' per-vertex work runs on the device
    /// (`false`: a part of the bake exceeds a device limit, and the CPU runs the stages and
    /// uploads their records); `None` for a per-pixel bake.
    pub fn vertex_stages_on_device(&self) -> Option<bool> {
        match &self.gpu {
            Backend::Vertex(g) => Some(g.device_stages()),
            Backend::Pixel(_) => None,
        }
    }

    /// Per-vertex, when the light and material stages run on the CPU: why (the device limit a
    /// part of the bake exceeds, named as [`GpuError::Limit`] names it, or the context's
    /// [`GpuOptions::vertex_stages_on_cpu`]). `None` when they run on the device, and for a
    /// per-pixel bake.
    pub fn vertex_stages_on_cpu(&self) -> Option<&str> {
        match &self.gpu {
            Backend::Vertex(g) => g.stages_on_cpu(),
            Backend::Pixel(_) => None,
        }
    }

    /// Hands the CPU relighter back (to render on the CPU after all).
    pub fn into_relighter(self) -> Relighter {
        self.cpu
    }

    /// Renders the current settings on the device and reads the frame back into `out`:
    /// `3 * width * height` floats, linear RGB, row-major, top row first, the layout of
    /// [`Relighter::render_into`] (another length is refused with the same error). Nothing is
    /// allocated on the device per frame once the size has settled.
    pub fn render_into(&mut self, out: &mut [f32]) -> Result<GpuStats, GpuError> {
        let start = Instant::now();
        let (w, h) = self.cpu.size();
        let expected = 3 * w as usize * h as usize;
        if out.len() != expected {
            return Err(prt_runtime::RuntimeError::BufferSize {
                what: "the output buffer",
                width: w,
                height: h,
                expected,
                got: out.len(),
            }
            .into());
        }
        let mut stats = GpuStats::default();
        match (&mut self.gpu, &mut self.cpu) {
            (Backend::Pixel(g), Relighter::Pixel(r)) => {
                stats.bytes_read = Some(g.render_into(r, out)?);
            }
            (Backend::Vertex(g), Relighter::Vertex(r)) => {
                let stages = prepare_vertex(g, r)?;
                stats.light_s = stages.light_s;
                stats.material_s = stages.material_s;
                g.render_into(r, out)?;
            }
            _ => return Err(GpuError::Unsupported("the bake's kind changed".into())),
        }
        stats.seconds = start.elapsed().as_secs_f64();
        Ok(stats)
    }

    /// [`GpuRelighter::render_into`] into a new [`Image`].
    pub fn render(&mut self) -> Result<Image, GpuError> {
        let (w, h) = self.cpu.size();
        let mut image = Image::new(w, h);
        self.render_into(image.pixels.as_flattened_mut())?;
        Ok(image)
    }

    /// Renders the current settings on the device and waits until the device is done, without
    /// reading the frame back: the device's part of a frame, which `bench gpu` times beside
    /// [`GpuRelighter::render_into`].
    pub fn render_on_device(&mut self) -> Result<GpuStats, GpuError> {
        let start = Instant::now();
        let mut stats = GpuStats::default();
        match (&mut self.gpu, &mut self.cpu) {
            (Backend::Pixel(g), Relighter::Pixel(r)) => {
                stats.bytes_read = Some(g.render_on_device(r)?);
            }
            (Backend::Vertex(g), Relighter::Vertex(r)) => {
                let stages = prepare_vertex(g, r)?;
                stats.light_s = stages.light_s;
                stats.material_s = stages.material_s;
                g.render_on_device(r)?;
            }
            _ => return Err(GpuError::Unsupported("the bake's kind changed".into())),
        }
        stats.seconds = start.elapsed().as_secs_f64();
        Ok(stats)
    }

    /// Renders the current settings into a caller's texture view (format `Rgba32Float`,
    /// the current image size, made with `RENDER_ATTACHMENT` usage on the context's device),
    /// so an engine or a viewer displays it without a copy through the host: RGB the frame
    /// [`GpuRelighter::render_into`] reads back, alpha 1. Another size, format or usage is
    /// refused ([`GpuError::Unsupported`], naming it).
    pub fn render_to_view(&mut self, view: &wgpu::TextureView) -> Result<GpuStats, GpuError> {
        let start = Instant::now();
        match (&mut self.gpu, &mut self.cpu) {
            (Backend::Vertex(g), Relighter::Vertex(r)) => {
                let (w, h) = r.size();
                present::check_view(view, w, h)?;
                let stages = prepare_vertex(g, r)?;
                g.render_to_view(r, view)?;
                Ok(GpuStats {
                    seconds: start.elapsed().as_secs_f64(),
                    light_s: stages.light_s,
                    material_s: stages.material_s,
                    bytes_read: None,
                })
            }
            (Backend::Pixel(g), Relighter::Pixel(r)) => {
                let bytes_read = g.render_to_view(r, view)?;
                Ok(GpuStats {
                    seconds: start.elapsed().as_secs_f64(),
                    bytes_read: Some(bytes_read),
                    ..Default::default()
                })
            }
            _ => Err(GpuError::Unsupported("the bake's kind changed".into())),
        }
    }
}
