//! The GGX (Trowbridge-Reitz) lobe with the separable Smith masking term and Fresnel = 1:
//! `D(h) G1(wi) G1(wo) / (4 cos_i cos_o)`, its half-vector sampling, and the same lobe in f64
//! for basis tabulation (docs/brdf.md).

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

// The lobe itself is shared with the runtime (which shades compact lights with it).
pub use prt_formats::lobe::ggx::{d, lobe, smith_g1};

/// Density over the half vector's solid angle of [`sample_half`]: `D(h) cos(theta_h)`.
#[inline]
pub fn half_pdf(alpha: f32, cos_h: f32) -> f32 {
    d(alpha, cos_h) * cos_h
}

/// Half vector with density `D(h) cos(theta_h)`.
#[inline]
pub fn sample_half(alpha: f32, u: Vec2) -> Vec3 {
    let a2 = alpha * alpha;
    // tan^2 = a2 u / (1 - u)  <=>  cos^2 = (1 - u) / (1 + (a2 - 1) u)
    let cos2 = ((1.0 - u.x) / (1.0 + (a2 - 1.0) * u.x)).clamp(0.0, 1.0);
    let cos_t = cos2.sqrt();
    let sin_t = (1.0 - cos2).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// [`d`] in f64.
pub fn d_f64(alpha: f64, cos_h: f64) -> f64 {
    let a2 = alpha * alpha;
    let c2 = cos_h * cos_h;
    let denom = a2 * c2 + (1.0 - c2).max(0.0);
    if denom <= 0.0 {
        return 0.0;
    }
    a2 / (std::f64::consts::PI * denom * denom)
}

/// [`lobe`] in f64 (basis tabulation), written to stay finite at grazing angles:
/// `G1(c) / c = 2 / (c + sqrt(a^2 + (1 - a^2) c^2))`. Cosines are taken as given (clamp them to
/// [0, 1] first).
pub fn lobe_f64(alpha: f64, cos_i: f64, cos_o: f64, cos_h: f64) -> f64 {
    let a2 = alpha * alpha;
    let d = d_f64(alpha, cos_h);
    let g1c = |c: f64| 2.0 / (c + (a2 + (1.0 - a2) * c * c).sqrt());
    d * g1c(cos_i) * g1c(cos_o) / 4.0
}

/// [`sample_half`]'s `cos(theta_h)` in f64 from a uniform `u`.
pub fn sample_cos_h_f64(alpha: f64, u: f64) -> f64 {
    let a2 = alpha * alpha;
    ((1.0 - u) / (1.0 + (a2 - 1.0) * u)).clamp(0.0, 1.0).sqrt()
}

/// [`half_pdf`] in f64.
pub fn half_pdf_f64(alpha: f64, cos_h: f64) -> f64 {
    d_f64(alpha, cos_h) * cos_h
}
