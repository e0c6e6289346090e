//! Lat-long environment maps from OpenEXR or Radiance HDR files.
//!
//! Both formats store the top image row first, which is the convention of
//! [`Environment::LatLong`]: row 0 looks at +Y (up). Both hold linear radiance, so no colour
//! transform is applied; the texels are multiplied by the config's `intensity`.

use std::path::Path;

use glam::Vec3;

use super::Environment;

/// Larger maps are refused: 32K x 16K RGB f32 is already 6 GiB.
pub const MAX_ENV_SIDE: usize = 32768;

/// What loading an environment map produced, besides the map.
#[derive(Debug, Default)]
pub struct EnvMapReport {
    /// Texels that were NaN, infinite or negative and were replaced by black.
    pub replaced_texels: usize,
}

/// Loads `path` (.exr or .hdr, by extension) as an [`Environment::LatLong`] scaled by
/// `intensity`. Errors are plain messages; the caller adds the file name.
pub fn load_latlong(path: &Path, intensity: f32) -> Result<(Environment, EnvMapReport), String> {
    if !(intensity.is_finite() && intensity >= 0.0) {
        return Err(format!("intensity {intensity} must be finite and >= 0"));
    }
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let (width, height, mut texels) = match ext.as_str() {
        "exr" => read_exr(path)?,
        "hdr" => read_hdr(path)?,
        _ => return Err("unknown extension (expected .exr or .hdr)".to_owned()),
    };
    if width == 0 || height == 0 {
        return Err("the image is empty".to_owned());
    }
    let mut report = EnvMapReport::default();
    for t in &mut texels {
        let v = *t * intensity;
        if v.is_finite() && v.min_element() >= 0.0 {
            *t = v;
        } else {
            // A single NaN or negative texel would poison every pixel that samples the sky;
            // black is the conservative replacement, and the caller warns with the count.
            report.replaced_texels += 1;
            *t = Vec3::ZERO;
        }
    }
    Ok((
        Environment::LatLong {
            width: width as u32,
            height: height as u32,
            texels,
        },
        report,
    ))
}

type Pixels = (usize, usize, Vec<Vec3>);

fn read_exr(path: &Path) -> Result<Pixels, String> {
    use exr::prelude::*;
    if !path.is_file() {
        return Err("file not found".to_owned());
    }
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| {
            let (w, h) = (resolution.width(), resolution.height());
            if w > MAX_ENV_SIDE || h > MAX_ENV_SIDE {
                // Signalled to the caller by the empty buffer; avoids allocating.
                (w, h, Vec::new())
            } else {
                (w, h, vec![Vec3::ZERO; w * h])
            }
        },
        |px: &mut Pixels, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let (w, _, ref mut data) = *px;
            if let Some(t) = data.get_mut(pos.y() * w + pos.x()) {
                *t = Vec3::new(r, g, b);
            }
        },
    )
    .map_err(|e| format!("cannot read OpenEXR: {e}"))?;
    let (w, h, data) = image.layer_data.channel_data.pixels;
    if data.len() != w * h {
        return Err(format!(
            "{w}x{h} is larger than the supported {MAX_ENV_SIDE}x{MAX_ENV_SIDE}"
        ));
    }
    Ok((w, h, data))
}

fn read_hdr(path: &Path) -> Result<Pixels, String> {
    let reader = image::ImageReader::open(path)
        .map_err(|e| format!("cannot open: {e}"))?
        .with_guessed_format()
        .map_err(|e| format!("cannot read: {e}"))?;
    if reader.format() != Some(image::ImageFormat::Hdr) {
        return Err("not a Radiance HDR file".to_owned());
    }
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| format!("cannot read Radiance HDR header: {e}"))?;
    if w as usize > MAX_ENV_SIDE || h as usize > MAX_ENV_SIDE {
        return Err(format!(
            "{w}x{h} is larger than the supported {MAX_ENV_SIDE}x{MAX_ENV_SIDE}"
        ));
    }
    let img = image::ImageReader::open(path)
        .map_err(|e| format!("cannot open: {e}"))?
        .with_guessed_format()
        .map_err(|e| format!("cannot read: {e}"))?
        .decode()
        .map_err(|e| format!("cannot decode Radiance HDR: {e}"))?
        .to_rgb32f();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let texels = img
        .pixels()
        .map(|p| Vec3::new(p.0[0], p.0[1], p.0[2]))
        .collect();
    Ok((w, h, texels))
}

/// The unit direction a lat-long texel centre looks at (the convention of
/// [`Environment::LatLong`]): theta = pi v from +Y, phi = 2 pi (u - 0.5), direction
/// (sin theta sin phi, cos theta, -sin theta cos phi). The map's centre column looks down -Z.
pub fn latlong_direction(u: f32, v: f32) -> Vec3 {
    let theta = std::f32::consts::PI * v;
    let phi = 2.0 * std::f32::consts::PI * (u - 0.5);
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    Vec3::new(st * sp, ct, -st * cp)
}

/// The inverse of [`latlong_direction`]: (u, v) in [0,1]^2 for a unit direction.
pub fn latlong_uv(dir: Vec3) -> (f32, f32) {
    let theta = dir.y.clamp(-1.0, 1.0).acos();
    let phi = dir.x.atan2(-dir.z);
    let u = phi / (2.0 * std::f32::consts::PI) + 0.5;
    (u, theta / std::f32::consts::PI)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latlong_mapping_roundtrips_and_matches_the_documented_axes() {
        assert!(latlong_direction(0.5, 0.0).abs_diff_eq(Vec3::Y, 1e-6));
        assert!(latlong_direction(0.5, 0.5).abs_diff_eq(Vec3::NEG_Z, 1e-6));
        assert!(latlong_direction(0.75, 0.5).abs_diff_eq(Vec3::X, 1e-6));
        for &(u, v) in &[(0.1, 0.3), (0.6, 0.8), (0.9, 0.5)] {
            let (u2, v2) = latlong_uv(latlong_direction(u, v));
            assert!(
                (u - u2).abs() < 1e-5 && (v - v2).abs() < 1e-5,
                "{u} {v} -> {u2} {v2}"
            );
        }
    }
}
