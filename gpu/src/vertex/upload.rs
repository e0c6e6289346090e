//! What the per-vertex view stage reads that the CPU stages make: the cube texture (the
//! prefiltered cubes and the open sky's irradiance table), and the uploads of the light's and
//! the materials' results when the stages' run counters move.

use prt_runtime::gpu_surface::VertexSurface;

use super::blocks::{cube_sizes, family_code, MaterialBlock};
use super::VertexGpu;
use crate::buffers::check_binding;
use crate::context::GpuContext;
use crate::error::GpuError;

impl VertexGpu {
    /// The prefiltered cubes' texture: one 2D array, six layers per cube, each cube in the
    /// top-left corner of a layer as large as the largest cube.
    ///
    /// Why not `texture_cube` with a filtering sampler: the CPU runtime filters bilinearly in
    /// f64 across face edges (`CubeMap::lookup_bilinear_face_st`); a sampler's filtering needs
    /// a device feature for 32-bit float texels and interpolates with a few bits of weight
    /// precision, so the shader loads the four texels and weighs them itself, as the CPU does.
    pub(super) fn cube_texture(
        ctx: &GpuContext,
        s: &VertexSurface,
    ) -> Result<wgpu::Texture, GpuError> {
        let cubes = cube_sizes(s);
        let side = cubes.iter().copied().max().unwrap_or(1).max(1) as u32;
        let layers = (6 * cubes.len()).max(6) as u32;
        let limits = ctx.limits();
        if side > limits.max_texture_dimension_2d {
            return Err(GpuError::Limit {
                limit: "max_texture_dimension_2d",
                what: "a prefiltered cube's side".into(),
                needed: u64::from(side),
                max: u64::from(limits.max_texture_dimension_2d),
            });
        }
        if layers > limits.max_texture_array_layers {
            return Err(GpuError::Limit {
                limit: "max_texture_array_layers",
                what: format!("{} prefiltered cubes", cubes.len()),
                needed: u64::from(layers),
                max: u64::from(limits.max_texture_array_layers),
            });
        }
        Ok(ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("prt-gpu prefiltered cubes"),
            size: wgpu::Extent3d {
                width: side,
                height: side,
                depth_or_array_layers: layers,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        }))
    }

    /// Uploads what changed since the last frame: the light's results (environment map,
    /// prefiltered cubes, and for the device's stages the light's coefficients) when the
    /// light stage ran, the materials and the records (or for the device's stages the slot
    /// coefficients) when the material stage ran. Returns whether the light and the materials
    /// moved.
    pub(super) fn upload_changes(&mut self, s: &VertexSurface) -> Result<(bool, bool), GpuError> {
        let queue = self.ctx.queue.clone();
        let mut rebind = false;
        let light_moved = self.light_runs != s.light_runs();
        let materials_moved = self.material_runs != s.material_runs();
        // The map's texels and its prefiltered cubes (of the unturned map) change with a new
        // map or intensity, not with a turn.
        let map_moved = self.map_runs != Some(s.map_runs());
        let env = s.environment();
        // The device's light stage also reads the map less its compact lights (the glossy
        // rows' light), after the map; the view stage the lights, after both.
        let glossy = s.glossy_environment().filter(|_| self.stages.is_some());
        if light_moved && map_moved {
            let texels = env.width * env.height;
            let lights = s.compact_lights();
            let mut data: Vec<f32> = Vec::with_capacity(
                3 * texels * (1 + usize::from(glossy.is_some())) + 8 * lights.len(),
            );
            data.extend(env.texels.iter().flatten());
            if let Some((rest, intensity)) = glossy {
                data.extend(rest.texels.iter().flatten().map(|v| v * intensity));
            }
            self.offsets.lights_at = data.len() as u32;
            self.offsets.n_lights = lights.len() as u32;
            for l in &lights {
                data.extend(l.direction);
                data.push(0.0);
                data.extend(l.power);
                data.push(0.0);
            }
            let bytes = 4 * data.len() as u64;
            if bytes > self.environment.size() {
                check_binding(&self.ctx, "the environment map", bytes)?;
                self.environment = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("prt-gpu environment"),
                    size: bytes,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                rebind = true;
            }
            queue.write_buffer(&self.environment, 0, bytemuck::cast_slice(&data));
            self.offsets.env_width = env.width as u32;
            self.offsets.env_height = env.height as u32;
        }
        if light_moved {
            if let Some(stages) = &mut self.stages {
                stages.set_light(
                    &self.ctx,
                    &self.environment,
                    (env.width, env.height),
                    s.environment_rotation(),
                    glossy.map(|_| 3 * env.width * env.height),
                    rebind,
                )?;
            }
            let side = self.cubes.width();
            // The cubes made here: the prefiltered ones, and the open sky's table when the
            // CPU ran the light stage (else the device makes it: `stages.rs`).
            let cubes: Vec<_> = s.prefiltered().iter().chain(s.open_sky()).collect();
            let open_sky_here = s.open_sky().is_some();
            if cube_sizes(s).len() as i32
                != s.prefiltered().len() as i32 + i32::from(self.offsets.open_sky_cube >= 0)
                || (open_sky_here && self.offsets.open_sky_cube < 0)
            {
                return Err(GpuError::Unsupported(
                    "the light's cubes changed in number after opening".into(),
                ));
            }
            for (c, cube) in cubes.iter().enumerate() {
                if c < s.prefiltered().len() && !map_moved {
                    continue;
                }
                let n = cube.size();
                if n as u32 > side || 6 * (c as u32 + 1) > self.cubes.depth_or_array_layers() {
                    return Err(GpuError::Unsupported(
                        "the prefiltered cubes changed size after opening".into(),
                    ));
                }
                self.cube_data.clear();
                self.cube_data
                    .extend(cube.texels().iter().map(|t| [t[0], t[1], t[2], 0.0]));
                queue.write_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.cubes,
                        mip_level: 0,
                        origin: wgpu::Origin3d {
                            x: 0,
                            y: 0,
                            z: 6 * c as u32,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    bytemuck::cast_slice(&self.cube_data),
                    wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(16 * n as u32),
                        rows_per_image: Some(n as u32),
                    },
                    wgpu::Extent3d {
                        width: n as u32,
                        height: n as u32,
                        depth_or_array_layers: 6,
                    },
                );
            }
            self.light_runs = s.light_runs();
            self.map_runs = Some(s.map_runs());
        }
        if materials_moved {
            if let Some(stages) = &mut self.stages {
                stages.write_coefficients(&self.ctx, s);
            } else {
                self.record_data.clear();
                for g in 0..s.groups() {
                    self.record_data.extend_from_slice(s.records(g).1);
                }
                if !self.record_data.is_empty() {
                    queue.write_buffer(&self.records, 0, bytemuck::cast_slice(&self.record_data));
                }
            }
            self.material_data.clear();
            self.core_data.clear();
            for m in 0..s.materials() {
                let Some(mat) = s.material(m) else { continue };
                let mut block = MaterialBlock {
                    kd: mat.kd,
                    ks: mat.ks,
                    group: mat.group.map_or(-1, |g| g as i32),
                    texture: mat.texture.map_or(-1, |t| t as i32),
                    normal_map: mat.normal_map.map_or(-1, |t| t as i32),
                    basis: -1,
                    ..Default::default()
                };
                if let Some(lobe) = mat.lobe {
                    block.basis = lobe.basis as i32;
                    block.family = family_code(lobe.family);
                    block.param = lobe.param;
                    block.core_at = self.core_data.len() as u32;
                    self.core_data.extend_from_slice(lobe.core);
                    block.taps_len = lobe.taps_len as u32;
                    (block.tap0, block.tap0_w) = (lobe.taps[0].0 as u32, lobe.taps[0].1);
                    (block.tap1, block.tap1_w) = (lobe.taps[1].0 as u32, lobe.taps[1].1);
                }
                self.material_data.push(block);
            }
            if !self.material_data.is_empty() {
                queue.write_buffer(
                    &self.materials,
                    0,
                    bytemuck::cast_slice(&self.material_data),
                );
            }
            if !self.core_data.is_empty() {
                queue.write_buffer(&self.cores, 0, bytemuck::cast_slice(&self.core_data));
            }
            self.material_runs = s.material_runs();
        }
        if rebind {
            self.bind_group = Self::bind_group(
                &self.ctx.device,
                &self.layout,
                [
                    &self.frame,
                    &self.geometry,
                    &self.index,
                    &self.records,
                    &self.visibility,
                    &self.materials,
                    &self.bases,
                    &self.tables,
                    &self.environment,
                    &self.cores,
                ],
                &self.cubes,
            );
        }
        Ok((light_moved, materials_moved))
    }
}
