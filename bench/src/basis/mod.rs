//! `bench basis ...`: builds a family's PCA basis, prints its error table (text or `--json`),
//! optionally writes the basis, runs the Tucker grid, or regenerates docs/brdf-basis.md.

pub mod continuous;
pub mod docgen;
pub mod report;

use anyhow::{anyhow, bail, Context, Result};
use continuous::ContinuousError;
use prt_bake::basis::pca::PcaOptions;
use prt_bake::basis::tucker::{self, HemiGrid, TuckerReport};
use prt_bake::basis::{BasisConfig, FamilySpec};
use prt_bake::brdf::Family;
use prt_formats::basis::{AngularGrid, GridKind, GridSpec};
use report::FamilyReport;
use std::path::PathBuf;

/// Arguments of `bench basis`.
#[derive(clap::Args, Debug, Clone)]
pub struct BasisArgs {
    /// BRDF family: blinn-phong or ggx.
    #[arg(long, default_value = "blinn-phong")]
    pub family: String,
    /// Number of bases N_b (Lambert basis included) of the basis to build and time.
    #[arg(long, default_value_t = 6)]
    pub count: usize,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Smallest N_b in the error table.
    #[arg(long, default_value_t = 2)]
    pub min_count: usize,
    /// Largest N_b in the error table.
    #[arg(long, default_value_t = 12)]
    pub max_count: usize,
    /// Parameter range "lo,hi" (default: s in 1,200 for blinn-phong; alpha in 0.02,1 for ggx).
    #[arg(long)]
    pub range: Option<String>,
    /// Table grid sizes "n1 x n2 x n3" along the grid kind's axes (default: 96x64x8 for
    /// half-diff, the thesis' 30x30x60 for angles).
    #[arg(long)]
    pub grid: Option<String>,
    /// Table grid: half-diff (theta_h, theta_d, phi_d, graded; default) or angles (the
    /// thesis' uniform theta_i, theta_o, phi; default with --thesis-method).
    #[arg(long)]
    pub grid_kind: Option<String>,
    /// Lobes sampled (uniformly in the warped parameter) to build the basis.
    #[arg(long, default_value_t = 256)]
    pub samples: usize,
    /// Lobes (uniform in the parameter) the errors are measured on (thesis: 200).
    #[arg(long, default_value_t = 200)]
    pub eval_samples: usize,
    /// Build with the thesis' method instead of ours (for comparison).
    #[arg(long)]
    pub thesis_method: bool,
    /// Pick the smallest N_b whose max relative error (mean with --target-mean) is at most
    /// this value (e.g. 0.01 for 1 %); overrides --count.
    #[arg(long)]
    pub target: Option<f64>,
    /// Apply --target to the mean error instead of the max.
    #[arg(long)]
    pub target_mean: bool,
    /// Write the chosen basis (prt_formats::basis::BrdfBasis) as JSON to this file.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also run the Tucker error grid (thesis figure 5-5).
    #[arg(long)]
    pub tucker: bool,
    /// Hemisphere direction grid of the Tucker tensor "n_theta x n_phi".
    #[arg(long, default_value = "8x32")]
    pub tucker_dirs: String,
    /// Parameter samples of the Tucker tensor.
    #[arg(long, default_value_t = 32)]
    pub tucker_samples: usize,
    /// Regenerate the report (markdown, both families, Tucker grids, SVG plots in an `img/`
    /// folder beside it), e.g. docs/brdf-basis.md.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

fn parse_grid(s: &str) -> Result<AngularGrid> {
    let v: Vec<usize> = s
        .split(['x', 'X'])
        .map(|t| t.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("bad --grid {s:?}, expected e.g. 30x30x60"))?;
    if v.len() != 3 {
        bail!("bad --grid {s:?}, expected three sizes like 30x30x60");
    }
    let g = AngularGrid {
        n_theta_i: v[0],
        n_theta_o: v[1],
        n_phi: v[2],
    };
    g.validate().map_err(|e| anyhow!("{e}"))?;
    if g.len() > 4_000_000 {
        bail!(
            "--grid {s} has {} nodes; at most 4,000,000 are supported",
            g.len()
        );
    }
    Ok(g)
}

fn parse_dirs(s: &str) -> Result<HemiGrid> {
    let v: Vec<usize> = s
        .split(['x', 'X'])
        .map(|t| t.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("bad --tucker-dirs {s:?}, expected e.g. 8x32"))?;
    if v.len() != 2 || v[0] == 0 || v[1] == 0 || v[0] * v[1] > 2048 {
        bail!("bad --tucker-dirs {s:?}: two positive sizes, at most 2048 directions");
    }
    Ok(HemiGrid {
        n_theta: v[0],
        n_phi: v[1],
    })
}

/// Builds the configuration from the arguments.
pub fn config_from_args(args: &BasisArgs) -> Result<BasisConfig> {
    let family = Family::parse(&args.family)
        .ok_or_else(|| anyhow!("unknown family {:?} (blinn-phong or ggx)", args.family))?;
    let mut cfg = BasisConfig::new(family, args.count)?;
    if let Some(r) = &args.range {
        let v: Vec<f64> = r
            .split(',')
            .map(|t| t.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("bad --range {r:?}, expected lo,hi"))?;
        if v.len() != 2 {
            bail!("bad --range {r:?}, expected lo,hi");
        }
        cfg.spec = cfg.spec.with_range(v[0], v[1])?;
    }
    let kind = match args.grid_kind.as_deref() {
        None if args.thesis_method => GridKind::Angles,
        None | Some("half-diff") => GridKind::HalfDiff,
        Some("angles") => GridKind::Angles,
        Some(k) => bail!("unknown --grid-kind {k:?} (half-diff or angles)"),
    };
    let dims = match &args.grid {
        Some(g) => parse_grid(g)?,
        None if kind == GridKind::Angles => AngularGrid::THESIS,
        None => GridSpec::DEFAULT.dims,
    };
    cfg = cfg.with_grid(GridSpec::new(kind, dims));
    if args.samples < 2 || args.samples > 4096 {
        bail!("--samples must be in 2..=4096");
    }
    cfg.param_samples = args.samples;
    if args.thesis_method {
        cfg.options = PcaOptions::thesis();
    }
    if args.count == 0
        || args.min_count == 0
        || args.min_count > args.max_count
        || args.max_count > 64
    {
        bail!("need 1 <= --min-count <= --max-count <= 64 and --count >= 1");
    }
    if args.eval_samples < 2 || args.eval_samples > 4096 {
        bail!("--eval-samples must be in 2..=4096");
    }
    Ok(cfg)
}

/// Entry point of `bench basis`.
pub fn run(args: &BasisArgs) -> Result<()> {
    if let Some(path) = &args.report {
        return docgen::write_report(path, args).map(|_| ());
    }
    let cfg = config_from_args(args)?;
    let counts: Vec<usize> = (args.min_count..=args.max_count).collect();
    let (mut rep, mut basis) = report::family_report(&cfg, &counts, args.count, args.eval_samples)?;
    let mut selected = None;
    if let Some(t) = args.target {
        if t.is_nan() || t <= 0.0 {
            bail!("--target must be a positive relative error, e.g. 0.01");
        }
        match report::select_count(&rep, t, args.target_mean) {
            Some(nb) => {
                selected = Some(nb);
                if nb != args.count {
                    let mut a = args.clone();
                    a.count = nb;
                    let c = config_from_args(&a)?;
                    let r = report::family_report(&c, &[nb], nb, args.eval_samples)?;
                    basis = r.1;
                    rep.chosen = nb;
                    rep.eval_all_ns = r.0.eval_all_ns;
                    rep.coefficients_ns = r.0.coefficients_ns;
                }
            }
            None => eprintln!(
                "warning: no N_b in {}..={} meets the target {t}; keeping --count {}",
                args.min_count, args.max_count, args.count
            ),
        }
    }
    let tk = if args.tucker {
        Some(run_tucker(&cfg.spec, args)?)
    } else {
        None
    };
    let sharp = sharp_checks(&cfg.spec, &basis);
    if let Some(out) = &args.out {
        let s = serde_json::to_string(&basis)?;
        std::fs::write(out, s).with_context(|| format!("cannot write {}", out.display()))?;
    }
    if args.json {
        let v = serde_json::json!({
            "report": rep,
            "selected_by_target": selected,
            "sharp_lobes": sharp,
            "tucker": tk,
        });
        println!("{}", serde_json::to_string(&v)?);
    } else {
        print!("{}", report::format_table(&rep));
        if let Some(nb) = selected {
            println!("target met by N_b = {nb}");
        }
        println!(
            "end-to-end error vs the exact lobe, off-grid (N_b = {}, {} Monte Carlo pairs):",
            basis.num_bases,
            sharp.first().map_or(0, |c| c.samples)
        );
        for c in &sharp {
            println!(
                "  p = {:>8}: basis {:>8.3} % (+- {:.3}), grid alone {:>8.3} % (+- {:.3}); albedo max error: basis {:.2} %, grid alone {:.2} %{}{}",
                c.param,
                100.0 * c.basis,
                100.0 * c.basis_stderr,
                100.0 * c.grid_only,
                100.0 * c.grid_only_stderr,
                100.0 * c.albedo_max,
                100.0 * c.albedo_grid_max,
                if c.clamped {
                    " (outside range: clamped)"
                } else {
                    ""
                },
                if c.finite { "" } else { " NON-FINITE" }
            );
        }
        if let Some(t) = &tk {
            print!("{}", format_tucker(t));
        }
    }
    Ok(())
}

/// End-to-end checks on a few lobes including very sharp ones outside the range.
pub fn sharp_checks(
    spec: &FamilySpec,
    basis: &prt_formats::basis::BrdfBasis,
) -> Vec<ContinuousError> {
    let params: Vec<f64> = match spec.family {
        Family::BlinnPhong => vec![1.0, 10.0, 50.0, 100.0, 200.0, 2000.0],
        Family::Ggx => vec![1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01],
        Family::Diffuse => vec![],
    };
    params
        .into_iter()
        .map(|p| continuous::continuous_error(basis, spec.family, p))
        .collect()
}

/// The Tucker grid n_h in 1..=6, n_o = n_i in 4, 8, .., 32.
pub fn run_tucker(spec: &FamilySpec, args: &BasisArgs) -> Result<TuckerReport> {
    let dirs = parse_dirs(&args.tucker_dirs)?;
    if args.tucker_samples < 2 || args.tucker_samples > 512 {
        bail!("--tucker-samples must be in 2..=512");
    }
    let nd: Vec<usize> = (1..=8).map(|k| 4 * k).collect();
    Ok(tucker::tucker_report(
        *spec,
        args.tucker_samples,
        dirs,
        &[1, 2, 3, 4, 5, 6],
        &nd,
    )?)
}

/// Text table of a Tucker report (rows n_h, columns n_o = n_i).
pub fn format_tucker(t: &TuckerReport) -> String {
    let mut nds: Vec<usize> = t.cells.iter().map(|c| c.n_dir).collect();
    nds.dedup();
    nds.sort_unstable();
    nds.dedup();
    let mut nhs: Vec<usize> = t.cells.iter().map(|c| c.n_h).collect();
    nhs.sort_unstable();
    nhs.dedup();
    let mut s = format!(
        "Tucker relative error, {} family, {} lobes, {}x{} directions; plain / with specular split (||S||/||F|| = {:.3})\n n_h \\ n_o=n_i |",
        t.family, t.param_samples, t.dirs.n_theta, t.dirs.n_phi, t.specular_fraction
    );
    for nd in &nds {
        s += &format!(" {nd:>13} |");
    }
    s += "\n";
    for nh in &nhs {
        s += &format!(" {nh:>13} |");
        for nd in &nds {
            if let Some(c) = t.cells.iter().find(|c| c.n_h == *nh && c.n_dir == *nd) {
                s += &format!(" {:.4}/{:.4} |", c.plain, c.split);
            }
        }
        s += "\n";
    }
    s += &format!("({:.1} s)\n", t.elapsed_ms / 1e3);
    s
}

/// Helper for docgen: a report per family with the CLI's settings.
pub fn family_reports(
    args: &BasisArgs,
) -> Result<Vec<(FamilyReport, prt_formats::basis::BrdfBasis, BasisConfig)>> {
    let mut out = Vec::new();
    for fam in ["blinn-phong", "ggx"] {
        let mut a = args.clone();
        a.family = fam.into();
        a.range = None;
        let cfg = config_from_args(&a)?;
        let counts: Vec<usize> = (a.min_count..=a.max_count).collect();
        let (r, b) = report::family_report(&cfg, &counts, a.count, a.eval_samples)?;
        out.push((r, b, cfg));
    }
    Ok(out)
}
