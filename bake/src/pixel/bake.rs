//! The bake itself: trace every pixel's samples through the shared integrator, accumulate the
//! transfer rows per visible material, compact them to the active slots, and assemble the
//! metadata (deterministic figures only; timings are returned beside it).

use std::time::Instant;

use prt_formats::basis::BrdfBasis;
use prt_formats::pixel::{
    BakeStats, BasisMeta, CameraMeta, GroupMeta, PixelBakeMeta, Precision, PIXEL_SCHEMA_VERSION,
};
use rayon::prelude::*;

use crate::accel::Accel;
use crate::integrator::Integrator;
use crate::lights::LightSet;
use crate::progress::{Progress, Stage};
use crate::sampling::PixelSampler;
use crate::scene::Scene;

use super::compact::{active_slots, compact_rows};
use super::compress::{pca_rows, Compressed};
use super::error::PixelError;
use super::layout::SlotLayout;
use super::model::BakeModel;
use super::sink::TensorSink;

/// Settings of a per-pixel bake.
#[derive(Clone, Debug)]
pub struct PixelBakeOptions {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Camera samples per path sample for what the camera sees directly
    /// ([`crate::film_emission::DEFAULT_EMISSION_OVERSAMPLING`]).
    pub emission_oversampling: u32,
    pub reflections: u32,
    pub seed: u64,
    pub precision: Precision,
    /// Refuse to bake when the estimated working memory exceeds this many bytes.
    pub max_memory: Option<u64>,
    /// Also store a rank-k PCA-over-pixels variant of every group.
    pub compress_rank: Option<usize>,
}

/// The result of a per-pixel bake, ready to be written.
pub struct PixelBake {
    /// Everything the file's metadata holds (inputs and deterministic figures only).
    pub meta: PixelBakeMeta,
    /// How long the bake took: reported by the tools, never written to the file.
    pub timings: BakeTimings,
    /// Radiance reaching the camera without reflection, [H, W, 3].
    pub emission: Vec<f32>,
    pub groups: Vec<GroupData>,
    /// Basis tables per used basis (as stored in `basis.<i>.tables`).
    pub basis_tables: Vec<Vec<f32>>,
}

/// One group's tensors (f32, compacted to its active slots).
pub struct GroupData {
    pub pixels: Vec<u32>,
    /// [pixels, row_len].
    pub rows: Vec<f32>,
    /// Low-rank variant: mean [row_len], components [rank, row_len], weights [pixels, rank].
    pub compressed: Option<Compressed>,
}

/// Wall-clock figures of a bake (not stored in the file).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct BakeTimings {
    /// Tracing and accumulation.
    pub trace_seconds: f64,
    /// The whole bake call (tracing, compaction, compression).
    pub bake_seconds: f64,
    /// Rays traced per second of tracing.
    pub rays_per_second: f64,
}

/// The bases as a bake file stores them: metadata without the tables, and the tables (the
/// tensors `basis.<i>.tables`, [`super::write::add_basis_tables`]). The per-vertex bake
/// stores its PCA bases the same way.
pub(crate) fn persisted_bases(bases: &[BrdfBasis]) -> (Vec<BasisMeta>, Vec<Vec<f32>>) {
    let mut metas = Vec::with_capacity(bases.len());
    let mut tables = Vec::with_capacity(bases.len());
    for b in bases {
        let mut meta = b.clone();
        tables.push(std::mem::take(&mut meta.tables));
        metas.push(BasisMeta { basis: meta });
    }
    (metas, tables)
}

/// Builds the ray-query structure and lights for `scene` and runs the bake ([`bake_with`]).
pub fn bake(
    scene: &Scene,
    layout: &SlotLayout,
    opts: &PixelBakeOptions,
    progress: Option<&dyn Progress>,
) -> Result<PixelBake, PixelError> {
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let integ = Integrator::new(
        scene,
        &accel,
        &lights,
        opts.reflections as usize,
        opts.width,
        opts.height,
    );
    bake_with(&integ, layout, opts, progress)
}

/// Runs the bake on an integrator built for the options' image size and reflections (so the
/// caller can use the same one for [`estimate_memory`] and build the BVH once). `progress` is
/// advanced once per image row.
pub fn bake_with(
    integ: &Integrator,
    layout: &SlotLayout,
    opts: &PixelBakeOptions,
    progress: Option<&dyn Progress>,
) -> Result<PixelBake, PixelError> {
    let start = Instant::now();
    let (common, basis_tables) = pixel_common(integ, layout, opts)?;
    let all: Vec<u32> = (0..opts.height).collect();
    let rows = trace_rows(integ, layout, opts, &all, progress)?;
    let trace_seconds = start.elapsed().as_secs_f64();
    let mut bake = finish_rows(&common, rows, basis_tables);
    bake.timings = BakeTimings {
        trace_seconds,
        bake_seconds: start.elapsed().as_secs_f64(),
        rays_per_second: bake.meta.stats.rays as f64 / trace_seconds.max(1e-9),
    };
    Ok(bake)
}

/// What one image row of the bake produced: the emission of its pixels and, per pixel and
/// visible material, its dense transfer row (divided by spp).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RowOut {
    /// `[width, 3]`.
    pub emission: Vec<f32>,
    /// (pixel, material, row) in pixel order, materials as the sink found them.
    pub entries: Vec<(u32, u32, Vec<f32>)>,
    /// Rays traced for the row.
    pub rays: u64,
}

/// What finishing the rows needs besides them: the metadata with every figure known before
/// tracing (its groups and the figures the rows add are filled in by [`finish_rows`]), the
/// slot count, the compression rank. A shard file carries it, so shards merge without the
/// scene.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct PixelCommon {
    pub meta: PixelBakeMeta,
    /// Global slots J.
    pub total_slots: usize,
    pub compress_rank: Option<usize>,
}

/// The bake's common part and its basis tables (checks the integrator against the options).
pub fn pixel_common(
    integ: &Integrator,
    layout: &SlotLayout,
    opts: &PixelBakeOptions,
) -> Result<(PixelCommon, Vec<Vec<f32>>), PixelError> {
    let reflections = opts.reflections as usize;
    if (integ.width, integ.height, integ.reflections) != (opts.width, opts.height, reflections) {
        return Err(PixelError::IntegratorMismatch {
            integ_width: integ.width,
            integ_height: integ.height,
            integ_reflections: integ.reflections,
            width: opts.width,
            height: opts.height,
            reflections: opts.reflections,
        });
    }
    let scene = integ.scene;
    let plan = integ.emission_plan(opts.emission_oversampling);
    let (bases_meta, basis_tables) = persisted_bases(&layout.bases);
    let cam = &scene.camera;
    let meta = PixelBakeMeta {
        pixel_schema_version: PIXEL_SCHEMA_VERSION,
        width: opts.width,
        height: opts.height,
        spp: opts.spp.max(1),
        emission_oversampling: Some(opts.emission_oversampling.max(1)),
        reflections: opts.reflections,
        seed: opts.seed,
        channels: layout.channels as u32,
        tint: layout.tint.to_array(),
        precision: opts.precision,
        materials: layout.materials.clone(),
        bases: bases_meta,
        groups: Vec::new(),
        camera: CameraMeta {
            position: cam.position.to_array(),
            forward: cam.forward.to_array(),
            up: cam.up.to_array(),
            yfov: cam.yfov,
        },
        stats: BakeStats {
            rays: plan.probe_rays(),
            dense_values: 0,
            stored_values: 0,
            allocation: layout.reasons.clone(),
            triangles: scene.triangles.len() as u64,
        },
    };
    Ok((
        PixelCommon {
            meta,
            total_slots: layout.total_slots,
            compress_rank: opts.compress_rank,
        },
        basis_tables,
    ))
}

/// Traces image rows `ys` (in that order, each from its own random streams, so any subset
/// gives the same rows as a whole bake). `progress` is advanced once per row.
pub fn trace_rows(
    integ: &Integrator,
    layout: &SlotLayout,
    opts: &PixelBakeOptions,
    ys: &[u32],
    progress: Option<&dyn Progress>,
) -> Result<Vec<RowOut>, PixelError> {
    let reflections = opts.reflections as usize;
    let scene = integ.scene;
    let model = BakeModel::new(scene, layout);
    let w = opts.width;
    let spp = opts.spp.max(1);
    let inv = 1.0 / spp as f32;
    let plan = integ.emission_plan(opts.emission_oversampling);
    let stage = Stage::start(progress, "baking", ys.len() as u64);
    let rows: Vec<RowOut> = ys
        .par_iter()
        .map(|&y| {
            stage.check()?;
            let mut out = RowOut {
                emission: Vec::with_capacity(3 * w as usize),
                entries: Vec::new(),
                rays: 0,
            };
            // One per row: it keeps the shuffle tables' memory between pixels.
            let mut sampler = PixelSampler::new(spp, integ.draws_per_sample());
            for x in 0..w {
                let pixel = y as u64 * w as u64 + x as u64;
                let mut sink = TensorSink::new(layout, reflections);
                sampler.start(opts.seed, pixel);
                for s in 0..spp {
                    let mut rng = sampler.sample(s);
                    sink.current = None;
                    out.rays += integ.trace_sample(&model, &mut sink, x, y, &mut rng) as u64;
                }
                let (emission, rays) = integ.pixel_emission(
                    &sampler,
                    x,
                    y,
                    spp,
                    plan.oversampling(x, y),
                    sink.emission,
                );
                out.rays += rays;
                out.emission.extend(emission.to_array());
                for (m, mut row) in sink.rows {
                    row.iter_mut().for_each(|v| *v *= inv);
                    out.entries.push((pixel as u32, m, row));
                }
            }
            stage.advance(1);
            Ok(out)
        })
        .collect::<Result<_, PixelError>>()?;
    Ok(rows)
}

/// The bake from every row of the image, in order: gathered per material, compacted to the
/// slots that carry light, compressed when asked, with the metadata's groups and figures.
/// Timings are left at zero (the caller knows them).
pub fn finish_rows(
    common: &PixelCommon,
    rows: Vec<RowOut>,
    basis_tables: Vec<Vec<f32>>,
) -> PixelBake {
    let mut meta = common.meta.clone();
    let reflections = meta.reflections as usize;
    let nmat = meta.materials.len();
    let (w, h) = (meta.width, meta.height);
    // Gather per material, in pixel order.
    let mut emission = Vec::with_capacity((w * h * 3) as usize);
    let mut per_mat: Vec<(Vec<u32>, Vec<Vec<f32>>)> = vec![(Vec::new(), Vec::new()); nmat];
    let mut rays = meta.stats.rays;
    for r in rows {
        emission.extend(r.emission);
        rays += r.rays;
        for (p, m, row) in r.entries {
            per_mat[m as usize].0.push(p);
            per_mat[m as usize].1.push(row);
        }
    }

    // Compact each group to the slots that carry light into it.
    let jn = common.total_slots;
    let c = meta.channels as usize;
    let mut groups_meta = Vec::new();
    let mut groups = Vec::new();
    let mut dense_values = 0u64;
    let mut stored_values = 0u64;
    for (m, (pixels, rows)) in per_mat.into_iter().enumerate() {
        if pixels.is_empty() {
            continue;
        }
        let n0 = meta.materials[m].slots.len();
        let active = active_slots(&rows, n0, jn, reflections, c);
        let (compact_len, compact) = compact_rows(&rows, n0, jn, &active, reflections, c);
        dense_values += rows.iter().map(|r| r.len() as u64).sum::<u64>();
        stored_values += compact.len() as u64;
        let compressed = common
            .compress_rank
            .map(|k| pca_rows(&compact, pixels.len(), compact_len, k));
        groups_meta.push(GroupMeta {
            material: m as u32,
            pixels: pixels.len() as u32,
            slots: n0 as u32,
            active: active.iter().map(|&j| j as u32).collect(),
            row_len: compact_len as u32,
            compressed_rank: compressed.as_ref().map(|c| c.rank as u32),
            scale: 1.0,
        });
        groups.push(GroupData {
            pixels,
            rows: compact,
            compressed,
        });
    }
    meta.groups = groups_meta;
    meta.stats.rays = rays;
    meta.stats.dense_values = dense_values;
    meta.stats.stored_values = stored_values;
    PixelBake {
        meta,
        timings: BakeTimings::default(),
        emission,
        groups,
        basis_tables,
    }
}
