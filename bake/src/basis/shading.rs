//! Building the persisted Tucker shading basis ([`prt_formats::basis::ShadingBasis`], thesis
//! 5.2.2 and 5.3.1; docs/brdf-basis.md, "Shading basis"): the family's lobe as a 3-tensor over
//! parameter samples and an equal-area hemisphere grid, the specular split, HOSVD + HOOI as in
//! [`super::tucker::tucker_report`], then the factors unscaled to raw BRDF units and the split
//! amplitudes turned into reflectances.
//!
//! One difference from the report's tensor: the incident axis holds **cosine-weighted cell
//! averages** of the lobe, `F(p, wo, i) = integral_cell_i f(p, wo, w) cos(theta) dw / (z_i dw)`,
//! not point values (the outgoing axis keeps point values: it is where the lobe is evaluated).
//! A point sample cannot see a lobe narrower than a cell: on the 16 x 64 grid GGX at
//! alpha = 0.05 has about one node across its peak, and the grid's quadrature of point values
//! misses the directional albedo by -70 % at normal incidence and at 80 degrees. With cell
//! averages the grid's quadrature `sum_i F z_i dw` is the lobe's albedo (to the sub-sampling's
//! accuracy), so the energy the split and the residual share is the lobe's. Cells near the
//! mirror direction are sub-sampled finely (adaptively, see [`cell_average_row`]); far cells
//! keep one sample at their node, which is the point value. The split's Gaussians are cell
//! averages too ([`cell_average_profile`]), so the fit compares like with like; the spike is
//! the report's, a unit on the mirror node.
//!
//! Two additions the report does not need: **pole rows** (the normal has no node; see
//! `super::pole`) and an **energy correction** of the reflectances
//! ([`ShadingParts::conserve_energy`]): the truncated Tucker residual cannot follow the fine
//! ring of negative values that the Gaussians leave about a sharp lobe's mirror direction, and
//! loses or gains its energy (GGX alpha = 0.02 at normal incidence: +13 % of the albedo);
//! the reflectances give it back, so the reconstructed albedo at every node is the lobe's.
//!
//! The lobes are isotropic and the grid turns onto itself by one column, so the tensor is
//! equivariant under those rotations: it is sampled, split and decomposed by its **ring rows**
//! (the fibres of the first node of every ring; [`RingTensor`], [`hosvd_rings`],
//! [`tucker_rings`]), `n_phi` times less work than the full tensor, which is never stored.
//! Every parallel step places its results by index and sums in a fixed order, so the basis is
//! the same bit for bit on any number of threads.

use super::cells::{cell_average_profile, cell_average_row};
use super::error::BasisError;
use super::pole::{core_i, core_o, fit_row, PoleParts};
use super::split::{specular_split_rings, RingSplit, SPLIT_WIDTHS_DEG};
use super::tensor::{ring_offset, RingTensor};
use super::tucker::{hosvd_rings, tucker_rings};
use super::FamilySpec;
use crate::brdf::Family;
use prt_formats::basis::{
    BasisError as FormatError, HemiGrid, ShadingBasis, TuckerRanks, MAX_SHADING_PARAMS,
    MAX_SHADING_RANK, SHADING_SCHEMA_VERSION,
};
use rayon::prelude::*;
use std::f64::consts::TAU;

/// Default direction grid of the shading basis: 16 rings x 64 azimuths (1024 directions,
/// cells of about 4.5 degrees at mid latitudes; see docs/brdf-basis.md for the choice).
pub const SHADING_DIRS: HemiGrid = HemiGrid {
    n_theta: 16,
    n_phi: 64,
};

/// Default number of parameter samples (uniform in the warped parameter): 32, a step of 13 %
/// in alpha for GGX over [0.02, 1] and of 17 % in s + 1 for Blinn-Phong over [1, 200].
pub const SHADING_PARAMS: usize = 32;

/// Largest tensor (`n_params x n_dirs^2` f64 values) the builder accepts: 2^28 values, 2 GiB,
/// held twice (tensor and residual) plus the unfoldings of the decomposition.
pub const MAX_TENSOR_VALUES: usize = 1 << 28;

/// The sampled tensor and its specular split, before the decomposition (kept apart so tests
/// can compare the decomposition with what it decomposes).
pub struct ShadingParts {
    /// The scaled tensor: cell-averaged over the incident axis ([`cell_average_row`]), scaled
    /// by `sqrt(cos(theta) dw)` per direction and normalized per lobe, as the report's; stored
    /// by its ring rows (the lobe is isotropic, see [`RingTensor`]).
    pub tensor: RingTensor,
    /// The specular split of `tensor` (amplitudes `[h][o][k]`, the scaled residual's ring
    /// rows).
    pub split: RingSplit,
    /// `[o][k]`: the grid's `sum_i G_k(i) cos(theta_i) dw` of every split profile (cell
    /// averages: the Gaussian's `integral G cos dw` over the hemisphere; for width 0,
    /// `cos(theta) dw` of the cell the spike sits on); amplitude times this over the lobe's
    /// normalization is the reflectance.
    pub profile_mass: Vec<f64>,
    /// The fibres through the pole (the normal as `wo`, and as `wi`), for the pole rows.
    pub pole: PoleParts,
}

impl ShadingParts {
    /// Samples the tensor of `spec`'s lobe at `n_params` parameters (uniform in the warped
    /// parameter) over `dirs`, and splits it.
    pub fn new(
        spec: FamilySpec,
        n_params: usize,
        dirs: HemiGrid,
    ) -> Result<ShadingParts, BasisError> {
        if spec.family.lobe_param().is_none() {
            return Err(BasisError::DiffuseFamily);
        }
        FamilySpec::with_range(spec, spec.range.0, spec.range.1)?;
        if n_params < 2 {
            return Err(BasisError::TooFewSamples);
        }
        if n_params > MAX_SHADING_PARAMS {
            return Err(FormatError::TooMany {
                field: "param_samples",
                found: n_params,
                max: MAX_SHADING_PARAMS,
            }
            .into());
        }
        dirs.validate()?;
        let nd = dirs.len();
        let values = n_params.saturating_mul(nd * nd);
        if values > MAX_TENSOR_VALUES {
            return Err(FormatError::TooMany {
                field: "tensor (n_params x n_dirs^2)",
                found: values,
                max: MAX_TENSOR_VALUES,
            }
            .into());
        }
        let params = super::grid::param_samples(spec.range, spec.warp, n_params);
        // the lobe is isotropic: only the first node of every ring is sampled and split, the
        // other outgoing directions are its rotations (exactly: the grid turns onto itself)
        let tensor = RingTensor::new(spec, params, dirs, |p, o, row| {
            cell_average_row(spec.family, p, dirs.dir(o), &dirs, row)
        });
        let nk = SPLIT_WIDTHS_DEG.len();
        let s = &tensor.dir_scale;
        // the profiles about the first node of every ring, [j][k][i]
        let mut g = vec![0.0; dirs.n_theta * nk * nd];
        g.par_chunks_mut(nk * nd)
            .enumerate()
            .for_each(|(j, out)| cell_average_profile(&dirs, s, dirs.index(j, 0), out));
        let split = specular_split_rings(&tensor, &g);
        let mut profile_mass = vec![0.0; nd * nk];
        for o in 0..nd {
            let j = o / dirs.n_phi;
            let o0 = dirs.index(j, 0);
            for k in 0..nk {
                let prof = &g[(j * nk + k) * nd..][..nd];
                // profile = G s_i s_o, so G cos_i dw = profile s_i / s_o (node o's profile is
                // the ring's first one turned, with the same sum)
                let m: f64 = prof.iter().zip(s).map(|(x, si)| x * si).sum();
                profile_mass[o * nk + k] = m / s[o0];
            }
        }
        let pole = PoleParts::new(&tensor, &split);
        Ok(ShadingParts {
            tensor,
            split,
            profile_mass,
            pole,
        })
    }

    fn unscale(&self, h: usize, o: usize, i: usize, v: f64) -> f64 {
        let t = &self.tensor;
        let den = t.lobe_scale[h] * t.dir_scale[o] * t.dir_scale[i];
        if den > 0.0 {
            v / den
        } else {
            0.0
        }
    }

    /// The sampled lobe `F(h, o, i)` in raw units (1/sr).
    pub fn raw_lobe(&self, h: usize, o: usize, i: usize) -> f64 {
        self.unscale(h, o, i, self.tensor.at(h, o, i))
    }

    /// The split's residual at `(h, o, i)` in raw units (1/sr).
    pub fn raw_residual(&self, h: usize, o: usize, i: usize) -> f64 {
        let d = self.tensor.dirs;
        let v = self.split.residual[h * d.n_theta * d.len() + ring_offset(d, o, i)];
        self.unscale(h, o, i, v)
    }

    /// Reflectance `R_k(h, o)` of split profile `k`: its amplitude times the profile's mass
    /// over the lobe's normalization (for the spike, `a cos(theta_cell) dw / lobe_scale`).
    pub fn reflectance(&self, h: usize, o: usize, k: usize) -> f64 {
        let nk = SPLIT_WIDTHS_DEG.len();
        let nd = self.tensor.dirs.len();
        let ls = self.tensor.lobe_scale[h];
        if ls <= 0.0 {
            return 0.0;
        }
        self.split.amplitudes[(h * nd + o) * nk + k] * self.profile_mass[o * nk + k] / ls
    }

    /// Tucker-decomposes the residual to `ranks` (HOSVD start, HOOI sweeps until the error
    /// improves by less than 1e-4 relative, at most 8, as the report) and stores the unscaled
    /// factors and the reflectances.
    /// The reflectances are then rescaled per node so that the reconstructed lobe keeps the
    /// sampled lobe's albedo ([`ShadingParts::conserve_energy`]).
    pub fn decompose(&self, ranks: TuckerRanks) -> Result<ShadingBasis, BasisError> {
        let mut b = self.decompose_raw(ranks)?;
        self.conserve_energy(&mut b);
        Ok(b)
    }

    /// [`ShadingParts::decompose`] without the energy correction: the reflectances are the
    /// split's ([`ShadingParts::reflectance`]).
    pub fn decompose_raw(&self, ranks: TuckerRanks) -> Result<ShadingBasis, BasisError> {
        let t = &self.tensor;
        let dims = t.dims();
        for (mode, rank, size) in [
            ("h", ranks.h, dims.0),
            ("o", ranks.o, dims.1),
            ("i", ranks.i, dims.2),
        ] {
            let max = size.min(MAX_SHADING_RANK);
            if rank == 0 || rank > max {
                return Err(FormatError::Rank { mode, rank, max }.into());
            }
        }
        let (nh, nd) = (dims.0, dims.1);
        let x = &self.split.residual;
        let start = hosvd_rings(x, nh, t.dirs)?;
        let r3 = (ranks.h, ranks.o, ranks.i);
        let tk = tucker_rings(x, nh, t.dirs, &start, r3, 8, 1e-4)?;
        let mut u_h = Vec::with_capacity(nh * ranks.h);
        for h in 0..nh {
            let ls = t.lobe_scale[h];
            for a in 0..ranks.h {
                u_h.push(to_f32(if ls > 0.0 { tk.u_h[(h, a)] / ls } else { 0.0 }));
            }
        }
        let dir_rows = |u: &faer::Mat<f64>, r: usize| -> Vec<f32> {
            let mut v = Vec::with_capacity(nd * r);
            for n in 0..nd {
                for b in 0..r {
                    v.push(to_f32(u[(n, b)] / t.dir_scale[n]));
                }
            }
            v
        };
        let nk = SPLIT_WIDTHS_DEG.len();
        let mut reflectances = Vec::with_capacity(nh * nd * nk);
        for h in 0..nh {
            for o in 0..nd {
                for k in 0..nk {
                    reflectances.push(to_f32(self.reflectance(h, o, k)));
                }
            }
        }
        // pole rows: the fibres through the normal fitted in the span of the other factors,
        // in the tensor's metric (the pole's own sqrt(cos dw) cancels: they come out raw)
        let ls = &t.lobe_scale;
        let s = &t.dir_scale;
        let x_o: Vec<f64> = (0..nh * nd)
            .map(|n| self.pole.residual[n] * ls[n / nd] * s[n % nd])
            .collect();
        let x_i: Vec<f64> = (0..nh * nd)
            .map(|n| self.pole.column[n] * ls[n / nd] * s[n % nd])
            .collect();
        let r3 = (ranks.h, ranks.o, ranks.i);
        let u_o_pole = fit_row(&x_o, &tk.u_h, &tk.u_i, r3, core_o(&tk.core, ranks));
        let r3 = (ranks.h, ranks.i, ranks.o);
        let u_i_pole = fit_row(&x_i, &tk.u_h, &tk.u_o, r3, core_i(&tk.core, ranks));
        let spec = t.spec;
        let params: Vec<f32> = t.params.iter().map(|&p| p as f32).collect();
        Ok(ShadingBasis {
            version: SHADING_SCHEMA_VERSION,
            family: spec.family,
            method: format!(
                "tucker of the split residual: hosvd + {} hooi sweeps, residual rel. error {:.4}, \
                 ||S||/||F|| {:.4}, {} params, {}x{} dirs, incident cells averaged",
                tk.sweeps,
                tk.rel_error,
                self.split.specular_fraction,
                nh,
                t.dirs.n_theta,
                t.dirs.n_phi
            ),
            param_range: [params[0], params[params.len() - 1]],
            param_warp: spec.warp,
            param_samples: params,
            dirs: t.dirs,
            ranks,
            u_h,
            u_o: dir_rows(&tk.u_o, ranks.o),
            u_o_pole: u_o_pole.iter().map(|&v| to_f32(v)).collect(),
            u_i: dir_rows(&tk.u_i, ranks.i),
            u_i_pole: u_i_pole.iter().map(|&v| to_f32(v)).collect(),
            core: tk.core.iter().map(|&v| to_f32(v)).collect(),
            split_widths_deg: SPLIT_WIDTHS_DEG.iter().map(|&w| w as f32).collect(),
            reflectances,
            reflectances_pole: self.pole.reflectances.iter().map(|&v| to_f32(v)).collect(),
        })
    }

    /// The grid's albedo of the sampled lobe at node `(h, o)`: `sum_i F(h, o, i) z_i dw`
    /// (the lobe's directional albedo, the incident axis holding cell averages).
    pub fn node_albedo(&self, h: usize, o: usize) -> f64 {
        let d = &self.tensor.dirs;
        (0..d.len())
            .map(|i| self.raw_lobe(h, o, i) * d.dir(i)[2])
            .sum::<f64>()
            * d.solid_angle()
    }

    /// Gives the energy the truncation lost back to the split lobes. The Tucker residual
    /// cannot follow the residual's fine structure about the mirror direction (a ring of
    /// negative values where the Gaussians overshoot a sharp lobe's heavy tail), so its
    /// albedo `integral f_r cos dwi` differs from the residual's; at every node `(h, o)` the
    /// reflectances are scaled by `1 - delta / sum_w R_w` (clamped to [0, 4]), `delta` that
    /// difference, with `integral U^i cos dwi` computed as the runtime does (the interpolated
    /// rows, [`constant_response`]). The reconstructed albedo at the nodes is then the
    /// sampled lobe's, and between them its interpolation.
    pub fn conserve_energy(&self, b: &mut ShadingBasis) {
        let ones = constant_response(b);
        let (nd, nk, r) = (b.n_dirs(), b.n_widths(), b.ranks);
        let dw = b.dirs.solid_angle();
        let zs: Vec<f64> = (0..nd).map(|i| b.dirs.dir(i)[2] * dw).collect();
        // per parameter sample (in parallel, each independently): the truncation's albedo
        // error at the nodes, then the pole (o = nd)
        let bb = &*b;
        let deltas: Vec<Vec<f64>> = (0..bb.n_params())
            .into_par_iter()
            .map(|h| {
                // the core contracted with U^h(h) and the constant response: a vector over b
                let mut m = vec![0.0f64; r.o];
                for a in 0..r.h {
                    let ua = bb.u_h[h * r.h + a] as f64;
                    for (q, mb) in m.iter_mut().enumerate() {
                        let row = &bb.core[(a * r.o + q) * r.i..][..r.i];
                        *mb += ua
                            * row
                                .iter()
                                .zip(&ones)
                                .map(|(d, c)| *d as f64 * c)
                                .sum::<f64>();
                    }
                }
                // the residual's albedo at the first node of every ring (the others are its
                // rotations: the same sum), raw_residual(h, o, i) z_i dw over i
                let t = &self.tensor;
                let (nt, np) = (t.dirs.n_theta, t.dirs.n_phi);
                let e_rings: Vec<f64> = (0..nt)
                    .map(|j| {
                        let lso = t.lobe_scale[h] * t.dir_scale[t.dirs.index(j, 0)];
                        let res = &self.split.residual[(h * nt + j) * nd..][..nd];
                        res.iter()
                            .zip(&t.dir_scale)
                            .zip(&zs)
                            .map(|((v, si), z)| {
                                let den = lso * si;
                                (if den > 0.0 { v / den } else { 0.0 }) * z
                            })
                            .sum()
                    })
                    .collect();
                (0..=nd)
                    .map(|o| {
                        let uo = if o < nd {
                            &bb.u_o[o * r.o..][..r.o]
                        } else {
                            &bb.u_o_pole[..]
                        };
                        let e_tucker: f64 = uo.iter().zip(&m).map(|(u, v)| *u as f64 * v).sum();
                        let e_residual: f64 = if o < nd {
                            e_rings[o / np]
                        } else {
                            let res = &self.pole.residual[h * nd..][..nd];
                            res.iter().zip(&zs).map(|(v, z)| v * z).sum()
                        };
                        e_tucker - e_residual
                    })
                    .collect()
            })
            .collect();
        for (h, delta) in deltas.iter().enumerate() {
            for (o, d) in delta.iter().enumerate() {
                let rw = if o < nd {
                    &mut b.reflectances[(h * nd + o) * nk..][..nk]
                } else {
                    &mut b.reflectances_pole[h * nk..][..nk]
                };
                let total: f64 = rw.iter().map(|&v| v as f64).sum();
                if total > 0.0 {
                    let scale = (1.0 - d / total).clamp(0.0, 4.0);
                    for v in rw.iter_mut() {
                        *v = to_f32(*v as f64 * scale);
                    }
                }
            }
        }
    }
}

/// `integral U^i(w, c) cos(theta) dw` over the hemisphere for every `c` (the incident
/// projections of a constant unit environment), with the persisted rows interpolated as the
/// runtime does, by the midpoint rule on 8 x 8 equal-area sub-cells of every cell (the rows
/// are bilinear in `(z, phi)` within a cell, blended linearly in `z` in the polar cap).
pub fn constant_response(b: &ShadingBasis) -> Vec<f64> {
    const SUB: usize = 8;
    let (nt, np) = (b.dirs.n_theta * SUB, b.dirs.n_phi * SUB);
    let dw = TAU / (nt * np) as f64;
    let r = b.ranks.i;
    let mut acc = vec![0.0f64; r];
    let mut row = [0.0f32; MAX_SHADING_RANK];
    for j in 0..nt {
        let z = 1.0 - (j as f64 + 0.5) / nt as f64;
        let s = (1.0 - z * z).max(0.0).sqrt();
        for k in 0..np {
            let (sp, cp) = (TAU * (k as f64 + 0.5) / np as f64).sin_cos();
            b.u_i_row([(s * cp) as f32, (s * sp) as f32, z as f32], &mut row);
            for (a, v) in acc.iter_mut().zip(&row[..r]) {
                *a += *v as f64 * z * dw;
            }
        }
    }
    acc
}

/// f64 to f32 with magnitudes below 1e-30 flushed to zero (subnormal table entries slow every
/// evaluation that touches them and carry nothing).
fn to_f32(x: f64) -> f32 {
    if x.abs() < 1e-30 {
        0.0
    } else {
        x as f32
    }
}

/// The shading basis of `spec`'s lobe: `n_params` parameter samples, the direction grid
/// `dirs`, Tucker ranks `ranks` (see the module docs).
pub fn shading_basis(
    spec: FamilySpec,
    n_params: usize,
    dirs: HemiGrid,
    ranks: TuckerRanks,
) -> Result<ShadingBasis, BasisError> {
    ShadingParts::new(spec, n_params, dirs)?.decompose(ranks)
}

/// The default shading basis of a family: its default parameter range and warp,
/// [`SHADING_PARAMS`] samples, [`SHADING_DIRS`], the thesis' ranks
/// ([`TuckerRanks::thesis`]: 4 x 8 x 8, Blinn-Phong 3 x 8 x 8).
pub fn default_shading_basis(family: Family) -> Result<ShadingBasis, BasisError> {
    let spec = FamilySpec::default_for(family)?;
    let ranks = TuckerRanks::thesis(family).ok_or(BasisError::DiffuseFamily)?;
    shading_basis(spec, SHADING_PARAMS, SHADING_DIRS, ranks)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every table of a basis as raw bits (so that -0.0 and 0.0, or two NaNs, are told apart).
    fn bits(b: &ShadingBasis) -> Vec<(&'static str, Vec<u32>)> {
        let t = |name, v: &[f32]| (name, v.iter().map(|x| x.to_bits()).collect());
        vec![
            t("param_samples", &b.param_samples),
            t("u_h", &b.u_h),
            t("u_o", &b.u_o),
            t("u_o_pole", &b.u_o_pole),
            t("u_i", &b.u_i),
            t("u_i_pole", &b.u_i_pole),
            t("core", &b.core),
            t("reflectances", &b.reflectances),
            t("reflectances_pole", &b.reflectances_pole),
        ]
    }

    /// The build is the same, bit for bit, on 1 and 2 threads: every parallel step places its
    /// results by index and sums in a fixed order. The grid and sample count are large enough
    /// that the parallel loops (rows, fits, slabs, product blocks) split into several pieces.
    #[test]
    fn build_is_bit_identical_on_1_and_2_threads() {
        let grid = HemiGrid {
            n_theta: 8,
            n_phi: 32,
        };
        for family in [Family::Ggx, Family::BlinnPhong] {
            let spec = FamilySpec::default_for(family).unwrap();
            let ranks = TuckerRanks { h: 3, o: 6, i: 6 };
            let run = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| shading_basis(spec, 12, grid, ranks).unwrap())
            };
            let (a, b) = (run(1), run(2));
            assert_eq!(a.method, b.method, "{family:?}");
            for ((name, x), (_, y)) in bits(&a).into_iter().zip(bits(&b)) {
                let diff = x.iter().zip(&y).filter(|(p, q)| p != q).count();
                assert!(
                    x.len() == y.len() && diff == 0,
                    "{family:?} {name}: {diff} of {} values differ",
                    x.len()
                );
            }
        }
    }
}
