//! The BRDF families, as a name both the baker and the runtime agree on, and the rule of which
//! material parameter fits which family (docs/brdf.md states the formulas).
//!
//! The formulas themselves (evaluation, sampling) live in the baker (`prt_bake::brdf`); the
//! runtime never evaluates a family's formula, it reads the baked basis tables. What both must
//! agree on bit for bit is here: the family's name in the bake file, the parameter it takes and
//! that parameter's accepted range.
//!
//! Adding a family: a variant here (name, parameter, range), its formulas in `prt_bake::brdf`,
//! and its glTF mapping in the scene loader (docs/design.md, "Where things go").

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// A material parameter that can be overridden. New parameters are added here (with their
/// name in [`Param::name`] and a variant in `overrides::OverrideValue`); the error messages list the
/// valid names from [`Param::ALL`] automatically.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Param {
    /// `kd`: diffuse albedo (RGB).
    Kd,
    /// `ks`: specular albedo (RGB).
    Ks,
    /// `shininess`: the Blinn-Phong exponent.
    Shininess,
    /// `alpha`: the GGX roughness.
    Alpha,
}

impl Param {
    /// Every parameter, in the order error messages list them.
    pub const ALL: &'static [Param] = &[Param::Kd, Param::Ks, Param::Shininess, Param::Alpha];

    /// The name used on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            Param::Kd => "kd",
            Param::Ks => "ks",
            Param::Shininess => "shininess",
            Param::Alpha => "alpha",
        }
    }

    /// Parses a parameter name (ASCII case-insensitive, so `Kd` works too).
    pub fn from_name(name: &str) -> Option<Param> {
        Param::ALL
            .iter()
            .copied()
            .find(|p| p.name().eq_ignore_ascii_case(name))
    }

    pub(crate) fn valid_names() -> String {
        Param::ALL
            .iter()
            .map(|p| p.name())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl fmt::Display for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A BRDF family. Every family is `Kd / pi` plus `Ks` times the family's specular lobe.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Family {
    /// Lambert only: `f = Kd / pi`.
    Diffuse,
    /// `Kd / pi + Ks (s + 2) / (2 pi) cos^s(theta_h)` (normalised Blinn-Phong, thesis eq. 4-15).
    BlinnPhong,
    /// `Kd / pi + Ks D(h) G1(wi) G1(wo) / (4 cos_i cos_o)`: Trowbridge-Reitz D, separable
    /// Smith G1, Fresnel = 1.
    Ggx,
}

/// Accepted range of the Blinn-Phong exponent s (the thesis samples [1, 200]; larger values
/// are accepted and clamped to a basis' sampled range where a basis is used).
pub const SHININESS_RANGE: (f32, f32) = (0.0, 1.0e6);

/// Accepted range of the GGX roughness alpha (below 1e-4 the lobe is a numerical delta).
pub const ALPHA_RANGE: (f32, f32) = (1.0e-4, 1.0);

impl Family {
    /// Every family, in a fixed order.
    pub const ALL: [Family; 3] = [Family::Diffuse, Family::BlinnPhong, Family::Ggx];

    /// The name in configs, bake files and messages.
    pub const fn name(self) -> &'static str {
        match self {
            Family::Diffuse => "diffuse",
            Family::BlinnPhong => "blinn-phong",
            Family::Ggx => "ggx",
        }
    }

    /// Parses a family name; a few common aliases are accepted (`lambert`, `phong`,
    /// `blinnphong`).
    pub fn parse(s: &str) -> Option<Family> {
        match s {
            "diffuse" | "lambert" => Some(Family::Diffuse),
            "blinn-phong" | "blinnphong" | "phong" => Some(Family::BlinnPhong),
            "ggx" => Some(Family::Ggx),
            _ => None,
        }
    }

    /// The parameter that shapes the specular lobe (`shininess` or `alpha`), if the family has
    /// a lobe.
    pub const fn lobe_param(self) -> Option<Param> {
        match self {
            Family::Diffuse => None,
            Family::BlinnPhong => Some(Param::Shininess),
            Family::Ggx => Some(Param::Alpha),
        }
    }

    /// The accepted range of the lobe parameter, if the family has a lobe.
    pub const fn lobe_param_range(self) -> Option<(f32, f32)> {
        match self {
            Family::Diffuse => None,
            Family::BlinnPhong => Some(SHININESS_RANGE),
            Family::Ggx => Some(ALPHA_RANGE),
        }
    }

    /// Whether a material of this family has parameter `p`: every family has `kd`; families
    /// with a lobe have `ks` and their own lobe parameter. The one rule the baker's overrides,
    /// the config checker and the runtime all use.
    pub fn has_param(self, p: Param) -> bool {
        match p {
            Param::Kd => true,
            Param::Ks => self != Family::Diffuse,
            Param::Shininess | Param::Alpha => self.lobe_param() == Some(p),
        }
    }

    /// The names of the parameters this family has, for messages.
    pub fn param_names(self) -> Vec<&'static str> {
        Param::ALL
            .iter()
            .filter(|p| self.has_param(**p))
            .map(|p| p.name())
            .collect()
    }
}

/// The warning for a material that reflects more light than it receives, or `None`: when
/// `kd + ks` (`ks` only for a family with a specular lobe) exceeds 1 in some channel. Every
/// family here is `Kd / pi` plus `Ks` times a lobe that reflects at most all it receives, so
/// `kd + ks <= 1` per channel keeps a material physical (furnace-safe). Such values are accepted
/// (they make a picture, and may be wanted), but rarely meant: the warning names the material,
/// the channel, the values and the range. The baker's config and the runtime's `--set` share it.
pub fn reflectance_warning(
    material: &str,
    family: Family,
    kd: [f32; 3],
    ks: [f32; 3],
) -> Option<String> {
    let with_ks = family.has_param(Param::Ks);
    // The first channel with the largest sum (red when they are equal).
    let (channel, sum) = (0..3)
        .map(|c| (c, kd[c] + if with_ks { ks[c] } else { 0.0 }))
        .reduce(|best, next| if next.1 > best.1 { next } else { best })?;
    if sum.is_nan() || sum <= 1.0 {
        return None;
    }
    let name = ["red", "green", "blue"][channel];
    let values = if with_ks {
        format!("kd + ks = {} + {} = {sum}", kd[channel], ks[channel])
    } else {
        format!("kd = {sum}")
    };
    Some(format!(
        "material `{material}` reflects more light than it receives: {values} in the {name} \
         channel, above 1 ({}{} must lie in [0, 1] per channel for a physical material)",
        "kd",
        if with_ks { " + ks" } else { "" }
    ))
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Error of [`Family::from_str`]: the unknown name, with the valid ones in the message.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown BRDF family '{0}' (expected diffuse, blinn-phong or ggx)")]
pub struct UnknownFamily(pub String);

impl FromStr for Family {
    type Err = UnknownFamily;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Family::parse(s).ok_or_else(|| UnknownFamily(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_through_parse_and_serde() {
        for f in Family::ALL {
            assert_eq!(Family::parse(f.name()), Some(f));
            let json = serde_json::to_string(&f).unwrap();
            assert_eq!(json, format!("\"{}\"", f.name()));
            assert_eq!(serde_json::from_str::<Family>(&json).unwrap(), f);
        }
        assert!("velvet".parse::<Family>().is_err());
    }

    #[test]
    fn materials_reflecting_more_than_they_receive_are_named() {
        let w = reflectance_warning("bunny", Family::Diffuse, [1.5, 0.2, 0.2], [0.0; 3])
            .expect("kd 1.5 warns");
        assert!(
            w.contains("`bunny`") && w.contains("kd = 1.5") && w.contains("red"),
            "{w}"
        );
        assert!(w.contains("[0, 1]"), "{w}");
        let w = reflectance_warning("ball", Family::Ggx, [0.2, 0.7, 0.2], [0.1, 0.4, 0.1])
            .expect("kd + ks 1.1 warns");
        assert!(
            w.contains("`ball`") && w.contains("0.7 + 0.4") && w.contains("green"),
            "{w}"
        );
        // At 1 exactly, and a diffuse material's unused ks: no warning.
        assert_eq!(
            reflectance_warning("m", Family::BlinnPhong, [0.5; 3], [0.5; 3]),
            None
        );
        assert_eq!(
            reflectance_warning("m", Family::Diffuse, [0.9; 3], [0.9; 3]),
            None
        );
    }

    #[test]
    fn each_lobe_parameter_fits_exactly_one_family() {
        assert!(Family::ALL.iter().all(|f| f.has_param(Param::Kd)));
        assert!(!Family::Diffuse.has_param(Param::Ks));
        assert!(Family::BlinnPhong.has_param(Param::Shininess));
        assert!(!Family::BlinnPhong.has_param(Param::Alpha));
        assert!(Family::Ggx.has_param(Param::Alpha));
        assert!(!Family::Ggx.has_param(Param::Shininess));
        assert_eq!(Family::Ggx.param_names(), ["kd", "ks", "alpha"]);
    }
}
