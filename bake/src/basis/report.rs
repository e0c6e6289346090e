//! Error measurement of PCA bases (docs/brdf-basis.md): relative L2 reconstruction error of
//! every sampled lobe, for `N_b = 2..12`, ours against the thesis' method.

use super::grid::{cosine_weights, tabulate, uniform_weights};
use super::pca::{rel_err_w, PcaBuilder, PcaModel, PcaOptions};
use super::{BasisBuilder, BasisConfig, BuiltBasis, FamilySpec};
use faer::Mat;
use prt_formats::basis::{AngularGrid, BrdfBasis};
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
    pub fn thesis(spec: &FamilySpec, grid: &AngularGrid, count: usize) -> EvalSet {
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

/// Errors of reconstructions `recon(j)` of the evaluation lobes under weights `w`; also the
/// negativity of the reconstructions (measured with the cosine weights `wc`).
fn measure(
    eval: &EvalSet,
    grid: &AngularGrid,
    w: &[f64],
    wc: &[f64],
    recon: impl Fn(usize) -> Vec<f64>,
) -> (ErrStats, Negativity) {
    let mut errs = Vec::with_capacity(eval.params.len());
    let (mut num, mut den) = (0.0, 0.0);
    let mut neg = Negativity::default();
    let cos_i: Vec<f64> = (0..grid.n_theta_i)
        .map(|i| AngularGrid::theta(grid.n_theta_i, i).cos().max(0.0))
        .collect();
    let per_i = grid.n_theta_o * grid.n_phi;
    for j in 0..eval.params.len() {
        let l = eval.lobes.col_as_slice(j);
        let r = recon(j);
        errs.push(rel_err_w(w, l, &r));
        let peak = (0..l.len())
            .map(|n| l[n] * cos_i[n / per_i])
            .fold(0.0, f64::max);
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
                let v = r[n] * cos_i[n / per_i] / peak;
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
    /// Ours, measured with the thesis' metric (uniform grid norm).
    pub ours_uniform_metric: ErrStats,
    /// The thesis' method (raw lobes, uniform norm, PCA of the evaluation lobes themselves),
    /// measured with its own metric.
    pub thesis: ErrStats,
    /// The thesis' method measured with our cosine-weighted metric.
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
    pub build_samples: usize,
    pub eval_set: String,
    pub method: PcaOptions,
    pub rows: Vec<NbRow>,
    /// Tabulating the build lobes and factoring them (ms).
    pub setup_ms: f64,
    /// Runtime `eval_all` cost (ns per direction pair, all bases) for the `chosen` basis.
    pub eval_all_ns: f64,
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
    let eval = EvalSet::thesis(&config.spec, &config.grid, eval_count);
    let thesis = PcaBuilder::new(eval.lobes.as_ref(), config.grid, PcaOptions::thesis())?;
    let wc = cosine_weights(&config.grid);
    let wu = uniform_weights(&config.grid);
    let mut rows = Vec::new();
    let mut chosen_basis = None;
    for &nb in counts {
        let t = Instant::now();
        let built: BuiltBasis = builder.build(nb)?;
        let build_ms = t.elapsed().as_secs_f64() * 1e3;
        let persisted = built.to_persisted();
        let g = &config.grid;
        let pr = |j: usize| persisted_recon(&persisted, eval.params[j]);
        let (ours, negativity) = measure(&eval, g, &wc, &wc, pr);
        let (ours_uniform_metric, _) = measure(&eval, g, &wu, &wc, pr);
        let (ours_projected, _) = measure(&eval, g, &wc, &wc, |j| {
            projected_recon(&built.model, eval.lobes.col_as_slice(j))
        });
        let tm = thesis.build(nb)?;
        let tr = |j: usize| projected_recon(&tm, eval.lobes.col_as_slice(j));
        let (th, _) = measure(&eval, g, &wu, &wc, tr);
        let (thc, _) = measure(&eval, g, &wc, &wc, tr);
        rows.push(NbRow {
            num_bases: nb,
            ours,
            ours_projected,
            ours_uniform_metric,
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
    let (eval_all_ns, coefficients_ns) = time_runtime(&basis);
    Ok((
        FamilyReport {
            family: config.spec.family.name().into(),
            param_range: [config.spec.range.0, config.spec.range.1],
            grid: [
                config.grid.n_theta_i,
                config.grid.n_theta_o,
                config.grid.n_phi,
            ],
            build_samples: config.param_samples,
            eval_set: eval.description.clone(),
            method: config.options.clone(),
            rows,
            setup_ms,
            eval_all_ns,
            coefficients_ns,
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

/// Measures `eval_all` (ns per direction pair, 65536 random direction pairs) and
/// `coefficients` (ns per call) on a fixed pseudo-random workload; the minimum over 24 rounds.
pub fn time_runtime(basis: &BrdfBasis) -> (f64, f64) {
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
    let mut out = vec![0.0f32; basis.num_bases];
    let mut acc = 0.0f32;
    // the minimum over short rounds: robust to time slicing on a shared machine
    let rounds = 24;
    let mut eval_ns = f64::INFINITY;
    for _ in 0..rounds {
        let t = Instant::now();
        for d in &dirs {
            basis.eval_all(d[0], d[1], d[2], &mut out);
            acc += out[basis.num_bases - 1];
        }
        eval_ns = eval_ns.min(t.elapsed().as_secs_f64() * 1e9 / n as f64);
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
    (eval_ns, coeff_ns)
}

/// Plain-text table of a report.
pub fn format_table(r: &FamilyReport) -> String {
    let mut s = format!(
        "{} basis, {} in [{}, {}], grid {}x{}x{}, {} build samples; errors on {}\n\
         relative L2 error (cosine-weighted, %), ours vs the thesis' method; thesis-metric = uniform grid norm\n",
        r.family,
        if r.family == "ggx" { "alpha" } else { "s" },
        r.param_range[0],
        r.param_range[1],
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
        "setup (tabulate + QR) {:.0} ms; runtime eval_all {:.1} ns/call ({} bases), coefficients {:.1} ns/call\n",
        r.setup_ms, r.eval_all_ns, r.chosen, r.coefficients_ns
    );
    s
}

/// End-to-end error of one lobe against the exact formula, off the grid.
#[derive(Clone, Debug, Serialize)]
pub struct ContinuousError {
    pub param: f64,
    /// Whether the parameter was outside the basis range (clamped).
    pub clamped: bool,
    /// Basis + runtime interpolation (`coefficients` then `eval_all`) vs the exact lobe.
    pub basis: f64,
    /// Trilinear interpolation of the lobe's own exact table (no PCA): the grid's share.
    pub grid_only: f64,
    /// Whether all reconstructed values were finite.
    pub finite: bool,
}

/// Cosine-weighted relative L2 error of the runtime reconstruction of lobe `param` against the
/// exact f64 lobe, by midpoint quadrature on a `2 n_theta x 2 n_theta x 2 n_phi` grid of
/// cell centres (points between the table's nodes).
pub fn continuous_error(
    basis: &BrdfBasis,
    family: crate::brdf::Family,
    param: f64,
) -> ContinuousError {
    use std::f64::consts::{FRAC_PI_2, PI};
    let g = basis.grid;
    let (nt_i, nt_o, np) = (2 * g.n_theta_i, 2 * g.n_theta_o, 2 * g.n_phi);
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
    let mut out = vec![0.0f32; basis.num_bases];
    let mut one = [0.0f32];
    let (mut num_b, mut num_g, mut den) = (0.0, 0.0, 0.0);
    let mut finite = true;
    for i in 0..nt_i {
        let ti = (i as f64 + 0.5) * FRAC_PI_2 / nt_i as f64;
        for o in 0..nt_o {
            let to = (o as f64 + 0.5) * FRAC_PI_2 / nt_o as f64;
            let w_io = ti.sin() * ti.cos() * to.sin() * to.cos();
            for k in 0..np {
                let ph = (k as f64 + 0.5) * PI / np as f64;
                let exact = super::grid::lobe_f64(family, param, ti, to, ph);
                let (ci, co, cp) = (ti.cos() as f32, to.cos() as f32, ph.cos() as f32);
                basis.eval_all(ci, co, cp, &mut out);
                let rb: f64 = out.iter().zip(&c).map(|(a, b)| *a as f64 * *b as f64).sum();
                own.eval_all(ci, co, cp, &mut one);
                let rg = one[0] as f64;
                finite &= rb.is_finite() && rg.is_finite();
                num_b += w_io * (rb - exact).powi(2);
                num_g += w_io * (rg - exact).powi(2);
                den += w_io * exact * exact;
            }
        }
    }
    let rel = |n: f64| if den > 0.0 { (n / den).sqrt() } else { 0.0 };
    ContinuousError {
        param,
        clamped,
        basis: rel(num_b),
        grid_only: rel(num_g),
        finite,
    }
}
