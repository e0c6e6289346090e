//! Tucker decomposition of a 3-tensor (thesis 5.2.2, 5.3.1), `X ~ D x_h U^h x_o U^o x_i U^i`:
//! HOSVD start ([`hosvd`]), HOOI refinement ([`tucker`]), and the error grid of thesis figure
//! 5-5 with and without the specular split ([`tucker_report`]). The tensors come from
//! `super::tensor` (sampled and scaled there, so the errors here are in its metric) and the
//! split's residual from `super::split`.
//!
//! The equivariant tensor of an isotropic lobe is decomposed from its ring rows
//! ([`hosvd_rings`], [`tucker_rings`]), `n_phi` times fewer than its rows, and is never
//! expanded whole: that is what makes the shading basis cheap to build (docs/brdf-basis.md,
//! "Shading basis": 65 MB and under a second, against 1.0 GB and 25 to 30 s dense).

use super::error::BasisError;
use super::linalg::{
    block_circulant_eig, leading_eigvecs, leading_left_vectors, matmul, matmul_into, matmul_tn,
};
use super::split::{specular_split, SPLIT_WIDTHS_DEG};
use super::tensor::{expand_slab, BrdfTensor};
use super::FamilySpec;
use crate::brdf::Family;
use faer::{Accum, Mat, MatMut, MatRef};
use rayon::prelude::*;
use serde::Serialize;
use std::borrow::Cow;

/// The grid [`hosvd_rings`], [`tucker_rings`] and [`tucker_report`] take, re-exported so that
/// their callers name it from here.
pub use super::tensor::HemiGrid;

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

/// Mode unfoldings of a (small) tensor `[a][b][c]` (c fastest), as copies.
fn unfold(x: &[f64], dims: (usize, usize, usize), mode: usize) -> Mat<f64> {
    let (a, b, c) = dims;
    match mode {
        0 => Mat::from_fn(a, b * c, |i, j| x[i * b * c + j]),
        1 => Mat::from_fn(b, a * c, |i, j| x[(j / c) * b * c + i * c + j % c]),
        _ => Mat::from_fn(c, a * b, |i, j| x[j * c + i]),
    }
}

/// Rows of `x` viewed as `(b c) x a` per block in [`contract`] (mode 0), and columns of it
/// viewed as `c x (a b)` per block (mode 2): fixed sizes, so the blocks, each computed
/// sequentially, do not depend on the thread count.
const CONTRACT_BLOCK: usize = 8192;

/// Sub-blocks of [`contract`]'s mode 0 (its accumulators stay in L1).
const CONTRACT_SUB: usize = 256;

/// `x ×_mode U^T` for a tensor `[a][b][c]`, returning the new tensor and its dims. The tensor
/// is read in place (no unfolding is copied); the work is split into fixed blocks computed in
/// parallel, each sequentially, so the result does not depend on the thread count.
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
            // out[i][j] = sum_h u(h, i) x[h][j], summed over h in order; blocks of j in
            // parallel (a streaming pass: x is read once)
            let bc = b * c;
            let mut out = vec![0.0; r * bc];
            if bc > 0 && r > 0 {
                let blocks: Vec<Vec<f64>> = (0..bc.div_ceil(CONTRACT_BLOCK))
                    .into_par_iter()
                    .map(|n| {
                        let j0 = n * CONTRACT_BLOCK;
                        let len = CONTRACT_BLOCK.min(bc - j0);
                        // y[i][jj] over sub-blocks small enough to stay in L1 while every
                        // slab streams through
                        let mut y = vec![0.0; r * len];
                        let w: Vec<f64> = (0..a * r).map(|n| u[(n / r, n % r)]).collect();
                        for s0 in (0..len).step_by(CONTRACT_SUB) {
                            let sl = CONTRACT_SUB.min(len - s0);
                            for h in 0..a {
                                let xs = &x[h * bc + j0 + s0..][..sl];
                                for i in 0..r {
                                    let wi = w[h * r + i];
                                    let yi = &mut y[i * len + s0..][..sl];
                                    for (v, xv) in yi.iter_mut().zip(xs) {
                                        *v += wi * xv;
                                    }
                                }
                            }
                        }
                        y
                    })
                    .collect();
                out.par_chunks_mut(bc).enumerate().for_each(|(i, o)| {
                    for (n, y) in blocks.iter().enumerate() {
                        let len = y.len() / r;
                        o[n * CONTRACT_BLOCK..][..len].copy_from_slice(&y[i * len..][..len]);
                    }
                });
            }
            (out, (r, b, c))
        }
        1 => {
            // per slab: x[ia] as c x b, column-major; out[ia] as c x r = x[ia] u
            let mut out = vec![0.0; a * r * c];
            if r * c > 0 && b * c > 0 {
                out.par_chunks_mut(r * c)
                    .zip(x.par_chunks(b * c))
                    .for_each(|(o, s)| {
                        let om = MatMut::from_column_major_slice_mut(o, c, r);
                        let sm = MatRef::from_column_major_slice(s, c, b);
                        matmul_into(om, Accum::Replace, sm, u.as_ref());
                    });
            }
            (out, (a, r, c))
        }
        _ => {
            // x as c x (a b), column-major; out as r x (a b) = u^T x
            let ab = a * b;
            let m = MatRef::from_column_major_slice(x, c, ab);
            let mut out = vec![0.0; r * ab];
            if r > 0 {
                out.par_chunks_mut(r * CONTRACT_BLOCK)
                    .enumerate()
                    .for_each(|(n, o)| {
                        let len = o.len() / r;
                        let om = MatMut::from_column_major_slice_mut(o, r, len);
                        let xm = m.subcols(n * CONTRACT_BLOCK, len);
                        matmul_into(om, Accum::Replace, u.as_ref().transpose(), xm);
                    });
            }
            (out, (a, b, r))
        }
    }
}

/// HOSVD factors of all three modes, full rank (computed once, truncated per rank choice).
pub struct Hosvd {
    pub factors: [Mat<f64>; 3],
}

/// The Gram matrix of the mode-0 unfolding (`a x a`), read in place.
fn gram_mode0(x: &[f64], (a, b, c): (usize, usize, usize)) -> Mat<f64> {
    let m = MatRef::from_column_major_slice(x, b * c, a);
    matmul_tn(m, m)
}

/// HOSVD of a tensor `[a][b][c]`: the leading left singular vectors of every mode unfolding,
/// as eigenvectors of its Gram matrix (`a x a`, `b x b`, `c x c`; the unfoldings are read in
/// place, never copied). The three modes run in parallel, each sequentially.
pub fn hosvd(x: &[f64], dims: (usize, usize, usize)) -> Result<Hosvd, BasisError> {
    let (a, b, c) = dims;
    let g1 = || {
        // sum over slabs of x[ia] x[ia]^T, x[ia] as c x b column-major
        let mut g = Mat::<f64>::zeros(b, b);
        for s in x.chunks_exact(b * c) {
            let sm = MatRef::from_column_major_slice(s, c, b);
            matmul_into(g.as_mut(), Accum::Add, sm.transpose(), sm);
        }
        leading_eigvecs(g.as_ref(), b)
    };
    let g2 = || {
        let m = MatRef::from_column_major_slice(x, c, a * b);
        leading_eigvecs(matmul(m, m.transpose()).as_ref(), c)
    };
    let g0 = || leading_eigvecs(gram_mode0(x, dims).as_ref(), a);
    let (f0, (f1, f2)) = rayon::join(g0, || rayon::join(g1, g2));
    Ok(Hosvd {
        factors: [f0?, f1?, f2?],
    })
}

/// [`hosvd`] of an equivariant tensor over `[param][wo][wi]` on `dirs` given by its ring rows
/// `rings` (`[h][j][i]`, `nh` slabs; see [`RingTensor`]). `n_phi` times less work than
/// [`hosvd`] of the expanded tensor, and no copy of it:
///
/// - mode 0: `G(h, h') = n_phi sum_j <X(h, (j, 0), .), X(h', (j, 0), .)>`;
/// - modes 1 and 2: the Gram matrices are block circulant, `G((j, k), (l, m)) = G((j, 0),
///   (l, m - k))`. Their rows `(j, 0)` are accumulated slab by slab (each slab expanded into
///   a buffer; slabs in parallel, summed in order), and [`block_circulant_eig`]
///   diagonalizes them through the Fourier transform over the azimuth. The eigenvalues of
///   azimuthal frequencies `f` and `n_phi - f` are equal; the pair's vectors are taken as
///   the cosine and sine parts, the cosine peaking at column 0.
///
/// The same factors as [`hosvd`] to rounding, up to the choice of basis within those pairs.
///
/// [`RingTensor`]: super::tensor::RingTensor
pub fn hosvd_rings(rings: &[f64], nh: usize, dirs: HemiGrid) -> Result<Hosvd, BasisError> {
    let (nd, nt, np) = (dirs.len(), dirs.n_theta, dirs.n_phi);
    assert_eq!(rings.len(), nh * nt * nd);
    let g0 = || {
        let r = MatRef::from_column_major_slice(rings, nt * nd, nh);
        let mut g = matmul_tn(r, r);
        for v in g.col_iter_mut().flat_map(|c| c.iter_mut()) {
            *v *= np as f64;
        }
        leading_eigvecs(g.as_ref(), nh)
    };
    let g12 = || {
        let rows: Vec<(Mat<f64>, Mat<f64>)> = (0..nh)
            .into_par_iter()
            .map_init(
                || vec![0.0; nd * nd],
                |buf, h| {
                    let ring = &rings[h * nt * nd..][..nt * nd];
                    expand_slab(ring, dirs, buf);
                    let sm = MatRef::from_column_major_slice(buf, nd, nd); // (i, o) = X(o, i)
                    let rm = MatRef::from_column_major_slice(ring, nd, nt); // (i, j) = X((j, 0), i)
                                                                            // rows (j, 0) of X X^T (mode 1) and of X^T X (mode 2)
                    let r1 = matmul(rm.transpose(), sm);
                    let sel = Mat::from_fn(nt, nd, |j, o| sm[(j * np, o)]);
                    let r2 = matmul(sel.as_ref(), sm.transpose());
                    (r1, r2)
                },
            )
            .collect();
        let mut rows1 = Mat::<f64>::zeros(nt, nd);
        let mut rows2 = Mat::<f64>::zeros(nt, nd);
        for (r1, r2) in &rows {
            rows1 += r1;
            rows2 += r2;
        }
        rayon::join(
            || block_circulant_eig(rows1.as_ref(), np).map(|(_, u)| u),
            || block_circulant_eig(rows2.as_ref(), np).map(|(_, u)| u),
        )
    };
    let (f0, (f1, f2)) = rayon::join(g0, g12);
    Ok(Hosvd {
        factors: [f0?, f1?, f2?],
    })
}

/// Ring rows per block of [`Operand::mode2`] on ring rows (fixed, so the blocks do not depend
/// on the thread count).
const RING_BLOCK: usize = 64;

/// What [`tucker_with`] decomposes: a dense tensor `[a][b][c]`, or an equivariant one over
/// `[param][wo][wi]` by its ring rows (`[a][j][i]`, see [`RingTensor`]).
///
/// [`RingTensor`]: super::tensor::RingTensor
enum Operand<'a> {
    Dense(Cow<'a, [f64]>, (usize, usize, usize)),
    Rings(Cow<'a, [f64]>, usize, HemiGrid),
}

impl Operand<'_> {
    /// `||X||^2`.
    fn norm2(&self) -> f64 {
        match self {
            Operand::Dense(x, _) => x.iter().map(|v| v * v).sum(),
            // every ring row stands for n_phi rows with the same values
            Operand::Rings(r, _, dirs) => dirs.n_phi as f64 * r.iter().map(|v| v * v).sum::<f64>(),
        }
    }

    /// `X ×_0 U^T`, equivariant again when `X` is: its ring rows are the contraction of `X`'s.
    fn mode0(&self, u: &Mat<f64>) -> Operand<'static> {
        match self {
            Operand::Dense(x, d) => {
                let (t, d) = contract(x, *d, 0, u);
                Operand::Dense(Cow::Owned(t), d)
            }
            Operand::Rings(r, a, dirs) => {
                let (t, _) = contract(r, (*a, dirs.n_theta, dirs.len()), 0, u);
                Operand::Rings(Cow::Owned(t), u.ncols(), *dirs)
            }
        }
    }

    /// `X ×_1 U^T`, dense. Ring rows: slab by slab (expanded into a buffer; slabs in parallel).
    fn mode1(&self, u: &Mat<f64>) -> (Vec<f64>, (usize, usize, usize)) {
        match self {
            Operand::Dense(x, d) => contract(x, *d, 1, u),
            Operand::Rings(rings, a, dirs) => {
                let (nd, nt) = (dirs.len(), dirs.n_theta);
                let r = u.ncols();
                let mut out = vec![0.0; a * r * nd];
                if r * nd > 0 {
                    out.par_chunks_mut(r * nd).enumerate().for_each_init(
                        || vec![0.0; nd * nd],
                        |buf, (h, o)| {
                            expand_slab(&rings[h * nt * nd..][..nt * nd], *dirs, buf);
                            let sm = MatRef::from_column_major_slice(buf, nd, nd);
                            let om = MatMut::from_column_major_slice_mut(o, nd, r);
                            matmul_into(om, Accum::Replace, sm, u.as_ref());
                        },
                    );
                }
                (out, (*a, r, nd))
            }
        }
    }

    /// `X ×_2 U^T`, dense. Ring rows: `X((j, k), .) U` is the ring row `(j, 0)` times `U`
    /// turned by `k` columns, `U_k((j', k'), c) = U((j', k' + k), c)`; all of them at once,
    /// `[rows (h, j)] x [U_0 .. U_{n_phi - 1}]`, whose result is laid out `[h][(j, k)][c]`.
    fn mode2(&self, u: &Mat<f64>) -> (Vec<f64>, (usize, usize, usize)) {
        match self {
            Operand::Dense(x, d) => contract(x, *d, 2, u),
            Operand::Rings(rings, a, dirs) => {
                let (nd, nt, np) = (dirs.len(), dirs.n_theta, dirs.n_phi);
                let r = u.ncols();
                let urot = Mat::from_fn(nd, np * r, |i, q| {
                    let (k, c) = (q / r, q % r);
                    let (jp, kp) = (i / np, i % np);
                    u[(jp * np + (kp + k) % np, c)]
                });
                let m = MatRef::from_column_major_slice(rings, nd, a * nt);
                let mut out = vec![0.0; a * nd * r];
                if r > 0 {
                    // out as (n_phi r) x (a n_theta), column-major
                    out.par_chunks_mut(np * r * RING_BLOCK)
                        .enumerate()
                        .for_each(|(n, o)| {
                            let len = o.len() / (np * r);
                            let om = MatMut::from_column_major_slice_mut(o, np * r, len);
                            let xm = m.subcols(n * RING_BLOCK, len);
                            matmul_into(om, Accum::Replace, urot.transpose(), xm);
                        });
                }
                (out, (*a, nd, r))
            }
        }
    }
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
    let x = Operand::Dense(Cow::Borrowed(x), dims);
    tucker_with(&x, start, ranks, max_sweeps, tol)
}

/// [`tucker`] of an equivariant tensor given by its ring rows (`[h][j][i]`, `nh` slabs on
/// `dirs`; see [`RingTensor`]), started from [`hosvd_rings`]. The same sweeps; the products
/// with the tensor use its ring rows, and no copy of it is made.
///
/// [`RingTensor`]: super::tensor::RingTensor
pub fn tucker_rings(
    rings: &[f64],
    nh: usize,
    dirs: HemiGrid,
    start: &Hosvd,
    ranks: (usize, usize, usize),
    max_sweeps: usize,
    tol: f64,
) -> Result<Tucker, BasisError> {
    assert_eq!(rings.len(), nh * dirs.n_theta * dirs.len());
    let x = Operand::Rings(Cow::Borrowed(rings), nh, dirs);
    tucker_with(&x, start, ranks, max_sweeps, tol)
}

fn tucker_with(
    x: &Operand<'_>,
    start: &Hosvd,
    ranks: (usize, usize, usize),
    max_sweeps: usize,
    tol: f64,
) -> Result<Tucker, BasisError> {
    let norm2 = x.norm2();
    let mut u = [
        truncate(&start.factors[0], ranks.0),
        truncate(&start.factors[1], ranks.1),
        truncate(&start.factors[2], ranks.2),
    ];
    // the core and the error, from x already contracted along mode 0
    let core_of = |t0: &Operand<'_>, u: &[Mat<f64>; 3]| -> (Vec<f64>, f64) {
        let (t, d) = t0.mode1(&u[1]);
        let (core, _) = contract(&t, d, 2, &u[2]);
        let c2: f64 = core.iter().map(|v| v * v).sum();
        let e = if norm2 > 0.0 {
            ((norm2 - c2).max(0.0) / norm2).sqrt()
        } else {
            0.0
        };
        (core, e)
    };
    let (mut core, mut err) = core_of(&x.mode0(&u[0]), &u);
    let mut sweeps = 0;
    for _ in 0..max_sweeps {
        // mode 0: contract modes 1 and 2
        let (t, d) = x.mode2(&u[2]);
        let (t, d) = contract(&t, d, 1, &u[1]);
        u[0] = leading_left_vectors(unfold(&t, d, 0).as_ref(), u[0].ncols())?;
        let t = x.mode0(&u[0]);
        let (t2, d2) = t.mode2(&u[2]);
        u[1] = leading_left_vectors(unfold(&t2, d2, 1).as_ref(), u[1].ncols())?;
        let (t3, d3) = t.mode1(&u[1]);
        u[2] = leading_left_vectors(unfold(&t3, d3, 2).as_ref(), u[2].ncols())?;
        sweeps += 1;
        // u[0] is the one `t` was contracted with
        let (c, e) = core_of(&t, &u);
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
    use super::super::tensor::expand_rings;
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

    /// A small equivariant tensor: ring rows of arbitrary values and their expansion.
    fn ring_example() -> (Vec<f64>, Vec<f64>, usize, HemiGrid) {
        let dirs = HemiGrid {
            n_theta: 4,
            n_phi: 8,
        };
        let nh = 3;
        let rings: Vec<f64> = (0..nh * dirs.n_theta * dirs.len())
            .map(|n| ((n * 7919) % 1009) as f64 / 1009.0 - 0.3)
            .collect();
        let x = expand_rings(&rings, nh, dirs);
        (rings, x, nh, dirs)
    }

    fn close(a: &[f64], b: &[f64], tol: f64) {
        assert_eq!(a.len(), b.len());
        let m = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= tol * m, "{x} vs {y}");
        }
    }

    /// The products with ring rows are those with the expanded tensor.
    #[test]
    fn ring_operands_contract_like_the_expanded_tensor() {
        let (rings, x, nh, dirs) = ring_example();
        let nd = dirs.len();
        let dense = Operand::Dense(Cow::Borrowed(&x), (nh, nd, nd));
        let ring = Operand::Rings(Cow::Borrowed(&rings), nh, dirs);
        let n2 = dense.norm2();
        assert!((ring.norm2() - n2).abs() <= 1e-13 * n2);
        let u = |n: usize, r: usize| {
            Mat::from_fn(n, r, |i, c| ((i * 3 + c * 5 + 1) as f64 * 0.37).sin())
        };
        // mode 0: the same sums, so the same bits
        let Operand::Rings(t, a, _) = ring.mode0(&u(nh, 2)) else {
            panic!("mode 0 of ring rows is ring rows")
        };
        assert_eq!(a, 2);
        let Operand::Dense(td, _) = dense.mode0(&u(nh, 2)) else {
            panic!()
        };
        assert_eq!(expand_rings(&t, 2, dirs), td.to_vec());
        for mode in [1, 2] {
            let um = u(nd, 5);
            let ((a, da), (b, db)) = if mode == 1 {
                (ring.mode1(&um), dense.mode1(&um))
            } else {
                (ring.mode2(&um), dense.mode2(&um))
            };
            assert_eq!(da, db);
            close(&a, &b, 1e-13);
        }
    }

    /// `hosvd_rings` gives orthonormal eigenvectors of the expanded tensor's Gram matrices
    /// (with its eigenvalues), and `tucker_rings` the expanded tensor's decomposition.
    #[test]
    fn ring_decomposition_matches_the_expanded_tensor() {
        let (rings, x, nh, dirs) = ring_example();
        let nd = dirs.len();
        let dims = (nh, nd, nd);
        let h = hosvd_rings(&rings, nh, dirs).unwrap();
        for mode in 0..3 {
            let w = unfold(&x, dims, mode);
            let g = matmul(w.as_ref(), w.transpose());
            let (vals, _) = super::super::linalg::sym_eig_desc(g.as_ref()).unwrap();
            let u = &h.factors[mode];
            assert_eq!(u.ncols(), g.nrows());
            let gu = matmul(g.as_ref(), u.as_ref());
            let utu = matmul_tn(u.as_ref(), u.as_ref());
            for c in 0..u.ncols() {
                for i in 0..u.nrows() {
                    let r = gu[(i, c)] - vals[c] * u[(i, c)];
                    assert!(r.abs() < 1e-10 * vals[0], "mode {mode} col {c}: {r}");
                    let id = if i == c { 1.0 } else { 0.0 };
                    assert!((utu[(i, c)] - id).abs() < 1e-12);
                }
            }
        }
        for ranks in [(2, 5, 5), (3, 8, 4)] {
            let a = tucker_rings(&rings, nh, dirs, &h, ranks, 8, 1e-10).unwrap();
            let b = tucker(&x, dims, &h, ranks, 8, 1e-10).unwrap();
            assert_eq!(a.sweeps, b.sweeps);
            // (the factors may differ within subspaces of equal singular values, which the
            // symmetry makes common; the error cannot)
            assert!((a.rel_error - b.rel_error).abs() < 1e-10, "{ranks:?}");
        }
    }
}
