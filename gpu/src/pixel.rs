//! The per-pixel relight on the GPU (docs/gpu.md, "Per-pixel"): the stored tensors are
//! uploaded once (per representation, when it is first rendered), the frame's weights are
//! uploaded per frame, and a compute shader contracts them (`shaders/pixel.wgsl`).
//!
//! A group's rows are cut into chunks that each fit one storage binding (the device's
//! `max_storage_buffer_binding_size`, or [`crate::GpuOptions::max_binding_bytes`]); each
//! chunk is one dispatch adding its part of the contraction into the image, so a tensor larger
//! than a binding is relit in several passes over its pixels. A frame copies the emission
//! image into the frame buffer, runs the dispatches in group order and copies the frame to a
//! reused read-back buffer: nothing is allocated on the device per frame.

use std::ops::Range;

use prt_formats::pixel::{group_weights, names, PixelBakeMeta, Precision};
use prt_runtime::{PixelRelighter, Variant};

use crate::buffers::upload;
use crate::context::GpuContext;
use crate::error::GpuError;
use crate::present::{check_view, Present};
use crate::readback::Readback;

/// Invocations per workgroup (`WORKGROUP` in the shader).
const WORKGROUP: u32 = 256;

/// The uniform block of one chunk (`Chunk` in the shader), at a 256-byte stride.
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct ChunkParams {
    pixels: u32,
    col_start: u32,
    col_count: u32,
    groups_x: u32,
    init: [f32; 4],
}

/// One dispatch: a range of a group's rows in one storage buffer.
struct Chunk {
    group: usize,
    rows: Range<usize>,
    bind_group: wgpu::BindGroup,
}

/// The chunks of one representation (the full rows, or the low-rank weights).
struct Chunks {
    f16: bool,
    chunks: Vec<Chunk>,
}

/// The GPU side of a per-pixel bake.
pub(crate) struct PixelGpu {
    ctx: GpuContext,
    layout: wgpu::BindGroupLayout,
    pipeline_f32: wgpu::ComputePipeline,
    pipeline_f16: wgpu::ComputePipeline,
    /// Per group, its pixel indices.
    pixel_index: Vec<wgpu::Buffer>,
    emission: wgpu::Buffer,
    image: wgpu::Buffer,
    readback: Readback,
    full: Option<Chunks>,
    compressed: Option<Chunks>,
    /// Per-frame columns and chunk parameters, grown when a representation is first built.
    columns: wgpu::Buffer,
    params: wgpu::Buffer,
    params_stride: u64,
    /// Host copies of the per-frame uploads, kept so a frame allocates nothing.
    column_data: Vec<[f32; 4]>,
    param_data: Vec<u8>,
    /// Draws the frame into a caller's texture (made at the first such frame).
    present: Option<Present>,
}

impl PixelGpu {
    /// Uploads the bake's emission, pixel lists and the tensors of its current variant (the
    /// other variant when it is first rendered).
    pub(crate) fn new(ctx: &GpuContext, r: &PixelRelighter) -> Result<PixelGpu, GpuError> {
        let mut gpu = PixelGpu::buffers(ctx, r)?;
        gpu.ensure(r, r.variant())?;
        Ok(gpu)
    }

    fn buffers(ctx: &GpuContext, r: &PixelRelighter) -> Result<PixelGpu, GpuError> {
        ctx.checked("uploading a per-pixel bake", || {
            let device = &ctx.device;
            let meta = r.meta();
            let (w, h) = r.size();
            let npix = w as u64 * h as u64;
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("prt-gpu pixel"),
                source: wgpu::ShaderSource::Wgsl(include_str!("shaders/pixel.wgsl").into()),
            });
            let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            };
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("prt-gpu pixel"),
                entries: &[
                    storage(0, true),
                    storage(1, true),
                    storage(2, true),
                    storage(3, false),
                    wgpu::BindGroupLayoutEntry {
                        binding: 4,
                        visibility: wgpu::ShaderStages::COMPUTE,
                        ty: wgpu::BindingType::Buffer {
                            ty: wgpu::BufferBindingType::Uniform,
                            has_dynamic_offset: true,
                            min_binding_size: wgpu::BufferSize::new(
                                std::mem::size_of::<ChunkParams>() as u64,
                            ),
                        },
                        count: None,
                    },
                ],
            });
            let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("prt-gpu pixel"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipeline = |entry| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&pl),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            };
            let max = ctx.device_binding_bytes();
            let image_bytes = 12 * npix;
            if image_bytes > max {
                return Err(GpuError::Limit {
                    limit: "max_storage_buffer_binding_size",
                    what: format!("the {w}x{h} image"),
                    needed: image_bytes,
                    max,
                });
            }
            let file = r.file();
            let emission = upload(
                ctx,
                "emission",
                file.tensor(names::EMISSION)?.bytes(),
                wgpu::BufferUsages::COPY_SRC,
            )?;
            let image = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("prt-gpu pixel image"),
                size: image_bytes,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let mut pixel_index = Vec::with_capacity(meta.groups.len());
            for (g, gm) in meta.groups.iter().enumerate() {
                let bytes = file.tensor(&names::pixels(g))?.bytes();
                if bytes.len() as u64 > max {
                    return Err(GpuError::Limit {
                        limit: "max_storage_buffer_binding_size",
                        what: format!("group {g}'s pixel list ({} pixels)", gm.pixels),
                        needed: bytes.len() as u64,
                        max,
                    });
                }
                pixel_index.push(upload(
                    ctx,
                    "pixel index",
                    bytes,
                    wgpu::BufferUsages::STORAGE,
                )?);
            }
            let align = u64::from(ctx.limits().min_uniform_buffer_offset_alignment);
            let params_stride = (std::mem::size_of::<ChunkParams>() as u64).div_ceil(align) * align;
            let small = |label, size, usage| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size,
                    usage: usage | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            Ok(PixelGpu {
                ctx: ctx.clone(),
                pipeline_f32: pipeline("contract_f32"),
                pipeline_f16: pipeline("contract_f16"),
                layout,
                pixel_index,
                emission,
                image,
                readback: Readback::new(ctx, image_bytes),
                full: None,
                compressed: None,
                columns: small("prt-gpu columns", 16, wgpu::BufferUsages::STORAGE),
                params: small(
                    "prt-gpu chunk params",
                    params_stride,
                    wgpu::BufferUsages::UNIFORM,
                ),
                params_stride,
                column_data: Vec::new(),
                param_data: Vec::new(),
                present: None,
            })
        })
    }

    /// Uploads the representation `variant` reads unless it is on the device already.
    fn ensure(&mut self, r: &PixelRelighter, variant: Variant) -> Result<(), GpuError> {
        let built = match variant {
            Variant::Full => self.full.is_some(),
            Variant::Compressed => self.compressed.is_some(),
        };
        if built {
            return Ok(());
        }
        let plan = self.plan(r, variant)?;
        let rows: usize = plan.iter().map(|(_, rows)| rows.len()).sum();
        let max = self.ctx.device_binding_bytes();
        let columns_bytes = (16 * rows as u64).max(16);
        if columns_bytes > max {
            return Err(GpuError::Limit {
                limit: "max_storage_buffer_binding_size",
                what: format!("the frame's weights ({rows} columns)"),
                needed: columns_bytes,
                max,
            });
        }
        let params_bytes = self.params_stride * plan.len().max(1) as u64;
        let device = &self.ctx.device;
        if self.columns.size() < columns_bytes || self.params.size() < params_bytes {
            self.columns = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("prt-gpu columns"),
                size: columns_bytes.max(self.columns.size()),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.params = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("prt-gpu chunk params"),
                size: params_bytes.max(self.params.size()),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            // The other representation's bind groups name the old buffers: it is uploaded
            // again when it is next rendered.
            self.full = None;
            self.compressed = None;
        }
        let ctx = self.ctx.clone();
        let chunks = ctx.checked("uploading a per-pixel bake's tensors", || {
            self.build(r, variant, &plan)
        })?;
        match variant {
            Variant::Full => self.full = Some(chunks),
            Variant::Compressed => self.compressed = Some(chunks),
        }
        Ok(())
    }

    /// The chunks of `variant`: per group, its rows cut into ranges that each fit one
    /// storage binding.
    fn plan(
        &self,
        r: &PixelRelighter,
        variant: Variant,
    ) -> Result<Vec<(usize, Range<usize>)>, GpuError> {
        let meta = r.meta();
        let max = self.ctx.max_binding_bytes();
        let f16 = variant == Variant::Full && meta.precision == Precision::F16;
        let mut plan = Vec::new();
        for (g, gm) in meta.groups.iter().enumerate() {
            let p = gm.pixels as u64;
            let rows = match variant {
                Variant::Full => gm.row_len as usize,
                Variant::Compressed => match gm.compressed_rank {
                    Some(k) => k as usize,
                    None => return Err(prt_runtime::RuntimeError::NoCompressed.into()),
                },
            };
            // A chunk's bytes are its rows', rounded up to whole words.
            let row_bytes = p * if f16 { 2 } else { 4 };
            let fits = |n: u64| (n * row_bytes).div_ceil(4) * 4 <= max;
            if !fits(1) {
                return Err(GpuError::Limit {
                    limit: "max_storage_buffer_binding_size",
                    what: format!("one stored row of group {g} ({p} pixels)"),
                    needed: row_bytes,
                    max,
                });
            }
            let mut per_chunk = (max / row_bytes).max(1).min(rows.max(1) as u64);
            while !fits(per_chunk) {
                per_chunk -= 1;
            }
            let mut e0 = 0;
            while e0 < rows {
                let e1 = (e0 + per_chunk as usize).min(rows);
                plan.push((g, e0..e1));
                e0 = e1;
            }
        }
        Ok(plan)
    }

    /// Uploads the chunks of `plan`, binding them to the current column and parameter
    /// buffers.
    fn build(
        &self,
        r: &PixelRelighter,
        variant: Variant,
        plan: &[(usize, Range<usize>)],
    ) -> Result<Chunks, GpuError> {
        let meta = r.meta();
        let file = r.file();
        let f16 = variant == Variant::Full && meta.precision == Precision::F16;
        let value_bytes = if f16 { 2 } else { 4 };
        let mut chunks = Vec::with_capacity(plan.len());
        for (g, rows) in plan {
            let g = *g;
            let p = meta.groups[g].pixels as usize;
            let name = match variant {
                Variant::Full => names::transfer(g),
                Variant::Compressed => names::weights(g),
            };
            let bytes = file.tensor(&name)?.bytes();
            let part = &bytes[rows.start * p * value_bytes..rows.end * p * value_bytes];
            let buffer = upload(&self.ctx, "stored rows", part, wgpu::BufferUsages::STORAGE)?;
            let bind_group = self
                .ctx
                .device
                .create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("prt-gpu chunk"),
                    layout: &self.layout,
                    entries: &[
                        entry(0, &buffer),
                        entry(1, &self.pixel_index[g]),
                        entry(2, &self.columns),
                        entry(3, &self.image),
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                                buffer: &self.params,
                                offset: 0,
                                size: wgpu::BufferSize::new(
                                    std::mem::size_of::<ChunkParams>() as u64
                                ),
                            }),
                        },
                    ],
                });
            chunks.push(Chunk {
                group: g,
                rows: rows.clone(),
                bind_group,
            });
        }
        Ok(Chunks { f16, chunks })
    }

    /// Relights the current material setting into `out` (`3 * width * height` floats);
    /// returns the bytes of bake data the frame read.
    pub(crate) fn render_into(
        &mut self,
        r: &PixelRelighter,
        out: &mut [f32],
    ) -> Result<u64, GpuError> {
        let bytes_read = self.frame(r, true, None)?;
        self.readback.read(&self.ctx, |bytes| {
            out.copy_from_slice(bytemuck::cast_slice(bytes));
        })?;
        Ok(bytes_read)
    }

    /// Relights the current material setting into the device's frame buffer and waits for
    /// it (no read-back): what the device's work alone costs, for the benchmark.
    pub(crate) fn render_on_device(&mut self, r: &PixelRelighter) -> Result<u64, GpuError> {
        let bytes_read = self.frame(r, false, None)?;
        self.ctx.wait("relighting")?;
        Ok(bytes_read)
    }

    /// Relights the current material setting and draws the frame into a caller's texture
    /// view (`Rgba32Float`, the image's size, `RENDER_ATTACHMENT` usage), without reading it
    /// back; returns the bytes of bake data the frame read.
    pub(crate) fn render_to_view(
        &mut self,
        r: &PixelRelighter,
        view: &wgpu::TextureView,
    ) -> Result<u64, GpuError> {
        let (width, height) = (r.meta().width, r.meta().height);
        check_view(view, width, height)?;
        if self.present.is_none() {
            self.present = Some(Present::new(&self.ctx, &self.image, width, height));
        }
        let ctx = self.ctx.clone();
        ctx.checked("drawing into the caller's texture", || {
            self.frame(r, false, Some(view))
        })
    }

    /// Uploads the frame's weights and submits its work (and, with `read_back`, the copy to
    /// the read-back buffer; with `view`, drawing the frame into it); returns the bytes of
    /// bake data it reads.
    fn frame(
        &mut self,
        r: &PixelRelighter,
        read_back: bool,
        view: Option<&wgpu::TextureView>,
    ) -> Result<u64, GpuError> {
        let variant = r.variant();
        self.ensure(r, variant)?;
        let meta = r.meta();
        let file = r.file();
        let (coeff, _) = r.coefficients();
        let chunks = match variant {
            Variant::Full => self.full.as_ref(),
            Variant::Compressed => self.compressed.as_ref(),
        };
        let Some(chunks) = chunks else {
            return Err(GpuError::Unsupported(
                "the representation was not uploaded".into(),
            ));
        };
        self.column_data.clear();
        self.param_data.clear();
        let mut bytes_read = 12 * u64::from(meta.width) * u64::from(meta.height);
        let mut dispatches: Vec<(usize, u32, u32)> = Vec::with_capacity(chunks.chunks.len());
        let mut weights = GroupWeights::default();
        for (k, chunk) in chunks.chunks.iter().enumerate() {
            let g = chunk.group;
            let gm = &meta.groups[g];
            if weights.group != Some(g) {
                weights.compute(meta, file, g, &coeff, variant)?;
            }
            let col_start = self.column_data.len() as u32;
            for (e, w) in weights
                .columns
                .iter()
                .filter(|(e, _)| chunk.rows.contains(e))
            {
                let row = (e - chunk.rows.start) as u32;
                self.column_data
                    .push([f32::from_bits(row), w[0], w[1], w[2]]);
            }
            let col_count = self.column_data.len() as u32 - col_start;
            let init = if chunk.rows.start == 0 {
                weights.init
            } else {
                [0.0; 3]
            };
            let p = gm.pixels;
            let groups = p.div_ceil(WORKGROUP);
            let groups_x = groups.min(self.ctx.limits().max_compute_workgroups_per_dimension);
            let groups_y = groups.div_ceil(groups_x.max(1));
            let params = ChunkParams {
                pixels: p,
                col_start,
                col_count,
                groups_x,
                init: [init[0], init[1], init[2], 0.0],
            };
            let at = k * self.params_stride as usize;
            self.param_data.resize(at + self.params_stride as usize, 0);
            self.param_data[at..at + std::mem::size_of::<ChunkParams>()]
                .copy_from_slice(bytemuck::bytes_of(&params));
            let value_bytes = if chunks.f16 { 2 } else { 4 };
            bytes_read += u64::from(col_count) * u64::from(p) * value_bytes;
            if col_count > 0 || init != [0.0; 3] {
                dispatches.push((k, groups_x, groups_y));
            }
        }
        let queue = &self.ctx.queue;
        if !self.column_data.is_empty() {
            queue.write_buffer(&self.columns, 0, bytemuck::cast_slice(&self.column_data));
        }
        if !self.param_data.is_empty() {
            queue.write_buffer(&self.params, 0, &self.param_data);
        }
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.emission, 0, &self.image, 0, self.image.size());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("prt-gpu pixel relight"),
                timestamp_writes: None,
            });
            pass.set_pipeline(if chunks.f16 {
                &self.pipeline_f16
            } else {
                &self.pipeline_f32
            });
            for &(k, gx, gy) in &dispatches {
                let offset = (k as u64 * self.params_stride) as u32;
                pass.set_bind_group(0, &chunks.chunks[k].bind_group, &[offset]);
                pass.dispatch_workgroups(gx, gy, 1);
            }
        }
        if read_back {
            encoder.copy_buffer_to_buffer(
                &self.image,
                0,
                &self.readback.buffer,
                0,
                self.image.size(),
            );
        }
        if let (Some(view), Some(present)) = (view, &self.present) {
            present.encode(&mut encoder, view);
        }
        queue.submit([encoder.finish()]);
        Ok(bytes_read)
    }
}

/// One group's weights for a frame: its columns with a nonzero weight (stored elements, or
/// low-rank components) and the radiance its pixels start from (the low-rank mean's).
#[derive(Default)]
struct GroupWeights {
    group: Option<usize>,
    columns: Vec<(usize, [f32; 3])>,
    init: [f32; 3],
}

impl GroupWeights {
    /// The CPU runtime's weights (`PixelRelighter::render_into`): `group_weights` of the slot
    /// coefficients, times the group's scale for f16 rows; for the low-rank variant the mean
    /// and the components contracted with them.
    fn compute(
        &mut self,
        meta: &PixelBakeMeta,
        file: &prt_formats::BakeFile,
        g: usize,
        coeff: &[[f32; 3]],
        variant: Variant,
    ) -> Result<(), GpuError> {
        let gm = &meta.groups[g];
        let m = &meta.materials[gm.material as usize];
        let w = group_weights(
            gm,
            m,
            coeff,
            meta.reflections as usize,
            meta.channels as usize,
            meta.tint,
        );
        let len = gm.row_len as usize;
        self.group = Some(g);
        self.columns.clear();
        self.init = [0.0; 3];
        match variant {
            Variant::Full => {
                let scale = if meta.precision == Precision::F16 {
                    gm.scale
                } else {
                    1.0
                };
                for e in 0..len {
                    let we = [w[e] * scale, w[len + e] * scale, w[2 * len + e] * scale];
                    if we != [0.0; 3] {
                        self.columns.push((e, we));
                    }
                }
            }
            Variant::Compressed => {
                let k = gm.compressed_rank.unwrap_or(0) as usize;
                let mean = file.tensor(&names::mean(g))?.as_f32()?;
                let comps = file.tensor(&names::components(g))?.as_f32()?;
                self.init = dot3(mean, &w, len);
                for r in 0..k {
                    self.columns
                        .push((r, dot3(&comps[r * len..(r + 1) * len], &w, len)));
                }
            }
        }
        Ok(())
    }
}

/// `sum_e W[c][e] x[e]` per output channel (`w` is 3 x len, channel-major).
fn dot3(x: &[f32], w: &[f32], len: usize) -> [f32; 3] {
    let mut out = [0.0f32; 3];
    for e in 0..len {
        out[0] += w[e] * x[e];
        out[1] += w[len + e] * x[e];
        out[2] += w[2 * len + e] * x[e];
    }
    out
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}
