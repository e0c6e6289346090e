//! The multi-sample pass: for a few chosen pixels (the silhouettes and creases found after
//! shading, `antialias.rs`), what [`SAMPLES`] film positions spread over each pixel see, by the
//! same edge functions, tie rule and depth test as the pixel-centre pass, so that a sample
//! agrees with the tracer's ray through it exactly as a centre does.
//!
//! Per pixel, the samples are grouped by the triangle they see: each group is one [`Part`]
//! with its share of the pixel and the barycentrics at the centroid of its samples (inside
//! the triangle: the mean of points of a convex set), where the pixel shades that triangle
//! once, as a GPU's multisampling does; the samples that see nothing form the background's
//! part. The pattern is a 4 x 4 multi-jittered grid: every column and every row of a 16 x 16
//! grid over the pixel holds one sample, so a near-horizontal or near-vertical edge is
//! resolved in sixteenths, not quarters.

use prt_formats::view::CameraFrame;
use rayon::prelude::*;

use super::{edges, inside, min, Film, Rasterizer, VisibilityBuffer, BAND_ROWS};
use crate::vertex::view::{RasterError, ViewRays, NO_TRIANGLE};

/// Samples per side of the pattern's coarse grid.
const SIDE: usize = 4;

/// Samples per pixel.
pub(crate) const SAMPLES: usize = SIDE * SIDE;

/// The sample positions within a pixel (`[0, 1)^2`, x right, y down): sample `(a, b)` of the
/// 4 x 4 grid at `((a + (b + 1/2) / 4) / 4, (b + (a + 1/2) / 4) / 4)`, one per column and per row
/// of the 16 x 16 grid.
pub(crate) fn offsets() -> [(f64, f64); SAMPLES] {
    std::array::from_fn(|i| {
        let (a, b) = ((i % SIDE) as f64, (i / SIDE) as f64);
        let n = SIDE as f64;
        ((a + (b + 0.5) / n) / n, (b + (a + 0.5) / n) / n)
    })
}

/// One surface's share of a pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Part {
    /// The pixel (row-major index).
    pub(crate) pixel: u32,
    /// The triangle seen, or [`NO_TRIANGLE`] for the samples that see the environment.
    pub(crate) triangle: u32,
    /// The weights of the triangle's vertices 1 and 2 at the centroid of its samples (as
    /// [`super::Fragment::bary`]); zero for the background.
    pub(crate) bary: [f32; 2],
    /// Which samples (bit `i`: [`offsets`]`()[i]`) see this surface; its share of the pixel is
    /// their count over [`SAMPLES`].
    pub(crate) samples: u16,
}

impl Rasterizer {
    /// What the [`SAMPLES`] sample positions of each pixel in `pixels` (row-major indices,
    /// ascending) see, as [`Part`]s into `out` (replaced; pixel by pixel in the order given,
    /// each pixel's parts in the order their triangles were first met by a sample, the
    /// background last). Must follow [`Rasterizer::render`] of the same `triangles` and
    /// `camera` into `vis`: it reads the vertices and bins that render left.
    pub(crate) fn samples(
        &self,
        triangles: &[[u32; 3]],
        camera: &CameraFrame,
        vis: &VisibilityBuffer,
        pixels: &[u32],
        out: &mut Vec<Part>,
    ) -> Result<(), RasterError> {
        out.clear();
        let (width, height) = (vis.width, vis.height);
        let rays = ViewRays::new(camera, width, height)?;
        let film = Film::new(&rays, vis.near);
        let bands = height.div_ceil(BAND_ROWS) as usize;
        let band_pixels = (width * BAND_ROWS) as usize;
        let offsets = offsets();
        let chunks = &self.chunks;
        let verts = &self.verts;
        let per_band: Vec<Vec<Part>> = (0..bands)
            .into_par_iter()
            .map(|band| {
                let lo = pixels.partition_point(|&p| (p as usize) < band * band_pixels);
                let hi = pixels.partition_point(|&p| (p as usize) < (band + 1) * band_pixels);
                let mine = &pixels[lo..hi];
                if mine.is_empty() {
                    return Vec::new();
                }
                #[cfg(target_arch = "x86_64")]
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2 (checked just above).
                    return unsafe {
                        band_samples_avx2(
                            &rays, &film, vis, triangles, verts, chunks, band, mine, &offsets,
                        )
                    };
                }
                band_samples(
                    &rays, &film, vis, triangles, verts, chunks, band, mine, &offsets,
                )
            })
            .collect();
        for parts in per_band {
            out.extend(parts);
        }
        Ok(())
    }
}

/// [`band_samples`] compiled for AVX2 (as the pixel-centre pass): the same operations in the
/// same order, so the same parts bit for bit.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn band_samples_avx2(
    rays: &ViewRays,
    film: &Film,
    vis: &VisibilityBuffer,
    triangles: &[[u32; 3]],
    verts: &[super::Vertex],
    chunks: &[super::ChunkBins],
    band: usize,
    mine: &[u32],
    offsets: &[(f64, f64); SAMPLES],
) -> Vec<Part> {
    band_samples(
        rays, film, vis, triangles, verts, chunks, band, mine, offsets,
    )
}

/// [`Rasterizer::samples`] for one band's pixels `mine`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn band_samples(
    rays: &ViewRays,
    film: &Film,
    vis: &VisibilityBuffer,
    triangles: &[[u32; 3]],
    verts: &[super::Vertex],
    chunks: &[super::ChunkBins],
    band: usize,
    mine: &[u32],
    offsets: &[(f64, f64); SAMPLES],
) -> Vec<Part> {
    const NONE: u32 = u32::MAX;
    let width = vis.width as usize;
    let q_near = 1.0 / film.near;
    let y_first = band * BAND_ROWS as usize;
    let rows = (BAND_ROWS as usize).min(vis.height as usize - y_first);
    // Per pixel of the band: its position in `mine`, or NONE.
    let mut slot = vec![NONE; rows * width];
    for (i, &p) in mine.iter().enumerate() {
        slot[p as usize - y_first * width] = i as u32;
    }
    // Per pixel and sample: the film position, then the nearest inverse depth so far and the
    // position of its triangle's edge functions in `seen`.
    // (Coordinates apart, so that the sample loop reads each as one vector.)
    let film_at: Vec<[[f64; SAMPLES]; 2]> = mine
        .iter()
        .map(|&p| {
            let (x, y) = ((p as usize % width) as f64, (p as usize / width) as f64);
            let at = offsets.map(|(ox, oy)| rays.film(x + ox, y + oy));
            [at.map(|a| a.0), at.map(|a| a.1)]
        })
        .collect();
    // Half a pixel in film units along x and y, and each chosen pixel's centre: a triangle
    // one of whose edges is negative over the whole pixel square (its value at the centre plus
    // the most the square can add) covers none of its samples.
    let (cx0, cy0) = rays.film(0.5, 0.5);
    let (cx1, cy1) = rays.film(1.5, 1.5);
    let (half_x, half_y) = (0.5 * (cx1 - cx0).abs(), 0.5 * (cy1 - cy0).abs());
    let centre: Vec<(f64, f64)> = mine
        .iter()
        .map(|&p| {
            let (x, y) = ((p as usize % width) as f64, (p as usize / width) as f64);
            rays.film(x + 0.5, y + 0.5)
        })
        .collect();
    let mut depth = vec![0.0f64; mine.len() * SAMPLES];
    let mut seq = vec![NONE; mine.len() * SAMPLES];
    let mut seen = Vec::new();
    for chunk in chunks {
        let run = chunk.starts[band] as usize..chunk.starts[band + 1] as usize;
        for e in &chunk.entries[run] {
            let a = e.area;
            let y0 = usize::from(a.y0).max(y_first);
            let y1 = usize::from(a.y1).min(y_first + rows - 1);
            let (x0, x1) = (usize::from(a.x0), usize::from(a.x1));
            let mut s = None;
            for y in y0..=y1 {
                let row = &slot[(y - y_first) * width..][..width];
                for &i in row[x0..=x1].iter().filter(|&&i| i != NONE) {
                    // The edge functions, once per triangle that reaches a chosen pixel.
                    let (sid, t) = match s {
                        Some(found) => found,
                        None => {
                            let tri = triangles[e.triangle as usize];
                            let Some(t) = edges(tri.map(|v| verts[v as usize].c), e.triangle)
                            else {
                                break;
                            };
                            let sid = seen.len() as u32;
                            seen.push(t);
                            s = Some((sid, t));
                            (sid, t)
                        }
                    };
                    let [n0, n1, n2] = t.n;
                    let (o0, o1, o2) = (t.owns & 1 != 0, t.owns & 2 != 0, t.owns & 4 != 0);
                    let i = i as usize;
                    let (px, py) = centre[i];
                    let apart = |e: [f64; 3]| {
                        e[0] * px + (e[1] * py + e[2]) + e[0].abs() * half_x + e[1].abs() * half_y
                            < 0.0
                    };
                    if apart(n0) || apart(n1) || apart(n2) {
                        continue;
                    }
                    let [fx, fy] = &film_at[i];
                    let depth = &mut depth[i * SAMPLES..][..SAMPLES];
                    let seq = &mut seq[i * SAMPLES..][..SAMPLES];
                    for k in 0..SAMPLES {
                        let (sx, sy) = (fx[k], fy[k]);
                        let w0 = n0[0] * sx + (n0[1] * sy + n0[2]);
                        let w1 = n1[0] * sx + (n1[1] * sy + n1[2]);
                        let w2 = n2[0] * sx + (n2[1] * sy + n2[2]);
                        let m = min(min(w0, w1), w2);
                        let covered = (m > 0.0)
                            | (m == 0.0 && inside(w0, o0) & inside(w1, o1) & inside(w2, o2));
                        let q = (w0 + w1 + w2) * t.inv_det;
                        // Branch-free: whether a sample is covered is unpredictable.
                        let wins = covered & (q > depth[k]) & (q <= q_near);
                        depth[k] = if wins { q } else { depth[k] };
                        seq[k] = if wins { sid } else { seq[k] };
                    }
                }
            }
        }
    }
    // Group each pixel's samples by what they see (a triangle has one position in `seen`:
    // it is binned once per band).
    let mut parts = Vec::with_capacity(2 * mine.len());
    let mut groups: Vec<(u32, u16)> = Vec::with_capacity(SAMPLES);
    for (i, &pixel) in mine.iter().enumerate() {
        groups.clear();
        let mut background = 0u16;
        for k in 0..SAMPLES {
            let id = seq[i * SAMPLES + k];
            if id == NONE {
                background |= 1 << k;
                continue;
            }
            match groups.iter_mut().find(|g| g.0 == id) {
                Some(g) => g.1 |= 1 << k,
                None => groups.push((id, 1 << k)),
            }
        }
        for &(id, samples) in &groups {
            // The centroid of the part's samples, and the barycentrics of the ray through it
            // (its edge values over their sum, as at a pixel centre).
            let (mut cx, mut cy) = (0.0, 0.0);
            for k in (0..SAMPLES).filter(|k| samples & (1 << k) != 0) {
                cx += film_at[i][0][k];
                cy += film_at[i][1][k];
            }
            let n = f64::from(samples.count_ones());
            let (cx, cy) = (cx / n, cy / n);
            let t = &seen[id as usize];
            let w: [f64; 3] = t.n.map(|e| e[0] * cx + (e[1] * cy + e[2]));
            let sum = w[0] + w[1] + w[2];
            parts.push(Part {
                pixel,
                triangle: t.triangle,
                bary: [(w[1] / sum) as f32, (w[2] / sum) as f32],
                samples,
            });
        }
        if background != 0 {
            parts.push(Part {
                pixel,
                triangle: NO_TRIANGLE,
                bary: [0.0; 2],
                samples: background,
            });
        }
    }
    parts
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every column and every row of the 16 x 16 grid holds exactly one sample, each sample at
    /// its cell's centre.
    #[test]
    fn the_pattern_is_multi_jittered() {
        let o = offsets();
        let n = SAMPLES as f64;
        let mut columns = [0; SAMPLES];
        let mut rows = [0; SAMPLES];
        for (x, y) in o {
            assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
            let (cx, cy) = ((x * n).floor(), (y * n).floor());
            assert!(((x * n) - cx - 0.5).abs() < 1e-12 && ((y * n) - cy - 0.5).abs() < 1e-12);
            columns[cx as usize] += 1;
            rows[cy as usize] += 1;
        }
        assert_eq!(columns, [1; SAMPLES]);
        assert_eq!(rows, [1; SAMPLES]);
    }
}
