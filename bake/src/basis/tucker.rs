//! Tensor basis for shading (thesis 5.2.2, 5.3.1): the family sampled as a 3-tensor
//! `F(h, wo, wi)` (h = lobe parameter sample, wo/wi = directions on a hemisphere grid),
//! optionally minus a specular part made of Gaussians about the mirror direction, then a
//! Tucker decomposition `F ~ D x_h U^h x_o U^o x_i U^i` (HOSVD start, HOOI refinement).
//!
//! Metric: entries are scaled by `sqrt(cos(theta_o) cos(theta_i) dwo dwi)` and every lobe is
//! normalized to unit norm, so the Frobenius norm is the cosine-weighted L2 norm of
//! docs/brdf-basis.md and the reported error `||F - F^|| / ||F||` is the RMS of the lobes'
//! relative errors. The scalings are per mode, so unscaling the factor matrices gives a Tucker
//! decomposition of the raw BRDF values.

use super::error::BasisError;
use super::grid::lobe_f64;
use super::linalg::{fix_sign, matmul, matmul_tn, sym_eig_desc};
use super::FamilySpec;
use crate::brdf::Family;
use faer::Mat;
use rayon::prelude::*;
use serde::Serialize;

/// The equal-area hemisphere grid of the tensor's direction modes; it lives in
/// `prt_formats::basis` because the shading basis persists tables over it.
pub use prt_formats::basis::HemiGrid;

/// Gaussian widths of the specular split (thesis 5.3.1), degrees; 0 = a mirror spike.
pub const SPLIT_WIDTHS_DEG: [f64; 4] = [0.0, 7.0, 14.0, 21.0];

/// The sampled, scaled tensor, layout `[h][o][i]` (i fastest).
pub struct BrdfTensor {
    pub spec: FamilySpec,
    pub params: Vec<f64>,
    pub dirs: HemiGrid,
    pub data: Vec<f64>,
    /// Per-direction scale `sqrt(cos(theta) dw)`.
    pub dir_scale: Vec<f64>,
    /// Per-lobe normalization applied (1 / cosine-weighted norm).
    pub lobe_scale: Vec<f64>,
}

impl BrdfTensor {
    /// The lobe sampled at the grid's nodes (both directions).
    pub fn new(spec: FamilySpec, params: Vec<f64>, dirs: HemiGrid) -> BrdfTensor {
        let dv: Vec<[f64; 3]> = (0..dirs.len()).map(|n| dirs.dir(n)).collect();
        BrdfTensor::from_rows(spec, params, dirs, |p, o, row| {
            for (v, wi) in row.iter_mut().zip(&dv) {
                *v = eval_pair(spec, p, dv[o], *wi);
            }
        })
    }

    /// A tensor whose raw (unscaled) values `F(p, o, .)` over the incident directions are
    /// written by `row(p, o, out)`; scaled and normalized as [`BrdfTensor::new`]. Slabs are
    /// computed in parallel, each value independently, so the result does not depend on the
    /// thread count.
    pub fn from_rows(
        spec: FamilySpec,
        params: Vec<f64>,
        dirs: HemiGrid,
        row: impl Fn(f64, usize, &mut [f64]) + Sync,
    ) -> BrdfTensor {
        let nd = dirs.len();
        let dir_scale: Vec<f64> = (0..nd)
            .map(|n| (dirs.dir(n)[2] * dirs.solid_angle()).sqrt())
            .collect();
        let slabs: Vec<(Vec<f64>, f64)> = params
            .par_iter()
            .map(|&p| {
                let mut s = vec![0.0; nd * nd];
                for (o, r) in s.chunks_exact_mut(nd).enumerate() {
                    row(p, o, r);
                    for (v, si) in r.iter_mut().zip(&dir_scale) {
                        *v *= dir_scale[o] * si;
                    }
                }
                let norm = s.iter().map(|x| x * x).sum::<f64>().sqrt();
                let sc = if norm > 0.0 { 1.0 / norm } else { 0.0 };
                for x in s.iter_mut() {
                    *x *= sc;
                }
                (s, sc)
            })
            .collect();
        let mut data = Vec::with_capacity(params.len() * nd * nd);
        let mut lobe_scale = Vec::new();
        for (s, sc) in slabs {
            data.extend_from_slice(&s);
            lobe_scale.push(sc);
        }
        BrdfTensor {
            spec,
            params,
            dirs,
            data,
            dir_scale,
            lobe_scale,
        }
    }

    pub fn dims(&self) -> (usize, usize, usize) {
        (self.params.len(), self.dirs.len(), self.dirs.len())
    }
}

fn eval_pair(spec: FamilySpec, p: f64, wo: [f64; 3], wi: [f64; 3]) -> f64 {
    let to = wo[2].clamp(-1.0, 1.0).acos();
    let ti = wi[2].clamp(-1.0, 1.0).acos();
    let lo = (wo[0] * wo[0] + wo[1] * wo[1]).sqrt();
    let li = (wi[0] * wi[0] + wi[1] * wi[1]).sqrt();
    let cp = if lo * li > 1e-300 {
        ((wo[0] * wi[0] + wo[1] * wi[1]) / (lo * li)).clamp(-1.0, 1.0)
    } else {
        1.0
    };
    lobe_f64(spec.family, p, ti, to, cp.acos())
}

/// The specular split: per (h, wo) nonnegative amplitudes of the Gaussians in
/// [`SPLIT_WIDTHS_DEG`], fitted by nonnegative least squares (in the tensor's metric) to the
/// wi-fiber, and the residual tensor.
pub struct SpecularSplit {
    /// `[h][o][k]` amplitudes.
    pub amplitudes: Vec<f64>,
    /// Residual tensor, same layout and scaling as the input.
    pub residual: Vec<f64>,
    /// `||specular part|| / ||F||`.
    pub specular_fraction: f64,
}

/// Gaussian profiles (scaled like the tensor) about the mirror direction of each `wo`:
/// `[o][k][i]`. Width 0 is a unit spike at the grid direction nearest to the mirror direction.
pub fn split_profiles(dirs: &HemiGrid, dir_scale: &[f64]) -> Vec<f64> {
    let nd = dirs.len();
    let nk = SPLIT_WIDTHS_DEG.len();
    let dv: Vec<[f64; 3]> = (0..nd).map(|n| dirs.dir(n)).collect();
    let mut g = vec![0.0; nd * nk * nd];
    for o in 0..nd {
        let w = dv[o];
        let r = [-w[0], -w[1], w[2]];
        let mut nearest = 0;
        let mut best = -2.0;
        for (i, d) in dv.iter().enumerate() {
            let c = d[0] * r[0] + d[1] * r[1] + d[2] * r[2];
            if c > best {
                best = c;
                nearest = i;
            }
        }
        for (k, &wd) in SPLIT_WIDTHS_DEG.iter().enumerate() {
            let base = (o * nk + k) * nd;
            if wd == 0.0 {
                g[base + nearest] = dir_scale[nearest] * dir_scale[o];
                continue;
            }
            let sig = wd.to_radians();
            for (i, d) in dv.iter().enumerate() {
                let c = (d[0] * r[0] + d[1] * r[1] + d[2] * r[2]).clamp(-1.0, 1.0);
                let a = c.acos();
                g[base + i] = (-a * a / (2.0 * sig * sig)).exp() * dir_scale[i] * dir_scale[o];
            }
        }
    }
    g
}

/// Nonnegative least squares for a handful of unknowns by enumerating active sets: minimize
/// `||y - G^T a||` with `a >= 0`, given the Gram matrix `gg = G G^T` and `gy = G y`.
fn nnls_small(gg: &[f64], gy: &[f64], k: usize) -> Vec<f64> {
    let mut best = vec![0.0; k];
    let mut best_obj = 0.0; // objective relative to ||y||^2: -2 a.gy + a.gg.a
    for mask in 1u32..(1 << k) {
        let idx: Vec<usize> = (0..k).filter(|&j| mask & (1 << j) != 0).collect();
        let m = idx.len();
        // solve the m x m system by Gaussian elimination with partial pivoting
        let mut a = vec![0.0; m * (m + 1)];
        for (r, &jr) in idx.iter().enumerate() {
            for (c, &jc) in idx.iter().enumerate() {
                a[r * (m + 1) + c] = gg[jr * k + jc];
            }
            a[r * (m + 1) + m] = gy[jr];
        }
        let mut ok = true;
        for col in 0..m {
            let piv = (col..m)
                .max_by(|&x, &y| {
                    a[x * (m + 1) + col]
                        .abs()
                        .total_cmp(&a[y * (m + 1) + col].abs())
                })
                .unwrap_or(col);
            if a[piv * (m + 1) + col].abs() < 1e-300 {
                ok = false;
                break;
            }
            for c in 0..=m {
                a.swap(col * (m + 1) + c, piv * (m + 1) + c);
            }
            for r in 0..m {
                if r != col {
                    let f = a[r * (m + 1) + col] / a[col * (m + 1) + col];
                    for c in col..=m {
                        a[r * (m + 1) + c] -= f * a[col * (m + 1) + c];
                    }
                }
            }
        }
        if !ok {
            continue;
        }
        let mut x = vec![0.0; k];
        let mut feasible = true;
        for (r, &jr) in idx.iter().enumerate() {
            let v = a[r * (m + 1) + m] / a[r * (m + 1) + r];
            if !v.is_finite() || v < 0.0 {
                feasible = false;
            }
            x[jr] = v;
        }
        if !feasible {
            continue;
        }
        let mut obj = 0.0;
        for p in 0..k {
            obj -= 2.0 * x[p] * gy[p];
            for q in 0..k {
                obj += x[p] * gg[p * k + q] * x[q];
            }
        }
        if obj < best_obj {
            best_obj = obj;
            best = x;
        }
    }
    best
}

/// The Gram matrix `G G^T` (`nk x nk`) of `nk` profiles stored one after the other.
pub fn profile_gram(g: &[f64], nk: usize) -> Vec<f64> {
    let nd = g.len() / nk.max(1);
    let mut gg = vec![0.0; nk * nk];
    for p in 0..nk {
        for q in 0..nk {
            let (a, b) = (&g[p * nd..][..nd], &g[q * nd..][..nd]);
            gg[p * nk + q] = a.iter().zip(b).map(|(x, y)| x * y).sum();
        }
    }
    gg
}

/// Fits the `nk` profiles `g` (one after the other, Gram matrix `gram`) to the fibre `y` by
/// nonnegative least squares, subtracts the fit from `y` and returns the amplitudes.
pub fn split_fibre(y: &mut [f64], g: &[f64], gram: &[f64], nk: usize) -> Vec<f64> {
    let nd = y.len();
    let gy: Vec<f64> = (0..nk)
        .map(|k| {
            g[k * nd..][..nd]
                .iter()
                .zip(y.iter())
                .map(|(a, b)| a * b)
                .sum()
        })
        .collect();
    let a = nnls_small(gram, &gy, nk);
    for k in 0..nk {
        for (v, p) in y.iter_mut().zip(&g[k * nd..][..nd]) {
            *v -= a[k] * p;
        }
    }
    a
}

/// Fits and removes the specular Gaussians from every (h, wo) fiber.
pub fn specular_split(t: &BrdfTensor) -> SpecularSplit {
    specular_split_with(t, &split_profiles(&t.dirs, &t.dir_scale))
}

/// [`specular_split`] with the profiles `g` (`[o][k][i]`, scaled like the tensor, one per
/// width of [`SPLIT_WIDTHS_DEG`]) given.
pub fn specular_split_with(t: &BrdfTensor, g: &[f64]) -> SpecularSplit {
    let (nh, nd, _) = t.dims();
    let nk = SPLIT_WIDTHS_DEG.len();
    let grams: Vec<Vec<f64>> = (0..nd)
        .map(|o| profile_gram(&g[o * nk * nd..(o + 1) * nk * nd], nk))
        .collect();
    let results: Vec<(Vec<f64>, Vec<f64>)> = (0..nh)
        .into_par_iter()
        .map(|h| {
            let mut amps = vec![0.0; nd * nk];
            let mut res = t.data[h * nd * nd..(h + 1) * nd * nd].to_vec();
            for o in 0..nd {
                let y = &mut res[o * nd..(o + 1) * nd];
                let prof = &g[o * nk * nd..(o + 1) * nk * nd];
                let a = split_fibre(y, prof, &grams[o], nk);
                amps[o * nk..(o + 1) * nk].copy_from_slice(&a);
            }
            (amps, res)
        })
        .collect();
    let mut amplitudes = Vec::with_capacity(nh * nd * nk);
    let mut residual = Vec::with_capacity(t.data.len());
    for (a, r) in results {
        amplitudes.extend_from_slice(&a);
        residual.extend_from_slice(&r);
    }
    let total: f64 = t.data.iter().map(|x| x * x).sum();
    let spec: f64 = t
        .data
        .iter()
        .zip(&residual)
        .map(|(a, b)| (a - b) * (a - b))
        .sum();
    SpecularSplit {
        amplitudes,
        residual,
        specular_fraction: if total > 0.0 {
            (spec / total).sqrt()
        } else {
            0.0
        },
    }
}

/// A Tucker decomposition: orthonormal factors (columns) and the core `[rh][ro][ri]`.
pub struct Tucker {
    pub u_h: Mat<f64>,
    pub u_o: Mat<f64>,
    pub u_i: Mat<f64>,
    pub core: Vec<f64>,
    pub ranks: (usize, usize, usize),
    /// `||X - X^||_F / ||X||_F`.
    pub rel_error: f64,
    /// HOOI sweeps run.
    pub sweeps: usize,
}

/// Leading `r` eigenvectors (sign-fixed) of the Gram matrix of the rows of the mode
/// unfolding given as a `dim x rest` matrix.
fn leading_left(unfold: &Mat<f64>, r: usize) -> Result<Mat<f64>, BasisError> {
    let g = matmul(unfold.as_ref(), unfold.transpose());
    let (_, v) = sym_eig_desc(g.as_ref())?;
    let r = r.min(v.ncols());
    let mut u = Mat::<f64>::zeros(v.nrows(), r);
    for c in 0..r {
        let mut col: Vec<f64> = (0..v.nrows()).map(|i| v[(i, c)]).collect();
        fix_sign(&mut col);
        for (i, x) in col.into_iter().enumerate() {
            u[(i, c)] = x;
        }
    }
    Ok(u)
}

/// Mode unfoldings of a tensor `[a][b][c]` (c fastest).
fn unfold(x: &[f64], dims: (usize, usize, usize), mode: usize) -> Mat<f64> {
    let (a, b, c) = dims;
    match mode {
        0 => Mat::from_fn(a, b * c, |i, j| x[i * b * c + j]),
        1 => Mat::from_fn(b, a * c, |i, j| x[(j / c) * b * c + i * c + j % c]),
        _ => Mat::from_fn(c, a * b, |i, j| x[j * c + i]),
    }
}

/// `x ×_mode U^T` for a tensor `[a][b][c]`, returning the new tensor and its dims.
fn contract(
    x: &[f64],
    dims: (usize, usize, usize),
    mode: usize,
    u: &Mat<f64>,
) -> (Vec<f64>, (usize, usize, usize)) {
    let (a, b, c) = dims;
    let r = u.ncols();
    match mode {
        0 => {
            let xm = Mat::from_fn(a, b * c, |i, j| x[i * b * c + j]);
            let y = matmul_tn(u.as_ref(), xm.as_ref()); // r x (b c)
            let mut out = vec![0.0; r * b * c];
            for i in 0..r {
                for j in 0..b * c {
                    out[i * b * c + j] = y[(i, j)];
                }
            }
            (out, (r, b, c))
        }
        1 => {
            let mut out = vec![0.0; a * r * c];
            for ia in 0..a {
                let xm = Mat::from_fn(b, c, |i, j| x[ia * b * c + i * c + j]);
                let y = matmul_tn(u.as_ref(), xm.as_ref()); // r x c
                for i in 0..r {
                    for j in 0..c {
                        out[ia * r * c + i * c + j] = y[(i, j)];
                    }
                }
            }
            (out, (a, r, c))
        }
        _ => {
            let xm = Mat::from_fn(a * b, c, |i, j| x[i * c + j]);
            let y = matmul(xm.as_ref(), u.as_ref()); // (a b) x r
            let mut out = vec![0.0; a * b * r];
            for i in 0..a * b {
                for j in 0..r {
                    out[i * r + j] = y[(i, j)];
                }
            }
            (out, (a, b, r))
        }
    }
}

/// HOSVD factors of all three modes, full rank (computed once, truncated per rank choice).
pub struct Hosvd {
    pub factors: [Mat<f64>; 3],
}

pub fn hosvd(x: &[f64], dims: (usize, usize, usize)) -> Result<Hosvd, BasisError> {
    let f0 = leading_left(&unfold(x, dims, 0), dims.0)?;
    let f1 = leading_left(&unfold(x, dims, 1), dims.1)?;
    let f2 = leading_left(&unfold(x, dims, 2), dims.2)?;
    Ok(Hosvd {
        factors: [f0, f1, f2],
    })
}

fn truncate(u: &Mat<f64>, r: usize) -> Mat<f64> {
    let r = r.min(u.ncols());
    Mat::from_fn(u.nrows(), r, |i, j| u[(i, j)])
}

/// Tucker decomposition to `ranks` (clamped to the dimensions): HOSVD start, then HOOI sweeps
/// until the error improves by less than `tol` (relative) or `max_sweeps` is reached.
pub fn tucker(
    x: &[f64],
    dims: (usize, usize, usize),
    start: &Hosvd,
    ranks: (usize, usize, usize),
    max_sweeps: usize,
    tol: f64,
) -> Result<Tucker, BasisError> {
    let norm2: f64 = x.iter().map(|v| v * v).sum();
    let mut u = [
        truncate(&start.factors[0], ranks.0),
        truncate(&start.factors[1], ranks.1),
        truncate(&start.factors[2], ranks.2),
    ];
    let err_of = |u: &[Mat<f64>; 3]| -> (Vec<f64>, f64) {
        let (t, d) = contract(x, dims, 0, &u[0]);
        let (t, d) = contract(&t, d, 1, &u[1]);
        let (core, _) = contract(&t, d, 2, &u[2]);
        let c2: f64 = core.iter().map(|v| v * v).sum();
        let e = if norm2 > 0.0 {
            ((norm2 - c2).max(0.0) / norm2).sqrt()
        } else {
            0.0
        };
        (core, e)
    };
    let (mut core, mut err) = err_of(&u);
    let mut sweeps = 0;
    for _ in 0..max_sweeps {
        // mode 0: contract modes 1 and 2
        let (t, d) = contract(x, dims, 2, &u[2]);
        let (t, d) = contract(&t, d, 1, &u[1]);
        u[0] = leading_left(&unfold(&t, d, 0), u[0].ncols())?;
        let (t, d) = contract(x, dims, 0, &u[0]);
        let (t2, d2) = contract(&t, d, 2, &u[2]);
        u[1] = leading_left(&unfold(&t2, d2, 1), u[1].ncols())?;
        let (t3, d3) = contract(&t, d, 1, &u[1]);
        u[2] = leading_left(&unfold(&t3, d3, 2), u[2].ncols())?;
        sweeps += 1;
        let (c, e) = err_of(&u);
        let improved = err - e;
        core = c;
        let old = err;
        err = e;
        if improved <= tol * old.max(1e-300) {
            break;
        }
    }
    let ranks = (u[0].ncols(), u[1].ncols(), u[2].ncols());
    let [u_h, u_o, u_i] = u;
    Ok(Tucker {
        u_h,
        u_o,
        u_i,
        core,
        ranks,
        rel_error: err,
        sweeps,
    })
}

/// One cell of the error grid.
#[derive(Clone, Debug, Serialize)]
pub struct TuckerCell {
    pub n_h: usize,
    pub n_dir: usize,
    /// `||F - T(F)|| / ||F||` without the split.
    pub plain: f64,
    /// `||F - (S + T(F - S))|| / ||F||` with the specular split S.
    pub split: f64,
}

/// The error grid of thesis figure 5-5, with and without the specular split.
#[derive(Clone, Debug, Serialize)]
pub struct TuckerReport {
    pub family: Family,
    pub param_range: [f64; 2],
    pub param_samples: usize,
    pub dirs: HemiGrid,
    pub split_widths_deg: Vec<f64>,
    /// `||S|| / ||F||`.
    pub specular_fraction: f64,
    pub cells: Vec<TuckerCell>,
    pub elapsed_ms: f64,
}

/// Runs the grid `n_h in nh_list` x `n_o = n_i in ndir_list`.
pub fn tucker_report(
    spec: FamilySpec,
    param_samples: usize,
    dirs: HemiGrid,
    nh_list: &[usize],
    ndir_list: &[usize],
) -> Result<TuckerReport, BasisError> {
    let t0 = std::time::Instant::now();
    let params = super::grid::param_samples(spec.range, spec.warp, param_samples);
    let t = BrdfTensor::new(spec, params, dirs);
    let dims = t.dims();
    let split = specular_split(&t);
    let norm2: f64 = t.data.iter().map(|v| v * v).sum();
    let rnorm2: f64 = split.residual.iter().map(|v| v * v).sum();
    let h_plain = hosvd(&t.data, dims)?;
    let h_split = hosvd(&split.residual, dims)?;
    let mut cells = Vec::new();
    for &nh in nh_list {
        for &nd in ndir_list {
            let ranks = (nh, nd, nd);
            let a = tucker(&t.data, dims, &h_plain, ranks, 8, 1e-4)?;
            let b = tucker(&split.residual, dims, &h_split, ranks, 8, 1e-4)?;
            // error of the residual's approximation relative to ||F||
            let split_err = if norm2 > 0.0 {
                b.rel_error * (rnorm2 / norm2).sqrt()
            } else {
                0.0
            };
            cells.push(TuckerCell {
                n_h: nh,
                n_dir: nd,
                plain: a.rel_error,
                split: split_err,
            });
        }
    }
    Ok(TuckerReport {
        family: spec.family,
        param_range: [spec.range.0, spec.range.1],
        param_samples,
        dirs,
        split_widths_deg: SPLIT_WIDTHS_DEG.to_vec(),
        specular_fraction: split.specular_fraction,
        cells,
        elapsed_ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tucker_recovers_exact_low_rank() {
        // rank (2, 2, 2) tensor
        let dims = (5, 6, 7);
        let a = |i: usize, r: usize| ((i * (r + 2)) as f64 * 0.37).sin() + r as f64 * 0.1;
        let mut x = vec![0.0; 5 * 6 * 7];
        for h in 0..5 {
            for o in 0..6 {
                for i in 0..7 {
                    x[(h * 6 + o) * 7 + i] =
                        a(h, 0) * a(o, 0) * a(i, 0) + 0.5 * a(h, 1) * a(o, 1) * a(i, 1);
                }
            }
        }
        let s = hosvd(&x, dims).unwrap();
        let t = tucker(&x, dims, &s, (2, 2, 2), 5, 1e-12).unwrap();
        assert!(t.rel_error < 1e-6, "{}", t.rel_error);
        let t1 = tucker(&x, dims, &s, (1, 1, 1), 5, 1e-12).unwrap();
        assert!(t1.rel_error > 1e-3);
    }

    #[test]
    fn nnls_matches_unconstrained_when_feasible() {
        let gg = [2.0, 0.5, 0.5, 1.0];
        let gy = [1.0, 1.0];
        let a = nnls_small(&gg, &gy, 2);
        // unconstrained solution: [2 .5; .5 1]^-1 [1 1] = [0.2857, 0.8571]
        assert!((a[0] - 2.0 / 7.0).abs() < 1e-12 && (a[1] - 6.0 / 7.0).abs() < 1e-12);
        let a = nnls_small(&gg, &[-1.0, 1.0], 2);
        assert_eq!(a[0], 0.0);
        assert!((a[1] - 1.0).abs() < 1e-12);
    }
}
