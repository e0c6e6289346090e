//! The per-vertex light and material stages on the device (`shaders/stages.wgsl`; docs/gpu.md,
//! "Per-vertex"): what the CPU runtime's `incident.rs` and `clustered.rs` do per vertex and per
//! cluster, as compute dispatches that write the vertex records the view stage reads.
//!
//! A light change runs `environment.rs`'s kernels (the turned cube, `C0`, `C1`, `C2`, the
//! open sky's table, into this module's light buffer) and then the vertex kernels here; a
//! material change uploads the slot coefficients (a few KB) and runs the material kernels.
//! Each group's stored tensors are uploaded once, as the file stores them (f16 two per word).

use prt_formats::lighting::cubemap::{bilinear_taps, direction_to_face_st};
use prt_formats::lighting::irradiance::IRRADIANCE_CUBE;
use prt_formats::lighting::sh::SH_COUNT;
use prt_formats::vertex::{cube_len, DIRECT_CUBE, T1_LIGHT_CUBE, T2_LIGHT_CUBE};
use prt_runtime::gpu_surface::{
    ClusteredTensor, StageGroup, StageTensor, StoredValues, VertexSurface, RECORD_U,
};

use super::environment::{EnvironmentStage, LightTargets};
use crate::buffers::{check_binding, storage_buffer, upload};
use crate::compute::{Binding, ComputeProgram};
use crate::context::GpuContext;
use crate::error::GpuError;

/// Invocations per workgroup of every kernel (`WORKGROUP` in the shader).
const WORKGROUP: u32 = 64;

/// "No such part" in the shader's offsets.
const NONE: u32 = u32::MAX;

/// `Tensor` in the shader.
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct TensorBlock {
    kind: u32,
    f16: u32,
    values_at: u32,
    core_at: u32,
    vertex_at: u32,
    table_at: u32,
    row_cluster_at: u32,
    clusters: u32,
    max_a: u32,
    max_r: u32,
    max_b: u32,
    vertex_rank: u32,
    elements: u32,
    bins: u32,
    light_at: u32,
    scale: f32,
    p_at: u32,
    q_at: u32,
    s_at: u32,
    m_at: u32,
    rows: u32,
    pad: [u32; 3],
}

/// `Group` in the shader.
#[repr(C)]
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct GroupBlock {
    vertices: u32,
    rows: u32,
    terms: u32,
    t0_f16: u32,
    t0_index_at: u32,
    t0_values_at: u32,
    open_at: u32,
    t0dot_at: u32,
    scale_t0: f32,
    channels: u32,
    j: u32,
    n_i: u32,
    coeff_at: u32,
    ci_at: u32,
    cluster_of_at: u32,
    stride: u32,
    record_at: u32,
    rank: u32,
    cwi_at: u32,
    cconst_at: u32,
    ehat_at: u32,
    which: u32,
    open_sky_at: u32,
    glossy_c0_at: u32,
    t: [TensorBlock; 2],
}

/// Where each group's records lie in the records buffer: `(first float, floats per vertex)`.
pub(super) fn record_layout(
    s: &VertexSurface,
    groups: &[StageGroup],
) -> Result<Vec<(usize, usize)>, GpuError> {
    let mut at = 0usize;
    let mut out = Vec::with_capacity(groups.len());
    for (g, group) in groups.iter().enumerate() {
        let rank = match group.shading {
            Some(b) => {
                s.shading_constants(b)
                    .ok_or_else(|| {
                        GpuError::Unsupported(format!("group {g}: no shading basis {b}"))
                    })?
                    .rank
            }
            None => 0,
        };
        let stride = RECORD_U + 3 * rank;
        out.push((at, stride));
        at += stride * group.vertices.len();
    }
    Ok(out)
}

/// The light buffer's parts, in entries (one RGB entry each).
struct LightLayout {
    c1_at: usize,
    c2_at: usize,
    open_sky_at: usize,
    /// C0 of the map less its compact lights (the glossy rows').
    glossy_c0_at: usize,
    len: usize,
}

impl LightLayout {
    fn new() -> LightLayout {
        let c1_at = cube_len(DIRECT_CUBE);
        let c2_at = c1_at + cube_len(T1_LIGHT_CUBE);
        let open_sky_at = c2_at + cube_len(T2_LIGHT_CUBE);
        let glossy_c0_at = open_sky_at + cube_len(IRRADIANCE_CUBE);
        LightLayout {
            c1_at,
            c2_at,
            open_sky_at,
            glossy_c0_at,
            len: glossy_c0_at + cube_len(DIRECT_CUBE),
        }
    }
}

/// One tensor's dispatches: how many invocations each kernel runs.
#[derive(Clone, Copy, Default)]
struct TensorJob {
    /// Dense: `dense_light`'s invocations; clustered: `cluster_p`, `cluster_q`, `cluster_s`.
    light: [u32; 3],
    /// Clustered: `cluster_m`'s.
    material: u32,
    clustered: bool,
}

/// One group's device state.
struct GroupJob {
    /// Bind groups with `which` 0 (T1) and 1 (T2).
    bind: [wgpu::BindGroup; 2],
    t0_invocations: u32,
    vertices: u32,
    tensors: [Option<TensorJob>; 2],
    /// Global slots of J, and where the group's coefficients start in `coeff`.
    active: Vec<u32>,
    coeff_at: usize,
}

/// The stages' pipelines and buffers (see the module documentation).
pub(super) struct DeviceStages {
    t0_dot: wgpu::ComputePipeline,
    dense_light: wgpu::ComputePipeline,
    cluster_p: wgpu::ComputePipeline,
    cluster_q: wgpu::ComputePipeline,
    cluster_s: wgpu::ComputePipeline,
    cluster_m: wgpu::ComputePipeline,
    records_of: wgpu::ComputePipeline,
    light: wgpu::Buffer,
    coeff: wgpu::Buffer,
    groups: Vec<GroupJob>,
    t2_slots: Vec<u32>,
    ci_at: usize,
    layout: LightLayout,
    environment: EnvironmentStage,
    /// Host scratch of the uploads, kept between frames.
    coeff_data: Vec<[f32; 4]>,
}

/// A group's static data as 32-bit words, with the offsets of its parts.
#[derive(Default)]
struct Words(Vec<u32>);

impl Words {
    fn at(&self) -> Result<u32, GpuError> {
        u32::try_from(self.0.len()).map_err(|_| too_large("a group's stage data"))
    }

    fn f32s(&mut self, v: &[f32]) -> Result<u32, GpuError> {
        let at = self.at()?;
        self.0.extend(v.iter().map(|x| x.to_bits()));
        Ok(at)
    }

    fn u32s(&mut self, v: impl IntoIterator<Item = u32>) -> Result<u32, GpuError> {
        let at = self.at()?;
        self.0.extend(v);
        Ok(at)
    }

    /// 16-bit values, two per word, the first in the low half.
    fn u16s(&mut self, v: &[u16]) -> Result<u32, GpuError> {
        let at = self.at()?;
        self.0.extend(
            v.chunks(2)
                .map(|p| u32::from(p[0]) | (u32::from(p.get(1).copied().unwrap_or(0)) << 16)),
        );
        Ok(at)
    }

    fn stored(&mut self, v: StoredValues) -> Result<u32, GpuError> {
        match v {
            StoredValues::F32(x) => self.f32s(x),
            StoredValues::F16(x) => self.u16s(x),
        }
    }
}

fn too_large(what: &str) -> GpuError {
    GpuError::Limit {
        limit: "max_storage_buffer_binding_size",
        what: format!("{what} (32-bit offsets)"),
        needed: u64::from(u32::MAX) + 1,
        max: u64::from(u32::MAX),
    }
}

fn to_u32(x: usize, what: &str) -> Result<u32, GpuError> {
    u32::try_from(x).map_err(|_| too_large(what))
}

/// Floats of `work` handed out to the groups' intermediate results.
struct WorkLayout(usize);

impl WorkLayout {
    fn take(&mut self, floats: usize) -> Result<u32, GpuError> {
        let at = to_u32(self.0, "the stages' intermediate results")?;
        self.0 += floats;
        Ok(at)
    }
}

impl DeviceStages {
    /// Uploads what the stages read of every group of `s` (prepared with
    /// `VertexRelighter::prepare_device_stages`); `records` is where the view stage reads the
    /// records (laid out by [`record_layout`]). A part over the device's binding limit is
    /// refused with [`GpuError::Limit`] (the caller then runs the stages on the CPU).
    pub(super) fn new(
        ctx: &GpuContext,
        s: &VertexSurface,
        groups: &[StageGroup],
        records_layout: &[(usize, usize)],
        records: &wgpu::Buffer,
    ) -> Result<DeviceStages, GpuError> {
        let device = &ctx.device;
        let layout = LightLayout::new();
        let t2_slots = s.t2_slots().to_vec();
        let n_i = t2_slots.len();
        let ehat = s.irradiance_sh();
        let normals = s.normals();
        let mut work = WorkLayout(0);
        let mut coeff_len = 0usize;
        let mut blocks = Vec::with_capacity(groups.len());
        let mut datas = Vec::with_capacity(groups.len());
        let mut jobs = Vec::with_capacity(groups.len());
        for (g, (group, &(record_at, stride))) in groups.iter().zip(records_layout).enumerate() {
            let nv = group.vertices.len();
            let mut data = Words::default();
            let mut block = GroupBlock {
                vertices: to_u32(nv, "a group's vertices")?,
                rows: to_u32(group.rows, "T0's rows")?,
                terms: to_u32(group.terms, "T0's terms")?,
                t0_f16: u32::from(group.t0_values.is_f16()),
                scale_t0: group.scales[0],
                channels: to_u32(group.channels, "channels")?,
                j: to_u32(group.active.len(), "active slots")?,
                n_i: to_u32(n_i, "T2's slots")?,
                coeff_at: to_u32(coeff_len, "slot coefficients")?,
                stride: to_u32(stride, "a record")?,
                record_at: to_u32(record_at, "the vertex records")?,
                open_sky_at: to_u32(layout.open_sky_at, "the light")?,
                glossy_c0_at: to_u32(layout.glossy_c0_at, "the light")?,
                open_at: NONE,
                cluster_of_at: NONE,
                ..Default::default()
            };
            coeff_len += group.active.len();
            let t0_len = nv * group.rows * group.terms;
            if group.t0_index.len() != t0_len || group.t0_values.len() != t0_len {
                return Err(GpuError::Unsupported(format!(
                    "group {g}: T0 holds {} indices and {} values, expected {t0_len}",
                    group.t0_index.len(),
                    group.t0_values.len()
                )));
            }
            block.t0_index_at = data.u16s(group.t0_index)?;
            block.t0_values_at = data.stored(group.t0_values)?;
            if group.t0_open.contains(&true) {
                let mut taps = Vec::with_capacity(9 * nv);
                for (v, &global) in group.vertices.iter().enumerate() {
                    let open = group.t0_open.get(v).copied().unwrap_or(false);
                    taps.push(u32::from(open));
                    let n = normals
                        .get(global as usize)
                        .copied()
                        .unwrap_or([0.0, 0.0, 1.0])
                        .map(f64::from);
                    let (face, u, w) = direction_to_face_st(n);
                    for (texel, weight) in bilinear_taps(IRRADIANCE_CUBE, face, u, w) {
                        taps.push(texel as u32);
                        taps.push((weight as f32).to_bits());
                    }
                }
                block.open_at = data.u32s(taps)?;
            }
            block.t0dot_at = work.take(3 * nv * group.rows)?;
            if let Some(b) = group.shading {
                let c = s.shading_constants(b).ok_or_else(|| {
                    GpuError::Unsupported(format!("group {g}: no shading basis {b}"))
                })?;
                block.rank = to_u32(c.rank, "a shading rank")?;
                block.cwi_at = data.f32s(c.cwi)?;
                block.cconst_at = data.f32s(c.cconst)?;
            }
            block.ehat_at = data.f32s(&ehat)?;
            let mut tensor_jobs = [None, None];
            let tensors = [Some(&group.t1), group.t2.as_ref()];
            for (which, tensor) in tensors.into_iter().enumerate() {
                let Some(tensor) = tensor else { continue };
                let (bins, light_at) = if which == 0 {
                    (cube_len(T1_LIGHT_CUBE), layout.c1_at)
                } else {
                    (cube_len(T2_LIGHT_CUBE), layout.c2_at)
                };
                let elements = group.elements[which];
                let mut t = TensorBlock {
                    elements: to_u32(elements, "a tensor's elements")?,
                    bins: bins as u32,
                    light_at: light_at as u32,
                    scale: group.scales[1 + which],
                    ..Default::default()
                };
                let job = match tensor {
                    StageTensor::Dense(values) => {
                        let want = nv * bins * elements * group.channels;
                        if values.len() != want {
                            return Err(GpuError::Unsupported(format!(
                                "group {g}: a dense tensor holds {} values, expected {want}",
                                values.len()
                            )));
                        }
                        t.kind = 1;
                        t.f16 = u32::from(values.is_f16());
                        t.values_at = data.stored(*values)?;
                        t.s_at = work.take(3 * nv * elements)?;
                        TensorJob {
                            light: [to_u32(nv * elements, "a dense contraction")?, 0, 0],
                            material: 0,
                            clustered: false,
                        }
                    }
                    StageTensor::Clustered(c) => {
                        t.kind = 2;
                        let clusters = group.clusters.ok_or_else(|| {
                            GpuError::Unsupported(format!(
                                "group {g}: a compressed tensor without clusters"
                            ))
                        })?;
                        if block.cluster_of_at == NONE {
                            block.cluster_of_at = data.u32s(clusters.iter().copied())?;
                        }
                        clustered_tensor(&mut t, &mut data, &mut work, c, elements, which)?
                    }
                };
                block.t[which] = t;
                tensor_jobs[which] = Some(job);
            }
            check_binding(ctx, "a group's stage data", 4 * data.0.len() as u64)?;
            blocks.push(block);
            datas.push(data);
            jobs.push((
                tensor_jobs,
                group.active.to_vec(),
                nv * group.rows,
                nv,
                coeff_len - group.active.len(),
            ));
        }
        let ci_at = coeff_len;
        for b in &mut blocks {
            b.ci_at = to_u32(ci_at, "slot coefficients")?;
        }
        let work_bytes = 4 * work.0.max(1) as u64;
        check_binding(ctx, "the stages' intermediate results", work_bytes)?;
        let work = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("prt-gpu stage results"),
            size: work_bytes,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let light = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("prt-gpu light coefficients"),
            size: 16 * layout.len as u64,
            // COPY_SRC: the open sky's table is copied into the view stage's cube texture.
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let environment = EnvironmentStage::new(
            ctx,
            LightTargets {
                c1_at: layout.c1_at,
                c2_at: layout.c2_at,
                open_sky_at: layout.open_sky_at,
                glossy_c0_at: layout.glossy_c0_at,
            },
            s.needs_open_sky(),
        )?;
        let coeff = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("prt-gpu slot coefficients"),
            size: 16 * (coeff_len + n_i).max(1) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let program = ComputeProgram::new(
            device,
            "prt-gpu stages",
            include_str!("../shaders/stages.wgsl"),
            &[
                Binding::Uniform,
                Binding::Read,
                Binding::Read,
                Binding::Read,
                Binding::Write,
                Binding::Write,
            ],
        );
        let pipeline = |entry: &str| program.pipeline(device, entry);
        let mut group_jobs = Vec::with_capacity(groups.len());
        for ((block, data), (tensors, active, t0, nv, coeff_at)) in
            blocks.iter().zip(&datas).zip(jobs)
        {
            let data = storage_buffer(ctx, "a group's stage data", bytemuck::cast_slice(&data.0))?;
            let bind = [0u32, 1].map(|which| {
                let uniform = upload(
                    ctx,
                    "prt-gpu stage group",
                    bytemuck::bytes_of(&GroupBlock { which, ..*block }),
                    wgpu::BufferUsages::UNIFORM,
                );
                uniform.map(|u| {
                    program.bind_group(
                        device,
                        "prt-gpu stage group",
                        &[&u, &light, &coeff, &data, &work, records],
                    )
                })
            });
            let [b0, b1] = bind;
            group_jobs.push(GroupJob {
                bind: [b0?, b1?],
                t0_invocations: to_u32(t0, "T0's rows")?,
                vertices: to_u32(nv, "a group's vertices")?,
                tensors,
                active,
                coeff_at,
            });
        }
        Ok(DeviceStages {
            t0_dot: pipeline("t0_dot"),
            dense_light: pipeline("dense_light"),
            cluster_p: pipeline("cluster_p"),
            cluster_q: pipeline("cluster_q"),
            cluster_s: pipeline("cluster_s"),
            cluster_m: pipeline("cluster_m"),
            records_of: pipeline("records_of"),
            light,
            coeff,
            groups: group_jobs,
            t2_slots,
            ci_at,
            layout,
            environment,
            coeff_data: Vec::new(),
        })
    }

    /// Sets the lighting map (`map`, its texels, `size` its width and height) and rotation
    /// the next [`DeviceStages::encode_light`] runs the light stage for, with `glossy_at`
    /// where in `map` (floats) the map less its compact lights lies when it has any;
    /// `rebind`: the map's buffer was made anew.
    pub(super) fn set_light(
        &mut self,
        ctx: &GpuContext,
        map: &wgpu::Buffer,
        size: (usize, usize),
        rotation_deg: f32,
        glossy_at: Option<usize>,
        rebind: bool,
    ) -> Result<(), GpuError> {
        self.environment
            .set(ctx, map, size, rotation_deg, glossy_at, &self.light, rebind)
    }

    /// Records copying the open sky's table into layers `layer ..= layer + 5` of `cubes` (the
    /// view stage's cube texture), after [`DeviceStages::encode_light`].
    pub(super) fn encode_open_sky_copy(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        cubes: &wgpu::Texture,
        layer: u32,
    ) {
        let n = IRRADIANCE_CUBE as u32;
        encoder.copy_buffer_to_texture(
            wgpu::TexelCopyBufferInfo {
                buffer: &self.light,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 16 * self.layout.open_sky_at as u64,
                    bytes_per_row: Some(16 * n),
                    rows_per_image: Some(n),
                },
            },
            wgpu::TexelCopyTextureInfo {
                texture: cubes,
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: 0,
                    y: 0,
                    z: layer,
                },
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::Extent3d {
                width: n,
                height: n,
                depth_or_array_layers: 6,
            },
        );
    }

    /// Uploads the slot coefficients of the current materials.
    pub(super) fn write_coefficients(&mut self, ctx: &GpuContext, s: &VertexSurface) {
        let slots = s.slot_coefficients();
        let slot = |j: u32| {
            let c = slots.get(j as usize).copied().unwrap_or([0.0; 3]);
            [c[0], c[1], c[2], 0.0]
        };
        let d = &mut self.coeff_data;
        d.clear();
        for job in &self.groups {
            debug_assert_eq!(d.len(), job.coeff_at);
            d.extend(job.active.iter().map(|&j| slot(j)));
        }
        debug_assert_eq!(d.len(), self.ci_at);
        d.extend(self.t2_slots.iter().map(|&i| slot(i)));
        if !d.is_empty() {
            ctx.queue
                .write_buffer(&self.coeff, 0, bytemuck::cast_slice(&self.coeff_data));
        }
    }

    /// Records the light stage's dispatches (after [`DeviceStages::set_light`]): the
    /// environment's kernels, then the vertices'.
    pub(super) fn encode_light(&self, encoder: &mut wgpu::CommandEncoder, ctx: &GpuContext) {
        self.environment.encode(encoder);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("prt-gpu light stage"),
            timestamp_writes: None,
        });
        for job in &self.groups {
            dispatch(
                &mut pass,
                ctx,
                &self.t0_dot,
                &job.bind[0],
                job.t0_invocations,
            );
            for (which, t) in job.tensors.iter().enumerate() {
                let Some(t) = t else { continue };
                if t.clustered {
                    for (pipeline, n) in [&self.cluster_p, &self.cluster_q, &self.cluster_s]
                        .into_iter()
                        .zip(t.light)
                    {
                        dispatch(&mut pass, ctx, pipeline, &job.bind[which], n);
                    }
                } else {
                    dispatch(
                        &mut pass,
                        ctx,
                        &self.dense_light,
                        &job.bind[which],
                        t.light[0],
                    );
                }
            }
        }
    }

    /// Records the material stage's dispatches (after [`DeviceStages::write_coefficients`]
    /// and, when the light changed, [`DeviceStages::encode_light`]).
    pub(super) fn encode_material(&self, encoder: &mut wgpu::CommandEncoder, ctx: &GpuContext) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("prt-gpu material stage"),
            timestamp_writes: None,
        });
        for job in &self.groups {
            for (which, t) in job.tensors.iter().enumerate() {
                if let Some(t) = t.filter(|t| t.clustered) {
                    dispatch(
                        &mut pass,
                        ctx,
                        &self.cluster_m,
                        &job.bind[which],
                        t.material,
                    );
                }
            }
            dispatch(&mut pass, ctx, &self.records_of, &job.bind[0], job.vertices);
        }
    }
}

/// A compressed tensor's part of the group data and the intermediate results it needs.
fn clustered_tensor(
    t: &mut TensorBlock,
    data: &mut Words,
    work: &mut WorkLayout,
    c: &ClusteredTensor,
    elements: usize,
    which: usize,
) -> Result<TensorJob, GpuError> {
    let k = c.ranks.len();
    if c.factor_at.len() != k || c.core_at.len() != k || c.rows_at.len() != k {
        return Err(GpuError::Unsupported(
            "a compressed tensor's tables differ in length".into(),
        ));
    }
    let max = |i: usize| c.ranks.iter().map(|r| r[i]).max().unwrap_or(0);
    let (max_a, max_r, max_b) = (max(0), max(1), max(2));
    t.values_at = data.f32s(c.factors)?;
    t.core_at = data.f32s(c.core)?;
    t.vertex_at = data.f32s(c.vertex)?;
    let mut table = Vec::with_capacity(6 * k);
    for i in 0..k {
        let [a, r, b] = c.ranks[i];
        for x in [a, r, b, c.factor_at[i], c.core_at[i], c.rows_at[i]] {
            table.push(to_u32(x, "a compressed tensor's tables")?);
        }
    }
    t.table_at = data.u32s(table)?;
    let mut row_cluster = Vec::with_capacity(c.rows);
    for (i, r) in c.ranks.iter().enumerate() {
        row_cluster.extend(std::iter::repeat_n(i as u32, r[2]));
    }
    if row_cluster.len() != c.rows {
        return Err(GpuError::Unsupported(format!(
            "a compressed tensor has {} rows, its ranks add to {}",
            c.rows,
            row_cluster.len()
        )));
    }
    t.row_cluster_at = data.u32s(row_cluster)?;
    t.clusters = to_u32(k, "clusters")?;
    t.max_a = to_u32(max_a, "a light rank")?;
    t.max_r = to_u32(max_r, "an element rank")?;
    t.max_b = to_u32(max_b, "a vertex rank")?;
    t.vertex_rank = to_u32(c.vertex_rank, "a vertex rank")?;
    t.rows = to_u32(c.rows, "a compressed tensor's rows")?;
    t.p_at = work.take(3 * k * max_a)?;
    t.q_at = work.take(3 * k * max_b * max_r)?;
    t.s_at = work.take(3 * c.rows * elements)?;
    let per = if which == 0 { SH_COUNT } else { 1 };
    t.m_at = work.take(3 * c.rows * per)?;
    Ok(TensorJob {
        light: [
            to_u32(k * max_a, "a compressed contraction")?,
            to_u32(k * max_b * max_r, "a compressed contraction")?,
            to_u32(c.rows * elements, "a compressed contraction")?,
        ],
        material: to_u32(c.rows * per, "a compressed contraction")?,
        clustered: true,
    })
}

/// Dispatches `invocations` of `pipeline` (nothing for none): workgroups in rows of at most
/// the device's per-dimension limit.
fn dispatch(
    pass: &mut wgpu::ComputePass,
    ctx: &GpuContext,
    pipeline: &wgpu::ComputePipeline,
    bind: &wgpu::BindGroup,
    invocations: u32,
) {
    if invocations == 0 {
        return;
    }
    let groups = invocations.div_ceil(WORKGROUP);
    let max = ctx.limits().max_compute_workgroups_per_dimension.max(1);
    let x = groups.min(max);
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind, &[]);
    pass.dispatch_workgroups(x, groups.div_ceil(x), 1);
}
