//! The per-vertex baker (thesis ch. 5; docs/vertex.md): per mesh vertex, the light arriving
//! from the environment directly (T0, sparse Haar rows per incident basis function of the
//! material's shading basis, and the visible fraction of each direction), after one
//! reflection (T1, per light bin, slot and SH coefficient in the vertex frame) and after two
//! (T2). `prt_formats::vertex` documents the file's meaning and layout; this module computes
//! exactly that.
//!
//! - [`VertexPlan`] (`plan.rs`): the groups (one per material with vertices), the refusals
//!   (lights other than the environment, unsupported reflections), the pre-pass that finds
//!   each group's active slots, the allocation report; `memory.rs` its memory estimate;
//! - [`VertexTracer`] (`trace.rs`): one vertex traced into dense arrays ([`VertexResult`]), on
//!   the shared [`Integrator`]'s surfaces and the per-pixel mode's
//!   [`BakeModel`](crate::pixel::BakeModel) (slot evaluation and a coefficient-independent
//!   sampling mixture, so one trace serves every material setting); `direct.rs` its T0 rows,
//!   visibility and Haar truncation;
//! - [`bake_vertex_with`] (`bake.rs`): every group in fixed blocks of vertices (rayon), storage
//!   precision and per-group scales, the metadata;
//! - [`write_vertex_file`] (`write.rs`): the file, written atomically;
//! - [`Checkpoint`] (`checkpoint.rs`): the traced waves saved beside the output as the bake
//!   goes, so that a killed bake resumes; [`Fingerprint`] (`fingerprint.rs`) what they belong
//!   to.
//!
//! `spp` means N1 in this mode: the directions traced from each vertex for T1 and T2.
//! The result does not depend on the thread count: every vertex's sums run sequentially from
//! its own random streams (`Rng::for_sample(seed, vertex, sample)`), results are placed by
//! vertex index, and group-wide figures are reduced in vertex order.

mod bake;
mod bins;
mod buffers;
mod checkpoint;
mod cluster;
mod cluster_choice;
mod compress;
mod direct;
mod error;
mod fingerprint;
mod frame;
mod memory;
mod plan;
mod t0_choice;
mod trace;
mod write;

#[cfg(test)]
mod tests;

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

pub use bake::{bake_vertex_checkpointed, bake_vertex_with, VertexTimings, WAVE_VERTICES};
pub use checkpoint::{checkpoint_folder, Checkpoint};
pub use direct::T0_TEXELS;
pub use error::{CheckpointError, VertexError};
pub use fingerprint::Fingerprint;
pub use memory::VertexMemoryEstimate;
pub use plan::{check_scene, vertex_materials, PlannedGroup, VertexPlan};
#[doc(hidden)]
pub use trace::{EscapingPath, SecondBounce};
pub use trace::{VertexResult, VertexTracer};
pub use write::{vertex_file_bytes, write_vertex_file, Stored, StoredTucker};

/// Largest N2 (`[vertex] secondary`).
pub const MAX_SECONDARY: u32 = crate::config::MAX_SECONDARY;

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
            samples: crate::config::DEFAULT_SPP,
            secondary: crate::config::DEFAULT_SECONDARY,
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
        range("spp", self.samples as u64, 1, crate::config::MAX_SPP as u64)?;
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

/// Default relative L2 error per cluster of compressed T1 and T2 (`[vertex] compress_error`).
pub const DEFAULT_COMPRESS_ERROR: f32 = 0.1;
/// Vertices per cluster tried when `[vertex] cluster_vertices` is not given (the default):
/// each group keeps the one that meets the error target at the smallest size.
pub use cluster_choice::AUTO_CLUSTER_VERTICES;
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

/// One group's tensors as they will be stored.
pub struct VertexGroupData {
    /// Global vertex indices, ascending.
    pub vertices: Vec<u32>,
    /// `[vertices, t0_rows, K]` Haar indices (K: the group's `t0_terms` when compressed, or
    /// the bake's).
    pub t0_index: Vec<u16>,
    /// `[vertices, t0_rows, K]` Haar values (divided by the group's `scale_t0`).
    pub t0_value: Stored,
    /// `[vertices, 6 * 16 * 16]` visible fractions, 255 = all, for a group with a specular
    /// lobe; empty (`[vertices, 0]`) for one without.
    pub visibility: Vec<u8>,
    /// `[vertices, 384, J, 16, channels]` (divided by `scale_t1`).
    pub t1: Stored,
    /// `[vertices, 24, J, I, channels]` (divided by `scale_t2`); empty when reflections = 2.
    pub t2: Stored,
    /// T1 and T2 compressed (then `t1` and `t2` are empty).
    pub compressed: Option<CompressedGroupData>,
}

/// A group's T1 and T2 stored compressed (`prt_formats::clustered`).
pub struct CompressedGroupData {
    /// The cluster of each vertex of the group.
    pub clusters: Vec<u32>,
    /// T1 (its core divided by `scale_t1`).
    pub t1: StoredTucker,
    /// T2 (its core divided by `scale_t2`), when the bake has T2.
    pub t2: Option<StoredTucker>,
}

/// The result of a per-vertex bake, ready to be written ([`write_vertex_file`]).
pub struct VertexBake {
    /// Everything the file's metadata holds (inputs and deterministic figures only).
    pub meta: VertexBakeMeta,
    /// How long the bake took: reported by the tools, never written to the file.
    pub timings: VertexTimings,
    /// One per `meta.groups`.
    pub groups: Vec<VertexGroupData>,
    /// The shading bases with their tables (`meta.shading` holds them emptied).
    pub shading: Vec<ShadingBasis>,
    /// Tables of `meta.bases` (as stored in `basis.<i>.tables`).
    pub basis_tables: Vec<Vec<f32>>,
    /// The mesh, flat: positions and normals `[V, 3]`, uvs `[V, 2]`, triangles `[T, 3]`,
    /// triangle materials `[T]`.
    pub mesh: MeshData,
    /// The lat-long environment `[h, w, 3]` (empty for a constant one).
    pub environment: Vec<f32>,
    /// Per `meta.textures`, its texels `[h, w, 3]`.
    pub textures: Vec<Vec<f32>>,
}

/// The mesh tensors of a per-vertex bake, flat.
pub struct MeshData {
    /// `[V, 3]` world positions.
    pub positions: Vec<f32>,
    /// `[V, 3]` the unit normals the vertices were baked with.
    pub normals: Vec<f32>,
    /// `[V, 2]`.
    pub uvs: Vec<f32>,
    /// `[T, 3]`.
    pub triangles: Vec<u32>,
    /// `[T]`.
    pub triangle_material: Vec<u32>,
}

/// Bakes `scene` per vertex: builds the ray-query structure, plans the groups (the pre-pass),
/// and runs [`bake_vertex_with`]. `bases` are the PCA bases of the editable glossy families,
/// `shading` the shading bases of every family with a lobe that a group's material uses
/// (`prt_bake::basis::shading::default_shading_basis`; extra ones are ignored).
pub fn bake_vertex(
    scene: &Scene,
    bases: &[BrdfBasis],
    shading: &[ShadingBasis],
    opts: &VertexBakeOptions,
    progress: Option<&dyn Progress>,
) -> Result<VertexBake, VertexError> {
    opts.validate()?;
    check_scene(scene)?;
    let counts: Vec<_> = bases.iter().map(|b| (b.family, b.num_bases)).collect();
    let slots = SlotPlan::per_unit_radiance(scene, &counts)?;
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let integ = Integrator::new(scene, &accel, &lights, opts.reflections as usize, 1, 1);
    let plan = VertexPlan::new(&integ, slots, opts, progress)?;
    bake_vertex_with(&integ, &plan, bases, shading, opts, progress)
}
