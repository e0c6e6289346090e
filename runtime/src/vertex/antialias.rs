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
//! surfaces' shades (the triangles that share a vertex being one surface), each surface shaded
//! once at the centroid of its largest triangle's samples and weighted by its share (the
//! environment's part: the mean radiance along its samples' rays), as a GPU's multisampling
//! resolves a pixel.

use rayon::prelude::*;

use super::raster::samples::{offsets, Part, SAMPLES};
use super::raster::{Fragment, VisibilityBuffer};
use super::shade::ViewInputs;
use super::view::{ViewRays, NO_TRIANGLE};

// A part's samples are a u16 mask.
const _: () = assert!(SAMPLES <= 16);

/// How much two neighbouring pixels' colours (the sum of their RGB) must differ, relative to
/// the brighter, for the pixels to be sampled: below it, giving a whole pixel to one side moves
/// the pixel by less than this, and sampling it would cost more than it buys (on the gallery
/// at 512 x 512, 2 % sampled 7 050 pixels and 10 % 5 482 for the same image error, 8.27 %).
pub(crate) const CONTRAST: f32 = 0.1;

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
    // Each pair of neighbours is judged once: bit 1, the pixel and the one to its right
    // differ; bit 2, the pixel and the one below.
    const RIGHT: u8 = 1;
    const DOWN: u8 = 2;
    let mut flags = vec![0u8; w * h];
    flags.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, f) in row.iter_mut().enumerate() {
            let p = y * w + x;
            let right = x + 1 < w && differs(p, p + 1);
            let down = y + 1 < h && differs(p, p + w);
            *f = (u8::from(right) * RIGHT) | (u8::from(down) * DOWN);
        }
    });
    out.clear();
    out.par_extend((0..w * h).into_par_iter().filter_map(|p| {
        let (x, y) = (p % w, p / w);
        let hit = flags[p] != 0
            || (x > 0 && flags[p - 1] & RIGHT != 0)
            || (y > 0 && flags[p - w] & DOWN != 0);
        hit.then_some(p as u32)
    }));
}

/// What the resolve shades: one surface of a pixel (a triangle at barycentrics, or the
/// environment along the samples in `samples`) and its share.
struct Job {
    pixel: u32,
    triangle: u32,
    bary: [f32; 2],
    samples: u16,
    weight: f32,
    /// The surface holds the triangle the pixel's centre sees: the pixel's shade is its
    /// (shaded at the centre, inside the pixel as the centroid is), and is not shaded again.
    at_centre: bool,
}

/// The pixel's parts as shading jobs: parts whose triangles share a vertex (one smooth
/// surface: a pixel of a finely tessellated mesh holds several of its triangles) are shaded
/// once, at the centroid of the samples of the one with the most, with their summed share;
/// the background's part is its own job.
fn jobs(parts: &[Part], triangles: &[[u32; 3]], centre: &[Fragment], out: &mut Vec<Job>) {
    let mut start = 0;
    while start < parts.len() {
        let pixel = parts[start].pixel;
        let end = start
            + parts[start..]
                .iter()
                .take_while(|p| p.pixel == pixel)
                .count();
        let mine = &parts[start..end];
        // Union-find over the pixel's parts (at most 17).
        let mut root: Vec<usize> = (0..mine.len()).collect();
        fn find(root: &mut [usize], mut i: usize) -> usize {
            while root[i] != i {
                root[i] = root[root[i]];
                i = root[i];
            }
            i
        }
        for a in 0..mine.len() {
            for b in a + 1..mine.len() {
                let (ta, tb) = (mine[a].triangle, mine[b].triangle);
                if ta == NO_TRIANGLE || tb == NO_TRIANGLE {
                    continue;
                }
                let (va, vb) = (triangles[ta as usize], triangles[tb as usize]);
                if va.iter().any(|v| vb.contains(v)) {
                    let (ra, rb) = (find(&mut root, a), find(&mut root, b));
                    root[ra.max(rb)] = ra.min(rb);
                }
            }
        }
        for i in 0..mine.len() {
            let r = find(&mut root, i);
            root[i] = r;
        }
        for r in (0..mine.len()).filter(|&i| root[i] == i) {
            // The member with the most samples (the first of equals) is shaded.
            let seen = centre[pixel as usize].triangle;
            let (mut count, mut best, mut at_centre) = (0u32, r, false);
            for (i, p) in mine.iter().enumerate().filter(|&(i, _)| root[i] == r) {
                count += p.samples.count_ones();
                at_centre |= p.triangle == seen && seen != NO_TRIANGLE;
                if p.samples.count_ones() > mine[best].samples.count_ones() {
                    best = i;
                }
            }
            out.push(Job {
                pixel,
                triangle: mine[best].triangle,
                bary: mine[best].bary,
                samples: mine[best].samples,
                weight: count as f32 / SAMPLES as f32,
                at_centre,
            });
        }
        start = end;
    }
}

/// Replaces each sampled pixel of `out` (RGB rows, shaded at the pixels' centres as `vis`
/// shows them) by the sum of its surfaces' shades, each weighted by its share of the pixel.
pub(super) fn resolve(
    inputs: &ViewInputs,
    rays: &ViewRays,
    vis: &VisibilityBuffer,
    parts: &[Part],
    out: &mut [f32],
) {
    let mut work = Vec::with_capacity(parts.len());
    jobs(parts, &inputs.scene.triangles, &vis.fragments, &mut work);
    let mut shades = vec![[0.0f32; 3]; work.len()];
    let image: &[f32] = out;
    shades
        .par_chunks_mut(64)
        .zip(work.par_chunks(64))
        .for_each(|(shades, work)| {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above).
                unsafe { shade_jobs_avx2(inputs, rays, image, work, shades) };
                return;
            }
            shade_jobs(inputs, rays, image, work, shades);
        });
    let mut last = None;
    for (job, rgb) in work.iter().zip(shades) {
        let at = 3 * job.pixel as usize;
        let px = &mut out[at..at + 3];
        if last != Some(job.pixel) {
            px.fill(0.0);
            last = Some(job.pixel);
        }
        (0..3).for_each(|c| px[c] += rgb[c]);
    }
}

/// [`shade_jobs`] compiled for AVX2, as the view stage's rows are (the same pixels bit for
/// bit).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn shade_jobs_avx2(
    inputs: &ViewInputs,
    rays: &ViewRays,
    image: &[f32],
    work: &[Job],
    out: &mut [[f32; 3]],
) {
    shade_jobs(inputs, rays, image, work, out);
}

/// Each job's shade times its weight (`image`: the pixels shaded at their centres).
#[inline(always)]
fn shade_jobs(
    inputs: &ViewInputs,
    rays: &ViewRays,
    image: &[f32],
    work: &[Job],
    out: &mut [[f32; 3]],
) {
    let width = rays.width as usize;
    let offsets = offsets();
    for (job, o) in work.iter().zip(out) {
        let rgb = if job.at_centre {
            let at = 3 * job.pixel as usize;
            [image[at], image[at + 1], image[at + 2]]
        } else if job.triangle == NO_TRIANGLE {
            let x = (job.pixel as usize % width) as f64;
            let y = (job.pixel as usize / width) as f64;
            let mut sum = [0.0f32; 3];
            for (k, (ox, oy)) in offsets.iter().enumerate() {
                if job.samples & (1 << k) != 0 {
                    let d = rays.direction(x + ox, y + oy).map(|c| c as f32);
                    let r = inputs.environment.radiance(d);
                    (0..3).for_each(|c| sum[c] += r[c]);
                }
            }
            let n = job.samples.count_ones() as f32;
            sum.map(|v| v / n)
        } else {
            inputs.shade(job.triangle as usize, job.bary)
        };
        *o = rgb.map(|v| v * job.weight);
    }
}
