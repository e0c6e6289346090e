//! The `bake` command's jobs, as library functions: load a config's scene, build the bases
//! its editable materials need, bake (whole or one shard), write; merge shards. The binaries
//! only parse arguments and show progress ([`Progress`]).
//!
//! - this file: loading, the bases, `--set` edits;
//! - `pixel.rs` ([`run_pixel`]), `vertex.rs` ([`run_vertex`]): a bake of each mode;
//! - `merge.rs` ([`run_merge`]): shard files into the bake file;
//! - `memory.rs`: the memory check both modes run before tracing.

mod memory;
mod merge;
mod pixel;
mod vertex;

pub use memory::{available_memory, memory_limit, EstimatedMemory};
pub use merge::{run_merge, MergeSummary};
pub use pixel::{run_pixel, PixelRunSettings, PixelRunSummary};
pub use vertex::{run_vertex, CheckpointMode, VertexRunSettings, VertexRunSummary};

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

use prt_formats::basis::BrdfBasis;
use prt_formats::{MaterialOverride, OverrideValue};

use crate::basis::{BasisBuilder, BasisConfig};
use crate::brdf::{Family, Lobe};
use crate::config::BakeConfig;
use crate::error::BakeError;
use crate::progress::Progress;
use crate::scene::Scene;
use crate::shard::ShardSpec;

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
pub(crate) fn basis_count_setting(config: &BakeConfig, explicit: Option<usize>) -> BasisCount {
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

/// The shard file of a bake whose output is `output`: `<output>.shard-<I>-of-<N>`.
pub fn shard_output(output: &Path, spec: ShardSpec) -> PathBuf {
    let mut name = output.as_os_str().to_os_string();
    name.push(format!(".shard-{}-of-{}", spec.index, spec.count));
    PathBuf::from(name)
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
