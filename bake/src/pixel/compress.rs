//! Low-rank compression of a group's per-pixel transfer rows: PCA over pixels. Each row x_p
//! (length E) is approximated as mean + sum_r w_p[r] U_r, so the runtime contracts the K
//! components with the coefficients once per frame and then needs only K multiply-adds per
//! pixel and channel instead of E.

use faer::Mat;
use rayon::prelude::*;

use crate::basis::linalg::{fix_sign, matmul_tn, sym_eig_desc};

/// A group's low-rank variant: row_p ~ mean + sum_r weights[p, r] components[r].
pub struct Compressed {
    /// The mean row, `[row_len]`.
    pub mean: Vec<f32>,
    /// `[rank, row_len]`.
    pub components: Vec<f32>,
    /// `[pixels, rank]`.
    pub weights: Vec<f32>,
    /// Number of components kept (at most the requested rank; fewer when the data has lower
    /// rank).
    pub rank: usize,
}

/// Rows per covariance chunk; chunks are reduced in a fixed order, so the result does not
/// depend on the thread count.
const CHUNK: usize = 4096;

/// PCA of `n` rows of length `len` (row-major in `rows`), keeping `k` components (at most
/// `min(n, len)`; fewer when the data has lower rank).
pub fn pca_rows(rows: &[f32], n: usize, len: usize, k: usize) -> Compressed {
    let mut mean = vec![0.0f64; len];
    for r in rows.chunks_exact(len) {
        for (m, v) in mean.iter_mut().zip(r) {
            *m += *v as f64;
        }
    }
    let inv_n = 1.0 / n.max(1) as f64;
    mean.iter_mut().for_each(|m| *m *= inv_n);

    let partials: Vec<Mat<f64>> = rows
        .par_chunks(CHUNK * len)
        .map(|chunk| {
            let m = chunk.len() / len;
            let x = Mat::from_fn(m, len, |i, j| chunk[i * len + j] as f64 - mean[j]);
            matmul_tn(x.as_ref(), x.as_ref())
        })
        .collect();
    let mut cov = Mat::<f64>::zeros(len, len);
    for p in &partials {
        cov += p;
    }
    let (vals, vecs) = match sym_eig_desc(cov.as_ref()) {
        Ok(x) => x,
        Err(_) => (Vec::new(), Mat::zeros(len, 0)),
    };
    // Keep components with non-negligible variance only (rank-deficient data).
    let top = vals.first().copied().unwrap_or(0.0).max(0.0);
    let rank = vals
        .iter()
        .take(k.min(len).min(n))
        .take_while(|&&v| v > top * 1e-12 && v > 0.0)
        .count();
    let mut components = vec![0.0f32; rank * len];
    let mut comp64 = vec![vec![0.0f64; len]; rank];
    for (r, c) in comp64.iter_mut().enumerate() {
        for (j, v) in c.iter_mut().enumerate() {
            *v = vecs[(j, r)];
        }
        fix_sign(c);
        for j in 0..len {
            components[r * len + j] = c[j] as f32;
        }
    }
    let mean_ref = &mean;
    let weights: Vec<f32> = rows
        .par_chunks(len)
        .flat_map_iter(|row| {
            comp64.iter().map(move |c| {
                row.iter()
                    .zip(c)
                    .zip(mean_ref)
                    .map(|((x, u), m)| (*x as f64 - m) * u)
                    .sum::<f64>() as f32
            })
        })
        .collect();
    Compressed {
        mean: mean.iter().map(|&m| m as f32).collect(),
        components,
        weights,
        rank,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows that vary along one direction about a mean far from zero: one component holds
    /// them exactly, but only about the right mean (about any other point they span two
    /// dimensions). A wrong mean, or weights taken about another point, fails.
    #[test]
    fn one_component_reconstructs_rank_one_rows_about_their_mean() {
        let (n, len) = (50, 6);
        let mean = [3.0f32, -2.0, 5.0, 1.0, 0.5, 4.0];
        let dir = [0.5f32, 0.5, -0.5, 0.5, 0.0, 0.0];
        let rows: Vec<f32> = (0..n)
            .flat_map(|p| {
                // Symmetric about 0, so the rows' mean is `mean` itself.
                let a = (p as f32 - (n - 1) as f32 / 2.0) * 0.1;
                (0..len).map(move |j| mean[j] + a * dir[j])
            })
            .collect();
        // Asked for more components than the data has, only the one with variance is kept
        // (the others are rounding noise, positive or negative).
        assert_eq!(pca_rows(&rows, n, len, 4).rank, 1);
        let c = pca_rows(&rows, n, len, 1);
        assert_eq!(c.rank, 1);
        for (j, (&got, &want)) in c.mean.iter().zip(&mean).enumerate() {
            assert!((got - want).abs() < 1e-4, "mean[{j}] {got} vs {want}");
        }
        for p in 0..n {
            for j in 0..len {
                let rebuilt = c.mean[j] + c.weights[p] * c.components[j];
                let x = rows[p * len + j];
                assert!((rebuilt - x).abs() < 1e-4, "row {p}[{j}]: {rebuilt} vs {x}");
            }
        }
    }
}
