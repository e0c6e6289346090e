//! Lat-long environment maps: loading them from OpenEXR or Radiance HDR files (feature
//! `image-io`), and checking maps handed over in memory. Shared by the baker (its scene's
//! environment) and the runtime (`relight --env`), so both accept and refuse the same maps.
//!
//! Both formats store the top image row first, the convention of [`crate::latlong`]: row 0
//! looks at +Y (up). Both hold linear radiance, so no colour transform is applied; the texels
//! are multiplied by `intensity`.
//!
//! **Policy for bad texels.** A NaN or infinite texel is refused with an error naming it: it
//! would poison every pixel that sees or samples the sky, and no replacement is right.
//! Negative channels are clamped to 0 and counted: lossy EXR compression (DWA, PXR24) rings
//! around bright spots and leaves small negative values next to them; radiance cannot be
//! negative, and the callers warn with the count.

#[cfg(feature = "image-io")]
use std::path::Path;

/// Larger maps are refused: 32K x 16K RGB f32 is already 6 GiB.
pub const MAX_ENV_SIDE: usize = 32768;

/// A lat-long radiance map in the convention of [`crate::latlong`]: row-major, top row (+Y)
/// first, linear RGB, every channel finite and >= 0.
#[derive(Debug, Clone, PartialEq)]
pub struct LatLongMap {
    /// Texels per row (>= 1).
    pub width: usize,
    /// Rows (>= 1).
    pub height: usize,
    /// `width * height` texels.
    pub texels: Vec<[f32; 3]>,
}

/// What loading a map changed, besides scaling.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct EnvMapReport {
    /// Texels with at least one negative channel, clamped to 0 (see the module docs).
    pub clamped_texels: usize,
}

/// Why an environment map cannot be used. The file name is added by the caller.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EnvMapError {
    /// The intensity multiplier is negative or not finite.
    #[error("intensity {0} must be finite and >= 0")]
    Intensity(f32),
    /// Neither `.exr` nor `.hdr`.
    #[error("unknown extension (expected .exr or .hdr)")]
    Extension,
    /// No texels.
    #[error("the image is empty")]
    Empty,
    /// Larger than [`MAX_ENV_SIDE`] on a side.
    #[error("{width}x{height} is larger than the supported {MAX_ENV_SIDE}x{MAX_ENV_SIDE}")]
    TooLarge {
        /// Width in texels.
        width: usize,
        /// Height in texels.
        height: usize,
    },
    /// The texel count does not match the size (an in-memory map).
    #[error("{texels} texels for a {width}x{height} map")]
    Size {
        /// Width in texels.
        width: usize,
        /// Height in texels.
        height: usize,
        /// Texels given.
        texels: usize,
    },
    /// Some texel is NaN or infinite (after scaling by the intensity).
    #[error(
        "{count} texel(s) are NaN or infinite, the first at column {x}, row {y}: the map \
         cannot light anything"
    )]
    NonFinite {
        /// How many texels.
        count: usize,
        /// Column of the first.
        x: usize,
        /// Row of the first (0 = top).
        y: usize,
    },
    /// The OpenEXR file is missing, unreadable or malformed.
    #[error("cannot read OpenEXR: {reason}")]
    Exr {
        /// The reader's message.
        reason: String,
    },
    /// The file cannot be opened.
    #[error("cannot open: {0}")]
    Open(#[source] std::io::Error),
    /// The file cannot be read.
    #[error("cannot read: {0}")]
    Read(#[source] std::io::Error),
    /// A `.hdr` file that is not Radiance HDR.
    #[error("not a Radiance HDR file")]
    NotHdr,
    /// The Radiance HDR header is malformed.
    #[cfg(feature = "image-io")]
    #[error("cannot read Radiance HDR header: {0}")]
    HdrHeader(#[source] image::ImageError),
    /// The Radiance HDR pixels are malformed.
    #[cfg(feature = "image-io")]
    #[error("cannot decode Radiance HDR: {0}")]
    HdrDecode(#[source] image::ImageError),
}

/// Loads `path` (.exr or .hdr, by extension) scaled by `intensity`, and checks it as
/// [`LatLongMap::new`] does. Errors do not repeat the file name; the caller adds it.
#[cfg(feature = "image-io")]
pub fn load_latlong(
    path: &Path,
    intensity: f32,
) -> Result<(LatLongMap, EnvMapReport), EnvMapError> {
    if !(intensity.is_finite() && intensity >= 0.0) {
        return Err(EnvMapError::Intensity(intensity));
    }
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let (width, height, texels) = match ext.as_str() {
        "exr" => read_exr(path)?,
        "hdr" => read_hdr(path)?,
        _ => return Err(EnvMapError::Extension),
    };
    LatLongMap::new(width, height, texels, intensity)
}

impl LatLongMap {
    /// A map from texels in memory (row-major, top row first), scaled by `intensity`: refuses
    /// an empty or oversized map, a texel count that does not match, and NaN or infinite
    /// texels; clamps negative channels to 0 (counted in the report).
    pub fn new(
        width: usize,
        height: usize,
        mut texels: Vec<[f32; 3]>,
        intensity: f32,
    ) -> Result<(LatLongMap, EnvMapReport), EnvMapError> {
        if !(intensity.is_finite() && intensity >= 0.0) {
            return Err(EnvMapError::Intensity(intensity));
        }
        if width == 0 || height == 0 {
            return Err(EnvMapError::Empty);
        }
        if width > MAX_ENV_SIDE || height > MAX_ENV_SIDE {
            return Err(EnvMapError::TooLarge { width, height });
        }
        if texels.len() != width * height {
            return Err(EnvMapError::Size {
                width,
                height,
                texels: texels.len(),
            });
        }
        let mut report = EnvMapReport::default();
        let mut non_finite = 0usize;
        let mut first = None;
        for (i, t) in texels.iter_mut().enumerate() {
            let scaled = t.map(|c| c * intensity);
            if scaled.iter().any(|c| !c.is_finite()) {
                non_finite += 1;
                first.get_or_insert(i);
                continue;
            }
            if scaled.iter().any(|&c| c < 0.0) {
                report.clamped_texels += 1;
            }
            *t = scaled.map(|c| c.max(0.0));
        }
        if let Some(i) = first {
            return Err(EnvMapError::NonFinite {
                count: non_finite,
                x: i % width,
                y: i / width,
            });
        }
        Ok((
            LatLongMap {
                width,
                height,
                texels,
            },
            report,
        ))
    }
}

#[cfg(feature = "image-io")]
type Pixels = (usize, usize, Vec<[f32; 3]>);

/// Reads the first RGB(A) layer through [`crate::read_exr_rgb`], after checking the header's
/// sizes (so a corrupt or hostile header cannot make us allocate gigabytes).
#[cfg(feature = "image-io")]
fn read_exr(path: &Path) -> Result<Pixels, EnvMapError> {
    use crate::ImageIoError;
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
    crate::read_exr_rgb(path).map_err(exr_err)
}

#[cfg(feature = "image-io")]
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
    let texels = img.pixels().map(|p| p.0).collect();
    Ok((w, h, texels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_memory_maps_are_checked_scaled_and_clamped() {
        let (map, report) =
            LatLongMap::new(2, 1, vec![[1.0, -0.5, 2.0], [0.0, 0.0, 0.0]], 2.0).expect("valid map");
        assert_eq!(map.texels, vec![[2.0, 0.0, 4.0], [0.0, 0.0, 0.0]]);
        assert_eq!(report.clamped_texels, 1);
        let err = |r: Result<(LatLongMap, EnvMapReport), EnvMapError>| match r {
            Err(e) => e.to_string(),
            Ok(_) => panic!("must be refused"),
        };
        assert!(err(LatLongMap::new(0, 1, vec![], 1.0)).contains("empty"));
        assert!(err(LatLongMap::new(2, 2, vec![[0.0; 3]; 3], 1.0)).contains("3 texels"));
        assert!(err(LatLongMap::new(1, 1, vec![[1.0; 3]], -1.0)).contains("intensity"));
        assert!(err(LatLongMap::new(1, 1, vec![[1.0; 3]], f32::NAN)).contains("intensity"));
        let e = err(LatLongMap::new(
            3,
            2,
            vec![
                [1.0; 3],
                [1.0; 3],
                [1.0; 3],
                [1.0; 3],
                [f32::NAN, 0.0, 0.0],
                [0.0, f32::INFINITY, 0.0],
            ],
            1.0,
        ));
        assert!(
            e.contains("2 texel(s)") && e.contains("column 1, row 1"),
            "{e}"
        );
        // Finite texels that overflow when scaled are refused too.
        let e = err(LatLongMap::new(1, 1, vec![[3e38; 3]], 10.0));
        assert!(e.contains("NaN or infinite"), "{e}");
        assert!(err(LatLongMap::new(MAX_ENV_SIDE + 1, 1, vec![], 1.0)).contains("larger"));
    }
}
