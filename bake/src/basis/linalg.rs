//! Thin wrappers over faer's f64 decompositions, always run sequentially (`Par::Seq`) so that
//! results are bit-for-bit identical whatever the thread count, plus a sign convention.

use super::error::BasisError;
use faer::diag::Diag;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors};
use faer::linalg::qr::no_pivoting::factor::{
    qr_in_place, qr_in_place_scratch, recommended_block_size,
};
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::{c64, Accum, Mat, MatMut, MatRef, Par};

/// Clears the upper halves of the AVX registers (`vzeroupper`). faer's SIMD kernels can
/// return with them dirty; afterwards every SSE instruction in the thread (and in threads it
/// spawns, which inherit the register state) pays a transition penalty. Measured: the runtime's
/// `eval_all` ran 3.7x slower (180 vs 48 ns) after a basis build until this was called. Every
/// wrapper here calls it; call it yourself after using faer directly.
#[inline]
pub fn clear_simd_upper_state() {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx")]
        unsafe fn zero_upper() {
            std::arch::x86_64::_mm256_zeroupper();
        }
        if std::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU supports AVX (checked above); vzeroupper has no other effect.
            unsafe { zero_upper() }
        }
    }
}

/// `(U, s, V)` of a thin SVD.
pub type SvdParts = (Mat<f64>, Vec<f64>, Mat<f64>);

/// Thin SVD `A = U diag(s) V^T` with singular values in nonincreasing order.
pub fn svd_thin(a: MatRef<'_, f64>) -> Result<SvdParts, BasisError> {
    let (m, n) = a.shape();
    let k = m.min(n);
    let mut u = Mat::<f64>::zeros(m, k);
    let mut v = Mat::<f64>::zeros(n, k);
    let mut s = Diag::<f64>::zeros(k);
    if k == 0 {
        return Ok((u, Vec::new(), v));
    }
    let req = svd_scratch::<f64>(
        m,
        n,
        ComputeSvdVectors::Thin,
        ComputeSvdVectors::Thin,
        Par::Seq,
        Default::default(),
    );
    let mut buf = MemBuffer::new(req);
    let r = svd(
        a,
        s.as_mut(),
        Some(u.as_mut()),
        Some(v.as_mut()),
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    )
    .map_err(|e| BasisError::Svd(format!("{e:?}")));
    clear_simd_upper_state();
    r?;
    let s: Vec<f64> = (0..k).map(|i| s[i]).collect();
    Ok((u, s, v))
}

/// The `min(m, n) x n` upper-triangular factor R of `A = Q R` (no pivoting). Takes `A` by
/// value and factors it in place: the basis build calls this on its largest matrix, and a copy
/// would add a quarter to the bake's peak memory.
pub fn qr_r(mut w: Mat<f64>) -> Mat<f64> {
    let (m, n) = w.shape();
    let k = m.min(n);
    if k == 0 {
        return Mat::zeros(k, n);
    }
    let bs = recommended_block_size::<f64>(m, n);
    let mut q = Mat::<f64>::zeros(bs, k);
    let req = qr_in_place_scratch::<f64>(m, n, bs, Par::Seq, Default::default());
    let mut buf = MemBuffer::new(req);
    qr_in_place(
        w.as_mut(),
        q.as_mut(),
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    );
    clear_simd_upper_state();
    Mat::from_fn(k, n, |i, j| if i <= j { w[(i, j)] } else { 0.0 })
}

/// How [`sym_eig`] computed a decomposition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EigMethod {
    /// faer's self-adjoint eigendecomposition (tridiagonalization, then QR or divide and
    /// conquer): fast, and the usual case.
    Faer,
    /// The cyclic Jacobi method, after faer reported no convergence: slower (O(n^3) per sweep)
    /// but it converges for every finite symmetric matrix.
    Jacobi,
}

/// A symmetric eigendecomposition: eigenvalues in *nonincreasing* order with the matching
/// eigenvector columns, and how it was computed.
#[derive(Clone, Debug)]
pub struct SymEig {
    pub vals: Vec<f64>,
    pub vecs: Mat<f64>,
    pub method: EigMethod,
}

/// Eigendecomposition of a symmetric matrix that cannot fail on finite input (a non-finite
/// entry is an error naming it).
///
/// Rows and columns that are exactly zero are deflated first: each is an eigenvector (a unit
/// vector) of eigenvalue 0, and only the rest is decomposed. faer 0.24's `self_adjoint_evd`
/// reports `NoConvergence` on matrices made mostly of such rows: the Gram matrix of a
/// per-vertex cluster whose vertices see almost nothing of the other objects (231 of 240 rows
/// zero; kept as a test), which stopped whole bakes. Should faer still not converge on the
/// rest, the cyclic Jacobi method computes it instead ([`EigMethod::Jacobi`]).
pub fn sym_eig(a: MatRef<'_, f64>) -> Result<SymEig, BasisError> {
    let n = a.nrows();
    for j in 0..a.ncols() {
        for i in 0..n {
            if !a[(i, j)].is_finite() {
                return Err(BasisError::Eigen(format!(
                    "the matrix holds {} at ({i}, {j})",
                    a[(i, j)]
                )));
            }
        }
    }
    let live: Vec<usize> = (0..n)
        .filter(|&i| (0..n).any(|j| a[(i, j)] != 0.0))
        .collect();
    if live.len() == n {
        return eig_live(a);
    }
    // Decompose the live rows only; the zero rows are eigenvectors of eigenvalue 0.
    let sub = Mat::from_fn(live.len(), live.len(), |i, j| a[(live[i], live[j])]);
    let part = eig_live(sub.as_ref())?;
    let dead: Vec<usize> = (0..n).filter(|i| !live.contains(i)).collect();
    // Merge by value, the decomposed ones first on a tie (the order is deterministic).
    enum Source {
        Live(usize),
        Dead(usize),
    }
    let mut order: Vec<(f64, Source)> = part
        .vals
        .iter()
        .enumerate()
        .map(|(k, &v)| (v, Source::Live(k)))
        .chain(dead.iter().map(|&d| (0.0, Source::Dead(d))))
        .collect();
    order.sort_by(|x, y| {
        let rank = |s: &Source| matches!(s, Source::Dead(_));
        y.0.total_cmp(&x.0).then(rank(&x.1).cmp(&rank(&y.1)))
    });
    let mut vecs = Mat::<f64>::zeros(n, n);
    let mut vals = Vec::with_capacity(n);
    for (col, (v, source)) in order.iter().enumerate() {
        vals.push(*v);
        match *source {
            Source::Live(k) => {
                for (r, &i) in live.iter().enumerate() {
                    vecs[(i, col)] = part.vecs[(r, k)];
                }
            }
            Source::Dead(d) => vecs[(d, col)] = 1.0,
        }
    }
    Ok(SymEig {
        vals,
        vecs,
        method: part.method,
    })
}

/// [`sym_eig`] without the method: eigenvalues in *nonincreasing* order with the matching
/// eigenvector columns.
pub fn sym_eig_desc(a: MatRef<'_, f64>) -> Result<(Vec<f64>, Mat<f64>), BasisError> {
    let e = sym_eig(a)?;
    Ok((e.vals, e.vecs))
}

/// faer's decomposition of a finite symmetric matrix, or Jacobi's where faer fails.
fn eig_live(a: MatRef<'_, f64>) -> Result<SymEig, BasisError> {
    match faer_eig(a) {
        Ok((vals, vecs)) => Ok(SymEig {
            vals,
            vecs,
            method: EigMethod::Faer,
        }),
        Err(_) => {
            let (vals, vecs) = jacobi_eig(a);
            Ok(SymEig {
                vals,
                vecs,
                method: EigMethod::Jacobi,
            })
        }
    }
}

fn faer_eig(a: MatRef<'_, f64>) -> Result<(Vec<f64>, Mat<f64>), BasisError> {
    let n = a.nrows();
    let mut u = Mat::<f64>::zeros(n, n);
    let mut s = Diag::<f64>::zeros(n);
    if n == 0 {
        return Ok((Vec::new(), u));
    }
    let req =
        self_adjoint_evd_scratch::<f64>(n, ComputeEigenvectors::Yes, Par::Seq, Default::default());
    let mut buf = MemBuffer::new(req);
    let r = self_adjoint_evd(
        a,
        s.as_mut(),
        Some(u.as_mut()),
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    )
    .map_err(|e| BasisError::Eigen(format!("{e:?}")));
    clear_simd_upper_state();
    r?;
    let vals: Vec<f64> = (0..n).rev().map(|i| s[i]).collect();
    let vecs = Mat::from_fn(n, n, |i, j| u[(i, n - 1 - j)]);
    Ok((vals, vecs))
}

/// Sweeps of the cyclic Jacobi method before it stops: it converges quadratically once the
/// off-diagonal is small, typically in 6-12 sweeps; the cap only bounds a pathological case.
const JACOBI_SWEEPS: usize = 100;

/// The cyclic Jacobi eigenvalue method (Golub & Van Loan, Matrix Computations, 8.5) on the
/// lower triangle of `a` (symmetrized): eigenvalues in nonincreasing order and orthonormal
/// eigenvector columns. Written here rather than taken from a crate because it is only the
/// fallback of faer's decomposition, and twenty lines.
fn jacobi_eig(a: MatRef<'_, f64>) -> (Vec<f64>, Mat<f64>) {
    let n = a.nrows();
    let mut m = Mat::from_fn(n, n, |i, j| if i >= j { a[(i, j)] } else { a[(j, i)] });
    let mut v = Mat::<f64>::identity(n, n);
    let norm: f64 = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| m[(i, j)] * m[(i, j)])
        .sum::<f64>()
        .sqrt();
    for _ in 0..JACOBI_SWEEPS {
        let off: f64 = (0..n)
            .flat_map(|i| (0..i).map(move |j| (i, j)))
            .map(|(i, j)| m[(i, j)] * m[(i, j)])
            .sum::<f64>()
            .sqrt();
        if off <= f64::EPSILON * norm || off == 0.0 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = m[(p, q)];
                if apq == 0.0 {
                    continue;
                }
                let theta = (m[(q, q)] - m[(p, p)]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (mkp, mkq) = (m[(k, p)], m[(k, q)]);
                    m[(k, p)] = c * mkp - s * mkq;
                    m[(k, q)] = s * mkp + c * mkq;
                }
                for k in 0..n {
                    let (mpk, mqk) = (m[(p, k)], m[(q, k)]);
                    m[(p, k)] = c * mpk - s * mqk;
                    m[(q, k)] = s * mpk + c * mqk;
                }
                for k in 0..n {
                    let (vkp, vkq) = (v[(k, p)], v[(k, q)]);
                    v[(k, p)] = c * vkp - s * vkq;
                    v[(k, q)] = s * vkp + c * vkq;
                }
            }
        }
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&x, &y| m[(y, y)].total_cmp(&m[(x, x)]).then(x.cmp(&y)));
    let vals = order.iter().map(|&i| m[(i, i)]).collect();
    let vecs = Mat::from_fn(n, n, |i, j| v[(i, order[j])]);
    (vals, vecs)
}

/// Eigendecomposition of a Hermitian matrix (lower triangle read); eigenvalues in
/// *nonincreasing* order with the matching eigenvector columns.
fn herm_eig_desc(a: MatRef<'_, c64>) -> Result<(Vec<f64>, Mat<c64>), BasisError> {
    let n = a.nrows();
    let mut u = Mat::<c64>::zeros(n, n);
    let mut s = Diag::<c64>::zeros(n);
    if n == 0 {
        return Ok((Vec::new(), u));
    }
    let req =
        self_adjoint_evd_scratch::<c64>(n, ComputeEigenvectors::Yes, Par::Seq, Default::default());
    let mut buf = MemBuffer::new(req);
    let r = self_adjoint_evd(
        a,
        s.as_mut(),
        Some(u.as_mut()),
        Par::Seq,
        MemStack::new(&mut buf),
        Default::default(),
    )
    .map_err(|e| BasisError::Eigen(format!("{e:?}")));
    clear_simd_upper_state();
    r?;
    let vals: Vec<f64> = (0..n).rev().map(|i| s[i].re).collect();
    let vecs = Mat::from_fn(n, n, |i, j| u[(i, n - 1 - j)]);
    Ok((vals, vecs))
}

/// Eigendecomposition of a symmetric **block-circulant** matrix of `nb x nb` blocks of size
/// `np`, `G((j, k), (l, m)) = rows(j, l np + (m - k mod np))` (index `(j, k)` = `j np + k`),
/// given its rows `(j, 0)` (`rows`: `nb x nb np`). Eigenvalues nonincreasing, eigenvectors
/// real and orthonormal (columns), each sign-fixed by [`fix_sign`].
///
/// The discrete Fourier transform over `k` block-diagonalizes `G`: for frequency `f` the
/// vectors `a_l e^{i theta m}` (`theta = 2 pi f / np`) map to `(B_f a)_j e^{i theta k}` with
/// the Hermitian `nb x nb` block `B_f(j, l) = sum_d rows(j, l np + d) e^{i theta d}`
/// (symmetrized, `(B_f + B_f^H) / 2`, so rounding in `rows` cannot break the symmetry). So
/// `nb np` eigenpairs come from `np / 2 + 1` small eigenproblems: frequencies 0 and `np / 2`
/// give real vectors `a_l (+-1)^m / sqrt(np)`, every other `f < np / 2` gives a pair of equal
/// eigenvalues with the vectors `sqrt(2 / np) (Re, Im)(a_l e^{i theta m})` (the phase of `a`
/// fixed so that its largest component is real and positive: the cosine part peaks at column
/// 0). Ties are ordered by frequency, then cosine before sine.
pub fn block_circulant_eig(
    rows: MatRef<'_, f64>,
    np: usize,
) -> Result<(Vec<f64>, Mat<f64>), BasisError> {
    let nb = rows.nrows();
    let n = nb * np;
    assert_eq!(rows.ncols(), n);
    let angle = |q: usize| std::f64::consts::TAU * (q % np) as f64 / np as f64;
    let trig: Vec<(f64, f64)> = (0..np).map(|q| angle(q).sin_cos()).collect();
    // (eigenvalue, frequency, index within it, 0 = cos / 1 = sin, the block's vector)
    let mut pairs: Vec<(f64, usize, usize, usize, Vec<c64>)> = Vec::with_capacity(n);
    for f in 0..=np / 2 {
        let b = Mat::<c64>::from_fn(nb, nb, |j, l| {
            let mut acc = c64::new(0.0, 0.0);
            for d in 0..np {
                let (si, co) = trig[(f * d) % np];
                acc += c64::new(co, si) * rows[(j, l * np + d)];
            }
            acc
        });
        let b = Mat::<c64>::from_fn(nb, nb, |j, l| (b[(j, l)] + b[(l, j)].conj()) * 0.5);
        let real = f == 0 || 2 * f == np;
        let (vals, vecs) = if real {
            let br = Mat::<f64>::from_fn(nb, nb, |j, l| b[(j, l)].re);
            let (v, u) = sym_eig_desc(br.as_ref())?;
            (
                v,
                Mat::<c64>::from_fn(nb, nb, |j, l| c64::new(u[(j, l)], 0.0)),
            )
        } else {
            herm_eig_desc(b.as_ref())?
        };
        for (idx, &lambda) in vals.iter().enumerate() {
            let mut a: Vec<c64> = (0..nb).map(|l| vecs[(l, idx)]).collect();
            // phase: the largest component (the first on ties) real and positive
            let mut big = 0;
            for l in 0..nb {
                if a[l].norm() > a[big].norm() {
                    big = l;
                }
            }
            let m = a[big].norm();
            if m > 0.0 {
                let ph = a[big].conj() / m;
                for x in a.iter_mut() {
                    *x *= ph;
                }
            }
            let parts = if real { 1 } else { 2 };
            for part in 0..parts {
                pairs.push((lambda, f, idx, part, a.clone()));
            }
        }
    }
    pairs.sort_by(|x, y| {
        y.0.total_cmp(&x.0)
            .then(x.1.cmp(&y.1))
            .then(x.2.cmp(&y.2))
            .then(x.3.cmp(&y.3))
    });
    let mut u = Mat::<f64>::zeros(n, n);
    let mut col = vec![0.0; n];
    for (c, (_, f, _, part, a)) in pairs.iter().enumerate() {
        let real = *f == 0 || 2 * f == np;
        let scale = if real {
            1.0 / (np as f64).sqrt()
        } else {
            (2.0 / np as f64).sqrt()
        };
        for (l, al) in a.iter().enumerate() {
            for m in 0..np {
                let (si, co) = trig[(f * m) % np];
                let e = *al * c64::new(co, si);
                col[l * np + m] = scale * if *part == 0 { e.re } else { e.im };
            }
        }
        fix_sign(&mut col);
        for (i, &x) in col.iter().enumerate() {
            u[(i, c)] = x;
        }
    }
    Ok((pairs.iter().map(|p| p.0).collect(), u))
}

/// `C = A B` computed sequentially.
pub fn matmul(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut c = Mat::<f64>::zeros(a.nrows(), b.ncols());
    faer::linalg::matmul::matmul(c.as_mut(), Accum::Replace, a, b, 1.0, Par::Seq);
    clear_simd_upper_state();
    c
}

/// `C = A^T B` computed sequentially.
pub fn matmul_tn(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut c = Mat::<f64>::zeros(a.ncols(), b.ncols());
    faer::linalg::matmul::matmul(c.as_mut(), Accum::Replace, a.transpose(), b, 1.0, Par::Seq);
    clear_simd_upper_state();
    c
}

/// `G += A^T A` on the lower triangle of `g` only (its upper triangle is left as it was):
/// half the work of [`matmul_tn`] for a Gram matrix. Call [`mirror_lower`] after the last sum.
pub fn gram_lower_add(g: MatMut<'_, f64>, a: MatRef<'_, f64>) {
    use faer::linalg::matmul::triangular::{matmul as tri_matmul, BlockStructure};
    tri_matmul(
        g,
        BlockStructure::TriangularLower,
        Accum::Add,
        a.transpose(),
        BlockStructure::Rectangular,
        a,
        BlockStructure::Rectangular,
        1.0,
        Par::Seq,
    );
    clear_simd_upper_state();
}

/// `A^T A`, computed on its lower triangle and mirrored ([`gram_lower_add`]).
pub fn gram(a: MatRef<'_, f64>) -> Mat<f64> {
    let mut g = Mat::<f64>::zeros(a.ncols(), a.ncols());
    gram_lower_add(g.as_mut(), a);
    mirror_lower(&mut g);
    g
}

/// Copies the strict lower triangle of a square matrix onto its upper one.
pub fn mirror_lower(g: &mut Mat<f64>) {
    for j in 0..g.ncols() {
        for i in 0..j {
            g[(i, j)] = g[(j, i)];
        }
    }
}

/// `C = A B` (`accum` = [`Accum::Replace`]) or `C += A B` ([`Accum::Add`]) into a given
/// matrix view, computed sequentially.
pub fn matmul_into(c: MatMut<'_, f64>, accum: Accum, a: MatRef<'_, f64>, b: MatRef<'_, f64>) {
    faer::linalg::matmul::matmul(c, accum, a, b, 1.0, Par::Seq);
    clear_simd_upper_state();
}

/// Leading `r` eigenvectors (columns, eigenvalues nonincreasing) of a symmetric matrix, each
/// sign-fixed by [`fix_sign`].
pub fn leading_eigvecs(g: MatRef<'_, f64>, r: usize) -> Result<Mat<f64>, BasisError> {
    let (_, v) = sym_eig_desc(g)?;
    Ok(sign_fixed_columns(v.as_ref(), r))
}

/// The first `r` columns of `v`, each sign-fixed by [`fix_sign`] (for eigenvectors from
/// [`sym_eig_desc`] when the eigenvalues decide `r`).
pub fn sign_fixed_columns(v: MatRef<'_, f64>, r: usize) -> Mat<f64> {
    let r = r.min(v.ncols());
    let mut u = Mat::<f64>::zeros(v.nrows(), r);
    let mut col = vec![0.0; v.nrows()];
    for c in 0..r {
        for (i, x) in col.iter_mut().enumerate() {
            *x = v[(i, c)];
        }
        fix_sign(&mut col);
        for (i, &x) in col.iter().enumerate() {
            u[(i, c)] = x;
        }
    }
    u
}

/// Leading `r` left singular vectors of `w` (`m x n`), sign-fixed by [`fix_sign`]: the leading
/// eigenvectors of the Gram matrix `w w^T` (`m x m`), or, when `w` is tall (`n < m`) and its
/// leading `r` singular values are clearly nonzero, those of the small Gram matrix `w^T w`
/// (`n x n`) mapped back, `u_k = w v_k / sigma_k`, and re-orthonormalized (two passes of
/// Gram-Schmidt). The two agree to rounding wherever the singular values are distinct.
pub fn leading_left_vectors(w: MatRef<'_, f64>, r: usize) -> Result<Mat<f64>, BasisError> {
    let (m, n) = w.shape();
    let r = r.min(m);
    if n < m && r <= n && r > 0 {
        let g = matmul_tn(w, w);
        let (vals, v) = sym_eig_desc(g.as_ref())?;
        // sigma_k^2 well above the Gram matrix's rounding (relative 1e-12 keeps sigma_k above
        // 1e-6 sigma_0, where w v_k / sigma_k still carries eight good digits)
        if vals[0] > 0.0 && vals[r - 1] > 1e-12 * vals[0] {
            let mut u = matmul(w, v.get(.., ..r));
            for (c, &l) in vals[..r].iter().enumerate() {
                let inv = 1.0 / l.sqrt();
                for i in 0..m {
                    u[(i, c)] *= inv;
                }
            }
            let mut cols: Vec<Vec<f64>> = (0..r)
                .map(|c| (0..m).map(|i| u[(i, c)]).collect())
                .collect();
            orthonormalize(&mut cols);
            for c in cols.iter_mut() {
                fix_sign(c);
            }
            return Ok(Mat::from_fn(m, r, |i, c| cols[c][i]));
        }
    }
    let g = matmul(w, w.transpose());
    leading_eigvecs(g.as_ref(), r)
}

/// Two passes of modified Gram-Schmidt over `cols` in order (columns already nearly
/// orthonormal stay where they are to rounding).
fn orthonormalize(cols: &mut [Vec<f64>]) {
    for _ in 0..2 {
        for c in 0..cols.len() {
            let (done, rest) = cols.split_at_mut(c);
            let v = &mut rest[0];
            for q in done.iter() {
                let d: f64 = q.iter().zip(v.iter()).map(|(a, b)| a * b).sum();
                for (x, y) in v.iter_mut().zip(q) {
                    *x -= d * y;
                }
            }
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm > 0.0 {
                for x in v.iter_mut() {
                    *x /= norm;
                }
            }
        }
    }
}

/// Sign convention for a vector: flip it so that its largest-magnitude component (the first
/// one, on exact ties) is positive. Returns the sign applied.
pub fn fix_sign(v: &mut [f64]) -> f64 {
    let mut best = 0.0f64;
    let mut sign = 1.0;
    for &x in v.iter() {
        if x.abs() > best {
            best = x.abs();
            sign = if x < 0.0 { -1.0 } else { 1.0 };
        }
    }
    if sign < 0.0 {
        for x in v.iter_mut() {
            *x = -*x;
        }
    }
    sign
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Gram matrix that stopped a per-vertex bake with `NoConvergence` (issue: a ground
    /// cluster of 240 vertices of which 231 receive no light after one reflection): 240 x 240,
    /// zero but for these rows and columns.
    const STUCK_INDEX: [usize; 9] = [0, 16, 32, 48, 64, 80, 96, 112, 224];
    #[rustfmt::skip]
    const STUCK_BLOCK: [f64; 81] = [
        4.765075677085203e-06, 4.032690369194e-06, -7.753602051829985e-06, 1.1435699400010957e-05, -7.761458029617715e-06, -5.5455696369447935e-06, 3.907318223966778e-06, 3.934146817580805e-06, 7.273132036063855e-05,
        4.032690369194e-06, 3.412871634336323e-06, -6.561884519765734e-06, 9.67804877836302e-06, -6.568533045017396e-06, -4.693223525105005e-06, 3.306769008295287e-06, 3.3294740854898815e-06, 6.15526205738088e-05,
        -7.753602051829985e-06, -6.561884519765734e-06, 1.2616451207112108e-05, -1.8607860260946374e-05, 1.2629234241343231e-05, 9.023600679073198e-06, -6.35788236148926e-06, -6.401537122208752e-06, -0.0001183464341379583,
        1.1435699400010957e-05, 9.67804877836302e-06, -1.8607860260946374e-05, 2.7444521268842927e-05, -1.862671381261307e-05, -1.3308805917794158e-05, 9.377168317461289e-06, 9.441554227085022e-06, 0.00017454780846606205,
        -7.761458029617715e-06, -6.568533045017396e-06, 1.2629234241343231e-05, -1.862671381261307e-05, 1.2642030227391111e-05, 9.032743424087228e-06, -6.364324191012491e-06, -6.408023182894254e-06, -0.00011846634317528443,
        -5.5455696369447935e-06, -4.693223525105005e-06, 9.023600679073198e-06, -1.3308805917794158e-05, 9.032743424087228e-06, 6.45390434114067e-06, -4.5473160917279965e-06, -4.5785390657645565e-06, -8.46443223948088e-05,
        3.907318223966778e-06, 3.306769008295287e-06, -6.35788236148926e-06, 9.377168317461289e-06, -6.364324191012491e-06, -4.5473160917279965e-06, 3.203965002436605e-06, 3.225964202419008e-06, 5.9639013681336665e-05,
        3.934146817580805e-06, 3.3294740854898815e-06, -6.401537122208752e-06, 9.441554227085022e-06, -6.408023182894254e-06, -4.5785390657645565e-06, 3.225964202419008e-06, 3.2481144542385876e-06, 6.004850959896724e-05,
        7.273132036063855e-05, 6.15526205738088e-05, -0.0001183464341379583, 0.00017454780846606205, -0.00011846634317528443, -8.46443223948088e-05, 5.9639013681336665e-05, 6.004850959896724e-05, 0.08033917353140804,
    ];

    fn stuck_gram() -> Mat<f64> {
        let mut g = Mat::<f64>::zeros(240, 240);
        for (a, &i) in STUCK_INDEX.iter().enumerate() {
            for (b, &j) in STUCK_INDEX.iter().enumerate() {
                g[(i, j)] = STUCK_BLOCK[a * STUCK_INDEX.len() + b];
            }
        }
        g
    }

    /// `|A V - V diag(vals)|` and `|V^T V - I|`, largest entries.
    fn residuals(a: MatRef<'_, f64>, e: &SymEig) -> (f64, f64) {
        let n = a.nrows();
        let av = matmul(a, e.vecs.as_ref());
        let mut r = 0.0f64;
        for j in 0..n {
            for i in 0..n {
                r = r.max((av[(i, j)] - e.vecs[(i, j)] * e.vals[j]).abs());
            }
        }
        let vtv = matmul_tn(e.vecs.as_ref(), e.vecs.as_ref());
        let mut o = 0.0f64;
        for j in 0..n {
            for i in 0..n {
                o = o.max((vtv[(i, j)] - if i == j { 1.0 } else { 0.0 }).abs());
            }
        }
        (r, o)
    }

    #[test]
    fn the_stuck_gram_matrix_decomposes_and_faer_alone_does_not() {
        let g = stuck_gram();
        // The root cause, kept visible: faer's decomposition of the whole matrix fails.
        assert!(
            faer_eig(g.as_ref()).is_err(),
            "faer now converges here: revisit sym_eig"
        );
        let e = sym_eig(g.as_ref()).expect("decomposes");
        assert_eq!(e.vals.len(), 240);
        // numpy's eigvalsh of the block: 0.08034019404497231, 7.276642024832731e-05, ~0.
        assert!((e.vals[0] - 0.080_340_194_044_972_31).abs() < 1e-15);
        assert!((e.vals[1] - 7.276_642_024_832_731e-5).abs() < 1e-15);
        assert!(e.vals[2..].iter().all(|v| v.abs() < 1e-15));
        assert!(e.vals.windows(2).all(|w| w[0] >= w[1]));
        let (r, o) = residuals(g.as_ref(), &e);
        assert!(r < 1e-15 && o < 1e-12, "{r} {o}");
        // The zero rows' eigenvectors are their unit vectors.
        let col = (0..240).find(|&c| e.vecs[(1, c)] != 0.0).unwrap();
        assert_eq!(e.vecs[(1, col)], 1.0);
    }

    #[test]
    fn jacobi_agrees_with_faer_and_non_finite_input_is_an_error() {
        for (n, seed) in [(1usize, 1u64), (7, 2), (40, 3)] {
            let mut s = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
            let mut next = || {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            };
            let x = Mat::from_fn(n + 3, n, |_, _| next());
            let a = matmul_tn(x.as_ref(), x.as_ref());
            let (fv, _) = faer_eig(a.as_ref()).unwrap();
            let (jv, jvecs) = jacobi_eig(a.as_ref());
            let e = SymEig {
                vals: jv.clone(),
                vecs: jvecs,
                method: EigMethod::Jacobi,
            };
            let top = fv[0].abs().max(1e-300);
            for (f, j) in fv.iter().zip(&jv) {
                assert!((f - j).abs() < 1e-12 * top, "n {n}: {f} vs {j}");
            }
            let (r, o) = residuals(a.as_ref(), &e);
            assert!(r < 1e-12 * top && o < 1e-12, "n {n}: {r} {o}");
        }
        let mut bad = Mat::<f64>::identity(3, 3);
        bad[(2, 1)] = f64::NAN;
        let err = sym_eig(bad.as_ref()).unwrap_err().to_string();
        assert!(err.contains("NaN") && err.contains("(2, 1)"), "{err}");
    }

    #[test]
    fn svd_and_qr_agree() {
        let a = Mat::from_fn(50, 6, |i, j| {
            ((i * 7 + j * 3) % 11) as f64 - 5.0 + (i as f64) * 0.01
        });
        let (_, s, _) = svd_thin(a.as_ref()).unwrap();
        let r = qr_r(a.clone());
        let (_, s2, _) = svd_thin(r.as_ref()).unwrap();
        for (x, y) in s.iter().zip(&s2) {
            assert!((x - y).abs() < 1e-9 * s[0], "{x} {y}");
        }
        let g = matmul_tn(a.as_ref(), a.as_ref());
        let (l, _) = sym_eig_desc(g.as_ref()).unwrap();
        for (x, y) in s.iter().zip(&l) {
            assert!((x * x - y).abs() < 1e-8 * l[0]);
        }
    }

    /// The block-circulant eigensolver agrees with the dense one: same eigenvalues, and its
    /// vectors are orthonormal eigenvectors of the full matrix.
    #[test]
    fn block_circulant_eig_matches_dense() {
        for np in [6, 7] {
            let nb = 3;
            let n = nb * np;
            // G = sum of x x^T over vectors rotated in k: symmetric block circulant
            let base: Vec<Vec<f64>> = (0..4)
                .map(|s| {
                    (0..n)
                        .map(|i| ((i * (s + 2)) as f64 * 0.71).sin())
                        .collect()
                })
                .collect();
            let mut g = Mat::<f64>::zeros(n, n);
            for v in &base {
                for k in 0..np {
                    let rot = |i: usize| v[(i / np) * np + (i % np + np - k) % np];
                    for a in 0..n {
                        for b in 0..n {
                            g[(a, b)] += rot(a) * rot(b);
                        }
                    }
                }
            }
            let rows = Mat::from_fn(nb, n, |j, q| g[(j * np, q)]);
            let (vals, u) = block_circulant_eig(rows.as_ref(), np).unwrap();
            let (want, _) = sym_eig_desc(g.as_ref()).unwrap();
            for (x, y) in vals.iter().zip(&want) {
                assert!((x - y).abs() < 1e-10 * want[0], "{np}: {x} {y}");
            }
            let gu = matmul(g.as_ref(), u.as_ref());
            let utu = matmul_tn(u.as_ref(), u.as_ref());
            for c in 0..n {
                for i in 0..n {
                    assert!((gu[(i, c)] - vals[c] * u[(i, c)]).abs() < 1e-10 * want[0]);
                    let id = if i == c { 1.0 } else { 0.0 };
                    assert!((utu[(i, c)] - id).abs() < 1e-12);
                }
            }
        }
    }

    /// The small-Gram path of `leading_left_vectors` (tall matrices) gives the left singular
    /// vectors of the large one, orthonormal.
    #[test]
    fn leading_left_vectors_small_and_large_gram_agree() {
        let w = Mat::from_fn(40, 5, |i, j| {
            ((i * (j + 3)) as f64 * 0.37).sin() + 0.1 * j as f64
        });
        let small = leading_left_vectors(w.as_ref(), 3).unwrap();
        let large = leading_eigvecs(matmul(w.as_ref(), w.transpose()).as_ref(), 3).unwrap();
        let (u, _, _) = svd_thin(w.as_ref()).unwrap();
        for c in 0..3 {
            let mut col: Vec<f64> = (0..40).map(|i| u[(i, c)]).collect();
            fix_sign(&mut col);
            for i in 0..40 {
                assert!((small[(i, c)] - col[i]).abs() < 1e-10, "{c} {i}");
                assert!((large[(i, c)] - col[i]).abs() < 1e-10, "{c} {i}");
            }
        }
        let g = matmul_tn(small.as_ref(), small.as_ref());
        for a in 0..3 {
            for b in 0..3 {
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((g[(a, b)] - want).abs() < 1e-14);
            }
        }
        // more vectors than the rank: the large Gram path (null-space vectors)
        let all = leading_left_vectors(w.as_ref(), 8).unwrap();
        assert_eq!(all.ncols(), 8);
    }
}
