//! Regenerates docs/brdf-basis.md (text, tables, Tucker grids) and its SVG plots: the text is
//! `bench/templates/brdf-basis*.md`, filled with the run's figures.

use super::continuous::ContinuousError;
use super::report::{format_table, time_runtime, FamilyReport, NbRow};
use super::{family_reports, format_tucker, run_tucker, sharp_checks, BasisArgs};
use crate::plot::{Legend, LinePlot, Series};
use crate::template::{render, render_section};
use anyhow::{Context, Result};
use prt_bake::basis::tucker::TuckerReport;
use prt_bake::basis::BasisBuilder;
use prt_formats::basis::{BrdfBasis, GridSpec};
use prt_formats::Family;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The command that regenerates docs/brdf-basis.md (run from the repository root).
pub const REGENERATE: &str =
    "cargo run --release -p prt-bench -- basis --report docs/brdf-basis.md";

const TEMPLATE: &str = include_str!("../../templates/brdf-basis.md");
const FAMILY: &str = include_str!("../../templates/brdf-basis-family.md");

fn pct(x: f64) -> String {
    format!("{:.3}", 100.0 * x)
}

fn error_plot(r: &FamilyReport, path: &Path) -> Result<()> {
    let mut p = LinePlot::new(
        format!("{} basis: relative L2 error vs N_b", r.family),
        "N_b (bases, Lambert included)",
        "relative L2 error",
    );
    p.log_y = true;
    let pts = |f: &dyn Fn(&NbRow) -> f64| -> Vec<(f64, f64)> {
        r.rows
            .iter()
            .map(|row| (row.num_bases as f64, f(row)))
            .collect()
    };
    p.series
        .push(Series::new("ours mean", pts(&|x| x.ours.mean)).color([0, 114, 178]));
    p.series.push(
        Series::new("ours max", pts(&|x| x.ours.max))
            .color([0, 114, 178])
            .dashed(),
    );
    p.series.push(
        Series::new("thesis method mean", pts(&|x| x.thesis_cosine_metric.mean))
            .color([213, 94, 0]),
    );
    p.series.push(
        Series::new("thesis method max", pts(&|x| x.thesis_cosine_metric.max))
            .color([213, 94, 0])
            .dashed(),
    );
    if r.family == Family::BlinnPhong {
        let mut s = Series::new("thesis paper, N_b=6", vec![(6.0, 0.007979), (6.0, 0.06747)])
            .color([0, 0, 0]);
        s.dashed = true;
        p.series.push(s);
    }
    p.write_svg(path)
}

fn tucker_plot(t: &TuckerReport, path: &Path) -> Result<()> {
    let mut p = LinePlot::new(
        format!("{} Tucker error (solid: specular split)", t.family),
        "n_o = n_i",
        "relative error",
    );
    p.log_y = true;
    p.legend = Legend::MiddleLeft;
    let colors = [[0, 114, 178], [213, 94, 0], [0, 158, 115]];
    for (ci, nh) in [1usize, 3, 6].iter().enumerate() {
        let plain: Vec<(f64, f64)> = t
            .cells
            .iter()
            .filter(|c| c.n_h == *nh)
            .map(|c| (c.n_dir as f64, c.plain))
            .collect();
        let split: Vec<(f64, f64)> = t
            .cells
            .iter()
            .filter(|c| c.n_h == *nh)
            .map(|c| (c.n_dir as f64, c.split))
            .collect();
        p.series
            .push(Series::new(format!("n_h={nh} split"), split).color(colors[ci]));
        p.series.push(
            Series::new(format!("n_h={nh} plain"), plain)
                .color(colors[ci])
                .dashed(),
        );
    }
    p.write_svg(path)
}

fn table_md(r: &FamilyReport) -> String {
    let mut s = String::new();
    s += "| N_b | ours mean % | ours max % (at p) | thesis method mean % | thesis method max % | ours, thesis metric: mean / max % | thesis method, thesis metric: mean / max % | min f cos / peak | neg. mass | build ms |\n";
    s += "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for row in &r.rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} ({}) | {} | {} | {} / {} | {} / {} | {:.2e} | {:.2e} | {:.0} |",
            row.num_bases,
            pct(row.ours.mean),
            pct(row.ours.max),
            row.ours.max_at,
            pct(row.thesis_cosine_metric.mean),
            pct(row.thesis_cosine_metric.max),
            pct(row.ours_uniform_metric.mean),
            pct(row.ours_uniform_metric.max),
            pct(row.thesis.mean),
            pct(row.thesis.max),
            row.negativity.min_rel,
            row.negativity.neg_mass,
            row.build_ms
        );
    }
    s
}

fn tucker_md(t: &TuckerReport) -> String {
    let mut nds: Vec<usize> = t.cells.iter().map(|c| c.n_dir).collect();
    nds.sort_unstable();
    nds.dedup();
    let mut nhs: Vec<usize> = t.cells.iter().map(|c| c.n_h).collect();
    nhs.sort_unstable();
    nhs.dedup();
    let mut s = String::from("| n_h \\ n_o = n_i |");
    for nd in &nds {
        let _ = write!(s, " {nd} |");
    }
    s += "\n|---:|";
    for _ in &nds {
        s += "---:|";
    }
    s += "\n";
    for nh in &nhs {
        let _ = write!(s, "| {nh} |");
        for nd in &nds {
            if let Some(c) = t.cells.iter().find(|c| c.n_h == *nh && c.n_dir == *nd) {
                let _ = write!(s, " {:.3} / **{:.3}** |", c.plain, c.split);
            }
        }
        s += "\n";
    }
    s
}

/// Writes the markdown report and its plots; returns the image paths.
pub fn write_report(md_path: &Path, args: &BasisArgs) -> Result<Vec<PathBuf>> {
    let dir = md_path.parent().unwrap_or(Path::new("."));
    let img_dir = dir.join("img");
    std::fs::create_dir_all(&img_dir)
        .with_context(|| format!("cannot create {}", img_dir.display()))?;
    let t0 = std::time::Instant::now();
    let reps = family_reports(args)?;
    let mut imgs = Vec::new();
    let mut tuckers = Vec::new();
    for (r, _, cfg) in &reps {
        let p = img_dir.join(format!("brdf-basis-error-{}.svg", r.family));
        error_plot(r, &p)?;
        imgs.push(p);
        eprintln!("{}", format_table(r));
        let t = run_tucker(&cfg.spec, args)?;
        eprint!("{}", format_tucker(&t));
        let p = img_dir.join(format!("brdf-basis-tucker-{}.svg", r.family));
        tucker_plot(&t, &p)?;
        imgs.push(p);
        tuckers.push(t);
    }
    let mut summary = String::new();
    for (r, _, _) in &reps {
        if let Some(row) = r.rows.iter().find(|x| x.num_bases == 6) {
            summary += &summary_line(r.family.name(), row)?;
            summary += "\n";
        }
    }
    let families = reps
        .iter()
        .zip(&tuckers)
        .map(|((r, basis, cfg), t)| family_section(r, basis, cfg, t))
        .collect::<Result<Vec<_>>>()?
        .join("\n\n");
    let md = render(
        TEMPLATE,
        &[
            ("regenerate", REGENERATE.to_string()),
            (
                "grid",
                reps.first()
                    .map(|(_, _, c)| c.grid_spec().describe())
                    .unwrap_or_default(),
            ),
            ("samples", args.samples.to_string()),
            ("eval_samples", args.eval_samples.to_string()),
            ("seconds", format!("{:.0}", t0.elapsed().as_secs_f64())),
            ("summary", summary),
            ("families", families),
        ],
    )?;
    std::fs::write(md_path, md).with_context(|| format!("cannot write {}", md_path.display()))?;
    eprintln!("wrote {} and {} plots", md_path.display(), imgs.len());
    Ok(imgs)
}

fn summary_line(family: &str, row: &NbRow) -> Result<String> {
    render_section(
        FAMILY,
        "summary",
        &[
            ("family", family.to_string()),
            ("ours_mean", pct(row.ours.mean)),
            ("ours_max", pct(row.ours.max)),
            ("ours_u_mean", pct(row.ours_uniform_metric.mean)),
            ("ours_u_max", pct(row.ours_uniform_metric.max)),
            ("ours_i_mean", pct(row.ours_uniform_metric_inner.mean)),
            ("ours_i_max", pct(row.ours_uniform_metric_inner.max)),
            ("thesis_c_mean", pct(row.thesis_cosine_metric.mean)),
            ("thesis_c_max", pct(row.thesis_cosine_metric.max)),
            ("thesis_mean", pct(row.thesis.mean)),
            ("thesis_max", pct(row.thesis.max)),
        ],
    )
}

/// Largest standard error of the end-to-end estimates relative to their values.
fn rel_se(v: &[ContinuousError]) -> f64 {
    v.iter()
        .flat_map(|c| {
            [
                c.basis_stderr / c.basis.max(1e-300),
                c.grid_only_stderr / c.grid_only.max(1e-300),
            ]
        })
        .fold(0.0f64, f64::max)
}

fn sharp_rows(now: &[ContinuousError], before: &[ContinuousError]) -> String {
    let mut s = String::new();
    for (c, b) in now.iter().zip(before) {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} / {} | {} / {} | {} |",
            c.param,
            pct(c.basis),
            pct(c.grid_only),
            pct(b.basis),
            pct(b.grid_only),
            pct(c.albedo_max),
            pct(c.albedo_grid_max),
            pct(b.albedo_max),
            pct(b.albedo_grid_max),
            match (c.clamped, c.finite && b.finite) {
                (_, false) => "non-finite!",
                (true, _) => "outside the range: clamped",
                _ => "",
            }
        );
    }
    s
}

fn family_section(
    r: &FamilyReport,
    basis: &BrdfBasis,
    cfg: &prt_bake::basis::BasisConfig,
    t: &TuckerReport,
) -> Result<String> {
    // the schema-1 configuration: same method on the thesis grid
    let legacy = BasisBuilder::new(cfg.clone().with_grid(GridSpec::THESIS))
        .and_then(|b| b.build(basis.num_bases))?
        .to_persisted();
    let lt = time_runtime(&legacy);
    let nt = time_runtime(basis);
    let now = sharp_checks(&cfg.spec, basis);
    let before = sharp_checks(&cfg.spec, &legacy);
    render_section(
        FAMILY,
        "family",
        &[
            ("family", r.family.to_string()),
            (
                "param",
                if r.family == Family::Ggx {
                    "alpha"
                } else {
                    "s"
                }
                .into(),
            ),
            ("lo", r.param_range[0].to_string()),
            ("hi", r.param_range[1].to_string()),
            ("table", table_md(r)),
            ("build_samples", r.build_samples.to_string()),
            ("setup_ms", format!("{:.0}", r.setup_ms)),
            ("nb", basis.num_bases.to_string()),
            ("eval_ns", format!("{:.1}", nt.eval_all_ns)),
            ("eval_ns_thesis", format!("{:.1}", lt.eval_all_ns)),
            ("local_ns", format!("{:.1}", nt.eval_local_ns)),
            ("local_ns_thesis", format!("{:.1}", lt.eval_local_ns)),
            ("coeff_ns", format!("{:.1}", nt.coefficients_ns)),
            ("nodes", basis.grid.len().to_string()),
            ("values", basis.tables.len().to_string()),
            ("mb", format!("{:.2}", basis.tables.len() as f64 * 4e-6)),
            ("nodes_thesis", legacy.grid.len().to_string()),
            (
                "mb_thesis",
                format!("{:.2}", legacy.tables.len() as f64 * 4e-6),
            ),
            ("pairs", now.first().map_or(0, |c| c.samples).to_string()),
            ("se_now", format!("{:.1}", 100.0 * rel_se(&now))),
            ("se_before", format!("{:.1}", 100.0 * rel_se(&before))),
            ("grid_now", basis.grid_spec().describe()),
            ("grid_before", GridSpec::THESIS.describe()),
            ("sharp_rows", sharp_rows(&now, &before)),
            ("tucker_lobes", t.param_samples.to_string()),
            (
                "tucker_dirs",
                format!("{}x{}", t.dirs.n_theta, t.dirs.n_phi),
            ),
            ("tucker_widths", format!("{:?}", t.split_widths_deg)),
            ("tucker_s", format!("{:.3}", t.specular_fraction)),
            ("tucker_seconds", format!("{:.0}", t.elapsed_ms / 1e3)),
            ("tucker_table", tucker_md(t)),
        ],
    )
}
