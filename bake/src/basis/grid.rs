//! Tabulation of a family's specular lobes on a basis grid (`prt_formats::basis::GridSpec`:
//! the thesis' `(theta_i, theta_o, phi)` grid or the graded half/difference grid; see
//! `prt_formats::basis` for the conventions) and the quadrature weights that define the error
//! metric of docs/brdf-basis.md.

use crate::brdf::{Family, Lobe};
use faer::Mat;
use prt_formats::basis::{
    half_diff_node, half_diff_pair, AngularGrid, GridKind, GridNode, GridSpec, ParamWarp,
    HALF_DIFF_COS_OFFSET,
};
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
    lobe_cosines(family, p, ci, co, h[2] / len)
}

/// The family's specular lobe in f64 from `cos(theta_i)`, `cos(theta_o)` and `cos(theta_h)`.
/// Cosines below 0 are clamped to 0, so the value continues the lobe past the horizon with its
/// grazing limit (what half/difference nodes outside the hemisphere pair hold).
pub fn lobe_cosines(family: Family, p: f64, ci: f64, co: f64, cos_h: f64) -> f64 {
    family.lobe_cosines_f64(p, ci, co, cos_h)
}

/// The lobe for local-frame unit vectors (both above the horizon, else 0), in f64.
pub fn lobe_vectors(family: Family, p: f64, wi: [f64; 3], wo: [f64; 3]) -> f64 {
    if wi[2] <= 0.0 || wo[2] <= 0.0 {
        return 0.0;
    }
    let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let len = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    if len <= 1e-300 {
        return 0.0;
    }
    lobe_cosines(family, p, wi[2], wo[2], h[2] / len)
}

/// The lobe's value at a grid node: the [`lobe_f64`] limit from inside on the thesis grid's
/// horizon nodes, the lobe continued with clamped cosines at half/difference nodes.
pub fn lobe_at_node(family: Family, p: f64, kind: GridKind, n: &GridNode) -> f64 {
    match kind {
        GridKind::Angles => lobe_f64(
            family,
            p,
            n.cos_theta_i.clamp(-1.0, 1.0).acos(),
            n.cos_theta_o.clamp(-1.0, 1.0).acos(),
            n.cos_phi.clamp(-1.0, 1.0).acos(),
        ),
        GridKind::HalfDiff => lobe_cosines(family, p, n.cos_theta_i, n.cos_theta_o, n.cos_theta_h),
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
/// the pair of hemispheres, for isotropic functions tabulated on `grid` and interpolated
/// trilinearly in its coordinates: the integrals of the node's hat function against the
/// measure. The constant `1/pi` has unit norm under them (up to quadrature error).
pub fn cosine_weights(grid: &GridSpec) -> Vec<f64> {
    match grid.kind {
        GridKind::Angles => angles_cosine_weights(&grid.dims),
        GridKind::HalfDiff => half_diff_cosine_weights(&grid.dims),
    }
}

/// [`cosine_weights`] of the thesis grid: `4 pi w_i w_o w_phi` (separable).
fn angles_cosine_weights(grid: &AngularGrid) -> Vec<f64> {
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

/// Gauss-Legendre nodes and weights on [0, 1], 6 points.
const GAUSS6: [(f64, f64); 6] = [
    (0.033_765_242_898_423_99, 0.085_662_246_189_585_17),
    (0.169_395_306_766_867_74, 0.180_380_786_524_069_3),
    (0.380_690_406_958_401_55, 0.233_956_967_286_345_53),
    (0.619_309_593_041_598_5, 0.233_956_967_286_345_53),
    (0.830_604_693_233_132_3, 0.180_380_786_524_069_3),
    (0.966_234_757_101_576, 0.085_662_246_189_585_17),
];

/// [`cosine_weights`] of a half/difference grid. With
///
/// ```text
/// dwi dwo = 4 cos(theta_d) sin(theta_h) sin(theta_d) d theta_h d phi_h d theta_d d phi_d,
/// sin(theta_h) d theta_h = 4 u1^3 du1,
/// sin(theta_d) d theta_d = |ln(c0 / (1 + c0))| (cos(theta_d) + c0) du2,
/// ```
///
/// the integral over `phi_h` (2 pi) and the fold of `phi_d` onto `[0, pi/2]` (x 4), the weight
/// of a node is `8 pi` times the integral, over the cells around it, of its hat function times
/// `4 u1^3 |ln(c0/(1+c0))| (cos_d + c0) 4 cos_d max(cos_i, 0) max(cos_o, 0)` in `u1`, `u2` and
/// `phi_d` (the hat is linear in `u3 = sin^2 phi_d`). Each cell is integrated with a 6-point
/// Gauss rule per axis; cells are computed in parallel and summed in a fixed order, so the
/// weights do not depend on the thread count.
fn half_diff_cosine_weights(grid: &AngularGrid) -> Vec<f64> {
    let (n1, n2, n3) = (grid.n_theta_i, grid.n_theta_o, grid.n_phi);
    let c0 = HALF_DIFF_COS_OFFSET;
    let lam = (c0 / (1.0 + c0)).ln().abs();
    let phi_at = |k: usize| (k as f64 / (n3 - 1) as f64).sqrt().asin();
    let cells: Vec<(usize, usize, usize)> = (0..n1 - 1)
        .flat_map(|i| (0..n2 - 1).flat_map(move |o| (0..n3 - 1).map(move |k| (i, o, k))))
        .collect();
    let contrib: Vec<[f64; 8]> = cells
        .par_iter()
        .map(|&(i, o, k)| {
            let (du1, du2) = (1.0 / (n1 - 1) as f64, 1.0 / (n2 - 1) as f64);
            let (p0, p1) = (phi_at(k), phi_at(k + 1));
            let (s0, s1) = (k as f64 / (n3 - 1) as f64, (k + 1) as f64 / (n3 - 1) as f64);
            let mut acc = [0.0f64; 8];
            for &(x1, g1) in &GAUSS6 {
                let u1 = (i as f64 + x1) * du1;
                for &(x2, g2) in &GAUSS6 {
                    let u2 = (o as f64 + x2) * du2;
                    for &(x3, g3) in &GAUSS6 {
                        let ph = p0 + x3 * (p1 - p0);
                        let s2 = ph.sin().powi(2);
                        let t3 = ((s2 - s0) / (s1 - s0)).clamp(0.0, 1.0);
                        let (ch, cd, _) = half_diff_node(u1, u2, s2);
                        let n = half_diff_pair(ch, cd, s2);
                        let m = n.cos_theta_i.max(0.0) * n.cos_theta_o.max(0.0);
                        if m <= 0.0 {
                            continue;
                        }
                        let jac = 4.0 * u1.powi(3) * lam * (cd + c0) * 4.0 * cd;
                        let w = g1 * g2 * g3 * du1 * du2 * (p1 - p0) * jac * m * 8.0 * PI;
                        let (t1, t2) = (x1, x2);
                        for (c, a) in acc.iter_mut().enumerate() {
                            let h1 = if c & 4 != 0 { t1 } else { 1.0 - t1 };
                            let h2 = if c & 2 != 0 { t2 } else { 1.0 - t2 };
                            let h3 = if c & 1 != 0 { t3 } else { 1.0 - t3 };
                            *a += w * h1 * h2 * h3;
                        }
                    }
                }
            }
            acc
        })
        .collect();
    let mut w = vec![0.0; grid.len()];
    for (&(i, o, k), acc) in cells.iter().zip(&contrib) {
        for (c, a) in acc.iter().enumerate() {
            let n = grid.index(i + (c >> 2 & 1), o + (c >> 1 & 1), k + (c & 1));
            w[n] += a;
        }
    }
    w
}

/// Unit weights: the plain Euclidean norm of the table (the thesis' "L2 norm" of a sampled
/// BRDF vector).
pub fn uniform_weights(grid: &GridSpec) -> Vec<f64> {
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
pub fn tabulate(family: Family, grid: &GridSpec, params: &[f64]) -> Mat<f64> {
    let n = grid.len();
    let nodes = grid.nodes();
    let cols: Vec<Vec<f64>> = params
        .par_iter()
        .map(|&p| {
            nodes
                .iter()
                .map(|nd| lobe_at_node(family, p, grid.kind, nd))
                .collect()
        })
        .collect();
    let mut m = Mat::<f64>::zeros(n, params.len());
    for (j, c) in cols.iter().enumerate() {
        m.col_as_slice_mut(j).copy_from_slice(c);
    }
    m
}

/// One lobe as a table (see [`tabulate`]).
pub fn tabulate_one(family: Family, grid: &GridSpec, p: f64) -> Vec<f64> {
    grid.nodes()
        .iter()
        .map(|nd| lobe_at_node(family, p, grid.kind, nd))
        .collect()
}

/// `max(cos(theta_i), 0)` of every node (0 outside the hemisphere pair).
pub fn node_cos_i(grid: &GridSpec) -> Vec<f64> {
    grid.nodes()
        .iter()
        .map(|n| if n.inside() { n.cos_theta_i } else { 0.0 })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_integrate_constants() {
        let w = projected_theta_weights(30);
        let s: f64 = w.iter().sum();
        assert!((s - 0.5).abs() < 1e-12, "{s}");
        let cw = cosine_weights(&GridSpec::THESIS);
        let norm: f64 = cw.iter().map(|w| w / (PI * PI)).sum();
        assert!((norm - 1.0).abs() < 1e-12, "{norm}");
        for dims in [
            AngularGrid::HALF_DIFF,
            AngularGrid {
                n_theta_i: 9,
                n_theta_o: 7,
                n_phi: 3,
            },
        ] {
            let g = GridSpec::new(GridKind::HalfDiff, dims);
            let cw = cosine_weights(&g);
            assert!(cw.iter().all(|w| w.is_finite() && *w >= 0.0));
            let norm: f64 = cw.iter().map(|w| w / (PI * PI)).sum();
            assert!((norm - 1.0).abs() < 1e-6, "{dims:?}: {norm}");
        }
    }

    #[test]
    fn half_diff_weights_integrate_cos_powers() {
        // int int cos^2(theta_i) cos^2(theta_o) dwi dwo = (2 pi / 3)^2; the weights integrate
        // the grid's interpolant of cos_i cos_o exactly, which has a kink where the horizon
        // cuts a cell: check to the grid's accuracy
        let g = GridSpec::DEFAULT;
        let cw = cosine_weights(&g);
        let s: f64 = cw
            .iter()
            .zip(g.nodes())
            .map(|(w, n)| w * n.cos_theta_i.max(0.0) * n.cos_theta_o.max(0.0))
            .sum();
        let want = (2.0 * PI / 3.0).powi(2);
        assert!((s / want - 1.0).abs() < 5e-3, "{s} vs {want}");
    }

    #[test]
    fn samples_are_monotone_with_exact_ends() {
        let p = param_samples((1.0, 200.0), ParamWarp::Log { offset: 1.0 }, 7);
        assert_eq!(p[0], 1.0);
        assert_eq!(p[6], 200.0);
        assert!(p.windows(2).all(|w| w[0] < w[1]));
    }
}
