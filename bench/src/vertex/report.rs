//! The report's text (from `bench/templates/report-vertex.md`), plots (SVG) and pictures (PNG).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;

use super::measure::LIGHTS;
use super::SceneRun;
use crate::pictures::{auto_exposure, side_by_side_with, Panels};
use crate::plot::{LinePlot, Series, PALETTE};
use crate::util::{link, ms, pct};

/// The report's prose; `{{name}}` fields are filled in by [`write`].
const TEMPLATE: &str = include_str!("../../templates/report-vertex.md");

pub(crate) struct Inputs<'a> {
    pub main: &'a SceneRun,
    pub detail: &'a SceneRun,
    pub large: Option<&'a SceneRun>,
    pub img_dir: &'a Path,
    pub out: &'a Path,
    pub spp: u32,
    pub rounds: usize,
}

fn mb(bytes: u64) -> String {
    format!("{:.1} MB", bytes as f64 / 1e6)
}

fn gb(bytes: Option<u64>) -> String {
    bytes.map_or("n/a".into(), |b| format!("{:.2} GB", b as f64 / 1e9))
}

fn fps(seconds: f64) -> String {
    format!("{} ms ({:.0} fps)", ms(seconds), 1.0 / seconds)
}

/// The file name of a scene's config folder (`scenes/gallery/bake.toml` -> `gallery`).
fn scene_name(config: &Path) -> String {
    let p = if config.extension().is_some() {
        config.parent().unwrap_or(config)
    } else {
        config
    };
    p.file_name()
        .map_or("scene".into(), |n| n.to_string_lossy().into_owned())
}

/// The per-setting table of a scene (errors per light; times when measured).
fn setting_rows(s: &SceneRun, with_dense: bool) -> String {
    let mut rows = String::new();
    for (i, set) in s.settings.iter().enumerate() {
        let b = &s.baked[i];
        let e = &s.errors[i];
        let err = |li: usize| {
            if with_dense {
                format!("{} / {}", pct(e.vs_dense[li]), pct(e.vs_reference[li]))
            } else {
                pct(e.vs_reference[li])
            }
        };
        let _ = write!(
            rows,
            "| {} | {} | {:.1} s | {:.1} s | {} | {} | {}",
            set.label,
            mb(b.file_bytes),
            b.trace_seconds,
            b.compress_seconds,
            gb(b.peak_bytes),
            err(0),
            err(1),
        );
        if let Some(t) = s.times.get(i) {
            let _ = write!(
                rows,
                " | {} | {} | {}",
                ms(t.view),
                ms(t.view_brdf),
                ms(t.view_brdf_light)
            );
        } else if !s.times.is_empty() {
            rows.push_str(" | not timed | not timed | not timed");
        }
        rows.push_str(" |\n");
    }
    rows.trim_end().to_string()
}

/// Writes a plot next to the report and returns its markdown image link.
fn save(p: &LinePlot, inputs: &Inputs, name: &str) -> Result<String> {
    let path = inputs.img_dir.join(name);
    p.write_svg(&path)?;
    let from = inputs.out.parent().unwrap_or(Path::new("."));
    Ok(format!("![{}]({})", p.title, link(from, &path)))
}

/// Error against each knob (thesis figure 5-9): one plot per knob of a scene.
fn knob_plots(s: &SceneRun, inputs: &Inputs, with_dense: bool) -> Result<Vec<String>> {
    let mut knobs: Vec<&str> = Vec::new();
    for set in &s.settings {
        if !set.knob.is_empty() && !knobs.contains(&set.knob) {
            knobs.push(set.knob);
        }
    }
    let name = scene_name(&s.config);
    let mut out = Vec::new();
    for (k, knob) in knobs.iter().enumerate() {
        let idx: Vec<usize> = (0..s.settings.len())
            .filter(|&i| s.settings[i].knob == *knob)
            .collect();
        let mut p = LinePlot::new(
            format!("{name}: error against {knob}"),
            knob.to_string(),
            "relative L2 error",
        );
        p.log_y = true;
        p.width = 560;
        p.height = 380;
        for (li, light) in LIGHTS.iter().enumerate() {
            let points = |f: &dyn Fn(usize) -> f64| -> Vec<(f64, f64)> {
                let mut v: Vec<(f64, f64)> =
                    idx.iter().map(|&i| (s.settings[i].value, f(i))).collect();
                v.sort_by(|a, b| a.0.total_cmp(&b.0));
                v
            };
            p.series.push(
                Series::new(
                    format!("{}: vs reference", light.name),
                    points(&|i| s.errors[i].vs_reference[li]),
                )
                .color(PALETTE[li]),
            );
            if with_dense {
                p.series.push(
                    Series::new(
                        format!("{}: vs dense", light.name),
                        points(&|i| s.errors[i].vs_dense[li]),
                    )
                    .color(PALETTE[li])
                    .dashed(),
                );
            }
        }
        let slug: String = knob
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        out.push(save(
            &p,
            inputs,
            &format!("report-{name}-knob-{k}-{slug}.svg"),
        )?);
    }
    Ok(out)
}

/// Frame time of each path against the error from the dense relight, and file size against
/// the same error, over the main scene's compressed settings.
fn speed_plots(s: &SceneRun, inputs: &Inputs) -> Result<Vec<String>> {
    let name = scene_name(&s.config);
    let compressed: Vec<usize> = (0..s.settings.len())
        .filter(|&i| s.settings[i].compress && i < s.times.len())
        .collect();
    let err = |i: usize| s.errors[i].vs_dense.iter().copied().fold(0.0, f64::max);
    let sorted = |f: &dyn Fn(usize) -> f64| -> Vec<(f64, f64)> {
        let mut v: Vec<(f64, f64)> = compressed.iter().map(|&i| (f(i), err(i))).collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        v
    };
    let mut speed = LinePlot::new(
        format!("{name}: frame time against error (compressed settings)"),
        "frame time (ms)",
        "relative L2 from the dense relight (worse light)",
    );
    speed.log_y = true;
    type PathTime = fn(&super::PathTimes) -> f64;
    let paths: [(&str, PathTime); 3] = [
        ("view", |t| t.view),
        ("view + BRDF", |t| t.view_brdf),
        ("view + BRDF + light", |t| t.view_brdf_light),
    ];
    for (k, (label, f)) in paths.iter().enumerate() {
        speed
            .series
            .push(Series::new(*label, sorted(&|i| 1e3 * f(&s.times[i]))).color(PALETTE[k]));
    }
    let mut size = LinePlot::new(
        format!("{name}: file size against error (compressed settings)"),
        "file (MB)",
        "relative L2 from the dense relight (worse light)",
    );
    size.log_y = true;
    size.series.push(Series::new(
        "compressed settings",
        sorted(&|i| s.baked[i].file_bytes as f64 / 1e6),
    ));
    Ok(vec![
        save(&speed, inputs, &format!("report-{name}-speed-vs-error.svg"))?,
        save(&size, inputs, &format!("report-{name}-size-vs-error.svg"))?,
    ])
}

/// The pictures' difference gain (the relit images' per-vertex noise saturates x 10).
const DIFFERENCE_GAIN: f32 = 4.0;
/// Each picture pixel averages 2 x 2 rendered ones: 256-pixel panels keep the docs small.
const PICTURE_SHRINK: u32 = 2;

/// relit | reference | difference of a scene's first setting, per light.
fn pictures(s: &SceneRun, inputs: &Inputs) -> Result<Vec<String>> {
    let name = scene_name(&s.config);
    let from = inputs.out.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for (li, light) in LIGHTS.iter().enumerate() {
        let reference = &s.references[li];
        let path = inputs
            .img_dir
            .join(format!("report-{name}-{}.png", light.slug));
        let panels = Panels {
            exposure: auto_exposure(reference),
            gain: DIFFERENCE_GAIN,
            shrink: PICTURE_SHRINK,
        };
        side_by_side_with(
            &s.errors[0].images[li],
            reference,
            s.size,
            s.size,
            panels,
            &path,
        )?;
        out.push(format!(
            "![{name}, {}: relit ({}) | reference | difference x {DIFFERENCE_GAIN}]({})",
            light.name,
            s.settings[0].label,
            link(from, &path)
        ));
    }
    Ok(out)
}

/// The noise floor's distance from the dense relight, per light ("n/a" without one).
fn noise_floor(s: &SceneRun) -> String {
    match s.settings.iter().position(|x| x.seed_offset != 0) {
        Some(i) => format!(
            "{} under the baked light and {} under the turned studio map",
            pct(s.errors[i].vs_dense[0]),
            pct(s.errors[i].vs_dense[1])
        ),
        None => "n/a".into(),
    }
}

/// The goals of the per-vertex mode, checked on the main scene's defaults (setting 0).
fn goals(s: &SceneRun) -> String {
    let b = &s.baked[0];
    let t = &s.times[0];
    let worst_dense = s.errors[0].vs_dense.iter().copied().fold(0.0, f64::max);
    let verdict = |met: bool, by: String| {
        if met {
            "met".to_string()
        } else {
            format!("not met: {by}")
        }
    };
    let rate = |seconds: f64, goal: f64| {
        verdict(
            1.0 / seconds >= goal,
            format!("{:.1}x too slow", goal * seconds),
        )
    };
    let bake = b.seconds;
    let rows = [
        (
            "view only >= 500 fps".to_string(),
            fps(t.view),
            rate(t.view, 500.0),
        ),
        (
            "view + BRDF >= 100 fps".into(),
            fps(t.view_brdf),
            rate(t.view_brdf, 100.0),
        ),
        (
            "view + BRDF + light >= 30 fps".into(),
            fps(t.view_brdf_light),
            rate(t.view_brdf_light, 30.0),
        ),
        (
            "file <= 130 MB".into(),
            mb(b.file_bytes),
            verdict(
                b.file_bytes as f64 <= 130e6,
                format!("{:.2}x", b.file_bytes as f64 / 130e6),
            ),
        ),
        (
            "image error against the uncompressed relight < 1 %".into(),
            format!("{} (worse of the two lights)", pct(worst_dense)),
            verdict(worst_dense < 0.01, format!("{:.1}x", worst_dense / 0.01)),
        ),
        (
            "bake plus compression < 10 minutes".into(),
            format!("{:.0} s", bake),
            verdict(bake < 600.0, format!("{:.2}x", bake / 600.0)),
        ),
    ];
    let mut out = String::from("| goal | measured | verdict |\n| --- | ---: | --- |\n");
    for (g, m, v) in rows {
        let _ = writeln!(out, "| {g} | {m} | {v} |");
    }
    out.trim_end().to_string()
}

pub(crate) fn write(inputs: &Inputs) -> Result<String> {
    let (m, d) = (inputs.main, inputs.detail);
    let t0 = m.times[0];
    let b0 = &m.baked[0];
    let mut plots = knob_plots(m, inputs, true)?;
    plots.extend(knob_plots(d, inputs, false)?);
    let speed = speed_plots(m, inputs)?;
    let mut pics = pictures(m, inputs)?;
    let large = match inputs.large {
        Some(l) => {
            pics.extend(pictures(l, inputs)?);
            let t = l.times[0];
            let b = &l.baked[0];
            format!(
                "`{}` ({} vertices, {}x{} images) at its defaults: {} file, traced in {:.0} s \
                 and compressed in {:.0} s, peak memory {} (estimated {}); against the \
                 reference {} under the baked light and {} under the turned studio map; view \
                 {}, view + BRDF {}, view + BRDF + light {} (medians of {} rounds).",
                l.config.display(),
                l.vertices,
                l.size,
                l.size,
                mb(b.file_bytes),
                b.trace_seconds,
                b.compress_seconds,
                gb(b.peak_bytes),
                gb(Some(b.estimated_bytes)),
                pct(l.errors[0].vs_reference[0]),
                pct(l.errors[0].vs_reference[1]),
                fps(t.view),
                fps(t.view_brdf),
                fps(t.view_brdf_light),
                inputs.rounds
            )
        }
        None => "Not run this time (`--large-config` not given).".into(),
    };
    let values = [
        ("host", crate::util::cpu_model()),
        ("threads", rayon::current_num_threads().to_string()),
        ("load", crate::util::load_average()),
        (
            "commit",
            crate::util::git_head().unwrap_or_else(|| "unknown".into()),
        ),
        ("date", crate::util::utc_now()),
        ("config", m.config.display().to_string()),
        ("vertices", m.vertices.to_string()),
        ("size", m.size.to_string()),
        ("spp", inputs.spp.to_string()),
        ("rounds", inputs.rounds.to_string()),
        ("goals", goals(m)),
        ("trace_s", format!("{:.0}", b0.trace_seconds)),
        ("vertices_per_s", format!("{:.0}", b0.vertices_per_second)),
        ("peak", gb(b0.peak_bytes)),
        ("estimate", gb(Some(b0.estimated_bytes))),
        ("main_rows", setting_rows(m, true)),
        ("knob_plots", plots.join("\n")),
        ("speed_plots", speed.join("\n")),
        ("detail_config", d.config.display().to_string()),
        ("detail_vertices", d.vertices.to_string()),
        ("detail_size", d.size.to_string()),
        ("detail_rows", setting_rows(d, false)),
        ("large", large),
        ("pictures", pics.join("\n\n")),
        ("view_ms", ms(t0.view)),
        ("view_stage_ms", ms(t0.view_stage)),
        ("raster_ms", ms(t0.raster)),
        ("shade_ms", ms(t0.view_stage - t0.raster)),
        ("material_ms", ms(t0.material)),
        ("light_ms", ms(t0.light)),
        ("noise", noise_floor(m)),
        (
            "worst_dense",
            pct(m.errors[0].vs_dense.iter().copied().fold(0.0, f64::max)),
        ),
        (
            "shade_ns",
            format!(
                "{:.0}",
                (t0.view_stage - t0.raster) * 1e9 * rayon::current_num_threads() as f64
                    / f64::from(m.size * m.size)
            ),
        ),
    ];
    crate::template::render(TEMPLATE, &values)
}
