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
use faer::{Accum, Mat, MatRef, Par};

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

/// Eigendecomposition of a symmetric matrix; eigenvalues in *nonincreasing* order with the
/// matching eigenvector columns.
pub fn sym_eig_desc(a: MatRef<'_, f64>) -> Result<(Vec<f64>, Mat<f64>), BasisError> {
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
}
