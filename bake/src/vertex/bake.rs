//! The per-vertex bake, unit by unit (docs/vertex.md, "Bounded memory"): batches of units
//! traced over all threads, each unit then compressed and saved as a piece
//! ([`PieceStore`]); the file assembled from the pieces (`assemble.rs`). Only the units in
//! flight are ever held: the batch is as many units as fit [`BATCH_BYTES`] (at least one, at
//! most one per thread), so memory does not grow with the vertex count.
//!
//! What is known before tracing (the metadata but for the figures the pieces add up, the mesh,
//! the environment, the bases) is the bake's common part ([`vertex_common`]): a shard file
//! carries it, so shards merge without the scene.

use std::borrow::Cow;
use std::time::Instant;

use glam::Vec3;
use prt_formats::basis::{BrdfBasis, ShadingBasis};
use prt_formats::pixel::CameraMeta;
use prt_formats::vertex::{
    names, shading_tables, shading_tables_mut, EnvironmentMeta, ShadingMeta, TextureMeta,
    VertexBakeMeta, VertexBakeStats, VertexGroupMeta, VERTEX_SCHEMA_VERSION,
};
use prt_formats::Dtype;
use rayon::prelude::*;

use crate::integrator::Integrator;
use crate::progress::{Progress, Stage};
use crate::scene::{Environment, Scene};
use crate::shard::{CommonTensor, PieceStore};

use super::assemble::VertexCommon;
use super::error::VertexError;
use super::plan::{persisted, VertexPlan};
use super::trace::VertexTracer;
use super::unit::{finish_unit, trace_units, traced_from_piece, traced_piece, TracedUnit};
use super::units::Unit;
use super::VertexBakeOptions;

/// Bytes of dense unit tensors held at once: units in flight are as many as fit (at least
/// one). Bounds the bake's working memory whatever the vertex count (docs/vertex.md).
pub const BATCH_BYTES: u64 = 1 << 30;

/// Wall-clock figures of a per-vertex bake (not stored in the file).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct VertexTimings {
    /// Tracing the units (T0, T1, T2 of every vertex traced by this run), Haar truncation
    /// included, compression not.
    pub trace_seconds: f64,
    /// Compressing T1 and T2 unit by unit (0 for a dense bake).
    pub compress_seconds: f64,
    /// Writing the file from the pieces.
    pub write_seconds: f64,
    /// The whole bake call.
    pub bake_seconds: f64,
    /// Vertices traced per second of tracing (those restored from a checkpoint left out).
    pub vertices_per_second: f64,
    /// Rays of the trace (not the pre-pass, nor those of restored units) per second of
    /// tracing.
    pub rays_per_second: f64,
}

/// What [`bake_units`] did.
#[derive(Clone, Copy, Debug, Default)]
pub struct UnitsDone {
    /// Units traced (and compressed) by this run.
    pub traced: usize,
    /// Units compressed from their kept traced tensors.
    pub recompressed: usize,
    /// Units whose finished piece was already in the store.
    pub restored: usize,
    /// Vertices and rays traced by this run.
    pub traced_vertices: u64,
    pub traced_rays: u64,
    pub trace_seconds: f64,
    pub compress_seconds: f64,
}

/// Units in flight for `plan` and `opts`: as many as [`BATCH_BYTES`] holds, 1 ..= `threads`.
pub fn units_in_flight(plan: &VertexPlan, opts: &VertexBakeOptions, threads: usize) -> usize {
    let per_unit = plan.unit_bytes(opts).max(1);
    ((BATCH_BYTES / per_unit) as usize).clamp(1, threads.max(1))
}

/// Makes the pieces of units `todo` (indices into `plan.units`, in order) into `store`:
/// those already there are skipped, those with kept traced tensors compressed again, the rest
/// traced, a batch at a time. `keep_traced` also saves each traced unit's dense tensors.
/// `progress` advances by vertices, in the stage "baking vertices".
#[allow(clippy::too_many_arguments)]
pub fn bake_units(
    integ: &Integrator,
    plan: &VertexPlan,
    shading: &[ShadingBasis],
    layout: &crate::pixel::SlotLayout,
    opts: &VertexBakeOptions,
    todo: &[usize],
    store: &mut PieceStore,
    keep_traced: bool,
    progress: Option<&dyn Progress>,
) -> Result<UnitsDone, VertexError> {
    opts.validate()?;
    let tracer = VertexTracer::new(integ, plan, layout, shading, opts)?;
    let units = &plan.units;
    let total: u64 = todo.iter().map(|&u| units[u].vertices.len() as u64).sum();
    let stage = Stage::start(progress, "baking vertices", total);
    let mut done = UnitsDone::default();
    let mut fresh: Vec<usize> = Vec::new();
    let t0_rows = |u: &Unit| tracer.group_shading(u.group).map_or(1, |b| b.ranks.i + 1);
    for &u in todo {
        stage.check()?;
        if store.has(u) {
            stage.restored(units[u].vertices.len() as u64);
            done.restored += 1;
        } else if store.has_traced(u) {
            let start = Instant::now();
            let traced = traced_from_piece(&store.traced(u)?)
                .map_err(|e| VertexError::Inconsistent(e.to_string()))?;
            let piece = finish_unit(u, &units[u], &traced, plan, opts, t0_rows(&units[u]))?;
            store.save(u, &piece)?;
            done.compress_seconds += start.elapsed().as_secs_f64();
            stage.restored(units[u].vertices.len() as u64);
            done.recompressed += 1;
        } else {
            fresh.push(u);
        }
    }
    let batch = units_in_flight(plan, opts, rayon::current_num_threads());
    for chunk in fresh.chunks(batch) {
        stage.check()?;
        let start = Instant::now();
        let traced: Vec<TracedUnit> = trace_units(&tracer, units, chunk, &|n| {
            stage.advance(n);
            stage.check().is_ok()
        })?;
        done.trace_seconds += start.elapsed().as_secs_f64();
        let start = Instant::now();
        let pieces = chunk
            .par_iter()
            .zip(&traced)
            .map(|(&u, t)| {
                let rows = t0_rows(&units[u]);
                let piece = finish_unit(u, &units[u], t, plan, opts, rows)?;
                let kept = if keep_traced && opts.compression.is_some() {
                    Some(traced_piece(u, &units[u], t, plan, opts, rows)?)
                } else {
                    None
                };
                Ok((piece, kept))
            })
            .collect::<Result<Vec<_>, VertexError>>()?;
        for ((&u, t), (piece, kept)) in chunk.iter().zip(&traced).zip(&pieces) {
            if let Some(k) = kept {
                store.save_traced(u, k)?;
            }
            store.save(u, piece)?;
            done.traced_vertices += units[u].vertices.len() as u64;
            done.traced_rays += t.rays;
        }
        done.compress_seconds += start.elapsed().as_secs_f64();
        done.traced += chunk.len();
    }
    Ok(done)
}

/// The bake's common part: the metadata with every figure known before tracing, the units,
/// and the tensors that are not per group (mesh, environment; shading and basis tables,
/// textures), in file order.
pub fn vertex_common(
    scene: &Scene,
    plan: &VertexPlan,
    layout: &crate::pixel::SlotLayout,
    shading: &[ShadingBasis],
    opts: &VertexBakeOptions,
) -> Result<(VertexCommon, Vec<CommonTensor<'static>>), VertexError> {
    let used_shading: Vec<&ShadingBasis> = plan
        .shading_families()
        .iter()
        .filter_map(|f| shading.iter().find(|b| b.family == *f))
        .collect();
    let groups_meta = plan
        .groups
        .iter()
        .map(|g| {
            let basis = g
                .lobe
                .and_then(|f| used_shading.iter().position(|b| b.family == f));
            VertexGroupMeta {
                material: g.material,
                vertices: g.vertices.len() as u32,
                t0_rows: basis.map_or(1, |b| used_shading[b].ranks.i as u32 + 1),
                shading: g.lobe.map(|_| basis.unwrap_or(usize::MAX) as u32),
                active: g.active.clone(),
                scale_t0: 1.0,
                scale_t1: 1.0,
                scale_t2: 1.0,
                compression: None,
                t0_terms: None,
            }
        })
        .collect();
    let (bases_meta, basis_tables) = persisted(layout);
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
    let stored = stored_textures(scene);
    let (textures_meta, textures) = (stored.meta, stored.texels);
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
        material_textures: stored.base_colour,
        material_normal_maps: stored.normal_maps,
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
            rays: plan.prepass_rays,
            allocation: plan.slots.reasons.clone(),
            t0_truncation_error: Vec::new(),
        },
        compression: opts.compression,
    };
    let tensor = |name: &str, dtype: Dtype, shape: Vec<usize>, bytes: Vec<u8>| CommonTensor {
        name: name.to_string(),
        dtype,
        shape,
        bytes: Cow::Owned(bytes),
    };
    let f32s = |v: &[f32]| prt_formats::container::element_bytes(v).into_owned();
    let u32s = |v: &[u32]| prt_formats::container::element_bytes(v).into_owned();
    let (nv, nt) = (scene.positions.len(), scene.triangles.len());
    let flat3 = |v: &[Vec3]| -> Vec<f32> { v.iter().flat_map(|p| p.to_array()).collect() };
    let mut tensors = vec![
        tensor(
            names::POSITIONS,
            Dtype::F32,
            vec![nv, 3],
            f32s(&flat3(&scene.positions)),
        ),
        tensor(
            names::NORMALS,
            Dtype::F32,
            vec![nv, 3],
            f32s(&flat3(&plan.normals)),
        ),
        tensor(
            names::UVS,
            Dtype::F32,
            vec![nv, 2],
            f32s(
                &scene
                    .uvs
                    .iter()
                    .flat_map(|u| u.to_array())
                    .collect::<Vec<_>>(),
            ),
        ),
        tensor(
            names::TRIANGLES,
            Dtype::U32,
            vec![nt, 3],
            u32s(
                &scene
                    .triangles
                    .iter()
                    .flatten()
                    .copied()
                    .collect::<Vec<_>>(),
            ),
        ),
        tensor(
            names::TRIANGLE_MATERIAL,
            Dtype::U32,
            vec![nt],
            u32s(&scene.triangle_material),
        ),
    ];
    if let EnvironmentMeta::LatLong { width, height, .. } = meta.environment {
        tensors.push(tensor(
            names::ENVIRONMENT,
            Dtype::F32,
            vec![height as usize, width as usize, 3],
            f32s(&environment),
        ));
    }
    let before_groups = tensors.len();
    for (b, basis) in used_shading.iter().enumerate() {
        for (table, values) in shading_tables(basis) {
            tensors.push(tensor(
                &names::shading_table(b, table),
                Dtype::F32,
                vec![values.len()],
                f32s(values),
            ));
        }
    }
    for (b, (m, t)) in meta.bases.iter().zip(&basis_tables).enumerate() {
        let nb = m.basis.num_bases;
        tensors.push(tensor(
            &prt_formats::pixel::names::basis_tables(b),
            Dtype::F32,
            vec![t.len() / nb.max(1), nb],
            f32s(t),
        ));
    }
    for (t, (tm, texels)) in meta.textures.iter().zip(&textures).enumerate() {
        tensors.push(tensor(
            &names::texture(t),
            Dtype::F32,
            vec![tm.height as usize, tm.width as usize, 3],
            f32s(texels),
        ));
    }
    let common = VertexCommon {
        meta,
        units: plan
            .units
            .iter()
            .map(|u| (u.group, u.vertices.len()))
            .collect(),
        before_groups,
    };
    Ok((common, tensors))
}

/// The textures the last reflection reads, as stored.
struct StoredTextures {
    meta: Vec<TextureMeta>,
    /// Per material, its base-colour texture.
    base_colour: Vec<Option<u32>>,
    /// Per material, its normal map; empty when no material has one.
    normal_maps: Vec<Option<u32>>,
    texels: Vec<Vec<f32>>,
}

/// The base-colour textures and normal maps of the materials (each stored once, in order of
/// first use) and each material's index into them.
fn stored_textures(scene: &Scene) -> StoredTextures {
    let mut used: Vec<usize> = Vec::new();
    let mut index_of = |t: Option<usize>| -> Option<u32> {
        let t = t?;
        scene.textures.get(t)?;
        Some(match used.iter().position(|&u| u == t) {
            Some(i) => i as u32,
            None => {
                used.push(t);
                (used.len() - 1) as u32
            }
        })
    };
    let base_colour: Vec<Option<u32>> = scene
        .materials
        .iter()
        .map(|m| index_of(m.base_color_texture))
        .collect();
    let mut normal_maps: Vec<Option<u32>> = scene
        .materials
        .iter()
        .map(|m| index_of(m.normal_texture))
        .collect();
    if normal_maps.iter().all(Option::is_none) {
        normal_maps.clear();
    }
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
    StoredTextures {
        meta,
        base_colour,
        normal_maps,
        texels,
    }
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

/// The PCA bases the bake was given, kept for the API's symmetry with the per-pixel mode.
#[allow(dead_code)]
fn unused(_: &[BrdfBasis]) {}
