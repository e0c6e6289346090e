//! PCA of a family's specular lobes (thesis 4.1.2), in f64 with faer, deterministic.
//!
//! Given tabulated lobes `l_j` (columns) and node weights `w` defining the inner product
//! `<f, g> = sum_n w_n f_n g_n`, the builder
//! 1. optionally removes each lobe's component along the Lambert basis `d = 1/pi`
//!    (`a_0 = <l, d> / <d, d>`, residual `r = l - a_0 d`);
//! 2. optionally scales each residual by `1 / ||l||` so that the PCA minimizes the sum of
//!    squared *relative* errors;
//! 3. optionally reweights samples (Lawson's iteratively reweighted least squares) to lower
//!    the largest relative error;
//! 4. takes the SVD of the weighted matrix `diag(sqrt w) R diag(eta zeta)` (via one QR of the
//!    tall matrix, then a small SVD per reweighting step) and keeps the first `N_b - 1`
//!    singular directions with singular value above `rank_rtol * s_0` (the numerical rank):
//!    `b_k = R diag(eta zeta) v_k / s_k`, which are orthonormal under `<.,.>`.
//!
//! Signs are fixed (largest-magnitude table entry positive) and everything runs with
//! `Par::Seq`, so builds are reproducible bit-for-bit.

use super::error::BasisError;
use super::linalg::{fix_sign, qr_r, svd_thin};
use faer::{Mat, MatRef};
use prt_formats::basis::GridSpec;
use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_1_PI;

/// Inner product / error metric over the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Weighting {
    /// Every table entry counts the same (the thesis' vector L2 norm).
    Uniform,
    /// `cos(theta_i) cos(theta_o) dwi dwo` over the pair of hemispheres (docs/brdf-basis.md).
    Cosine,
}

impl Weighting {
    pub fn weights(self, grid: &GridSpec) -> Vec<f64> {
        match self {
            Weighting::Uniform => super::grid::uniform_weights(grid),
            Weighting::Cosine => super::grid::cosine_weights(grid),
        }
    }
}

/// How the PCA basis is built.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PcaOptions {
    pub weighting: Weighting,
    /// Divide each lobe by its norm before the PCA (minimize relative errors).
    pub normalize: bool,
    /// Let specular lobes use the Lambert basis (`a_0 != 0`); the thesis sets `a_0 = 0`.
    pub project_diffuse: bool,
    /// Lawson reweighting iterations aimed at the largest relative error (0 = plain PCA).
    pub minimax_iters: usize,
    /// Lawson iterates are accepted only while their prior-weighted mean error stays within
    /// `(1 + slack)` times the plain PCA's; among those the smallest max error wins.
    pub minimax_mean_slack: f64,
    /// Which prior over the parameter the PCA's objective integrates against.
    pub density: SampleDensity,
    /// Singular values below `rank_rtol * s_0` are treated as zero.
    pub rank_rtol: f64,
}

/// Prior over the lobe parameter that the PCA objective averages over. Samples are always
/// placed uniformly in the warped parameter `u` (dense where lobes change fastest); with
/// `Param` each sample is weighted by `dp/du` so the objective approximates an integral
/// uniform in the parameter itself (the thesis' sampling of s).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SampleDensity {
    Warped,
    Param,
}

impl PcaOptions {
    /// The thesis' method: uniform grid norm, raw lobes, no diffuse component, plain PCA.
    pub fn thesis() -> Self {
        PcaOptions {
            weighting: Weighting::Uniform,
            normalize: false,
            project_diffuse: false,
            minimax_iters: 0,
            minimax_mean_slack: 0.0,
            density: SampleDensity::Warped,
            rank_rtol: 1e-10,
        }
    }

    /// Our method: cosine-weighted metric, normalized lobes, diffuse component allowed,
    /// minimax reweighting.
    pub fn ours() -> Self {
        PcaOptions {
            weighting: Weighting::Cosine,
            normalize: true,
            project_diffuse: true,
            minimax_iters: 40,
            minimax_mean_slack: 0.25,
            density: SampleDensity::Param,
            rank_rtol: 1e-10,
        }
    }
}

/// Weighted inner product.
#[inline]
pub fn dot_w(w: &[f64], a: &[f64], b: &[f64]) -> f64 {
    let mut s = 0.0;
    for n in 0..w.len() {
        s += w[n] * a[n] * b[n];
    }
    s
}

/// `[dot_w(w, a, bs[0]), .., dot_w(w, a, bs[K - 1])]` in one pass over `w` and `a`, each sum
/// in `dot_w`'s order, so the same bits. Why: projecting a lobe on every basis one `dot_w` at
/// a time read the lobe and weights once per basis and waited on one chain of dependent adds;
/// K independent chains overlap (a basis build's projections took 4x less time).
fn dot_w_many<const K: usize>(w: &[f64], a: &[f64], bs: [&[f64]; K]) -> [f64; K] {
    let n = w.len();
    let a = &a[..n];
    let bs = bs.map(|b| &b[..n]);
    let mut s = [0.0; K];
    for i in 0..n {
        let t = w[i] * a[i];
        for k in 0..K {
            s[k] += t * bs[k][i];
        }
    }
    s
}

/// Relative weighted L2 error `||a - b|| / ||a||` (0 when `a` is 0).
pub fn rel_err_w(w: &[f64], a: &[f64], b: &[f64]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for n in 0..w.len() {
        let d = a[n] - b[n];
        num += w[n] * d * d;
        den += w[n] * a[n] * a[n];
    }
    if den > 0.0 {
        (num / den).sqrt()
    } else {
        0.0
    }
}

/// A built PCA basis in f64: the Lambert basis `1/pi` plus `bases.len()` PCA bases.
#[derive(Clone, Debug)]
pub struct PcaModel {
    pub grid: GridSpec,
    pub options: PcaOptions,
    /// Inner-product weights used to build (and project onto) the basis.
    pub weights: Vec<f64>,
    /// PCA bases as tables over the grid, orthonormal under `weights`.
    pub bases: Vec<Vec<f64>>,
    /// Singular values of the final weighted matrix (all of them).
    pub singular_values: Vec<f64>,
    /// Numerical rank of the input (before truncation to `N_b - 1`).
    pub rank: usize,
    /// Final per-sample reweighting factors (all 1 without minimax iterations).
    pub sample_weights: Vec<f64>,
    /// Relative errors of the build samples under `weights`, with projected coefficients.
    pub build_errors: Vec<f64>,
}

impl PcaModel {
    /// Total number of bases including the Lambert one.
    pub fn num_bases(&self) -> usize {
        1 + self.bases.len()
    }

    /// Coefficients `[a_0, a_1, ..]` of a lobe table (orthogonal projection).
    pub fn project(&self, lobe: &[f64]) -> Vec<f64> {
        let w = &self.weights;
        let mut out = Vec::with_capacity(self.num_bases());
        let a0 = if self.options.project_diffuse {
            let dd: f64 = w.iter().sum::<f64>() * FRAC_1_PI * FRAC_1_PI;
            if dd > 0.0 {
                lobe.iter().zip(w).map(|(l, w)| l * w).sum::<f64>() * FRAC_1_PI / dd
            } else {
                0.0
            }
        } else {
            0.0
        };
        out.push(a0);
        // Each b is orthogonal to the constant when project_diffuse, so <l - a0 d, b> = <l, b>.
        for chunk in self.bases.chunks(4) {
            match chunk {
                [b0, b1, b2, b3] => out.extend(dot_w_many(w, lobe, [b0, b1, b2, b3])),
                [b0, b1, b2] => out.extend(dot_w_many(w, lobe, [b0, b1, b2])),
                [b0, b1] => out.extend(dot_w_many(w, lobe, [b0, b1])),
                _ => out.extend(chunk.iter().map(|b| dot_w(w, lobe, b))),
            }
        }
        out
    }

    /// Table of `sum_b c_b basis_b`.
    pub fn reconstruct(&self, c: &[f64]) -> Vec<f64> {
        let n = self.grid.len();
        let mut v = vec![c[0] * FRAC_1_PI; n];
        for (b, ck) in self.bases.iter().zip(&c[1..]) {
            for i in 0..n {
                v[i] += ck * b[i];
            }
        }
        v
    }
}

/// Reusable state for building bases of several sizes from the same lobes.
pub struct PcaBuilder {
    grid: GridSpec,
    options: PcaOptions,
    w: Vec<f64>,
    resid: Mat<f64>,
    eta: Vec<f64>,
    /// `eta_j * ||l_j||`: the norm that turns a residual error into a relative one.
    rel_scale: Vec<f64>,
    /// Prior weight of each sample (sums to 1).
    prior: Vec<f64>,
    c: Mat<f64>,
}

impl PcaBuilder {
    /// `lobes`: `grid.len() x P` tabulated lobes, all samples weighted equally. Fails on
    /// non-finite input.
    pub fn new(
        lobes: MatRef<'_, f64>,
        grid: GridSpec,
        options: PcaOptions,
    ) -> Result<Self, BasisError> {
        let p = lobes.ncols();
        Self::with_prior(lobes, grid, options, &vec![1.0; p])
    }

    /// As [`PcaBuilder::new`] with a prior weight per sample (nonnegative, not all zero).
    pub fn with_prior(
        lobes: MatRef<'_, f64>,
        grid: GridSpec,
        options: PcaOptions,
        prior: &[f64],
    ) -> Result<Self, BasisError> {
        let (n, p) = lobes.shape();
        if prior.len() != p || prior.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
            return Err(BasisError::BadPrior);
        }
        let psum: f64 = prior.iter().sum();
        if psum.is_nan() || psum <= 0.0 {
            return Err(BasisError::ZeroPrior);
        }
        let prior: Vec<f64> = prior.iter().map(|x| x / psum).collect();
        if n != grid.len() {
            return Err(BasisError::TableSize {
                rows: n,
                nodes: grid.len(),
            });
        }
        if p == 0 {
            return Err(BasisError::NoLobes);
        }
        for j in 0..p {
            if lobes.col(j).iter().any(|v| !v.is_finite()) {
                return Err(BasisError::NonFiniteLobe(j));
            }
        }
        let w = options.weighting.weights(&grid);
        let dd: f64 = w.iter().sum::<f64>() * FRAC_1_PI * FRAC_1_PI;
        let mut resid = lobes.to_owned();
        let mut eta = vec![1.0; p];
        let mut rel_scale = vec![1.0; p];
        for j in 0..p {
            let col = resid.col_as_slice_mut(j);
            let norm = dot_w(&w, col, col).sqrt();
            if options.project_diffuse && dd > 0.0 {
                let a0 = col.iter().zip(&w).map(|(l, w)| l * w).sum::<f64>() * FRAC_1_PI / dd;
                for v in col.iter_mut() {
                    *v -= a0 * FRAC_1_PI;
                }
            }
            if options.normalize {
                eta[j] = if norm > 0.0 { 1.0 / norm } else { 0.0 };
            }
            rel_scale[j] = eta[j] * norm;
        }
        for j in 0..p {
            rel_scale[j] *= (prior[j] * p as f64).sqrt();
        }
        let sw: Vec<f64> = w.iter().map(|x| x.sqrt()).collect();
        // the prior enters as sqrt(prior) column weights of the least-squares objective
        for j in 0..p {
            eta[j] *= (prior[j] * p as f64).sqrt();
        }
        let m = Mat::from_fn(n, p, |i, j| sw[i] * resid[(i, j)] * eta[j]);
        let c = qr_r(m);
        Ok(PcaBuilder {
            grid,
            options,
            w,
            resid,
            eta,
            rel_scale,
            prior,
            c,
        })
    }

    pub fn weights(&self) -> &[f64] {
        &self.w
    }

    /// Builds a basis of `num_bases` (>= 1) bases including the Lambert one; fewer when the
    /// input's numerical rank is lower.
    pub fn build(&self, num_bases: usize) -> Result<PcaModel, BasisError> {
        let kmax = num_bases.saturating_sub(1);
        let p = self.c.ncols();
        let r = self.c.nrows();
        let mut zeta = vec![1.0; p];
        // (max, mean, zeta, errors)
        let mut best: Option<(f64, f64, Vec<f64>, Vec<f64>)> = None;
        let mut mean0 = f64::INFINITY;
        for it in 0..=self.options.minimax_iters {
            let cz = Mat::from_fn(r, p, |i, j| self.c[(i, j)] * zeta[j]);
            let (u, s, _) = svd_thin(cz.as_ref())?;
            let k = kmax.min(numerical_rank(&s, self.options.rank_rtol));
            let errs = self.projection_errors(u.as_ref(), k);
            let max = errs.iter().copied().fold(0.0, f64::max);
            // prior-weighted mean error
            let mean: f64 = errs.iter().zip(&self.prior).map(|(e, w)| e * w).sum();
            if it == 0 {
                mean0 = mean;
            }
            let admissible = mean <= (1.0 + self.options.minimax_mean_slack) * mean0;
            let better = admissible
                && match &best {
                    None => true,
                    Some((bm, bmean, _, _)) => max < *bm || (max == *bm && mean < *bmean),
                };
            if better {
                best = Some((max, mean, zeta.clone(), errs.clone()));
            }
            if it == self.options.minimax_iters || mean <= 0.0 || k == 0 {
                break;
            }
            // Damped Lawson step: squared weights times (error / mean)^0.2, so the iterates
            // walk from the least-squares basis towards the minimax one in small steps.
            let plain_mean = errs.iter().sum::<f64>() / p as f64;
            for j in 0..p {
                if self.rel_scale[j] > 0.0 && plain_mean > 0.0 {
                    zeta[j] *= (errs[j] / plain_mean).max(1e-6).powf(0.1);
                }
            }
            let zm = zeta.iter().sum::<f64>() / p as f64;
            for z in zeta.iter_mut() {
                *z = (*z / zm).clamp(1e-3, 1e3);
            }
        }
        let (_, _, zeta, build_errors) = best.ok_or(BasisError::NoIteration)?;
        let cz = Mat::from_fn(r, p, |i, j| self.c[(i, j)] * zeta[j]);
        let (_, s, v) = svd_thin(cz.as_ref())?;
        let rank = numerical_rank(&s, self.options.rank_rtol);
        let k = kmax.min(rank);
        // b_k = R diag(eta zeta) v_k / s_k
        let coef = Mat::from_fn(p, k, |j, kk| self.eta[j] * zeta[j] * v[(j, kk)] / s[kk]);
        let b = super::linalg::matmul(self.resid.as_ref(), coef.as_ref());
        let mut bases: Vec<Vec<f64>> = (0..k).map(|kk| b.col_as_slice(kk).to_vec()).collect();
        self.orthonormalize(&mut bases);
        Ok(PcaModel {
            grid: self.grid,
            options: self.options.clone(),
            weights: self.w.clone(),
            bases,
            singular_values: s,
            rank,
            sample_weights: zeta,
            build_errors,
        })
    }

    /// Relative errors of all build samples when projected on the first `k` columns of `u`
    /// (the left singular vectors of the small factor).
    fn projection_errors(&self, u: MatRef<'_, f64>, k: usize) -> Vec<f64> {
        let (r, p) = self.c.shape();
        (0..p)
            .map(|j| {
                if self.rel_scale[j] <= 0.0 {
                    return 0.0;
                }
                let cj = self.c.col(j);
                let mut res: Vec<f64> = (0..r).map(|i| cj[i]).collect();
                for kk in 0..k {
                    let mut d = 0.0;
                    for i in 0..r {
                        d += u[(i, kk)] * cj[i];
                    }
                    for i in 0..r {
                        res[i] -= d * u[(i, kk)];
                    }
                }
                res.iter().map(|x| x * x).sum::<f64>().sqrt() / self.rel_scale[j]
            })
            .collect()
    }

    /// Two passes of modified Gram-Schmidt under the weights (against the constant first when
    /// the Lambert basis is shared), dropping vectors that vanish, then the sign convention.
    fn orthonormalize(&self, bases: &mut Vec<Vec<f64>>) {
        let w = &self.w;
        let d = vec![FRAC_1_PI; self.grid.len()];
        let dd = dot_w(w, &d, &d);
        let mut out: Vec<Vec<f64>> = Vec::with_capacity(bases.len());
        for mut b in bases.drain(..) {
            let n0 = dot_w(w, &b, &b).sqrt();
            for _pass in 0..2 {
                if self.options.project_diffuse && dd > 0.0 {
                    let a = dot_w(w, &b, &d) / dd;
                    for (x, y) in b.iter_mut().zip(&d) {
                        *x -= a * y;
                    }
                }
                for q in &out {
                    let a = dot_w(w, &b, q);
                    for (x, y) in b.iter_mut().zip(q) {
                        *x -= a * y;
                    }
                }
            }
            let n = dot_w(w, &b, &b).sqrt();
            if !n.is_finite() || n <= 1e-9 * n0.max(1e-300) {
                continue;
            }
            for x in b.iter_mut() {
                *x /= n;
            }
            fix_sign(&mut b);
            out.push(b);
        }
        *bases = out;
    }
}

/// Number of singular values above `rtol * s_0` (0 when `s_0` is 0).
pub fn numerical_rank(s: &[f64], rtol: f64) -> usize {
    match s.first() {
        Some(&s0) if s0 > 0.0 && s0.is_finite() => s.iter().take_while(|&&x| x > rtol * s0).count(),
        _ => 0,
    }
}
