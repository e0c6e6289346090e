//! Drawing a frame into a caller's texture (docs/gpu.md): the checks both kinds make of the
//! texture, and for the per-pixel kind, whose frame is a storage buffer, a render pass that
//! draws the buffer into the texture (`shaders/present.wgsl`).

use crate::context::GpuContext;
use crate::error::GpuError;

/// Refuses a texture view the frame cannot be drawn into: another size than the image's, a
/// format other than `Rgba32Float`, or a texture made without `RENDER_ATTACHMENT`.
pub(crate) fn check_view(
    view: &wgpu::TextureView,
    width: u32,
    height: u32,
) -> Result<(), GpuError> {
    let texture = view.texture();
    let size = texture.size();
    if (size.width, size.height) != (width, height) {
        return Err(GpuError::Unsupported(format!(
            "the caller's texture is {}x{}, the image {width}x{height}",
            size.width, size.height
        )));
    }
    if texture.format() != wgpu::TextureFormat::Rgba32Float {
        return Err(GpuError::Unsupported(format!(
            "the caller's texture is {:?}, expected Rgba32Float",
            texture.format()
        )));
    }
    if !texture
        .usage()
        .contains(wgpu::TextureUsages::RENDER_ATTACHMENT)
    {
        return Err(GpuError::Unsupported(
            "the caller's texture was made without RENDER_ATTACHMENT usage".into(),
        ));
    }
    Ok(())
}

/// The pipeline that draws a per-pixel frame buffer into a texture, with its bind group.
pub(crate) struct Present {
    pipeline: wgpu::RenderPipeline,
    bind_group: wgpu::BindGroup,
}

impl Present {
    /// A pipeline drawing `image` (`3 * width * height` floats) into `Rgba32Float` targets.
    pub(crate) fn new(ctx: &GpuContext, image: &wgpu::Buffer, width: u32, height: u32) -> Present {
        let device = &ctx.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("prt-gpu present"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shaders/present.wgsl").into()),
        });
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("prt-gpu present"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Storage { read_only: true }),
                entry(1, wgpu::BufferBindingType::Uniform),
            ],
        });
        let size = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("prt-gpu present size"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        ctx.queue
            .write_buffer(&size, 0, bytemuck::cast_slice(&[width, height, 0, 0]));
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("prt-gpu present"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: image.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: size.as_entire_binding(),
                },
            ],
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("prt-gpu present"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("prt-gpu present"),
            layout: Some(&pl),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("present_vertex"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("present_fragment"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: wgpu::TextureFormat::Rgba32Float,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        Present {
            pipeline,
            bind_group,
        }
    }

    /// Records drawing the frame buffer into `view`.
    pub(crate) fn encode(&self, encoder: &mut wgpu::CommandEncoder, view: &wgpu::TextureView) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("prt-gpu present"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}
