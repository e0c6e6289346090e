//! The one definition of relative luminance, used to weight lights for sampling.

use glam::Vec3;

/// Relative luminance of linear sRGB primaries (Rec. 709 weights).
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}
