//! The error tables of `bench basis` (docs/brdf-basis.md): relative L2 reconstruction error of
//! every sampled lobe for each `N_b`, ours against the thesis' method and under several
//! metrics, and the runtime's evaluation cost.

use prt_bake::basis::grid::{cosine_weights, node_cos_i, uniform_weights};
use prt_bake::basis::pca::{PcaBuilder, PcaModel, PcaOptions};
use prt_bake::basis::select::{measure, persisted_recon, ErrStats, EvalSet, Negativity};
use prt_bake::basis::{BasisBuilder, BasisConfig, BasisError, BuiltBasis};
use prt_formats::basis::{BrdfBasis, GridSpec};
use prt_formats::Family;
use serde::Serialize;
use std::time::Instant;

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
    pub family: Family,
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
) -> Result<(FamilyReport, BrdfBasis), BasisError> {
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
            family: config.spec.family,
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
        if r.family == Family::Ggx { "alpha" } else { "s" },
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
