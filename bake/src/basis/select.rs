//! Reconstruction error of a family's bases per `N_b`, and the smallest `N_b` meeting an error
//! target (docs/brdf-basis.md): what the baker's `[basis] error_target` runs. The full error
//! tables (the thesis' method, other metrics, timings) are measured by the `prt-bench` crate
//! with the pieces of this module.

use super::grid::{cosine_weights, node_cos_i, tabulate};
use super::pca::rel_err_w;
use super::{BasisBuilder, BasisConfig, BasisError, FamilySpec};
use faer::Mat;
use prt_formats::basis::{BrdfBasis, GridSpec};
use serde::Serialize;

/// The lobes errors are measured on.
pub struct EvalSet {
    pub params: Vec<f64>,
    pub lobes: Mat<f64>,
    pub description: String,
}

impl EvalSet {
    /// The thesis' sampling: `count` values uniform in the (unwarped) parameter over the range,
    /// i.e. s = 1, 2, .., 200 for Blinn-Phong on [1, 200] with `count` = 200.
    pub fn thesis(spec: &FamilySpec, grid: &GridSpec, count: usize) -> EvalSet {
        let (lo, hi) = spec.range;
        let count = count.max(2);
        let params: Vec<f64> = (0..count)
            .map(|j| lo + (hi - lo) * j as f64 / (count - 1) as f64)
            .collect();
        let lobes = tabulate(spec.family, grid, &params);
        EvalSet {
            description: format!(
                "{count} {} lobes uniform in the parameter over [{lo}, {hi}]",
                spec.family.name()
            ),
            params,
            lobes,
        }
    }
}

/// Error statistics over an evaluation set.
#[derive(Clone, Debug, Serialize)]
pub struct ErrStats {
    pub mean: f64,
    pub max: f64,
    /// Parameter of the worst lobe.
    pub max_at: f64,
    /// `||L - L^||_F / ||L||_F` over all lobes together.
    pub aggregate: f64,
}

impl ErrStats {
    fn new(errs: &[f64], params: &[f64], sq_num: f64, sq_den: f64) -> ErrStats {
        let mut max = 0.0;
        let mut max_at = params.first().copied().unwrap_or(0.0);
        for (e, p) in errs.iter().zip(params) {
            if *e > max {
                max = *e;
                max_at = *p;
            }
        }
        ErrStats {
            mean: errs.iter().sum::<f64>() / errs.len().max(1) as f64,
            max,
            max_at,
            aggregate: if sq_den > 0.0 {
                (sq_num / sq_den).sqrt()
            } else {
                0.0
            },
        }
    }
}

/// Negativity of reconstructed lobes (Kd = 0, Ks = 1: the worst case, Kd only adds).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Negativity {
    /// Most negative `f cos(theta_i)` over the grid, relative to the largest
    /// `lobe cos(theta_i)` of the same lobe (the quantity a renderer integrates).
    pub min_rel: f64,
    /// Parameter of that lobe.
    pub min_rel_at: f64,
    /// Largest `||min(f, 0)|| / ||lobe||` (cosine-weighted L2): the negative part's mass.
    pub neg_mass: f64,
}

/// Errors of reconstructions `recon(j)` of the evaluation lobes (tabulated on some grid) under
/// weights `w`; also the negativity of the reconstructions, measured with the cosine weights
/// `wc` and the nodes' `max(cos(theta_i), 0)` (`cos_i`, 0 outside the hemisphere pair).
pub fn measure(
    eval: &EvalSet,
    w: &[f64],
    wc: &[f64],
    cos_i: &[f64],
    recon: impl Fn(usize) -> Vec<f64>,
) -> (ErrStats, Negativity) {
    let mut errs = Vec::with_capacity(eval.params.len());
    let (mut num, mut den) = (0.0, 0.0);
    let mut neg = Negativity::default();
    for j in 0..eval.params.len() {
        let l = eval.lobes.col_as_slice(j);
        let r = recon(j);
        errs.push(rel_err_w(w, l, &r));
        let peak = (0..l.len()).map(|n| l[n] * cos_i[n]).fold(0.0, f64::max);
        let (mut nm, mut ln) = (0.0, 0.0);
        for n in 0..w.len() {
            let d = l[n] - r[n];
            num += w[n] * d * d;
            den += w[n] * l[n] * l[n];
            if r[n] < 0.0 {
                nm += wc[n] * r[n] * r[n];
            }
            ln += wc[n] * l[n] * l[n];
            if peak > 0.0 {
                let v = r[n] * cos_i[n] / peak;
                if v < neg.min_rel {
                    neg.min_rel = v;
                    neg.min_rel_at = eval.params[j];
                }
            }
        }
        if ln > 0.0 {
            neg.neg_mass = neg.neg_mass.max((nm / ln).sqrt());
        }
    }
    (ErrStats::new(&errs, &eval.params, num, den), neg)
}

/// Reconstruction of a lobe from a persisted basis with the runtime's interpolated
/// coefficients (what the baker and runtime actually use).
pub fn persisted_recon(basis: &BrdfBasis, param: f64) -> Vec<f64> {
    let (c, _) = basis.coefficients(param as f32);
    let nb = basis.num_bases;
    basis
        .tables
        .chunks_exact(nb)
        .map(|t| t.iter().zip(&c).map(|(a, b)| *a as f64 * *b as f64).sum())
        .collect()
}

/// The error of the persisted basis with `num_bases` bases.
#[derive(Clone, Debug, Serialize)]
pub struct ErrorRow {
    pub num_bases: usize,
    /// Cosine-weighted relative L2 error, coefficients interpolated from the persisted table.
    pub ours: ErrStats,
    /// Negativity of the reconstructed lobes.
    pub negativity: Negativity,
}

/// The errors of a family's bases, one row per `N_b`.
#[derive(Clone, Debug, Serialize)]
pub struct ErrorTable {
    pub rows: Vec<ErrorRow>,
}

/// Measures the persisted basis of every `N_b` in `counts` on `eval_count` lobes (see
/// [`EvalSet::thesis`]); returns the table and the persisted basis with `chosen` bases.
pub fn family_report(
    config: &BasisConfig,
    counts: &[usize],
    chosen: usize,
    eval_count: usize,
) -> Result<(ErrorTable, BrdfBasis), BasisError> {
    let builder = BasisBuilder::new(config.clone())?;
    let g = config.grid_spec();
    let eval = EvalSet::thesis(&config.spec, &g, eval_count);
    let wc = cosine_weights(&g);
    let cos_i = node_cos_i(&g);
    let mut rows = Vec::new();
    let mut chosen_basis = None;
    for &nb in counts {
        let persisted = builder.build(nb)?.to_persisted();
        let pr = |j: usize| persisted_recon(&persisted, eval.params[j]);
        let (ours, negativity) = measure(&eval, &wc, &wc, &cos_i, pr);
        rows.push(ErrorRow {
            num_bases: nb,
            ours,
            negativity,
        });
        if nb == chosen {
            chosen_basis = Some(persisted);
        }
    }
    let basis = match chosen_basis {
        Some(b) => b,
        None => builder.build(chosen)?.to_persisted(),
    };
    Ok((ErrorTable { rows }, basis))
}

/// Smallest `N_b` in the table whose error (max, or mean when `use_mean`) meets `target`.
pub fn select_count(table: &ErrorTable, target: f64, use_mean: bool) -> Option<usize> {
    table
        .rows
        .iter()
        .find(|r| {
            let e = if use_mean { r.ours.mean } else { r.ours.max };
            e <= target
        })
        .map(|r| r.num_bases)
}
