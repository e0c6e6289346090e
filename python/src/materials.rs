//! A bake's materials as Python sees them ([`Material`], [`Param`], read from the runtime's
//! `MaterialInfo`), and parameters given by name (`r.set("bunny", kd=(0.8, 0.2, 0.2),
//! alpha=0.3)`) as the runtime's `OverrideValue`s.

use prt_runtime::{MaterialInfo, OverrideValue, Param as ParamName, ParamInfo, ParamRange};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::arrays::decimal;
use crate::errors::{message, Kind};

/// One parameter of a material: its current value, the values `set` accepts, and for a
/// glossy lobe the range its bake sampled.
#[pyclass(module = "prt", frozen, get_all)]
pub struct Param {
    /// `"kd"`, `"ks"`, `"shininess"` or `"alpha"`.
    pub name: &'static str,
    /// The current value: `(r, g, b)` for a colour, a float for a lobe parameter.
    pub value: Py<PyAny>,
    /// `(min, max)` of the values `set` accepts (per channel for a colour; `max` may be
    /// infinite).
    pub range: (f64, f64),
    /// The lobe parameter of an editable glossy material: the `(min, max)` its bake sampled;
    /// a value outside is accepted and rendered as at the nearest end (clamped).
    pub sampled: Option<(f64, f64)>,
    /// Whether the current value lies outside `sampled` and is rendered clamped.
    pub clamped: bool,
}

#[pymethods]
impl Param {
    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let value = self.value.bind(py).repr()?;
        let sampled = match self.sampled {
            Some((a, b)) => format!(", sampled=({a}, {b})"),
            None => String::new(),
        };
        Ok(format!(
            "Param({}={value}, range=({}, {}){sampled}{})",
            self.name,
            self.range.0,
            self.range.1,
            if self.clamped { ", clamped" } else { "" }
        ))
    }
}

/// A material of the bake: its BRDF family, whether it can be edited, and its parameters.
#[pyclass(module = "prt", frozen, get_all)]
pub struct Material {
    /// The name `set` addresses it by.
    pub name: String,
    /// `"diffuse"`, `"blinn-phong"` or `"ggx"`.
    pub family: String,
    /// Whether it was baked editable (a fixed material refuses `set`).
    pub editable: bool,
    /// Whether a base-colour texture modulates its `kd`.
    pub textured: bool,
    /// Its parameters by name (`kd`; for a glossy family also `ks` and `shininess` or
    /// `alpha`), as `Param`s.
    pub params: Py<PyDict>,
}

#[pymethods]
impl Material {
    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let values: Vec<String> = self
            .params
            .bind(py)
            .iter()
            .map(|(k, p)| Ok(format!("{k}={}", p.getattr("value")?.repr()?)))
            .collect::<PyResult<_>>()?;
        Ok(format!(
            "Material({:?}, {}, {}{}: {})",
            self.name,
            self.family,
            if self.editable { "editable" } else { "fixed" },
            if self.textured { ", textured" } else { "" },
            values.join(", ")
        ))
    }
}

fn range(r: ParamRange) -> (f64, f64) {
    (decimal(r.min), decimal(r.max))
}

fn param(py: Python<'_>, p: &ParamInfo) -> PyResult<Param> {
    let value = match p.value {
        OverrideValue::Kd(c) | OverrideValue::Ks(c) => {
            PyTuple::new(py, c.map(decimal))?.into_any().unbind()
        }
        OverrideValue::Shininess(v) | OverrideValue::Alpha(v) => {
            decimal(v).into_pyobject(py)?.into_any().unbind()
        }
        // A parameter the runtime lists but this binding does not know yet.
        other => {
            return Err(message(
                Kind::Other,
                format!(
                    "parameter {:?} is not supported by this binding",
                    other.param()
                ),
            ))
        }
    };
    Ok(Param {
        name: p.param().name(),
        value,
        range: range(p.range),
        sampled: p.sampled.map(range),
        clamped: p.clamped(),
    })
}

/// The runtime's materials as Python objects.
pub fn materials(py: Python<'_>, infos: &[MaterialInfo]) -> PyResult<Vec<Material>> {
    infos
        .iter()
        .map(|m| {
            let params = PyDict::new(py);
            for p in &m.params {
                params.set_item(p.param().name(), param(py, p)?)?;
            }
            Ok(Material {
                name: m.name.clone(),
                family: m.family.to_string(),
                editable: m.editable,
                textured: m.textured,
                params: params.unbind(),
            })
        })
        .collect()
}

/// A colour given as one number (gray) or three.
fn colour(name: &str, value: &Bound<'_, PyAny>) -> PyResult<[f32; 3]> {
    if let Ok(v) = value.extract::<f32>() {
        return Ok([v; 3]);
    }
    value.extract::<[f32; 3]>().map_err(|_| {
        message(
            Kind::Parameter,
            format!("{name} = {value}: give a colour as three numbers (r, g, b) or one (gray)"),
        )
    })
}

/// Keyword parameters (`kd=(0.8, 0.2, 0.2)`, `ks=0.5`, `shininess=50`, `alpha=0.3`) as
/// runtime values, in the order given. The runtime checks them against the material.
pub fn values(params: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<OverrideValue>> {
    let Some(params) = params else {
        return Ok(Vec::new());
    };
    let mut out = Vec::with_capacity(params.len());
    for (key, value) in params.iter() {
        let key: String = key.extract()?;
        let Some(p) = ParamName::from_name(&key) else {
            let valid: Vec<&str> = ParamName::ALL.iter().map(|p| p.name()).collect();
            return Err(message(
                Kind::Parameter,
                format!(
                    "unknown parameter '{key}'; valid parameters: {}",
                    valid.join(", ")
                ),
            ));
        };
        let scalar = || {
            value
                .extract::<f32>()
                .map_err(|_| message(Kind::Parameter, format!("{key} = {value}: give a number")))
        };
        out.push(match p {
            ParamName::Kd => OverrideValue::Kd(colour(&key, &value)?),
            ParamName::Ks => OverrideValue::Ks(colour(&key, &value)?),
            ParamName::Shininess => OverrideValue::Shininess(scalar()?),
            ParamName::Alpha => OverrideValue::Alpha(scalar()?),
            // A parameter the syntax knows but this binding does not yet.
            other => {
                return Err(message(
                    Kind::Parameter,
                    format!("parameter '{other}' is not supported by this binding"),
                ))
            }
        });
    }
    Ok(out)
}
