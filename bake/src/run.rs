//! The `bake` command's jobs, as library functions: load a config's scene, build the bases
//! its editable materials need, bake, write. The binaries only parse arguments and show
//! progress ([`Progress`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

use prt_formats::basis::BrdfBasis;
use prt_formats::{MaterialOverride, OverrideValue};

use crate::accel::Accel;
use crate::basis::shading::default_shading_basis;
use crate::basis::{BasisBuilder, BasisConfig};
use crate::brdf::{Family, Lobe};
use crate::config::{BakeConfig, Mode};
use crate::error::BakeError;
use crate::integrator::Integrator;
use crate::lights::LightSet;
use crate::pixel::{self, BakeTimings, PixelBakeOptions, Precision, SlotPlan};
use crate::progress::Progress;
use crate::scene::Scene;
use crate::units::human_bytes;
use crate::vertex::{
    self, Checkpoint, Fingerprint, VertexBakeOptions, VertexError, VertexPlan, VertexTimings,
};

/// Loads the config and its scene, with errors that name the file; the loader's warnings
/// (skipped primitives, ignored glTF features) go to `progress`. `config_path` may name what
/// `bake` accepts: a config, a scene folder holding `bake.toml`, or a glTF (its defaults).
pub fn load(config_path: &Path, progress: &dyn Progress) -> Result<(BakeConfig, Scene), BakeError> {
    let resolved = crate::config::input::resolve(config_path)?;
    for w in &resolved.warnings {
        progress.warn(w);
    }
    let scene = load_scene(&resolved.config, progress)?;
    Ok((resolved.config, scene))
}

/// Loads a config's scene, refusing one with nothing to trace; warnings go to `progress`
/// (among them [`crate::scene::unlit_warning`]: nothing lights the scene).
pub fn load_scene(config: &BakeConfig, progress: &dyn Progress) -> Result<Scene, BakeError> {
    let (scene, warnings) = crate::scene::load_with_warnings(config)?;
    for w in &warnings {
        progress.warn(w);
    }
    if scene.triangles.is_empty() {
        return Err(BakeError::NoTriangles(config.scene_path.clone()));
    }
    if let Some(w) = crate::scene::unlit_warning(config, &scene) {
        progress.warn(&w);
    }
    Ok(scene)
}

/// How many basis BRDFs each editable glossy family gets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BasisCount {
    /// The same count for every family.
    Fixed(usize),
    /// The smallest N_b in 2..=12 whose max relative L2 reconstruction error over the family's
    /// sampled lobes (docs/brdf-basis.md) is at most this.
    ErrorTarget(f64),
    /// [`Lobe::default_basis_count`] per family.
    Default,
}

/// Largest N_b the error-target selection considers.
const MAX_SELECTED_COUNT: usize = 12;

/// Picks N_b for `family` by error target (measured on the family's default sampling).
fn count_for_target(
    family: Family,
    target: f64,
    progress: &dyn Progress,
) -> Result<usize, BakeError> {
    if target.is_nan() || target <= 0.0 {
        return Err(BakeError::BadErrorTarget(target));
    }
    let basis_err = |message: String| BakeError::Basis { family, message };
    let cfg = BasisConfig::new(family, MAX_SELECTED_COUNT).map_err(|e| basis_err(e.to_string()))?;
    let counts: Vec<usize> = (2..=MAX_SELECTED_COUNT).collect();
    let (report, _) = crate::basis::select::family_report(&cfg, &counts, 2, 64)
        .map_err(|e| basis_err(e.to_string()))?;
    let chosen = crate::basis::select::select_count(&report, target, false);
    let nb = chosen.unwrap_or(MAX_SELECTED_COUNT);
    let err = report
        .rows
        .iter()
        .find(|r| r.num_bases == nb)
        .map_or(f64::NAN, |r| r.ours.max);
    match chosen {
        Some(_) => progress.note(&format!(
            "basis {family}: N_b = {nb} meets the error target {} (max relative L2 error {err:.4})",
            target as f32
        )),
        None => progress.warn(&format!(
            "basis {family}: no N_b up to {MAX_SELECTED_COUNT} meets the error target {}; using {nb} (max error {err:.4})",
            target as f32
        )),
    }
    Ok(nb)
}

/// The families of the scene's editable glossy materials, each with its number of basis
/// BRDFs (an error target runs the selection here, which builds trial bases).
pub fn basis_counts(
    scene: &Scene,
    count: BasisCount,
    progress: &dyn Progress,
) -> Result<Vec<(Family, usize)>, BakeError> {
    let mut families: Vec<Family> = Vec::new();
    for m in &scene.materials {
        if m.editable && m.brdf.family != Family::Diffuse && !families.contains(&m.brdf.family) {
            families.push(m.brdf.family);
        }
    }
    families
        .into_iter()
        .map(|f| {
            let n = match count {
                BasisCount::Fixed(n) => n,
                BasisCount::ErrorTarget(t) => count_for_target(f, t, progress)?,
                BasisCount::Default => f.default_basis_count(),
            };
            Ok((f, n))
        })
        .collect()
}

/// Builds one basis per (family, size), all at once: each build is mostly serial (its
/// minimax iterations are a chain of small SVDs), so two families take about the time of one
/// on two cores. The default scene's bake (two families) measured 3.05-3.18 s with bases
/// 1.71-1.80 s one after the other, 2.40-2.45 s with bases 1.06-1.10 s at once (3 runs each,
/// interleaved), the file byte-identical. Their memory adds up
/// ([`crate::pixel::memory::bases_build_bytes`]): 576 MiB instead of 288. The notes come in
/// family order.
pub fn build_counted_bases(
    counts: &[(Family, usize)],
    progress: &dyn Progress,
) -> Result<Vec<BrdfBasis>, BakeError> {
    let built: Vec<Result<(BrdfBasis, f64), BakeError>> = counts
        .par_iter()
        .map(|&(f, count)| {
            let start = Instant::now();
            let basis_err = |message: String| BakeError::Basis { family: f, message };
            let cfg = BasisConfig::new(f, count).map_err(|e| basis_err(e.to_string()))?;
            let built = BasisBuilder::new(cfg)
                .and_then(|b| b.build(count))
                .map_err(|e| basis_err(e.to_string()))?;
            Ok((built.to_persisted(), start.elapsed().as_secs_f64()))
        })
        .collect();
    let mut out = Vec::with_capacity(counts.len());
    for (result, &(f, _)) in built.into_iter().zip(counts) {
        let (basis, seconds) = result?;
        progress.note(&format!(
            "basis {f}: {} BRDFs over {:?} built in {seconds:.2} s",
            basis.num_bases, basis.param_range,
        ));
        out.push(basis);
    }
    Ok(out)
}

/// Builds one basis per family used by an editable glossy material, sized by `count`.
pub fn build_bases(
    scene: &Scene,
    count: BasisCount,
    progress: &dyn Progress,
) -> Result<Vec<BrdfBasis>, BakeError> {
    build_counted_bases(&basis_counts(scene, count, progress)?, progress)
}

/// How many basis BRDFs per family: an explicit count wins; else the config's `[basis]`
/// count, else its error target; else the default.
fn basis_count_setting(config: &BakeConfig, explicit: Option<usize>) -> BasisCount {
    let basis_cfg = config.basis.as_ref();
    match (
        explicit,
        basis_cfg.and_then(|b| b.count),
        basis_cfg.and_then(|b| b.error_target),
    ) {
        (Some(n), _, _) => BasisCount::Fixed(n),
        (None, Some(n), _) => BasisCount::Fixed(n as usize),
        (None, None, Some(t)) => BasisCount::ErrorTarget(t as f64),
        (None, None, None) => BasisCount::Default,
    }
}

/// Command-line settings of a per-pixel bake on top of the config.
#[derive(Clone, Debug, Default)]
pub struct PixelRunSettings {
    pub spp: Option<u32>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub output: Option<PathBuf>,
    pub precision: Option<Precision>,
    pub max_memory: Option<u64>,
    pub compress_rank: Option<usize>,
    pub basis_count: Option<usize>,
}

/// What a bake did, for the CLI's summary and `--json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PixelRunSummary {
    pub output: PathBuf,
    pub file_bytes: u64,
    /// The estimated peak memory ([`pixel::MemoryEstimate::bytes`]).
    pub estimated_bytes: u64,
    /// Its parts: held throughout, the basis build's peak, the trace and write's peak.
    pub estimated_resident_bytes: u64,
    pub estimated_basis_bytes: u64,
    pub estimated_trace_bytes: u64,
    pub seconds: f64,
    pub basis_seconds: f64,
    pub timings: BakeTimings,
    pub stats: prt_formats::pixel::BakeStats,
}

/// Runs a per-pixel bake for a config: bases, allocation report and memory estimate (as
/// notes on `progress`, before any tracing), the bake, the file.
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
    report.push_str(&format!(
        "\nmemory estimate: {} peak ({} resident + the larger of basis build {} and trace {})",
        human_bytes(est.bytes),
        human_bytes(est.resident_bytes),
        human_bytes(est.basis_bytes),
        human_bytes(est.trace_bytes),
    ));
    progress.note(&report);
    if let Some(limit) = opts.max_memory {
        if est.bytes > limit {
            return Err(BakeError::MemoryLimit {
                needed: est.bytes,
                limit,
            });
        }
    }
    let basis_start = Instant::now();
    let bases = build_counted_bases(&counts, progress)?;
    let basis_seconds = basis_start.elapsed().as_secs_f64();
    let layout = plan.with_bases(&bases)?;
    let bake = pixel::bake_with(&integ, &layout, &opts, Some(progress))?;
    let output = s.output.clone().unwrap_or_else(|| config.output.clone());
    let file_bytes = pixel::write_bake_file(&bake, &output, opts.precision)?;
    Ok(PixelRunSummary {
        output,
        file_bytes,
        estimated_bytes: est.bytes,
        estimated_resident_bytes: est.resident_bytes,
        estimated_basis_bytes: est.basis_bytes,
        estimated_trace_bytes: est.trace_bytes,
        seconds: start.elapsed().as_secs_f64(),
        basis_seconds,
        timings: bake.timings,
        stats: bake.meta.stats.clone(),
    })
}

/// Whether a per-vertex run saves its traced waves as it goes, so that a killed run can be
/// continued (`vertex::Checkpoint`, in `<output>.partial/`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CheckpointMode {
    /// No checkpoint is written or read.
    #[default]
    Off,
    /// A new checkpoint; an existing one (an interrupted bake's) is refused, not reused.
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
    pub max_memory: Option<u64>,
    pub basis_count: Option<usize>,
    /// Checkpoints (default: none).
    pub checkpoint: CheckpointMode,
    /// Leave the checkpoint in place once the file is written (default: removed). It holds the
    /// traced waves before compression, and the `[vertex]` compression keys are not part of
    /// its fingerprint: a later [`CheckpointMode::Resume`] run with other compression keys
    /// compresses again without tracing a ray.
    pub keep_checkpoint: bool,
}

/// What a per-vertex bake did, for the CLI's summary and `--json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VertexRunSummary {
    pub output: PathBuf,
    pub file_bytes: u64,
    /// The estimated peak memory ([`vertex::VertexMemoryEstimate::bytes`]).
    pub estimated_bytes: u64,
    /// Its parts: held throughout, the basis builds' peak, the trace and write's peak.
    pub estimated_resident_bytes: u64,
    pub estimated_basis_bytes: u64,
    pub estimated_trace_bytes: u64,
    /// Vertices baked (those in groups).
    pub vertices: u64,
    pub seconds: f64,
    /// Building the PCA bases and the shading bases.
    pub basis_seconds: f64,
    /// The pre-pass that finds the active slots.
    pub prepass_seconds: f64,
    pub timings: VertexTimings,
    pub stats: prt_formats::vertex::VertexBakeStats,
}

/// Runs a per-vertex bake for a config: refusals, the pre-pass, the allocation report and
/// memory estimate (as notes on `progress`, before the bases are built and the vertices
/// traced), the checkpoint (`s.checkpoint`: refused or resumed before any tracing), the bases,
/// the bake, the file, and the checkpoint's removal once the file is in place.
pub fn run_vertex(
    config: &BakeConfig,
    scene: &Scene,
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
    vertex::check_scene(scene)?;
    let output = s.output.clone().unwrap_or_else(|| config.output.clone());
    let checkpoint_dir = vertex::checkpoint_folder(&output);
    if s.checkpoint == CheckpointMode::Save {
        Checkpoint::ensure_absent(&checkpoint_dir).map_err(VertexError::from)?;
    }
    let count = basis_count_setting(config, s.basis_count);
    let counts = basis_counts(scene, count, progress)?;
    let slots = SlotPlan::per_unit_radiance(scene, &counts)?;
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let integ = Integrator::new(scene, &accel, &lights, opts.reflections as usize, 1, 1);
    let prepass_start = Instant::now();
    let plan = VertexPlan::new(&integ, slots, &opts, Some(progress))?;
    let prepass_seconds = prepass_start.elapsed().as_secs_f64();
    let est = plan.estimate_memory(scene, &opts, rayon::current_num_threads());
    progress.note(&format!(
        "{}\nmemory estimate: {} peak ({} resident + the larger of basis build {} and trace {})",
        plan.report(scene, &opts),
        human_bytes(est.bytes),
        human_bytes(est.resident_bytes),
        human_bytes(est.basis_bytes),
        human_bytes(est.trace_bytes),
    ));
    if let Some(limit) = s.max_memory {
        if est.bytes > limit {
            return Err(BakeError::MemoryLimit {
                needed: est.bytes,
                limit,
            });
        }
    }
    let checkpoint = open_checkpoint(s.checkpoint, &checkpoint_dir, scene, &plan, &opts, progress)?;
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
    let bake = vertex::bake_vertex_checkpointed(
        &integ,
        &plan,
        &bases,
        &shading,
        &opts,
        checkpoint.as_ref(),
        Some(progress),
    )?;
    let file_bytes = vertex::write_vertex_file(&bake, &output)?;
    // Only once the output is in place: a kill before this point resumes from the checkpoint.
    if let Some(c) = checkpoint.filter(|_| !s.keep_checkpoint) {
        let dir = c.dir().to_path_buf();
        if let Err(e) = c.remove() {
            progress.warn(&format!(
                "the bake is written, but its checkpoint {} could not be removed ({e}); \
                 delete it",
                dir.display()
            ));
        }
    }
    Ok(VertexRunSummary {
        output,
        file_bytes,
        estimated_bytes: est.bytes,
        estimated_resident_bytes: est.resident_bytes,
        estimated_basis_bytes: est.basis_bytes,
        estimated_trace_bytes: est.trace_bytes,
        vertices: plan.grouped_vertices() as u64,
        seconds: start.elapsed().as_secs_f64(),
        basis_seconds,
        prepass_seconds,
        timings: bake.timings,
        stats: bake.meta.stats.clone(),
    })
}

/// The run's checkpoint in `dir`, per `mode`: none, a new one, or the existing one when its
/// inputs are this bake's (a resume without a checkpoint starts a new one, saying so).
fn open_checkpoint(
    mode: CheckpointMode,
    dir: &Path,
    scene: &Scene,
    plan: &VertexPlan,
    opts: &VertexBakeOptions,
    progress: &dyn Progress,
) -> Result<Option<Checkpoint>, VertexError> {
    if mode == CheckpointMode::Off {
        return Ok(None);
    }
    let fingerprint = Fingerprint::new(scene, plan, opts);
    if mode == CheckpointMode::Resume && dir.exists() {
        let c = Checkpoint::resume(dir, &fingerprint)?;
        let mut restored = 0;
        for (gi, g) in plan.groups.iter().enumerate() {
            for (wi, wave) in g.vertices.chunks(vertex::WAVE_VERTICES).enumerate() {
                if c.has(gi, wi) {
                    restored += wave.len();
                }
            }
        }
        progress.note(&format!(
            "resuming from {}: {restored} of {} vertices already traced",
            dir.display(),
            plan.grouped_vertices()
        ));
        return Ok(Some(c));
    }
    if mode == CheckpointMode::Resume {
        progress.note(&format!(
            "no checkpoint at {}: baking from the start",
            dir.display()
        ));
    }
    Ok(Some(Checkpoint::create(dir, &fingerprint)?))
}

/// Applies a `--set MATERIAL.PARAM=VALUE` edit to the scene's true BRDFs (for the reference
/// tracer). Errors name the material and what is wrong; which parameter fits which family is
/// [`Family::has_param`], the rule the runtime uses too.
pub fn apply_override(scene: &mut Scene, o: &MaterialOverride) -> Result<(), BakeError> {
    let Some(i) = scene.material_index(&o.material) else {
        let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
        return Err(prt_formats::check_material(&o.material, &names)
            .err()
            .unwrap_or_else(|| prt_formats::OverrideError::UnknownMaterial {
                name: o.material.clone(),
                available: names.join(", "),
            })
            .into());
    };
    let b = &mut scene.materials[i].brdf;
    let param = o.value.param();
    let wrong = BakeError::WrongParam {
        material: o.material.clone(),
        family: b.family,
        param: param.name(),
        valid: b.family.param_names().join(", "),
    };
    if !b.family.has_param(param) {
        return Err(wrong);
    }
    match o.value {
        OverrideValue::Kd(c) => b.kd = glam::Vec3::from_array(c),
        OverrideValue::Ks(c) => b.ks = glam::Vec3::from_array(c),
        OverrideValue::Shininess(v) | OverrideValue::Alpha(v) => b.param = v,
        // A parameter added to the syntax but not yet to the baker.
        _ => return Err(wrong),
    }
    Ok(())
}
