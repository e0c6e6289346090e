//! A small PNG line-plot writer: several series, optional log-y axis, legend, axis labels and
//! a built-in 5x7 bitmap font (no font files, no extra dependencies beyond `image`).
//!
//! ```no_run
//! use prt_bake::plot::{LinePlot, Series};
//! let mut p = LinePlot::new("error vs N_b", "N_b", "relative L2 error");
//! p.log_y = true;
//! p.series.push(Series::new("ours", vec![(2.0, 0.3), (3.0, 0.1), (4.0, 0.03)]));
//! p.write_png("plot.png").unwrap();
//! ```

use image::{Rgb, RgbImage};
use std::path::Path;

/// One polyline with a legend entry.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Colour; `None` picks one from the palette by index.
    pub color: Option<[u8; 3]>,
    pub dashed: bool,
    pub markers: bool,
}

impl Series {
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.into(),
            points,
            color: None,
            dashed: false,
            markers: true,
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
        }
    }

    /// Renders and writes a PNG.
    pub fn write_png(&self, path: impl AsRef<Path>) -> Result<(), String> {
        let path = path.as_ref();
        self.render()
            .save(path)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))
    }

    /// Renders to an image.
    pub fn render(&self) -> RgbImage {
        let (w, h) = (self.width.max(200), self.height.max(150));
        let mut img = RgbImage::from_pixel(w, h, Rgb([255, 255, 255]));
        let scale = 2;
        let (left, right, top, bottom) = (80i64, 20i64, 40i64, 60i64);
        let (x0, x1, y0, y1) = (left, w as i64 - right, top, h as i64 - bottom);
        // data ranges
        let ty = |y: f64| if self.log_y { y.log10() } else { y };
        let pts: Vec<(f64, f64)> = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .filter(|&(x, y)| x.is_finite() && y.is_finite() && (!self.log_y || y > 0.0))
            .collect();
        let (mut xmin, mut xmax) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
            (a.0.min(p.0), a.1.max(p.0))
        });
        let (mut ymin, mut ymax) = match self.y_range {
            Some((a, b)) => (ty(a), ty(b)),
            None => pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
                (a.0.min(ty(p.1)), a.1.max(ty(p.1)))
            }),
        };
        if !(xmin.is_finite() && xmax.is_finite()) {
            (xmin, xmax) = (0.0, 1.0);
        }
        if !(ymin.is_finite() && ymax.is_finite()) {
            (ymin, ymax) = (0.0, 1.0);
        }
        if xmax - xmin <= 0.0 {
            xmax = xmin + 1.0;
        }
        if self.log_y {
            ymin = ymin.floor();
            ymax = ymax.ceil();
            if ymax - ymin < 1.0 {
                ymax = ymin + 1.0;
            }
        } else {
            if ymax - ymin <= 0.0 {
                ymax = ymin + 1.0;
            }
            let pad = 0.05 * (ymax - ymin);
            ymin -= pad;
            ymax += pad;
        }
        let px = |x: f64| x0 as f64 + (x - xmin) / (xmax - xmin) * (x1 - x0) as f64;
        let py = |y: f64| y1 as f64 - (ty(y) - ymin) / (ymax - ymin) * (y1 - y0) as f64;
        let grey = Rgb([220, 220, 220]);
        let black = Rgb([0, 0, 0]);
        // grid and ticks
        if self.log_y {
            for e in ymin as i64..=ymax as i64 {
                let yy = y1 as f64 - (e as f64 - ymin) / (ymax - ymin) * (y1 - y0) as f64;
                hline(&mut img, x0, x1, yy as i64, grey);
                let label = format!("1e{e}");
                draw_text(
                    &mut img,
                    x0 - 8 - text_width(&label, scale),
                    yy as i64 - 7,
                    &label,
                    scale,
                    black,
                );
                for m in 2..10 {
                    let v = e as f64 + (m as f64).log10();
                    if v < ymax {
                        let ym = y1 as f64 - (v - ymin) / (ymax - ymin) * (y1 - y0) as f64;
                        hline(&mut img, x0, x0 + 5, ym as i64, black);
                    }
                }
            }
        } else {
            for v in nice_ticks(ymin, ymax) {
                let yy = y1 as f64 - (v - ymin) / (ymax - ymin) * (y1 - y0) as f64;
                hline(&mut img, x0, x1, yy as i64, grey);
                let label = fmt_tick(v);
                draw_text(
                    &mut img,
                    x0 - 8 - text_width(&label, scale),
                    yy as i64 - 7,
                    &label,
                    scale,
                    black,
                );
            }
        }
        for v in nice_ticks(xmin, xmax) {
            let xx = px(v) as i64;
            vline(&mut img, xx, y0, y1, grey);
            let label = fmt_tick(v);
            draw_text(
                &mut img,
                xx - text_width(&label, scale) / 2,
                y1 + 6,
                &label,
                scale,
                black,
            );
        }
        // frame
        hline(&mut img, x0, x1, y0, black);
        hline(&mut img, x0, x1, y1, black);
        vline(&mut img, x0, y0, y1, black);
        vline(&mut img, x1, y0, y1, black);
        // labels
        draw_text(
            &mut img,
            (w as i64 - text_width(&self.title, scale)) / 2,
            10,
            &self.title,
            scale,
            black,
        );
        draw_text(
            &mut img,
            (x0 + x1 - text_width(&self.x_label, scale)) / 2,
            h as i64 - 24,
            &self.x_label,
            scale,
            black,
        );
        draw_text_vertical(
            &mut img,
            8,
            (y0 + y1 + text_width(&self.y_label, scale)) / 2,
            &self.y_label,
            scale,
            black,
        );
        // series
        for (si, s) in self.series.iter().enumerate() {
            let c = Rgb(s.color.unwrap_or(PALETTE[si % PALETTE.len()]));
            let p: Vec<(f64, f64)> = s
                .points
                .iter()
                .filter(|&&(x, y)| x.is_finite() && y.is_finite() && (!self.log_y || y > 0.0))
                .map(|&(x, y)| (px(x), py(y)))
                .collect();
            let mut dist = 0.0;
            for seg in p.windows(2) {
                dist = draw_line(
                    &mut img,
                    seg[0],
                    seg[1],
                    c,
                    s.dashed,
                    dist,
                    (x0, x1, y0, y1),
                );
            }
            if s.markers {
                for &(x, y) in &p {
                    for dy in -2..=2 {
                        for dx in -2..=2 {
                            put_clipped(
                                &mut img,
                                x as i64 + dx,
                                y as i64 + dy,
                                c,
                                (x0, x1, y0, y1),
                            );
                        }
                    }
                }
            }
        }
        // legend (top right, inside the frame)
        let lw = self
            .series
            .iter()
            .map(|s| text_width(&s.name, scale))
            .max()
            .unwrap_or(0)
            + 40;
        let lx = x1 - lw - 10;
        let mut ly = y0 + 8;
        if !self.series.is_empty() {
            let lh = self.series.len() as i64 * 18 + 6;
            for yy in ly - 4..ly - 4 + lh {
                for xx in lx - 6..x1 - 4 {
                    if xx >= 0 && yy >= 0 && (xx as u32) < w && (yy as u32) < h {
                        img.put_pixel(xx as u32, yy as u32, Rgb([255, 255, 255]));
                    }
                }
            }
        }
        for (si, s) in self.series.iter().enumerate() {
            let c = Rgb(s.color.unwrap_or(PALETTE[si % PALETTE.len()]));
            let clip = (0, w as i64 - 1, 0, h as i64 - 1);
            draw_line(
                &mut img,
                (lx as f64, ly as f64 + 7.0),
                (lx as f64 + 28.0, ly as f64 + 7.0),
                c,
                s.dashed,
                0.0,
                clip,
            );
            draw_text(&mut img, lx + 34, ly, &s.name, scale, black);
            ly += 18;
        }
        img
    }
}

fn fmt_tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-2..1e5).contains(&a) {
        let s = format!("{v:.3}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// About five round ticks covering [lo, hi].
fn nice_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = hi - lo;
    if !span.is_finite() || span <= 0.0 {
        return vec![lo];
    }
    let raw = span / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| span / s <= 6.0)
        .unwrap_or(10.0 * mag);
    let mut v = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while v <= hi + 1e-9 * step && out.len() < 20 {
        out.push(if v.abs() < 1e-12 * step { 0.0 } else { v });
        v += step;
    }
    out
}

fn put_clipped(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>, clip: (i64, i64, i64, i64)) {
    if x >= clip.0
        && x <= clip.1
        && y >= clip.2
        && y <= clip.3
        && x >= 0
        && y >= 0
        && (x as u32) < img.width()
        && (y as u32) < img.height()
    {
        img.put_pixel(x as u32, y as u32, c);
    }
}

fn hline(img: &mut RgbImage, x0: i64, x1: i64, y: i64, c: Rgb<u8>) {
    for x in x0..=x1 {
        put_clipped(img, x, y, c, (0, i64::MAX, 0, i64::MAX));
    }
}

fn vline(img: &mut RgbImage, x: i64, y0: i64, y1: i64, c: Rgb<u8>) {
    for y in y0..=y1 {
        put_clipped(img, x, y, c, (0, i64::MAX, 0, i64::MAX));
    }
}

/// 2-pixel-wide line; returns the dash phase at the end.
fn draw_line(
    img: &mut RgbImage,
    a: (f64, f64),
    b: (f64, f64),
    c: Rgb<u8>,
    dashed: bool,
    mut dist: f64,
    clip: (i64, i64, i64, i64),
) -> f64 {
    let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
    let steps = (len * 2.0).ceil().max(1.0) as usize;
    for k in 0..=steps {
        let t = k as f64 / steps as f64;
        let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
        let d = dist + t * len;
        if dashed && (d / 8.0) as i64 % 2 == 1 {
            continue;
        }
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            put_clipped(img, x as i64 + dx, y as i64 + dy, c, clip);
        }
    }
    dist += len;
    dist
}

/// Width in pixels of `s` drawn at `scale`.
pub fn text_width(s: &str, scale: i64) -> i64 {
    s.chars().count() as i64 * 6 * scale
}

fn draw_text(img: &mut RgbImage, x: i64, y: i64, s: &str, scale: i64, c: Rgb<u8>) {
    for (n, ch) in s.chars().enumerate() {
        let g = glyph(ch);
        for (row, bits) in g.iter().enumerate() {
            for col in 0..5 {
                if bits & (0x10 >> col) != 0 {
                    for sy in 0..scale {
                        for sx in 0..scale {
                            let px = x + (n as i64 * 6 + col) * scale + sx;
                            let py = y + row as i64 * scale + sy;
                            put_clipped(img, px, py, c, (0, i64::MAX, 0, i64::MAX));
                        }
                    }
                }
            }
        }
    }
}

/// Text rotated 90 degrees counter-clockwise, starting at (x, y_bottom) going up.
fn draw_text_vertical(img: &mut RgbImage, x: i64, y_bottom: i64, s: &str, scale: i64, c: Rgb<u8>) {
    for (n, ch) in s.chars().enumerate() {
        let g = glyph(ch);
        for (row, bits) in g.iter().enumerate() {
            for col in 0..5 {
                if bits & (0x10 >> col) != 0 {
                    for sy in 0..scale {
                        for sx in 0..scale {
                            let px = x + row as i64 * scale + sx;
                            let py = y_bottom - (n as i64 * 6 + col) * scale - sy;
                            put_clipped(img, px, py, c, (0, i64::MAX, 0, i64::MAX));
                        }
                    }
                }
            }
        }
    }
}

/// 5x7 glyph rows (bit 4 = leftmost column); unknown characters draw as '?'.
fn glyph(c: char) -> [u8; 7] {
    match c {
        ' ' => [0, 0, 0, 0, 0, 0, 0],
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        'A' => [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'B' => [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        'C' => [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        'D' => [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C],
        'E' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        'F' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        'G' => [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        'H' => [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'I' => [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'M' => [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'Q' => [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
        'R' => [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        'S' => [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        'T' => [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
        'X' => [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
        'Z' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
        'a' => [0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F],
        'b' => [0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x1E],
        'c' => [0x00, 0x00, 0x0E, 0x10, 0x10, 0x11, 0x0E],
        'd' => [0x01, 0x01, 0x0D, 0x13, 0x11, 0x11, 0x0F],
        'e' => [0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E],
        'f' => [0x06, 0x09, 0x08, 0x1C, 0x08, 0x08, 0x08],
        'g' => [0x00, 0x0F, 0x11, 0x11, 0x0F, 0x01, 0x0E],
        'h' => [0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11],
        'i' => [0x04, 0x00, 0x0C, 0x04, 0x04, 0x04, 0x0E],
        'j' => [0x02, 0x00, 0x06, 0x02, 0x02, 0x12, 0x0C],
        'k' => [0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12],
        'l' => [0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'm' => [0x00, 0x00, 0x1A, 0x15, 0x15, 0x11, 0x11],
        'n' => [0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11],
        'o' => [0x00, 0x00, 0x0E, 0x11, 0x11, 0x11, 0x0E],
        'p' => [0x00, 0x00, 0x1E, 0x11, 0x1E, 0x10, 0x10],
        'q' => [0x00, 0x00, 0x0D, 0x13, 0x0F, 0x01, 0x01],
        'r' => [0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10],
        's' => [0x00, 0x00, 0x0E, 0x10, 0x0E, 0x01, 0x1E],
        't' => [0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06],
        'u' => [0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x0D],
        'v' => [0x00, 0x00, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'w' => [0x00, 0x00, 0x11, 0x11, 0x15, 0x15, 0x0A],
        'x' => [0x00, 0x00, 0x11, 0x0A, 0x04, 0x0A, 0x11],
        'y' => [0x00, 0x00, 0x11, 0x11, 0x0F, 0x01, 0x0E],
        'z' => [0x00, 0x00, 0x1F, 0x02, 0x04, 0x08, 0x1F],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C],
        ',' => [0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08],
        '-' => [0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00],
        '+' => [0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00],
        '=' => [0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00],
        '_' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '[' => [0x0E, 0x08, 0x08, 0x08, 0x08, 0x08, 0x0E],
        ']' => [0x0E, 0x02, 0x02, 0x02, 0x02, 0x02, 0x0E],
        '/' => [0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00],
        ':' => [0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00],
        ';' => [0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x04, 0x08],
        '%' => [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03],
        '^' => [0x04, 0x0A, 0x11, 0x00, 0x00, 0x00, 0x00],
        '*' => [0x00, 0x04, 0x15, 0x0E, 0x15, 0x04, 0x00],
        '<' => [0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02],
        '>' => [0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08],
        '!' => [0x04, 0x04, 0x04, 0x04, 0x04, 0x00, 0x04],
        '\'' => [0x04, 0x04, 0x08, 0x00, 0x00, 0x00, 0x00],
        '"' => [0x0A, 0x0A, 0x00, 0x00, 0x00, 0x00, 0x00],
        '#' => [0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A],
        '|' => [0x04, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        '~' => [0x00, 0x00, 0x08, 0x15, 0x02, 0x00, 0x00],
        _ => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_log_plot_with_legend() {
        let mut p = LinePlot::new("Test plot", "x", "y (log)");
        p.log_y = true;
        p.series
            .push(Series::new("a", vec![(1.0, 1.0), (2.0, 0.1), (3.0, 0.01)]));
        p.series
            .push(Series::new("b", vec![(1.0, 0.5), (3.0, 0.05)]).dashed());
        p.series
            .push(Series::new("bad", vec![(1.0, f64::NAN), (2.0, -1.0)]));
        let img = p.render();
        assert_eq!(img.width(), 720);
        let coloured = img.pixels().filter(|px| px.0 == PALETTE[0]).count();
        assert!(coloured > 50);
    }

    #[test]
    fn ticks_are_round() {
        let t = nice_ticks(0.0, 10.0);
        assert_eq!(t, vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
    }
}
