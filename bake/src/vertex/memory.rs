//! The per-vertex bake's memory estimate, printed before tracing and checked against
//! `--max-memory` before the bases are built and the vertices traced. It models the peak
//! resident memory phase by phase from what the code allocates:
//! - **resident** throughout: the process, the scene and the ray-query structure (the
//!   per-pixel model's figures);
//! - **basis builds**, one at a time: a PCA basis (the per-pixel model) or a default shading
//!   basis (measured);
//! - **trace and write**: everything the groups store, the largest group's f32 values before
//!   their conversion to f16 or their compression, the workers' scratch (or, when larger, the
//!   compression's cluster blocks), the flat copies written to the file. Compressed, what the
//!   groups store is bounded by the rank caps (`compressed_bytes`).

use prt_formats::pixel::Precision;
use prt_formats::vertex::{cube_len, VISIBILITY_CUBE};

use crate::pixel::memory::{bases_build_bytes, scene_bytes, PROCESS_BYTES};
use crate::scene::{Environment, Scene};

use super::cluster_choice::candidate_sizes;
use super::direct::T0_TEXELS;
use super::plan::VertexPlan;
use super::VertexBakeOptions;

/// Peak resident memory of building one default shading basis: 65 MB measured for the ring
/// build (docs/brdf-basis.md, "Defaults and cost"), rounded up to 96 MB.
const SHADING_BUILD_BYTES: u64 = 96 << 20;

impl VertexPlan {
    /// The bake's peak memory, modelled phase by phase as the code allocates (see
    /// [`VertexMemoryEstimate`]).
    pub fn estimate_memory(
        &self,
        scene: &Scene,
        opts: &VertexBakeOptions,
        threads: usize,
    ) -> VertexMemoryEstimate {
        let resident_bytes = PROCESS_BYTES + scene_bytes(scene);
        let pca = bases_build_bytes(&self.slots.basis_families);
        let shading = if self.shading_families().is_empty() {
            0
        } else {
            SHADING_BUILD_BYTES
        };
        let basis_bytes = pca.max(shading);
        let group_bytes: Vec<u64> = self
            .groups
            .iter()
            .map(|g| self.bytes_per_vertex(g, opts) * g.vertices.len() as u64)
            .collect();
        // Compressed, the dense tensors are never stored: the output is the factors (bounded
        // by the rank caps), and compressing a group needs its f32 values (below) plus each
        // thread's cluster block in f64, about three copies of it.
        let stored: u64 = match &opts.compression {
            None => group_bytes.iter().sum(),
            Some(c) => self
                .groups
                .iter()
                .map(|g| self.compressed_bytes(g, c, opts))
                .sum(),
        };
        let compress_work = opts.compression.map_or(0, |c| {
            let block = self
                .groups
                .iter()
                .map(|g| {
                    let (_, t1, t2) = self.values_per_vertex(g, g.planned_t0_rows(), opts);
                    let largest = candidate_sizes(c.cluster_vertices, g.vertices.len())
                        .into_iter()
                        .max()
                        .unwrap_or(1);
                    let n = g.vertices.len().min(2 * largest as usize);
                    3 * 8 * (n * t1.max(t2)) as u64
                })
                .max()
                .unwrap_or(0);
            block * threads.max(1) as u64
        });
        // A group is traced into f32 buffers, converted to its storage, and the f32 freed:
        // with f16 storage the largest group's f32 values are held beside everything stored.
        let f32_group = match (opts.precision, &opts.compression) {
            (Precision::F32, None) => 0,
            _ => self
                .groups
                .iter()
                .map(|g| {
                    let (t0, t1, t2) = self.values_per_vertex(g, g.planned_t0_rows(), opts);
                    (t0 + t1 + t2) as u64 * 4 * g.vertices.len() as u64
                })
                .max()
                .unwrap_or(0),
        };
        // Per worker thread: the dense T0 rows of one vertex (f32) and their Haar transform
        // (f64 inside, f32 out), the f64 T1 and T2 sums; and one wave of finished blocks.
        let worker: u64 = self
            .groups
            .iter()
            .map(|g| {
                let rows = g.planned_t0_rows();
                let (t0, t1, t2) = self.values_per_vertex(g, rows, opts);
                let dense = (rows * T0_TEXELS * (4 + 8 + 8 + 4)) as u64;
                let sums = (t1 + t2) as u64 * 8;
                let wave = super::bake::WAVE_VERTICES as u64
                    * ((t0 * 6 + t1 * 4 + t2 * 4) as u64 + cube_len(VISIBILITY_CUBE) as u64)
                    / threads.max(1) as u64;
                dense + sums + wave
            })
            .max()
            .unwrap_or(0);
        // Flat copies of the mesh, environment and textures for the file.
        let env_texels = match &scene.environment {
            Environment::Constant(_) => 0,
            Environment::LatLong { texels, .. } => texels.len(),
        };
        let tex_texels: usize = scene.textures.iter().map(|t| t.texels.len()).sum();
        let copies = (scene.positions.len() * 32
            + scene.triangles.len() * 16
            + (env_texels + tex_texels) * 12) as u64;
        let trace_bytes =
            stored + f32_group + (worker * threads.max(1) as u64).max(compress_work) + copies;
        VertexMemoryEstimate {
            bytes: resident_bytes + basis_bytes.max(trace_bytes),
            resident_bytes,
            basis_bytes,
            trace_bytes,
            stored_bytes: stored,
            group_bytes,
        }
    }
}

/// Memory estimate of a per-vertex bake, in bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct VertexMemoryEstimate {
    /// The estimated peak: `resident_bytes` plus the larger of the basis builds and the trace.
    /// This is what `--max-memory` is checked against.
    pub bytes: u64,
    /// Held throughout: the process, the scene and the ray-query structure.
    pub resident_bytes: u64,
    /// Peak of building one basis (PCA or shading; one at a time).
    pub basis_bytes: u64,
    /// Peak of the trace and write: everything stored, the f32 values of the largest group
    /// before conversion (f16 storage), the workers' scratch, flat copies for the file.
    pub trace_bytes: u64,
    /// What the groups store.
    pub stored_bytes: u64,
    /// Per group, its stored bytes.
    pub group_bytes: Vec<u64>,
}

impl VertexPlan {
    /// An upper bound of what group `g` stores when compressed with `c`: T0, the visibility of
    /// a group with a lobe, the cluster of each vertex, and per compressed tensor its factors,
    /// cores and vertex rows at the rank caps (clusters of `cluster_vertices`, or of whichever
    /// candidate size would store the most when it is chosen per group).
    fn compressed_bytes(
        &self,
        g: &super::plan::PlannedGroup,
        c: &prt_formats::clustered::CompressionSettings,
        opts: &VertexBakeOptions,
    ) -> u64 {
        use prt_formats::vertex::{T1_LIGHT_CUBE, T2_LIGHT_CUBE};
        let p = super::write::value_bytes(opts.precision) as u64;
        let v = g.vertices.len() as u64;
        let (t0, t1, t2) = self.values_per_vertex(g, g.planned_t0_rows(), opts);
        let tucker = |size: u32, bins: usize, values: usize| -> u64 {
            if values == 0 {
                return 0;
            }
            let clusters = v.div_ceil(u64::from(size.max(1)));
            let b = u64::from(c.max_vertex_rank.min(size.saturating_mul(2)));
            let width = (values / bins) as u64;
            let a = u64::from(c.max_light_rank).min(bins as u64);
            let r = u64::from(c.max_element_rank).min(width);
            (clusters * (bins as u64 * a + width * r + b * a * r) + v * b) * p
        };
        let tuckers = candidate_sizes(c.cluster_vertices, g.vertices.len())
            .into_iter()
            .map(|size| {
                tucker(size, cube_len(T1_LIGHT_CUBE), t1)
                    + tucker(size, cube_len(T2_LIGHT_CUBE), t2)
            })
            .max()
            .unwrap_or(0);
        let visibility = if g.lobe.is_some() {
            cube_len(VISIBILITY_CUBE) as u64
        } else {
            0
        };
        v * (8 + t0 as u64 * (2 + p) + visibility) + tuckers
    }
}
