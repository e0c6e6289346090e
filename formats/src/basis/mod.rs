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
//!
//! # Files of this module
//! * `grid.rs`: the node grid and its angular coordinates ([`GridKind`], [`AngularGrid`],
//!   [`GridSpec`], [`GridNode`]; the baker-side direction pair of every node).
//! * `brdf_basis.rs`: the persisted [`BrdfBasis`], its validation and its lobe coefficients.
//! * `warp.rs`: [`ParamWarp`], the warp in which coefficients are interpolated.
//! * `eval.rs`: evaluation of the tables (coordinates of a direction pair, [`GridWeights`],
//!   trilinear interpolation; shared by the baker and the runtime).
//! * `error.rs`: [`BasisError`].
//! * `hemigrid.rs`: [`HemiGrid`], the equal-area hemisphere grid of the shading basis, and
//!   [`HemiWeights`], bilinear interpolation over it (wrapping in `phi`, blended towards a
//!   stored pole row in the polar cap, clamped at the horizon).
//! * `shading.rs`: the persisted Tucker shading basis [`ShadingBasis`] of the per-vertex mode
//!   (residual lobe as a Tucker decomposition, specular split as reflectances), its validation
//!   and evaluation.
//! * `split_lookup.rs`: where a split Gaussian's prefiltered light is read
//!   ([`cosine_centroid`]: the mirror direction raised by the cosine-weighted centroid's
//!   tilt).

mod brdf_basis;
mod error;
mod eval;
mod grid;
mod hemigrid;
mod shading;
mod split_lookup;
mod warp;

pub use brdf_basis::BrdfBasis;
pub use error::BasisError;
pub use eval::{cos_phi_local, fast_acos, GridWeights};
pub use grid::{half_diff_node, half_diff_pair, AngularGrid, GridKind, GridNode, GridSpec};
pub use hemigrid::{HemiGrid, HemiWeights, MAX_HEMI_DIRS};
pub use shading::{
    mirror, ShadingBasis, TuckerRanks, MAX_SHADING_PARAMS, MAX_SHADING_RANK, MAX_SPLIT_WIDTHS,
    SHADING_SCHEMA_VERSION,
};
pub use split_lookup::{cosine_centroid, cosine_centroid_tilt};
pub use warp::{ParamWarp, ParamWeights};

/// Version of the [`BrdfBasis`] schema. Bump when the meaning or layout of a field changes.
/// Version 2 added [`BrdfBasis::grid_kind`] (the half/difference grid); version 1 files are
/// refused.
pub const BASIS_SCHEMA_VERSION: u32 = 2;

/// `c0` of the [`GridKind::HalfDiff`] `theta_d` axis: nodes are uniform in `ln(cos theta_d + c0)`
/// near the grazing end, so cells shrink to about `c0` in `cos theta_d`, which resolves the GGX
/// grazing limit `G1(c)/c -> 2/alpha` (reached within `c ~ alpha`) down to alpha ~ 2 c0.
pub const HALF_DIFF_COS_OFFSET: f64 = 0.01;

#[cfg(test)]
mod tests;
