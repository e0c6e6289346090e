//! Pictures of the reports: relit, reference and their difference side by side (PNG),
//! tone-mapped with one exposure.

use std::path::Path;

use anyhow::{Context, Result};
use image::{Rgb, RgbImage};
use prt_formats::image_io::tonemap_srgb8;

/// Exposure that maps the 95th percentile of the reference's largest channel to 0.8.
pub fn auto_exposure(reference: &[[f32; 3]]) -> f32 {
    let mut v: Vec<f32> = reference
        .iter()
        .map(|p| p[0].max(p[1]).max(p[2]))
        .filter(|v| v.is_finite())
        .collect();
    if v.is_empty() {
        return 1.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let p = v[(v.len() * 95 / 100).min(v.len() - 1)];
    if p > 0.0 {
        (0.8 / p).clamp(0.01, 1e4)
    } else {
        1.0
    }
}

/// How a side-by-side picture is drawn.
#[derive(Clone, Copy, Debug)]
pub struct Panels {
    /// Tone-mapping exposure, one for all three panels.
    pub exposure: f32,
    /// The difference panel's gain.
    pub gain: f32,
    /// Each panel averages `shrink x shrink` pixels (in linear RGB) into one, so the pictures
    /// in the docs stay small; 1 keeps every pixel.
    pub shrink: u32,
}

/// relit | reference | |relit - reference| x 10, tone-mapped with one exposure.
pub fn side_by_side(
    relit: &[[f32; 3]],
    reference: &[[f32; 3]],
    w: u32,
    h: u32,
    exposure: f32,
    path: &Path,
) -> Result<()> {
    let panels = Panels {
        exposure,
        gain: 10.0,
        shrink: 1,
    };
    side_by_side_with(relit, reference, w, h, panels, path)
}

/// relit | reference | |relit - reference| x `gain`, as `panels` says.
pub fn side_by_side_with(
    relit: &[[f32; 3]],
    reference: &[[f32; 3]],
    w: u32,
    h: u32,
    panels: Panels,
    path: &Path,
) -> Result<()> {
    let k = panels.shrink.max(1);
    let (pw, ph) = (w / k, h / k);
    let gap = 4u32;
    let mut img = RgbImage::from_pixel(3 * pw + 2 * gap, ph, Rgb([255, 255, 255]));
    let area = (k * k) as f32;
    for y in 0..ph {
        for x in 0..pw {
            let (mut a, mut b, mut d) = ([0.0f32; 3], [0.0f32; 3], [0.0f32; 3]);
            for dy in 0..k {
                for dx in 0..k {
                    let i = ((y * k + dy) * w + x * k + dx) as usize;
                    for c in 0..3 {
                        a[c] += relit[i][c] / area;
                        b[c] += reference[i][c] / area;
                        d[c] += (relit[i][c] - reference[i][c]).abs() * panels.gain / area;
                    }
                }
            }
            for (panel, v) in [a, b, d].iter().enumerate() {
                let px = Rgb(v.map(|c| tonemap_srgb8(c, panels.exposure)));
                img.put_pixel(panel as u32 * (pw + gap) + x, y, px);
            }
        }
    }
    img.save(path)
        .with_context(|| format!("writing {}", path.display()))
}
