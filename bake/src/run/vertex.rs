//! `bake` of a per-vertex config, whole or as one shard (docs/vertex.md, docs/shards.md): the
//! scene prepared (welded, ordered by unit), the pre-pass, the allocation report and memory
//! estimate (as notes, before the bases are built and the vertices traced), the checkpoint
//! (refused or resumed before any tracing), the units, and the file or the shard file from
//! their pieces; the checkpoint removed once the output is in place.

use std::path::PathBuf;
use std::time::Instant;

use crate::accel::Accel;
use crate::basis::shading::default_shading_basis;
use crate::config::{BakeConfig, Mode};
use crate::error::BakeError;
use crate::integrator::Integrator;
use crate::lights::LightSet;
use crate::pixel::{Precision, SlotPlan};
use crate::progress::Progress;
use crate::scene::Scene;
use crate::shard::{checkpoint_folder, write_shard_file, PieceStore, ShardSpec};
use crate::units::human_bytes;
use crate::vertex::{
    self, assemble_vertex_file, bake_units, prepare_scene_for, vertex_common, vertex_fingerprints,
    VertexBakeOptions, VertexPlan, VertexTimings,
};

use super::memory::{memory_limit, EstimatedMemory};
use super::{basis_count_setting, basis_counts, build_counted_bases, shard_output};

/// Whether a per-vertex run keeps its pieces as a checkpoint (`<output>.partial/`) that a
/// killed run can continue from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CheckpointMode {
    /// The pieces are scratch: a later run replaces them, a failed run removes them.
    Off,
    /// A new checkpoint; an existing one (an interrupted bake's) is refused, not reused.
    #[default]
    Save,
    /// Continue from the existing checkpoint when its inputs are this run's (refused, naming
    /// what changed, when they are not); without one, bake from the start and save one.
    Resume,
}

/// Command-line settings of a per-vertex bake on top of the config.
#[derive(Clone, Debug, Default)]
pub struct VertexRunSettings {
    /// N1 (default: the config's `spp`).
    pub spp: Option<u32>,
    pub output: Option<PathBuf>,
    /// Storage of T0 values, T1 and T2 (default f16).
    pub precision: Option<Precision>,
    /// Refuse above this many bytes (default: the memory available).
    pub max_memory: Option<u64>,
    pub basis_count: Option<usize>,
    /// Checkpoints (default: saved).
    pub checkpoint: CheckpointMode,
    /// Keep every unit's traced tensors in the checkpoint and the checkpoint after the file is
    /// written: a later [`CheckpointMode::Resume`] run with other `[vertex]` compression keys
    /// compresses again without tracing a ray.
    pub keep_traced: bool,
    /// Bake only this shard's units into a shard file (`bake merge` makes the bake).
    pub shard: Option<ShardSpec>,
}

/// What a per-vertex bake did, for the CLI's summary and `--json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VertexRunSummary {
    pub output: PathBuf,
    pub file_bytes: u64,
    /// The shard made, when sharded (`output` is then the shard file).
    pub shard: Option<ShardSpec>,
    #[serde(flatten)]
    pub estimate: EstimatedMemory,
    /// Units traced and compressed at once, and the most one holds.
    pub units_in_flight: usize,
    pub unit_bytes: u64,
    /// Vertices baked (those in groups, after welding; a shard's: those of its units).
    pub vertices: u64,
    /// Vertices the scene had as loaded, merged by welding, and used by no triangle.
    pub loaded_vertices: u64,
    pub welded_vertices: u64,
    pub unused_vertices: u64,
    /// Units of the bake, and of them: traced by this run, compressed again from their kept
    /// traced tensors, restored from the checkpoint.
    pub units: usize,
    pub units_traced: usize,
    pub units_recompressed: usize,
    pub units_restored: usize,
    pub seconds: f64,
    /// Building the PCA bases and the shading bases.
    pub basis_seconds: f64,
    /// The pre-pass that finds the active slots.
    pub prepass_seconds: f64,
    pub timings: VertexTimings,
    /// The file's figures (None for a shard: its merge has them).
    pub stats: Option<prt_formats::vertex::VertexBakeStats>,
    /// Groups that missed the compression's error target.
    pub warnings: Vec<String>,
}

/// Runs a per-vertex bake for a config (see the module documentation).
pub fn run_vertex(
    config: &BakeConfig,
    loaded: &Scene,
    s: &VertexRunSettings,
    progress: &dyn Progress,
) -> Result<VertexRunSummary, BakeError> {
    let start = Instant::now();
    if config.mode != Mode::Vertex {
        return Err(BakeError::WrongMode {
            config: config.config_path.clone(),
            mode: "pixel",
            called: "vertex",
        });
    }
    let vcfg = config.vertex.clone().unwrap_or_default();
    let opts = VertexBakeOptions {
        samples: s.spp.unwrap_or(config.spp),
        secondary: vcfg.secondary(),
        reflections: config.reflections,
        seed: config.seed,
        t0_terms: vcfg.t0_terms() as usize,
        precision: s.precision.unwrap_or(Precision::F16),
        light_bins: vcfg.light_bins(),
        compression: vcfg.compression(),
    };
    // Refuse what the mode cannot bake before any work.
    opts.validate()?;
    vertex::check_scene(loaded)?;
    let output = s.output.clone().unwrap_or_else(|| config.output.clone());
    // Every task of a job array runs the same command line: a shard's file is named after the
    // output and the shard, never the output itself.
    let output = match s.shard {
        Some(spec) => shard_output(&output, spec),
        None => output,
    };
    let dir = checkpoint_folder(&output);
    if s.checkpoint == CheckpointMode::Save {
        PieceStore::ensure_absent(&dir)?;
    }

    let prepared = prepare_scene_for(loaded, &opts);
    if prepared.welded > 0 || prepared.unused > 0 {
        progress.note(&format!(
            "{} vertices loaded; {} welded (they share position, normal, texture coordinate \
             and material with another: the corners of a faceted mesh's flat faces), {} used \
             by no triangle: {} vertices to bake",
            prepared.loaded_vertices,
            prepared.welded,
            prepared.unused,
            prepared.scene.positions.len()
        ));
    }
    let scene = &prepared.scene;
    let count = basis_count_setting(config, s.basis_count);
    let slots = SlotPlan::per_unit_radiance(scene, &basis_counts(scene, count, progress)?)?;
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let integ = Integrator::new(scene, &accel, &lights, opts.reflections as usize, 1, 1);
    let prepass_start = Instant::now();
    let plan = VertexPlan::new(&integ, slots, &opts, prepared.units, Some(progress))?;
    let prepass_seconds = prepass_start.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();
    let est = plan.estimate_memory(scene, &opts, threads);
    let estimate = EstimatedMemory {
        bytes: est.bytes,
        resident_bytes: est.resident_bytes,
        basis_bytes: est.basis_bytes,
        trace_bytes: est.trace_bytes,
    };
    progress.note(&format!(
        "{}\n{} ({} units of up to {} vertices, {} in flight at up to {} each)",
        plan.report(scene, &opts),
        estimate.note(),
        plan.units.len(),
        plan.units
            .iter()
            .map(|u| u.vertices.len())
            .max()
            .unwrap_or(0),
        est.units_in_flight,
        human_bytes(est.unit_bytes),
    ));
    estimate.check(
        memory_limit(s.max_memory),
        &format!(
            "the bake holds the scene and its ray-query structure ({}) and {} unit(s) of \
             vertices at a time ({} each), whatever the vertex count: fewer slots per vertex \
             (a lower [basis] count, fewer editable materials) or smaller units \
             (vertex.cluster_vertices below 256) lower it",
            human_bytes(est.resident_bytes),
            est.units_in_flight,
            human_bytes(est.unit_bytes)
        ),
    )?;

    let fingerprints = vertex_fingerprints(scene, &plan, &opts);
    let mut store = match s.checkpoint {
        CheckpointMode::Resume if dir.exists() => {
            let (store, r) = PieceStore::resume(&dir, &fingerprints)?;
            store.verify()?;
            let mut what = format!("{} of {} units already done", r.pieces, plan.units.len());
            if r.traced > 0 {
                what.push_str(&format!(
                    ", {} to compress again from their traced tensors",
                    r.traced
                ));
            }
            if r.dropped > 0 {
                what.push_str(&format!(
                    " ({} finished with other compression settings dropped)",
                    r.dropped
                ));
            }
            progress.note(&format!("resuming from {}: {what}", dir.display()));
            store
        }
        CheckpointMode::Resume => {
            progress.note(&format!(
                "no checkpoint at {}: baking from the start",
                dir.display()
            ));
            PieceStore::create(&dir, &fingerprints, true)?
        }
        CheckpointMode::Save => PieceStore::create(&dir, &fingerprints, true)?,
        CheckpointMode::Off => PieceStore::create(&dir, &fingerprints, false)?,
    };
    let result = bake_into(
        &integ,
        &plan,
        &opts,
        s,
        &output,
        &fingerprints,
        &mut store,
        progress,
    );
    let resumable = store.resumable();
    match (&result, resumable, s.keep_traced) {
        // Only once the output is in place: a kill before this point resumes from the pieces.
        (Ok(_), _, false) | (Err(_), false, _) => {
            let dir = store.dir().to_path_buf();
            if let Err(e) = store.remove() {
                progress.warn(&format!(
                    "the pieces in {} could not be removed ({e}); delete the folder",
                    dir.display()
                ));
            }
        }
        _ => {}
    }
    let (done, file_bytes, stats, warnings, basis_seconds, write_seconds) = result?;
    for w in &warnings {
        progress.warn(w);
    }
    Ok(VertexRunSummary {
        output,
        file_bytes,
        shard: s.shard,
        estimate,
        units_in_flight: est.units_in_flight,
        unit_bytes: est.unit_bytes,
        vertices: match s.shard {
            Some(spec) => spec
                .units(plan.units.len())
                .map(|u| plan.units[u].vertices.len() as u64)
                .sum(),
            None => plan.grouped_vertices() as u64,
        },
        loaded_vertices: prepared.loaded_vertices as u64,
        welded_vertices: prepared.welded as u64,
        unused_vertices: prepared.unused as u64,
        units: plan.units.len(),
        units_traced: done.traced,
        units_recompressed: done.recompressed,
        units_restored: done.restored,
        seconds: start.elapsed().as_secs_f64(),
        basis_seconds,
        prepass_seconds,
        timings: vertex::timings(&done, write_seconds, start),
        stats,
        warnings,
    })
}

type Baked = (
    vertex::UnitsDone,
    u64,
    Option<prt_formats::vertex::VertexBakeStats>,
    Vec<String>,
    f64,
    f64,
);

/// The bases, the units, and the file or shard file.
#[allow(clippy::too_many_arguments)]
fn bake_into(
    integ: &Integrator,
    plan: &VertexPlan,
    opts: &VertexBakeOptions,
    s: &VertexRunSettings,
    output: &std::path::Path,
    fingerprints: &crate::shard::StoreFingerprints,
    store: &mut PieceStore,
    progress: &dyn Progress,
) -> Result<Baked, BakeError> {
    let basis_start = Instant::now();
    let bases = build_counted_bases(&plan.slots.basis_families, progress)?;
    let mut shading = Vec::new();
    for f in plan.shading_families() {
        let t = Instant::now();
        let b = default_shading_basis(f).map_err(|e| BakeError::Basis {
            family: f,
            message: e.to_string(),
        })?;
        progress.note(&format!(
            "shading basis {f}: ranks {} x {} x {} built in {:.2} s",
            b.ranks.h,
            b.ranks.o,
            b.ranks.i,
            t.elapsed().as_secs_f64()
        ));
        shading.push(b);
    }
    let basis_seconds = basis_start.elapsed().as_secs_f64();
    let layout = plan.layout(&bases)?;
    let todo: Vec<usize> = match s.shard {
        Some(spec) => spec.units(plan.units.len()).collect(),
        None => (0..plan.units.len()).collect(),
    };
    let done = bake_units(
        integ,
        plan,
        &shading,
        &layout,
        opts,
        &todo,
        store,
        s.keep_traced,
        Some(progress),
    )?;
    let (common, tensors) = vertex_common(integ.scene, plan, &layout, &shading, opts)?;
    let write_start = Instant::now();
    match s.shard {
        Some(spec) => {
            let bytes = write_shard_file(
                output,
                "vertex",
                spec,
                plan.units.len(),
                &fingerprints.pieces,
                // Plain numbers, strings and lists: it always serializes.
                serde_json::to_value(&common).unwrap_or(serde_json::Value::Null),
                &tensors,
                store,
            )?;
            let secs = write_start.elapsed().as_secs_f64();
            Ok((done, bytes, None, Vec::new(), basis_seconds, secs))
        }
        None => {
            let a = assemble_vertex_file(&common, &tensors, store, output)?;
            for n in &a.notes {
                progress.note(n);
            }
            let secs = write_start.elapsed().as_secs_f64();
            let stats = a.meta.map(|m| m.stats);
            Ok((done, a.file_bytes, stats, a.warnings, basis_seconds, secs))
        }
    }
}
