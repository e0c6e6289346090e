//! The editable materials both relighters share: the bake's materials and PCA bases, the
//! current parameters of every material, the rules of an edit (which material, editable or
//! not, which parameter its family has, which values it accepts), what a caller is shown of
//! them ([`MaterialInfo`]), and the RGB coefficient of every global slot
//! (`prt_formats::pixel::slot_coefficients`), so a per-pixel and a per-vertex bake accept and
//! refuse the same edits and weigh their slots the same way.

use std::fmt;

use prt_formats::basis::BrdfBasis;
use prt_formats::overrides::{OverrideValue, Param};
use prt_formats::pixel::{slot_coefficients, BasisMeta, MaterialMeta, MaterialParams};
use prt_formats::Family;

use crate::error::RuntimeError;

/// A closed range of values a parameter takes, `[min, max]`; a colour's range holds for each
/// of its channels. Only finite values lie in a range (a colour's `max` is infinite: any
/// finite value >= `min`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamRange {
    /// Smallest value.
    pub min: f32,
    /// Largest value (`f32::INFINITY`: no bound but finiteness).
    pub max: f32,
}

impl ParamRange {
    /// The range of a colour channel (`kd`, `ks`): finite and >= 0.
    pub const COLOUR: ParamRange = ParamRange {
        min: 0.0,
        max: f32::INFINITY,
    };

    /// Whether `v` is finite and in the range.
    pub fn contains(&self, v: f32) -> bool {
        v.is_finite() && v >= self.min && v <= self.max
    }
}

impl fmt::Display for ParamRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[{}, {}]", self.min, self.max)
    }
}

/// One parameter of a material, as [`MaterialInfo`] lists it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamInfo {
    /// The parameter and its current value.
    pub value: OverrideValue,
    /// The values `set_params` accepts (a colour: per channel); others are refused.
    pub range: ParamRange,
    /// The lobe parameter of an editable glossy material: the range its bake's bases sampled.
    /// A value outside it is accepted and rendered as at the nearest end of this range
    /// (clamped); [`ParamInfo::clamped`] says whether the current value is.
    pub sampled: Option<ParamRange>,
}

impl ParamInfo {
    /// Which parameter this is.
    pub fn param(&self) -> Param {
        self.value.param()
    }

    /// Whether the current value lies outside [`ParamInfo::sampled`] and is rendered clamped.
    pub fn clamped(&self) -> bool {
        match (self.sampled, self.value) {
            (Some(s), OverrideValue::Shininess(v) | OverrideValue::Alpha(v)) => !s.contains(v),
            _ => false,
        }
    }
}

/// A material of the bake and its current parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialInfo {
    /// The material's name, as `set_params` (and `--set`) address it.
    pub name: String,
    /// Its BRDF family.
    pub family: Family,
    /// Whether it was baked editable (a fixed material refuses edits).
    pub editable: bool,
    /// Whether a base-colour texture modulates its `kd`.
    pub textured: bool,
    /// Whether its BRDF varies over its surface (a fixed material baked with its glTF
    /// metallicRoughnessTexture, one `own` slot): `params` are then the texture's mean, what
    /// the per-vertex mode's last reflection uses.
    pub varying: bool,
    /// Every parameter its family has (`kd`; `ks` and the lobe parameter for a glossy
    /// family), in the order of [`Param::ALL`].
    pub params: Vec<ParamInfo>,
}

/// The values parameter `p` of a material of `family` accepts.
fn accepted(family: Family, p: Param) -> ParamRange {
    match (p, family.lobe_param_range()) {
        (Param::Shininess | Param::Alpha, Some((min, max))) => ParamRange { min, max },
        _ => ParamRange::COLOUR,
    }
}

/// The sampled range of a basis' parameter samples (increasing, non-empty: checked at open).
fn sampled_range(samples: &[f32]) -> Option<ParamRange> {
    Some(ParamRange {
        min: *samples.first()?,
        max: *samples.last()?,
    })
}

/// The materials of a bake and their current parameters.
#[derive(Clone, Debug)]
pub(crate) struct Materials {
    materials: Vec<MaterialMeta>,
    bases: Vec<BrdfBasis>,
    params: Vec<MaterialParams>,
    /// Per material, the range of its lobe parameter every basis it is evaluated with
    /// sampled (the intersection of their ranges), when it has a basis.
    sampled: Vec<Option<ParamRange>>,
}

impl Materials {
    /// The materials at the parameters they were baked with. Refuses (with the reason, for the
    /// caller's schema error) a basis whose coefficient table is inconsistent and a material
    /// naming a basis that does not exist: edits and the slot coefficients read every
    /// material's basis.
    pub(crate) fn new(materials: &[MaterialMeta], bases: &[BasisMeta]) -> Result<Self, String> {
        let bases: Vec<BrdfBasis> = bases.iter().map(|b| b.basis.clone()).collect();
        for (i, b) in bases.iter().enumerate() {
            // Everything relighting reads of a basis: its sampled parameters and coefficients.
            if let Err(e) = b.validate_coefficients() {
                return Err(format!(
                    "basis {i} ({}) has an inconsistent coefficient table: {e}",
                    b.family
                ));
            }
        }
        for m in materials {
            if m.basis.is_some_and(|b| b as usize >= bases.len()) {
                return Err(format!("material '{}' names a missing basis", m.name));
            }
        }
        let sampled = materials
            .iter()
            .map(|m| {
                let b = &bases[m.basis? as usize];
                sampled_range(&b.param_samples)
            })
            .collect();
        Ok(Materials {
            materials: materials.to_vec(),
            params: materials.iter().map(|m| m.params()).collect(),
            bases,
            sampled,
        })
    }

    /// Narrows material `m`'s sampled range to the `samples` of another basis it is evaluated
    /// with (the per-vertex shading basis of its group): a value outside either is clamped.
    pub(crate) fn narrow_sampled(&mut self, m: usize, samples: &[f32]) {
        let Some(other) = sampled_range(samples) else {
            return;
        };
        let narrowed = match self.sampled[m] {
            Some(s) => ParamRange {
                min: s.min.max(other.min),
                max: s.max.min(other.max),
            },
            None => other,
        };
        self.sampled[m] = Some(narrowed);
    }

    /// The current parameters of every material, in the bake's order.
    pub(crate) fn all(&self) -> &[MaterialParams] {
        &self.params
    }

    /// Every material with its parameters, current values and ranges.
    pub(crate) fn info(&self) -> Vec<MaterialInfo> {
        self.materials
            .iter()
            .zip(&self.params)
            .zip(&self.sampled)
            .map(|((m, p), sampled)| {
                let params = Param::ALL
                    .iter()
                    .filter(|&&q| m.family.has_param(q))
                    .map(|&q| {
                        let value = match q {
                            Param::Kd => OverrideValue::Kd(p.kd),
                            Param::Ks => OverrideValue::Ks(p.ks),
                            Param::Shininess => OverrideValue::Shininess(p.param),
                            _ => OverrideValue::Alpha(p.param),
                        };
                        let lobe = matches!(q, Param::Shininess | Param::Alpha);
                        ParamInfo {
                            value,
                            range: accepted(m.family, q),
                            sampled: if lobe { *sampled } else { None },
                        }
                    })
                    .collect();
                MaterialInfo {
                    name: m.name.clone(),
                    family: m.family,
                    editable: m.editable,
                    textured: m.textured,
                    varying: m.slots.contains(&prt_formats::pixel::SlotKind::Own),
                    params,
                }
            })
            .collect()
    }

    /// Current parameters of material `name`.
    pub(crate) fn params(&self, name: &str) -> Result<MaterialParams, RuntimeError> {
        Ok(self.params[self.index(name)?])
    }

    /// The index of material `name`, or the error listing the bake's materials.
    pub(crate) fn index(&self, name: &str) -> Result<usize, RuntimeError> {
        self.materials
            .iter()
            .position(|m| m.name == name)
            .ok_or_else(|| RuntimeError::UnknownMaterial {
                name: name.to_string(),
                available: self.list(|_| true),
            })
    }

    fn list(&self, keep: impl Fn(&MaterialMeta) -> bool) -> String {
        self.materials
            .iter()
            .filter(|m| keep(m))
            .map(|m| m.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The index of material `name` when it may be edited.
    fn editable(&self, name: &str) -> Result<usize, RuntimeError> {
        let i = self.index(name)?;
        let m = &self.materials[i];
        if !m.editable {
            return Err(RuntimeError::NotEditable {
                name: m.name.clone(),
                editable: self.list(|m| m.editable),
            });
        }
        Ok(i)
    }

    /// Sets parameters of the editable material `name`, all or none: every value is checked
    /// (a parameter its family has, within its accepted range) before any is applied. A lobe
    /// parameter outside a basis' sampled range is accepted and clamped to it when used.
    pub(crate) fn set(&mut self, name: &str, values: &[OverrideValue]) -> Result<(), RuntimeError> {
        let i = self.editable(name)?;
        let m = &self.materials[i];
        let mut p = self.params[i];
        for &value in values {
            let param = value.param();
            let wrong = || RuntimeError::WrongParam {
                name: m.name.clone(),
                family: m.family.to_string(),
                param: param.to_string(),
                params: m.family.param_names().join(", "),
            };
            if !m.family.has_param(param) {
                return Err(wrong());
            }
            let range = accepted(m.family, param);
            let outside = |shown: String| RuntimeError::OutOfRange {
                name: m.name.clone(),
                param,
                value: shown,
                min: range.min,
                max: range.max,
            };
            let colour = |c: [f32; 3]| match c.iter().all(|&v| range.contains(v)) {
                true => Ok(c),
                false => Err(outside(format!("{c:?}"))),
            };
            match value {
                OverrideValue::Kd(c) => p.kd = colour(c)?,
                OverrideValue::Ks(c) => p.ks = colour(c)?,
                OverrideValue::Shininess(v) | OverrideValue::Alpha(v) => {
                    if !range.contains(v) {
                        return Err(outside(v.to_string()));
                    }
                    p.param = v;
                }
                // A parameter the syntax knows but this runtime does not.
                _ => return Err(wrong()),
            }
        }
        self.params[i] = p;
        Ok(())
    }

    /// RGB coefficient of every global slot for the current parameters, and whether any
    /// parameter lay outside its basis' sampled range (and was clamped).
    pub(crate) fn coefficients(&self) -> (Vec<[f32; 3]>, bool) {
        let mut out = Vec::new();
        let mut clamped = false;
        for (m, p) in self.materials.iter().zip(&self.params) {
            let lobe = match m.basis {
                Some(b) => {
                    let (c, cl) = self.bases[b as usize].coefficients(p.param);
                    clamped |= cl;
                    c
                }
                None => Vec::new(),
            };
            out.extend(slot_coefficients(m, p, &lobe));
        }
        (out, clamped)
    }
}
