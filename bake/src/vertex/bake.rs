//! The bake itself: every group's vertices traced in fixed blocks (rayon), each vertex's T0
//! rows Haar-truncated, the results placed by vertex index, each group converted to its
//! storage precision as soon as it is done (so only one group is ever held in f32), and the
//! metadata assembled (deterministic figures only; timings are returned beside it).

use std::time::Instant;

use glam::Vec3;
use prt_formats::basis::{BrdfBasis, ShadingBasis};
use prt_formats::pixel::CameraMeta;
use prt_formats::vertex::{
    shading_tables_mut, EnvironmentMeta, ShadingMeta, TextureMeta, VertexBakeMeta, VertexBakeStats,
    VertexGroupMeta, VERTEX_SCHEMA_VERSION,
};
use rayon::prelude::*;

use crate::integrator::Integrator;
use crate::progress::{Progress, Stage};
use crate::scene::{Environment, Scene};

use super::buffers::GroupBuffers;
use super::checkpoint::Checkpoint;
use super::compress::{compress_group, GroupShape};
use super::error::VertexError;
use super::plan::{persisted, VertexPlan, BLOCK_VERTICES};
use super::t0_choice::{choose_t0_terms, cut_rows, T0_ERROR_SHARE};
use super::trace::VertexTracer;
use super::write::{store, Stored};
use super::{MeshData, VertexBake, VertexBakeOptions, VertexGroupData};

/// Vertices whose results are gathered before being appended to their group's buffers: bounds
/// the memory of finished blocks while keeping both threads busy. Also the checkpoint's
/// granularity: a killed bake loses at most the wave it was tracing.
pub const WAVE_VERTICES: usize = 512;

/// Wall-clock figures of a per-vertex bake (not stored in the file).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct VertexTimings {
    /// The trace (T0, T1, T2 of every vertex; reading the checkpoint's waves instead when
    /// resuming), Haar truncation and conversion included, compression not.
    pub trace_seconds: f64,
    /// Clustering and compressing T1 and T2 (0 for a dense bake).
    pub compress_seconds: f64,
    /// The whole bake call.
    pub bake_seconds: f64,
    /// Vertices traced per second of tracing (those restored from a checkpoint left out).
    pub vertices_per_second: f64,
    /// Rays of the trace (not the pre-pass, nor those of restored vertices) per second of
    /// tracing.
    pub rays_per_second: f64,
}

/// Traces the vertices of `vertices` in order into buffers.
fn trace_block(tracer: &VertexTracer, vertices: &[u32]) -> Result<GroupBuffers, VertexError> {
    let mut out = GroupBuffers::default();
    for &v in vertices {
        let r = tracer.trace(v)?;
        let (index, value, total, dropped) = tracer.haar_terms(&r)?;
        out.t0_index.extend(index);
        out.t0_value.extend(value);
        out.visibility.extend(r.visibility_u8());
        out.t1.extend(r.t1);
        out.t2.extend(r.t2);
        out.rays += r.rays;
        out.t0_total += total;
        out.t0_dropped += dropped;
    }
    Ok(out)
}

/// Runs the bake of `plan` on the integrator it was planned with. `bases` are the PCA bases of
/// the plan's editable glossy families, `shading` the shading bases of its lobed groups
/// (others are ignored). `progress` advances once per block of vertices.
pub fn bake_vertex_with(
    integ: &Integrator,
    plan: &VertexPlan,
    bases: &[BrdfBasis],
    shading: &[ShadingBasis],
    opts: &VertexBakeOptions,
    progress: Option<&dyn Progress>,
) -> Result<VertexBake, VertexError> {
    bake_vertex_checkpointed(integ, plan, bases, shading, opts, None, progress)
}

/// [`bake_vertex_with`], saving each traced wave to `checkpoint` and taking the waves it
/// already holds from it instead of tracing them (the result is the same bytes). The
/// checkpoint must have been opened with this bake's [`Fingerprint`](super::Fingerprint).
pub fn bake_vertex_checkpointed(
    integ: &Integrator,
    plan: &VertexPlan,
    bases: &[BrdfBasis],
    shading: &[ShadingBasis],
    opts: &VertexBakeOptions,
    checkpoint: Option<&Checkpoint>,
    progress: Option<&dyn Progress>,
) -> Result<VertexBake, VertexError> {
    let start = Instant::now();
    opts.validate()?;
    let scene = integ.scene;
    let layout = plan.layout(bases)?;
    let tracer = VertexTracer::new(integ, plan, &layout, shading, opts)?;
    let used_shading: Vec<&ShadingBasis> = plan
        .shading_families()
        .iter()
        .filter_map(|f| shading.iter().find(|b| b.family == *f))
        .collect();

    let stage = Stage::start(progress, "baking vertices", plan.grouped_vertices() as u64);
    let mut groups = Vec::with_capacity(plan.groups.len());
    let mut groups_meta = Vec::with_capacity(plan.groups.len());
    let mut truncation = Vec::with_capacity(plan.groups.len());
    let mut rays = plan.prepass_rays;
    let mut trace_rays = 0u64;
    // Waves taken from the checkpoint: left out of the timings' rates.
    let (mut restored_vertices, mut restored_rays) = (0usize, 0u64);
    let mut compress_seconds = 0.0;
    for (gi, g) in plan.groups.iter().enumerate() {
        let mut buf = GroupBuffers::default();
        for (wi, wave) in g.vertices.chunks(WAVE_VERTICES).enumerate() {
            let blocks: Vec<GroupBuffers> = match checkpoint {
                Some(c) if c.has(gi, wi) => {
                    let blocks = c.load(gi, wi, wave)?;
                    stage.restored(wave.len() as u64);
                    restored_vertices += wave.len();
                    restored_rays += blocks.iter().map(|b| b.rays).sum::<u64>();
                    blocks
                }
                _ => {
                    let blocks: Vec<GroupBuffers> = wave
                        .par_chunks(BLOCK_VERTICES)
                        .map(|block| {
                            let b = trace_block(&tracer, block);
                            stage.advance(block.len() as u64);
                            b
                        })
                        .collect::<Result<_, _>>()?;
                    if let Some(c) = checkpoint {
                        c.save(gi, wi, wave, &blocks)?;
                    }
                    blocks
                }
            };
            for b in blocks {
                buf.append(b);
            }
        }
        trace_rays += buf.rays;
        // With compression on, T0 keeps the fewest Haar terms meeting its share of the error
        // target (`t0_choice.rs`); off, every row keeps the `t0_terms` the trace kept.
        let (t0_terms, t0_note) = match &opts.compression {
            Some(settings) => {
                let target = settings.error_target * T0_ERROR_SHARE;
                let choice = choose_t0_terms(&buf.t0_value, opts.t0_terms, f64::from(target));
                cut_rows(
                    &mut buf.t0_index,
                    &mut buf.t0_value,
                    opts.t0_terms,
                    choice.terms,
                );
                buf.t0_dropped += choice.cut;
                let note = format!(
                    "T0 {} of {} Haar terms per row (error {:.2} % against the {} terms, \
                     target {:.2} %)",
                    choice.terms,
                    opts.t0_terms,
                    100.0 * choice.error(),
                    opts.t0_terms,
                    100.0 * target
                );
                (Some(choice.terms as u32), note)
            }
            None => (None, String::new()),
        };
        truncation.push(if buf.t0_total > 0.0 {
            (buf.t0_dropped / buf.t0_total).sqrt() as f32
        } else {
            0.0
        });
        let (t0_value, scale_t0) = store(std::mem::take(&mut buf.t0_value), opts.precision);
        let (t1, t2, scale_t1, scale_t2, compression, compressed) = match &opts.compression {
            None => {
                let (t1, scale_t1) = store(std::mem::take(&mut buf.t1), opts.precision);
                let (t2, scale_t2) = store(std::mem::take(&mut buf.t2), opts.precision);
                (t1, t2, scale_t1, scale_t2, None, None)
            }
            Some(settings) => {
                let shape = GroupShape {
                    active: g.active.len(),
                    t2_slots: plan.t2_slots.len(),
                    channels: plan.slots.channels,
                    reflections: opts.reflections,
                };
                let compress_start = Instant::now();
                let c = compress_group(
                    scene,
                    &plan.normals,
                    &g.vertices,
                    &buf.t1,
                    &buf.t2,
                    shape,
                    settings,
                    opts.precision,
                )?;
                compress_seconds += compress_start.elapsed().as_secs_f64();
                // The candidates borrowed the f32 tensors; free them before the next group.
                buf.t1 = Vec::new();
                buf.t2 = Vec::new();
                if let Some(p) = progress {
                    p.note(&format!(
                        "compressed {}: {t0_note}; {}",
                        scene.materials[g.material as usize].name, c.summary
                    ));
                }
                (
                    Stored::F32(Vec::new()),
                    Stored::F32(Vec::new()),
                    c.scale_t1,
                    c.scale_t2,
                    Some(c.meta),
                    Some(c.data),
                )
            }
        };
        let rows = tracer.group_shading(gi).map_or(1, |b| b.ranks.i + 1);
        groups_meta.push(VertexGroupMeta {
            material: g.material,
            vertices: g.vertices.len() as u32,
            t0_rows: rows as u32,
            shading: g.lobe.map(|f| {
                used_shading
                    .iter()
                    .position(|b| b.family == f)
                    .unwrap_or(usize::MAX) as u32
            }),
            active: g.active.clone(),
            scale_t0,
            scale_t1,
            scale_t2,
            compression,
            t0_terms,
        });
        groups.push(VertexGroupData {
            vertices: g.vertices.clone(),
            t0_index: buf.t0_index,
            t0_value,
            // Only the specular lobes read the visibility (docs/vertex.md, section 3): a group
            // without one stores none.
            visibility: if g.lobe.is_some() {
                buf.visibility
            } else {
                Vec::new()
            },
            t1,
            t2,
            compressed,
        });
    }
    drop(stage);
    rays += trace_rays;
    let trace_seconds = start.elapsed().as_secs_f64() - compress_seconds;

    let (bases_meta, basis_tables) = persisted(&layout);
    let shading_meta = used_shading
        .iter()
        .map(|b| {
            let mut basis = (*b).clone();
            for (_, t) in shading_tables_mut(&mut basis) {
                t.clear();
            }
            ShadingMeta { basis }
        })
        .collect();
    let (textures_meta, material_textures, textures) = base_colour_textures(scene);
    let (environment_meta, environment) = environment(scene);
    let cam = &scene.camera;
    let meta = VertexBakeMeta {
        vertex_schema_version: VERTEX_SCHEMA_VERSION,
        vertices: scene.positions.len() as u32,
        triangles: scene.triangles.len() as u32,
        samples: opts.samples,
        secondary: opts.secondary,
        light_bins: opts.light_bins,
        reflections: opts.reflections,
        seed: opts.seed,
        channels: plan.slots.channels as u32,
        precision: opts.precision,
        t0_terms: opts.t0_terms as u32,
        materials: layout.materials.clone(),
        bases: bases_meta,
        shading: shading_meta,
        textures: textures_meta,
        material_textures,
        t2_slots: plan.t2_slots.clone(),
        groups: groups_meta,
        environment: environment_meta,
        camera: CameraMeta {
            position: cam.position.to_array(),
            forward: cam.forward.to_array(),
            up: cam.up.to_array(),
            yfov: cam.yfov,
        },
        stats: VertexBakeStats {
            rays,
            allocation: plan.slots.reasons.clone(),
            t0_truncation_error: truncation,
        },
        compression: opts.compression,
    };
    meta.validate().map_err(VertexError::Inconsistent)?;
    let traced_vertices = (plan.grouped_vertices() - restored_vertices) as f64;
    let traced_rays = (trace_rays - restored_rays) as f64;
    Ok(VertexBake {
        meta,
        timings: VertexTimings {
            trace_seconds,
            compress_seconds,
            bake_seconds: start.elapsed().as_secs_f64(),
            vertices_per_second: traced_vertices / trace_seconds.max(1e-9),
            rays_per_second: traced_rays / trace_seconds.max(1e-9),
        },
        groups,
        shading: used_shading.into_iter().cloned().collect(),
        basis_tables,
        mesh: mesh(scene, &plan.normals),
        environment,
        textures,
    })
}

/// The mesh tensors, flat; `normals` are the ones the vertices were baked with.
fn mesh(scene: &Scene, normals: &[Vec3]) -> MeshData {
    MeshData {
        positions: scene.positions.iter().flat_map(|p| p.to_array()).collect(),
        normals: normals.iter().flat_map(|n| n.to_array()).collect(),
        uvs: scene.uvs.iter().flat_map(|u| u.to_array()).collect(),
        triangles: scene.triangles.iter().flatten().copied().collect(),
        triangle_material: scene.triangle_material.clone(),
    }
}

/// The base-colour textures of the materials (each stored once, in order of first use), each
/// material's index into them, and their texels.
fn base_colour_textures(scene: &Scene) -> (Vec<TextureMeta>, Vec<Option<u32>>, Vec<Vec<f32>>) {
    let mut used: Vec<usize> = Vec::new();
    let material_textures = scene
        .materials
        .iter()
        .map(|m| {
            let t = m.base_color_texture?;
            scene.textures.get(t)?;
            Some(match used.iter().position(|&u| u == t) {
                Some(i) => i as u32,
                None => {
                    used.push(t);
                    (used.len() - 1) as u32
                }
            })
        })
        .collect();
    let meta = used
        .iter()
        .map(|&t| TextureMeta {
            width: scene.textures[t].width,
            height: scene.textures[t].height,
        })
        .collect();
    let texels = used
        .iter()
        .map(|&t| flat(&scene.textures[t].texels))
        .collect();
    (meta, material_textures, texels)
}

/// The scene's environment as stored, and the lat-long texels (empty for a constant one).
fn environment(scene: &Scene) -> (EnvironmentMeta, Vec<f32>) {
    match &scene.environment {
        Environment::Constant(c) => (
            EnvironmentMeta::Constant {
                radiance: c.to_array(),
            },
            Vec::new(),
        ),
        Environment::LatLong {
            width,
            height,
            texels,
        } => (
            EnvironmentMeta::LatLong {
                width: *width,
                height: *height,
                rotation_deg: scene.environment_rotation,
            },
            flat(texels),
        ),
    }
}

fn flat(texels: &[Vec3]) -> Vec<f32> {
    texels.iter().flat_map(|t| t.to_array()).collect()
}
