//! A linear frame turned into what the page draws (8-bit RGBA, or a PNG of it) and what
//! "save" downloads (EXR, PNG), through the one display encoding `relight` writes PNGs with
//! (`prt_formats::image_io::tonemap_srgb8_with`, here through its table `Srgb8Table`, the
//! same bytes without a `powf` per channel), so the canvas shows the bytes of the command's
//! PNG.

use prt_formats::{Srgb8Table, ToneCurve};
use rayon::prelude::*;

use crate::ViewerError;

/// Tone-maps a linear frame (`3 * width * height` floats) into `out` as 8-bit RGBA (alpha
/// 255), the layout of a canvas' `ImageData`.
pub fn rgba8(linear: &[f32], exposure: f32, curve: ToneCurve, out: &mut Vec<u8>) {
    let pixels = linear.len() / 3;
    out.resize(4 * pixels, 0);
    let table = Srgb8Table::shared();
    // Rows of 1024 pixels per task: enough work to share between threads, few tasks.
    out.par_chunks_mut(4 * 1024)
        .zip(linear.par_chunks(3 * 1024))
        .for_each(|(o, l)| table.tonemap_rgba8(l, exposure, curve, o));
}

/// `|a - b|` per channel (the reference's difference view, tone-mapped like the images).
pub fn abs_difference(a: &[f32], b: &[f32]) -> Vec<f32> {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).collect()
}

/// A PNG of 8-bit RGBA pixels, compressed fast (a frame, not an archive).
pub fn png_rgba(width: u32, height: u32, rgba: &[u8]) -> Result<Vec<u8>, ViewerError> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Sub)
        .write_image(rgba, width, height, image::ExtendedColorType::Rgba8)
        .map_err(|e| ViewerError::Encode(e.to_string()))?;
    Ok(out)
}

/// The file "save" gives: the frame as `relight --out NAME.exr` (linear) or `.png`
/// (tone-mapped) writes it, through the same writer; `extension` is `exr` or `png`.
pub fn image_file(
    width: u32,
    height: u32,
    linear: &[f32],
    exposure: f32,
    curve: ToneCurve,
    extension: &str,
) -> Result<Vec<u8>, ViewerError> {
    let dir = tempfile::tempdir().map_err(|e| ViewerError::Encode(e.to_string()))?;
    let path = dir.path().join(format!("frame.{extension}"));
    let rgb = linear.as_chunks::<3>().0;
    prt_formats::write_image_with(&path, width as usize, height as usize, rgb, exposure, curve)
        .map_err(|e| ViewerError::Encode(e.to_string()))?;
    std::fs::read(&path).map_err(|e| ViewerError::Encode(e.to_string()))
}
