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

/// Why an environment map cannot be used. The caller ([`crate::scene::SceneError`]) adds the
/// file name.
#[derive(Debug, thiserror::Error)]
pub enum EnvMapError {
    #[error("intensity {0} must be finite and >= 0")]
    Intensity(f32),
    #[error("unknown extension (expected .exr or .hdr)")]
    Extension,
    #[error("the image is empty")]
    Empty,
    #[error("{width}x{height} is larger than the supported {MAX_ENV_SIDE}x{MAX_ENV_SIDE}")]
    TooLarge { width: usize, height: usize },
    /// The OpenEXR file is missing, unreadable or malformed.
    #[error("cannot read OpenEXR: {reason}")]
    Exr { reason: String },
    #[error("cannot open: {0}")]
    Open(#[source] std::io::Error),
    #[error("cannot read: {0}")]
    Read(#[source] std::io::Error),
    #[error("not a Radiance HDR file")]
    NotHdr,
    #[error("cannot read Radiance HDR header: {0}")]
    HdrHeader(#[source] image::ImageError),
    #[error("cannot decode Radiance HDR: {0}")]
    HdrDecode(#[source] image::ImageError),
}

/// What loading an environment map produced, besides the map.
#[derive(Debug, Default)]
pub struct EnvMapReport {
    /// Texels that were NaN, infinite or negative and were replaced by black.
    pub replaced_texels: usize,
}

/// Loads `path` (.exr or .hdr, by extension) as an [`Environment::LatLong`] scaled by
/// `intensity`. Errors do not repeat the file name; the caller adds it.
pub fn load_latlong(
    path: &Path,
    intensity: f32,
) -> Result<(Environment, EnvMapReport), EnvMapError> {
    if !(intensity.is_finite() && intensity >= 0.0) {
        return Err(EnvMapError::Intensity(intensity));
    }
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let (width, height, mut texels) = match ext.as_str() {
        "exr" => read_exr(path)?,
        "hdr" => read_hdr(path)?,
        _ => return Err(EnvMapError::Extension),
    };
    if width == 0 || height == 0 {
        return Err(EnvMapError::Empty);
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

/// Reads the first RGB(A) layer through [`prt_formats::read_exr_rgb`], after checking the
/// header's sizes (so a corrupt or hostile header cannot make us allocate gigabytes).
fn read_exr(path: &Path) -> Result<Pixels, EnvMapError> {
    use prt_formats::ImageIoError;
    let exr_err = |e: ImageIoError| EnvMapError::Exr {
        reason: match e {
            ImageIoError::Read { reason, .. } => reason,
            other => other.to_string(),
        },
    };
    if path.is_file() {
        let meta =
            exr::meta::MetaData::read_from_file(path, false).map_err(|e| EnvMapError::Exr {
                reason: e.to_string(),
            })?;
        for header in meta.headers.iter() {
            let (w, h) = (header.layer_size.width(), header.layer_size.height());
            if w > MAX_ENV_SIDE || h > MAX_ENV_SIDE {
                return Err(EnvMapError::TooLarge {
                    width: w,
                    height: h,
                });
            }
        }
    }
    let (w, h, data) = prt_formats::read_exr_rgb(path).map_err(exr_err)?;
    Ok((w, h, data.into_iter().map(Vec3::from_array).collect()))
}

fn read_hdr(path: &Path) -> Result<Pixels, EnvMapError> {
    let open = || -> Result<_, EnvMapError> {
        image::ImageReader::open(path)
            .map_err(EnvMapError::Open)?
            .with_guessed_format()
            .map_err(EnvMapError::Read)
    };
    let reader = open()?;
    if reader.format() != Some(image::ImageFormat::Hdr) {
        return Err(EnvMapError::NotHdr);
    }
    let (w, h) = reader.into_dimensions().map_err(EnvMapError::HdrHeader)?;
    if w as usize > MAX_ENV_SIDE || h as usize > MAX_ENV_SIDE {
        return Err(EnvMapError::TooLarge {
            width: w as usize,
            height: h as usize,
        });
    }
    let img = open()?
        .decode()
        .map_err(EnvMapError::HdrDecode)?
        .to_rgb32f();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let texels = img
        .pixels()
        .map(|p| Vec3::new(p.0[0], p.0[1], p.0[2]))
        .collect();
    Ok((w, h, texels))
}
