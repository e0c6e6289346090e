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

/// relit | reference | |relit - reference| x 10, tone-mapped with one exposure.
pub fn side_by_side(
    relit: &[[f32; 3]],
    reference: &[[f32; 3]],
    w: u32,
    h: u32,
    exposure: f32,
    path: &Path,
) -> Result<()> {
    let gap = 4u32;
    let mut img = RgbImage::from_pixel(3 * w + 2 * gap, h, Rgb([255, 255, 255]));
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let (a, b) = (relit[i], reference[i]);
            let d = [
                (a[0] - b[0]).abs() * 10.0,
                (a[1] - b[1]).abs() * 10.0,
                (a[2] - b[2]).abs() * 10.0,
            ];
            for (panel, v) in [a, b, d].iter().enumerate() {
                let px = Rgb(v.map(|c| tonemap_srgb8(c, exposure)));
                img.put_pixel(panel as u32 * (w + gap) + x, y, px);
            }
        }
    }
    img.save(path)
        .with_context(|| format!("writing {}", path.display()))
}
