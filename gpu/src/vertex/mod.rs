//! The per-vertex bake on the GPU (docs/gpu.md, "Per-vertex"): the light and material
//! stages' per-vertex work as compute dispatches (`stages.rs`, `shaders/stages.wgsl`) that
//! write the vertex records, and the view stage as a render pipeline that draws the mesh (the
//! rasterizer interpolates barycentric weights perspective-correctly, with a reversed depth
//! test) and whose fragment shader shades the last reflection from the records
//! (`shaders/vertex.wgsl`); a second pipeline fills the pixels no triangle covers with the
//! environment.
//!
//! The CPU runs what does not grow with the vertex count (`prt_runtime`'s
//! `prepare_device_stages`, through its `gpu-surface` feature: the light's cubes and
//! coefficients, the materials' contracted cores and slot coefficients); those are uploaded
//! when the stages' run counters move, so a view-only frame uploads one uniform block and
//! nothing else, and a frame allocates nothing on the device once its size is set. A bake
//! whose stage data exceed a device limit runs the whole stages on the CPU and uploads their
//! records instead ([`VertexGpu::device_stages`] tells which).

use prt_formats::lighting::cubemap::rotation_y;
use prt_runtime::gpu_surface::VertexSurface;
use prt_runtime::VertexRelighter;

use crate::buffers::{check_binding, storage_buffer};
use crate::context::GpuContext;
use crate::error::GpuError;
use crate::readback::Readback;

mod blocks;
mod environment;
mod stages;
mod upload;

use blocks::{cube_sizes, BasisBlock, FrameBlock, MaterialBlock};
use stages::DeviceStages;

/// The rasterizer's near plane, relative to the scene's depth (the CPU rasterizer's
/// `NEAR_PLANE_RELATIVE`, here of the bounding box's farthest corner).
const NEAR_PLANE_RELATIVE: f32 = 1e-5;

/// The visibility bytes per vertex of a group with a shading basis (6 x 16 x 16).
const VISIBILITY_BYTES: usize = 6 * 16 * 16;

/// The image being rendered and its read-back copy, made for one size.
struct Target {
    width: u32,
    height: u32,
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    readback: Readback,
    /// Bytes per row of the read-back copy (a multiple of 256).
    row_pitch: u32,
}

/// The GPU side of a per-vertex bake.
pub(crate) struct VertexGpu {
    ctx: GpuContext,
    layout: wgpu::BindGroupLayout,
    mesh_pipeline: wgpu::RenderPipeline,
    background_pipeline: wgpu::RenderPipeline,
    frame: wgpu::Buffer,
    geometry: wgpu::Buffer,
    index: wgpu::Buffer,
    records: wgpu::Buffer,
    visibility: wgpu::Buffer,
    materials: wgpu::Buffer,
    bases: wgpu::Buffer,
    tables: wgpu::Buffer,
    environment: wgpu::Buffer,
    cores: wgpu::Buffer,
    cubes: wgpu::Texture,
    bind_group: wgpu::BindGroup,
    /// The stages' per-vertex work on the device; `None`: on the CPU, for the reason in
    /// `stages_on_cpu` (a part over a limit, or the context's option).
    stages: Option<DeviceStages>,
    stages_on_cpu: Option<String>,
    /// The stages' run counts whose results are on the device.
    light_runs: u64,
    material_runs: u64,
    /// The lighting map's change count whose texels and prefiltered cubes are on the device.
    map_runs: Option<u64>,
    triangles: u32,
    /// The mesh's bounding box (for the near plane).
    bounds: [[f32; 3]; 2],
    offsets: FrameBlock,
    target: Option<Target>,
    /// Host scratch of the uploads, kept between frames.
    record_data: Vec<f32>,
    material_data: Vec<MaterialBlock>,
    core_data: Vec<f32>,
    cube_data: Vec<[f32; 4]>,
}

impl VertexGpu {
    /// Uploads the mesh, the stages' data, the shading tables, the textures and the light of
    /// `r` (whose stages must have run: `VertexRelighter::prepare_device_stages` or
    /// `prepare_stages`).
    pub(crate) fn new(ctx: &GpuContext, r: &VertexRelighter) -> Result<VertexGpu, GpuError> {
        let Some(s) = r.surface() else {
            return Err(GpuError::Unsupported(
                "the light and material stages have not run".into(),
            ));
        };
        ctx.checked("uploading a per-vertex bake", || Self::create(ctx, &s))
    }

    fn create(ctx: &GpuContext, s: &VertexSurface) -> Result<VertexGpu, GpuError> {
        let device = &ctx.device;
        let positions = s.positions();
        let nv = positions.len();
        let triangles = s.triangles();
        // Geometry: positions, normals, texture coordinates.
        let mut geometry: Vec<f32> = Vec::with_capacity(8 * nv);
        geometry.extend(positions.iter().flatten());
        geometry.extend(s.normals().iter().flatten());
        geometry.extend(s.uvs().iter().flatten());
        let mut bounds = [[f32::INFINITY; 3], [f32::NEG_INFINITY; 3]];
        for p in positions.iter().filter(|p| p.iter().all(|c| c.is_finite())) {
            for c in 0..3 {
                bounds[0][c] = bounds[0][c].min(p[c]);
                bounds[1][c] = bounds[1][c].max(p[c]);
            }
        }
        // Records of all groups back to back; each vertex's offset into them.
        let stage_groups = s.stage_groups()?;
        let record_layout = stages::record_layout(s, &stage_groups)?;
        let records_len = record_layout
            .last()
            .zip(stage_groups.last())
            .map_or(0, |(&(at, stride), g)| at + stride * g.vertices.len());
        let mut vis_at = Vec::with_capacity(s.groups());
        let mut vis_len = 0usize;
        for g in 0..s.groups() {
            vis_at.push(vis_len);
            vis_len += s.visibility(g).len();
        }
        let mut index: Vec<u32> =
            Vec::with_capacity(3 * triangles.len() + triangles.len() + 2 * nv);
        index.extend(triangles.iter().flatten());
        let materials_of_at = index.len() as u32;
        index.extend(s.triangle_material());
        let vertex_info_at = index.len() as u32;
        for &(g, local) in s.vertex_group() {
            let g = g as usize;
            if g < s.groups() {
                let (record_at, stride) = record_layout[g];
                let vis = if s.visibility(g).is_empty() {
                    0
                } else {
                    vis_at[g] + local as usize * VISIBILITY_BYTES
                };
                index.push((record_at + local as usize * stride) as u32);
                index.push(vis as u32);
            } else {
                index.extend([0, 0]);
            }
        }
        if records_len > u32::MAX as usize || vis_len > u32::MAX as usize {
            return Err(GpuError::Limit {
                limit: "max_storage_buffer_binding_size",
                what: "the vertex records or visibility (32-bit offsets)".into(),
                needed: (4 * records_len).max(vis_len) as u64,
                max: u64::from(u32::MAX),
            });
        }
        // Tables: per basis its U^o, pole row, reflectances, their pole rows and widths;
        // then the textures.
        let mut tables: Vec<f32> = Vec::new();
        let mut bases = Vec::with_capacity(s.shading().len());
        for (b, basis) in s.shading().iter().enumerate() {
            let mut block = BasisBlock {
                n_theta: basis.dirs.n_theta as u32,
                n_phi: basis.dirs.n_phi as u32,
                r_o: basis.ranks.o as u32,
                r_i: basis.ranks.i as u32,
                n_widths: basis.n_widths() as u32,
                n_dirs: basis.n_dirs() as u32,
                ..Default::default()
            };
            block.u_o_at = tables.len() as u32;
            tables.extend(&basis.u_o);
            block.u_o_pole_at = tables.len() as u32;
            tables.extend(&basis.u_o_pole);
            block.refl_at = tables.len() as u32;
            tables.extend(&basis.reflectances);
            block.refl_pole_at = tables.len() as u32;
            tables.extend(&basis.reflectances_pole);
            block.widths_at = tables.len() as u32;
            for k in 0..basis.n_widths() {
                let w = s.split_width(b, k).ok_or_else(|| {
                    GpuError::Unsupported(format!("shading basis {b} has no split width {k}"))
                })?;
                tables.push(f32::from_bits(w.prefiltered as u32));
                tables.extend(w.sh_factors);
                tables.extend([w.sigma, 0.0, 0.0]);
            }
            if basis.n_widths() > 8 || basis.ranks.o > 32 || basis.ranks.i > 32 {
                return Err(GpuError::Unsupported(format!(
                    "shading basis {b}: {} split widths, ranks {} x {} (at most 8 widths and rank 32)",
                    basis.n_widths(),
                    basis.ranks.o,
                    basis.ranks.i
                )));
            }
            bases.push(block);
        }
        let texture_info_at = index.len() as u32;
        for t in 0..s.textures() {
            let (w, h, texels) = s.texture(t).unwrap_or((0, 0, &[]));
            index.extend([tables.len() as u32, w as u32, h as u32, 0]);
            tables.extend(texels.iter().flatten());
        }
        let cube_size_at = index.len() as u32;
        index.extend(cube_sizes(s).iter().map(|&c| c as u32));
        let tables_bytes = 4 * tables.len() as u64;
        if tables.len() > u32::MAX as usize {
            return Err(GpuError::Limit {
                limit: "max_storage_buffer_binding_size",
                what: "the shading tables and textures (32-bit offsets)".into(),
                needed: tables_bytes,
                max: u64::from(u32::MAX),
            });
        }
        let geometry = storage_buffer(ctx, "the mesh's vertices", bytemuck::cast_slice(&geometry))?;
        let index = storage_buffer(ctx, "the mesh's triangles", bytemuck::cast_slice(&index))?;
        let records = {
            check_binding(ctx, "the vertex records", 4 * records_len as u64)?;
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("prt-gpu records"),
                size: (4 * records_len as u64).max(4),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let mut vis_bytes = Vec::with_capacity(vis_len);
        for g in 0..s.groups() {
            vis_bytes.extend_from_slice(s.visibility(g));
        }
        let visibility = storage_buffer(ctx, "the visibility", &vis_bytes)?;
        let nmat = s.materials().max(1);
        let materials = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("prt-gpu materials"),
            size: (nmat * std::mem::size_of::<MaterialBlock>()) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        if bases.is_empty() {
            bases.push(BasisBlock::default());
        }
        let bases = storage_buffer(ctx, "the shading bases", bytemuck::cast_slice(&bases))?;
        let tables = storage_buffer(
            ctx,
            "the shading tables and textures",
            bytemuck::cast_slice(&tables),
        )?;
        let core_len: usize = s
            .shading()
            .iter()
            .map(|b| b.ranks.o * b.ranks.i)
            .max()
            .unwrap_or(1)
            * nmat;
        let cores = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("prt-gpu cores"),
            size: (4 * core_len as u64).max(4),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let env = s.environment();
        let env_bytes = 12 * (env.width * env.height) as u64;
        check_binding(ctx, "the environment map", env_bytes)?;
        let environment = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("prt-gpu environment"),
            size: env_bytes.max(4),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let cubes = Self::cube_texture(ctx, s)?;
        let frame = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("prt-gpu frame"),
            size: std::mem::size_of::<FrameBlock>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = Self::bind_group_layout(device);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("prt-gpu vertex"),
            source: wgpu::ShaderSource::Wgsl(
                concat!(
                    include_str!("../shaders/latlong.wgsl"),
                    include_str!("../shaders/vertex.wgsl")
                )
                .into(),
            ),
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("prt-gpu vertex"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |vertex, fragment, compare, write| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(fragment),
                layout: Some(&pl),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(vertex),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    // Triangles are two-sided: the shader decides what the back shows.
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: wgpu::TextureFormat::Depth32Float,
                    depth_write_enabled: Some(write),
                    depth_compare: Some(compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fragment),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: wgpu::TextureFormat::Rgba32Float,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        // Reversed depth: nearer is greater; of equally near triangles the first drawn (the
        // lowest index, as on the CPU) stays.
        let mesh_pipeline = pipeline(
            "mesh_vertex",
            "mesh_fragment",
            wgpu::CompareFunction::Greater,
            true,
        );
        let background_pipeline = pipeline(
            "background_vertex",
            "background_fragment",
            wgpu::CompareFunction::GreaterEqual,
            false,
        );
        let offsets = FrameBlock {
            normals_at: 3 * nv as u32,
            uvs_at: 6 * nv as u32,
            materials_of_at,
            vertex_info_at,
            texture_info_at,
            cube_size_at,
            open_sky_cube: if s.needs_open_sky() {
                s.prefiltered().len() as i32
            } else {
                -1
            },
            ..Default::default()
        };
        let bind_group = Self::bind_group(
            device,
            &layout,
            [
                &frame,
                &geometry,
                &index,
                &records,
                &visibility,
                &materials,
                &bases,
                &tables,
                &environment,
                &cores,
            ],
            &cubes,
        );
        let (stages, stages_on_cpu) = if ctx.vertex_stages_on_cpu() {
            (None, Some("GpuOptions::vertex_stages_on_cpu".to_string()))
        } else {
            match DeviceStages::new(ctx, s, &stage_groups, &record_layout, &records) {
                Ok(st) => (Some(st), None),
                Err(e @ GpuError::Limit { .. }) => (None, Some(e.to_string())),
                Err(e) => return Err(e),
            }
        };
        Ok(VertexGpu {
            ctx: ctx.clone(),
            layout,
            mesh_pipeline,
            background_pipeline,
            frame,
            geometry,
            index,
            records,
            visibility,
            materials,
            bases,
            tables,
            environment,
            cores,
            cubes,
            bind_group,
            stages,
            stages_on_cpu,
            light_runs: 0,
            material_runs: 0,
            map_runs: None,
            triangles: triangles.len() as u32,
            bounds,
            offsets,
            target: None,
            record_data: Vec::new(),
            material_data: Vec::new(),
            core_data: Vec::new(),
            cube_data: Vec::new(),
        })
    }

    fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
        let stages = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let mut entries = vec![wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: stages,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }];
        for binding in 1..=9 {
            entries.push(wgpu::BindGroupLayoutEntry {
                binding,
                visibility: stages,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only: true },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            });
        }
        entries.push(wgpu::BindGroupLayoutEntry {
            binding: 10,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2Array,
                multisampled: false,
            },
            count: None,
        });
        device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("prt-gpu vertex"),
            entries: &entries,
        })
    }

    fn bind_group(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        buffers: [&wgpu::Buffer; 10],
        cubes: &wgpu::Texture,
    ) -> wgpu::BindGroup {
        let view = cubes.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let mut entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: 10,
            resource: wgpu::BindingResource::TextureView(&view),
        });
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("prt-gpu vertex"),
            layout,
            entries: &entries,
        })
    }

    /// Makes the image and depth targets for `width` x `height` unless they exist.
    fn ensure_target(&mut self, width: u32, height: u32) -> Result<(), GpuError> {
        if self
            .target
            .as_ref()
            .is_some_and(|t| t.width == width && t.height == height)
        {
            return Ok(());
        }
        let max = self.ctx.limits().max_texture_dimension_2d;
        if width > max || height > max {
            return Err(GpuError::Limit {
                limit: "max_texture_dimension_2d",
                what: format!("a {width}x{height} image"),
                needed: u64::from(width.max(height)),
                max: u64::from(max),
            });
        }
        let device = &self.ctx.device;
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let texture = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = texture(
            "prt-gpu image",
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = texture(
            "prt-gpu depth",
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let row_pitch = (16 * width).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        self.target = Some(Target {
            width,
            height,
            color_view: color.create_view(&Default::default()),
            color,
            depth_view: depth.create_view(&Default::default()),
            readback: Readback::new(&self.ctx, u64::from(row_pitch) * u64::from(height)),
            row_pitch,
        });
        Ok(())
    }

    /// The uniform block of the current camera, size and environment rotation.
    fn frame_block(&self, s: &VertexSurface) -> FrameBlock {
        let cam = s.camera();
        let (width, height) = s.size();
        let v4 = |v: [f32; 3]| [v[0], v[1], v[2], 0.0];
        // The farthest corner of the mesh's box from the eye bounds its camera-space depth.
        let mut far = 0.0f32;
        for k in 0..8 {
            let corner: [f32; 3] = std::array::from_fn(|c| self.bounds[(k >> c) & 1][c]);
            let d: f32 = (0..3)
                .map(|c| (corner[c] - cam.position[c]).powi(2))
                .sum::<f32>()
                .sqrt();
            if d.is_finite() {
                far = far.max(d);
            }
        }
        // R_y(-rotation), the CPU's `Environment::back`, row by row.
        let m = rotation_y(-f64::from(s.environment_rotation()));
        let back = m.map(|row| [row[0] as f32, row[1] as f32, row[2] as f32, 0.0]);
        FrameBlock {
            eye: v4(cam.position),
            right: v4(cam.right),
            up: v4(cam.up),
            forward: v4(cam.forward),
            back,
            tan_half_fov: (f64::from(cam.yfov) * 0.5).tan() as f32,
            aspect: (f64::from(width) / f64::from(height)) as f32,
            near: (NEAR_PLANE_RELATIVE * far).max(f32::MIN_POSITIVE),
            turned: u32::from(s.environment_rotation() != 0.0),
            width: width as f32,
            height: height as f32,
            background_samples: s.background_samples(),
            ..self.offsets
        }
    }

    /// Draws the current view into `view` (an `Rgba32Float` texture view of the current size)
    /// and, when `read_back`, copies it to the read-back buffer.
    fn draw(
        &mut self,
        r: &VertexRelighter,
        view: Option<&wgpu::TextureView>,
        read_back: bool,
    ) -> Result<(), GpuError> {
        let Some(s) = r.surface() else {
            return Err(GpuError::Unsupported(
                "the light and material stages have not run".into(),
            ));
        };
        let (light_moved, materials_moved) = self.upload_changes(&s)?;
        let (width, height) = s.size();
        self.ensure_target(width, height)?;
        let block = self.frame_block(&s);
        self.ctx
            .queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(&block));
        let Some(target) = &self.target else {
            return Err(GpuError::Unsupported("no render target".into()));
        };
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        if let Some(stages) = &self.stages {
            if light_moved {
                stages.encode_light(&mut encoder, &self.ctx);
                if self.offsets.open_sky_cube >= 0 {
                    stages.encode_open_sky_copy(
                        &mut encoder,
                        &self.cubes,
                        6 * self.offsets.open_sky_cube as u32,
                    );
                }
            }
            if light_moved || materials_moved {
                stages.encode_material(&mut encoder, &self.ctx);
            }
        }
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("prt-gpu view stage"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: view.unwrap_or(&target.color_view),
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &target.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_pipeline(&self.mesh_pipeline);
            pass.draw(0..3 * self.triangles, 0..1);
            pass.set_pipeline(&self.background_pipeline);
            pass.draw(0..3, 0..1);
        }
        if read_back {
            encoder.copy_texture_to_buffer(
                target.color.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &target.readback.buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(target.row_pitch),
                        rows_per_image: Some(height),
                    },
                },
                wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
            );
        }
        self.ctx.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Whether the stages' per-vertex work runs on the device (else the relighter must run
    /// them on the CPU: `VertexRelighter::prepare_stages`).
    pub(crate) fn device_stages(&self) -> bool {
        self.stages.is_some()
    }

    /// Why the stages' per-vertex work runs on the CPU, when it does.
    pub(crate) fn stages_on_cpu(&self) -> Option<&str> {
        self.stages_on_cpu.as_deref()
    }

    /// Renders the current view and reads it back into `out` (`3 * width * height` floats).
    pub(crate) fn render_into(
        &mut self,
        r: &VertexRelighter,
        out: &mut [f32],
    ) -> Result<(), GpuError> {
        self.draw(r, None, true)?;
        let Some(target) = &self.target else {
            return Err(GpuError::Unsupported("no render target".into()));
        };
        let (w, pitch) = (target.width as usize, target.row_pitch as usize);
        target.readback.read(&self.ctx, |bytes| {
            for (row, dst) in out.chunks_exact_mut(3 * w).enumerate() {
                let src: &[f32] = bytemuck::cast_slice(&bytes[row * pitch..row * pitch + 16 * w]);
                for (d, s) in dst.chunks_exact_mut(3).zip(src.chunks_exact(4)) {
                    d.copy_from_slice(&s[..3]);
                }
            }
        })?;
        let _ = target.readback.size();
        Ok(())
    }

    /// Renders the current view into the device's own target and waits for it (no
    /// read-back): what the device's work alone costs, for the benchmark.
    pub(crate) fn render_on_device(&mut self, r: &VertexRelighter) -> Result<(), GpuError> {
        self.draw(r, None, false)?;
        self.ctx.wait("rendering")
    }

    /// Renders the current view into a caller's texture view (`Rgba32Float`, the current
    /// size, usable as a render attachment), without reading it back.
    pub(crate) fn render_to_view(
        &mut self,
        r: &VertexRelighter,
        view: &wgpu::TextureView,
    ) -> Result<(), GpuError> {
        let ctx = self.ctx.clone();
        ctx.checked("rendering into the caller's texture", || {
            self.draw(r, Some(view), false)
        })
    }
}
