//! The per-vertex baker (thesis ch. 5; docs/vertex.md): per mesh vertex, the light arriving
//! from the environment directly (T0, sparse Haar rows per incident basis function of the
//! material's shading basis, and the visible fraction of each direction), after one
//! reflection (T1, per light bin, slot and SH coefficient in the vertex frame) and after two
//! (T2). `prt_formats::vertex` documents the file's meaning and layout; this module computes
//! exactly that.
//!
//! - [`prepare_scene`] (`prepare.rs`): the vertices welded where they share position, normal,
//!   UV and group, and ordered by group and unit; [`plan_units`] (`units.rs`) the units:
//!   super-clusters of up to 256 vertices by bisection, the unit of tracing, compression,
//!   checkpoints and shards;
//! - [`VertexPlan`] (`plan.rs`): the groups (one per material with vertices), the refusals
//!   (lights other than the environment, unsupported reflections), the pre-pass that finds
//!   each group's active slots, the allocation report; `memory.rs` its memory estimate;
//! - [`VertexTracer`] (`trace.rs`): one vertex traced into dense arrays ([`VertexResult`]), on
//!   the shared [`Integrator`]'s surfaces and the per-pixel mode's
//!   [`BakeModel`](crate::pixel::BakeModel) (slot evaluation and a coefficient-independent
//!   sampling mixture, so one trace serves every material setting); `direct.rs` its T0 rows,
//!   visibility and Haar truncation;
//! - [`bake_units`] (`bake.rs`, `unit.rs`): batches of units traced over all threads, each
//!   compressed (`compress.rs`, `cluster_choice.rs`) into a piece saved to the checkpoint
//!   folder ([`crate::shard::PieceStore`]); [`vertex_common`] what is known before tracing;
//! - [`assemble_vertex_file`] (`assemble.rs`): the file written from the pieces, streamed,
//!   whether they come from this run's folder or from shard files ([`crate::shard`]);
//! - [`vertex_fingerprints`] (`fingerprint.rs`): what the pieces depend on.
//!
//! `spp` means N1 in this mode: the directions traced from each vertex for T1 and T2.
//! The result does not depend on the thread count, the batch or the shards: every vertex's
//! sums run sequentially from its own random streams (`Rng::for_sample(seed, vertex, sample)`),
//! every unit's piece depends on its vertices alone, and group-wide figures are reduced in unit
//! order.

mod assemble;
mod bake;
mod bins;
mod cluster_choice;
mod compress;
mod direct;
mod error;
mod fingerprint;
mod frame;
mod memory;
mod plan;
mod prepare;
mod t0_choice;
mod trace;
mod unit;
mod units;
mod write;

#[cfg(test)]
mod tests;

use std::path::Path;
use std::time::Instant;

use prt_formats::basis::{BrdfBasis, ShadingBasis};
use prt_formats::clustered::CompressionSettings;
use prt_formats::pixel::Precision;
use prt_formats::vertex::{cube_len, VertexBakeMeta, DEFAULT_T0_TERMS, DIRECT_CUBE};

use crate::accel::Accel;
use crate::integrator::Integrator;
use crate::lights::LightSet;
use crate::pixel::SlotPlan;
use crate::progress::Progress;
use crate::scene::Scene;
use crate::shard::{checkpoint_folder, PieceStore};

pub use assemble::{assemble_vertex_file, Assembled, VertexCommon};
pub use bake::{bake_units, units_in_flight, vertex_common, UnitsDone, VertexTimings, BATCH_BYTES};
pub use cluster_choice::{unit_vertices, DEFAULT_PARTS};
pub use direct::{HaarTerms, T0_TEXELS};
pub use error::VertexError;
pub use fingerprint::vertex_fingerprints;
pub use memory::VertexMemoryEstimate;
pub use plan::{check_scene, vertex_materials, PlannedGroup, VertexPlan};
pub use prepare::{prepare_scene, prepare_scene_unwelded, PreparedScene};
pub use trace::{half_noise, VertexResult, VertexTracer};
#[doc(hidden)]
pub use trace::{EscapingPath, SecondBounce};
pub use units::{plan_units, Unit, UNIT_VERTICES};

/// Default N2 (`[vertex] secondary`).
pub const DEFAULT_SECONDARY: u32 = 4;
/// Largest N2 (`[vertex] secondary`).
pub const MAX_SECONDARY: u32 = 64;

/// Settings of a per-vertex bake.
#[derive(Clone, Debug, PartialEq)]
pub struct VertexBakeOptions {
    /// N1: directions traced from each vertex for T1 and T2 (the config's `spp`).
    pub samples: u32,
    /// N2: directions sampled at each first hit (`[vertex] secondary`).
    pub secondary: u32,
    /// 2 (T0, T1) or 3 (adds T2).
    pub reflections: u32,
    /// The seed of the random streams.
    pub seed: u64,
    /// Haar terms kept per T0 row (`[vertex] t0_terms`).
    pub t0_terms: usize,
    /// Storage of T0 values, T1 and T2.
    pub precision: Precision,
    /// T1 also draws one direction in every light bin per first hit, combined with the BRDF
    /// draws by multiple importance sampling (`[vertex] light_bins`, default true).
    pub light_bins: bool,
    /// Store T1 and T2 compressed with these settings (docs/vertex.md "Compression"), or
    /// dense when None.
    pub compression: Option<CompressionSettings>,
}

impl Default for VertexBakeOptions {
    /// 64 samples, 4 secondary directions, 2 reflections, seed 0, 96 terms, f16, light bins.
    fn default() -> Self {
        VertexBakeOptions {
            samples: crate::sampling::DEFAULT_SPP,
            secondary: DEFAULT_SECONDARY,
            reflections: 2,
            seed: 0,
            t0_terms: DEFAULT_T0_TERMS,
            precision: Precision::F16,
            light_bins: true,
            compression: None,
        }
    }
}

impl VertexBakeOptions {
    /// Refuses reflections other than 2 or 3 and counts out of range, naming them.
    pub fn validate(&self) -> Result<(), VertexError> {
        if !(2..=3).contains(&self.reflections) {
            return Err(VertexError::Reflections(self.reflections));
        }
        let range = |key, value: u64, lo: u64, hi: u64| {
            if value < lo || value > hi {
                Err(VertexError::OutOfRange { key, value, lo, hi })
            } else {
                Ok(())
            }
        };
        range(
            "spp",
            self.samples as u64,
            1,
            crate::sampling::MAX_SPP as u64,
        )?;
        range(
            "vertex.secondary",
            self.secondary as u64,
            1,
            MAX_SECONDARY as u64,
        )?;
        range(
            "vertex.t0_terms",
            self.t0_terms as u64,
            1,
            cube_len(DIRECT_CUBE) as u64,
        )?;
        if let Some(c) = &self.compression {
            validate_compression(c)?;
        }
        Ok(())
    }
}

/// Default relative L2 error of compressed T1 and T2 beyond their Monte Carlo noise
/// (`[vertex] compress_error`).
pub const DEFAULT_COMPRESS_ERROR: f32 = 0.1;
/// Default largest light rank (`[vertex] light_rank`): the thesis' light dimension.
pub const DEFAULT_LIGHT_RANK: u32 = 64;
/// Default largest element rank (`[vertex] element_rank`).
pub const DEFAULT_ELEMENT_RANK: u32 = 64;
/// Default largest vertex rank (`[vertex] vertex_rank`): the thesis' 32 eigenvectors.
pub const DEFAULT_VERTEX_RANK: u32 = 32;

/// The compression settings used when none are given but compression is on.
pub fn default_compression() -> CompressionSettings {
    CompressionSettings {
        error_target: DEFAULT_COMPRESS_ERROR,
        cluster_vertices: None,
        max_light_rank: DEFAULT_LIGHT_RANK,
        max_element_rank: DEFAULT_ELEMENT_RANK,
        max_vertex_rank: DEFAULT_VERTEX_RANK,
    }
}

/// Refuses compression settings that cannot work, naming the key.
fn validate_compression(c: &CompressionSettings) -> Result<(), VertexError> {
    if !(c.error_target.is_finite() && (0.0..1.0).contains(&c.error_target)) {
        return Err(VertexError::BadSetting {
            key: "vertex.compress_error",
            value: c.error_target.to_string(),
            reason: "a relative error in [0, 1)",
        });
    }
    for (key, v) in [
        ("vertex.cluster_vertices", c.cluster_vertices.unwrap_or(1)),
        ("vertex.light_rank", c.max_light_rank),
        ("vertex.element_rank", c.max_element_rank),
        ("vertex.vertex_rank", c.max_vertex_rank),
    ] {
        if v == 0 {
            return Err(VertexError::BadSetting {
                key,
                value: v.to_string(),
                reason: "at least 1",
            });
        }
    }
    Ok(())
}

/// What a per-vertex bake wrote.
#[derive(Clone, Debug)]
pub struct VertexBakeResult {
    /// The file's metadata as written.
    pub meta: VertexBakeMeta,
    /// Its size in bytes.
    pub file_bytes: u64,
    /// How long the bake took: reported by the tools, never written to the file.
    pub timings: VertexTimings,
    /// One line per compressed group: what was chosen and the errors.
    pub notes: Vec<String>,
    /// Groups that missed the error target, with what would meet it.
    pub warnings: Vec<String>,
}

/// Bakes `scene` per vertex into the file `output`: prepares the scene (welds and orders its
/// vertices, [`prepare_scene`]), builds the ray-query structure, plans the groups (the
/// pre-pass) and runs [`bake_vertex_with`]. `bases` are the PCA bases of the editable glossy
/// families, `shading` the shading bases of every family with a lobe that a group's material
/// uses (`prt_bake::basis::shading::default_shading_basis`; extra ones are ignored).
pub fn bake_vertex(
    scene: &Scene,
    bases: &[BrdfBasis],
    shading: &[ShadingBasis],
    opts: &VertexBakeOptions,
    output: &Path,
    progress: Option<&dyn Progress>,
) -> Result<VertexBakeResult, VertexError> {
    opts.validate()?;
    check_scene(scene)?;
    let prepared = prepare_scene_for(scene, opts);
    let scene = &prepared.scene;
    let counts: Vec<_> = bases.iter().map(|b| (b.family, b.num_bases)).collect();
    let slots = SlotPlan::per_unit_radiance(scene, &counts)?;
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let integ = Integrator::new(scene, &accel, &lights, opts.reflections as usize, 1, 1);
    let plan = VertexPlan::new(&integ, slots, opts, prepared.units, progress)?;
    bake_vertex_with(&integ, &plan, bases, shading, opts, output, progress)
}

/// [`prepare_scene`] with the units as large as `opts` needs ([`unit_vertices`]).
pub fn prepare_scene_for(scene: &Scene, opts: &VertexBakeOptions) -> PreparedScene {
    prepare::prepare_scene_with(
        scene,
        unit_vertices(opts.compression.and_then(|c| c.cluster_vertices)),
    )
}

/// Runs the bake of `plan` on the integrator it was planned with (its scene prepared by
/// [`prepare_scene`]) into the file `output`, through a scratch piece store beside it
/// (`<output>.partial/`, removed once the file is written; `bake` keeps it as a checkpoint
/// instead: `crate::run::run_vertex`).
pub fn bake_vertex_with(
    integ: &Integrator,
    plan: &VertexPlan,
    bases: &[BrdfBasis],
    shading: &[ShadingBasis],
    opts: &VertexBakeOptions,
    output: &Path,
    progress: Option<&dyn Progress>,
) -> Result<VertexBakeResult, VertexError> {
    let start = Instant::now();
    let layout = plan.layout(bases)?;
    let fingerprints = vertex_fingerprints(integ.scene, plan, opts);
    let dir = checkpoint_folder(output);
    let mut store = PieceStore::create(&dir, &fingerprints, false)?;
    let all: Vec<usize> = (0..plan.units.len()).collect();
    let result = (|| {
        let done = bake_units(
            integ, plan, shading, &layout, opts, &all, &mut store, false, progress,
        )?;
        let (common, tensors) = vertex_common(integ.scene, plan, &layout, shading, opts)?;
        let write_start = Instant::now();
        let a = assemble_vertex_file(&common, &tensors, &store, output)?;
        Ok::<_, VertexError>((done, a, write_start.elapsed().as_secs_f64()))
    })();
    let removed = store.remove();
    let (done, a, write_seconds) = result?;
    removed?;
    Ok(VertexBakeResult {
        meta: a
            .meta
            .ok_or_else(|| VertexError::Inconsistent("no metadata written".into()))?,
        file_bytes: a.file_bytes,
        timings: timings(&done, write_seconds, start),
        notes: a.notes,
        warnings: a.warnings,
    })
}

/// The timings of a bake from what its units did.
pub fn timings(done: &UnitsDone, write_seconds: f64, start: Instant) -> VertexTimings {
    VertexTimings {
        trace_seconds: done.trace_seconds,
        compress_seconds: done.compress_seconds,
        write_seconds,
        bake_seconds: start.elapsed().as_secs_f64(),
        vertices_per_second: done.traced_vertices as f64 / done.trace_seconds.max(1e-9),
        rays_per_second: done.traced_rays as f64 / done.trace_seconds.max(1e-9),
    }
}
