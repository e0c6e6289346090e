//! `bake` of a per-pixel config, whole or as one shard (docs/shards.md): bases, allocation
//! report and memory estimate (as notes, before any tracing), the rows, the file or the shard
//! file.

use std::path::PathBuf;
use std::time::Instant;

use crate::accel::Accel;
use crate::config::{BakeConfig, Mode};
use crate::error::BakeError;
use crate::integrator::Integrator;
use crate::lights::LightSet;
use crate::pixel::{self, BakeTimings, PixelBakeOptions, Precision, SlotPlan};
use crate::progress::{Progress, Stage};
use crate::scene::Scene;
use crate::shard::{checkpoint_folder, write_shard_file, CommonTensor, PieceStore, ShardSpec};

use super::memory::{memory_limit, EstimatedMemory};
use super::{basis_count_setting, basis_counts, build_counted_bases, shard_output};

/// Command-line settings of a per-pixel bake on top of the config.
#[derive(Clone, Debug, Default)]
pub struct PixelRunSettings {
    pub spp: Option<u32>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub output: Option<PathBuf>,
    pub precision: Option<Precision>,
    /// Refuse above this many bytes (default: the memory available).
    pub max_memory: Option<u64>,
    pub compress_rank: Option<usize>,
    pub basis_count: Option<usize>,
    /// Bake only this shard's rows into a shard file (`bake merge` makes the bake).
    pub shard: Option<ShardSpec>,
    /// Continue a killed shard from its checkpoint (shards save their rows as they go).
    pub resume: bool,
}

/// What a bake did, for the CLI's summary and `--json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PixelRunSummary {
    pub output: PathBuf,
    pub file_bytes: u64,
    /// The shard made, when sharded (`output` is then the shard file).
    pub shard: Option<ShardSpec>,
    #[serde(flatten)]
    pub estimate: EstimatedMemory,
    pub seconds: f64,
    pub basis_seconds: f64,
    pub timings: BakeTimings,
    /// The file's figures (None for a shard: its merge has them).
    pub stats: Option<prt_formats::pixel::BakeStats>,
}

/// Runs a per-pixel bake for a config (see the module documentation).
pub fn run_pixel(
    config: &BakeConfig,
    scene: &Scene,
    s: &PixelRunSettings,
    progress: &dyn Progress,
) -> Result<PixelRunSummary, BakeError> {
    let start = Instant::now();
    if config.mode == Mode::Vertex {
        return Err(BakeError::WrongMode {
            config: config.config_path.clone(),
            mode: "vertex",
            called: "pixel",
        });
    }
    let count = basis_count_setting(config, s.basis_count);
    let counts = basis_counts(scene, count, progress)?;
    let plan = SlotPlan::new(scene, &counts)?;
    let opts = PixelBakeOptions {
        width: s.width.unwrap_or(config.width),
        height: s.height.unwrap_or(config.height),
        spp: s.spp.unwrap_or(config.spp),
        emission_oversampling: config.emission_oversampling,
        reflections: config.reflections,
        seed: config.seed,
        precision: s.precision.unwrap_or(Precision::F32),
        max_memory: s.max_memory,
        compress_rank: s.compress_rank,
    };
    // One ray-query structure and light set serve the memory estimate and the bake.
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
    let est = pixel::estimate_memory(&integ, &plan, opts.reflections as usize, opts.precision);
    let estimate = EstimatedMemory {
        bytes: est.bytes,
        resident_bytes: est.resident_bytes,
        basis_bytes: est.basis_bytes,
        trace_bytes: est.trace_bytes,
    };
    let mut report = format!("allocation ({} global slots):", plan.total_slots);
    for r in &plan.reasons {
        report.push_str(&format!("\n  {r}"));
    }
    for (m, (&p, &v)) in plan
        .materials
        .iter()
        .zip(est.pixels_per_material.iter().zip(&est.values_per_pixel))
    {
        if p > 0 {
            report.push_str(&format!("\n  {}: ~{p} pixels x {v} values", m.name));
        }
    }
    report.push('\n');
    report.push_str(&estimate.note());
    progress.note(&report);
    estimate.check(
        memory_limit(s.max_memory),
        "lower the resolution (--width, --height), the reflections or the basis count",
    )?;
    let basis_start = Instant::now();
    let bases = build_counted_bases(&counts, progress)?;
    let basis_seconds = basis_start.elapsed().as_secs_f64();
    let layout = plan.with_bases(&bases)?;
    let output = s.output.clone().unwrap_or_else(|| config.output.clone());
    let Some(spec) = s.shard else {
        let bake = pixel::bake_with(&integ, &layout, &opts, Some(progress))?;
        let file_bytes = pixel::write_bake_file(&bake, &output, opts.precision)?;
        return Ok(PixelRunSummary {
            output,
            file_bytes,
            shard: None,
            estimate,
            seconds: start.elapsed().as_secs_f64(),
            basis_seconds,
            timings: bake.timings,
            stats: Some(bake.meta.stats.clone()),
        });
    };

    // A shard: its rows, saved as pieces as they finish (a killed shard resumes), then the
    // shard file.
    // Every task of a job array runs the same command line: a shard's file is named after the
    // output and the shard, never the output itself.
    let output = shard_output(&output, spec);
    let fingerprints = pixel::pixel_fingerprints(scene, &layout, &opts);
    let dir = checkpoint_folder(&output);
    let mut store = if s.resume && dir.exists() {
        let (store, restored) = PieceStore::resume(&dir, &fingerprints)?;
        progress.note(&format!(
            "resuming from {}: {} rows already traced",
            dir.display(),
            restored.pieces
        ));
        store
    } else {
        PieceStore::create(&dir, &fingerprints, true)?
    };
    let (common, basis_tables) = pixel::pixel_common(&integ, &layout, &opts)?;
    let mine: Vec<usize> = spec.units(opts.height as usize).collect();
    let todo: Vec<u32> = mine
        .iter()
        .filter(|&&y| !store.has(y))
        .map(|&y| y as u32)
        .collect();
    let stage = Stage::start(Some(progress), "baking", mine.len() as u64);
    stage.restored((mine.len() - todo.len()) as u64);
    let trace_start = Instant::now();
    // Rows a band at a time, each saved when its band is done: a kill loses one band.
    let band = (rayon::current_num_threads() * 4).max(1);
    let mut rays = 0u64;
    for ys in todo.chunks(band) {
        if progress.cancelled() {
            return Err(crate::progress::Cancelled.into());
        }
        let rows = pixel::trace_rows(&integ, &layout, &opts, ys, None)?;
        for (&y, row) in ys.iter().zip(&rows) {
            store.save(y as usize, &pixel::row_piece(y, row))?;
            rays += row.rays;
        }
        stage.advance(ys.len() as u64);
    }
    drop(stage);
    let trace_seconds = trace_start.elapsed().as_secs_f64();
    let tensors: Vec<CommonTensor> = common
        .meta
        .bases
        .iter()
        .zip(&basis_tables)
        .enumerate()
        .map(|(b, (m, t))| CommonTensor {
            name: prt_formats::pixel::names::basis_tables(b),
            dtype: prt_formats::Dtype::F32,
            shape: vec![t.len() / m.basis.num_bases.max(1), m.basis.num_bases],
            bytes: std::borrow::Cow::Owned(prt_formats::container::element_bytes(t).into_owned()),
        })
        .collect();
    let file_bytes = write_shard_file(
        &output,
        "pixel",
        spec,
        opts.height as usize,
        &fingerprints.pieces,
        // Plain numbers, strings and lists: it always serializes.
        serde_json::to_value(&common).unwrap_or(serde_json::Value::Null),
        &tensors,
        &store,
    )?;
    if let Err(e) = store.remove() {
        progress.warn(&format!(
            "the shard is written, but its checkpoint could not be removed ({e}); delete it"
        ));
    }
    Ok(PixelRunSummary {
        output,
        file_bytes,
        shard: Some(spec),
        estimate,
        seconds: start.elapsed().as_secs_f64(),
        basis_seconds,
        timings: BakeTimings {
            trace_seconds,
            bake_seconds: start.elapsed().as_secs_f64(),
            rays_per_second: rays as f64 / trace_seconds.max(1e-9),
        },
        stats: None,
    })
}
