//! The persisted Tucker shading basis of one family (thesis 5.2.2, 5.3.1; docs/brdf-basis.md,
//! "Shading basis"): what the per-vertex runtime needs to evaluate the last reflection for any
//! view and any lobe parameter.
//!
//! Everything is in **raw BRDF units**: the family's specular lobe with `Ks = 1` and no `Kd`
//! (`f(p, wo, wi)`, 1/sr), split into
//!
//! ```text
//! f(p, wo, wi) ~ f_r(p, wo, wi) + sum_w f_w(p, wo, wi)
//! f_r(p, wo, wi) = sum_abc D(a, b, c) U^h(p, a) U^o(wo, b) U^i(wi, c)      (the residual)
//! ```
//!
//! where `f_w` are the Gaussian lobes of the specular split about the mirror direction
//! `r = (-wo.x, -wo.y, wo.z)` (width 0: the mirror itself). The Gaussians are not stored as
//! lobes but as **reflectances** `R_w(p, wo) = integral f_w(p, wo, wi) cos(theta_i) dwi`: the
//! fraction of light from the mirror direction's neighbourhood that Gaussian `w` reflects
//! towards `wo`. Under an incident radiance `I`, the lobe reflects
//!
//! ```text
//! B(wo) = integral I f cos(theta_i) dwi
//!       ~ sum_abc D(a, b, c) U^h(p, a) U^o(wo, b) U_I(c)  +  sum_w R_w(p, wo) Ibar_w(r)
//! U_I(c) = integral I(wi) U^i(wi, c) cos(theta_i) dwi
//! Ibar_w(r) = integral G_w(angle(w, r)) I(w) dw / integral G_w dw
//! ```
//!
//! `Ibar_w` is `I` prefiltered by the *normalized* Gaussian of width `w` (width 0: `I(r)`; with
//! `prt_formats::lighting::prefilter`, its prefiltered map divided by `kernel_integral`). The
//! approximation is `integral G_w I cos / integral G_w cos ~ integral G_w I / integral G_w`:
//! the cosine is taken as constant over the lobe (exact for a constant `I`, and within the
//! cosine's variation across a 21-degree lobe otherwise).
//!
//! Tables: `U^h` over the parameter samples (interpolated linearly in the warped parameter,
//! clamped outside the range and reported, as [`super::BrdfBasis`]), `U^o`, `U^i` and the
//! reflectances over the nodes of a [`HemiGrid`] plus a row each for the pole (interpolated
//! bilinearly, [`HemiWeights`]), all f32, the last index fastest.

use serde::{Deserialize, Serialize};

use super::{BasisError, HemiGrid, HemiWeights, ParamWarp, ParamWeights};
use crate::family::Family;

/// Version of the [`ShadingBasis`] schema. Bump when the meaning or layout of a field changes.
pub const SHADING_SCHEMA_VERSION: u32 = 1;

/// Largest Tucker rank of any mode (evaluation keeps rows of this length on the stack).
pub const MAX_SHADING_RANK: usize = 32;

/// Most Gaussian widths of the specular split.
pub const MAX_SPLIT_WIDTHS: usize = 8;

/// Most parameter samples.
pub const MAX_SHADING_PARAMS: usize = 4096;

/// Tucker ranks `(r_h, r_o, r_i)` of the parameter, outgoing and incident modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct TuckerRanks {
    /// Rank of the parameter mode (`U^h` columns).
    pub h: usize,
    /// Rank of the outgoing-direction mode (`U^o` columns).
    pub o: usize,
    /// Rank of the incident-direction mode (`U^i` columns).
    pub i: usize,
}

impl TuckerRanks {
    /// The thesis' ranks for GGX (and any family with a lobe but Blinn-Phong): 4 x 8 x 8.
    pub const THESIS: TuckerRanks = TuckerRanks { h: 4, o: 8, i: 8 };

    /// The thesis' ranks for Blinn-Phong: 3 x 8 x 8.
    pub const THESIS_BLINN_PHONG: TuckerRanks = TuckerRanks { h: 3, o: 8, i: 8 };

    /// The thesis' ranks of a family (`None` for diffuse, which has no lobe).
    pub fn thesis(family: Family) -> Option<TuckerRanks> {
        match family {
            Family::Diffuse => None,
            Family::BlinnPhong => Some(TuckerRanks::THESIS_BLINN_PHONG),
            Family::Ggx => Some(TuckerRanks::THESIS),
        }
    }
}

/// A family's Tucker shading basis, as carried by a per-vertex bake file (see the module docs
/// for the meaning of every table).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShadingBasis {
    /// [`SHADING_SCHEMA_VERSION`].
    pub version: u32,
    /// The family (stored by name); it must have a lobe.
    pub family: Family,
    /// How the basis was built (free text, for provenance).
    pub method: String,
    /// Sampled parameter range `[min, max]`, equal to the first and last sample.
    pub param_range: [f32; 2],
    /// Warp in which `u_h` and `reflectances` are interpolated over the parameter.
    pub param_warp: ParamWarp,
    /// Parameter samples, strictly increasing.
    pub param_samples: Vec<f32>,
    /// The direction grid of `u_o`, `u_i` and `reflectances`.
    pub dirs: HemiGrid,
    /// Tucker ranks.
    pub ranks: TuckerRanks,
    /// `U^h`, `[n_params][r_h]` (1/sr: the lobe's magnitude lives here).
    pub u_h: Vec<f32>,
    /// `U^o`, `[n_dirs][r_o]`.
    pub u_o: Vec<f32>,
    /// `U^o` at the pole (`wo` along the normal), `[r_o]`: the pole row of the polar cap's
    /// interpolation ([`HemiWeights`]).
    pub u_o_pole: Vec<f32>,
    /// `U^i`, `[n_dirs][r_i]`.
    pub u_i: Vec<f32>,
    /// `U^i` at the pole, `[r_i]`.
    pub u_i_pole: Vec<f32>,
    /// The core `D`, `[r_h][r_o][r_i]`.
    pub core: Vec<f32>,
    /// Widths of the split's Gaussians in degrees, strictly increasing; 0 is the mirror spike.
    pub split_widths_deg: Vec<f32>,
    /// Reflectances `R_w(p, wo)`, `[n_params][n_dirs][n_widths]`, nonnegative.
    pub reflectances: Vec<f32>,
    /// Reflectances at the pole, `[n_params][n_widths]`, nonnegative.
    pub reflectances_pole: Vec<f32>,
}

/// The mirror direction `r = (-wo.x, -wo.y, wo.z)` of `wo` about the normal (local frame).
#[inline]
pub fn mirror(wo: [f32; 3]) -> [f32; 3] {
    [-wo[0], -wo[1], wo[2]]
}

/// The first index of `v` at which `bad` holds, as a [`BasisError::NonFinite`]-style error.
fn check_all(
    v: &[f32],
    field: &'static str,
    bad: impl Fn(f32) -> bool,
    err: fn(&'static str, usize) -> BasisError,
) -> Result<(), BasisError> {
    match v.iter().position(|&x| bad(x)) {
        Some(index) => Err(err(field, index)),
        None => Ok(()),
    }
}

fn non_finite(field: &'static str, index: usize) -> BasisError {
    BasisError::NonFinite { field, index }
}

fn shape(field: &'static str, found: usize, want: Option<usize>) -> Result<(), BasisError> {
    if want == Some(found) {
        return Ok(());
    }
    Err(BasisError::Shape {
        field,
        found,
        expected: want.unwrap_or(usize::MAX),
    })
}

impl ShadingBasis {
    /// Number of parameter samples.
    pub fn n_params(&self) -> usize {
        self.param_samples.len()
    }

    /// Number of grid directions.
    pub fn n_dirs(&self) -> usize {
        self.dirs.len()
    }

    /// Number of split widths.
    pub fn n_widths(&self) -> usize {
        self.split_widths_deg.len()
    }

    /// The Gaussian width (degrees) a renderer gives split width `k`: the stored width, but
    /// for width 0 [`ShadingBasis::spike_width_deg`].
    pub fn rendered_width_deg(&self, k: usize) -> Option<f32> {
        let w = *self.split_widths_deg.get(k)?;
        Some(if w == 0.0 { self.spike_width_deg() } else { w })
    }

    /// The Gaussian width (degrees) that renders the split's width-0 term. That term was
    /// fitted as a unit value on the one cell of `dirs` nearest to the mirror direction, so
    /// its light is the environment averaged over a cell (solid angle `2 pi / (n_theta
    /// n_phi)`, the grid being equal-area), not the environment at the mirror direction: read
    /// there, a light smaller than a cell (a sun) showed as its own sharp image, up to twice
    /// as bright as the reference's highlight on a GGX 0.1 sphere. A Gaussian with a square
    /// cell's variance per axis, `sigma = sqrt(omega / 12)` radians (1.3 degrees on the 16 x
    /// 64 grid), stands for the cell.
    pub fn spike_width_deg(&self) -> f32 {
        let omega = std::f64::consts::TAU / self.dirs.len().max(1) as f64;
        (omega / 12.0).sqrt().to_degrees() as f32
    }

    /// Checks the version, the family, the parameter samples and warp, the grid, the ranks,
    /// the split widths, every table's length, finiteness, and that reflectances are
    /// nonnegative. Evaluation may index out of bounds on a basis that fails this.
    pub fn validate(&self) -> Result<(), BasisError> {
        if self.version != SHADING_SCHEMA_VERSION {
            return Err(BasisError::ShadingVersion {
                found: self.version,
                expected: SHADING_SCHEMA_VERSION,
            });
        }
        if self.family.lobe_param().is_none() {
            return Err(BasisError::NoLobe {
                family: self.family.name(),
            });
        }
        self.validate_params()?;
        self.dirs.validate()?;
        let (np, nd) = (self.n_params(), self.n_dirs());
        let r = self.ranks;
        for (mode, rank, size) in [("h", r.h, np), ("o", r.o, nd), ("i", r.i, nd)] {
            let max = size.min(MAX_SHADING_RANK);
            if rank == 0 || rank > max {
                return Err(BasisError::Rank { mode, rank, max });
            }
        }
        self.validate_widths()?;
        let nw = self.n_widths();
        shape("u_h", self.u_h.len(), np.checked_mul(r.h))?;
        shape("u_o", self.u_o.len(), nd.checked_mul(r.o))?;
        shape("u_i", self.u_i.len(), nd.checked_mul(r.i))?;
        shape("core", self.core.len(), Some(r.h * r.o * r.i))?;
        shape("u_o_pole", self.u_o_pole.len(), Some(r.o))?;
        shape("u_i_pole", self.u_i_pole.len(), Some(r.i))?;
        let nr = np.checked_mul(nd).and_then(|x| x.checked_mul(nw));
        shape("reflectances", self.reflectances.len(), nr)?;
        shape(
            "reflectances_pole",
            self.reflectances_pole.len(),
            np.checked_mul(nw),
        )?;
        for (field, v) in [
            ("u_h", &self.u_h),
            ("u_o", &self.u_o),
            ("u_o_pole", &self.u_o_pole),
            ("u_i", &self.u_i),
            ("u_i_pole", &self.u_i_pole),
            ("core", &self.core),
            ("reflectances", &self.reflectances),
            ("reflectances_pole", &self.reflectances_pole),
        ] {
            check_all(v, field, |x| !x.is_finite(), non_finite)?;
        }
        let negative = |field, index| BasisError::Negative { field, index };
        check_all(&self.reflectances, "reflectances", |x| x < 0.0, negative)?;
        check_all(
            &self.reflectances_pole,
            "reflectances_pole",
            |x| x < 0.0,
            negative,
        )
    }

    fn validate_params(&self) -> Result<(), BasisError> {
        let ps = &self.param_samples;
        let field = "param_samples";
        if ps.is_empty() {
            return Err(BasisError::Empty { field });
        }
        if ps.len() > MAX_SHADING_PARAMS {
            return Err(BasisError::TooMany {
                field,
                found: ps.len(),
                max: MAX_SHADING_PARAMS,
            });
        }
        check_all(ps, field, |x| !x.is_finite(), non_finite)?;
        if let Some(i) = ps.windows(2).position(|w| w[0] >= w[1]) {
            return Err(BasisError::NotIncreasing {
                field,
                index: i + 1,
            });
        }
        let (first, last) = (ps[0], ps[ps.len() - 1]);
        if self.param_range != [first, last] {
            return Err(BasisError::ParamRange {
                range: self.param_range,
                first,
                last,
            });
        }
        if let ParamWarp::Log { offset } = self.param_warp {
            if first + offset <= 0.0 || offset.is_nan() {
                return Err(BasisError::LogWarp { offset, first });
            }
        }
        Ok(())
    }

    fn validate_widths(&self) -> Result<(), BasisError> {
        let w = &self.split_widths_deg;
        let field = "split_widths_deg";
        if w.is_empty() {
            return Err(BasisError::Empty { field });
        }
        if w.len() > MAX_SPLIT_WIDTHS {
            return Err(BasisError::TooMany {
                field,
                found: w.len(),
                max: MAX_SPLIT_WIDTHS,
            });
        }
        for (index, &value) in w.iter().enumerate() {
            let after_previous = index == 0 || value > w[index - 1];
            if !((0.0..90.0).contains(&value) && after_previous) {
                return Err(BasisError::SplitWidth { index, value });
            }
        }
        Ok(())
    }

    /// Interpolation weights of parameter `p` (linear in the warped parameter); the flag is
    /// true when `p` was outside the sampled range (or NaN) and was clamped to it.
    #[inline]
    pub fn param_weights(&self, p: f32) -> (ParamWeights, bool) {
        self.param_warp.weights(&self.param_samples, p)
    }

    /// Interpolation weights of a local direction over the grid ([`HemiGrid::weights`]).
    #[inline]
    pub fn dir_weights(&self, w: [f32; 3]) -> HemiWeights {
        self.dirs.weights(w)
    }

    /// `U^h(p)` into `out[..r_h]`; returns whether `p` was clamped.
    #[inline]
    pub fn u_h_row(&self, p: f32, out: &mut [f32]) -> bool {
        let (w, clamped) = self.param_weights(p);
        let r = self.ranks.h;
        let (a, b) = (&self.u_h[w.j0 * r..][..r], &self.u_h[w.j1 * r..][..r]);
        for ((o, x), y) in out[..r].iter_mut().zip(a).zip(b) {
            *o = x + w.t * (y - x);
        }
        clamped
    }

    /// `U^o(wo)` into `out[..r_o]` (bilinear over the grid; `wo` in the local frame).
    #[inline]
    pub fn u_o_row(&self, wo: [f32; 3], out: &mut [f32]) {
        self.dirs
            .weights(wo)
            .interpolate(&self.u_o, &self.u_o_pole, self.ranks.o, out);
    }

    /// `U^i(wi)` into `out[..r_i]` (bilinear over the grid; `wi` in the local frame).
    #[inline]
    pub fn u_i_row(&self, wi: [f32; 3], out: &mut [f32]) {
        self.dirs
            .weights(wi)
            .interpolate(&self.u_i, &self.u_i_pole, self.ranks.i, out);
    }

    /// The core contracted with a `U^h` row: `out[b r_i + c] = sum_a D(a, b, c) u_h[a]`, an
    /// `r_o x r_i` matrix (row-major), computed once per material.
    pub fn contract_core(&self, u_h: &[f32], out: &mut [f32]) {
        let r = self.ranks;
        let m = r.o * r.i;
        let out = &mut out[..m];
        out.fill(0.0);
        for (a, &ua) in u_h[..r.h].iter().enumerate() {
            for (o, d) in out.iter_mut().zip(&self.core[a * m..(a + 1) * m]) {
                *o += ua * d;
            }
        }
    }

    /// The residual lobe `f_r(p, wo, wi)` (1/sr; 0 when either direction is at or below the
    /// horizon); the flag says whether `p` was clamped. Allocation-free; for many evaluations
    /// at one `p`, [`ShadingBasis::contract_core`] once and the rows are cheaper.
    pub fn residual(&self, p: f32, wo: [f32; 3], wi: [f32; 3]) -> (f32, bool) {
        let mut uh = [0.0f32; MAX_SHADING_RANK];
        let clamped = self.u_h_row(p, &mut uh);
        if !(wo[2] > 0.0 && wi[2] > 0.0) {
            return (0.0, clamped);
        }
        let mut uo = [0.0f32; MAX_SHADING_RANK];
        let mut ui = [0.0f32; MAX_SHADING_RANK];
        self.u_o_row(wo, &mut uo);
        self.u_i_row(wi, &mut ui);
        (self.contract(&uh, &uo, &ui), clamped)
    }

    /// `sum_abc D(a, b, c) uh[a] uo[b] ui[c]`.
    fn contract(&self, uh: &[f32], uo: &[f32], ui: &[f32]) -> f32 {
        let r = self.ranks;
        let mut sum = 0.0;
        for (a, &ua) in uh[..r.h].iter().enumerate() {
            for (b, &ub) in uo[..r.o].iter().enumerate() {
                let row = &self.core[(a * r.o + b) * r.i..][..r.i];
                let s: f32 = row.iter().zip(&ui[..r.i]).map(|(d, c)| d * c).sum();
                sum += ua * ub * s;
            }
        }
        sum
    }

    /// Reflectances `R_w(p, wo)` into `out[..n_widths]` (linear in the warped parameter,
    /// bilinear over the grid); returns whether `p` was clamped.
    pub fn reflectances_into(&self, p: f32, wo: [f32; 3], out: &mut [f32]) -> bool {
        let (pw, clamped) = self.param_weights(p);
        let nw = self.n_widths();
        let slab = self.n_dirs() * nw;
        let dw = self.dirs.weights(wo);
        out[..nw].fill(0.0);
        for (j, s) in [(pw.j0, 1.0 - pw.t), (pw.j1, pw.t)] {
            if s > 0.0 {
                let table = &self.reflectances[j * slab..][..slab];
                dw.add_rows(table, &self.reflectances_pole[j * nw..][..nw], nw, s, out);
            }
        }
        clamped
    }

    /// Radiance the lobe reflects towards `wo` (the module docs' `B`), given the incident
    /// light's projections `incident[c] = integral I U^i(., c) cos dwi` (`r_i` values) and its
    /// normalized Gaussian prefilters at the mirror direction `prefiltered[w] = Ibar_w(r)`
    /// (`n_widths` values). Returns `(B, clamped)`; `B` is 0 for `wo` at or below the horizon.
    pub fn reflected(
        &self,
        p: f32,
        wo: [f32; 3],
        incident: &[f32],
        prefiltered: &[f32],
    ) -> (f32, bool) {
        let mut uh = [0.0f32; MAX_SHADING_RANK];
        let mut rw = [0.0f32; MAX_SPLIT_WIDTHS];
        let clamped = self.reflectances_into(p, wo, &mut rw);
        if wo[2].is_nan() || wo[2] <= 0.0 {
            return (0.0, clamped);
        }
        self.u_h_row(p, &mut uh);
        let mut uo = [0.0f32; MAX_SHADING_RANK];
        self.u_o_row(wo, &mut uo);
        let nw = self.n_widths();
        let spec: f32 = rw[..nw]
            .iter()
            .zip(&prefiltered[..nw])
            .map(|(r, i)| r * i)
            .sum();
        (self.contract(&uh, &uo, incident) + spec, clamped)
    }
}
