//! The hemisphere integrals that turn a vertex's incident-light representations into what the
//! last reflection needs (docs/vertex.md, section 3), all in the vertex's local frame (z = the
//! normal):
//!
//! ```text
//! Ehat[s]     = integral_H Y_s(w) w.z dw             (irradiance of SH coefficient s)
//! Cwi[s][c]   = integral_H Y_s(w) U^i(w, c) w.z dw   (U^i projection of SH coefficient s)
//! Cconst[c]   = integral_H U^i(w, c) w.z dw          (U^i projection of a uniform radiance)
//! ```
//!
//! `Y_s` is `prt_formats::lighting::sh::sh_eval` (order 4) and `U^i` the shading basis' incident
//! rows as the runtime interpolates them (`ShadingBasis::u_i_row`). With `dw = dz dphi`, each
//! is computed once per basis on panels uniform in `(z, phi)` that cut every cell of the
//! basis' equal-area grid into [`SUB`] x [`SUB`] (an even count, so panel edges fall on the
//! nodes, where the bilinear rows have their kinks; the integrand is smooth on every panel),
//! at least [`MIN_Z`] x [`MIN_PHI`] panels: 3-point Gauss-Legendre in `z` (exact for the
//! polynomial `m = 0` terms), the midpoint rule in `phi`. Only `m = 0` terms of `Ehat` are
//! nonzero (closed forms in the tests: `sqrt(pi)/2`, `sqrt(pi/3)`, `sqrt(5 pi)/8`, 0).

use std::f64::consts::TAU;

use prt_formats::basis::{ShadingBasis, MAX_SHADING_RANK};
use prt_formats::lighting::quadrature::gauss_legendre;
use prt_formats::lighting::sh::{sh_eval, SH_COUNT};

/// Sub-cells per basis grid cell, along z and along phi.
pub(super) const SUB: usize = 8;
/// Fewest z steps of a quadrature.
pub(super) const MIN_Z: usize = 128;
/// Fewest phi steps of a quadrature.
pub(super) const MIN_PHI: usize = 512;

/// The hemisphere cut into `nz x nphi` panels uniform in `z` in [0, 1] and `phi`: 3-point
/// Gauss-Legendre in `z` and the midpoint in `phi` on each; calls `f(w, weight)` at each point
/// (the weights are solid angles and sum to 2 pi).
fn hemisphere(nz: usize, nphi: usize, mut f: impl FnMut([f64; 3], f64)) {
    let (x, wx) = gauss_legendre(3);
    let hz = 1.0 / nz as f64;
    let dphi = TAU / nphi as f64;
    for j in 0..nz {
        let mid = 1.0 - (j as f64 + 0.5) * hz;
        for (xi, wi) in x.iter().zip(&wx) {
            let z = mid + 0.5 * hz * xi;
            let dw = 0.5 * hz * wi * dphi;
            let s = (1.0 - z * z).max(0.0).sqrt();
            for k in 0..nphi {
                let (sp, cp) = ((k as f64 + 0.5) * dphi).sin_cos();
                f([s * cp, s * sp, z], dw);
            }
        }
    }
}

/// `Ehat[s] = integral_H Y_s(w) w.z dw` for the 16 SH coefficients.
pub(super) fn irradiance_sh() -> [f32; SH_COUNT] {
    let mut acc = [0.0f64; SH_COUNT];
    hemisphere(MIN_Z, MIN_PHI, |w, dw| {
        let y = sh_eval(w);
        for (a, ys) in acc.iter_mut().zip(y) {
            *a += ys * w[2] * dw;
        }
    });
    acc.map(|v| v as f32)
}

/// The constants of one shading basis.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct ShadingConstants {
    /// `r_i`, the basis' incident rank.
    pub rank: usize,
    /// `Cwi[s][c]`, `[16][rank]`.
    pub cwi: Vec<f32>,
    /// `Cconst[c]`, `[rank]`.
    pub cconst: Vec<f32>,
}

impl ShadingConstants {
    /// The constants of a validated basis.
    pub(super) fn new(b: &ShadingBasis) -> ShadingConstants {
        let r = b.ranks.i;
        let nz = (b.dirs.n_theta * SUB).max(MIN_Z);
        let nphi = (b.dirs.n_phi * SUB).max(MIN_PHI);
        let mut cwi = vec![0.0f64; SH_COUNT * r];
        let mut cconst = vec![0.0f64; r];
        let mut row = [0.0f32; MAX_SHADING_RANK];
        hemisphere(nz, nphi, |w, dw| {
            b.u_i_row(w.map(|c| c as f32), &mut row);
            let y = sh_eval(w);
            let cos_dw = w[2] * dw;
            for (c, &u) in row[..r].iter().enumerate() {
                let u = u as f64 * cos_dw;
                cconst[c] += u;
                for (s, ys) in y.iter().enumerate() {
                    cwi[s * r + c] += ys * u;
                }
            }
        });
        ShadingConstants {
            rank: r,
            cwi: cwi.iter().map(|&v| v as f32).collect(),
            cconst: cconst.iter().map(|&v| v as f32).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use prt_formats::basis::{HemiGrid, ParamWarp, TuckerRanks, SHADING_SCHEMA_VERSION};
    use prt_formats::Family;
    use std::f64::consts::PI;

    #[test]
    fn irradiance_of_sh_matches_the_closed_form() {
        let e = irradiance_sh();
        // Only m = 0 (indices 0, 2, 6, 12) survive the azimuthal integral:
        // 2 pi integral_0^1 Y_l0(z) z dz.
        let mut want = [0.0f64; SH_COUNT];
        want[0] = PI.sqrt() / 2.0;
        want[2] = (PI / 3.0).sqrt();
        want[6] = (5.0 * PI).sqrt() / 8.0;
        want[12] = 0.0;
        for s in 0..SH_COUNT {
            assert!(
                (e[s] as f64 - want[s]).abs() < 1e-6,
                "Ehat[{s}] = {} (closed form {})",
                e[s],
                want[s]
            );
        }
    }

    /// A basis whose incident rows are known functions: row 0 is 1 everywhere, row 1 is z
    /// at the nodes (so, interpolated, z clamped to the node range).
    fn basis() -> ShadingBasis {
        let dirs = HemiGrid {
            n_theta: 8,
            n_phi: 16,
        };
        let nd = dirs.len();
        let ranks = TuckerRanks { h: 1, o: 1, i: 2 };
        let mut u_i = Vec::new();
        for n in 0..nd {
            u_i.extend([1.0, dirs.dir(n)[2] as f32]);
        }
        ShadingBasis {
            version: SHADING_SCHEMA_VERSION,
            family: Family::Ggx,
            method: "test".into(),
            param_range: [0.1, 0.5],
            param_warp: ParamWarp::Linear,
            param_samples: vec![0.1, 0.5],
            dirs,
            ranks,
            u_h: vec![1.0, 1.0],
            u_o: vec![1.0; nd],
            u_o_pole: vec![1.0],
            u_i,
            u_i_pole: vec![1.0, 1.0],
            core: vec![1.0; 2],
            split_widths_deg: vec![0.0],
            reflectances: vec![0.0; 2 * nd],
            reflectances_pole: vec![0.0; 2],
        }
    }

    #[test]
    fn constants_of_known_rows() {
        let b = basis();
        b.validate().expect("valid basis");
        let c = ShadingConstants::new(&b);
        let ehat = irradiance_sh();
        // Row 0 is 1: Cconst = pi, Cwi[s][0] = Ehat[s].
        assert!((c.cconst[0] as f64 - PI).abs() < 1e-4, "{}", c.cconst[0]);
        for (s, e) in ehat.iter().enumerate() {
            assert!((c.cwi[s * 2] - e).abs() < 1e-4, "s {s}");
        }
        // Row 1 is about z: Cconst ~ 2 pi / 3 (the horizon clamp holds the last node's z in
        // the outer half ring, the polar cap blends to 1: both small).
        assert!(
            (c.cconst[1] as f64 - TAU / 3.0).abs() < 2e-2,
            "{}",
            c.cconst[1]
        );
        // Azimuthal symmetry: only m = 0 SH terms survive.
        for s in [1, 3, 4, 5, 7, 8, 9, 10, 11, 13, 14, 15] {
            assert!(
                c.cwi[s * 2].abs() < 1e-4 && c.cwi[s * 2 + 1].abs() < 1e-4,
                "s {s}"
            );
        }
    }
}
