//! Compression of one unit's T1 and T2 by clustered Tucker approximation (thesis 5.3.3.4-5;
//! docs/vertex.md "Compression"; the layout is `prt_formats::clustered`).
//!
//! Per cluster of vertices (a unit, or its halves or quarters: `units.rs`) the dense block
//! `X[v][l][w]` is decomposed by the sequentially truncated higher-order SVD: the element mode
//! first (its Gram matrix is the cheapest, `W x W`), then the light mode of the
//! element-projected block, then the vertex mode of what is left, which gives the core. Each
//! step keeps the fewest leading eigenvectors whose discarded eigenvalues fit its share of the
//! budget: with ST-HOSVD the squared error of the result is exactly the sum of the energies
//! discarded at the three steps, so a cluster meets its budget whenever no rank cap binds.
//!
//! **The budget separates compression from Monte Carlo noise.** The dense tensors carry the
//! noise of N1 first directions; a low-rank model removes much of it, so its distance from the
//! dense tensor says little about its distance from the converged one. The trace estimates
//! each vertex's noise energy from independent halves of its directions (`trace.rs`), and a
//! cluster may discard that much plus `error_target^2` of its signal energy (the dense energy
//! less the noise). The error a group reports is then the error *beyond the noise*,
//! `sqrt(max(0, discarded - noise) / (energy - noise))`, beside the error against the dense
//! tensor and the noise itself (docs/vertex.md, "What the error target means").
//!
//! Every cluster is computed sequentially (faer with `Par::Seq`) from its own rows; clusters
//! run in parallel and are placed in order, so the result does not depend on the thread
//! count. The dense block is read in chunks converted to f64, never copied whole.

use std::ops::Range;

use faer::{Accum, Mat};
use prt_formats::clustered::CompressionSettings;
use rayon::prelude::*;

use crate::basis::linalg::{
    gram, gram_lower_add, matmul, matmul_into, matmul_tn, mirror_lower, sign_fixed_columns,
    sym_eig, EigMethod,
};

use super::error::VertexError;

/// One cluster's Tucker factors (f32, row-major), as a piece stores them.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ClusterTucker {
    /// Vertices of the cluster.
    pub vertices: usize,
    /// `(a, r, b)`.
    pub ranks: [usize; 3],
    /// `light (L x a)` then `element (W x r)`.
    pub factors: Vec<f32>,
    /// `b x a x r`.
    pub core: Vec<f32>,
    /// `n x b`: the cluster's vertices' rows of the vertex factor, in vertex order.
    pub vertex: Vec<f32>,
    /// Figures of the cluster.
    pub figures: ClusterFigures,
}

/// Energies of one compressed cluster (sums of squares), added over clusters and groups.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct ClusterFigures {
    /// Discarded: the squared error made.
    pub sq_error: f64,
    /// The dense block's.
    pub sq_norm: f64,
    /// The dense block's estimated Monte Carlo noise.
    pub sq_noise: f64,
    /// Which rank caps bound (light, element, vertex): the budget wanted more.
    pub capped: [bool; 3],
    /// Eigendecompositions that needed the Jacobi fallback (`basis::linalg::sym_eig`).
    pub fallbacks: u32,
}

impl ClusterFigures {
    /// Adds another cluster's figures.
    pub fn add(&mut self, o: &ClusterFigures) {
        self.sq_error += o.sq_error;
        self.sq_norm += o.sq_norm;
        self.sq_noise += o.sq_noise;
        for (a, b) in self.capped.iter_mut().zip(o.capped) {
            *a |= b;
        }
        self.fallbacks += o.fallbacks;
    }

    /// Relative L2 error against the dense tensor.
    pub fn error(&self) -> f64 {
        ratio(self.sq_error, self.sq_norm)
    }

    /// Relative L2 error beyond the dense tensor's noise, against its signal.
    pub fn beyond_noise(&self) -> f64 {
        ratio(
            (self.sq_error - self.sq_noise).max(0.0),
            (self.sq_norm - self.sq_noise).max(0.0),
        )
    }

    /// The dense tensor's noise relative to its energy.
    pub fn noise(&self) -> f64 {
        ratio(self.sq_noise, self.sq_norm)
    }
}

fn ratio(part: f64, whole: f64) -> f64 {
    if whole > 0.0 {
        (part.max(0.0) / whole).sqrt()
    } else {
        0.0
    }
}

/// The budget of discarded energy of a block: all of its noise and `target^2` of its signal.
/// A target of 0 discards nothing, noise included: every rank the caps allow (the exactness
/// tests' setting, and what `compress_error = 0` promises).
pub(crate) fn budget(target: f32, sq_norm: f64, sq_noise: f64) -> f64 {
    if target <= 0.0 {
        return 0.0;
    }
    let noise = sq_noise.clamp(0.0, sq_norm);
    f64::from(target).powi(2) * (sq_norm - noise) + noise
}

/// Element Gram matrices of the clusters a unit has been compressed as, by range of rows. The
/// rows of a Gram matrix add, so a unit's is the sum of its halves': the split search
/// (`cluster_choice.rs`), which tries the halves first and then the whole unit, pays for the
/// largest product of the compression once. The sums are taken in a fixed order, so the
/// result does not depend on the thread count.
#[derive(Default)]
pub(crate) struct ElementGrams {
    known: Vec<(Range<usize>, Mat<f64>)>,
}

impl ElementGrams {
    /// The Gram matrix of `range` summed from known ones that tile it exactly (the longest
    /// known piece at each step), or None.
    fn get(&self, range: &Range<usize>) -> Option<Mat<f64>> {
        let mut at = range.start;
        let mut sum: Option<Mat<f64>> = None;
        while at < range.end {
            let (r, g) = self
                .known
                .iter()
                .filter(|(r, _)| r.start == at && r.end <= range.end && r.end > at)
                .max_by_key(|(r, _)| r.end)?;
            sum = Some(match sum {
                None => g.clone(),
                Some(s) => s + g,
            });
            at = r.end;
        }
        sum
    }

    fn insert(&mut self, range: Range<usize>, gram: Mat<f64>) {
        if !self.known.iter().any(|(r, _)| *r == range) {
            self.known.push((range, gram));
        }
    }
}

/// Compresses the clusters `ranges` (ranges of rows of `t`, `[V][bins][width]` f32) with the
/// noise energy of each row in `noise`; clusters in parallel, placed in order. Element Gram
/// matrices are taken from `grams` where it can sum them, and the new ones are added to it.
pub(crate) fn compress_clusters(
    t: &[f32],
    bins: usize,
    width: usize,
    ranges: &[Range<usize>],
    noise: &[f64],
    settings: &CompressionSettings,
    grams: &mut ElementGrams,
) -> Result<Vec<ClusterTucker>, VertexError> {
    let row = bins * width;
    let known: Vec<Option<Mat<f64>>> = ranges.iter().map(|r| grams.get(r)).collect();
    let done: Vec<(ClusterTucker, Mat<f64>)> = ranges
        .par_iter()
        .zip(known)
        .map(|(r, gram)| {
            let block = &t[r.start * row..r.end * row];
            let sq_noise: f64 = noise[r.clone()].iter().sum();
            tucker_block(block, r.len(), bins, width, sq_noise, settings, gram)
        })
        .collect::<Result<_, _>>()?;
    let mut out = Vec::with_capacity(done.len());
    for (r, (c, g)) in ranges.iter().zip(done) {
        grams.insert(r.clone(), g);
        out.push(c);
    }
    Ok(out)
}

/// The fewest leading eigenvalues (nonincreasing `vals`) whose discarded rest is at most
/// `budget`, at most `cap` and at least 1 (when there is a dimension); returns the rank, the
/// discarded energy and whether the cap bound.
fn rank_for(vals: &[f64], budget: f64, cap: usize) -> (usize, f64, bool) {
    let dim = vals.len();
    if dim == 0 {
        return (0, 0.0, false);
    }
    let mut rest: f64 = vals.iter().map(|v| v.max(0.0)).sum();
    let mut r = 0;
    let limit = dim.min(cap.max(1));
    while r < limit && (r == 0 || rest > budget) {
        rest -= vals[r].max(0.0);
        r += 1;
    }
    (r, rest.max(0.0), r == limit && limit < dim && rest > budget)
}

/// The leading eigenvectors (sign-fixed) of a Gram matrix that [`rank_for`] keeps, the energy
/// discarded, whether the cap bound and whether the decomposition fell back to Jacobi.
fn leading(
    g: &Mat<f64>,
    budget: f64,
    cap: usize,
) -> Result<(Mat<f64>, f64, bool, bool), VertexError> {
    let e = sym_eig(g.as_ref()).map_err(|e| VertexError::Compression(e.to_string()))?;
    let (r, discarded, capped) = rank_for(&e.vals, budget, cap);
    Ok((
        sign_fixed_columns(e.vecs.as_ref(), r),
        discarded,
        capped,
        e.method == EigMethod::Jacobi,
    ))
}

/// Rows of the dense block converted to f64 at a time: bounds the copy (the block itself can
/// be hundreds of MB for a large unit with many slots).
const CHUNK_ROWS: usize = 1024;

/// ST-HOSVD of one cluster's block `x` (`[n][bins][width]`), see the module documentation;
/// with its element Gram matrix when known (`known_gram`), which it returns.
fn tucker_block(
    x: &[f32],
    n: usize,
    bins: usize,
    width: usize,
    sq_noise: f64,
    s: &CompressionSettings,
    known_gram: Option<Mat<f64>>,
) -> Result<(ClusterTucker, Mat<f64>), VertexError> {
    let sq_norm: f64 = x.iter().map(|&v| f64::from(v) * f64::from(v)).sum();
    let mut figures = ClusterFigures {
        sq_norm,
        sq_noise: sq_noise.clamp(0.0, sq_norm),
        ..Default::default()
    };
    if n == 0 || bins == 0 || width == 0 {
        // Nothing to store (a group no slot sends light to has no T1 elements).
        let none = ClusterTucker {
            vertices: n,
            ranks: [0, 0, 0],
            factors: Vec::new(),
            core: Vec::new(),
            vertex: Vec::new(),
            figures,
        };
        return Ok((none, Mat::zeros(width, width)));
    }
    let budget = budget(s.error_target, sq_norm, figures.sq_noise);
    let rows = n * bins;
    // Element mode: rows (v, l), columns w. An element is a slot and SH band at the vertex:
    // the columns of slots no path of the cluster reaches are zero in every row (much of a
    // ground cluster's far from the editable objects), so the products below run over the
    // live columns only; the dead ones are zero rows and columns of the Gram matrix, which
    // `sym_eig` deflates (eigenvalue 0), and zero columns of X, so `X ue` needs only the live
    // rows of `ue`.
    let mut is_live = vec![false; width];
    for row in x.chunks_exact(width) {
        for (l, &v) in is_live.iter_mut().zip(row) {
            *l |= v != 0.0;
        }
    }
    let live: Vec<usize> = (0..width).filter(|&j| is_live[j]).collect();
    // A chunk of rows of X on its live columns, transposed: column-major, so each of its
    // columns is one row of X, read and written contiguously.
    let chunk_t = |start: usize| {
        let end = (start + CHUNK_ROWS).min(rows);
        let mut ct = Mat::<f64>::zeros(live.len(), end - start);
        for i in 0..end - start {
            let row = &x[(start + i) * width..(start + i + 1) * width];
            for (c, &j) in ct.col_as_slice_mut(i).iter_mut().zip(&live) {
                *c = f64::from(row[j]);
            }
        }
        ct
    };
    // The Gram matrix, the compression's largest product, unless the caller knows it: summed
    // over chunks of rows on its lower triangle (it is symmetric), then mirrored.
    let gw = match known_gram {
        Some(g) => g,
        None => {
            let mut g_live = Mat::<f64>::zeros(live.len(), live.len());
            if !live.is_empty() {
                for start in (0..rows).step_by(CHUNK_ROWS) {
                    gram_lower_add(g_live.as_mut(), chunk_t(start).as_ref().transpose());
                }
            }
            mirror_lower(&mut g_live);
            let mut g = Mat::<f64>::zeros(width, width);
            for (a, &i) in live.iter().enumerate() {
                for (b, &j) in live.iter().enumerate() {
                    g[(i, j)] = g_live[(a, b)];
                }
            }
            g
        }
    };
    let (ue, d_e, cap_e, fb_e) = leading(&gw, budget / 3.0, s.max_element_rank as usize)?;
    let r = ue.ncols();
    // y = X ue, (v, l) x r, chunk by chunk.
    let mut y = Mat::<f64>::zeros(rows, r);
    if !live.is_empty() {
        let ue_live = Mat::from_fn(live.len(), r, |k, c| ue[(live[k], c)]);
        for start in (0..rows).step_by(CHUNK_ROWS) {
            let ct = chunk_t(start);
            matmul_into(
                y.as_mut().subrows_mut(start, ct.ncols()),
                Accum::Replace,
                ct.as_ref().transpose(),
                ue_live.as_ref(),
            );
        }
    }
    // Light mode: rows (v, k), columns l.
    let yl = Mat::from_fn(n * r, bins, |i, l| {
        y[((i / r.max(1)) * bins + l, i % r.max(1))]
    });
    drop(y);
    let gl = gram(yl.as_ref());
    let (ul, d_l, cap_l, fb_l) = leading(
        &gl,
        (2.0 * budget / 3.0 - d_e).max(0.0),
        s.max_light_rank as usize,
    )?;
    let a = ul.ncols();
    let z = matmul(yl.as_ref(), ul.as_ref()); // (v, k) x a
    drop(yl);
    // Vertex mode: rows (a, k) of the core's order, columns v.
    let zv = Mat::from_fn(a * r, n, |i, v| z[(v * r + i % r.max(1), i / r.max(1))]);
    drop(z);
    let gv = gram(zv.as_ref());
    let (uv, d_v, cap_v, fb_v) = leading(
        &gv,
        (budget - d_e - d_l).max(0.0),
        s.max_vertex_rank as usize,
    )?;
    let b = uv.ncols();
    let core = matmul_tn(uv.as_ref(), zv.as_ref().transpose()); // b x (a, k)

    let mut factors = Vec::with_capacity(bins * a + width * r);
    for l in 0..bins {
        factors.extend((0..a).map(|c| ul[(l, c)] as f32));
    }
    for w in 0..width {
        factors.extend((0..r).map(|c| ue[(w, c)] as f32));
    }
    let core_flat = (0..b)
        .flat_map(|i| (0..a * r).map(move |j| (i, j)))
        .map(|(i, j)| core[(i, j)] as f32)
        .collect();
    let vertex = (0..n)
        .flat_map(|v| (0..b).map(move |c| (v, c)))
        .map(|(v, c)| uv[(v, c)] as f32)
        .collect();
    figures.sq_error = d_e + d_l + d_v;
    figures.capped = [cap_l, cap_e, cap_v];
    figures.fallbacks = u32::from(fb_e) + u32::from(fb_l) + u32::from(fb_v);
    Ok((
        ClusterTucker {
            vertices: n,
            ranks: [a, r, b],
            factors,
            core: core_flat,
            vertex,
            figures,
        },
        gw,
    ))
}

#[cfg(test)]
// The tests index tensors the way the formulas are written (a sum over b, a, r per element), and
// a one-cluster call passes one range.
#[allow(clippy::needless_range_loop, clippy::single_range_in_vec_init)]
mod tests {
    use super::*;

    fn settings(target: f32, caps: [u32; 3]) -> CompressionSettings {
        CompressionSettings {
            error_target: target,
            cluster_vertices: Some(64),
            max_light_rank: caps[0],
            max_element_rank: caps[1],
            max_vertex_rank: caps[2],
        }
    }

    /// The dense rows a cluster's factors stand for.
    fn expand(c: &ClusterTucker, n: usize, bins: usize, width: usize) -> Vec<f32> {
        let [a, r, b] = c.ranks;
        let light = &c.factors[..bins * a];
        let elem = &c.factors[bins * a..];
        let mut out = Vec::new();
        for v in 0..n {
            let u = &c.vertex[v * b..(v + 1) * b];
            for l in 0..bins {
                for w in 0..width {
                    let mut s = 0.0f64;
                    for bb in 0..b {
                        for aa in 0..a {
                            for rr in 0..r {
                                s += f64::from(u[bb])
                                    * f64::from(c.core[(bb * a + aa) * r + rr])
                                    * f64::from(light[l * a + aa])
                                    * f64::from(elem[w * r + rr]);
                            }
                        }
                    }
                    out.push(s as f32);
                }
            }
        }
        out
    }

    fn rel(a: &[f32], b: &[f32]) -> f64 {
        let d: f64 = a.iter().zip(b).map(|(x, y)| f64::from(x - y).powi(2)).sum();
        let n: f64 = b.iter().map(|y| f64::from(*y).powi(2)).sum();
        (d / n).sqrt()
    }

    /// A pseudo-random tensor.
    fn noise(len: usize, seed: u64) -> Vec<f32> {
        let mut s = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        (0..len)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5
            })
            .collect()
    }

    fn one(
        t: &[f32],
        n: usize,
        bins: usize,
        width: usize,
        noise_sq: f64,
        s: &CompressionSettings,
    ) -> ClusterTucker {
        let per_row = vec![noise_sq / n as f64; n];
        compress_clusters(
            t,
            bins,
            width,
            &[0..n],
            &per_row,
            s,
            &mut ElementGrams::default(),
        )
        .unwrap()
        .remove(0)
    }

    #[test]
    fn full_ranks_reproduce_the_tensor_and_the_factors_are_orthonormal() {
        let (n, bins, width) = (7, 5, 4);
        let t = noise(n * bins * width, 3);
        // Two clusters over rows 0..3 and 3..7.
        let c = compress_clusters(
            &t,
            bins,
            width,
            &[0..3, 3..7],
            &[0.0; 7],
            &settings(0.0, [99, 99, 99]),
            &mut ElementGrams::default(),
        )
        .unwrap();
        let mut back = expand(&c[0], 3, bins, width);
        back.extend(expand(&c[1], 4, bins, width));
        assert!(rel(&back, &t) < 1e-5, "{}", rel(&back, &t));
        assert!(c.iter().all(|c| c.figures.error() < 1e-5));
        let a = c[0].ranks[0];
        for i in 0..a {
            for j in 0..a {
                let d: f32 = (0..bins)
                    .map(|l| c[0].factors[l * a + i] * c[0].factors[l * a + j])
                    .sum();
                assert!((d - if i == j { 1.0 } else { 0.0 }).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn a_low_rank_tensor_is_found_and_the_target_bounds_the_error() {
        // Per vertex: T[v][l][w] = sum_q p_q(v) f_q(l) g_q(w) with 2 terms: ranks (2, 2, 2).
        let (n, bins, width) = (12, 9, 6);
        let f = noise(2 * bins, 1);
        let g = noise(2 * width, 2);
        let p = noise(2 * n, 4);
        let mut t = Vec::new();
        for v in 0..n {
            for l in 0..bins {
                for w in 0..width {
                    t.push(
                        (0..2)
                            .map(|q| p[2 * v + q] * f[2 * l + q] * g[2 * w + q])
                            .sum(),
                    );
                }
            }
        }
        let c = one(&t, n, bins, width, 0.0, &settings(1e-4, [99, 99, 99]));
        assert_eq!(c.ranks, [2, 2, 2]);
        assert!(rel(&expand(&c, n, bins, width), &t) < 1e-4);
        // On noise, the error made equals the error reported and stays under the target.
        let t = noise(n * bins * width, 9);
        for target in [0.1f32, 0.3, 0.6] {
            let c = one(&t, n, bins, width, 0.0, &settings(target, [99, 99, 99]));
            let made = rel(&expand(&c, n, bins, width), &t);
            assert!(made <= f64::from(target) + 1e-4, "target {target}: {made}");
            assert!((made - c.figures.error()).abs() < 1e-3);
            assert_eq!(c.figures.capped, [false; 3]);
        }
        // Caps bind: the error grows past the target, is reported as it is, and says so.
        let c = one(&t, n, bins, width, 0.0, &settings(0.01, [1, 1, 1]));
        assert_eq!(c.ranks, [1, 1, 1]);
        let made = rel(&expand(&c, n, bins, width), &t);
        assert!(made > 0.5 && (made - c.figures.error()).abs() < 1e-3);
        assert_eq!(c.figures.capped, [true; 3]);
    }

    #[test]
    fn the_noise_is_discarded_beside_the_target_and_the_error_beyond_it_is_reported() {
        // A rank-1 signal plus independent noise of known energy.
        let (n, bins, width) = (24, 16, 10);
        let f = noise(bins, 11);
        let g = noise(width, 12);
        let p = noise(n, 13);
        let e = noise(n * bins * width, 14);
        let mut signal = Vec::new();
        for v in 0..n {
            for l in 0..bins {
                for w in 0..width {
                    signal.push(4.0 * p[v] * f[l] * g[w]);
                }
            }
        }
        let sq = |x: &[f32]| x.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>();
        let scale = (0.3 * sq(&signal) / sq(&e)).sqrt() as f32; // noise at 30 % of the energy
        let t: Vec<f32> = signal.iter().zip(&e).map(|(s, e)| s + scale * e).collect();
        let noise_sq = sq(&t) - sq(&signal) * 1.0; // what an exact estimate would say, roughly
        let blind = one(&t, n, bins, width, 0.0, &settings(0.05, [99, 99, 99]));
        let aware = one(&t, n, bins, width, noise_sq, &settings(0.05, [99, 99, 99]));
        // Without the noise the 5 % target keeps much of it; with it the model is far smaller
        // and closer to the signal than the dense tensor is.
        let size = |c: &ClusterTucker| c.factors.len() + c.core.len() + c.vertex.len();
        assert!(
            size(&aware) * 3 < size(&blind),
            "{} {}",
            size(&aware),
            size(&blind)
        );
        let to_signal = rel(&expand(&aware, n, bins, width), &signal);
        assert!(to_signal < rel(&t, &signal), "{to_signal}");
        assert!(aware.figures.error() > 0.3 && aware.figures.beyond_noise() <= 0.05 + 1e-9);
        assert!((aware.figures.noise() - (noise_sq / sq(&t)).sqrt()).abs() < 1e-6);
        assert_eq!(budget(0.1, 2.0, 5.0), 2.0);
        assert_eq!(budget(0.0, 2.0, 1.0), 0.0, "a zero target keeps every rank");
        assert!((budget(0.1, 2.0, 1.0) - 1.01).abs() < 1e-8);
    }

    #[test]
    fn dead_elements_change_nothing_and_a_unit_sums_its_halves_gram_matrices() {
        // A low-rank block on 5 elements, spread over 12 columns of which 7 are zero (slots
        // no path of the cluster reaches).
        let (n, bins, small) = (10, 8, 5);
        let cols = [1usize, 4, 5, 9, 11];
        let width = 12;
        let f = noise(2 * bins, 21);
        let g = noise(2 * small, 22);
        let p = noise(2 * n, 23);
        let e = noise(n * bins * small, 24);
        let mut packed = Vec::new();
        for v in 0..n {
            for l in 0..bins {
                for w in 0..small {
                    let s: f32 = (0..2)
                        .map(|q| p[2 * v + q] * f[2 * l + q] * g[2 * w + q])
                        .sum();
                    packed.push(s + 0.01 * e[(v * bins + l) * small + w]);
                }
            }
        }
        let mut spread = vec![0.0f32; n * bins * width];
        for row in 0..n * bins {
            for (k, &c) in cols.iter().enumerate() {
                spread[row * width + c] = packed[row * small + k];
            }
        }
        for target in [0.0f32, 0.05] {
            let st = settings(target, [99, 99, 99]);
            let a = one(&packed, n, bins, small, 0.0, &st);
            let b = one(&spread, n, bins, width, 0.0, &st);
            assert_eq!(a.ranks, b.ranks, "target {target}");
            assert!((a.figures.sq_error - b.figures.sq_error).abs() <= 1e-9 * a.figures.sq_norm);
            // The same model, its element factor zero on the dead columns.
            let back = expand(&b, n, bins, width);
            let mut dense = expand(&a, n, bins, small).into_iter();
            for row in back.chunks_exact(width) {
                for (c, &v) in row.iter().enumerate() {
                    let want = if cols.contains(&c) {
                        dense.next().unwrap()
                    } else {
                        0.0
                    };
                    assert!(
                        (v - want).abs() < 1e-5,
                        "target {target}: column {c}: {v} vs {want}"
                    );
                }
            }
        }
        // The whole block's Gram matrix summed from its halves' equals the one of its rows.
        let st = settings(0.05, [99, 99, 99]);
        let per_row = vec![0.0; n];
        let mut halves = ElementGrams::default();
        compress_clusters(
            &spread,
            bins,
            width,
            &[0..4, 4..n],
            &per_row,
            &st,
            &mut halves,
        )
        .unwrap();
        let mut whole = ElementGrams::default();
        compress_clusters(&spread, bins, width, &[0..n], &per_row, &st, &mut whole).unwrap();
        let (from_halves, direct) = (halves.get(&(0..n)).unwrap(), whole.get(&(0..n)).unwrap());
        for i in 0..width {
            for j in 0..width {
                let (x, y) = (from_halves[(i, j)], direct[(i, j)]);
                assert!(
                    (x - y).abs() <= 1e-12 * direct[(i, i)].abs().max(1.0),
                    "({i}, {j})"
                );
                assert_eq!(x, from_halves[(j, i)], "symmetric");
            }
        }
        assert!(halves.get(&(0..3)).is_none() && halves.get(&(2..n)).is_none());
    }
}
