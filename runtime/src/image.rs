//! What a render gives: the image (one type for both kinds of bake) and what the render cost.
//!
//! Both relighters render into a caller's flat buffer of `3 * width * height` floats (linear
//! RGB, row-major, top row first), so a caller that owns the memory (a numpy array, a mapped
//! GPU buffer, a frame reused across renders) gets the image without a copy; [`Image`] is
//! that buffer owned, for callers that want one made.

use crate::error::RuntimeError;

/// A rendered image: linear RGB, row-major, top row first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` pixels (`pixels.as_flattened()` is the flat buffer a render writes).
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    /// A black image of the given size.
    pub fn new(width: u32, height: u32) -> Image {
        Image {
            width,
            height,
            pixels: vec![[0.0; 3]; width as usize * height as usize],
        }
    }
}

/// What one render cost, in wall-clock seconds (and bytes for a per-pixel bake). A stage that
/// does not belong to the bake's kind, or whose cached result was reused, is `None`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderStats {
    /// The whole render.
    pub seconds: f64,
    /// Per-vertex: the light stage, when it ran (a new environment, rotation or intensity).
    pub light_s: Option<f64>,
    /// Per-vertex: the material stage, when it ran (a material edit, or the light stage ran).
    pub material_s: Option<f64>,
    /// Per-vertex: the view stage (rasterization and shading), which runs every frame.
    pub view_s: Option<f64>,
    /// Per-vertex: the rasterization part of `view_s`.
    pub raster_s: Option<f64>,
    /// Per-vertex: how many pixels were antialiased (sampled 16 times: silhouettes and
    /// creases, `VertexRelighter::set_antialias`); `None` when antialiasing is off.
    pub antialiased_pixels: Option<u32>,
    /// Per-pixel: bytes of bake data the frame read.
    pub bytes_read: Option<u64>,
}

/// Refuses a caller's buffer that does not hold a `width` x `height` RGB image (`what` names
/// it in the error).
pub(crate) fn check_len(
    what: &'static str,
    buffer: &[f32],
    width: u32,
    height: u32,
) -> Result<(), RuntimeError> {
    let expected = 3 * width as usize * height as usize;
    if buffer.len() != expected {
        return Err(RuntimeError::BufferSize {
            what,
            width,
            height,
            expected,
            got: buffer.len(),
        });
    }
    Ok(())
}
