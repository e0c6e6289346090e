//! The persisted [`BrdfBasis`]: its fields, validation, and the lobe coefficients of a
//! material (evaluation of the tables is in `eval.rs`).

use serde::{Deserialize, Serialize};

use super::{
    AngularGrid, BasisError, GridKind, GridSpec, ParamWarp, ParamWeights, BASIS_SCHEMA_VERSION,
};

/// A BRDF family's basis, as carried by the bake file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BrdfBasis {
    /// [`BASIS_SCHEMA_VERSION`].
    pub version: u32,
    /// The family (stored by name: `"blinn-phong"` or `"ggx"`).
    pub family: crate::family::Family,
    /// How the basis was built (free text, for provenance).
    pub method: String,
    /// Sampled parameter range `[min, max]` (shininess s, or GGX alpha).
    pub param_range: [f32; 2],
    /// Warp in which coefficients are interpolated.
    pub param_warp: ParamWarp,
    /// Parameter values at which `coefficients` are tabulated, strictly increasing, first and
    /// last equal to `param_range`.
    pub param_samples: Vec<f32>,
    /// Axis sizes of the table grid.
    pub grid: AngularGrid,
    /// What the grid's axes are; a missing field means [`GridKind::Angles`] (schema 1).
    #[serde(default)]
    pub grid_kind: GridKind,
    /// `N_b`, including the Lambert basis 0.
    pub num_bases: usize,
    /// Basis tables, `grid.len() * num_bases` values, basis index fastest.
    pub tables: Vec<f32>,
    /// Lobe coefficients `a_b(p)`, `param_samples.len() * num_bases` values, basis index
    /// fastest.
    pub coefficients: Vec<f32>,
}

impl BrdfBasis {
    /// The table grid (kind and sizes).
    pub fn grid_spec(&self) -> GridSpec {
        GridSpec::new(self.grid_kind, self.grid)
    }

    /// Checks version, shapes, ordering and finiteness.
    pub fn validate(&self) -> Result<(), BasisError> {
        if self.version != BASIS_SCHEMA_VERSION {
            return Err(BasisError::Version {
                found: self.version,
                expected: BASIS_SCHEMA_VERSION,
            });
        }
        self.validate_coefficients()?;
        self.grid.validate()?;
        let want = self.grid.len().checked_mul(self.num_bases);
        if want != Some(self.tables.len()) {
            return Err(BasisError::Shape {
                field: "tables",
                found: self.tables.len(),
                expected: want.unwrap_or(usize::MAX),
            });
        }
        if !self.tables.iter().all(|v| v.is_finite()) {
            return Err(BasisError::Invalid("non-finite values".into()));
        }
        Ok(())
    }

    /// Checks everything [`BrdfBasis::coefficients`] relies on: `num_bases`, the parameter
    /// samples (strictly increasing, finite), the coefficient table's shape and finiteness, the
    /// warp. Not the version or the tables: a bake file's metadata carries a basis without its
    /// tables (they are a tensor), and the runtime needs only the coefficients.
    pub fn validate_coefficients(&self) -> Result<(), BasisError> {
        if self.num_bases == 0 {
            return Err(BasisError::Invalid("num_bases is 0".into()));
        }
        if self.param_samples.is_empty() {
            return Err(BasisError::Invalid("no parameter samples".into()));
        }
        let want = self.param_samples.len().checked_mul(self.num_bases);
        if want != Some(self.coefficients.len()) {
            return Err(BasisError::Shape {
                field: "coefficients",
                found: self.coefficients.len(),
                expected: want.unwrap_or(usize::MAX),
            });
        }
        if !self.param_samples.iter().all(|v| v.is_finite())
            || !self.coefficients.iter().all(|v| v.is_finite())
        {
            return Err(BasisError::Invalid("non-finite values".into()));
        }
        if !self.param_samples.windows(2).all(|w| w[0] < w[1]) {
            return Err(BasisError::Invalid(
                "param_samples must be strictly increasing".into(),
            ));
        }
        if let ParamWarp::Log { offset } = self.param_warp {
            if self.param_samples[0] + offset <= 0.0 || offset.is_nan() {
                return Err(BasisError::Invalid(
                    "log warp needs param + offset > 0 over the range".into(),
                ));
            }
        }
        Ok(())
    }

    /// Lobe coefficients `a_b(param)` (length `num_bases`) by linear interpolation in the
    /// warped parameter; `clamped` is true when `param` was outside the sampled range (or not
    /// finite) and was clamped to it.
    pub fn coefficients(&self, param: f32) -> (Vec<f32>, bool) {
        let mut out = vec![0.0; self.num_bases];
        let clamped = self.coefficients_into(param, &mut out);
        (out, clamped)
    }

    /// Allocation-free [`BrdfBasis::coefficients`]; `out` must hold `num_bases` values.
    pub fn coefficients_into(&self, param: f32, out: &mut [f32]) -> bool {
        let nb = self.num_bases;
        let (ParamWeights { j0, j1, t }, clamped) =
            self.param_warp.weights(&self.param_samples, param);
        let a = &self.coefficients[j0 * nb..(j0 + 1) * nb];
        let b = &self.coefficients[j1 * nb..(j1 + 1) * nb];
        for k in 0..nb {
            out[k] = a[k] + t * (b[k] - a[k]);
        }
        clamped
    }

    /// Per-channel basis coefficients of the BRDF `Kd/pi + Ks * lobe_param`:
    /// `c_0 = Kd + Ks a_0`, `c_b = Ks a_b`. Returns `(c[b][channel], clamped)`.
    pub fn material_coefficients(
        &self,
        kd: [f32; 3],
        ks: [f32; 3],
        param: f32,
    ) -> (Vec<[f32; 3]>, bool) {
        let (a, clamped) = self.coefficients(param);
        let c = a
            .iter()
            .enumerate()
            .map(|(b, &ab)| {
                let d = if b == 0 { kd } else { [0.0; 3] };
                [d[0] + ks[0] * ab, d[1] + ks[1] * ab, d[2] + ks[2] * ab]
            })
            .collect();
        (c, clamped)
    }
}
