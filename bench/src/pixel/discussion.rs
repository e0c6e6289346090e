//! Section 5 of the report: the run's figures read against the goals, with the text of
//! `bench/templates/report-pixel-discussion.md`.

use anyhow::Result;
use prt_bake::units::human_bytes;

use super::measure::RelightTiming;
use super::results::{noise_fit, slope, Report, SceneErrors};
use crate::template::{render_section, section};
use crate::util::{ms, pct};

const TEXT: &str = include_str!("../../templates/report-pixel-discussion.md");

/// Smallest and largest of `v` (NaN-free input assumed; empty gives (inf, 0)).
fn range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    v.fold((f64::INFINITY, 0.0f64), |a, x| (a.0.min(x), a.1.max(x)))
}

pub(crate) fn discussion(r: &Report) -> Result<String> {
    let mut parts = Vec::new();
    if let Some(p) = bake_cost(r)? {
        parts.push(p);
    }
    let fulls: Vec<&RelightTiming> = r.relight.iter().filter(|t| t.rank.is_none()).collect();
    if let Some(p) = uncompressed(r, &fulls)? {
        parts.push(p);
    }
    if let Some(p) = compressed(r, &fulls)? {
        parts.push(p);
    }
    for sc in &r.errors {
        parts.push(errors(r, sc)?);
    }
    if let Some(ring) = r.errors.iter().find(|e| e.name == "ring") {
        let noise = ring
            .settings
            .iter()
            .map(|e| e.ref_noise)
            .fold(0.0, f64::max);
        parts.push(render_section(
            TEXT,
            "ring",
            &[
                ("noise", pct(noise)),
                ("ref_spp", (2 * r.plan.ref_half_spp).to_string()),
            ],
        )?);
    }
    parts.push(section(TEXT, "closing")?.to_string());
    Ok(parts.join("\n"))
}

fn bake_cost(r: &Report) -> Result<Option<String>> {
    if r.ratio_rows.is_empty() {
        return Ok(None);
    }
    let (lo, hi) = range(
        r.ratio_rows
            .iter()
            .map(|x| x.bake_s / x.ref_s.unwrap_or(f64::NAN)),
    );
    let nbs: Vec<String> = r.ratio_rows.iter().map(|x| x.nb.to_string()).collect();
    let larger: Vec<String> = r
        .bake_rows
        .iter()
        .filter_map(|b| {
            b.ref_s
                .map(|t| format!("{:.2} at {}x{}", b.bake_s / t, b.width, b.height))
        })
        .collect();
    let verdict = if hi <= 1.5 && lo >= 0.5 && hi / lo <= 1.5 {
        "bake-flat"
    } else if hi / lo > 1.5 {
        "bake-grows"
    } else {
        "bake-slow"
    };
    let (basis_lo, basis_hi) = range(r.ratio_rows.iter().map(|x| x.basis_s));
    Ok(Some(render_section(
        TEXT,
        "bake",
        &[
            ("lo", format!("{lo:.2}")),
            ("hi", format!("{hi:.2}")),
            ("nbs", nbs.join(", ")),
            ("small", r.plan.small.to_string()),
            ("larger", larger.join(", ")),
            ("verdict", section(TEXT, verdict)?.to_string()),
            ("basis_lo", format!("{basis_lo:.1}")),
            ("basis_hi", format!("{basis_hi:.1}")),
        ],
    )?))
}

fn uncompressed(r: &Report, fulls: &[&RelightTiming]) -> Result<Option<String>> {
    let Some(f) = fulls.first() else {
        return Ok(None);
    };
    let bw = r.bandwidth.median;
    let ratio = f.median_s / (f.bytes_read as f64 / bw);
    let others: Vec<String> = fulls
        .iter()
        .skip(1)
        .map(|g| {
            format!(
                "{}: {} ms for {}, {:.2}x",
                g.label,
                ms(g.median_s),
                human_bytes(g.bytes_read),
                g.median_s / (g.bytes_read as f64 / bw)
            )
        })
        .collect();
    // The goal is judged per stored precision: each variant's own ratio.
    let (met, not_met): (Vec<&RelightTiming>, Vec<&RelightTiming>) = fulls
        .iter()
        .partition(|g| g.median_s / (g.bytes_read as f64 / bw) <= 1.5);
    let names = |v: &[&RelightTiming]| {
        v.iter()
            .map(|g| g.label.clone())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let verdict = match (met.is_empty(), not_met.is_empty()) {
        (false, true) => section(TEXT, "uncompressed-met")?.to_string(),
        (true, _) => section(TEXT, "uncompressed-not-met")?.to_string(),
        (false, false) => render_section(
            TEXT,
            "uncompressed-partly-met",
            &[("met", names(&met)), ("not_met", names(&not_met))],
        )?,
    };
    Ok(Some(render_section(
        TEXT,
        "uncompressed",
        &[
            ("label", f.label.clone()),
            ("ms", ms(f.median_s)),
            ("bytes", human_bytes(f.bytes_read)),
            ("ratio", format!("{ratio:.2}")),
            ("bandwidth", format!("{:.1}", bw / 1e9)),
            ("others", others.join("; ")),
            ("verdict", verdict),
        ],
    )?))
}

fn compressed(r: &Report, fulls: &[&RelightTiming]) -> Result<Option<String>> {
    let comp: Vec<&RelightTiming> = r.relight.iter().filter(|t| t.rank.is_some()).collect();
    let (Some(first), Some(last)) = (comp.first(), comp.last()) else {
        return Ok(None);
    };
    let bw = r.bandwidth.median;
    let big = r.plan.big.to_string();
    let added = match comp
        .iter()
        .find(|t| t.added_error.is_some_and(|e| e < 1e-3))
    {
        Some(t) => render_section(
            TEXT,
            "compressed-ok",
            &[
                ("big", big),
                ("rank", t.rank.unwrap_or(0).to_string()),
                ("error", pct(t.added_error.unwrap_or(f64::NAN))),
                ("ms", ms(t.median_s)),
            ],
        )?,
        None => render_section(
            TEXT,
            "compressed-not-ok",
            &[
                ("big", big),
                ("rank", last.rank.unwrap_or(0).to_string()),
                ("error", pct(last.added_error.unwrap_or(f64::NAN))),
            ],
        )?,
    };
    let under_2ms = match comp
        .iter()
        .filter(|t| t.median_s < 2e-3)
        .filter_map(|t| t.rank)
        .max()
    {
        Some(k) => format!("Frames stay under 2 ms up to rank {k}."),
        None => "No rank stays under 2 ms per frame.".into(),
    };
    let full_bytes = fulls.first().map_or(u64::MAX, |f| f.bytes_read);
    let bigger = match comp
        .iter()
        .find(|t| t.bytes_read > full_bytes)
        .and_then(|t| t.rank)
    {
        Some(k) => render_section(TEXT, "compressed-bigger", &[("rank", k.to_string())])? + " ",
        None => String::new(),
    };
    let (lo, hi) = range(
        comp.iter()
            .map(|t| t.median_s * bw / t.bytes_read.max(1) as f64),
    );
    let met = comp
        .iter()
        .any(|t| t.median_s < 2e-3 && t.added_error.is_some_and(|e| e < 1e-3));
    Ok(Some(render_section(
        TEXT,
        "compressed",
        &[
            ("added", added),
            ("under_2ms", under_2ms),
            (
                "big_spp",
                r.bake_rows.get(1).map_or(0, |b| b.spp).to_string(),
            ),
            (
                "top_spp",
                r.plan.bake_spps.iter().max().unwrap_or(&0).to_string(),
            ),
            ("bigger", bigger),
            ("fixed", human_bytes(first.bytes_read)),
            ("first_rank", first.rank.unwrap_or(0).to_string()),
            ("lo", format!("{lo:.1}")),
            ("hi", format!("{hi:.1}")),
            (
                "goal",
                if met { "met" } else { "not met on this bake" }.into(),
            ),
        ],
    )?))
}

fn errors(r: &Report, sc: &SceneErrors) -> Result<String> {
    let top = *r.plan.bake_spps.iter().max().unwrap_or(&0);
    let slopes: Vec<f64> = sc
        .settings
        .iter()
        .map(|e| slope(&e.by_spp))
        .filter(|x| x.is_finite())
        .collect();
    let mean_slope = slopes.iter().sum::<f64>() / slopes.len().max(1) as f64;
    let (best, worst) = range(
        sc.settings
            .iter()
            .filter_map(|e| e.by_spp.last().map(|x| x.1.rel)),
    );
    let noise = sc.settings.iter().map(|e| e.ref_noise).fold(0.0, f64::max);
    let max_floor = sc
        .settings
        .iter()
        .map(|e| noise_fit(e, top).1)
        .filter(|x| x.is_finite())
        .fold(0.0, f64::max);
    let (basis_label, basis) = sc
        .settings
        .iter()
        .filter_map(|e| {
            e.by_nb
                .iter()
                .find(|x| x.0 == r.plan.main_nb)
                .map(|x| (e.label.clone(), x.2))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or_else(|| (String::new(), f64::NAN));
    let denoise = sc.settings.iter().any(|e| {
        let full = e.by_spp.last().map_or(f64::NAN, |x| x.1.rel);
        e.by_rank.iter().any(|(_, _, t)| t.rel < 0.85 * full)
    });
    let basis_values = [
        ("basis", pct(basis)),
        ("nb", r.plan.main_nb.to_string()),
        ("basis_label", basis_label.clone()),
    ];
    let floor_text = if max_floor < 0.002 {
        section(TEXT, "floor-none")?.to_string()
    } else if basis >= 0.5 * max_floor {
        render_section(TEXT, "floor-basis", &basis_values)?
    } else {
        render_section(TEXT, "floor-other", &basis_values)?
    };
    let slope_note = if (mean_slope + 0.5).abs() < 0.1 {
        "slope-noise"
    } else {
        "slope-flat"
    };
    render_section(
        TEXT,
        "errors",
        &[
            ("scene", sc.name.clone()),
            ("top_spp", top.to_string()),
            ("best", pct(best)),
            ("worst", pct(worst)),
            ("noise", pct(noise)),
            ("slope", format!("{mean_slope:.2}")),
            ("slope_note", section(TEXT, slope_note)?.to_string()),
            ("floor", pct(max_floor)),
            ("floor_text", floor_text),
            ("nb", r.plan.main_nb.to_string()),
            (
                "nb_top",
                sc.settings
                    .first()
                    .and_then(|e| e.by_nb.last())
                    .map_or(0, |x| x.0)
                    .to_string(),
            ),
            ("basis", pct(basis)),
            ("basis_label", basis_label),
            (
                "basis_note",
                if basis > 0.005 {
                    format!(", {}", section(TEXT, "basis-large")?)
                } else {
                    String::new()
                },
            ),
            (
                "denoise",
                if denoise {
                    format!(" {}", section(TEXT, "denoise")?)
                } else {
                    String::new()
                },
            ),
        ],
    )
}
