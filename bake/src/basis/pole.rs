//! The pole rows of the shading basis (docs/brdf-basis.md, "Shading basis"): the hemisphere
//! grid has no node on the normal (ring 0's nodes are 14 degrees from it on 16 rings), yet a
//! view straight down the normal is the commonest there is, and a sharp lobe's albedo changes
//! by 6 % between the two (Blinn-Phong, s = 200). So the normal gets rows of its own: `U^o`
//! and the reflectances for `wo` along the normal, `U^i` for `wi` along it, which the polar
//! cap's interpolation blends towards ([`prt_formats::basis::HemiWeights`]).
//!
//! The lobe for `wo` on the normal is sampled like any other outgoing direction (cell averages
//! over the incident cells) and split about its mirror direction, the normal itself; the
//! mirror spike, which has no node to sit on there, is spread evenly over ring 0 (the cells
//! that touch the normal). The rows of `U^o` and `U^i` are the least-squares fits of those
//! fibres in the span of the other two factors and the core (the projection HOOI would give a
//! new slice), in the tensor's metric.

use super::cells::{cell_average_row, cell_averages};
use super::grid::lobe_vectors;
use super::split::{profile_gram, split_fibre, RingSplit, SPLIT_WIDTHS_DEG};
use super::tensor::RingTensor;
use faer::Mat;
use prt_formats::basis::TuckerRanks;
use rayon::prelude::*;

const NORMAL: [f64; 3] = [0.0, 0.0, 1.0];

/// The lobe's fibres through the pole, in raw units.
pub struct PoleParts {
    /// `[h][i]`: the sampled lobe for `wo` on the normal (cell averages, 1/sr).
    pub lobe: Vec<f64>,
    /// `[h][i]`: its residual after the split about the normal.
    pub residual: Vec<f64>,
    /// `[h][k]`: its reflectances (the raw amplitude times the profile's `sum_i G z_i dw`).
    pub reflectances: Vec<f64>,
    /// `[h][o]`: the split residual at `wi` on the normal for every node `o` (the lobe's
    /// point value there minus the Gaussians' point values).
    pub column: Vec<f64>,
}

impl PoleParts {
    /// Samples and splits the fibres through the pole of `tensor` (whose split is `split`).
    pub fn new(tensor: &RingTensor, split: &RingSplit) -> PoleParts {
        let dirs = tensor.dirs;
        let (nh, nd, _) = tensor.dims();
        let nk = SPLIT_WIDTHS_DEG.len();
        let dw = dirs.solid_angle();
        let z: Vec<f64> = (0..nd).map(|i| dirs.dir(i)[2]).collect();
        // raw profiles about the normal, [k][i]
        let mut prof = vec![0.0; nk * nd];
        for (k, &deg) in SPLIT_WIDTHS_DEG.iter().enumerate() {
            let p = &mut prof[k * nd..(k + 1) * nd];
            if deg == 0.0 {
                p[..dirs.n_phi].fill(1.0);
            } else {
                let sigma = deg.to_radians();
                let gauss = |w: [f64; 3]| {
                    (-w[2].clamp(-1.0, 1.0).acos().powi(2) / (2.0 * sigma * sigma)).exp()
                };
                cell_averages(&dirs, NORMAL, sigma, 1.0, gauss, p);
            }
        }
        let mass: Vec<f64> = (0..nk)
            .map(|k| (0..nd).map(|i| prof[k * nd + i] * z[i] * dw).sum())
            .collect();
        // the split in the tensor's metric (the pole's own scale cancels): entries times
        // sqrt(cos dw) of the incident direction
        let s = &tensor.dir_scale;
        let scaled: Vec<f64> = (0..nk * nd).map(|n| prof[n] * s[n % nd]).collect();
        let gram = profile_gram(&scaled, nk);
        let sigma: Vec<f64> = SPLIT_WIDTHS_DEG.iter().map(|d| d.to_radians()).collect();
        let family = tensor.spec.family;
        // per parameter sample (in parallel, each independently): lobe, residual,
        // reflectances, column
        type Rows = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);
        let rows: Vec<Rows> = (0..nh)
            .into_par_iter()
            .map(|h| {
                let p = tensor.params[h];
                let mut row = vec![0.0; nd];
                cell_average_row(family, p, NORMAL, &dirs, &mut row);
                let mut y: Vec<f64> = row.iter().zip(s).map(|(v, si)| v * si).collect();
                let a = split_fibre(&mut y, &scaled, &gram, nk);
                let residual: Vec<f64> = (0..nd)
                    .map(|i| if s[i] > 0.0 { y[i] / s[i] } else { 0.0 })
                    .collect();
                let refl: Vec<f64> = (0..nk).map(|k| a[k] * mass[k]).collect();
                // wi on the normal: the lobe minus the Gaussians fitted about each node's
                // mirror direction (the spike sits on a node, never on the normal)
                let ls = tensor.lobe_scale[h];
                let column: Vec<f64> = (0..nd)
                    .map(|o| {
                        let wo = dirs.dir(o);
                        let angle = wo[2].clamp(-1.0, 1.0).acos();
                        let mut v = lobe_vectors(family, p, NORMAL, wo);
                        for (k, sg) in sigma.iter().enumerate().skip(1) {
                            let amp = split.amplitudes[(h * nd + o) * nk + k];
                            if ls > 0.0 {
                                v -= amp / ls * (-angle * angle / (2.0 * sg * sg)).exp();
                            }
                        }
                        v
                    })
                    .collect();
                (row, residual, refl, column)
            })
            .collect();
        let cat = |f: fn(&Rows) -> &Vec<f64>| -> Vec<f64> {
            rows.iter().flat_map(|r| f(r).iter().copied()).collect()
        };
        let (lobe, residual) = (cat(|r| &r.0), cat(|r| &r.1));
        let (reflectances, column) = (cat(|r| &r.2), cat(|r| &r.3));
        PoleParts {
            lobe,
            residual,
            reflectances,
            column,
        }
    }
}

/// The row `u` (length `r_b`) that best reproduces the fibre `x[h][n]` (already in the tensor's
/// metric) as `sum_acd D u_h(h, a) u(b) v(n, c)` for fixed orthonormal `u_h` (`n_h x r_h`) and
/// `v` (`n x r_c`), in least squares. `core_at(a, b, c)` reads the core with `b` the mode
/// being fitted. Pivots below `1e-13` of the largest are dropped (a core without weight in a
/// direction of `b` cannot be fitted there).
pub fn fit_row(
    x: &[f64],
    u_h: &Mat<f64>,
    v: &Mat<f64>,
    (r_h, r_b, r_c): (usize, usize, usize),
    core_at: impl Fn(usize, usize, usize) -> f64,
) -> Vec<f64> {
    let (nh, n) = (u_h.nrows(), v.nrows());
    // y(a, c) = sum_h sum_n x(h, n) u_h(h, a) v(n, c)
    let mut y = vec![0.0; r_h * r_c];
    for h in 0..nh {
        for nn in 0..n {
            let xv = x[h * n + nn];
            if xv == 0.0 {
                continue;
            }
            for a in 0..r_h {
                let xa = xv * u_h[(h, a)];
                for c in 0..r_c {
                    y[a * r_c + c] += xa * v[(nn, c)];
                }
            }
        }
    }
    let mut m = vec![0.0; r_b * (r_b + 1)];
    for b in 0..r_b {
        for a in 0..r_h {
            for c in 0..r_c {
                let d = core_at(a, b, c);
                m[b * (r_b + 1) + r_b] += d * y[a * r_c + c];
                for b2 in 0..r_b {
                    m[b * (r_b + 1) + b2] += d * core_at(a, b2, c);
                }
            }
        }
    }
    solve_spd(&mut m, r_b)
}

/// Solves the augmented `k x (k + 1)` system by Gauss-Jordan elimination with partial
/// pivoting; a pivot below `1e-13` of the largest diagonal gives a zero component.
fn solve_spd(m: &mut [f64], k: usize) -> Vec<f64> {
    let w = k + 1;
    let scale = (0..k).map(|i| m[i * w + i].abs()).fold(0.0, f64::max);
    let mut dead = vec![false; k];
    for col in 0..k {
        let piv = (col..k)
            .max_by(|&a, &b| m[a * w + col].abs().total_cmp(&m[b * w + col].abs()))
            .unwrap_or(col);
        for c in 0..w {
            m.swap(col * w + c, piv * w + c);
        }
        let pivot = m[col * w + col].abs();
        if pivot.is_nan() || pivot <= 1e-13 * scale {
            dead[col] = true;
            continue;
        }
        for r in 0..k {
            if r != col {
                let f = m[r * w + col] / m[col * w + col];
                for c in col..w {
                    m[r * w + c] -= f * m[col * w + c];
                }
            }
        }
    }
    (0..k)
        .map(|i| {
            if dead[i] {
                0.0
            } else {
                m[i * w + k] / m[i * w + i]
            }
        })
        .collect()
}

/// The core of `ranks` stored `[a][b][c]`, read as `(a, mode-o index, c)`.
pub fn core_o(core: &[f64], r: TuckerRanks) -> impl Fn(usize, usize, usize) -> f64 + '_ {
    move |a, b, c| core[(a * r.o + b) * r.i + c]
}

/// The core read as `(a, mode-i index, mode-o index)`.
pub fn core_i(core: &[f64], r: TuckerRanks) -> impl Fn(usize, usize, usize) -> f64 + '_ {
    move |a, c, b| core[(a * r.o + b) * r.i + c]
}
