//! Error measurement of PCA bases (docs/brdf-basis.md): relative L2 reconstruction error of
//! every sampled lobe, for `N_b = 2..12`, ours against the thesis' method; and the end-to-end
//! error of the evaluated basis against the exact lobe ([`continuous_error`]).

use super::grid::{cosine_weights, lobe_vectors, node_cos_i, tabulate, uniform_weights};
use super::pca::{rel_err_w, PcaBuilder, PcaModel, PcaOptions};
use super::{BasisBuilder, BasisConfig, BuiltBasis, FamilySpec};
use crate::brdf::Family;
use faer::Mat;
use prt_formats::basis::{BrdfBasis, GridSpec};
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

/// The lobes errors are measured on.
pub struct EvalSet {
    pub params: Vec<f64>,
    pub lobes: Mat<f64>,
    pub description: String,
}

impl EvalSet {
    /// The thesis' sampling: 200 values uniform in the (unwarped) parameter over the range,
    /// i.e. s = 1, 2, .., 200 for Blinn-Phong on [1, 200].
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
fn measure(
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

/// The persisted basis evaluated by the runtime (`eval_all`) at the nodes of another grid:
/// `grid.len() x N_b` values, node-major. Nodes outside the hemisphere pair give zeros.
pub fn basis_at_nodes(basis: &BrdfBasis, grid: &GridSpec) -> Vec<f32> {
    let nb = basis.num_bases;
    let mut out = vec![0.0f32; grid.len() * nb];
    for (n, nd) in grid.nodes().iter().enumerate() {
        if nd.inside() {
            basis.eval_all(
                nd.cos_theta_i as f32,
                nd.cos_theta_o as f32,
                nd.cos_phi as f32,
                &mut out[n * nb..(n + 1) * nb],
            );
        }
    }
    out
}

/// Reconstruction of lobe `param` from basis values at nodes (see [`basis_at_nodes`]) with the
/// runtime's interpolated coefficients.
fn recon_from_values(basis: &BrdfBasis, values: &[f32], param: f64) -> Vec<f64> {
    let (c, _) = basis.coefficients(param as f32);
    values
        .chunks_exact(basis.num_bases)
        .map(|t| t.iter().zip(&c).map(|(a, b)| *a as f64 * *b as f64).sum())
        .collect()
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

/// Reconstruction by orthogonal projection on the model's span (optimal coefficients).
pub fn projected_recon(model: &PcaModel, lobe: &[f64]) -> Vec<f64> {
    model.reconstruct(&model.project(lobe))
}

/// One row of the error table.
#[derive(Clone, Debug, Serialize)]
pub struct NbRow {
    pub num_bases: usize,
    /// Ours, cosine-weighted metric, coefficients interpolated from the persisted table.
    pub ours: ErrStats,
    /// Ours, cosine-weighted metric, optimal (projected) coefficients.
    pub ours_projected: ErrStats,
    /// Ours, measured with the thesis' metric: the plain norm of the samples at the thesis
    /// grid's nodes, where our basis is evaluated by the runtime (`eval_all`).
    pub ours_uniform_metric: ErrStats,
    /// As `ours_uniform_metric` without the thesis grid's horizon nodes (theta_i or theta_o
    /// exactly 90 degrees, where the exact tables hold the grazing limit and our cosine-weighted
    /// PCA does not constrain the bases).
    pub ours_uniform_metric_inner: ErrStats,
    /// The thesis' method (raw lobes, uniform norm, PCA of the evaluation lobes themselves, on
    /// the thesis grid), measured with its own metric.
    pub thesis: ErrStats,
    /// The thesis' method measured with our cosine-weighted metric (on the thesis grid).
    pub thesis_cosine_metric: ErrStats,
    /// Negativity of our reconstructed lobes (persisted basis).
    pub negativity: Negativity,
    /// Wall time to build this basis from the tabulated lobes (ms).
    pub build_ms: f64,
}

/// The whole report for a family.
#[derive(Clone, Debug, Serialize)]
pub struct FamilyReport {
    pub family: String,
    pub param_range: [f64; 2],
    pub grid: [usize; 3],
    /// `angles` or `half-diff`.
    pub grid_kind: String,
    pub build_samples: usize,
    pub eval_set: String,
    pub method: PcaOptions,
    pub rows: Vec<NbRow>,
    /// Tabulating the build lobes and factoring them (ms).
    pub setup_ms: f64,
    /// Runtime `eval_all` cost (ns per direction pair, all bases) for the `chosen` basis.
    pub eval_all_ns: f64,
    /// Runtime `eval_all_local` cost (ns per direction pair; the baker's entry point).
    pub eval_local_ns: f64,
    /// Runtime `coefficients` cost (ns per call).
    pub coefficients_ns: f64,
    /// `N_b` of the basis the timings and `chosen_basis` refer to.
    pub chosen: usize,
}

/// Measures ours against the thesis' method for every `N_b` in `counts`; returns the report
/// and the persisted basis with `chosen` bases.
pub fn family_report(
    config: &BasisConfig,
    counts: &[usize],
    chosen: usize,
    eval_count: usize,
) -> Result<(FamilyReport, BrdfBasis), String> {
    let t0 = Instant::now();
    let builder = BasisBuilder::new(config.clone())?;
    let setup_ms = t0.elapsed().as_secs_f64() * 1e3;
    let g = config.grid_spec();
    let eval = EvalSet::thesis(&config.spec, &g, eval_count);
    // the thesis' method and metric live on the thesis grid
    let tg = GridSpec::THESIS;
    let eval_t = if g == tg {
        None
    } else {
        Some(EvalSet::thesis(&config.spec, &tg, eval_count))
    };
    let eval_t = eval_t.as_ref().unwrap_or(&eval);
    let thesis = PcaBuilder::new(eval_t.lobes.as_ref(), tg, PcaOptions::thesis())?;
    let wc = cosine_weights(&g);
    let cos_i = node_cos_i(&g);
    let wc_t = cosine_weights(&tg);
    let wu_t = uniform_weights(&tg);
    let cos_i_t = node_cos_i(&tg);
    let wu_inner: Vec<f64> = tg
        .nodes()
        .iter()
        .zip(&wu_t)
        .map(|(n, w)| {
            if n.cos_theta_i > 1e-9 && n.cos_theta_o > 1e-9 {
                *w
            } else {
                0.0
            }
        })
        .collect();
    let mut rows = Vec::new();
    let mut chosen_basis = None;
    for &nb in counts {
        let t = Instant::now();
        let built: BuiltBasis = builder.build(nb)?;
        let build_ms = t.elapsed().as_secs_f64() * 1e3;
        let persisted = built.to_persisted();
        let pr = |j: usize| persisted_recon(&persisted, eval.params[j]);
        let (ours, negativity) = measure(&eval, &wc, &wc, &cos_i, pr);
        let at_t = basis_at_nodes(&persisted, &tg);
        let (ours_uniform_metric, _) = measure(eval_t, &wu_t, &wc_t, &cos_i_t, |j| {
            recon_from_values(&persisted, &at_t, eval_t.params[j])
        });
        let (ours_uniform_metric_inner, _) = measure(eval_t, &wu_inner, &wc_t, &cos_i_t, |j| {
            recon_from_values(&persisted, &at_t, eval_t.params[j])
        });
        let (ours_projected, _) = measure(&eval, &wc, &wc, &cos_i, |j| {
            projected_recon(&built.model, eval.lobes.col_as_slice(j))
        });
        let tm = thesis.build(nb)?;
        let tr = |j: usize| projected_recon(&tm, eval_t.lobes.col_as_slice(j));
        let (th, _) = measure(eval_t, &wu_t, &wc_t, &cos_i_t, tr);
        let (thc, _) = measure(eval_t, &wc_t, &wc_t, &cos_i_t, tr);
        rows.push(NbRow {
            num_bases: nb,
            ours,
            ours_projected,
            ours_uniform_metric,
            ours_uniform_metric_inner,
            thesis: th,
            thesis_cosine_metric: thc,
            negativity,
            build_ms,
        });
        if nb == chosen {
            chosen_basis = Some(persisted);
        }
    }
    let basis = match chosen_basis {
        Some(b) => b,
        None => builder.build(chosen)?.to_persisted(),
    };
    let timing = time_runtime(&basis);
    Ok((
        FamilyReport {
            family: config.spec.family.name().into(),
            param_range: [config.spec.range.0, config.spec.range.1],
            grid: [
                config.grid.n_theta_i,
                config.grid.n_theta_o,
                config.grid.n_phi,
            ],
            grid_kind: config.grid_kind.name().into(),
            build_samples: config.param_samples,
            eval_set: eval.description.clone(),
            method: config.options.clone(),
            rows,
            setup_ms,
            eval_all_ns: timing.eval_all_ns,
            eval_local_ns: timing.eval_local_ns,
            coefficients_ns: timing.coefficients_ns,
            chosen: basis.num_bases,
        },
        basis,
    ))
}

/// Smallest `N_b` in the report whose error (max, or mean when `use_mean`) meets `target`.
pub fn select_count(report: &FamilyReport, target: f64, use_mean: bool) -> Option<usize> {
    report
        .rows
        .iter()
        .find(|r| {
            let e = if use_mean { r.ours.mean } else { r.ours.max };
            e <= target
        })
        .map(|r| r.num_bases)
}

/// Runtime costs of a basis (see [`time_runtime`]).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct RuntimeTiming {
    /// `eval_all`, ns per direction pair (all bases).
    pub eval_all_ns: f64,
    /// `eval_all_local`, ns per direction pair.
    pub eval_local_ns: f64,
    /// `coefficients_into`, ns per call.
    pub coefficients_ns: f64,
}

/// Measures `eval_all` and `eval_all_local` (ns per direction pair, 65536 random direction
/// pairs) and `coefficients` (ns per call) on a fixed pseudo-random workload; the minimum over
/// 24 rounds.
pub fn time_runtime(basis: &BrdfBasis) -> RuntimeTiming {
    let n = 1 << 16;
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let dirs: Vec<[f32; 3]> = (0..n)
        .map(|_| [next(), next(), next() * 2.0 - 1.0])
        .collect();
    // the same pairs as vectors: wi in the xz-plane, wo at azimuth acos(cos_phi)
    let vecs: Vec<([f32; 3], [f32; 3])> = dirs
        .iter()
        .map(|d| {
            let (ci, co, cp) = (d[0].max(1e-4), d[1].max(1e-4), d[2]);
            let si = (1.0 - ci * ci).max(0.0).sqrt();
            let so = (1.0 - co * co).max(0.0).sqrt();
            let sp = (1.0 - cp * cp).max(0.0).sqrt();
            ([si, 0.0, ci], [so * cp, so * sp, co])
        })
        .collect();
    let mut out = vec![0.0f32; basis.num_bases];
    let mut acc = 0.0f32;
    // the minimum over short rounds: robust to time slicing on a shared machine
    let rounds = 24;
    let mut eval_ns = f64::INFINITY;
    let mut local_ns = f64::INFINITY;
    for _ in 0..rounds {
        let t = Instant::now();
        for d in &dirs {
            basis.eval_all(d[0], d[1], d[2], &mut out);
            acc += out[basis.num_bases - 1];
        }
        eval_ns = eval_ns.min(t.elapsed().as_secs_f64() * 1e9 / n as f64);
        let t = Instant::now();
        for (wi, wo) in &vecs {
            basis.eval_all_local(*wi, *wo, &mut out);
            acc += out[basis.num_bases - 1];
        }
        local_ns = local_ns.min(t.elapsed().as_secs_f64() * 1e9 / n as f64);
    }
    let (lo, hi) = (basis.param_range[0], basis.param_range[1]);
    let params: Vec<f32> = (0..8192).map(|_| lo + (hi - lo) * next()).collect();
    let mut coeff_ns = f64::INFINITY;
    for _ in 0..rounds {
        let t = Instant::now();
        for &p in &params {
            basis.coefficients_into(p, &mut out);
            acc += out[0];
        }
        coeff_ns = coeff_ns.min(t.elapsed().as_secs_f64() * 1e9 / params.len() as f64);
    }
    std::hint::black_box(acc);
    RuntimeTiming {
        eval_all_ns: eval_ns,
        eval_local_ns: local_ns,
        coefficients_ns: coeff_ns,
    }
}

/// Plain-text table of a report.
pub fn format_table(r: &FamilyReport) -> String {
    let mut s = format!(
        "{} basis, {} in [{}, {}], grid {} {}x{}x{}, {} build samples; errors on {}\n\
         relative L2 error (cosine-weighted, %), ours vs the thesis' method (on the thesis grid); thesis-metric = uniform norm on the thesis grid\n",
        r.family,
        if r.family == "ggx" { "alpha" } else { "s" },
        r.param_range[0],
        r.param_range[1],
        r.grid_kind,
        r.grid[0],
        r.grid[1],
        r.grid[2],
        r.build_samples,
        r.eval_set
    );
    s += " N_b | ours mean  ours max (at p) | thesis mean  thesis max | thesis-metric: ours mean/max   thesis mean/max | min f cos | neg mass | build ms\n";
    for row in &r.rows {
        s += &format!(
            "{:>4} | {:>8.4}  {:>8.4} ({:>6.3}) | {:>10.4}  {:>10.4} | {:>10.4} / {:<8.4} {:>8.4} / {:<8.4} | {:>9.2e} | {:>8.2e} | {:>8.1}\n",
            row.num_bases,
            100.0 * row.ours.mean,
            100.0 * row.ours.max,
            row.ours.max_at,
            100.0 * row.thesis_cosine_metric.mean,
            100.0 * row.thesis_cosine_metric.max,
            100.0 * row.ours_uniform_metric.mean,
            100.0 * row.ours_uniform_metric.max,
            100.0 * row.thesis.mean,
            100.0 * row.thesis.max,
            row.negativity.min_rel,
            row.negativity.neg_mass,
            row.build_ms
        );
    }
    s += &format!(
        "setup (tabulate + QR) {:.0} ms; runtime eval_all {:.1} ns/call, eval_all_local {:.1} ns/call ({} bases), coefficients {:.1} ns/call\n",
        r.setup_ms, r.eval_all_ns, r.eval_local_ns, r.chosen, r.coefficients_ns
    );
    s
}

/// End-to-end error of one lobe against the exact formula, off the grid (see
/// [`continuous_error`]).
#[derive(Clone, Debug, Serialize)]
pub struct ContinuousError {
    pub param: f64,
    /// Whether the parameter was outside the basis range (clamped).
    pub clamped: bool,
    /// Basis + runtime interpolation (`coefficients` then `eval_all_local`) vs the exact lobe.
    pub basis: f64,
    /// Trilinear interpolation of the lobe's own exact table on the basis' grid (no PCA): the
    /// grid's share.
    pub grid_only: f64,
    /// Standard errors of the two estimates (from 32 independent batches).
    pub basis_stderr: f64,
    pub grid_only_stderr: f64,
    /// Direction pairs sampled.
    pub samples: usize,
    /// Whether all reconstructed values were finite.
    pub finite: bool,
    /// Largest error of the directional albedo `a(wo) = ∫ f cos_i dwi` over the view angles
    /// [`ALBEDO_THETAS_DEG`], relative to the largest exact albedo over those angles (see
    /// [`albedo_errors`]; Blinn-Phong's albedo falls to a few percent of its peak at grazing
    /// views, so errors relative to each angle's own albedo would overstate what a renderer
    /// shows there): basis + runtime, and grid alone.
    pub albedo_max: f64,
    pub albedo_grid_max: f64,
}

/// View angles (degrees from the normal) of the albedo check.
pub const ALBEDO_THETAS_DEG: [f64; 5] = [0.0, 30.0, 60.0, 80.0, 88.0];

/// Pairs per view angle of the albedo check.
pub const ALBEDO_SAMPLES: usize = 1 << 18;

/// Directional albedo of the exact lobe and of two reconstructions at one view angle.
#[derive(Clone, Debug, Serialize)]
pub struct AlbedoError {
    pub theta_o_deg: f64,
    pub exact: f64,
    /// Basis + runtime (`coefficients`, `eval_all_local`).
    pub basis: f64,
    /// The lobe's own table on the basis' grid.
    pub grid_only: f64,
}

/// Direction pairs [`continuous_error`] samples.
pub const CONTINUOUS_SAMPLES: usize = 1 << 20;

/// [`continuous_error_n`] with [`CONTINUOUS_SAMPLES`] pairs.
pub fn continuous_error(basis: &BrdfBasis, family: Family, param: f64) -> ContinuousError {
    continuous_error_n(basis, family, param, CONTINUOUS_SAMPLES)
}

/// Cosine-weighted relative L2 error, against the exact f64 lobe, of the runtime
/// reconstruction of lobe `param` (`coefficients`, then `eval_all_local`) and of the
/// interpolated exact table of the lobe on the basis' grid:
///
/// `e = sqrt( E[(f - g)^2 w] / E[f^2 w] )`, `w = cos_i cos_o / p(wo, wi)`
///
/// estimated by Monte Carlo over the pair of hemispheres with `samples` pairs drawn
/// independently of any grid: `wo` cosine-weighted, `wi` from the mixture (1/2 each) of the
/// cosine-weighted hemisphere and the lobe's own half-vector sampling about `wo` (Blinn-Phong:
/// `p(h) = (s+1)/(2 pi) cos^s(theta_h)`, GGX: `p(h) = D(h) cos(theta_h)`,
/// `p(wi) = p(h) / (4 wo.h)`), so both the peak and the rest of the hemisphere are covered
/// whatever the grid. Pairs come from 32 fixed-seed batches computed in parallel and summed in
/// order, so the result is deterministic.
pub fn continuous_error_n(
    basis: &BrdfBasis,
    family: Family,
    param: f64,
    samples: usize,
) -> ContinuousError {
    const BATCHES: usize = 32;
    let g = basis.grid_spec();
    let (c, clamped) = basis.coefficients(param as f32);
    let own_table: Vec<f32> = super::grid::tabulate_one(family, &g, param)
        .iter()
        .map(|&v| v as f32)
        .collect();
    let own = BrdfBasis {
        num_bases: 1,
        tables: own_table,
        coefficients: vec![1.0],
        param_samples: vec![param as f32],
        ..basis.clone()
    };
    let per = samples.div_ceil(BATCHES).max(1);
    // (num basis, num grid, den, finite)
    let batches: Vec<(f64, f64, f64, bool)> = (0..BATCHES)
        .into_par_iter()
        .map(|b| {
            let mut rng =
                Xorshift(0x9E37_79B9_7F4A_7C15 ^ ((b as u64 + 1) * 0xD1B5_4A32_D192_ED03));
            let mut out = vec![0.0f32; basis.num_bases];
            let mut one = [0.0f32];
            let (mut nb, mut ng, mut den) = (0.0, 0.0, 0.0);
            let mut finite = true;
            for _ in 0..per {
                let wo = cosine_dir(rng.next(), rng.next());
                let (u0, u1, u2) = (rng.next(), rng.next(), rng.next());
                let wi = if u0 < 0.5 {
                    cosine_dir(u1, u2)
                } else {
                    let h = sample_half(family, param, u1, u2);
                    let d = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
                    [
                        2.0 * d * h[0] - wo[0],
                        2.0 * d * h[1] - wo[1],
                        2.0 * d * h[2] - wo[2],
                    ]
                };
                if wi[2] <= 0.0 || wo[2] <= 0.0 {
                    continue;
                }
                let p_lobe = lobe_pdf(family, param, wi, wo);
                let p = 0.5 * wi[2] / std::f64::consts::PI + 0.5 * p_lobe;
                // p(wo) = cos_o / pi, so w = cos_i cos_o / (p(wo) p(wi)) = pi cos_i / p(wi)
                let w = std::f64::consts::PI * wi[2] / p;
                let f = lobe_vectors(family, param, wi, wo);
                let (wi32, wo32) = (to_f32(wi), to_f32(wo));
                basis.eval_all_local(wi32, wo32, &mut out);
                let rb: f64 = out.iter().zip(&c).map(|(a, b)| *a as f64 * *b as f64).sum();
                own.eval_all_local(wi32, wo32, &mut one);
                let rg = one[0] as f64;
                finite &= rb.is_finite() && rg.is_finite();
                nb += w * (rb - f) * (rb - f);
                ng += w * (rg - f) * (rg - f);
                den += w * f * f;
            }
            (nb, ng, den, finite)
        })
        .collect();
    let (mut nb, mut ng, mut den) = (0.0, 0.0, 0.0);
    for x in &batches {
        nb += x.0;
        ng += x.1;
        den += x.2;
    }
    let rel = |n: f64, d: f64| if d > 0.0 { (n / d).sqrt() } else { 0.0 };
    let stderr = |pick: fn(&(f64, f64, f64, bool)) -> f64| {
        let e: Vec<f64> = batches.iter().map(|x| rel(pick(x), x.2)).collect();
        let m = e.iter().sum::<f64>() / e.len() as f64;
        let var = e.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (e.len() - 1) as f64;
        (var / e.len() as f64).sqrt()
    };
    let albedo = albedo_errors(basis, &own, &c, family, param, ALBEDO_SAMPLES);
    let top = albedo.iter().map(|x| x.exact).fold(0.0, f64::max);
    let worst = |pick: fn(&AlbedoError) -> f64| {
        if top > 0.0 {
            albedo
                .iter()
                .map(|x| (pick(x) - x.exact).abs() / top)
                .fold(0.0, f64::max)
        } else {
            0.0
        }
    };
    ContinuousError {
        albedo_max: worst(|x| x.basis),
        albedo_grid_max: worst(|x| x.grid_only),
        param,
        clamped,
        basis: rel(nb, den),
        grid_only: rel(ng, den),
        basis_stderr: stderr(|x| x.0),
        grid_only_stderr: stderr(|x| x.1),
        samples: per * BATCHES,
        finite: batches.iter().all(|x| x.3),
    }
}

/// Directional albedo `a(wo) = ∫ f(wi, wo) cos_i dwi` of the exact lobe, of the runtime
/// reconstruction from `basis` with coefficients `c`, and of the one-basis table `own`, at the
/// view angles [`ALBEDO_THETAS_DEG`]: Monte Carlo with `samples` directions `wi` per angle from
/// the even mixture of cosine-weighted and lobe sampling (as [`continuous_error_n`]), the same
/// directions for all three, fixed seeds. The albedo is what a glossy surface under uniform
/// light shows, and unlike the L2 error it is not dominated by the lobe's peak: a broad error
/// of small amplitude next to a sharp peak moves it a lot.
pub fn albedo_errors(
    basis: &BrdfBasis,
    own: &BrdfBasis,
    c: &[f32],
    family: Family,
    param: f64,
    samples: usize,
) -> Vec<AlbedoError> {
    ALBEDO_THETAS_DEG
        .par_iter()
        .enumerate()
        .map(|(j, &deg)| {
            let t = deg.to_radians();
            let wo = [t.sin(), 0.0, t.cos()];
            let mut rng =
                Xorshift(0x2545_F491_4F6C_DD1D ^ ((j as u64 + 1) * 0x9E37_79B9_7F4A_7C15));
            let mut out = vec![0.0f32; basis.num_bases];
            let mut one = [0.0f32];
            let (mut ex, mut rb, mut rg) = (0.0, 0.0, 0.0);
            for _ in 0..samples {
                let (u0, u1, u2) = (rng.next(), rng.next(), rng.next());
                let wi = if u0 < 0.5 {
                    cosine_dir(u1, u2)
                } else {
                    let h = sample_half(family, param, u1, u2);
                    let d = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
                    [
                        2.0 * d * h[0] - wo[0],
                        2.0 * d * h[1] - wo[1],
                        2.0 * d * h[2] - wo[2],
                    ]
                };
                if wi[2] <= 0.0 {
                    continue;
                }
                let p = 0.5 * wi[2] / std::f64::consts::PI + 0.5 * lobe_pdf(family, param, wi, wo);
                let w = wi[2] / p;
                let (wi32, wo32) = (to_f32(wi), to_f32(wo));
                basis.eval_all_local(wi32, wo32, &mut out);
                own.eval_all_local(wi32, wo32, &mut one);
                ex += w * lobe_vectors(family, param, wi, wo);
                rb += w * out
                    .iter()
                    .zip(c)
                    .map(|(a, b)| *a as f64 * *b as f64)
                    .sum::<f64>();
                rg += w * one[0] as f64;
            }
            let n = samples.max(1) as f64;
            AlbedoError {
                theta_o_deg: deg,
                exact: ex / n,
                basis: rb / n,
                grid_only: rg / n,
            }
        })
        .collect()
}

struct Xorshift(u64);

impl Xorshift {
    /// Uniform in [0, 1).
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn to_f32(v: [f64; 3]) -> [f32; 3] {
    [v[0] as f32, v[1] as f32, v[2] as f32]
}

/// Cosine-weighted direction on the +Z hemisphere.
fn cosine_dir(u1: f64, u2: f64) -> [f64; 3] {
    let r = u1.sqrt();
    let ph = 2.0 * std::f64::consts::PI * u2;
    [r * ph.cos(), r * ph.sin(), (1.0 - u1).max(0.0).sqrt()]
}

/// Half vector with the lobe's density (see [`continuous_error_n`]).
fn sample_half(family: Family, p: f64, u1: f64, u2: f64) -> [f64; 3] {
    let ct = match family {
        Family::Ggx => {
            let a2 = p * p;
            ((1.0 - u1) / (1.0 + (a2 - 1.0) * u1))
                .clamp(0.0, 1.0)
                .sqrt()
        }
        _ => u1.max(1e-300).powf(1.0 / (p.max(0.0) + 1.0)),
    };
    let st = (1.0 - ct * ct).max(0.0).sqrt();
    let ph = 2.0 * std::f64::consts::PI * u2;
    [st * ph.cos(), st * ph.sin(), ct]
}

/// Density over `wi` (solid angle) of reflecting `wo` about a half vector from
/// [`sample_half`].
fn lobe_pdf(family: Family, p: f64, wi: [f64; 3], wo: [f64; 3]) -> f64 {
    let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let l = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    if l <= 1e-300 {
        return 0.0;
    }
    let ct = (h[2] / l).clamp(0.0, 1.0);
    let woh = (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]) / l;
    if woh <= 0.0 {
        return 0.0;
    }
    let ph = match family {
        Family::Ggx => {
            let a2 = p * p;
            let c2 = ct * ct;
            let den = a2 * c2 + (1.0 - c2).max(0.0);
            if den <= 0.0 {
                return 0.0;
            }
            a2 / (std::f64::consts::PI * den * den) * ct
        }
        _ => {
            let s = p.max(0.0);
            (s + 1.0) / (2.0 * std::f64::consts::PI) * (s * ct.max(1e-300).ln()).exp()
        }
    };
    ph / (4.0 * woh)
}
