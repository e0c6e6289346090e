//! The editable materials both relighters share: the bake's materials and PCA bases, the
//! current parameters of every material, the `--set` rules (which material, editable or not,
//! which parameter its family has), and the RGB coefficient of every global slot
//! (`prt_formats::pixel::slot_coefficients`), so a per-pixel and a per-vertex bake accept and
//! refuse the same edits and weigh their slots the same way.

use prt_formats::basis::BrdfBasis;
use prt_formats::family::Param;
use prt_formats::overrides::{MaterialOverride, OverrideValue};
use prt_formats::pixel::{slot_coefficients, BasisMeta, MaterialMeta, MaterialParams};

use crate::error::RuntimeError;

/// A lobe parameter outside the range its material's basis was built over: relighting uses
/// the nearest end of the range, since the basis holds no lobe beyond it.
#[derive(Clone, Debug, PartialEq)]
pub struct ClampedParam {
    /// The material's name.
    pub material: String,
    /// The parameter: `shininess` or `alpha`.
    pub param: Param,
    /// Its value.
    pub value: f32,
    /// The basis' sampled range `[min, max]`.
    pub range: [f32; 2],
}

impl ClampedParam {
    /// The value relighting uses: `value` clamped to `range`.
    pub fn used(&self) -> f32 {
        self.value.clamp(self.range[0], self.range[1])
    }
}

impl std::fmt::Display for ClampedParam {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}.{} = {} lies outside [{}, {}], the range the bake's {} basis was built over; \
             relit as {}",
            self.material,
            self.param,
            self.value,
            self.range[0],
            self.range[1],
            self.param,
            self.used()
        )
    }
}

/// The materials of a bake and their current parameters.
#[derive(Clone, Debug)]
pub(crate) struct Materials {
    materials: Vec<MaterialMeta>,
    bases: Vec<BrdfBasis>,
    params: Vec<MaterialParams>,
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
        Ok(Materials {
            materials: materials.to_vec(),
            params: materials.iter().map(|m| m.params()).collect(),
            bases,
        })
    }

    /// The current parameters of every material, in the bake's order.
    pub(crate) fn all(&self) -> &[MaterialParams] {
        &self.params
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

    /// Applies one `--set MATERIAL.PARAM=VALUE` edit (values already range-checked by the
    /// parser; shininess/alpha outside a basis' sampled range are clamped by it).
    pub(crate) fn apply(&mut self, o: &MaterialOverride) -> Result<(), RuntimeError> {
        let i = self.editable(&o.material)?;
        let m = &self.materials[i];
        let param = o.value.param();
        let wrong = |param: String| RuntimeError::WrongParam {
            name: m.name.clone(),
            family: m.family.to_string(),
            param,
        };
        if !m.family.has_param(param) {
            return Err(wrong(param.to_string()));
        }
        let p = &mut self.params[i];
        match o.value {
            OverrideValue::Kd(c) => p.kd = c,
            OverrideValue::Ks(c) => p.ks = c,
            OverrideValue::Shininess(v) | OverrideValue::Alpha(v) => p.param = v,
            // A parameter the syntax knows but this runtime does not.
            ref other => return Err(wrong(other.param().to_string())),
        }
        Ok(())
    }

    /// Sets every parameter of material `name` at once (it must be editable). Colours must be
    /// finite and >= 0 and the lobe parameter finite; it is clamped to a basis' sampled range
    /// when used, as an edit's is.
    pub(crate) fn set(&mut self, name: &str, p: MaterialParams) -> Result<(), RuntimeError> {
        let i = self.editable(name)?;
        let colour_ok = |c: [f32; 3]| c.iter().all(|v| v.is_finite() && *v >= 0.0);
        let bad = |what: &str, value: String| RuntimeError::BadParams {
            name: name.to_string(),
            reason: format!("{what} = {value} (finite and >= 0 expected)"),
        };
        if !colour_ok(p.kd) {
            return Err(bad("kd", format!("{:?}", p.kd)));
        }
        if !colour_ok(p.ks) {
            return Err(bad("ks", format!("{:?}", p.ks)));
        }
        if !(p.param.is_finite() && p.param >= 0.0) {
            return Err(bad("the lobe parameter", p.param.to_string()));
        }
        self.params[i] = p;
        Ok(())
    }

    /// Every material whose lobe parameter lies outside its basis' sampled range (relighting
    /// clamps it to the range), in the bake's order.
    pub(crate) fn clamped_params(&self) -> Vec<ClampedParam> {
        let mut out = Vec::new();
        for (m, p) in self.materials.iter().zip(&self.params) {
            let (Some(b), Some(param)) = (m.basis, m.family.lobe_param()) else {
                continue;
            };
            let samples = &self.bases[b as usize].param_samples;
            let (Some(&lo), Some(&hi)) = (samples.first(), samples.last()) else {
                continue;
            };
            if !(lo..=hi).contains(&p.param) {
                out.push(ClampedParam {
                    material: m.name.clone(),
                    param,
                    value: p.param,
                    range: [lo, hi],
                });
            }
        }
        out
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
