//! The report's plots (SVG) and side-by-side pictures (PNG).

use std::path::PathBuf;

use anyhow::Result;

use super::measure::RelightTiming;
use super::results::Report;
use crate::plot::{LinePlot, Series, PALETTE};

pub(crate) fn log2(x: f64) -> f64 {
    x.max(1e-300).log2()
}

/// Fixes the y range of a log plot so that the legend (top right) sits above the data.
pub(crate) fn legend_headroom(p: &mut LinePlot) {
    let ys: Vec<f64> = p
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|q| q.1))
        .filter(|y| y.is_finite() && *y > 0.0)
        .collect();
    if ys.is_empty() {
        return;
    }
    let lo = ys.iter().copied().fold(f64::INFINITY, f64::min).log10();
    let hi = ys.iter().copied().fold(f64::NEG_INFINITY, f64::max).log10();
    let span = (hi - lo).max(0.5);
    let frame = (p.height as f64 - 100.0).max(50.0);
    let frac = ((p.series.len() as f64 * 18.0 + 24.0) / frame).min(0.6);
    let top = hi + span * frac / (1.0 - frac);
    p.y_range = Some((10f64.powf(lo - 0.05 * span), 10f64.powf(top)));
}

pub(crate) fn write_plots(r: &Report) -> Result<Vec<(String, PathBuf)>> {
    let mut out = Vec::new();
    let mut save = |mut p: LinePlot, name: String, caption: String| -> Result<()> {
        p.log_y = true;
        p.width = 760;
        p.height = 520;
        legend_headroom(&mut p);
        let path = r.opts.img_dir.join(&name);
        p.write_svg(&path)?;
        out.push((caption, path));
        Ok(())
    };
    let top = r.plan.bake_spps.iter().copied().max().unwrap_or(0);
    let n = r.plan.small;
    for sc in &r.errors {
        let colour = |i: usize| PALETTE[i % PALETTE.len()];
        // Error vs bake spp.
        let mut p = LinePlot::new(
            format!("{}: error vs bake spp", sc.name),
            "log2(bake spp)",
            "relative L2 error",
        );
        for (i, e) in sc.settings.iter().enumerate() {
            let pts = e
                .by_spp
                .iter()
                .map(|(spp, x)| (log2(*spp as f64), x.rel))
                .collect();
            p.series
                .push(Series::new(e.label.clone(), pts).color(colour(i)));
        }
        if let Some(e) = sc.settings.first() {
            if let (Some(&(spp0, e0)), true) = (e.by_spp.first(), e.by_spp.len() > 1) {
                let pts = e
                    .by_spp
                    .iter()
                    .map(|(spp, _)| {
                        (
                            log2(*spp as f64),
                            e0.rel * (spp0 as f64 / *spp as f64).sqrt(),
                        )
                    })
                    .collect();
                p.series.push(
                    Series::new("1/sqrt(spp)", pts)
                        .dashed()
                        .color([120, 120, 120]),
                );
            }
            let noise = e
                .by_spp
                .iter()
                .map(|(spp, _)| (log2(*spp as f64), e.ref_noise))
                .collect();
            p.series.push(
                Series::new(format!("{} reference noise", e.label), noise)
                    .dashed()
                    .color(colour(0)),
            );
        }
        save(
            p,
            format!("pixel-error-vs-spp-{}.svg", sc.name),
            format!(
                "`{}`: relative L2 error of the relit image vs the reference against bake spp ({n}x{n}, N_b = {}).",
                sc.name, r.plan.main_nb
            ),
        )?;

        // Error vs N_b.
        let mut p = LinePlot::new(
            format!("{}: error vs basis size", sc.name),
            "N_b",
            "relative L2 error",
        );
        for (i, e) in sc.settings.iter().enumerate() {
            let pts = e
                .by_nb
                .iter()
                .map(|(nb, x, _)| (*nb as f64, x.rel))
                .collect();
            p.series
                .push(Series::new(format!("{} vs reference", e.label), pts).color(colour(i)));
            let last = e.by_nb.last().map(|x| x.0);
            let pts = e
                .by_nb
                .iter()
                .filter(|(nb, _, _)| Some(*nb) != last)
                .map(|(nb, _, d)| (*nb as f64, *d))
                .collect();
            let name = format!("{} vs N_b={}", e.label, last.unwrap_or(0));
            p.series
                .push(Series::new(name, pts).color(colour(i)).dashed());
        }
        save(
            p,
            format!("pixel-error-vs-nb-{}.svg", sc.name),
            format!(
                "`{}`: solid, relative L2 error vs the reference against N_b ({n}x{n}, {} spp); dashed, difference to the largest N_b baked with the same paths (the basis' own share).",
                sc.name, r.plan.small_spp
            ),
        )?;

        // Error vs rank.
        let mut p = LinePlot::new(
            format!("{}: error vs compression rank", sc.name),
            "log2(rank)",
            "relative L2 error",
        );
        for (i, e) in sc.settings.iter().enumerate() {
            let added = e
                .by_rank
                .iter()
                .map(|(k, a, _)| (log2(*k as f64), *a))
                .collect();
            p.series
                .push(Series::new(format!("{} added", e.label), added).color(colour(i)));
            let total = e
                .by_rank
                .iter()
                .map(|(k, _, t)| (log2(*k as f64), t.rel))
                .collect();
            p.series.push(
                Series::new(format!("{} total", e.label), total)
                    .color(colour(i))
                    .dashed(),
            );
        }
        save(
            p,
            format!("pixel-error-vs-rank-{}.svg", sc.name),
            format!(
                "`{}`: solid, error added by compression (compressed vs uncompressed relight); dashed, total error vs the reference ({n}x{n}, {top} spp, N_b = {}).",
                sc.name, r.plan.main_nb
            ),
        )?;
    }

    // Relight time vs rank.
    let mut p = LinePlot::new(
        format!("relight time per frame, {}x{}", r.plan.big, r.plan.big),
        "log2(rank)",
        "ms per frame",
    );
    let comp: Vec<&RelightTiming> = r.relight.iter().filter(|t| t.rank.is_some()).collect();
    let xs: Vec<f64> = comp
        .iter()
        .map(|t| log2(t.rank.unwrap_or(1) as f64))
        .collect();
    let (x0, x1) = (
        xs.first().copied().unwrap_or(0.0),
        xs.last().copied().unwrap_or(1.0),
    );
    let bw = r.bandwidth.median;
    let timed = comp
        .iter()
        .zip(&xs)
        .map(|(t, &x)| (x, t.median_s * 1e3))
        .collect();
    p.series
        .push(Series::new("compressed", timed).color(PALETTE[0]));
    let bound = comp
        .iter()
        .zip(&xs)
        .map(|(t, &x)| (x, t.bytes_read as f64 / bw * 1e3))
        .collect();
    p.series.push(
        Series::new("compressed, bound", bound)
            .color(PALETTE[0])
            .dashed(),
    );
    for (i, full) in r.relight.iter().filter(|t| t.rank.is_none()).enumerate() {
        let c = PALETTE[(i + 1) % PALETTE.len()];
        let t = full.median_s * 1e3;
        p.series
            .push(Series::new(full.label.clone(), vec![(x0, t), (x1, t)]).color(c));
        let bound = full.bytes_read as f64 / bw * 1e3;
        p.series.push(
            Series::new(
                format!("{}, bound", full.label),
                vec![(x0, bound), (x1, bound)],
            )
            .color(c)
            .dashed(),
        );
    }
    p.series.push(
        Series::new("2 ms goal", vec![(x0, 2.0), (x1, 2.0)])
            .color([0, 0, 0])
            .dashed(),
    );
    save(
        p,
        "pixel-relight-vs-rank.svg".into(),
        format!(
            "Median relight time per frame at {}x{} against compression rank (solid) and the time the bytes read take at the measured streaming bandwidth (dashed).",
            r.plan.big, r.plan.big
        ),
    )?;
    Ok(out)
}
