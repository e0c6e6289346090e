//! The bake's working-memory estimate, printed before baking and checked against
//! `--max-memory` before any expensive work.

use prt_formats::pixel::row_len;
use rayon::prelude::*;

use crate::integrator::Integrator;

use super::layout::SlotLayout;

/// Working-memory estimate of the bake: the dense rows of every (pixel, visible material).
pub struct MemoryEstimate {
    pub bytes: u64,
    pub pixels_per_material: Vec<u64>,
    pub values_per_pixel: Vec<usize>,
}

/// Counts the materials visible per pixel with a few primary rays per pixel, and sizes the
/// dense accumulation rows from that.
pub fn estimate_memory(
    integ: &Integrator,
    layout: &SlotLayout,
    reflections: usize,
) -> MemoryEstimate {
    let n = layout.materials.len();
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
    let values: Vec<usize> = layout
        .materials
        .iter()
        .map(|m| {
            row_len(
                m.slots.len(),
                layout.total_slots,
                reflections,
                layout.channels,
            )
        })
        .collect();
    let bytes = counts
        .iter()
        .zip(&values)
        .map(|(&p, &v)| p * v as u64 * 4)
        .sum::<u64>()
        + (w as u64 * h as u64 * 12);
    MemoryEstimate {
        bytes,
        pixels_per_material: counts,
        values_per_pixel: values,
    }
}
