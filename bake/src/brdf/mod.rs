//! BRDF families, exactly as docs/brdf.md states them:
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
//!
//! The family names and parameters are `prt_formats::family` (shared with the runtime); each
//! family's formulas live in its own file here ([`blinn_phong`], [`ggx`]) and [`Lobe`]
//! dispatches on the family. Adding a family: its variant in `prt_formats::family`, a file
//! here, and its arms in [`Lobe`].

pub mod blinn_phong;
pub mod ggx;

use crate::sampling::pick_component;
use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};
use std::f32::consts::{FRAC_1_PI, PI};

pub use prt_formats::family::{Family, ALPHA_RANGE, SHININESS_RANGE};

/// What the baker knows of a family's specular lobe (the factor multiplying Ks): evaluation,
/// sampling by the half vector, and the baker's defaults for it. Implemented for
/// [`Family`]; `Diffuse` has no lobe (zero everywhere, never sampled).
pub trait Lobe {
    /// The lobe for parameter `param` (shininess s or alpha) at local directions; zero below
    /// the horizon.
    fn specular_lobe(self, param: f32, wo: Vec3, wi: Vec3) -> f32;
    /// Density (solid angle, over wi) of reflecting `wo` about a half vector sampled by
    /// [`Lobe::sample_half`].
    fn lobe_pdf(self, param: f32, wo: Vec3, wi: Vec3) -> f32;
    /// A half vector sampled with the lobe's half-vector density (`None` for `Diffuse`).
    fn sample_half(self, param: f32, u: Vec2) -> Option<Vec3>;
    /// The lobe in f64 from `cos(theta_i)`, `cos(theta_o)` and `cos(theta_h)`, each clamped to
    /// [0, 1] (basis tabulation: past the horizon it continues with its grazing limit).
    fn lobe_cosines_f64(self, param: f64, cos_i: f64, cos_o: f64, cos_h: f64) -> f64;
    /// `cos(theta_h)` of a half vector sampled with the lobe's half-vector density, in f64,
    /// from a uniform `u` (the azimuth is uniform); 1 for `Diffuse`.
    fn sample_cos_h_f64(self, param: f64, u: f64) -> f64;
    /// The half-vector density (solid angle of h) of [`Lobe::sample_cos_h_f64`], in f64.
    fn half_pdf_f64(self, param: f64, cos_h: f64) -> f64;
    /// Whether a larger parameter makes the lobe sharper (shininess) or wider (alpha).
    fn sharper_with_larger_param(self) -> bool;
    /// Default number of basis BRDFs of an editable material of this family. Blinn-Phong keeps
    /// the thesis' 6 (mean 0.70 %, max 2.6 % relative L2 over s in [1, 200]). GGX gets 8: at 6
    /// the truncated PCA misses the reflectance of sharp lobes by 37 % at alpha = 0.05, at 8 by
    /// at most 2.4 % for alpha >= 0.05 (docs/brdf-basis.md).
    fn default_basis_count(self) -> usize;
}

impl Lobe for Family {
    #[inline]
    fn specular_lobe(self, param: f32, wo: Vec3, wi: Vec3) -> f32 {
        let (cos_o, cos_i) = (wo.z, wi.z);
        if cos_o <= 0.0 || cos_i <= 0.0 || self == Family::Diffuse {
            return 0.0;
        }
        let h = wi + wo;
        let len = h.length();
        if len <= 1e-12 {
            return 0.0;
        }
        let cos_h = (h.z / len).clamp(0.0, 1.0);
        match self {
            Family::Diffuse => 0.0,
            Family::BlinnPhong => blinn_phong::lobe(param, cos_h),
            Family::Ggx => ggx::lobe(param, cos_i, cos_o, cos_h),
        }
    }

    #[inline]
    fn lobe_pdf(self, param: f32, wo: Vec3, wi: Vec3) -> f32 {
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
        let pdf_h = match self {
            Family::BlinnPhong => blinn_phong::half_pdf(param, cos_h),
            Family::Ggx => ggx::half_pdf(param, cos_h),
            Family::Diffuse => return 0.0,
        };
        pdf_h / (4.0 * wo_h)
    }

    #[inline]
    fn sample_half(self, param: f32, u: Vec2) -> Option<Vec3> {
        match self {
            Family::BlinnPhong => Some(blinn_phong::sample_half(param, u)),
            Family::Ggx => Some(ggx::sample_half(param, u)),
            Family::Diffuse => None,
        }
    }

    fn lobe_cosines_f64(self, param: f64, cos_i: f64, cos_o: f64, cos_h: f64) -> f64 {
        let (ci, co) = (cos_i.clamp(0.0, 1.0), cos_o.clamp(0.0, 1.0));
        let cos_h = cos_h.clamp(0.0, 1.0);
        match self {
            Family::Diffuse => 0.0,
            Family::BlinnPhong => blinn_phong::lobe_f64(param, cos_h),
            Family::Ggx => ggx::lobe_f64(param, ci, co, cos_h),
        }
    }

    fn sample_cos_h_f64(self, param: f64, u: f64) -> f64 {
        match self {
            Family::BlinnPhong => blinn_phong::sample_cos_h_f64(param, u),
            Family::Ggx => ggx::sample_cos_h_f64(param, u),
            Family::Diffuse => 1.0,
        }
    }

    fn half_pdf_f64(self, param: f64, cos_h: f64) -> f64 {
        match self {
            Family::BlinnPhong => blinn_phong::half_pdf_f64(param, cos_h),
            Family::Ggx => ggx::half_pdf_f64(param, cos_h),
            Family::Diffuse => 0.0,
        }
    }

    fn sharper_with_larger_param(self) -> bool {
        self == Family::BlinnPhong
    }

    fn default_basis_count(self) -> usize {
        match self {
            Family::Ggx => 8,
            Family::BlinnPhong | Family::Diffuse => 6,
        }
    }
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

    /// Samples wi given wo, with `u` uniform in [0,1)^2: `u.x` also chooses the lobe
    /// (cosine-weighted diffuse, or the family's specular lobe; see
    /// [`crate::sampling::pick_component`]).
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<BrdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let p_spec = self.specular_probability();
        let (lobe, x) = pick_component(u.x, &[p_spec, 1.0 - p_spec]);
        let u = Vec2::new(x, u.y);
        let wi = if lobe == 0 {
            let h = self.family.sample_half(self.param, u)?;
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
            pdf += p_spec * self.family.lobe_pdf(self.param, wo, wi);
        }
        pdf
    }
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
