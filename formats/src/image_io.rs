//! Image output shared by the runtime (`relight`) and the baker (`reference`): linear EXR for
//! measurements, tone-mapped PNG for looking at. Every writer is atomic (temporary file, fsync,
//! rename; see [`crate::container::write_file_atomic`]), so an interrupted render never leaves a
//! half-written image behind and a failed write leaves the previous image untouched.
//!
//! Pixels are `[f32; 3]` linear RGB in row-major order, top row first (`rgb[y * width + x]`).

use std::io;
use std::path::{Path, PathBuf};

use exr::prelude::{
    Encoding, Image, ReadChannels, ReadLayers, SpecificChannels, Vec2, WritableImage,
};

use crate::container::write_file_atomic;

/// Sample type of an EXR file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ExrPrecision {
    /// 32-bit float: lossless for our f32 renders (the default; use for measurements).
    #[default]
    F32,
    /// 16-bit half float: half the size; finite values beyond ±65504 saturate to ±65504
    /// instead of becoming infinite (NaN and infinities are kept as they are).
    F16,
}

/// Everything that can go wrong writing or reading an image. Every error names the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImageIoError {
    /// The extension is neither `.exr` nor `.png` (nothing was written).
    #[error(
        "cannot write {}: unsupported image extension {}; use .exr (linear radiance) or .png \
         (tone-mapped)",
        .path.display(),
        .ext.as_deref().map_or("(none)".to_string(), |e| format!("'.{e}'"))
    )]
    UnsupportedExtension {
        /// The file concerned.
        path: PathBuf,
        /// The extension given, if any.
        ext: Option<String>,
    },
    /// The pixel slice does not hold `width * height` pixels.
    #[error(
        "cannot write {}: a {width}x{height} image needs {} pixels, but {len} were given",
        .path.display(), (*.width as u128) * (*.height as u128)
    )]
    SizeMismatch {
        /// The file concerned.
        path: PathBuf,
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
        /// Number of pixels given.
        len: usize,
    },
    /// The image has no pixels.
    #[error("cannot write {}: the image is empty ({width}x{height})", .path.display())]
    Empty {
        /// The file concerned.
        path: PathBuf,
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
    },
    /// The size does not fit the format (EXR stores coordinates as i32, PNG as u32).
    #[error("cannot write {}: {width}x{height} is too large for the format", .path.display())]
    TooLarge {
        /// The file concerned.
        path: PathBuf,
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
    },
    /// The exposure multiplier is negative or not finite.
    #[error(
        "cannot write {}: exposure must be a finite number >= 0, got {exposure}",
        .path.display()
    )]
    BadExposure {
        /// The file concerned.
        path: PathBuf,
        /// The exposure given.
        exposure: f32,
    },
    /// Encoding, writing, syncing or renaming the file failed.
    #[error("cannot write image {}: {source}", .path.display())]
    Write {
        /// The file concerned.
        path: PathBuf,
        /// The underlying I/O error.
        source: io::Error,
    },
    /// The file is missing, not a regular file, or not a readable EXR with an RGB layer.
    #[error("cannot read EXR {}: {reason}", .path.display())]
    Read {
        /// The file concerned.
        path: PathBuf,
        /// What went wrong (the EXR decoder's message, or why the path is unusable).
        reason: String,
    },
}

type Result<T, E = ImageIoError> = std::result::Result<T, E>;

fn check_size(path: &Path, width: usize, height: usize, len: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(ImageIoError::Empty {
            path: path.to_path_buf(),
            width,
            height,
        });
    }
    if width.checked_mul(height) != Some(len) {
        return Err(ImageIoError::SizeMismatch {
            path: path.to_path_buf(),
            width,
            height,
            len,
        });
    }
    Ok(())
}

fn write_err(path: &Path) -> impl FnOnce(io::Error) -> ImageIoError + '_ {
    move |source| ImageIoError::Write {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes scene-linear RGB as a 32-bit float EXR (ZIP compressed, lossless).
pub fn write_exr(
    path: impl AsRef<Path>,
    width: usize,
    height: usize,
    rgb: &[[f32; 3]],
) -> Result<()> {
    write_exr_with(path, width, height, rgb, ExrPrecision::F32)
}

/// Writes scene-linear RGB as an EXR with the given sample precision (ZIP compressed).
pub fn write_exr_with(
    path: impl AsRef<Path>,
    width: usize,
    height: usize,
    rgb: &[[f32; 3]],
    precision: ExrPrecision,
) -> Result<()> {
    let path = path.as_ref();
    check_size(path, width, height, rgb.len())?;
    // EXR stores coordinates as i32.
    if i32::try_from(width).is_err() || i32::try_from(height).is_err() {
        return Err(ImageIoError::TooLarge {
            path: path.to_path_buf(),
            width,
            height,
        });
    }
    // ZIP over 16 scanlines: renders are noisy, which defeats run-length coding, and every EXR
    // reader supports scanline ZIP.
    let encoding = Encoding::SMALL_LOSSLESS;
    // The encoder only asks for positions inside (width, height), and the length was checked;
    // `get` keeps even a misbehaving encoder from causing a panic.
    let pixel = move |Vec2(x, y): Vec2<usize>| rgb.get(y * width + x).copied().unwrap_or_default();
    write_file_atomic(path, |w| {
        let result = match precision {
            ExrPrecision::F32 => {
                let channels = SpecificChannels::rgb(|p| {
                    let [r, g, b] = pixel(p);
                    (r, g, b)
                });
                Image::from_encoded_channels((width, height), encoding, channels)
                    .write()
                    .to_buffered(w)
            }
            ExrPrecision::F16 => {
                let channels = SpecificChannels::rgb(|p| {
                    let [r, g, b] = pixel(p);
                    (
                        to_f16_saturating(r),
                        to_f16_saturating(g),
                        to_f16_saturating(b),
                    )
                });
                Image::from_encoded_channels((width, height), encoding, channels)
                    .write()
                    .to_buffered(w)
            }
        };
        result.map_err(|e| io::Error::other(format!("EXR encoder: {e}")))
    })
    .map_err(write_err(path))
}

/// f32 -> f16 that keeps finite values finite (saturating at ±65504, the largest half).
fn to_f16_saturating(v: f32) -> half::f16 {
    if v.is_finite() {
        half::f16::from_f32(v.clamp(-65504.0, 65504.0))
    } else {
        half::f16::from_f32(v)
    }
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1), for linear values in [0, 1].
pub fn srgb_oetf(linear: f32) -> f32 {
    if linear <= 0.003_130_8 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    }
}

/// The tone curve a PNG (and the viewer's canvas) applies after the exposure and before the
/// sRGB encoding: how scene radiances above 1 are shown.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ToneCurve {
    /// Clip to [0, 1] (the default): radiances up to 1 are shown as they are, brighter ones
    /// saturate.
    #[default]
    Clamp,
    /// Reinhard's `x / (1 + x)`: every radiance stays distinguishable, mid-tones darken.
    Reinhard,
    /// Narkowicz's fit of the ACES filmic curve, `x (2.51 x + 0.03) / (x (2.43 x + 0.59) +
    /// 0.14)` clipped to [0, 1]: a toe and a soft shoulder.
    Aces,
}

impl ToneCurve {
    /// Every curve, in the order a picker lists them.
    pub const ALL: [ToneCurve; 3] = [ToneCurve::Clamp, ToneCurve::Reinhard, ToneCurve::Aces];

    /// The curve's name as `relight --tone` takes it.
    pub fn name(self) -> &'static str {
        match self {
            ToneCurve::Clamp => "clamp",
            ToneCurve::Reinhard => "reinhard",
            ToneCurve::Aces => "aces",
        }
    }

    /// The curve at a linear value `v >= 0` (after the exposure), in [0, 1].
    pub fn apply(self, v: f32) -> f32 {
        match self {
            ToneCurve::Clamp => v.min(1.0),
            ToneCurve::Reinhard => v / (1.0 + v),
            ToneCurve::Aces => {
                let t = v * (2.51 * v + 0.03) / (v * (2.43 * v + 0.59) + 0.14);
                t.clamp(0.0, 1.0)
            }
        }
    }
}

impl std::fmt::Display for ToneCurve {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for ToneCurve {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        ToneCurve::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = ToneCurve::ALL.iter().map(|c| c.name()).collect();
                format!("unknown tone curve '{s}' (use {})", names.join(", "))
            })
    }
}

/// Display encoding of one linear channel: scale by `exposure`, clamp to [0, 1] (NaN and
/// negative values give 0), sRGB OETF, round to 8 bits.
pub fn tonemap_srgb8(linear: f32, exposure: f32) -> u8 {
    tonemap_srgb8_with(linear, exposure, ToneCurve::Clamp)
}

/// Display encoding of one linear channel through `curve`: scale by `exposure`, negative and
/// NaN values to 0, the curve (into [0, 1]), sRGB OETF, round to 8 bits.
pub fn tonemap_srgb8_with(linear: f32, exposure: f32, curve: ToneCurve) -> u8 {
    srgb8_of_display(display_value(linear, exposure, curve))
}

/// The first half of [`tonemap_srgb8_with`]: the value shown, in [0, 1].
fn display_value(linear: f32, exposure: f32, curve: ToneCurve) -> f32 {
    let v = linear * exposure;
    // `!(v > 0.0)` also catches NaN. Capped so that no curve's arithmetic overflows (ACES
    // squares it): every curve is 1 long before 1e18, so an infinite radiance shows white.
    if v > 0.0 {
        curve.apply(v.min(1e18))
    } else {
        0.0
    }
}

/// The second half of [`tonemap_srgb8_with`]: a shown value in [0, 1] to its 8-bit sRGB level.
fn srgb8_of_display(y: f32) -> u8 {
    (srgb_oetf(y) * 255.0 + 0.5) as u8
}

/// [`tonemap_srgb8_with`] through a table instead of a `powf` per channel, giving the same
/// bytes: for tone-mapping whole frames many times a second (the viewer's canvas). The level
/// of a shown value `y` in [0, 1] is the number of level edges at or below it; a bucket per
/// 2^16 `f32` bit patterns holds the level at its start and no bucket holds two edges, so a
/// lookup is two loads and one comparison, without a branch. Exact because the level never decreases as `y` grows (checked
/// at every edge and on a fine sweep of [0, 1] in the tests); `relight` keeps the direct
/// formula, so the browser check compares two independent computations.
#[derive(Debug, Clone)]
pub struct Srgb8Table {
    /// `edges[k]`: the smallest `f32` in [0, 1] whose level is `k` or more (`edges[0] = 0`,
    /// `edges[256]` infinite).
    edges: [f32; 257],
    /// The level at bit pattern `i << BUCKET_SHIFT`, for every `i` up to that of 1.0.
    buckets: Vec<u8>,
}

const BUCKET_SHIFT: u32 = 16;

impl Srgb8Table {
    /// Builds the table (255 binary searches and 65 025 evaluations: about a millisecond).
    pub fn new() -> Srgb8Table {
        let one = 1.0f32.to_bits();
        let level = |bits: u32| srgb8_of_display(f32::from_bits(bits));
        let mut edges = [0.0f32; 257];
        edges[256] = f32::INFINITY;
        for (k, edge) in edges.iter_mut().enumerate().take(256).skip(1) {
            // The smallest bit pattern in [0, 1] whose level reaches k (1.0's is 255).
            let (mut lo, mut hi) = (0u32, one);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if usize::from(level(mid)) >= k {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            *edge = f32::from_bits(lo);
        }
        let buckets: Vec<u8> = (0..=one >> BUCKET_SHIFT)
            .map(|i| level(i << BUCKET_SHIFT))
            .collect();
        // Levels are at least 1/(12.92 * 255) apart in y and 0.009 near 1, a bucket at most
        // 2^16 ulps (4e-3 near 1): never two edges in one bucket, which `level` relies on.
        for (i, pair) in buckets.windows(2).enumerate() {
            let last_in_bucket = level((((i + 1) as u32) << BUCKET_SHIFT) - 1);
            assert!(
                u16::from(last_in_bucket) <= u16::from(pair[0]) + 1,
                "two sRGB level edges in bucket {i}"
            );
        }
        Srgb8Table { edges, buckets }
    }

    /// One table for the process, built on first use.
    pub fn shared() -> &'static Srgb8Table {
        static TABLE: std::sync::OnceLock<Srgb8Table> = std::sync::OnceLock::new();
        TABLE.get_or_init(Srgb8Table::new)
    }

    /// `tonemap_srgb8_with(linear, exposure, curve)`, through the table.
    pub fn tonemap(&self, linear: f32, exposure: f32, curve: ToneCurve) -> u8 {
        self.level(display_value(linear, exposure, curve))
    }

    /// Tone-maps linear RGB triples (`rgb`, `3 n` floats) into `rgba` (`4 n` bytes, alpha
    /// 255), each channel as [`Srgb8Table::tonemap`] gives it. The curve is chosen once, not per
    /// channel, so the loop is a few instructions per channel (a viewer's whole frame).
    ///
    /// # Panics
    /// If `rgba.len() / 4 != rgb.len() / 3` (the caller's buffers, never user input).
    pub fn tonemap_rgba8(&self, rgb: &[f32], exposure: f32, curve: ToneCurve, rgba: &mut [u8]) {
        assert_eq!(rgb.len() / 3, rgba.len() / 4, "3 floats per 4 bytes");
        match curve {
            ToneCurve::Clamp => self.rgba8_with(rgb, exposure, rgba, |v| ToneCurve::Clamp.apply(v)),
            ToneCurve::Reinhard => {
                self.rgba8_with(rgb, exposure, rgba, |v| ToneCurve::Reinhard.apply(v))
            }
            ToneCurve::Aces => self.rgba8_with(rgb, exposure, rgba, |v| ToneCurve::Aces.apply(v)),
        }
    }

    /// [`Srgb8Table::tonemap_rgba8`] for one curve (`apply`), inlined into the loop.
    #[inline(always)]
    fn rgba8_with(&self, rgb: &[f32], exposure: f32, rgba: &mut [u8], apply: impl Fn(f32) -> f32) {
        // `display_value` with the curve fixed.
        let shown = |linear: f32| {
            let v = linear * exposure;
            if v > 0.0 {
                apply(v.min(1e18))
            } else {
                0.0
            }
        };
        for (o, l) in rgba.chunks_exact_mut(4).zip(rgb.chunks_exact(3)) {
            o[0] = self.level(shown(l[0]));
            o[1] = self.level(shown(l[1]));
            o[2] = self.level(shown(l[2]));
            o[3] = 255;
        }
    }

    /// The 8-bit sRGB level of a shown value `y` in [0, 1] (0 below, 255 above).
    #[inline(always)]
    pub fn level(&self, y: f32) -> u8 {
        // NaN and values at or below 0 read bucket 0, whose level is 0 and whose next edge
        // lies above 0. Values above 1 read the last bucket, starting at 1.0 (level 255).
        let y = if y > 0.0 { y } else { 0.0 };
        let i = ((y.to_bits() >> BUCKET_SHIFT) as usize).min(self.buckets.len() - 1);
        let k = self.buckets[i];
        // A bucket holds at most one edge (checked in `new`), so one comparison finds the
        // level, without a branch; `edges[256]` is infinite.
        k + u8::from(y >= self.edges[usize::from(k) + 1])
    }
}

impl Default for Srgb8Table {
    fn default() -> Self {
        Srgb8Table::new()
    }
}

/// Writes a tone-mapped 8-bit sRGB PNG: each channel is scaled by `exposure` (a linear
/// multiplier; 1 = unchanged), clamped to [0, 1] and sRGB-encoded.
pub fn write_png(
    path: impl AsRef<Path>,
    width: usize,
    height: usize,
    rgb: &[[f32; 3]],
    exposure: f32,
) -> Result<()> {
    write_png_with(path, width, height, rgb, exposure, ToneCurve::Clamp)
}

/// [`write_png`] through a tone curve ([`tonemap_srgb8_with`]).
pub fn write_png_with(
    path: impl AsRef<Path>,
    width: usize,
    height: usize,
    rgb: &[[f32; 3]],
    exposure: f32,
    curve: ToneCurve,
) -> Result<()> {
    use image::ImageEncoder;

    let path = path.as_ref();
    check_size(path, width, height, rgb.len())?;
    if !(exposure.is_finite() && exposure >= 0.0) {
        return Err(ImageIoError::BadExposure {
            path: path.to_path_buf(),
            exposure,
        });
    }
    let (Ok(w32), Ok(h32)) = (u32::try_from(width), u32::try_from(height)) else {
        return Err(ImageIoError::TooLarge {
            path: path.to_path_buf(),
            width,
            height,
        });
    };
    let bytes: Vec<u8> = rgb
        .iter()
        .flat_map(|p| p.map(|c| tonemap_srgb8_with(c, exposure, curve)))
        .collect();
    write_file_atomic(path, |w| {
        image::codecs::png::PngEncoder::new(w)
            .write_image(&bytes, w32, h32, image::ExtendedColorType::Rgb8)
            .map_err(|e| io::Error::other(format!("PNG encoder: {e}")))
    })
    .map_err(write_err(path))
}

/// Writes `.exr` (scene-linear, f32; `exposure` is NOT applied, so the numbers stay comparable
/// with reference renders) or `.png` (tone-mapped with `exposure`), chosen by the extension
/// (case-insensitive). Any other extension is an error and nothing is written.
pub fn write_image(
    path: impl AsRef<Path>,
    width: usize,
    height: usize,
    rgb: &[[f32; 3]],
    exposure: f32,
) -> Result<()> {
    write_image_with(path, width, height, rgb, exposure, ToneCurve::Clamp)
}

/// [`write_image`] with a PNG's tone curve (an EXR stays linear).
pub fn write_image_with(
    path: impl AsRef<Path>,
    width: usize,
    height: usize,
    rgb: &[[f32; 3]],
    exposure: f32,
    curve: ToneCurve,
) -> Result<()> {
    let path = path.as_ref();
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("exr") => write_exr(path, width, height, rgb),
        Some("png") => write_png_with(path, width, height, rgb, exposure, curve),
        _ => Err(ImageIoError::UnsupportedExtension {
            path: path.to_path_buf(),
            ext: path.extension().map(|e| e.to_string_lossy().into_owned()),
        }),
    }
}

/// Reads the first RGB(A) layer of an EXR as linear f32 RGB (alpha is dropped), returning
/// `(width, height, pixels)` with pixels row-major, top row first.
pub fn read_exr_rgb(path: impl AsRef<Path>) -> Result<(usize, usize, Vec<[f32; 3]>)> {
    let path = path.as_ref();
    let read_err = |reason: String| ImageIoError::Read {
        path: path.to_path_buf(),
        reason,
    };
    if !path.is_file() {
        return Err(read_err(if path.exists() {
            "not a regular file".to_string()
        } else {
            "no such file".to_string()
        }));
    }
    struct Pixels {
        width: usize,
        data: Vec<[f32; 3]>,
    }
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |size, _| Pixels {
                width: size.width(),
                data: vec![[0.0; 3]; size.area()],
            },
            |px: &mut Pixels, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                // In range: the decoder only yields positions inside the layer's size.
                if let Some(p) = px.data.get_mut(pos.y() * px.width + pos.x()) {
                    *p = [r, g, b];
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| read_err(e.to_string()))?;
    let size = image.layer_data.size;
    let pixels = image.layer_data.channel_data.pixels;
    Ok((size.width(), size.height(), pixels.data))
}
