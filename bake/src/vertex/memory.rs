//! The per-vertex bake's memory estimate, printed before tracing and checked against
//! `--max-memory` (by default the machine's available memory) before the bases are built and
//! the vertices traced. It models the peak resident memory phase by phase from what the code
//! allocates (docs/vertex.md, "Bounded memory"):
//! - **resident** throughout: the process, the loaded scene and the prepared one (welded and
//!   ordered), the ray-query structure, the plan's per-vertex arrays;
//! - **basis builds**, one at a time: a PCA basis (the per-pixel model) or a default shading
//!   basis (measured);
//! - **units in flight**: per unit its dense f32 tensors, its T0 terms and visibility, the
//!   compression's f64 working copies and its piece ([`VertexPlan::unit_bytes`]), times the
//!   units in flight ([`super::bake::units_in_flight`]); the workers' scratch; the common
//!   tensors (flat copies of the mesh and environment for the file).
//!
//! Nothing here grows with the vertex count but the scene and the plan's arrays: the units'
//! tensors go to disk as pieces, and the file is written from them piece by piece.

use prt_formats::vertex::{cube_len, T1_LIGHT_CUBE, VISIBILITY_CUBE};

use crate::pixel::memory::{bases_build_bytes, scene_bytes, PROCESS_BYTES};
use crate::scene::{Environment, Scene};

use super::direct::T0_TEXELS;
use super::plan::VertexPlan;
use super::VertexBakeOptions;

/// Peak resident memory of building one default shading basis: 65 MB measured for the ring
/// build (docs/brdf-basis.md, "Defaults and cost"), rounded up to 96 MB.
const SHADING_BUILD_BYTES: u64 = 96 << 20;

/// Bytes per vertex of the plan's and the tracer's per-vertex arrays (normals, groups, units,
/// the pre-pass's results).
const PLAN_BYTES_PER_VERTEX: u64 = 48;

impl VertexPlan {
    /// The bake's peak memory, modelled phase by phase as the code allocates (see
    /// [`VertexMemoryEstimate`]).
    pub fn estimate_memory(
        &self,
        scene: &Scene,
        opts: &VertexBakeOptions,
        threads: usize,
    ) -> VertexMemoryEstimate {
        let vertices = scene.positions.len() as u64;
        // The loaded scene and the prepared one (about the same size) are both held.
        let resident_bytes =
            PROCESS_BYTES + 2 * scene_bytes(scene) + vertices * PLAN_BYTES_PER_VERTEX;
        let pca = bases_build_bytes(&self.slots.basis_families);
        let shading = if self.shading_families().is_empty() {
            0
        } else {
            SHADING_BUILD_BYTES
        };
        let basis_bytes = pca.max(shading);
        let in_flight = super::bake::units_in_flight(self, opts, threads) as u64;
        let units = in_flight * self.unit_bytes(opts);
        // Per worker thread: the dense T0 rows of one vertex (f32) and their Haar transform
        // (f64 inside), the f64 T1 and T2 sums with their odd-sample halves.
        let worker: u64 = self
            .groups
            .iter()
            .map(|g| {
                let rows = g.planned_t0_rows();
                let (_, t1, t2) = self.values_per_vertex(g, rows, opts);
                (rows * T0_TEXELS * (4 + 8 + 8 + 4)) as u64 + (t1 + t2) as u64 * 16
            })
            .max()
            .unwrap_or(0);
        // Flat copies of the mesh, environment and textures for the file (the common part),
        // and the clusters' numbering of a group while it is written.
        let env_texels = match &scene.environment {
            Environment::Constant(_) => 0,
            Environment::LatLong { texels, .. } => texels.len(),
        };
        let tex_texels: usize = scene.textures.iter().map(|t| t.texels.len()).sum();
        let copies = (scene.positions.len() * 36
            + scene.triangles.len() * 16
            + (env_texels + tex_texels) * 12) as u64;
        let trace_bytes = units + worker * threads.max(1) as u64 + copies;
        VertexMemoryEstimate {
            bytes: resident_bytes + basis_bytes.max(trace_bytes),
            resident_bytes,
            basis_bytes,
            trace_bytes,
            units_in_flight: in_flight as usize,
            unit_bytes: self.unit_bytes(opts),
        }
    }

    /// The most bytes one unit in flight holds: its dense f32 T1 and T2, its T0 terms and
    /// visibility, and when compressed the f64 working copies of a cluster block (the
    /// element-projected block and its light-mode copy, at most 64 elements wide) and the
    /// piece being built (at most the dense size).
    pub fn unit_bytes(&self, opts: &VertexBakeOptions) -> u64 {
        self.groups
            .iter()
            .enumerate()
            .map(|(gi, g)| {
                let n = self
                    .units
                    .iter()
                    .filter(|u| u.group == gi)
                    .map(|u| u.vertices.len())
                    .max()
                    .unwrap_or(0) as u64;
                let rows = g.planned_t0_rows();
                let (t0, t1, t2) = self.values_per_vertex(g, rows, opts);
                let dense = (t1 + t2) as u64 * 4;
                let t0_bytes = t0 as u64 * 6
                    + if g.lobe.is_some() {
                        cube_len(VISIBILITY_CUBE) as u64
                    } else {
                        0
                    };
                let work = opts.compression.map_or(0, |c| {
                    let width = (t1 / cube_len(T1_LIGHT_CUBE)).min(c.max_element_rank as usize);
                    2 * (cube_len(T1_LIGHT_CUBE) * width) as u64 * 8 + dense
                });
                n * (dense + t0_bytes + work)
            })
            .max()
            .unwrap_or(0)
    }
}

/// Memory estimate of a per-vertex bake, in bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct VertexMemoryEstimate {
    /// The estimated peak: `resident_bytes` plus the larger of the basis builds and the trace.
    /// This is what `--max-memory` is checked against.
    pub bytes: u64,
    /// Held throughout: the process, the scenes, the ray-query structure, the plan.
    pub resident_bytes: u64,
    /// Peak of building one basis (PCA or shading; one at a time).
    pub basis_bytes: u64,
    /// Peak of the trace and write: the units in flight, the workers' scratch, the common
    /// tensors.
    pub trace_bytes: u64,
    /// Units traced and compressed at once.
    pub units_in_flight: usize,
    /// The most one unit holds.
    pub unit_bytes: u64,
}
