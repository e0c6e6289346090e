//! The bake's memory estimate, printed before baking and checked against `--max-memory`
//! before any expensive work (the basis build and the trace both come after it).
//!
//! The estimate models the process's peak resident memory, phase by phase, from what the code
//! allocates (docs/pixel.md, "Memory"):
//! - **resident** throughout: the scene, the ray-query structure and the process itself;
//! - **basis build**, one family at a time: the tabulated lobes, their residual and the
//!   weighted copy the QR factors in place, each `nodes x samples` f64;
//! - **trace and write**: the dense rows of every (pixel, visible material) with their
//!   per-row bookkeeping; after the trace the rows are compacted and transposed for the file
//!   (at most the dense size each). The dense rows are many small blocks that the allocator
//!   keeps for reuse rather than returning to the system, so the process's resident size
//!   holds all three at the write.
//!
//! The peak is the resident part plus the larger phase.

use prt_formats::pixel::{row_len, Precision};
use prt_formats::Family;
use rayon::prelude::*;

use crate::basis::BasisConfig;
use crate::integrator::Integrator;
use crate::scene::{Environment, Scene};

use super::layout::SlotPlan;

/// The process's own footprint (code, libraries, allocator arenas, thread stacks): the peak
/// resident size of a `bake` of `furnace.glb` (no basis to build) at 256x256, 14 MiB, less
/// its modelled scene and trace, rounded.
pub(crate) const PROCESS_BYTES: u64 = 10 << 20;

/// Bytes the ray-query structure holds per triangle: the packed triangle (three 16-byte
/// vectors), its original index, and the wide BVH's nodes and primitive indices.
const ACCEL_BYTES_PER_TRIANGLE: u64 = 48 + 4 + 40;

/// Bookkeeping per dense row: its `Vec` header, the (pixel, material) tag, and the
/// allocator's per-block overhead.
const ROW_OVERHEAD_BYTES: u64 = 24 + 8 + 16;

/// Copies of the `nodes x samples` lobe table alive at once while a basis is built.
const BASIS_TABLE_COPIES: u64 = 3;

/// Memory estimate of a per-pixel bake, in bytes.
pub struct MemoryEstimate {
    /// The estimated peak: `resident_bytes` plus the larger of the two phases. This is what
    /// `--max-memory` is checked against.
    pub bytes: u64,
    /// Held throughout: the process, the scene and the ray-query structure.
    pub resident_bytes: u64,
    /// Peak of the basis build (families are built one at a time; 0 without editable glossy
    /// materials).
    pub basis_bytes: u64,
    /// Peak of the trace and the file write.
    pub trace_bytes: u64,
    /// Pixels (of four primary rays each) that see each material.
    pub pixels_per_material: Vec<u64>,
    /// Dense row length of each material.
    pub values_per_pixel: Vec<usize>,
}

/// Bytes the scene's arrays hold, plus the ray-query structure built over it.
pub fn scene_bytes(scene: &Scene) -> u64 {
    let texels: usize = scene.textures.iter().map(|t| t.texels.len()).sum::<usize>()
        + match &scene.environment {
            Environment::Constant(_) => 0,
            Environment::LatLong { texels, .. } => texels.len(),
        };
    let bytes = scene.positions.len() * 12
        + scene.normals.len() * 12
        + scene.uvs.len() * 8
        + scene.triangles.len() * (12 + 4)
        + texels * 12;
    bytes as u64 + scene.triangles.len() as u64 * ACCEL_BYTES_PER_TRIANGLE
}

/// Peak bytes of building one basis of `family` with the baker's default configuration.
pub fn basis_build_bytes(family: Family) -> u64 {
    // The table size does not depend on the number of bases; any valid count will do.
    BasisConfig::new(family, 2).map_or(0, |c| {
        BASIS_TABLE_COPIES * (c.grid_spec().len() * c.param_samples * 8) as u64
    })
}

/// Peak bytes of building the bases of `families` (family, basis count): all at once, as
/// [`crate::run::build_counted_bases`] does.
pub fn bases_build_bytes(families: &[(Family, usize)]) -> u64 {
    families.iter().map(|&(f, _)| basis_build_bytes(f)).sum()
}

/// Estimates the bake's peak memory. Counts the materials visible per pixel with four
/// primary rays per pixel and sizes the dense accumulation rows from the planned slots.
pub fn estimate_memory(
    integ: &Integrator,
    plan: &SlotPlan,
    reflections: usize,
    precision: Precision,
) -> MemoryEstimate {
    let n = plan.materials.len();
    let (w, h) = (integ.width, integ.height);
    let counts = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut counts = vec![0u64; n];
            let mut seen = Vec::with_capacity(4);
            for x in 0..w {
                seen.clear();
                for (dx, dy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                    let (o, d) = integ.camera_ray(x as f32 + dx, y as f32 + dy);
                    if let Some(hit) = integ.accel.intersect(o, d, 0.0, f32::INFINITY) {
                        let m = integ.scene.triangle_material[hit.triangle as usize];
                        if !seen.contains(&m) {
                            seen.push(m);
                            counts[m as usize] += 1;
                        }
                    }
                }
            }
            counts
        })
        .reduce(
            || vec![0u64; n],
            |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
        );
    let values: Vec<usize> = plan
        .materials
        .iter()
        .map(|m| row_len(m.slots.len(), plan.total_slots, reflections, plan.channels))
        .collect();
    let dense: u64 = counts
        .iter()
        .zip(&values)
        .map(|(&p, &v)| p * (v as u64 * 4 + ROW_OVERHEAD_BYTES))
        .sum();
    let dense_values: u64 = counts
        .iter()
        .zip(&values)
        .map(|(&p, &v)| p * v as u64 * 4)
        .sum();
    // The write adds the compacted rows and their transposed copy (each at most the dense
    // size), plus an f16 copy of the transposed one, to the dense rows' blocks.
    let write = 2 * dense_values
        + match precision {
            Precision::F32 => 0,
            Precision::F16 => dense_values / 2,
        };
    let image = w as u64 * h as u64 * 12;
    let trace_bytes = dense + write + image;
    let basis_bytes = bases_build_bytes(&plan.basis_families);
    let resident_bytes = PROCESS_BYTES + scene_bytes(integ.scene);
    MemoryEstimate {
        bytes: resident_bytes + trace_bytes.max(basis_bytes),
        resident_bytes,
        basis_bytes,
        trace_bytes,
        pixels_per_material: counts,
        values_per_pixel: values,
    }
}
