//! Line plots as SVG files (through `plotters`): several series, optional log-y axis, legend,
//! axis labels. SVG keeps the generated figures small and their diffs readable.

use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::prelude::*;

/// One polyline with a legend entry.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Colour; `None` picks one from the palette by index.
    pub color: Option<[u8; 3]>,
    pub dashed: bool,
}

impl Series {
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.into(),
            points,
            color: None,
            dashed: false,
        }
    }

    pub fn dashed(mut self) -> Series {
        self.dashed = true;
        self
    }

    pub fn color(mut self, c: [u8; 3]) -> Series {
        self.color = Some(c);
        self
    }
}

/// Where the legend goes, inside the plot area.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Legend {
    #[default]
    UpperRight,
    MiddleLeft,
}

/// A line plot.
#[derive(Clone, Debug)]
pub struct LinePlot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_y: bool,
    pub series: Vec<Series>,
    pub width: u32,
    pub height: u32,
    /// Optional fixed y range (data units); `None` fits the data.
    pub y_range: Option<(f64, f64)>,
    pub legend: Legend,
}

/// Default palette (colour-blind friendly, Okabe-Ito).
pub const PALETTE: [[u8; 3]; 8] = [
    [0, 114, 178],
    [213, 94, 0],
    [0, 158, 115],
    [204, 121, 167],
    [230, 159, 0],
    [86, 180, 233],
    [0, 0, 0],
    [240, 228, 66],
];

/// Smallest and largest finite value (positive only when `positive`), or `None`.
fn bounds(v: impl Iterator<Item = f64>, positive: bool) -> Option<(f64, f64)> {
    v.filter(|x| x.is_finite() && (!positive || *x > 0.0))
        .fold(None, |acc, x| match acc {
            None => Some((x, x)),
            Some((lo, hi)) => Some((lo.min(x), hi.max(x))),
        })
}

/// A short number for an axis label: plain decimals between 1e-3 and 1e5, else `1e-4` style.
fn tick_label(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || (1e-3..1e5).contains(&a) {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        let s = format!("{v:.1e}");
        s.replace(".0e", "e")
    }
}

/// Ticks of a log axis over `[lo, hi]`: 1, 2 and 5 times the powers of ten, only the powers
/// when that gives more than 12.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let (k0, k1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let pick = |ms: &[f64]| -> Vec<f64> {
        (k0..=k1)
            .flat_map(|k| ms.iter().map(move |m| m * 10f64.powi(k)))
            .filter(|v| *v >= lo && *v <= hi)
            .collect()
    };
    let all = pick(&[1.0, 2.0, 5.0]);
    if all.len() > 12 {
        pick(&[1.0])
    } else {
        all
    }
}

/// Draws the chart of `$plot` on `$root` with the y coordinate `$y` (linear or log range).
macro_rules! draw_chart {
    ($root:expr, $plot:expr, $x:expr, $y:expr) => {{
        let p: &LinePlot = $plot;
        let mut chart = ChartBuilder::on($root)
            .caption(&p.title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(72)
            .build_cartesian_2d($x, $y)
            .map_err(|e| anyhow!("{e:?}"))?;
        chart
            .configure_mesh()
            .x_desc(p.x_label.as_str())
            .y_desc(p.y_label.as_str())
            .x_label_formatter(&|v: &f64| tick_label(*v))
            .y_label_formatter(&|v: &f64| tick_label(*v))
            .max_light_lines(0)
            .bold_line_style(RGBColor(230, 230, 230))
            .draw()
            .map_err(|e| anyhow!("{e:?}"))?;
        for (i, s) in p.series.iter().enumerate() {
            let [r, g, b] = s.color.unwrap_or(PALETTE[i % PALETTE.len()]);
            let style = RGBColor(r, g, b).stroke_width(2);
            let pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|q| q.0.is_finite() && q.1.is_finite() && (!p.log_y || q.1 > 0.0))
                .collect();
            let anno = if s.dashed {
                chart.draw_series(DashedLineSeries::new(pts.clone(), 10, 6, style))
            } else {
                chart.draw_series(LineSeries::new(pts.clone(), style))
            }
            .map_err(|e| anyhow!("{e:?}"))?;
            // a dashed series gets a gap in its legend line
            let gap = if s.dashed { 4 } else { 0 };
            anno.label(s.name.as_str()).legend(move |(x, y)| {
                let c = RGBColor(r, g, b).stroke_width(2);
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (8, 0)], c)
                    + PathElement::new(vec![(8 + gap, 0), (20, 0)], c)
            });
            chart
                .draw_series(
                    pts.iter()
                        .map(|&q| Circle::new(q, 3, RGBColor(r, g, b).filled())),
                )
                .map_err(|e| anyhow!("{e:?}"))?;
        }
        chart
            .configure_series_labels()
            .position(match p.legend {
                Legend::UpperRight => SeriesLabelPosition::UpperRight,
                Legend::MiddleLeft => SeriesLabelPosition::MiddleLeft,
            })
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(200, 200, 200))
            .draw()
            .map_err(|e| anyhow!("{e:?}"))?;
    }};
}

impl LinePlot {
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> LinePlot {
        LinePlot {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            log_y: false,
            series: Vec::new(),
            width: 720,
            height: 480,
            y_range: None,
            legend: Legend::UpperRight,
        }
    }

    /// Renders and writes an SVG file.
    pub fn write_svg(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let all = || self.series.iter().flat_map(|s| s.points.iter());
        let (x0, x1) = bounds(all().map(|q| q.0), false).unwrap_or((0.0, 1.0));
        let (x0, x1) = if x1 > x0 {
            (x0, x1)
        } else {
            (x0 - 0.5, x1 + 0.5)
        };
        let pad = 0.03 * (x1 - x0);
        let xr = (x0 - pad)..(x1 + pad);
        let (y0, y1) = self
            .y_range
            .or_else(|| bounds(all().map(|q| q.1), self.log_y))
            .unwrap_or((0.1, 1.0));
        let root =
            SVGBackend::new(path, (self.width.max(200), self.height.max(150))).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e:?}"))?;
        if self.log_y {
            let (y0, y1) = if y1 > y0 {
                (y0, y1)
            } else {
                (y0 * 0.5, y1 * 2.0)
            };
            let (y0, y1) = if self.y_range.is_some() {
                (y0, y1)
            } else {
                (y0 / 1.3, y1 * 1.3)
            };
            let ticks = log_ticks(y0, y1);
            draw_chart!(&root, self, xr, (y0..y1).log_scale().with_key_points(ticks));
        } else {
            let (y0, y1) = if y1 > y0 {
                (y0, y1)
            } else {
                (y0 - 0.5, y1 + 0.5)
            };
            let pad = 0.05 * (y1 - y0);
            draw_chart!(&root, self, xr, (y0 - pad)..(y1 + pad));
        }
        root.present()
            .map_err(|e| anyhow!("cannot write {}: {e:?}", path.display()))
    }
}
