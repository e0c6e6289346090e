//! The command-line material override syntax shared by the `reference` tool (baker) and the
//! `relight` tool (runtime): `--set MATERIAL.PARAM=VALUE`.
//!
//! ```text
//! bunny.kd=0.8,0.2,0.2     diffuse albedo (RGB)
//! bunny.ks=0.5             specular albedo; a single number means gray (0.5,0.5,0.5)
//! bunny.shininess=50       Blinn-Phong exponent, in [0, 1e6]
//! wall.alpha=0.3           GGX roughness, in [1e-4, 1]
//! ```
//!
//! The material name is everything before the *last* dot before `=`, so names may contain dots
//! (`car.body.paint.kd=...` sets `kd` of material `car.body.paint`); they cannot contain `=`.
//! Whether the material exists is checked by the caller, who knows the scene
//! ([`check_material`]).

use std::fmt;
use std::str::FromStr;

/// Largest accepted Blinn-Phong exponent.
pub const SHININESS_MAX: f32 = crate::family::SHININESS_RANGE.1;
/// Smallest accepted GGX roughness (below it the lobe is a numerical delta).
pub const ALPHA_MIN: f32 = crate::family::ALPHA_RANGE.0;
/// Largest accepted GGX roughness.
pub const ALPHA_MAX: f32 = crate::family::ALPHA_RANGE.1;

pub use crate::family::Param;

/// The new value of one parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum OverrideValue {
    /// Diffuse albedo, linear RGB, each >= 0.
    Kd([f32; 3]),
    /// Specular albedo, linear RGB, each >= 0.
    Ks([f32; 3]),
    /// Blinn-Phong exponent in [0, [`SHININESS_MAX`]].
    Shininess(f32),
    /// GGX roughness in [[`ALPHA_MIN`], [`ALPHA_MAX`]].
    Alpha(f32),
}

impl OverrideValue {
    /// The parameter this value sets.
    pub fn param(&self) -> Param {
        match self {
            OverrideValue::Kd(_) => Param::Kd,
            OverrideValue::Ks(_) => Param::Ks,
            OverrideValue::Shininess(_) => Param::Shininess,
            OverrideValue::Alpha(_) => Param::Alpha,
        }
    }
}

/// One parsed `--set` argument.
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialOverride {
    /// Name of the material (everything before the last `.`; may contain dots).
    pub material: String,
    /// The parameter and its new value.
    pub value: OverrideValue,
}

impl fmt::Display for MaterialOverride {
    /// Formats back into the command-line syntax (parses to the same value).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}=", self.material, self.value.param())?;
        match self.value {
            OverrideValue::Kd([r, g, b]) | OverrideValue::Ks([r, g, b]) => {
                write!(f, "{r},{g},{b}")
            }
            OverrideValue::Shininess(v) | OverrideValue::Alpha(v) => write!(f, "{v}"),
        }
    }
}

impl FromStr for MaterialOverride {
    type Err = OverrideError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        parse_override(s)
    }
}

/// Why an override was rejected. Every message quotes the offending input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum OverrideError {
    /// No `=` in the argument.
    #[error("'{input}': missing '=' (expected MATERIAL.PARAM=VALUE, e.g. bunny.kd=0.8,0.2,0.2)")]
    MissingEquals {
        /// The whole argument as given.
        input: String,
    },
    /// No `.` between the material and the parameter.
    #[error(
        "'{input}': missing '.' between material and parameter (expected MATERIAL.PARAM=VALUE, \
         e.g. bunny.shininess=50)"
    )]
    MissingDot {
        /// The whole argument as given.
        input: String,
    },
    /// The material name before the last `.` is empty.
    #[error("'{input}': empty material name")]
    EmptyMaterial {
        /// The whole argument as given.
        input: String,
    },
    /// The parameter name is not one of [`Param::ALL`].
    #[error("'{input}': unknown parameter '{param}'; valid parameters: {valid}")]
    UnknownParam {
        /// The whole argument as given.
        input: String,
        /// The parameter concerned.
        param: String,
        /// The valid parameter names, comma-separated.
        valid: String,
    },
    /// A value has the wrong number of comma-separated components (a colour takes 1 or 3, a
    /// scalar exactly 1).
    #[error("'{input}': {param} needs {expected}, got {got}")]
    WrongComponentCount {
        /// The whole argument as given.
        input: String,
        /// The parameter concerned.
        param: Param,
        /// What the parameter takes, in words (e.g. "exactly 1 number").
        expected: &'static str,
        /// The number of components given.
        got: usize,
    },
    /// A value component does not parse as a number.
    #[error("'{input}': '{text}' is not a number")]
    NotANumber {
        /// The whole argument as given.
        input: String,
        /// The offending text.
        text: String,
    },
    /// A value is NaN or infinite.
    #[error("'{input}': {param} must be finite, got {value}")]
    NonFinite {
        /// The whole argument as given.
        input: String,
        /// The parameter concerned.
        param: Param,
        /// The value given.
        value: f32,
    },
    /// A colour component is negative.
    #[error("'{input}': {param} must not be negative, got {value}")]
    Negative {
        /// The whole argument as given.
        input: String,
        /// The parameter concerned.
        param: Param,
        /// The value given.
        value: f32,
    },
    /// A shininess or roughness lies outside its accepted range.
    #[error("'{input}': {param} must be in [{min}, {max}], got {value}")]
    OutOfRange {
        /// The whole argument as given.
        input: String,
        /// The parameter concerned.
        param: Param,
        /// The value given.
        value: f32,
        /// Smallest accepted value.
        min: f32,
        /// Largest accepted value.
        max: f32,
    },
    /// The material is not one of the scene's ([`check_material`]).
    #[error("unknown material '{name}'; the scene has: {available}")]
    UnknownMaterial {
        /// The material name given.
        name: String,
        /// The scene's material names, comma-separated.
        available: String,
    },
}

/// Parses `MATERIAL.PARAM=VALUE`. Usable directly as a clap `value_parser`.
pub fn parse_override(s: &str) -> Result<MaterialOverride, OverrideError> {
    let input = || s.to_string();
    let (lhs, rhs) = s
        .split_once('=')
        .ok_or_else(|| OverrideError::MissingEquals { input: input() })?;
    let (material, param) = lhs
        .rsplit_once('.')
        .ok_or_else(|| OverrideError::MissingDot { input: input() })?;
    if material.is_empty() {
        return Err(OverrideError::EmptyMaterial { input: input() });
    }
    let param_text = param.trim();
    let param = Param::from_name(param_text).ok_or_else(|| OverrideError::UnknownParam {
        input: input(),
        param: param_text.to_string(),
        valid: Param::valid_names(),
    })?;

    let values = rhs
        .split(',')
        .map(|t| {
            let t = t.trim();
            t.parse::<f32>().map_err(|_| OverrideError::NotANumber {
                input: input(),
                text: t.to_string(),
            })
        })
        .collect::<Result<Vec<f32>, _>>()?;
    for &value in &values {
        if !value.is_finite() {
            return Err(OverrideError::NonFinite {
                input: input(),
                param,
                value,
            });
        }
        // `-0` is harmless; treat it as zero rather than reject it.
        if value < 0.0 {
            return Err(OverrideError::Negative {
                input: input(),
                param,
                value,
            });
        }
    }

    let count_err = |expected| OverrideError::WrongComponentCount {
        input: input(),
        param,
        expected,
        got: values.len(),
    };
    let rgb = || match *values.as_slice() {
        [v] => Ok([v; 3]),
        [r, g, b] => Ok([r, g, b]),
        _ => Err(count_err(
            "1 number (gray) or 3 comma-separated numbers (RGB)",
        )),
    };
    let scalar = |min: f32, max: f32| match *values.as_slice() {
        [v] if (min..=max).contains(&v) => Ok(v),
        [value] => Err(OverrideError::OutOfRange {
            input: input(),
            param,
            value,
            min,
            max,
        }),
        _ => Err(count_err("exactly 1 number")),
    };
    let value = match param {
        Param::Kd => OverrideValue::Kd(rgb()?),
        Param::Ks => OverrideValue::Ks(rgb()?),
        Param::Shininess => {
            OverrideValue::Shininess(scalar(crate::family::SHININESS_RANGE.0, SHININESS_MAX)?)
        }
        Param::Alpha => OverrideValue::Alpha(scalar(ALPHA_MIN, ALPHA_MAX)?),
    };
    Ok(MaterialOverride {
        material: material.to_string(),
        value,
    })
}

/// Checks that `name` is one of the scene's materials (exact, case-sensitive match).
pub fn check_material(name: &str, available: &[&str]) -> Result<(), OverrideError> {
    if available.contains(&name) {
        return Ok(());
    }
    Err(OverrideError::UnknownMaterial {
        name: name.to_string(),
        available: if available.is_empty() {
            "no materials".to_string()
        } else {
            available.join(", ")
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_round_trips() {
        for s in [
            "bunny.kd=0.8,0.2,0.2",
            "a.b.ks=0.5,0.5,0.5",
            "x.shininess=50",
            "wall.alpha=0.3",
        ] {
            let o = parse_override(s).unwrap();
            assert_eq!(parse_override(&o.to_string()).unwrap(), o);
        }
    }
}
