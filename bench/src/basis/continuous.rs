//! The end-to-end error of an evaluated basis against the exact lobe, off any grid
//! ([`continuous_error`]), and the error of its directional albedo.

use prt_bake::basis::grid::{lobe_vectors, tabulate_one};
use prt_bake::brdf::{Family, Lobe};
use prt_bake::sampling::Rng;
use prt_formats::basis::BrdfBasis;
use rayon::prelude::*;
use serde::Serialize;

/// End-to-end error of one lobe against the exact formula, off the grid (see
/// [`continuous_error`]).
#[derive(Clone, Debug, Serialize)]
pub struct ContinuousError {
    pub param: f64,
    /// Whether the parameter was outside the basis range (clamped).
    pub clamped: bool,
    /// Basis + runtime interpolation (`coefficients` then `eval_all_local`) vs the exact lobe.
    pub basis: f64,
    /// Trilinear interpolation of the lobe's own exact table on the basis' grid (no PCA): the
    /// grid's share.
    pub grid_only: f64,
    /// Standard errors of the two estimates (from 32 independent batches).
    pub basis_stderr: f64,
    pub grid_only_stderr: f64,
    /// Direction pairs sampled.
    pub samples: usize,
    /// Whether all reconstructed values were finite.
    pub finite: bool,
    /// Largest error of the directional albedo `a(wo) = ∫ f cos_i dwi` over the view angles
    /// [`ALBEDO_THETAS_DEG`], relative to the largest exact albedo over those angles (see
    /// [`albedo_errors`]; Blinn-Phong's albedo falls to a few percent of its peak at grazing
    /// views, so errors relative to each angle's own albedo would overstate what a renderer
    /// shows there): basis + runtime, and grid alone.
    pub albedo_max: f64,
    pub albedo_grid_max: f64,
}

/// View angles (degrees from the normal) of the albedo check.
pub const ALBEDO_THETAS_DEG: [f64; 5] = [0.0, 30.0, 60.0, 80.0, 88.0];

/// Pairs per view angle of the albedo check.
pub const ALBEDO_SAMPLES: usize = 1 << 18;

/// Directional albedo of the exact lobe and of two reconstructions at one view angle.
#[derive(Clone, Debug, Serialize)]
pub struct AlbedoError {
    pub theta_o_deg: f64,
    pub exact: f64,
    /// Basis + runtime (`coefficients`, `eval_all_local`).
    pub basis: f64,
    /// The lobe's own table on the basis' grid.
    pub grid_only: f64,
}

/// Direction pairs [`continuous_error`] samples.
pub const CONTINUOUS_SAMPLES: usize = 1 << 20;

/// [`continuous_error_n`] with [`CONTINUOUS_SAMPLES`] pairs.
pub fn continuous_error(basis: &BrdfBasis, family: Family, param: f64) -> ContinuousError {
    continuous_error_n(basis, family, param, CONTINUOUS_SAMPLES)
}

/// Cosine-weighted relative L2 error, against the exact f64 lobe, of the runtime
/// reconstruction of lobe `param` (`coefficients`, then `eval_all_local`) and of the
/// interpolated exact table of the lobe on the basis' grid:
///
/// `e = sqrt( E[(f - g)^2 w] / E[f^2 w] )`, `w = cos_i cos_o / p(wo, wi)`
///
/// estimated by Monte Carlo over the pair of hemispheres with `samples` pairs drawn
/// independently of any grid: `wo` cosine-weighted, `wi` from the mixture (1/2 each) of the
/// cosine-weighted hemisphere and the lobe's own half-vector sampling about `wo` (Blinn-Phong:
/// `p(h) = (s+1)/(2 pi) cos^s(theta_h)`, GGX: `p(h) = D(h) cos(theta_h)`,
/// `p(wi) = p(h) / (4 wo.h)`), so both the peak and the rest of the hemisphere are covered
/// whatever the grid. Pairs come from 32 fixed-seed batches computed in parallel and summed in
/// order, so the result is deterministic.
pub fn continuous_error_n(
    basis: &BrdfBasis,
    family: Family,
    param: f64,
    samples: usize,
) -> ContinuousError {
    const BATCHES: usize = 32;
    let g = basis.grid_spec();
    let (c, clamped) = basis.coefficients(param as f32);
    let own_table: Vec<f32> = tabulate_one(family, &g, param)
        .iter()
        .map(|&v| v as f32)
        .collect();
    let own = BrdfBasis {
        num_bases: 1,
        tables: own_table,
        coefficients: vec![1.0],
        param_samples: vec![param as f32],
        ..basis.clone()
    };
    let per = samples.div_ceil(BATCHES).max(1);
    // (num basis, num grid, den, finite)
    let batches: Vec<(f64, f64, f64, bool)> = (0..BATCHES)
        .into_par_iter()
        .map(|b| {
            let mut rng = Rng::for_sample(0x9E37_79B9_7F4A_7C15, b as u64, 0);
            let mut out = vec![0.0f32; basis.num_bases];
            let mut one = [0.0f32];
            let (mut nb, mut ng, mut den) = (0.0, 0.0, 0.0);
            let mut finite = true;
            for _ in 0..per {
                let wo = cosine_dir(rng.next_f64(), rng.next_f64());
                let (u0, u1, u2) = (rng.next_f64(), rng.next_f64(), rng.next_f64());
                let wi = if u0 < 0.5 {
                    cosine_dir(u1, u2)
                } else {
                    let h = sample_half(family, param, u1, u2);
                    let d = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
                    [
                        2.0 * d * h[0] - wo[0],
                        2.0 * d * h[1] - wo[1],
                        2.0 * d * h[2] - wo[2],
                    ]
                };
                if wi[2] <= 0.0 || wo[2] <= 0.0 {
                    continue;
                }
                let p_lobe = lobe_pdf(family, param, wi, wo);
                let p = 0.5 * wi[2] / std::f64::consts::PI + 0.5 * p_lobe;
                // p(wo) = cos_o / pi, so w = cos_i cos_o / (p(wo) p(wi)) = pi cos_i / p(wi)
                let w = std::f64::consts::PI * wi[2] / p;
                let f = lobe_vectors(family, param, wi, wo);
                let (wi32, wo32) = (to_f32(wi), to_f32(wo));
                basis.eval_all_local(wi32, wo32, &mut out);
                let rb: f64 = out.iter().zip(&c).map(|(a, b)| *a as f64 * *b as f64).sum();
                own.eval_all_local(wi32, wo32, &mut one);
                let rg = one[0] as f64;
                finite &= rb.is_finite() && rg.is_finite();
                nb += w * (rb - f) * (rb - f);
                ng += w * (rg - f) * (rg - f);
                den += w * f * f;
            }
            (nb, ng, den, finite)
        })
        .collect();
    let (mut nb, mut ng, mut den) = (0.0, 0.0, 0.0);
    for x in &batches {
        nb += x.0;
        ng += x.1;
        den += x.2;
    }
    let rel = |n: f64, d: f64| if d > 0.0 { (n / d).sqrt() } else { 0.0 };
    let stderr = |pick: fn(&(f64, f64, f64, bool)) -> f64| {
        let e: Vec<f64> = batches.iter().map(|x| rel(pick(x), x.2)).collect();
        let m = e.iter().sum::<f64>() / e.len() as f64;
        let var = e.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (e.len() - 1) as f64;
        (var / e.len() as f64).sqrt()
    };
    let albedo = albedo_errors(basis, &own, &c, family, param, ALBEDO_SAMPLES);
    let top = albedo.iter().map(|x| x.exact).fold(0.0, f64::max);
    let worst = |pick: fn(&AlbedoError) -> f64| {
        if top > 0.0 {
            albedo
                .iter()
                .map(|x| (pick(x) - x.exact).abs() / top)
                .fold(0.0, f64::max)
        } else {
            0.0
        }
    };
    ContinuousError {
        albedo_max: worst(|x| x.basis),
        albedo_grid_max: worst(|x| x.grid_only),
        param,
        clamped,
        basis: rel(nb, den),
        grid_only: rel(ng, den),
        basis_stderr: stderr(|x| x.0),
        grid_only_stderr: stderr(|x| x.1),
        samples: per * BATCHES,
        finite: batches.iter().all(|x| x.3),
    }
}

/// Directional albedo `a(wo) = ∫ f(wi, wo) cos_i dwi` of the exact lobe, of the runtime
/// reconstruction from `basis` with coefficients `c`, and of the one-basis table `own`, at the
/// view angles [`ALBEDO_THETAS_DEG`]: Monte Carlo with `samples` directions `wi` per angle from
/// the even mixture of cosine-weighted and lobe sampling (as [`continuous_error_n`]), the same
/// directions for all three, fixed seeds. The albedo is what a glossy surface under uniform
/// light shows, and unlike the L2 error it is not dominated by the lobe's peak: a broad error
/// of small amplitude next to a sharp peak moves it a lot.
pub fn albedo_errors(
    basis: &BrdfBasis,
    own: &BrdfBasis,
    c: &[f32],
    family: Family,
    param: f64,
    samples: usize,
) -> Vec<AlbedoError> {
    ALBEDO_THETAS_DEG
        .par_iter()
        .enumerate()
        .map(|(j, &deg)| {
            let t = deg.to_radians();
            let wo = [t.sin(), 0.0, t.cos()];
            let mut rng = Rng::for_sample(0x2545_F491_4F6C_DD1D, j as u64, 0);
            let mut out = vec![0.0f32; basis.num_bases];
            let mut one = [0.0f32];
            let (mut ex, mut rb, mut rg) = (0.0, 0.0, 0.0);
            for _ in 0..samples {
                let (u0, u1, u2) = (rng.next_f64(), rng.next_f64(), rng.next_f64());
                let wi = if u0 < 0.5 {
                    cosine_dir(u1, u2)
                } else {
                    let h = sample_half(family, param, u1, u2);
                    let d = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
                    [
                        2.0 * d * h[0] - wo[0],
                        2.0 * d * h[1] - wo[1],
                        2.0 * d * h[2] - wo[2],
                    ]
                };
                if wi[2] <= 0.0 {
                    continue;
                }
                let p = 0.5 * wi[2] / std::f64::consts::PI + 0.5 * lobe_pdf(family, param, wi, wo);
                let w = wi[2] / p;
                let (wi32, wo32) = (to_f32(wi), to_f32(wo));
                basis.eval_all_local(wi32, wo32, &mut out);
                own.eval_all_local(wi32, wo32, &mut one);
                ex += w * lobe_vectors(family, param, wi, wo);
                rb += w * out
                    .iter()
                    .zip(c)
                    .map(|(a, b)| *a as f64 * *b as f64)
                    .sum::<f64>();
                rg += w * one[0] as f64;
            }
            let n = samples.max(1) as f64;
            AlbedoError {
                theta_o_deg: deg,
                exact: ex / n,
                basis: rb / n,
                grid_only: rg / n,
            }
        })
        .collect()
}

fn to_f32(v: [f64; 3]) -> [f32; 3] {
    [v[0] as f32, v[1] as f32, v[2] as f32]
}

/// Cosine-weighted direction on the +Z hemisphere.
fn cosine_dir(u1: f64, u2: f64) -> [f64; 3] {
    let r = u1.sqrt();
    let ph = 2.0 * std::f64::consts::PI * u2;
    [r * ph.cos(), r * ph.sin(), (1.0 - u1).max(0.0).sqrt()]
}

/// Half vector with the lobe's density (see [`continuous_error_n`]).
fn sample_half(family: Family, p: f64, u1: f64, u2: f64) -> [f64; 3] {
    let ct = family.sample_cos_h_f64(p, u1);
    let st = (1.0 - ct * ct).max(0.0).sqrt();
    let ph = 2.0 * std::f64::consts::PI * u2;
    [st * ph.cos(), st * ph.sin(), ct]
}

/// Density over `wi` (solid angle) of reflecting `wo` about a half vector from
/// [`sample_half`].
fn lobe_pdf(family: Family, p: f64, wi: [f64; 3], wo: [f64; 3]) -> f64 {
    let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let l = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    if l <= 1e-300 {
        return 0.0;
    }
    let ct = (h[2] / l).clamp(0.0, 1.0);
    let woh = (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]) / l;
    if woh <= 0.0 {
        return 0.0;
    }
    let ph = family.half_pdf_f64(p, ct);
    ph / (4.0 * woh)
}
