//! Persisted BRDF basis (schema shared by the baker and the runtime; see docs/brdf-basis.md).
//!
//! A [`BrdfBasis`] represents every BRDF of one family (`blinn-phong` with shininess `s`, or
//! `ggx` with roughness `alpha`) as a combination of `N_b` fixed basis BRDFs:
//!
//! ```text
//! f(wi, wo) = Kd/pi + Ks * lobe_p(wi, wo)  ~=  sum_b c_b * basis_b(wi, wo)
//! c_0 = Kd + Ks * a_0(p),   c_b = Ks * a_b(p)  (b >= 1)
//! ```
//!
//! Basis 0 is the constant Lambert lobe `1/pi`; bases 1.. come from a PCA of the family's
//! specular lobes. `a_b(p)` are the lobe coefficients, tabulated at `param_samples` and
//! interpolated linearly in the warped parameter `u = warp(p)`; outside the sampled range the
//! parameter is clamped and the caller is told (`clamped = true`).
//!
//! Basis tables are sampled on an isotropic node grid over `(theta_i, theta_o, phi)`:
//! `theta = j * (pi/2) / (n_theta - 1)` (both endpoints included), `phi = k * pi / (n_phi - 1)`,
//! where `phi` is the angle between the projections of `wi` and `wo` on the tangent plane (so
//! the mirror direction has `phi = pi`). Evaluation is trilinear in these angles. `tables` is
//! stored with the basis index fastest: `tables[((i * n_theta_o + o) * n_phi + k) * N_b + b]`,
//! so one evaluation reads 8 runs of `N_b` contiguous floats and shares its weights between all
//! bases.
//!
//! This module depends on nothing but `serde`/`thiserror`, so the runtime can use it without
//! the baker.

use serde::{Deserialize, Serialize};
use std::f32::consts::{FRAC_PI_2, PI};

/// Bases up to this count are accumulated in registers by [`BrdfBasis::eval_weights`].
const MAX_REGISTER_BASES: usize = 16;

/// Version of the [`BrdfBasis`] schema. Bump when the meaning or layout of a field changes.
pub const BASIS_SCHEMA_VERSION: u32 = 1;

/// Errors found when validating a deserialized basis.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BasisError {
    #[error("unsupported BRDF basis schema version {found} (this build reads {expected})")]
    Version { found: u32, expected: u32 },
    #[error("BRDF basis field `{field}` has {found} values, expected {expected}")]
    Shape {
        field: &'static str,
        found: usize,
        expected: usize,
    },
    #[error("BRDF basis is invalid: {0}")]
    Invalid(String),
}

/// How the lobe parameter is warped before coefficients are interpolated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ParamWarp {
    /// `u = p`
    Linear,
    /// `u = ln(p + offset)`
    Log { offset: f32 },
}

impl ParamWarp {
    #[inline]
    pub fn apply(self, p: f64) -> f64 {
        match self {
            ParamWarp::Linear => p,
            ParamWarp::Log { offset } => (p + offset as f64).max(1e-300).ln(),
        }
    }

    /// [`ParamWarp::apply`] in f32 (the runtime's interpolation).
    #[inline]
    pub fn apply_f32(self, p: f32) -> f32 {
        match self {
            ParamWarp::Linear => p,
            ParamWarp::Log { offset } => (p + offset).max(f32::MIN_POSITIVE).ln(),
        }
    }

    #[inline]
    pub fn invert(self, u: f64) -> f64 {
        match self {
            ParamWarp::Linear => u,
            ParamWarp::Log { offset } => u.exp() - offset as f64,
        }
    }
}

/// Node counts of the isotropic `(theta_i, theta_o, phi)` grid (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct AngularGrid {
    pub n_theta_i: usize,
    pub n_theta_o: usize,
    pub n_phi: usize,
}

impl AngularGrid {
    /// The thesis' resolution (section 4.1.5): 30 x 30 x 60.
    pub const THESIS: AngularGrid = AngularGrid {
        n_theta_i: 30,
        n_theta_o: 30,
        n_phi: 60,
    };

    pub fn len(&self) -> usize {
        self.n_theta_i * self.n_theta_o * self.n_phi
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// theta of node `j` on an axis with `n` nodes.
    pub fn theta(n: usize, j: usize) -> f64 {
        j as f64 * std::f64::consts::FRAC_PI_2 / (n - 1) as f64
    }

    /// phi of node `k` on an axis with `n` nodes.
    pub fn phi(n: usize, k: usize) -> f64 {
        k as f64 * std::f64::consts::PI / (n - 1) as f64
    }

    /// Flat node index (basis index excluded).
    #[inline]
    pub fn index(&self, i: usize, o: usize, k: usize) -> usize {
        (i * self.n_theta_o + o) * self.n_phi + k
    }

    pub fn validate(&self) -> Result<(), BasisError> {
        if self.n_theta_i < 2 || self.n_theta_o < 2 || self.n_phi < 2 {
            return Err(BasisError::Invalid(format!(
                "angular grid {}x{}x{} needs at least 2 nodes per axis",
                self.n_theta_i, self.n_theta_o, self.n_phi
            )));
        }
        Ok(())
    }
}

/// A BRDF family's basis, as carried by the bake file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BrdfBasis {
    /// [`BASIS_SCHEMA_VERSION`].
    pub version: u32,
    /// `"blinn-phong"` or `"ggx"`.
    pub family: String,
    /// How the basis was built (free text, for provenance).
    pub method: String,
    /// Sampled parameter range `[min, max]` (shininess s, or GGX alpha).
    pub param_range: [f32; 2],
    /// Warp in which coefficients are interpolated.
    pub param_warp: ParamWarp,
    /// Parameter values at which `coefficients` are tabulated, strictly increasing, first and
    /// last equal to `param_range`.
    pub param_samples: Vec<f32>,
    pub grid: AngularGrid,
    /// `N_b`, including the Lambert basis 0.
    pub num_bases: usize,
    /// Basis tables, `grid.len() * num_bases` values, basis index fastest.
    pub tables: Vec<f32>,
    /// Lobe coefficients `a_b(p)`, `param_samples.len() * num_bases` values, basis index
    /// fastest.
    pub coefficients: Vec<f32>,
}

/// Fast `acos` (Abramowitz & Stegun 4.4.46, |error| <= 2e-8 in exact arithmetic), used so
/// that the baker and the runtime evaluate the tables identically and quickly. `x` is clamped
/// to [-1, 1].
#[inline]
#[allow(clippy::excessive_precision)]
pub fn fast_acos(x: f32) -> f32 {
    let x = x.clamp(-1.0, 1.0);
    let a = x.abs();
    let p = -0.001_262_491_1_f32;
    let p = p * a + 0.006_670_090_1;
    let p = p * a - 0.017_088_125_6;
    let p = p * a + 0.030_891_881_0;
    let p = p * a - 0.050_174_304_6;
    let p = p * a + 0.088_978_987_4;
    let p = p * a - 0.214_598_801_6;
    let p = p * a + 1.570_796_305_0;
    let r = (1.0 - a).max(0.0).sqrt() * p;
    if x >= 0.0 {
        r
    } else {
        PI - r
    }
}

/// Trilinear interpolation weights over the angular grid, shared by all bases.
#[derive(Clone, Copy, Debug)]
pub struct GridWeights {
    /// Flat node index (without the basis factor) of the (i0, o0, k0) corner.
    pub base: usize,
    /// Node strides for +1 in theta_i and theta_o (phi stride is 1).
    pub stride_i: usize,
    pub stride_o: usize,
    /// Fractions along theta_i, theta_o, phi.
    pub fi: f32,
    pub fo: f32,
    pub fp: f32,
}

#[inline]
fn axis(t: f32, n: usize) -> (usize, f32) {
    // t in node units, clamped to [0, n-1]
    let t = if t.is_nan() {
        0.0
    } else {
        t.clamp(0.0, (n - 1) as f32)
    };
    let i0 = (t as usize).min(n - 2);
    (i0, (t - i0 as f32).clamp(0.0, 1.0))
}

impl BrdfBasis {
    /// Checks version, shapes, ordering and finiteness.
    pub fn validate(&self) -> Result<(), BasisError> {
        if self.version != BASIS_SCHEMA_VERSION {
            return Err(BasisError::Version {
                found: self.version,
                expected: BASIS_SCHEMA_VERSION,
            });
        }
        self.grid.validate()?;
        if self.num_bases == 0 {
            return Err(BasisError::Invalid("num_bases is 0".into()));
        }
        let want = self.grid.len() * self.num_bases;
        if self.tables.len() != want {
            return Err(BasisError::Shape {
                field: "tables",
                found: self.tables.len(),
                expected: want,
            });
        }
        if self.param_samples.is_empty() {
            return Err(BasisError::Invalid("no parameter samples".into()));
        }
        let want = self.param_samples.len() * self.num_bases;
        if self.coefficients.len() != want {
            return Err(BasisError::Shape {
                field: "coefficients",
                found: self.coefficients.len(),
                expected: want,
            });
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
        if !self.tables.iter().all(|v| v.is_finite())
            || !self.coefficients.iter().all(|v| v.is_finite())
            || !self.param_samples.iter().all(|v| v.is_finite())
        {
            return Err(BasisError::Invalid("non-finite values".into()));
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
        let ps = &self.param_samples;
        let (lo, hi) = (ps[0], ps[ps.len() - 1]);
        let clamped = !(param >= lo && param <= hi);
        let p = if param.is_nan() {
            lo
        } else {
            param.clamp(lo, hi)
        };
        if ps.len() == 1 {
            out[..nb].copy_from_slice(&self.coefficients[..nb]);
            return clamped;
        }
        // first sample index j with ps[j] > p, so ps[j0] <= p < ps[j0 + 1]
        let j = ps.partition_point(|&x| x <= p);
        let j0 = j.saturating_sub(1).min(ps.len() - 2);
        let u0 = self.param_warp.apply_f32(ps[j0]);
        let u1 = self.param_warp.apply_f32(ps[j0 + 1]);
        let u = self.param_warp.apply_f32(p);
        let t = if u1 > u0 {
            ((u - u0) / (u1 - u0)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let a = &self.coefficients[j0 * nb..(j0 + 1) * nb];
        let b = &self.coefficients[(j0 + 1) * nb..(j0 + 2) * nb];
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

    /// Interpolation weights for a direction pair given by cosines: `cos_theta_i`,
    /// `cos_theta_o` (clamped to [0, 1]) and `cos_phi`, the cosine of the angle between the
    /// tangent-plane projections of wi and wo (any value works when one is along the normal).
    #[inline]
    pub fn weights(&self, cos_theta_i: f32, cos_theta_o: f32, cos_phi: f32) -> GridWeights {
        let g = &self.grid;
        let ti = fast_acos(cos_theta_i.max(0.0));
        let to = fast_acos(cos_theta_o.max(0.0));
        let ph = fast_acos(cos_phi);
        let (i0, fi) = axis(ti * ((g.n_theta_i - 1) as f32 / FRAC_PI_2), g.n_theta_i);
        let (o0, fo) = axis(to * ((g.n_theta_o - 1) as f32 / FRAC_PI_2), g.n_theta_o);
        let (k0, fp) = axis(ph * ((g.n_phi - 1) as f32 / PI), g.n_phi);
        GridWeights {
            base: g.index(i0, o0, k0),
            stride_i: g.n_theta_o * g.n_phi,
            stride_o: g.n_phi,
            fi,
            fo,
            fp,
        }
    }

    /// All basis values at the interpolation point `w`; `out` must hold `num_bases` values.
    #[inline]
    pub fn eval_weights(&self, w: &GridWeights, out: &mut [f32]) {
        let nb = self.num_bases;
        let t = &self.tables;
        let corners = [
            (0, (1.0 - w.fi) * (1.0 - w.fo)),
            (w.stride_o, (1.0 - w.fi) * w.fo),
            (w.stride_i, w.fi * (1.0 - w.fo)),
            (w.stride_i + w.stride_o, w.fi * w.fo),
        ];
        if nb <= MAX_REGISTER_BASES {
            // accumulate in a local array (kept in registers) rather than through `out`
            let mut acc = [0.0f32; MAX_REGISTER_BASES];
            for (off, wio) in corners {
                let n0 = (w.base + off) * nb;
                let (lo, hi) = t[n0..n0 + 2 * nb].split_at(nb);
                let (w0, w1) = (wio * (1.0 - w.fp), wio * w.fp);
                for b in 0..nb {
                    acc[b] += w0 * lo[b] + w1 * hi[b];
                }
            }
            out[..nb].copy_from_slice(&acc[..nb]);
            return;
        }
        let out = &mut out[..nb];
        out.fill(0.0);
        for (off, wio) in corners {
            let n0 = (w.base + off) * nb;
            let (lo, hi) = t[n0..n0 + 2 * nb].split_at(nb);
            let (w0, w1) = (wio * (1.0 - w.fp), wio * w.fp);
            for b in 0..nb {
                out[b] += w0 * lo[b] + w1 * hi[b];
            }
        }
    }

    /// All basis values `basis_b(wi, wo)` for a direction pair given by cosines (see
    /// [`BrdfBasis::weights`]); `out` must hold `num_bases` values.
    #[inline]
    pub fn eval_all(&self, cos_theta_i: f32, cos_theta_o: f32, cos_phi: f32, out: &mut [f32]) {
        let w = self.weights(cos_theta_i, cos_theta_o, cos_phi);
        self.eval_weights(&w, out);
    }

    /// All basis values for local-frame unit vectors (normal = +Z, both pointing away from
    /// the surface). Directions below the horizon give zeros.
    #[inline]
    pub fn eval_all_local(&self, wi: [f32; 3], wo: [f32; 3], out: &mut [f32]) {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            out[..self.num_bases].fill(0.0);
            return;
        }
        let (cp, _) = cos_phi_local(wi, wo);
        self.eval_all(wi[2], wo[2], cp, out);
    }

    /// Value of the BRDF `Kd/pi + Ks lobe` reconstructed from the basis for one channel,
    /// given its coefficients `c` (from [`BrdfBasis::material_coefficients`] or
    /// `coefficients`). Convenience for tests and tools; the baker uses `eval_all`.
    pub fn reconstruct(&self, c: &[f32], cos_theta_i: f32, cos_theta_o: f32, cos_phi: f32) -> f32 {
        let mut v = vec![0.0; self.num_bases];
        self.eval_all(cos_theta_i, cos_theta_o, cos_phi, &mut v);
        v.iter().zip(c).map(|(a, b)| a * b).sum()
    }
}

/// Cosine of the azimuth difference of two local-frame directions, and whether it was
/// defined (false when either lies along the normal; then 1 is returned).
#[inline]
pub fn cos_phi_local(wi: [f32; 3], wo: [f32; 3]) -> (f32, bool) {
    let li = wi[0] * wi[0] + wi[1] * wi[1];
    let lo = wo[0] * wo[0] + wo[1] * wo[1];
    let d = li * lo;
    if d <= 1e-20 {
        return (1.0, false);
    }
    (
        ((wi[0] * wo[0] + wi[1] * wo[1]) / d.sqrt()).clamp(-1.0, 1.0),
        true,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> BrdfBasis {
        let grid = AngularGrid {
            n_theta_i: 3,
            n_theta_o: 4,
            n_phi: 5,
        };
        let nb = 2;
        let mut tables = vec![0.0; grid.len() * nb];
        for i in 0..3 {
            for o in 0..4 {
                for k in 0..5 {
                    let n = grid.index(i, o, k);
                    tables[n * nb] = 1.0 / PI;
                    // linear in the three angles: trilinear interpolation is exact
                    let (ti, to, ph) = (
                        AngularGrid::theta(3, i),
                        AngularGrid::theta(4, o),
                        AngularGrid::phi(5, k),
                    );
                    tables[n * nb + 1] = (ti - 2.0 * to + 0.5 * ph) as f32;
                }
            }
        }
        BrdfBasis {
            version: BASIS_SCHEMA_VERSION,
            family: "blinn-phong".into(),
            method: "test".into(),
            param_range: [1.0, 100.0],
            param_warp: ParamWarp::Log { offset: 2.0 },
            param_samples: vec![1.0, 10.0, 100.0],
            grid,
            num_bases: nb,
            tables,
            coefficients: vec![0.1, 1.0, 0.2, 2.0, 0.3, 3.0],
        }
    }

    #[test]
    fn acos_accuracy() {
        let mut worst = 0.0f64;
        for i in 0..=20000 {
            let x = (-1.0 + 2.0 * i as f64 / 20000.0) as f32;
            let e = (fast_acos(x) as f64 - (x as f64).acos()).abs();
            worst = worst.max(e);
        }
        assert!(worst < 1e-6, "{worst}");
    }

    #[test]
    fn trilinear_exact_on_linear_table() {
        let b = tiny();
        b.validate().unwrap();
        let mut out = [0.0; 2];
        for &(ti, to, ph) in &[(0.3f32, 1.1f32, 2.0f32), (0.0, 0.0, 0.0), (1.5, 0.7, 3.1)] {
            b.eval_all(ti.cos(), to.cos(), ph.cos(), &mut out);
            assert!((out[0] - 1.0 / PI).abs() < 1e-6);
            let want = ti - 2.0 * to + 0.5 * ph;
            assert!((out[1] - want).abs() < 2e-5, "{} vs {}", out[1], want);
        }
    }

    #[test]
    fn coefficients_interpolate_and_clamp() {
        let b = tiny();
        let (c, cl) = b.coefficients(10.0);
        assert!(!cl);
        assert!((c[1] - 2.0).abs() < 1e-6);
        let (c, cl) = b.coefficients(1000.0);
        assert!(cl);
        assert_eq!(c, vec![0.3, 3.0]);
        let (c, cl) = b.coefficients(f32::NAN);
        assert!(cl);
        assert_eq!(c, vec![0.1, 1.0]);
        // halfway in log(p + 2) between 1 and 10
        let p = ((3.0f64.ln() + 12.0f64.ln()) / 2.0).exp() - 2.0;
        let (c, _) = b.coefficients(p as f32);
        assert!((c[1] - 1.5).abs() < 1e-4, "{c:?}");
        let (m, _) = b.material_coefficients([0.5; 3], [0.25; 3], 10.0);
        assert!((m[0][0] - (0.5 + 0.25 * 0.2)).abs() < 1e-6);
        assert!((m[1][2] - 0.5).abs() < 1e-6);
    }

    #[test]
    fn validate_catches_shapes() {
        let mut b = tiny();
        b.tables.pop();
        assert!(matches!(b.validate(), Err(BasisError::Shape { .. })));
        let mut b = tiny();
        b.version = 99;
        assert!(matches!(b.validate(), Err(BasisError::Version { .. })));
        let mut b = tiny();
        b.param_samples[1] = 0.5;
        assert!(b.validate().is_err());
    }

    #[test]
    fn serde_round_trip() {
        let b = tiny();
        let s = serde_json::to_string(&b).unwrap();
        let c: BrdfBasis = serde_json::from_str(&s).unwrap();
        assert_eq!(b, c);
    }
}
