//! The families' specular lobes (the factor multiplying `Ks`, docs/brdf.md), evaluated in
//! f32: the baker bakes and samples them (`prt_bake::brdf`, which adds sampling and the f64
//! forms it tabulates the bases with), the runtime evaluates them for the compact lights it
//! shades per pixel (docs/vertex.md, "Compact lights"). One home for the formulas, so that both
//! sides reflect a sun through the same lobe.
//!
//! Directions are local (normal `+z`), unit, both pointing away from the surface.

use crate::family::Family;
use std::f32::consts::{FRAC_1_PI, PI};

/// The lobe of `family` at parameter `param` (shininess s or alpha) for the local unit
/// directions `wo` and `wi`; 0 below either horizon and for `Diffuse`.
#[inline]
pub fn specular_lobe(family: Family, param: f32, wo: [f32; 3], wi: [f32; 3]) -> f32 {
    let (cos_o, cos_i) = (wo[2], wi[2]);
    if cos_o <= 0.0 || cos_i <= 0.0 || family == Family::Diffuse {
        return 0.0;
    }
    let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let len = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    if len <= 1e-12 {
        return 0.0;
    }
    let cos_h = (h[2] / len).clamp(0.0, 1.0);
    match family {
        Family::Diffuse => 0.0,
        Family::BlinnPhong => blinn_phong::lobe(param, cos_h),
        Family::Ggx => ggx::lobe(param, cos_i, cos_o, cos_h),
    }
}

/// The normalised Blinn-Phong lobe (thesis eq. 4-15).
pub mod blinn_phong {
    use super::{FRAC_1_PI, PI};

    /// `(s + 2) / (2 pi) cos^s(theta_h)`, computed as `exp(s ln cos)` so very large s cannot
    /// overflow.
    #[inline]
    pub fn lobe(s: f32, cos_h: f32) -> f32 {
        if cos_h <= 0.0 {
            return if s == 0.0 { 1.0 / PI } else { 0.0 };
        }
        (s + 2.0) * (0.5 * FRAC_1_PI) * (s * cos_h.ln()).exp()
    }
}

/// The GGX (Trowbridge-Reitz) lobe with the separable Smith masking term, Fresnel = 1.
pub mod ggx {
    use super::PI;

    /// Trowbridge-Reitz normal distribution, in a form that stays finite for tiny alpha:
    /// `alpha^2 / (pi ((alpha^2 - 1) cos^2 + 1)^2) = alpha^2 / (pi (alpha^2 cos^2 + sin^2)^2)`.
    #[inline]
    pub fn d(alpha: f32, cos_h: f32) -> f32 {
        let a2 = alpha * alpha;
        let c2 = cos_h * cos_h;
        let s2 = (1.0 - c2).max(0.0);
        let denom = a2 * c2 + s2;
        if denom <= 0.0 {
            return 0.0;
        }
        a2 / (PI * denom * denom)
    }

    /// Separable Smith masking term.
    #[inline]
    pub fn smith_g1(alpha: f32, cos_v: f32) -> f32 {
        if cos_v <= 0.0 {
            return 0.0;
        }
        let a2 = alpha * alpha;
        2.0 * cos_v / (cos_v + (a2 + (1.0 - a2) * cos_v * cos_v).sqrt())
    }

    /// `D(h) G1(wi) G1(wo) / (4 cos_i cos_o)` from the cosines of wi, wo and the half vector
    /// (all in (0, 1]).
    #[inline]
    pub fn lobe(alpha: f32, cos_i: f32, cos_o: f32, cos_h: f32) -> f32 {
        d(alpha, cos_h) * smith_g1(alpha, cos_i) * smith_g1(alpha, cos_o) / (4.0 * cos_i * cos_o)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `2 pi integral_0^1 g(mu) mu dmu` by the midpoint rule: `integral g(cos) cos dw` over the
    /// hemisphere for a `g` of the angle to the normal alone.
    fn cosine_integral(g: impl Fn(f32) -> f32) -> f64 {
        let n = 200_000;
        let sum: f64 = (0..n)
            .map(|k| {
                let mu = (k as f64 + 0.5) / n as f64;
                f64::from(g(mu as f32)) * mu
            })
            .sum();
        2.0 * std::f64::consts::PI * sum / n as f64
    }

    /// The normalisations the lobes are built on, exact: the Trowbridge-Reitz `D` projected
    /// onto the normal integrates to 1 over the half vectors, and so does the normalised
    /// Blinn-Phong lobe `(s + 2) / (2 pi) cos^s` (thesis eq. 4-15).
    #[test]
    fn the_lobes_are_normalised() {
        for alpha in [0.1f32, 0.3, 0.6, 1.0] {
            let i = cosine_integral(|mu| ggx::d(alpha, mu));
            assert!((i - 1.0).abs() < 1e-3, "GGX alpha {alpha}: {i}");
        }
        for s in [1.0f32, 10.0, 100.0] {
            let i = cosine_integral(|mu| blinn_phong::lobe(s, mu));
            assert!((i - 1.0).abs() < 1e-3, "Blinn-Phong s {s}: {i}");
        }
    }

    /// The dispatch: the family's lobe from directions equals its formula from their cosines,
    /// and nothing is reflected below either horizon or by a diffuse family.
    #[test]
    fn specular_lobe_dispatches_on_the_family() {
        let wo = [0.3f32, -0.2, 0.932_737_9];
        let wi = [-0.4f32, 0.1, 0.910_494_4];
        let h: [f32; 3] = std::array::from_fn(|k| wo[k] + wi[k]);
        let len = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
        let cos_h = h[2] / len;
        let ggx = specular_lobe(Family::Ggx, 0.2, wo, wi);
        assert_eq!(ggx, ggx::lobe(0.2, wi[2], wo[2], cos_h));
        let bp = specular_lobe(Family::BlinnPhong, 20.0, wo, wi);
        assert_eq!(bp, blinn_phong::lobe(20.0, cos_h));
        assert!(ggx > 0.0 && bp > 0.0);
        let below = [0.0f32, 0.6, -0.8];
        assert_eq!(specular_lobe(Family::Ggx, 0.2, wo, below), 0.0);
        assert_eq!(specular_lobe(Family::BlinnPhong, 20.0, below, wi), 0.0);
        assert_eq!(specular_lobe(Family::Diffuse, 0.0, wo, wi), 0.0);
    }
}
