//! The specular split (thesis 5.3.1): from every (h, wo) fibre over wi, Gaussians of the widths
//! in [`SPLIT_WIDTHS_DEG`] about the mirror direction, with nonnegative amplitudes fitted by
//! least squares in the tensor's metric, are removed; the Tucker decomposition (`super::tucker`)
//! sees only the residual. A sharp lobe's peak moves with the mirror direction, which a few
//! direction ranks cannot represent; the Gaussians move with it, so the residual reaches a
//! given error with fewer ranks (thesis figure 5-5; docs/brdf-basis.md, "Tensor basis for
//! shading").
//!
//! One fit ([`split_fibre`]), two variants: dense, on a [`BrdfTensor`] ([`specular_split`], the
//! report's), and by ring rows, on a [`RingTensor`] ([`specular_split_rings`], the shading
//! basis'). Kept apart from the decomposition because the shading basis' pole rows
//! (`super::pole`) fit their fibres with the same widths and [`split_fibre`], and decompose
//! nothing.

use super::tensor::{BrdfTensor, HemiGrid, RingTensor};
use rayon::prelude::*;

/// Gaussian widths of the specular split (thesis 5.3.1), degrees; 0 = a mirror spike.
pub const SPLIT_WIDTHS_DEG: [f64; 4] = [0.0, 7.0, 14.0, 21.0];

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
    let mut idx = Vec::with_capacity(k);
    let mut a = Vec::with_capacity(k * (k + 1));
    let mut x = vec![0.0; k];
    for mask in 1u32..(1 << k) {
        idx.clear();
        idx.extend((0..k).filter(|&j| mask & (1 << j) != 0));
        let m = idx.len();
        // solve the m x m system by Gaussian elimination with partial pivoting
        a.clear();
        a.resize(m * (m + 1), 0.0);
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
        x.fill(0.0);
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
            best.copy_from_slice(&x);
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

/// The specular split of a [`RingTensor`].
pub struct RingSplit {
    /// `[h][o][k]` amplitudes (the same along every ring).
    pub amplitudes: Vec<f64>,
    /// The residual's ring rows `[h][j][i]`, same scaling as the tensor's (the residual is
    /// equivariant too).
    pub residual: Vec<f64>,
    /// `||specular part|| / ||F||`.
    pub specular_fraction: f64,
}

/// [`specular_split_with`] for a [`RingTensor`]: only the first node of every ring is fitted,
/// against its profiles `g` (`[j][k][i]`, those about node `(j, 0)`'s mirror direction; node
/// `(j, k)`'s are them turned by `k` columns, and so are its fibre and its fit). Fits run in
/// parallel, each independently.
pub fn specular_split_rings(t: &RingTensor, g: &[f64]) -> RingSplit {
    let (nh, nd, _) = t.dims();
    let (nt, np) = (t.dirs.n_theta, t.dirs.n_phi);
    let nk = SPLIT_WIDTHS_DEG.len();
    assert_eq!(g.len(), nt * nk * nd);
    let grams: Vec<Vec<f64>> = g
        .chunks_exact(nk * nd)
        .map(|p| profile_gram(p, nk))
        .collect();
    let mut residual = t.rings.clone();
    let fits: Vec<Vec<f64>> = residual
        .par_chunks_mut(nd)
        .enumerate()
        .map(|(n, y)| {
            let j = n % nt;
            split_fibre(y, &g[j * nk * nd..][..nk * nd], &grams[j], nk)
        })
        .collect();
    let mut amplitudes = Vec::with_capacity(nh * nd * nk);
    for a in &fits {
        for _ in 0..np {
            amplitudes.extend_from_slice(a);
        }
    }
    // every ring row stands for n_phi rows with the same values
    let total: f64 = t.rings.iter().map(|x| x * x).sum();
    let spec: f64 = t
        .rings
        .iter()
        .zip(&residual)
        .map(|(a, b)| (a - b) * (a - b))
        .sum();
    RingSplit {
        amplitudes,
        residual,
        specular_fraction: if total > 0.0 {
            (spec / total).sqrt()
        } else {
            0.0
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
