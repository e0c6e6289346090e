//! The normalised Blinn-Phong lobe `(s + 2) / (2 pi) cos^s(theta_h)` (thesis eq. 4-15), its
//! half-vector sampling, and the same lobe in f64 for basis tabulation (docs/brdf.md).

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

// The lobe itself is shared with the runtime (which shades compact lights with it).
pub use prt_formats::lobe::blinn_phong::lobe;

/// Density over the half vector's solid angle of [`sample_half`]: `(s + 1) / (2 pi) cos^s`.
#[inline]
pub fn half_pdf(s: f32, cos_h: f32) -> f32 {
    (s + 1.0) * (0.5 * FRAC_1_PI) * (s * cos_h.max(1e-30).ln()).exp()
}

/// Half vector with density `(s + 1) / (2 pi) cos^s(theta_h)`.
#[inline]
pub fn sample_half(s: f32, u: Vec2) -> Vec3 {
    let cos_t = u.x.max(1e-30).powf(1.0 / (s + 1.0));
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// [`lobe`] in f64 (basis tabulation), from `cos(theta_h)` clamped to [0, 1].
pub fn lobe_f64(s: f64, cos_h: f64) -> f64 {
    use std::f64::consts::PI;
    if cos_h <= 0.0 {
        return if s == 0.0 { 1.0 / PI } else { 0.0 };
    }
    (s + 2.0) / (2.0 * PI) * (s * cos_h.ln()).exp()
}

/// [`sample_half`]'s `cos(theta_h)` in f64 from a uniform `u`.
pub fn sample_cos_h_f64(s: f64, u: f64) -> f64 {
    u.max(1e-300).powf(1.0 / (s.max(0.0) + 1.0))
}

/// [`half_pdf`] in f64.
pub fn half_pdf_f64(s: f64, cos_h: f64) -> f64 {
    let s = s.max(0.0);
    (s + 1.0) / (2.0 * std::f64::consts::PI) * (s * cos_h.max(1e-300).ln()).exp()
}
