//! Tabulation of a family's specular lobes on the isotropic `(theta_i, theta_o, phi)` node grid
//! (see `prt_formats::basis` for the grid convention) and the quadrature weights that define
//! the error metric of docs/brdf-basis.md.

use crate::brdf::Family;
use faer::Mat;
use prt_formats::basis::{AngularGrid, ParamWarp};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};

/// Largest polar angle at which lobes are evaluated: nodes on the horizon hold the limit of the
/// lobe from inside the hemisphere (the formulas' value at cos = 0 is that limit, except where
/// the half vector vanishes).
const THETA_MAX: f64 = FRAC_PI_2 - 1e-7;

/// The family's specular lobe in f64, at polar angles `ti`, `to` and azimuth difference `phi`
/// (mirror configuration at `phi = pi`). Same formulas as `crate::brdf`, written so that they
/// stay finite at grazing angles: GGX uses `G1(c)/c = 2 / (c + sqrt(a^2 + (1 - a^2) c^2))`.
pub fn lobe_f64(family: Family, p: f64, ti: f64, to: f64, phi: f64) -> f64 {
    let (si, ci) = ti.clamp(0.0, THETA_MAX).sin_cos();
    let (so, co) = to.clamp(0.0, THETA_MAX).sin_cos();
    let (sp, cp) = phi.sin_cos();
    let h = [si + so * cp, so * sp, ci + co];
    let len = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    if len <= 1e-300 {
        return 0.0;
    }
    let cos_h = (h[2] / len).clamp(0.0, 1.0);
    match family {
        Family::Diffuse => 0.0,
        Family::BlinnPhong => {
            let s = p;
            if cos_h <= 0.0 {
                return if s == 0.0 { 1.0 / PI } else { 0.0 };
            }
            (s + 2.0) / (2.0 * PI) * (s * cos_h.ln()).exp()
        }
        Family::Ggx => {
            let a2 = p * p;
            let c2 = cos_h * cos_h;
            let denom = a2 * c2 + (1.0 - c2).max(0.0);
            if denom <= 0.0 {
                return 0.0;
            }
            let d = a2 / (PI * denom * denom);
            let g1c = |c: f64| 2.0 / (c + (a2 + (1.0 - a2) * c * c).sqrt());
            d * g1c(ci) * g1c(co) / 4.0
        }
    }
}

/// Node weights `w_j = integral of hat_j(theta) sin(theta) cos(theta) d theta` over
/// [0, pi/2] for `n` uniform nodes (composite Simpson, 64 panels per cell).
pub fn projected_theta_weights(n: usize) -> Vec<f64> {
    let h = FRAC_PI_2 / (n - 1) as f64;
    let mut w = vec![0.0; n];
    const PANELS: usize = 64;
    for cell in 0..n - 1 {
        let a = cell as f64 * h;
        let dx = h / PANELS as f64;
        let (mut lo, mut hi) = (0.0, 0.0);
        for k in 0..=PANELS {
            let x = a + k as f64 * dx;
            let t = (x - a) / h;
            let c = if k == 0 || k == PANELS {
                1.0
            } else if k % 2 == 1 {
                4.0
            } else {
                2.0
            };
            let f = x.sin() * x.cos() * c * dx / 3.0;
            lo += f * (1.0 - t);
            hi += f * t;
        }
        w[cell] += lo;
        w[cell + 1] += hi;
    }
    w
}

/// Trapezoid (hat-function) weights over [0, pi] for `n` uniform phi nodes.
pub fn phi_weights(n: usize) -> Vec<f64> {
    let h = PI / (n - 1) as f64;
    (0..n)
        .map(|k| if k == 0 || k == n - 1 { h / 2.0 } else { h })
        .collect()
}

/// Quadrature weights of the cosine-weighted measure `cos(theta_i) cos(theta_o) dwi dwo` over
/// the pair of hemispheres, for isotropic functions tabulated on `grid`: `4 pi w_i w_o w_phi`.
/// The constant `1/pi` has unit norm under them (up to quadrature error).
pub fn cosine_weights(grid: &AngularGrid) -> Vec<f64> {
    let wi = projected_theta_weights(grid.n_theta_i);
    let wo = projected_theta_weights(grid.n_theta_o);
    let wp = phi_weights(grid.n_phi);
    let mut w = Vec::with_capacity(grid.len());
    for a in &wi {
        for b in &wo {
            for c in &wp {
                w.push(4.0 * PI * a * b * c);
            }
        }
    }
    w
}

/// Unit weights: the plain Euclidean norm of the table (the thesis' "L2 norm" of a sampled
/// BRDF vector).
pub fn uniform_weights(grid: &AngularGrid) -> Vec<f64> {
    vec![1.0; grid.len()]
}

/// `n` parameter values spread uniformly in the warped parameter over `[lo, hi]` (endpoints
/// exact).
pub fn param_samples(range: (f64, f64), warp: ParamWarp, n: usize) -> Vec<f64> {
    if n <= 1 {
        return vec![range.0];
    }
    let (u0, u1) = (warp.apply(range.0), warp.apply(range.1));
    (0..n)
        .map(|j| {
            if j == 0 {
                range.0
            } else if j == n - 1 {
                range.1
            } else {
                warp.invert(u0 + (u1 - u0) * j as f64 / (n - 1) as f64)
            }
        })
        .collect()
}

/// Tabulates the lobes for `params` on `grid`: a `grid.len() x params.len()` matrix, one
/// column per parameter (node index as in `AngularGrid::index`). Columns are computed in
/// parallel; every value is computed independently, so the result does not depend on the
/// thread count.
pub fn tabulate(family: Family, grid: &AngularGrid, params: &[f64]) -> Mat<f64> {
    let n = grid.len();
    let cols: Vec<Vec<f64>> = params
        .par_iter()
        .map(|&p| tabulate_one(family, grid, p))
        .collect();
    let mut m = Mat::<f64>::zeros(n, params.len());
    for (j, c) in cols.iter().enumerate() {
        m.col_as_slice_mut(j).copy_from_slice(c);
    }
    m
}

/// One lobe as a table (see [`tabulate`]).
pub fn tabulate_one(family: Family, grid: &AngularGrid, p: f64) -> Vec<f64> {
    let mut v = Vec::with_capacity(grid.len());
    for i in 0..grid.n_theta_i {
        let ti = AngularGrid::theta(grid.n_theta_i, i);
        for o in 0..grid.n_theta_o {
            let to = AngularGrid::theta(grid.n_theta_o, o);
            for k in 0..grid.n_phi {
                v.push(lobe_f64(family, p, ti, to, AngularGrid::phi(grid.n_phi, k)));
            }
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_integrate_constants() {
        let w = projected_theta_weights(30);
        let s: f64 = w.iter().sum();
        assert!((s - 0.5).abs() < 1e-12, "{s}");
        let g = AngularGrid::THESIS;
        let cw = cosine_weights(&g);
        let norm: f64 = cw.iter().map(|w| w / (PI * PI)).sum();
        assert!((norm - 1.0).abs() < 1e-12, "{norm}");
    }

    #[test]
    fn samples_are_monotone_with_exact_ends() {
        let p = param_samples((1.0, 200.0), ParamWarp::Log { offset: 1.0 }, 7);
        assert_eq!(p[0], 1.0);
        assert_eq!(p[6], 200.0);
        assert!(p.windows(2).all(|w| w[0] < w[1]));
    }
}
