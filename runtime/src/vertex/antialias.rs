//! Antialiased silhouettes and creases (docs/vertex.md, "Silhouettes are antialiased").
//!
//! The view stage shades one point per pixel, where the ray through the pixel's centre meets
//! the geometry; a path tracer averages its jittered rays over the pixel. Where a pixel holds
//! two surfaces (an object's outline against the floor or the sky, a tube of the knot in front
//! of another, a facet's crease) the centre gives all of the pixel to one of them: on the
//! gallery at 128 x 128 this was 9.5 % of the image's 12.7 % error against converged ground
//! truth, and the background region's mean 0.62 of the truth's (docs/report-vertex.md, "Error
//! budget").
//!
//! After the pixels are shaded, a pixel is chosen for sampling when one of its four neighbours
//! sees a different surface (one sees nothing and the other something, or their triangles
//! share no vertex) and its colour differs by more than [`CONTRAST`]: a silhouette, an occluding
//! contour or a shading crease, not the inside of a smooth mesh. Each chosen pixel is
//! rasterized again at 16 sample positions (`raster/samples.rs`) and becomes the sum of its
//! surfaces' shades, each surface shaded once at the centroid of its samples and weighted by
//! their share (the environment's part: the mean radiance along its samples' rays), as a
//! GPU's multisampling resolves a pixel.

use rayon::prelude::*;

use super::raster::samples::{offsets, Part, SAMPLES};
use super::raster::VisibilityBuffer;
use super::shade::ViewInputs;
use super::view::{ViewRays, NO_TRIANGLE};

// A part's samples are a u16 mask.
const _: () = assert!(SAMPLES <= 16);

/// How much two neighbouring pixels' colours (the sum of their RGB) must differ, relative to
/// the brighter, for the pixels to be sampled: below it, giving a whole pixel to one side moves
/// the pixel by less than this, and sampling it would cost more than it buys.
pub(crate) const CONTRAST: f32 = 0.02;

/// The pixels (row-major indices, ascending) of the shaded image `image` (RGB rows) whose
/// visibility `vis` and colour change across an edge to a neighbour, into `out` (replaced).
pub(super) fn edge_pixels(
    vis: &VisibilityBuffer,
    triangles: &[[u32; 3]],
    image: &[f32],
    out: &mut Vec<u32>,
) {
    let (w, h) = (vis.width as usize, vis.height as usize);
    let frags = &vis.fragments;
    let level = |p: usize| image[3 * p] + image[3 * p + 1] + image[3 * p + 2];
    let differs = |a: usize, b: usize| -> bool {
        let (ta, tb) = (frags[a].triangle, frags[b].triangle);
        let distinct = if ta == NO_TRIANGLE || tb == NO_TRIANGLE {
            ta != tb
        } else {
            ta != tb && {
                let (va, vb) = (triangles[ta as usize], triangles[tb as usize]);
                !va.iter().any(|v| vb.contains(v))
            }
        };
        if !distinct {
            return false;
        }
        let (la, lb) = (level(a), level(b));
        // NaN (never expected: shaded pixels are finite) counts as a difference.
        matches!(
            (la - lb).abs().partial_cmp(&(CONTRAST * la.max(lb))),
            Some(std::cmp::Ordering::Greater) | None
        )
    };
    out.clear();
    out.par_extend((0..w * h).into_par_iter().filter_map(|p| {
        let (x, y) = (p % w, p / w);
        let hit = (x > 0 && differs(p, p - 1))
            || (x + 1 < w && differs(p, p + 1))
            || (y > 0 && differs(p, p - w))
            || (y + 1 < h && differs(p, p + w));
        hit.then_some(p as u32)
    }));
}

/// Replaces each sampled pixel of `out` (RGB rows) by the sum of its `parts`' shades, each
/// weighted by its share of the pixel.
pub(super) fn resolve(inputs: &ViewInputs, rays: &ViewRays, parts: &[Part], out: &mut [f32]) {
    let width = rays.width as usize;
    let offsets = offsets();
    let shades: Vec<[f32; 3]> = parts
        .par_iter()
        .map(|p| {
            let rgb = if p.triangle == NO_TRIANGLE {
                let (x, y) = (
                    (p.pixel as usize % width) as f64,
                    (p.pixel as usize / width) as f64,
                );
                let mut sum = [0.0f32; 3];
                for (k, (ox, oy)) in offsets.iter().enumerate() {
                    if p.samples & (1 << k) != 0 {
                        let d = rays.direction(x + ox, y + oy).map(|c| c as f32);
                        let r = inputs.environment.radiance(d);
                        (0..3).for_each(|c| sum[c] += r[c]);
                    }
                }
                let n = p.samples.count_ones() as f32;
                sum.map(|v| v / n)
            } else {
                inputs.shade(p.triangle as usize, p.bary)
            };
            rgb.map(|v| v * p.weight())
        })
        .collect();
    let mut last = None;
    for (p, rgb) in parts.iter().zip(shades) {
        let at = 3 * p.pixel as usize;
        let px = &mut out[at..at + 3];
        if last != Some(p.pixel) {
            px.fill(0.0);
            last = Some(p.pixel);
        }
        (0..3).for_each(|c| px[c] += rgb[c]);
    }
}
