//! BRDF families, exactly as docs/brdf.md states them (DESIGN.md section 2.2):
//!
//! - `diffuse`:      f = Kd / pi
//! - `blinn-phong`:  f = Kd / pi + Ks (s + 2) / (2 pi) cos^s(theta_h)        (thesis eq. 4-15)
//! - `ggx`:          f = Kd / pi + Ks D(h) G1(wi) G1(wo) / (4 cos_i cos_o)   (F = 1)
//!
//! with theta_h the angle between the half vector h = normalize(wi + wo) and the normal,
//! Trowbridge-Reitz D(h) = alpha^2 / (pi (cos^2 theta_h (alpha^2 - 1) + 1)^2) and the separable
//! Smith G1(v) = 2 cos_v / (cos_v + sqrt(alpha^2 + (1 - alpha^2) cos_v^2)).
//!
//! All directions are in the local shading frame: unit vectors with the normal along +Z, both
//! pointing away from the surface. A direction below the horizon gets f = 0.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};
use std::f32::consts::{FRAC_1_PI, PI};

/// Range of the Blinn-Phong shininess exponent accepted from users (thesis: s in [1, 200]; we
/// accept more, the basis clamps to its sampled range and warns).
pub const SHININESS_RANGE: (f32, f32) = (0.0, 1.0e6);
/// Range of the GGX alpha accepted from users.
pub const ALPHA_RANGE: (f32, f32) = (1.0e-4, 1.0);

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Family {
    Diffuse,
    BlinnPhong,
    Ggx,
}

impl Family {
    pub fn name(self) -> &'static str {
        match self {
            Family::Diffuse => "diffuse",
            Family::BlinnPhong => "blinn-phong",
            Family::Ggx => "ggx",
        }
    }

    pub fn parse(s: &str) -> Option<Family> {
        match s {
            "diffuse" | "lambert" => Some(Family::Diffuse),
            "blinn-phong" | "blinnphong" | "phong" => Some(Family::BlinnPhong),
            "ggx" => Some(Family::Ggx),
            _ => None,
        }
    }

    /// The family's specular lobe (the factor multiplying Ks), for lobe parameter `param`
    /// (shininess s for Blinn-Phong, alpha for GGX). Zero for `diffuse` or below the horizon.
    #[inline]
    pub fn specular_lobe(self, param: f32, wo: Vec3, wi: Vec3) -> f32 {
        let (cos_o, cos_i) = (wo.z, wi.z);
        if cos_o <= 0.0 || cos_i <= 0.0 {
            return 0.0;
        }
        match self {
            Family::Diffuse => 0.0,
            Family::BlinnPhong => {
                let h = wi + wo;
                let len = h.length();
                if len <= 1e-12 {
                    return 0.0;
                }
                let cos_h = (h.z / len).clamp(0.0, 1.0);
                blinn_phong_lobe(param, cos_h)
            }
            Family::Ggx => {
                let h = wi + wo;
                let len = h.length();
                if len <= 1e-12 {
                    return 0.0;
                }
                let cos_h = (h.z / len).clamp(0.0, 1.0);
                ggx_d(param, cos_h) * smith_g1(param, cos_i) * smith_g1(param, cos_o)
                    / (4.0 * cos_i * cos_o)
            }
        }
    }
}

/// (s + 2) / (2 pi) cos^s(theta_h), computed as exp(s ln cos) so very large s cannot overflow.
#[inline]
pub fn blinn_phong_lobe(s: f32, cos_h: f32) -> f32 {
    if cos_h <= 0.0 {
        return if s == 0.0 { 1.0 / PI } else { 0.0 };
    }
    (s + 2.0) * (0.5 * FRAC_1_PI) * (s * cos_h.ln()).exp()
}

/// Trowbridge-Reitz (GGX) normal distribution, evaluated in a form that stays finite for tiny
/// alpha: alpha^2 / (pi ((alpha^2 - 1) cos^2 + 1)^2) = alpha^2 / (pi (alpha^2 cos^2 + sin^2)^2).
#[inline]
pub fn ggx_d(alpha: f32, cos_h: f32) -> f32 {
    let a2 = alpha * alpha;
    let c2 = cos_h * cos_h;
    let s2 = (1.0 - c2).max(0.0);
    let denom = a2 * c2 + s2;
    if denom <= 0.0 {
        return 0.0;
    }
    a2 / (PI * denom * denom)
}

/// Separable Smith masking term for GGX.
#[inline]
pub fn smith_g1(alpha: f32, cos_v: f32) -> f32 {
    if cos_v <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    2.0 * cos_v / (cos_v + (a2 + (1.0 - a2) * cos_v * cos_v).sqrt())
}

/// A BRDF of one of the families with its parameters. `kd`/`ks` are linear RGB.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BrdfParams {
    pub family: Family,
    pub kd: Vec3,
    pub ks: Vec3,
    /// Blinn-Phong shininess s, or GGX alpha; unused for `diffuse`.
    pub param: f32,
}

/// A sampled incident direction with its solid-angle density.
#[derive(Clone, Copy, Debug)]
pub struct BrdfSample {
    pub wi: Vec3,
    pub pdf: f32,
}

impl BrdfParams {
    pub fn diffuse(kd: Vec3) -> Self {
        BrdfParams {
            family: Family::Diffuse,
            kd,
            ks: Vec3::ZERO,
            param: 0.0,
        }
    }

    /// glTF metallic-roughness to our families (docs/brdf.md): Kd = baseColor (1 - metallic),
    /// Ks = mix(0.04, baseColor, metallic), GGX alpha = roughness^2; a fully rough dielectric
    /// (metallic = 0, roughness = 1) maps to `diffuse` with Kd = baseColor.
    pub fn from_gltf_pbr(base_color: Vec3, metallic: f32, roughness: f32) -> Self {
        let metallic = metallic.clamp(0.0, 1.0);
        let roughness = roughness.clamp(0.0, 1.0);
        if metallic == 0.0 && roughness >= 1.0 {
            return BrdfParams::diffuse(base_color);
        }
        BrdfParams {
            family: Family::Ggx,
            kd: base_color * (1.0 - metallic),
            ks: Vec3::splat(0.04).lerp(base_color, metallic),
            param: (roughness * roughness).max(ALPHA_RANGE.0),
        }
    }

    /// f(wo, wi) per channel (not multiplied by the cosine).
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let spec = if self.family == Family::Diffuse || self.ks == Vec3::ZERO {
            0.0
        } else {
            self.family.specular_lobe(self.param, wo, wi)
        };
        self.kd * FRAC_1_PI + self.ks * spec
    }

    /// Probability of choosing the specular lobe when sampling.
    #[inline]
    fn specular_probability(&self) -> f32 {
        if self.family == Family::Diffuse {
            return 0.0;
        }
        let d = self.kd.max_element().max(0.0);
        let s = self.ks.max_element().max(0.0);
        if d + s <= 0.0 {
            0.5
        } else {
            s / (d + s)
        }
    }

    /// Samples wi given wo, with `u` uniform in [0,1)^2 and `u_lobe` uniform in [0,1) choosing
    /// the lobe (cosine-weighted diffuse, or the family's specular lobe).
    pub fn sample(&self, wo: Vec3, u: Vec2, u_lobe: f32) -> Option<BrdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let p_spec = self.specular_probability();
        let wi = if u_lobe < p_spec {
            let h = match self.family {
                Family::BlinnPhong => sample_blinn_phong_half(self.param, u),
                Family::Ggx => sample_ggx_half(self.param, u),
                Family::Diffuse => return None,
            };
            let wi = reflect(wo, h);
            if wi.z <= 0.0 {
                return None;
            }
            wi
        } else {
            cosine_hemisphere(u)
        };
        let pdf = self.pdf(wo, wi);
        if pdf > 0.0 && pdf.is_finite() {
            Some(BrdfSample { wi, pdf })
        } else {
            None
        }
    }

    /// Solid-angle density of [`BrdfParams::sample`].
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let p_spec = self.specular_probability();
        let mut pdf = (1.0 - p_spec) * wi.z * FRAC_1_PI;
        if p_spec > 0.0 {
            pdf += p_spec * specular_lobe_pdf(self.family, self.param, wo, wi);
        }
        pdf
    }
}

/// Density (solid angle, over wi) of sampling the specular lobe of `family` by its half vector.
#[inline]
pub fn specular_lobe_pdf(family: Family, param: f32, wo: Vec3, wi: Vec3) -> f32 {
    let h = wi + wo;
    let len = h.length();
    if len <= 1e-12 || wi.z <= 0.0 {
        return 0.0;
    }
    let h = h / len;
    let cos_h = h.z.max(0.0);
    let wo_h = wo.dot(h);
    if wo_h <= 0.0 {
        return 0.0;
    }
    let pdf_h = match family {
        Family::BlinnPhong => {
            // (s+1)/(2 pi) cos^(s) theta_h over solid angle of h.
            let s = param;
            (s + 1.0) * (0.5 * FRAC_1_PI) * (s * cos_h.max(1e-30).ln()).exp()
        }
        Family::Ggx => ggx_d(param, cos_h) * cos_h,
        Family::Diffuse => return 0.0,
    };
    pdf_h / (4.0 * wo_h)
}

/// Half vector with density (s+1)/(2 pi) cos^s(theta_h).
#[inline]
pub fn sample_blinn_phong_half(s: f32, u: Vec2) -> Vec3 {
    let cos_t = u.x.max(1e-30).powf(1.0 / (s + 1.0));
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Half vector with density D(h) cos(theta_h) for Trowbridge-Reitz.
#[inline]
pub fn sample_ggx_half(alpha: f32, u: Vec2) -> Vec3 {
    let a2 = alpha * alpha;
    // tan^2 = a2 u / (1 - u)  <=>  cos^2 = (1 - u) / (1 + (a2 - 1) u)
    let cos2 = ((1.0 - u.x) / (1.0 + (a2 - 1.0) * u.x)).clamp(0.0, 1.0);
    let cos_t = cos2.sqrt();
    let sin_t = (1.0 - cos2).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Cosine-weighted direction on the +Z hemisphere (density cos(theta)/pi).
#[inline]
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let r = u.x.sqrt();
    let phi = 2.0 * PI * u.y;
    let z = (1.0 - u.x).max(0.0).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Mirror `v` about `n` (both unit, pointing away from the surface).
#[inline]
pub fn reflect(v: Vec3, n: Vec3) -> Vec3 {
    2.0 * v.dot(n) * n - v
}
