//! The light stage's per-environment part on the device (`shaders/environment.wgsl`): from the
//! lighting map and its rotation, the turned 6x64x64 cube, its Haar coefficients `C0`, the
//! coarse cubes `C1` and `C2` and the open sky's irradiance table, written into the stages'
//! light buffer (`stages.rs`), the open sky also copied into the view stage's cube texture.
//! The tables that depend only on the cube's geometry (texel solid angles and directions, the
//! resampling's sub-grid) are computed here with `prt_formats::lighting::cubemap`'s exact
//! formulas and uploaded once (the sub-grid again when the map's size changes).

use prt_formats::lighting::cubemap::{
    face_ab_to_vector, face_solid_angles, subsamples_per_texel, texel_centre_direction, Face,
};
use prt_formats::lighting::irradiance::{IRRADIANCE_CUBE, IRRADIANCE_SOURCE};
use prt_formats::vertex::{cube_len, DIRECT_CUBE, T1_LIGHT_CUBE, T2_LIGHT_CUBE};

use crate::compute::{Binding, ComputeProgram};
use crate::context::GpuContext;
use crate::error::GpuError;

/// Invocations per workgroup (`WORKGROUP` in the shader).
const WORKGROUP: u32 = 64;

/// `Env` in the shader.
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct EnvBlock {
    turns: f32,
    map_at: u32,
    c0_at: u32,
    pad0: u32,
    env_width: u32,
    env_height: u32,
    m: u32,
    ns: u32,
    weights_at: u32,
    sqrt_omega_at: u32,
    omega_at: u32,
    omega32_at: u32,
    dirs32_at: u32,
    c1_at: u32,
    c2_at: u32,
    open_sky_at: u32,
    source_at: u32,
    pad: [u32; 3],
}

/// Where the kernels write in the light buffer (entries).
#[derive(Clone, Copy)]
pub(super) struct LightTargets {
    pub(super) c1_at: usize,
    pub(super) c2_at: usize,
    pub(super) open_sky_at: usize,
    /// C0 of the map less its compact lights (the glossy rows' light).
    pub(super) glossy_c0_at: usize,
}

/// The kernels, their tables and their scratch (see the module documentation).
pub(super) struct EnvironmentStage {
    resample: wgpu::ComputePipeline,
    haar: wgpu::ComputePipeline,
    coarse: wgpu::ComputePipeline,
    open_sky: wgpu::ComputePipeline,
    program: ComputeProgram,
    uniform: wgpu::Buffer,
    /// The block of the glossy rows' pass (the map less its compact lights into
    /// `glossy_c0_at`), and its bind group.
    glossy_uniform: wgpu::Buffer,
    tables: Option<wgpu::Buffer>,
    cube: wgpu::Buffer,
    bind: Option<wgpu::BindGroup>,
    glossy_bind: Option<wgpu::BindGroup>,
    /// Whether the map has compact lights (then the glossy pass runs over the map less them;
    /// else the map's cube is transformed a second time into `glossy_c0_at`).
    glossy: bool,
    glossy_c0_at: usize,
    /// The map size the tables were made for.
    map_size: (usize, usize),
    needs_open_sky: bool,
    block: EnvBlock,
}

impl EnvironmentStage {
    /// The kernels writing `C1`, `C2` and the open sky (when `needs_open_sky`) at `targets`.
    pub(super) fn new(
        ctx: &GpuContext,
        targets: LightTargets,
        needs_open_sky: bool,
    ) -> Result<EnvironmentStage, GpuError> {
        // The shader's constants: a 64-cube and a 32-cube source and table.
        if DIRECT_CUBE != 64
            || T1_LIGHT_CUBE != 8
            || T2_LIGHT_CUBE != 2
            || IRRADIANCE_CUBE != 32
            || IRRADIANCE_SOURCE != 32
        {
            return Err(GpuError::Unsupported(
                "the environment kernels are written for light cubes of 6x64x64, 6x8x8 and \
                 6x2x2 and 6x32x32 open-sky tables"
                    .into(),
            ));
        }
        let device = &ctx.device;
        let program = ComputeProgram::new(
            device,
            "prt-gpu environment",
            concat!(
                include_str!("../shaders/latlong.wgsl"),
                include_str!("../shaders/environment.wgsl")
            ),
            &[
                Binding::Uniform,
                Binding::Read,
                Binding::Read,
                Binding::Write,
                Binding::Write,
            ],
        );
        let pipeline = |entry: &str| program.pipeline(device, entry);
        let source_at = cube_len(DIRECT_CUBE);
        let cube = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("prt-gpu light cube"),
            size: 16 * (source_at + cube_len(IRRADIANCE_SOURCE)) as u64,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let block_buffer = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: std::mem::size_of::<EnvBlock>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let uniform = block_buffer("prt-gpu environment block");
        let glossy_uniform = block_buffer("prt-gpu environment block, glossy rows");
        Ok(EnvironmentStage {
            resample: pipeline("resample"),
            haar: pipeline("haar"),
            coarse: pipeline("coarse"),
            open_sky: pipeline("open_sky"),
            program,
            uniform,
            glossy_uniform,
            tables: None,
            cube,
            bind: None,
            glossy_bind: None,
            glossy: false,
            glossy_c0_at: targets.glossy_c0_at,
            map_size: (0, 0),
            needs_open_sky,
            block: EnvBlock {
                c1_at: targets.c1_at as u32,
                c2_at: targets.c2_at as u32,
                open_sky_at: targets.open_sky_at as u32,
                source_at: source_at as u32,
                ..Default::default()
            },
        })
    }

    /// Sets the map (`map`: its texels, `width` x `height`; from float `glossy_at` on, the
    /// map less its compact lights when it has any) and rotation for the next
    /// [`EnvironmentStage::encode`]; `rebind`: the map's or the light's buffer was made anew.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn set(
        &mut self,
        ctx: &GpuContext,
        map: &wgpu::Buffer,
        (width, height): (usize, usize),
        rotation_deg: f32,
        glossy_at: Option<usize>,
        light: &wgpu::Buffer,
        rebind: bool,
    ) -> Result<(), GpuError> {
        if width == 0 || height == 0 {
            return Err(GpuError::Unsupported("an empty environment map".into()));
        }
        if self.map_size != (width, height) || self.tables.is_none() {
            let m = subsamples_per_texel(DIRECT_CUBE, width, height);
            let ns = DIRECT_CUBE * m;
            let mut tables: Vec<f32> = Vec::new();
            let b = &mut self.block;
            b.m = m as u32;
            b.ns = ns as u32;
            b.weights_at = 0;
            // Per sub-sample: its solid angle and its direction's lat-long coordinates
            // (`prt_formats::latlong::direction_to_uv`, in f64).
            let weights = face_solid_angles(ns);
            let centre = |k: usize| 2.0 * (k as f64 + 0.5) / ns as f64 - 1.0;
            for face in Face::ALL {
                for l in 0..ns {
                    for k in 0..ns {
                        let d = face_ab_to_vector(face, centre(k), centre(l));
                        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                        let theta = (d[1] / len).clamp(-1.0, 1.0).acos();
                        let phi = d[0].atan2(-d[2]);
                        let u = (phi / std::f64::consts::TAU + 0.5).rem_euclid(1.0);
                        let v = (theta / std::f64::consts::PI).clamp(0.0, 1.0);
                        tables.extend([weights[l * ns + k] as f32, u as f32, v as f32]);
                    }
                }
            }
            let omega = face_solid_angles(DIRECT_CUBE);
            b.sqrt_omega_at = tables.len() as u32;
            tables.extend(omega.iter().map(|&w| w.sqrt() as f32));
            b.omega_at = tables.len() as u32;
            tables.extend(omega.iter().map(|&w| w as f32));
            b.omega32_at = tables.len() as u32;
            tables.extend(
                face_solid_angles(IRRADIANCE_SOURCE)
                    .iter()
                    .map(|&w| w as f32),
            );
            b.dirs32_at = tables.len() as u32;
            let n = IRRADIANCE_SOURCE;
            for face in Face::ALL {
                for j in 0..n {
                    for i in 0..n {
                        let d = texel_centre_direction(n, face, i, j);
                        tables.extend([d[0] as f32, d[1] as f32, d[2] as f32, 0.0]);
                    }
                }
            }
            crate::buffers::check_binding(
                ctx,
                "the environment's tables",
                4 * tables.len() as u64,
            )?;
            self.tables = Some(crate::buffers::upload(
                ctx,
                "prt-gpu environment tables",
                bytemuck::cast_slice(&tables),
                wgpu::BufferUsages::STORAGE,
            )?);
            self.map_size = (width, height);
            self.bind = None;
        }
        if rebind {
            self.bind = None;
            self.glossy_bind = None;
        }
        if self.bind.is_none() || self.glossy_bind.is_none() {
            let Some(tables) = &self.tables else {
                return Err(GpuError::Unsupported("no environment tables".into()));
            };
            self.bind = Some(self.program.bind_group(
                &ctx.device,
                "prt-gpu environment",
                &[&self.uniform, map, tables, &self.cube, light],
            ));
            self.glossy_bind = Some(self.program.bind_group(
                &ctx.device,
                "prt-gpu environment, glossy rows",
                &[&self.glossy_uniform, map, tables, &self.cube, light],
            ));
        }
        self.block.turns = (f64::from(rotation_deg) / 360.0).rem_euclid(1.0) as f32;
        self.block.env_width = width as u32;
        self.block.env_height = height as u32;
        self.block.map_at = 0;
        self.block.c0_at = 0;
        ctx.queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&self.block));
        self.glossy = glossy_at.is_some();
        let to_u32 = |v: usize| {
            u32::try_from(v).map_err(|_| {
                GpuError::Unsupported("the map less its compact lights lies too far".into())
            })
        };
        let glossy = EnvBlock {
            map_at: to_u32(glossy_at.unwrap_or(0))?,
            c0_at: to_u32(self.glossy_c0_at)?,
            ..self.block
        };
        ctx.queue
            .write_buffer(&self.glossy_uniform, 0, bytemuck::bytes_of(&glossy));
        Ok(())
    }

    /// Records the kernels (after [`EnvironmentStage::set`]).
    pub(super) fn encode(&self, encoder: &mut wgpu::CommandEncoder) {
        let (Some(bind), Some(glossy_bind)) = (&self.bind, &self.glossy_bind) else {
            return;
        };
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("prt-gpu environment"),
            timestamp_writes: None,
        });
        let texels = cube_len(DIRECT_CUBE) as u32;
        if self.glossy {
            // The map less its compact lights first: the cube is then made again of the map,
            // which the coarse cubes and the open sky read.
            pass.set_bind_group(0, glossy_bind, &[]);
            for pipeline in [&self.resample, &self.haar] {
                pass.set_pipeline(pipeline);
                pass.dispatch_workgroups(texels.div_ceil(WORKGROUP), 1, 1);
            }
        }
        pass.set_bind_group(0, bind, &[]);
        for pipeline in [&self.resample, &self.haar] {
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(texels.div_ceil(WORKGROUP), 1, 1);
        }
        if !self.glossy {
            // Without compact lights the glossy rows read the map's own C0: the same cube's
            // coefficients written again where they look (a buffer cannot be copied into
            // itself).
            pass.set_bind_group(0, glossy_bind, &[]);
            pass.set_pipeline(&self.haar);
            pass.dispatch_workgroups(texels.div_ceil(WORKGROUP), 1, 1);
            pass.set_bind_group(0, bind, &[]);
        }
        let source = cube_len(IRRADIANCE_SOURCE) as u32;
        let mut kernels = vec![(
            &self.coarse,
            (cube_len(T1_LIGHT_CUBE) + cube_len(T2_LIGHT_CUBE)) as u32 + source,
        )];
        if self.needs_open_sky {
            kernels.push((&self.open_sky, cube_len(IRRADIANCE_CUBE) as u32));
        }
        for (pipeline, n) in kernels {
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(n.div_ceil(WORKGROUP), 1, 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::context::GpuOptions;
    use crate::readback::Readback;
    use prt_formats::lighting::irradiance::irradiance_table;
    use prt_formats::lighting::{CubeMap, HaarCube};

    /// The environment kernels against `prt_formats`' own definitions (what the CPU runtime's
    /// light stage computes): the turned cube's Haar coefficients, the coarse cubes and the
    /// open sky, each within 1e-5 of its part's largest value (measured: at most 1.2e-6).
    #[test]
    fn the_kernels_equal_the_cpu_light_coefficients() {
        let ctx = match GpuContext::new(&GpuOptions::default()) {
            Ok(c) => c,
            Err(e) if std::env::var("PRT_SKIP_GPU").as_deref() == Ok("1") => {
                eprintln!("SKIPPED: GPU environment kernels (PRT_SKIP_GPU=1): {e}");
                return;
            }
            Err(e) => panic!("{e}\n(PRT_SKIP_GPU=1 skips the GPU tests)"),
        };
        // A sky with a gradient, a band and a bright spot, 96 x 48 and 300 x 150 (one and
        // several sub-samples per cube texel).
        for (w, h) in [(96usize, 48usize), (300, 150)] {
            let texels: Vec<[f32; 3]> = (0..w * h)
                .map(|k| {
                    let (x, y) = ((k % w) as f32 / w as f32, (k / w) as f32 / h as f32);
                    let base = 0.5 + 0.8 * x + 0.6 * (1.0 - y) + 0.3 * (9.0 * x + 2.0 * y).sin();
                    let spot = if (0.6..0.7).contains(&x) && (0.25..0.35).contains(&y) {
                        20.0
                    } else {
                        0.0
                    };
                    [base + spot, 0.8 * base, 1.2 * base + 0.1 * spot]
                })
                .collect();
            for rotation in [0.0f32, 70.0] {
                let cube = CubeMap::from_latlong(&texels, w, h, DIRECT_CUBE, f64::from(rotation))
                    .expect("cube");
                let haar = HaarCube::new(DIRECT_CUBE)
                    .expect("haar")
                    .forward_cube(&cube)
                    .expect("coefficients");
                let mut c1 = cube.downsample().expect("32");
                let source = c1.clone();
                while c1.size() > T1_LIGHT_CUBE {
                    c1 = c1.downsample().expect("coarser");
                }
                let c2 = c1.downsample().expect("4").downsample().expect("2");
                let open = irradiance_table(&cube).expect("open sky");
                assert_eq!(source.size(), IRRADIANCE_SOURCE);

                let (c1_at, c2_at) = (cube_len(DIRECT_CUBE), cube_len(DIRECT_CUBE) + 384);
                let open_sky_at = c2_at + 24;
                let len = open_sky_at + cube_len(IRRADIANCE_CUBE) + cube_len(DIRECT_CUBE);
                let light = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: None,
                    size: 16 * len as u64,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                let flat: Vec<f32> = texels.iter().flatten().copied().collect();
                let map = crate::buffers::upload(
                    &ctx,
                    "map",
                    bytemuck::cast_slice(&flat),
                    wgpu::BufferUsages::STORAGE,
                )
                .expect("map");
                let targets = LightTargets {
                    c1_at,
                    c2_at,
                    open_sky_at,
                    glossy_c0_at: open_sky_at + cube_len(IRRADIANCE_CUBE),
                };
                let mut stage = EnvironmentStage::new(&ctx, targets, true).expect("kernels");
                stage
                    .set(&ctx, &map, (w, h), rotation, None, &light, false)
                    .expect("set");
                let readback = Readback::new(&ctx, 16 * len as u64);
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                stage.encode(&mut encoder);
                encoder.copy_buffer_to_buffer(&light, 0, &readback.buffer, 0, 16 * len as u64);
                ctx.queue.submit([encoder.finish()]);
                let mut got = vec![[0.0f32; 4]; len];
                readback
                    .read(&ctx, |bytes| {
                        got.copy_from_slice(bytemuck::cast_slice(bytes));
                    })
                    .expect("read back");
                let check = |what: &str, at: usize, want: &[[f32; 3]], bound: f32| {
                    let peak = want.iter().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
                    let (worst, wk) = want
                        .iter()
                        .enumerate()
                        .flat_map(|(k, t)| (0..3).map(move |c| (k, c, t[c])))
                        .map(|(k, c, v)| ((got[at + k][c] - v).abs(), k))
                        .fold((0.0f32, 0), |m, x| if x.0 > m.0 { x } else { m });
                    eprintln!(
                        "{w}x{h}, turned {rotation}: {what}: {:.2e} of the peak (at {wk})",
                        worst / peak
                    );
                    assert!(
                        worst <= bound * peak,
                        "{w}x{h}, turned {rotation}: {what} {worst} off (peak {peak})"
                    );
                };
                let c0: Vec<[f32; 3]> = (0..haar[0].len())
                    .map(|k| [haar[0][k], haar[1][k], haar[2][k]])
                    .collect();
                check("C0", 0, &c0, 1e-5);
                check("C1", c1_at, c1.texels(), 1e-5);
                check("C2", c2_at, c2.texels(), 1e-5);
                check("open sky", open_sky_at, open.texels(), 1e-5);
                // No compact lights: the glossy rows read the map's own C0.
                let glossy_c0_at = open_sky_at + cube_len(IRRADIANCE_CUBE);
                check("the glossy rows' C0", glossy_c0_at, &c0, 1e-5);
            }
        }
    }
}
