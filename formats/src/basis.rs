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
//! Basis tables are sampled on a node grid over three angular coordinates and evaluated by
//! trilinear interpolation in the grid's coordinates `u1, u2, u3` (each in `[0, 1]`, nodes
//! uniform in it). [`GridKind`] says what the coordinates are:
//!
//! - [`GridKind::HalfDiff`] (default of the builder): Rusinkiewicz' half/difference angles,
//!   graded towards the specular peak and the grazing limit (docs/brdf-basis.md):
//!   `u1 = (1 - cos theta_h)^(1/4)`, `u2 = ln((cos theta_d + c0) / (1 + c0)) / ln(c0 / (1 + c0))`
//!   with `c0 =` [`HALF_DIFF_COS_OFFSET`], `u3 = sin^2 phi_d`, where `phi_d` is the azimuth of
//!   `wi` about the half vector (folded onto `[0, pi/2]`: the families are isotropic and
//!   reciprocal). Nodes sit on both ends of every axis; nodes whose direction pair dips below
//!   the horizon hold the lobe continued with clamped cosines.
//! - [`GridKind::Angles`] (the thesis' grid, schema 1): `theta_i`, `theta_o` uniform in
//!   `[0, pi/2]`, `phi` uniform in `[0, pi]` (the angle between the tangent-plane projections of
//!   `wi` and `wo`; mirror at `phi = pi`), both ends included; horizon nodes hold the lobe's
//!   limit from inside.
//!
//! `tables` is stored with the basis index fastest:
//! `tables[((i * n_theta_o + o) * n_phi + k) * N_b + b]` (axis sizes from [`AngularGrid`]), so
//! one evaluation reads 8 runs of `N_b` contiguous floats and shares its weights between all
//! bases.
//!
//! This module depends on nothing but `serde`/`thiserror`, so the runtime can use it without
//! the baker.

use serde::{Deserialize, Serialize};
use std::f32::consts::{FRAC_PI_2, PI};

/// Bases up to this count are accumulated in registers by [`BrdfBasis::eval_weights`].
const MAX_REGISTER_BASES: usize = 16;

/// Version of the [`BrdfBasis`] schema. Bump when the meaning or layout of a field changes.
/// Version 2 added [`BrdfBasis::grid_kind`] (the half/difference grid); version 1 files are
/// refused.
pub const BASIS_SCHEMA_VERSION: u32 = 2;

/// `c0` of the [`GridKind::HalfDiff`] `theta_d` axis: nodes are uniform in `ln(cos theta_d + c0)`
/// near the grazing end, so cells shrink to about `c0` in `cos theta_d`, which resolves the GGX
/// grazing limit `G1(c)/c -> 2/alpha` (reached within `c ~ alpha`) down to alpha ~ 2 c0.
pub const HALF_DIFF_COS_OFFSET: f64 = 0.01;

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

/// What the three axes of an [`AngularGrid`] are (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GridKind {
    /// `(theta_i, theta_o, phi)`, uniform, horizon nodes included (the thesis' grid; the only
    /// meaning in schema 1, hence the default of a missing field).
    #[default]
    Angles,
    /// `(theta_h, theta_d, phi_d)` graded towards the specular peak and the grazing limit.
    HalfDiff,
}

impl GridKind {
    pub fn name(self) -> &'static str {
        match self {
            GridKind::Angles => "angles",
            GridKind::HalfDiff => "half-diff",
        }
    }

    /// Names of the three axes.
    pub fn axis_names(self) -> [&'static str; 3] {
        match self {
            GridKind::Angles => ["theta_i", "theta_o", "phi"],
            GridKind::HalfDiff => ["theta_h", "theta_d", "phi_d"],
        }
    }
}

/// Node counts of the isotropic three-axis grid (see the module docs). The field names are
/// those of the [`GridKind::Angles`] axes; for [`GridKind::HalfDiff`] they count the nodes
/// along `theta_h`, `theta_d` and `phi_d`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct AngularGrid {
    pub n_theta_i: usize,
    pub n_theta_o: usize,
    pub n_phi: usize,
}

/// A grid: what its axes are and how many nodes each has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridSpec {
    pub kind: GridKind,
    pub dims: AngularGrid,
}

impl GridSpec {
    /// The default grid of new bases: [`GridKind::HalfDiff`], [`AngularGrid::HALF_DIFF`].
    pub const DEFAULT: GridSpec = GridSpec {
        kind: GridKind::HalfDiff,
        dims: AngularGrid::HALF_DIFF,
    };

    /// The thesis' grid: [`GridKind::Angles`], [`AngularGrid::THESIS`].
    pub const THESIS: GridSpec = GridSpec {
        kind: GridKind::Angles,
        dims: AngularGrid::THESIS,
    };

    pub fn new(kind: GridKind, dims: AngularGrid) -> GridSpec {
        GridSpec { kind, dims }
    }

    pub fn len(&self) -> usize {
        self.dims.len()
    }

    pub fn is_empty(&self) -> bool {
        self.dims.is_empty()
    }

    /// The direction pair of node `(i, o, k)`.
    pub fn node(&self, i: usize, o: usize, k: usize) -> GridNode {
        self.dims.node(self.kind, i, o, k)
    }

    /// All nodes in table order ([`AngularGrid::index`]).
    pub fn nodes(&self) -> Vec<GridNode> {
        let g = &self.dims;
        let mut v = Vec::with_capacity(g.len());
        for i in 0..g.n_theta_i {
            for o in 0..g.n_theta_o {
                for k in 0..g.n_phi {
                    v.push(self.node(i, o, k));
                }
            }
        }
        v
    }

    /// e.g. `half-diff 96x64x8`.
    pub fn describe(&self) -> String {
        format!(
            "{} {}x{}x{}",
            self.kind.name(),
            self.dims.n_theta_i,
            self.dims.n_theta_o,
            self.dims.n_phi
        )
    }
}

/// A direction pair standing for one grid node (f64, baker side): cosines of `theta_i`,
/// `theta_o`, of the azimuth difference `phi` and of `theta_h`. For [`GridKind::HalfDiff`]
/// nodes outside the pair of hemispheres the cosines are returned unclamped (negative); the
/// tables hold the lobe continued with clamped cosines there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridNode {
    pub cos_theta_i: f64,
    pub cos_theta_o: f64,
    pub cos_phi: f64,
    pub cos_theta_h: f64,
}

impl GridNode {
    /// Whether both directions are above the horizon (weight > 0 in the error metric).
    pub fn inside(&self) -> bool {
        self.cos_theta_i > 0.0 && self.cos_theta_o > 0.0
    }
}

impl AngularGrid {
    /// The thesis' resolution (section 4.1.5): 30 x 30 x 60 over `(theta_i, theta_o, phi)`.
    pub const THESIS: AngularGrid = AngularGrid {
        n_theta_i: 30,
        n_theta_o: 30,
        n_phi: 60,
    };

    /// The default [`GridKind::HalfDiff`] resolution: 96 `theta_h` x 64 `theta_d` x 8 `phi_d`
    /// nodes (49152, fewer than [`AngularGrid::THESIS`]'s 54000).
    pub const HALF_DIFF: AngularGrid = AngularGrid {
        n_theta_i: 96,
        n_theta_o: 64,
        n_phi: 8,
    };

    pub fn len(&self) -> usize {
        self.n_theta_i * self.n_theta_o * self.n_phi
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// theta of node `j` on an [`GridKind::Angles`] theta axis with `n` nodes.
    pub fn theta(n: usize, j: usize) -> f64 {
        j as f64 * std::f64::consts::FRAC_PI_2 / (n - 1) as f64
    }

    /// phi of node `k` on an [`GridKind::Angles`] phi axis with `n` nodes.
    pub fn phi(n: usize, k: usize) -> f64 {
        k as f64 * std::f64::consts::PI / (n - 1) as f64
    }

    /// Flat node index (basis index excluded).
    #[inline]
    pub fn index(&self, i: usize, o: usize, k: usize) -> usize {
        (i * self.n_theta_o + o) * self.n_phi + k
    }

    /// The direction pair of node `(i, o, k)` for a grid of kind `kind`.
    pub fn node(&self, kind: GridKind, i: usize, o: usize, k: usize) -> GridNode {
        match kind {
            GridKind::Angles => {
                let (si, ci) = Self::theta(self.n_theta_i, i).sin_cos();
                let (so, co) = Self::theta(self.n_theta_o, o).sin_cos();
                let cp = Self::phi(self.n_phi, k).cos();
                let h = [si + so * cp, so * (1.0 - cp * cp).max(0.0).sqrt(), ci + co];
                let len = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
                GridNode {
                    cos_theta_i: ci,
                    cos_theta_o: co,
                    cos_phi: cp,
                    cos_theta_h: if len > 0.0 { h[2] / len } else { 0.0 },
                }
            }
            GridKind::HalfDiff => {
                let u = |j: usize, n: usize| j as f64 / (n - 1) as f64;
                let (ch, cd, s2) =
                    half_diff_node(u(i, self.n_theta_i), u(o, self.n_theta_o), u(k, self.n_phi));
                half_diff_pair(ch, cd, s2)
            }
        }
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

/// `(cos theta_h, cos theta_d, sin^2 phi_d)` at the [`GridKind::HalfDiff`] coordinates
/// `(u1, u2, u3)` (the inverse of the evaluation's mapping).
pub fn half_diff_node(u1: f64, u2: f64, u3: f64) -> (f64, f64, f64) {
    let c0 = HALF_DIFF_COS_OFFSET;
    let cos_h = 1.0 - u1.powi(4);
    let cos_d = ((1.0 + c0) * (u2 * (c0 / (1.0 + c0)).ln()).exp() - c0).clamp(0.0, 1.0);
    (cos_h.clamp(0.0, 1.0), cos_d, u3.clamp(0.0, 1.0))
}

/// The direction pair with half vector at polar angle `theta_h` (azimuth 0) and `wi` at
/// `(theta_d, phi_d)` about it (`wo` is `wi` mirrored about the half vector), given
/// `cos theta_h`, `cos theta_d` and `sin^2 phi_d` (`phi_d` in `[0, pi/2]`).
pub fn half_diff_pair(cos_h: f64, cos_d: f64, sin2_phi_d: f64) -> GridNode {
    let sh = (1.0 - cos_h * cos_h).max(0.0).sqrt();
    let sd = (1.0 - cos_d * cos_d).max(0.0).sqrt();
    let sp = sin2_phi_d.clamp(0.0, 1.0).sqrt();
    let cp = (1.0 - sin2_phi_d).clamp(0.0, 1.0).sqrt();
    // wi = R_y(theta_h) (sd cp, sd sp, cd); wo = 2 cd h - wi with h = (sh, 0, ch)
    let wi = [
        cos_h * sd * cp + sh * cos_d,
        sd * sp,
        -sh * sd * cp + cos_h * cos_d,
    ];
    let wo = [
        2.0 * cos_d * sh - wi[0],
        -wi[1],
        2.0 * cos_d * cos_h - wi[2],
    ];
    let li = (wi[0] * wi[0] + wi[1] * wi[1]).sqrt();
    let lo = (wo[0] * wo[0] + wo[1] * wo[1]).sqrt();
    let cos_phi = if li * lo > 1e-300 {
        ((wi[0] * wo[0] + wi[1] * wo[1]) / (li * lo)).clamp(-1.0, 1.0)
    } else {
        1.0
    };
    GridNode {
        cos_theta_i: wi[2],
        cos_theta_o: wo[2],
        cos_phi,
        cos_theta_h: cos_h,
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

/// `1 / (1 + c0)` and `1 / ln(c0 / (1 + c0))` of the `theta_d` axis, in f32.
const HD_INV_1C0: f32 = (1.0 / (1.0 + HALF_DIFF_COS_OFFSET)) as f32;
const HD_C0: f32 = HALF_DIFF_COS_OFFSET as f32;
/// `1 / ln(c0 / (1 + c0))` for `c0 = 0.01` (checked against f64 by a unit test).
const HD_INV_LN: f32 = -0.216_679_07;

/// `x` clamped to `[lo, hi]`, or `nan` when `x` is NaN.
#[inline]
fn clamp_or(x: f32, lo: f32, hi: f32, nan: f32) -> f32 {
    if x.is_nan() {
        nan
    } else {
        x.clamp(lo, hi)
    }
}

/// [`GridKind::HalfDiff`] coordinates `(u1, u2, u3)` of the pair `(wi, wo)` given `wi` and the
/// unnormalized half vector `h = wi + wo` (directions of unit length, above the horizon).
/// `cos theta_d = |h| / 2`; `1 - cos theta_h = (hx^2 + hy^2) / (|h| (|h| + hz))` (stable at the
/// pole); `sin^2 phi_d = a^2 / (a^2 + b^2)` with `a = |h| (wi x h)_z` and
/// `b = hz (wi_xy . h_xy) - wi_z (hx^2 + hy^2)`, the components of `wi` along the `phi` and
/// `theta` directions of the half vector's frame, times `|h| |h_xy|`. At the pole (`h_xy = 0`)
/// `u3 = 0`; the tables do not depend on `phi_d` there.
#[inline]
fn half_diff_coords(wi: [f32; 3], h: [f32; 3]) -> [f32; 3] {
    let r2 = h[0] * h[0] + h[1] * h[1];
    let l = (r2 + h[2] * h[2]).sqrt();
    let den = l * (l + h[2]);
    // h = 0 only for opposite pairs on the horizon; along cos_phi = -1 the half vector tends
    // to the normal there (|h_xy| is quadratic, h_z linear in the elevations)
    let omc = if den > 0.0 { (r2 / den).min(1.0) } else { 0.0 };
    let u1 = omc.sqrt().sqrt();
    let cd = (0.5 * l).min(1.0);
    let u2 = ((cd + HD_C0) * HD_INV_1C0).ln() * HD_INV_LN;
    let a = l * (wi[1] * h[0] - wi[0] * h[1]);
    let b = h[2] * (wi[0] * h[0] + wi[1] * h[1]) - wi[2] * r2;
    let a2 = a * a;
    let d = a2 + b * b;
    let u3 = if d > 0.0 { (a2 / d).min(1.0) } else { 0.0 };
    [u1, u2, u3]
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
        match self.grid_kind {
            GridKind::Angles => self.weights_angles(cos_theta_i, cos_theta_o, cos_phi),
            GridKind::HalfDiff => {
                let ci = clamp_or(cos_theta_i, 0.0, 1.0, 0.0);
                let co = clamp_or(cos_theta_o, 0.0, 1.0, 0.0);
                let cp = clamp_or(cos_phi, -1.0, 1.0, 1.0);
                let si = (1.0 - ci * ci).max(0.0).sqrt();
                let so = (1.0 - co * co).max(0.0).sqrt();
                let sp = (1.0 - cp * cp).max(0.0).sqrt();
                let wi = [si, 0.0, ci];
                let h = [si + so * cp, so * sp, ci + co];
                self.grid_weights(half_diff_coords(wi, h))
            }
        }
    }

    /// [`BrdfBasis::weights`] for local-frame unit vectors (normal = +Z, both pointing away
    /// from the surface, both above the horizon).
    #[inline]
    pub fn weights_local(&self, wi: [f32; 3], wo: [f32; 3]) -> GridWeights {
        match self.grid_kind {
            GridKind::Angles => {
                let (cp, _) = cos_phi_local(wi, wo);
                self.weights_angles(wi[2], wo[2], cp)
            }
            GridKind::HalfDiff => {
                let h = [
                    wi[0] + wo[0],
                    wi[1] + wo[1],
                    wi[2].max(0.0) + wo[2].max(0.0),
                ];
                self.grid_weights(half_diff_coords(wi, h))
            }
        }
    }

    /// Weights from grid coordinates `u` in `[0, 1]` (nodes uniform in them).
    #[inline]
    fn grid_weights(&self, u: [f32; 3]) -> GridWeights {
        let g = &self.grid;
        let (i0, fi) = axis(u[0] * (g.n_theta_i - 1) as f32, g.n_theta_i);
        let (o0, fo) = axis(u[1] * (g.n_theta_o - 1) as f32, g.n_theta_o);
        let (k0, fp) = axis(u[2] * (g.n_phi - 1) as f32, g.n_phi);
        GridWeights {
            base: g.index(i0, o0, k0),
            stride_i: g.n_theta_o * g.n_phi,
            stride_o: g.n_phi,
            fi,
            fo,
            fp,
        }
    }

    #[inline]
    fn weights_angles(&self, cos_theta_i: f32, cos_theta_o: f32, cos_phi: f32) -> GridWeights {
        let ti = fast_acos(cos_theta_i.max(0.0));
        let to = fast_acos(cos_theta_o.max(0.0));
        let ph = fast_acos(cos_phi);
        self.grid_weights([ti / FRAC_PI_2, to / FRAC_PI_2, ph / PI])
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
        if wi[2] <= 0.0 || wo[2] <= 0.0 || wi[2].is_nan() || wo[2].is_nan() {
            out[..self.num_bases].fill(0.0);
            return;
        }
        let w = self.weights_local(wi, wo);
        self.eval_weights(&w, out);
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
            grid_kind: GridKind::Angles,
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
        let h = half_diff_tiny();
        let s = serde_json::to_string(&h).unwrap();
        assert!(s.contains("\"grid_kind\":\"half-diff\""), "{s}");
        let c: BrdfBasis = serde_json::from_str(&s).unwrap();
        assert_eq!(h, c);
        // a file without `grid_kind` means the schema-1 grid; schema 1 itself is refused
        let mut v: serde_json::Value = serde_json::to_value(&h).unwrap();
        v.as_object_mut().unwrap().remove("grid_kind");
        let c: BrdfBasis = serde_json::from_value(v.clone()).unwrap();
        assert_eq!(c.grid_kind, GridKind::Angles);
        v["version"] = 1.into();
        let c: BrdfBasis = serde_json::from_value(v).unwrap();
        assert!(matches!(
            c.validate(),
            Err(BasisError::Version { found: 1, .. })
        ));
    }

    /// A half-diff basis whose second table is linear in the grid coordinates, so trilinear
    /// interpolation reproduces it exactly: `u1 + 2 u2 - 3 u3`.
    fn half_diff_tiny() -> BrdfBasis {
        let grid = AngularGrid {
            n_theta_i: 7,
            n_theta_o: 5,
            n_phi: 4,
        };
        let nb = 2;
        let mut tables = vec![0.0; grid.len() * nb];
        for i in 0..grid.n_theta_i {
            for o in 0..grid.n_theta_o {
                for k in 0..grid.n_phi {
                    let n = grid.index(i, o, k);
                    let u = |j: usize, m: usize| j as f32 / (m - 1) as f32;
                    tables[n * nb] = 1.0 / PI;
                    tables[n * nb + 1] =
                        u(i, grid.n_theta_i) + 2.0 * u(o, grid.n_theta_o) - 3.0 * u(k, grid.n_phi);
                }
            }
        }
        BrdfBasis {
            grid,
            grid_kind: GridKind::HalfDiff,
            tables,
            ..tiny()
        }
    }

    /// The half/difference coordinates of a pair, in f64, from first principles.
    fn half_diff_u_f64(wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let l = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
        let h = [h[0] / l, h[1] / l, h[2] / l];
        let cos_d = wi[0] * h[0] + wi[1] * h[1] + wi[2] * h[2];
        // frame of h: t1 along increasing theta_h, t2 along increasing phi_h
        let r = (h[0] * h[0] + h[1] * h[1]).sqrt();
        let (t1, t2) = if r > 1e-12 {
            (
                [h[2] * h[0] / r, h[2] * h[1] / r, -r],
                [-h[1] / r, h[0] / r, 0.0],
            )
        } else {
            ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        };
        let x = wi[0] * t1[0] + wi[1] * t1[1] + wi[2] * t1[2];
        let y = wi[0] * t2[0] + wi[1] * t2[1] + wi[2] * t2[2];
        let c0 = HALF_DIFF_COS_OFFSET;
        [
            (1.0 - h[2]).max(0.0).powf(0.25),
            ((cos_d + c0) / (1.0 + c0)).ln() / (c0 / (1.0 + c0)).ln(),
            if x * x + y * y > 0.0 {
                y * y / (x * x + y * y)
            } else {
                0.0
            },
        ]
    }

    #[test]
    fn half_diff_constant_matches_f64() {
        let c0 = HALF_DIFF_COS_OFFSET;
        let want = 1.0 / (c0 / (1.0 + c0)).ln();
        assert!((HD_INV_LN as f64 - want).abs() < 1e-7);
    }

    #[test]
    fn half_diff_coordinates_are_exact_on_linear_tables() {
        let b = half_diff_tiny();
        b.validate().unwrap();
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut out = [0.0f32; 2];
        let mut out_local = [0.0f32; 2];
        let mut worst = 0.0f64;
        for _ in 0..2000 {
            let (ti, to, ph) = (
                next() * FRAC_PI_2 as f64 * 0.999,
                next() * FRAC_PI_2 as f64 * 0.999,
                next() * PI as f64,
            );
            let wi = [ti.sin(), 0.0, ti.cos()];
            let wo = [to.sin() * ph.cos(), to.sin() * ph.sin(), to.cos()];
            let u = half_diff_u_f64(wi, wo);
            let want = u[0] + 2.0 * u[1] - 3.0 * u[2];
            b.eval_all(ti.cos() as f32, to.cos() as f32, ph.cos() as f32, &mut out);
            worst = worst.max((out[1] as f64 - want).abs());
            assert!((out[0] - 1.0 / PI).abs() < 1e-6);
            // same pair rotated about the normal, through the vector entry point
            let rot = next() * 6.0;
            let r = |v: [f64; 3]| {
                [
                    (v[0] * rot.cos() - v[1] * rot.sin()) as f32,
                    (v[0] * rot.sin() + v[1] * rot.cos()) as f32,
                    v[2] as f32,
                ]
            };
            b.eval_all_local(r(wi), r(wo), &mut out_local);
            worst = worst.max((out_local[1] as f64 - want).abs());
        }
        // f32 evaluation of the coordinates: u1 = (1 - cos)^(1/4) amplifies rounding near the
        // pole (u1 ~ 1e-2 needs 1 - cos ~ 1e-8)
        assert!(worst < 2e-3, "{worst}");
    }

    #[test]
    fn half_diff_nodes_round_trip() {
        let b = half_diff_tiny();
        let g = b.grid;
        let mut out = [0.0f32; 2];
        for i in 0..g.n_theta_i {
            for o in 0..g.n_theta_o {
                for k in 0..g.n_phi {
                    let n = g.node(GridKind::HalfDiff, i, o, k);
                    // phi_d is undefined at theta_h = 0 and theta_d = 0 (i, o = 0), where real
                    // tables do not depend on it
                    if i == 0 || o == 0 || n.cos_theta_i < 1e-3 || n.cos_theta_o < 1e-3 {
                        continue;
                    }
                    b.eval_all(
                        n.cos_theta_i as f32,
                        n.cos_theta_o as f32,
                        n.cos_phi as f32,
                        &mut out,
                    );
                    let t = b.tables[g.index(i, o, k) * 2 + 1];
                    assert!(
                        (out[1] - t).abs() < 2e-3,
                        "node ({i},{o},{k}): {} vs {t}",
                        out[1]
                    );
                }
            }
        }
        // the pair's own geometry: h at theta_h, wi at theta_d from it
        let p = half_diff_pair(0.8, 0.6, 0.3);
        let wi_z = p.cos_theta_i;
        let wo_z = p.cos_theta_o;
        assert!(wi_z < wo_z, "phi_d in [0, pi/2] puts wi on the low side");
        assert!(((wi_z + wo_z) - 2.0 * 0.6 * 0.8).abs() < 1e-12);
    }

    #[test]
    fn half_diff_evaluation_is_finite_everywhere() {
        let b = half_diff_tiny();
        let mut out = [0.0f32; 2];
        let vals = [
            -2.0f32,
            -1.0,
            -0.5,
            0.0,
            1e-30,
            1e-7,
            0.3,
            0.999_999,
            1.0,
            1.5,
            f32::NAN,
        ];
        for &ci in &vals {
            for &co in &vals {
                for &cp in &vals {
                    b.eval_all(ci, co, cp, &mut out);
                    assert!(out.iter().all(|v| v.is_finite()), "{ci} {co} {cp}: {out:?}");
                }
            }
        }
        // wi along the normal, grazing pairs, opposite grazing directions
        for (wi, wo) in [
            ([0.0f32, 0.0, 1.0], [0.0f32, 0.0, 1.0]),
            ([1.0, 0.0, 1e-9], [-1.0, 0.0, 1e-9]),
            ([1.0, 0.0, 1e-9], [1.0, 0.0, 1e-9]),
            ([0.6, 0.0, 0.8], [0.6, 0.0, 0.8]),
        ] {
            b.eval_all_local(wi, wo, &mut out);
            assert!(out.iter().all(|v| v.is_finite()), "{wi:?} {wo:?}: {out:?}");
        }
    }
}
