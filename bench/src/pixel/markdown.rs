//! The markdown of the report: `bench/templates/report-pixel.md` filled with the run's tables
//! and figures.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use prt_bake::units::human_bytes;

use super::results::{noise_fit, BakeRow, Report, SceneErrors, SettingErrors};
use super::REGENERATE;
use crate::template::render;
use crate::util::{cpu_model, git_head, link, ms, pct};

const TEMPLATE: &str = include_str!("../../templates/report-pixel.md");

pub(crate) fn markdown(r: &Report) -> Result<String> {
    let docs = r
        .opts
        .out
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let img = |p: &Path| link(&docs, p);
    let embed = |prefix: &str| -> String {
        let mut out = String::new();
        for (c, p) in &r.plots {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            if name.starts_with(prefix) {
                let _ = writeln!(out, "\n![{name}]({})\n\n{c}", img(p));
            }
        }
        out
    };
    let threads = rayon::current_num_threads();
    let bw = r.bandwidth.median;
    let top = r.plan.bake_spps.iter().copied().max().unwrap_or(0);
    let relight_plot = r
        .plots
        .iter()
        .find(|(_, p)| {
            p.file_name()
                .is_some_and(|n| n == "pixel-relight-vs-rank.svg")
        })
        .map_or(String::new(), |(c, p)| {
            format!("\n![relight time vs rank]({})\n\n{c}\n", img(p))
        });
    let mut pictures = String::new();
    for (label, describe, p) in &r.pictures {
        let _ = writeln!(
            pictures,
            "**{label}** ({describe})\n\n![{label}]({})\n",
            img(p)
        );
    }
    let values = [
        (
            "quick_banner",
            if r.opts.quick {
                "> **Quick smoke run** (`--quick`): tiny sizes, the figures mean nothing.\n\n"
                    .to_string()
            } else {
                String::new()
            },
        ),
        ("regenerate", REGENERATE.to_string()),
        ("run_table", run_table(r, threads)),
        ("summary_rows", summary_rows(r)),
        ("main_name", r.main_name.clone()),
        ("main_reflections", r.main_reflections.to_string()),
        ("main_nb", r.plan.main_nb.to_string()),
        (
            "basis_grid",
            match r.basis_grid {
                Some((g, n)) => format!(
                    "a {}x{}x{} grid at {n} parameter values",
                    g.n_theta_i, g.n_theta_o, g.n_phi
                ),
                None => "no grid: no editable glossy material".into(),
            },
        ),
        ("bake_table", bake_table(&r.bake_rows)),
        ("small", r.plan.small.to_string()),
        ("small_spp", r.plan.small_spp.to_string()),
        ("ratio_repeats", r.ratio_repeats.to_string()),
        ("ratio_table", bake_table(&r.ratio_rows)),
        ("big", r.plan.big.to_string()),
        ("bw_bytes", human_bytes(r.bandwidth.bytes)),
        ("bw_threads", r.bandwidth.threads.to_string()),
        ("bw_runs", r.bandwidth.runs.to_string()),
        ("bw_median", format!("{:.2}", bw / 1e9)),
        ("bw_best", format!("{:.2}", r.bandwidth.best / 1e9)),
        ("bw_write", format!("{:.2}", r.bandwidth.write_median / 1e9)),
        (
            "image_bytes",
            human_bytes(r.plan.big as u64 * r.plan.big as u64 * 12),
        ),
        ("threads", threads.to_string()),
        (
            "big_spp",
            r.bake_rows.get(1).map_or(0, |b| b.spp).to_string(),
        ),
        ("big_settings", r.big_settings.to_string()),
        ("frames", r.plan.frames.to_string()),
        (
            "max_rank",
            r.plan.ranks.iter().max().unwrap_or(&0).to_string(),
        ),
        ("pca_seconds", format!("{:.2}", r.pca_seconds)),
        ("relight_table", relight_table(r)),
        ("reads_table", reads_table(r)),
        ("relight_plot", relight_plot),
        ("ref_half_spp", r.plan.ref_half_spp.to_string()),
        ("ref_spp", (2 * r.plan.ref_half_spp).to_string()),
        ("top_spp", top.to_string()),
        ("error_table", error_table(r, top)),
        ("spp_plots", embed("pixel-error-vs-spp-")),
        (
            "scenes",
            r.errors
                .iter()
                .map(|e| format!("`{}` ({} triangles)", e.name, e.triangles))
                .collect::<Vec<_>>()
                .join(", "),
        ),
        (
            "ref_times",
            r.errors
                .iter()
                .flat_map(|sc| {
                    sc.settings
                        .iter()
                        .map(move |e| format!("{} {} {:.1} s", sc.name, e.label, e.ref_seconds))
                })
                .collect::<Vec<_>>()
                .join(", "),
        ),
        ("nb_table", nb_table(r)),
        ("nb_plots", embed("pixel-error-vs-nb-")),
        ("rank_table", rank_table(r)),
        ("rank_plots", embed("pixel-error-vs-rank-")),
        ("exposure", format!("{:.2}", r.exposure)),
        ("pictures", pictures),
        ("discussion", super::discussion::discussion(r)?),
    ];
    render(TEMPLATE, &values)
}

/// The table of this run's command, date, commit, machine and load.
fn run_table(r: &Report, threads: usize) -> String {
    let nproc = std::thread::available_parallelism().map_or(0, |n| n.get());
    let mut s = String::from("| | |\n| --- | --- |\n");
    let _ = writeln!(s, "| this run | `{}` |", r.opts.command);
    let _ = writeln!(s, "| date | {} |", r.started);
    if let Some(h) = git_head() {
        let _ = writeln!(
            s,
            "| commit | `{h}` (plus any uncommitted changes of the working tree) |"
        );
    }
    let _ = writeln!(
        s,
        "| machine | {nproc} CPUs (nproc), {}; {threads} rayon threads |",
        cpu_model()
    );
    let _ = writeln!(
        s,
        "| load average (1, 5, 15 min) | start {}, end {} |",
        r.load_start, r.load_end
    );
    let _ = writeln!(s, "| total run time | {:.0} s |", r.total_s);
    s
}

/// The rows of the summary table (goal, measured, met).
fn summary_rows(r: &Report) -> String {
    let mut s = String::new();
    let bw = r.bandwidth.median;
    let ratio_of = |x: &BakeRow| x.bake_s / x.ref_s.unwrap_or(f64::NAN);
    if let Some(row) = r
        .ratio_rows
        .iter()
        .find(|x| x.nb == r.plan.main_nb)
        .or(r.ratio_rows.first())
    {
        let all: Vec<String> = r
            .ratio_rows
            .iter()
            .map(|x| format!("{:.2}", ratio_of(x)))
            .collect();
        let nbs: Vec<String> = r.ratio_rows.iter().map(|x| x.nb.to_string()).collect();
        let met = r
            .ratio_rows
            .iter()
            .all(|x| x.bake_s <= 1.5 * x.ref_s.unwrap_or(0.0))
            && ratio_of(row).is_finite();
        let _ = writeln!(
            s,
            "| bake costs about one render, whatever N_b (thesis) | bake / reference render = {} for N_b = {} ({}x{}, {} spp) | {} |",
            all.join(", "),
            nbs.join(", "),
            row.width,
            row.height,
            row.spp,
            if met { "yes (within 1.5x)" } else { "no" }
        );
    }
    // One row per stored precision: f32 is the per-pixel default, f16 reads half the bytes.
    for f in r.relight.iter().filter(|t| t.rank.is_none()) {
        let bound = f.bytes_read as f64 / bw;
        let ratio = f.median_s / bound;
        let _ = writeln!(
            s,
            "| {} relight within 1.5x of the bandwidth bound | {} ms per frame (median) vs {} ms bound: {ratio:.2}x (least-disturbed frame vs best pass: {:.2}x) | {} |",
            f.label,
            ms(f.median_s),
            ms(bound),
            f.min_s / (f.bytes_read as f64 / r.bandwidth.best.max(1.0)),
            if ratio <= 1.5 { "yes" } else { "no" }
        );
    }
    let ok = |t: &&super::measure::RelightTiming| t.added_error.is_some_and(|e| e < 1e-3);
    let best = r
        .relight
        .iter()
        .filter(|t| t.rank.is_some() && t.median_s < 2e-3 && ok(t))
        .min_by(|a, b| a.median_s.total_cmp(&b.median_s));
    let smallest_ok = r.relight.iter().filter(ok).min_by_key(|t| t.rank);
    let measured = match (best, smallest_ok) {
        (Some(b), _) => format!(
            "rank {}: {} ms, added error {}",
            b.rank.unwrap_or(0),
            ms(b.median_s),
            pct(b.added_error.unwrap_or(f64::NAN))
        ),
        (None, Some(t)) => format!(
            "smallest rank with added error < 0.1 %: rank {} at {} ms",
            t.rank.unwrap_or(0),
            ms(t.median_s)
        ),
        (None, None) => "no rank up to the largest measured reaches 0.1 % added error".into(),
    };
    let _ = writeln!(
        s,
        "| compressed relight < 2 ms per frame at added error < 0.1 % ({}x{}) | {measured} | {} |",
        r.plan.big,
        r.plan.big,
        if best.is_some() { "yes" } else { "no" }
    );
    s
}

fn bake_table(rows: &[BakeRow]) -> String {
    let mut s = String::from("| bake | size | spp | N_b | slots | basis build (s) | bake (s) | Mrays/s | file (f16) | render (s) | render Mrays/s | bake / render |\n");
    s += "| --- | --- | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: |\n";
    for b in rows {
        let _ = writeln!(
            s,
            "| {} | {}x{} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {} | {} | {} | {} |",
            b.what,
            b.width,
            b.height,
            b.spp,
            b.nb,
            b.slots,
            b.basis_s,
            b.bake_s,
            b.rays as f64 / b.bake_s.max(1e-9) / 1e6,
            human_bytes(b.file_bytes),
            b.ref_s.map_or("-".into(), |t| format!("{t:.2}")),
            match (b.ref_s, b.ref_rays) {
                (Some(t), Some(n)) => format!("{:.2}", n as f64 / t.max(1e-9) / 1e6),
                _ => "-".into(),
            },
            b.ref_s
                .map_or("-".into(), |t| format!("{:.2}", b.bake_s / t))
        );
    }
    s
}

fn relight_table(r: &Report) -> String {
    let bw = r.bandwidth.median;
    let mut s = String::from("| variant | rank | file size | bytes read / frame | ms / frame (median) | min - max | bound (ms) | time / bound | min / best bound | added error |\n");
    s += "| --- | --: | --: | --: | --: | --: | --: | --: | --: | --: |\n";
    for t in &r.relight {
        let bound = t.bytes_read as f64 / bw;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} - {} | {} | {:.2} | {:.2} | {} |",
            t.label,
            t.rank.map_or("-".into(), |k| k.to_string()),
            human_bytes(t.file_bytes),
            human_bytes(t.bytes_read),
            ms(t.median_s),
            ms(t.min_s),
            ms(t.max_s),
            ms(bound),
            t.median_s / bound,
            t.min_s / (t.bytes_read as f64 / r.bandwidth.best.max(1.0)),
            t.added_error.map_or("-".into(), pct)
        );
    }
    s
}

/// The uncompressed variants' frames against their reads alone, the bandwidth bound, and the
/// bound that also counts writing the image.
fn reads_table(r: &Report) -> String {
    let bw = r.bandwidth.median;
    let image = (r.plan.big * r.plan.big * 3 * 4) as f64;
    let floor_write = image / r.bandwidth.write_median.max(1.0);
    let mut s = String::from("| variant | bytes read / frame | frame (ms) | reads alone (ms) | bound (ms) | reads alone / bound | frame / reads alone | read + write bound (ms) | frame / read + write bound |\n");
    s += "| --- | --: | --: | --: | --: | --: | --: | --: | --: |\n";
    for t in &r.relight {
        let Some(reads) = t.reads_median_s else {
            continue;
        };
        let bound = t.bytes_read as f64 / bw;
        let floor = bound + floor_write;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.2} | {:.2} | {} | {:.2} |",
            t.label,
            human_bytes(t.bytes_read),
            ms(t.median_s),
            ms(reads),
            ms(bound),
            reads / bound,
            t.median_s / reads,
            ms(floor),
            t.median_s / floor
        );
    }
    s
}

fn error_table(r: &Report, top: u32) -> String {
    let k = r.plan.table_rank;
    let mut s = String::from("| scene | setting | reference noise (rel. L2 / RMSE) |");
    for spp in &r.plan.bake_spps {
        let _ = write!(s, " rel. L2 @{spp} spp |");
    }
    let _ = writeln!(
        s,
        " RMSE @{top} spp | fit: bake noise @{top} spp | fit: floor | rank {k}: added | rank {k}: total |"
    );
    s += "| --- | --- | --: |";
    for _ in &r.plan.bake_spps {
        s += " --: |";
    }
    s += " --: | --: | --: | --: | --: |\n";
    for sc in &r.errors {
        for e in &sc.settings {
            let _ = write!(
                s,
                "| {} | {} ({}) | {} / {:.2e} |",
                sc.name,
                e.label,
                e.describe,
                pct(e.ref_noise),
                e.ref_rmse_noise
            );
            for (_, x) in &e.by_spp {
                let _ = write!(s, " {} |", pct(x.rel));
            }
            let last = e.by_spp.last().map_or(f64::NAN, |x| x.1.rmse);
            let rk = e.by_rank.iter().find(|x| x.0 == k);
            let (noise, floor) = noise_fit(e, top);
            let _ = writeln!(
                s,
                " {last:.2e} | {} | {} | {} | {} |",
                pct(noise),
                pct(floor),
                rk.map_or("n/a".into(), |x| pct(x.1)),
                rk.map_or("n/a".into(), |x| pct(x.2.rel))
            );
        }
    }
    s
}

/// Every (scene, setting) pair: the columns of the N_b and rank tables.
fn columns(r: &Report) -> Vec<(&SceneErrors, &SettingErrors)> {
    r.errors
        .iter()
        .flat_map(|sc| sc.settings.iter().map(move |e| (sc, e)))
        .collect()
}

/// A table with one row per `keys` entry and one column per (scene, setting); `cell` gives
/// the entry or `None` ("-").
fn sweep_table<K: std::fmt::Display>(
    first: &str,
    r: &Report,
    keys: &[K],
    cell: impl Fn(&SettingErrors, &K) -> Option<String>,
) -> String {
    let cols = columns(r);
    let mut s = format!("| {first} |");
    for (sc, e) in &cols {
        let _ = write!(s, " {} {} |", sc.name, e.label);
    }
    s += "\n| --: |";
    for _ in &cols {
        s += " --: |";
    }
    s += "\n";
    for k in keys {
        let _ = write!(s, "| {k} |");
        for (_, e) in &cols {
            let _ = write!(s, " {} |", cell(e, k).unwrap_or_else(|| "-".into()));
        }
        s += "\n";
    }
    s
}

fn nb_table(r: &Report) -> String {
    let nbs: Vec<usize> = columns(r)
        .first()
        .map_or(Vec::new(), |(_, e)| e.by_nb.iter().map(|x| x.0).collect());
    sweep_table("N_b", r, &nbs, |e, nb| {
        e.by_nb
            .iter()
            .find(|x| x.0 == *nb)
            .map(|(_, x, d)| format!("{} ({})", pct(x.rel), pct(*d)))
    })
}

fn rank_table(r: &Report) -> String {
    sweep_table("rank", r, &r.plan.ranks, |e, k| {
        e.by_rank
            .iter()
            .find(|x| x.0 == *k)
            .map(|(_, a, t)| format!("{} / {}", pct(*a), pct(t.rel)))
    })
}
