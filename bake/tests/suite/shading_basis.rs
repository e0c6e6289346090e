//! The Tucker shading basis (docs/brdf-basis.md, "Shading basis"): the persisted tables against
//! the tensor they decompose, and the reconstructed lobe against the true BRDF (directional
//! albedo and reflected radiance under smooth environments, by an independent quadrature).
#![allow(clippy::needless_range_loop)]

use prt_bake::basis::cells::cell_average_row;
use prt_bake::basis::shading::{
    constant_response, default_shading_basis, shading_basis, ShadingParts, SHADING_DIRS,
    SHADING_PARAMS,
};
use prt_bake::basis::FamilySpec;
use prt_bake::brdf::Family;
use prt_bake::testing::albedo;
use prt_formats::basis::{cosine_centroid, mirror, HemiGrid, ShadingBasis, TuckerRanks};
use std::f64::consts::PI;
use std::sync::OnceLock;

/// A tiny grid (24 directions) on which full ranks are affordable.
const TINY: HemiGrid = HemiGrid {
    n_theta: 3,
    n_phi: 8,
};

fn f32v(d: [f64; 3]) -> [f32; 3] {
    d.map(|x| x as f32)
}

/// The default bases, built once per test binary (the build time is printed).
fn default_basis(family: Family) -> &'static ShadingBasis {
    static GGX: OnceLock<ShadingBasis> = OnceLock::new();
    static BP: OnceLock<ShadingBasis> = OnceLock::new();
    let cell = if family == Family::Ggx { &GGX } else { &BP };
    cell.get_or_init(|| {
        let t = std::time::Instant::now();
        let b = default_shading_basis(family).unwrap();
        eprintln!(
            "default {} shading basis ({} params, {}x{} dirs, ranks {:?}): {:.1} s; {}",
            family.name(),
            SHADING_PARAMS,
            SHADING_DIRS.n_theta,
            SHADING_DIRS.n_phi,
            b.ranks,
            t.elapsed().as_secs_f64(),
            b.method
        );
        b.validate().unwrap();
        b
    })
}

/// With full ranks nothing is truncated: the persisted tables, evaluated at the nodes and the
/// parameter samples, give back the split residual in raw units.
#[test]
fn full_ranks_reproduce_the_split_residual_at_the_nodes() {
    for family in [Family::Ggx, Family::BlinnPhong] {
        let spec = FamilySpec::default_for(family).unwrap();
        let parts = ShadingParts::new(spec, 3, TINY).unwrap();
        let nd = TINY.len();
        let b = parts.decompose(TuckerRanks { h: 3, o: nd, i: nd }).unwrap();
        b.validate().unwrap();
        for h in 0..3 {
            let p = b.param_samples[h];
            let scale = (0..nd * nd)
                .map(|n| parts.raw_lobe(h, n / nd, n % nd).abs())
                .fold(0.0, f64::max);
            for o in 0..nd {
                let wo = f32v(TINY.dir(o));
                for i in 0..nd {
                    let wi = f32v(TINY.dir(i));
                    let (v, clamped) = b.residual(p, wo, wi);
                    assert!(!clamped);
                    let want = parts.raw_residual(h, o, i);
                    assert!(
                        (v as f64 - want).abs() <= 2e-5 * scale,
                        "{family:?} h {h} o {o} i {i}: {v} vs {want} (lobe max {scale})"
                    );
                }
            }
        }
    }
}

/// The stored reflectances at the nodes are the split's, and the spike's is its amplitude
/// times `cos(theta) dw` of the mirror node over the lobe's normalization, recomputed here
/// from the grid (the mirror image of node (j, k) is node (j, k + n_phi/2)).
#[test]
fn stored_reflectances_are_the_split_amplitudes() {
    let spec = FamilySpec::default_for(Family::Ggx).unwrap();
    let grid = HemiGrid {
        n_theta: 4,
        n_phi: 12,
    };
    let parts = ShadingParts::new(spec, 4, grid).unwrap();
    let b = parts
        .decompose_raw(TuckerRanks { h: 2, o: 3, i: 3 })
        .unwrap();
    let (nd, nk) = (grid.len(), b.n_widths());
    let mut r = vec![0.0f32; nk];
    let mut spikes = 0;
    for h in 0..4 {
        let ls = parts.tensor.lobe_scale[h];
        for o in 0..nd {
            b.reflectances_into(b.param_samples[h], f32v(grid.dir(o)), &mut r);
            for k in 0..nk {
                let want = parts.reflectance(h, o, k);
                // at a node the other taps get weights of f32 rounding (~1e-7)
                assert!(
                    (r[k] as f64 - want).abs() <= 1e-5 * want.abs() + 1e-6,
                    "h {h} o {o} k {k}: {} vs {want}",
                    r[k]
                );
                assert!(r[k] >= 0.0);
            }
            let (j, kk) = (o / grid.n_phi, o % grid.n_phi);
            let m = grid.index(j, (kk + grid.n_phi / 2) % grid.n_phi);
            let a = parts.split.amplitudes[(h * nd + o) * nk];
            let spike = a * grid.dir(m)[2] * grid.solid_angle() / ls;
            assert!(
                (r[0] as f64 - spike).abs() <= 1e-5 * spike + 1e-6,
                "spike h {h} o {o}: {} vs {spike}",
                r[0]
            );
            spikes += (spike > 1e-3) as usize;
        }
    }
    assert!(
        spikes > 0,
        "no spike was fitted: the check above tested nothing"
    );
}

/// After the energy correction the reconstructed lobe reflects, under a constant unit
/// environment, the sampled lobe's albedo at every node and at the pole (the incident
/// projections computed as the runtime would, by quadrature of the interpolated rows).
#[test]
fn reconstruction_keeps_the_albedo_at_the_nodes() {
    let grid = HemiGrid {
        n_theta: 6,
        n_phi: 24,
    };
    for family in [Family::Ggx, Family::BlinnPhong] {
        let spec = FamilySpec::default_for(family).unwrap();
        let parts = ShadingParts::new(spec, 5, grid).unwrap();
        let b = parts.decompose(TuckerRanks { h: 3, o: 6, i: 6 }).unwrap();
        b.validate().unwrap();
        let ones: Vec<f32> = constant_response(&b).iter().map(|&v| v as f32).collect();
        let white = vec![1.0f32; b.n_widths()];
        let nd = grid.len();
        let dw = grid.solid_angle();
        for h in 0..5 {
            let p = b.param_samples[h];
            for o in 0..=nd {
                let (wo, want) = if o < nd {
                    (f32v(grid.dir(o)), parts.node_albedo(h, o))
                } else {
                    let a: f64 = (0..nd)
                        .map(|i| parts.pole.lobe[h * nd + i] * grid.dir(i)[2] * dw)
                        .sum();
                    ([0.0, 0.0, 1.0], a)
                };
                let (v, _) = b.reflected(p, wo, &ones, &white);
                assert!(
                    (v as f64 / want - 1.0).abs() < 2e-3,
                    "{family:?} h {h} o {o}: {v} vs {want}"
                );
            }
        }
    }
}

/// The same request gives the same basis, bit for bit, on any number of threads.
#[test]
fn shading_basis_is_reproducible_across_thread_counts() {
    let spec = FamilySpec::default_for(Family::Ggx).unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| shading_basis(spec, 4, TINY, TuckerRanks { h: 2, o: 4, i: 4 }).unwrap())
    };
    let a = run(1);
    let b = run(2);
    assert_eq!(a, b);
    assert!(a
        .u_o
        .iter()
        .zip(&b.u_o)
        .all(|(x, y)| x.to_bits() == y.to_bits()));
}

/// The cosine-weighted cell averages integrate the lobe: `sum_i F_i z_i dw` is the directional
/// albedo of the independent quadrature, for sharp lobes too (point values miss it by tens of
/// per cent there).
#[test]
fn cell_averages_integrate_the_directional_albedo() {
    let g = SHADING_DIRS;
    let mut row = vec![0.0; g.len()];
    for (family, p, tol) in [
        (Family::Ggx, 0.05, 0.01),
        (Family::Ggx, 0.3, 0.005),
        (Family::BlinnPhong, 200.0, 0.01),
        (Family::BlinnPhong, 5.0, 0.005),
    ] {
        for j in [0, 5, 13, 15] {
            let wo = g.dir(g.index(j, 3));
            cell_average_row(family, p, wo, &g, &mut row);
            let sum: f64 = (0..g.len())
                .map(|n| row[n] * g.dir(n)[2] * g.solid_angle())
                .sum();
            let want = true_albedo(family, p, wo[2]);
            assert!(
                (sum / want - 1.0).abs() < tol,
                "{family:?} {p} ring {j}: grid {sum} vs {want}"
            );
        }
    }
}

/// The builder refuses what it cannot build.
#[test]
fn shading_basis_refuses_bad_requests() {
    let spec = FamilySpec::default_for(Family::Ggx).unwrap();
    let ranks = TuckerRanks { h: 2, o: 2, i: 2 };
    assert!(shading_basis(spec, 1, TINY, ranks).is_err());
    let bad_grid = HemiGrid {
        n_theta: 1,
        n_phi: 8,
    };
    assert!(shading_basis(spec, 3, bad_grid, ranks).is_err());
    for r in [
        TuckerRanks { h: 4, o: 2, i: 2 },
        TuckerRanks { h: 2, o: 25, i: 2 },
        TuckerRanks { h: 0, o: 2, i: 2 },
    ] {
        assert!(shading_basis(spec, 3, TINY, r).is_err(), "{r:?}");
    }
    let mut diffuse = spec;
    diffuse.family = Family::Diffuse;
    assert!(shading_basis(diffuse, 3, TINY, ranks).is_err());
    assert!(default_shading_basis(Family::Diffuse).is_err());
}

// ---- against the true BRDF --------------------------------------------------------------

/// The true lobe (docs/brdf.md, written here from the formulas, not the BRDF code), for local
/// unit vectors above the horizon.
fn true_lobe(family: Family, p: f64, wo: [f64; 3], wi: [f64; 3]) -> f64 {
    let h = [wo[0] + wi[0], wo[1] + wi[1], wo[2] + wi[2]];
    let ch = h[2] / (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    match family {
        Family::Ggx => {
            let a2 = p * p;
            let d = a2 / (PI * (a2 * ch * ch + 1.0 - ch * ch).powi(2));
            let g1 = |c: f64| 2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt());
            d * g1(wi[2]) * g1(wo[2]) / (4.0 * wi[2] * wo[2])
        }
        _ => (p + 2.0) / (2.0 * PI) * ch.powf(p),
    }
}

/// The half-vector width that `albedo::hemisphere` crowds its nodes into.
fn quad_width(family: Family, p: f64) -> f64 {
    match family {
        Family::Ggx => p,
        _ => (2.0 / (p + 2.0)).sqrt(),
    }
}

fn true_albedo(family: Family, p: f64, cos_o: f64) -> f64 {
    match family {
        Family::Ggx => albedo::ggx(p, cos_o, 768),
        _ => albedo::blinn_phong(p, cos_o, 768),
    }
}

/// Rotation about +Z by `phi`.
fn rot_z(phi: f64, v: [f64; 3]) -> [f64; 3] {
    let (s, c) = phi.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
}

/// A test environment in the frame where the view is in the xz-plane (symmetric about it,
/// as `albedo::hemisphere` needs).
#[derive(Clone, Copy, Debug)]
enum Env {
    /// Radiance 1.
    Constant,
    /// `1 + 0.9 (w . a)`, `a = (-0.8, 0, 0.6)`: a gradient towards the mirror side.
    Linear,
    /// `exp(4 (w . a - 1))`: a broad lobe (1/e at about 41 degrees) about `a`.
    Lobe,
    /// `1 + 20` within 6 degrees of `a` (the edge smoothed over 0.002 in `w . a`): a lamp
    /// the size of the studio map's, as the compact lights leave it (their level).
    Cap,
}

const ENV_AXIS: [f64; 3] = [-0.8, 0.0, 0.6];
/// `cos(6 degrees)`: the cap's edge.
const CAP_COS: f64 = 0.994_521_895_368_273_3;

impl Env {
    fn radiance(self, w: [f64; 3]) -> f64 {
        let d = w[0] * ENV_AXIS[0] + w[1] * ENV_AXIS[1] + w[2] * ENV_AXIS[2];
        match self {
            Env::Constant => 1.0,
            Env::Linear => 1.0 + 0.9 * d,
            Env::Lobe => (4.0 * (d - 1.0)).exp(),
            Env::Cap => 1.0 + 20.0 * (((d - CAP_COS) / 0.002).clamp(-1.0, 1.0) * 0.5 + 0.5),
        }
    }
}

/// `integral I(w) U^i(w, c) cos(theta) dw` over the hemisphere: a midpoint rule on 8 x 8
/// equal-area sub-cells of every grid cell (the rows are bilinear in (z, phi) within cells).
fn incident(b: &ShadingBasis, env: impl Fn([f64; 3]) -> f64) -> Vec<f32> {
    let (nt, np) = (b.dirs.n_theta * 8, b.dirs.n_phi * 8);
    let dw = 2.0 * PI / (nt * np) as f64;
    let r = b.ranks.i;
    let mut acc = vec![0.0f64; r];
    let mut row = vec![0.0f32; r];
    for j in 0..nt {
        let z = 1.0 - (j as f64 + 0.5) / nt as f64;
        let s = (1.0 - z * z).sqrt();
        for k in 0..np {
            let ph = 2.0 * PI * (k as f64 + 0.5) / np as f64;
            let w = [s * ph.cos(), s * ph.sin(), z];
            b.u_i_row(f32v(w), &mut row);
            let f = env(w) * z * dw;
            for c in 0..r {
                acc[c] += f * row[c] as f64;
            }
        }
    }
    acc.iter().map(|&v| v as f32).collect()
}

/// `Ibar_w(r)`: `env` averaged with the normalized Gaussian of width `deg` about `r` (over the
/// sphere; width 0 is `env(r)`), by a product rule in the angle from `r` and the azimuth.
fn prefiltered(env: impl Fn([f64; 3]) -> f64, r: [f64; 3], deg: f64) -> f64 {
    if deg == 0.0 {
        return env(r);
    }
    let sigma = deg.to_radians();
    let t_max = (6.0 * sigma).min(PI);
    // a frame about r
    let a = if r[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let cross = |u: [f64; 3], v: [f64; 3]| {
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    };
    let t1 = cross(a, r);
    let l = (t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]).sqrt();
    let t1 = t1.map(|x| x / l);
    let t2 = cross(r, t1);
    let (n_t, n_p) = (96, 96);
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..n_t {
        let t = t_max * (i as f64 + 0.5) / n_t as f64;
        let g = (-t * t / (2.0 * sigma * sigma)).exp() * t.sin();
        let (st, ct) = t.sin_cos();
        for k in 0..n_p {
            let ph = 2.0 * PI * (k as f64 + 0.5) / n_p as f64;
            let (sp, cp) = ph.sin_cos();
            let w = [0, 1, 2].map(|c| ct * r[c] + st * (cp * t1[c] + sp * t2[c]));
            num += g * env(w);
            den += g;
        }
    }
    num / den
}

/// Per family: the parameters, view angles (degrees) and the azimuth the view is rotated to
/// (off the grid's columns, so the interpolation is exercised).
const VIEW_DEG: [f64; 6] = [0.0, 20.0, 45.0, 70.0, 80.0, 88.0];
const VIEW_AZIMUTH: f64 = 0.37;

struct Measured {
    family: Family,
    param: f64,
    view_deg: f64,
    env: Env,
    truth: f64,
    ours: f64,
}

impl Measured {
    fn rel(&self) -> f64 {
        (self.ours - self.truth).abs() / self.truth.abs()
    }
}

/// Reconstructed (residual through the incident projections + reflectances times the
/// prefiltered environment at the mirror direction, the runtime's formula) and true reflected
/// radiance, for every parameter, view and environment.
fn measure(family: Family, params: &[f64]) -> Vec<Measured> {
    let b = default_basis(family);
    // As rendered: width 0 is the grid cell's Gaussian (`ShadingBasis::rendered_width_deg`).
    let widths: Vec<f64> = (0..b.n_widths())
        .filter_map(|k| b.rendered_width_deg(k))
        .map(f64::from)
        .collect();
    let mut out = Vec::new();
    for env in [Env::Constant, Env::Linear, Env::Lobe, Env::Cap] {
        // the reconstruction sees the environment rotated with the view
        let env_rot = |w: [f64; 3]| env.radiance(rot_z(-VIEW_AZIMUTH, w));
        let inc = incident(b, env_rot);
        for &p in params {
            for &deg in &VIEW_DEG {
                let t = deg.to_radians();
                let wo = [t.sin(), 0.0, t.cos()];
                let truth = albedo::hemisphere(quad_width(family, p), wo[2], 768, |o, i| {
                    true_lobe(family, p, o.to_array(), i.to_array()) * env.radiance(i.to_array())
                });
                let wo_rot = rot_z(VIEW_AZIMUTH, wo);
                let r = mirror(f32v(wo_rot));
                // Each width read where its Gaussian, weighted by the cosine, looks.
                let ibar: Vec<f32> = widths
                    .iter()
                    .map(|&w| {
                        let c = cosine_centroid(r, w.to_radians() as f32);
                        prefiltered(env_rot, c.map(f64::from), w) as f32
                    })
                    .collect();
                let (ours, clamped) = b.reflected(p as f32, f32v(wo_rot), &inc, &ibar);
                assert!(!clamped, "{p} is inside the sampled range");
                out.push(Measured {
                    family,
                    param: p,
                    view_deg: deg,
                    env,
                    truth,
                    ours: ours as f64,
                });
            }
        }
    }
    out
}

fn print_table(m: &[Measured]) {
    eprintln!("family param env | view angle: truth ours rel.err % ...");
    let mut i = 0;
    while i < m.len() {
        let a = &m[i];
        let mut line = format!("{} {} {:?} |", a.family.name(), a.param, a.env);
        while i < m.len() && m[i].param == a.param && m[i].env as u8 == a.env as u8 {
            let x = &m[i];
            line += &format!(
                " {}: {:.4} {:.4} {:+.2} |",
                x.view_deg,
                x.truth,
                x.ours,
                100.0 * (x.ours - x.truth) / x.truth
            );
            i += 1;
        }
        eprintln!("{line}");
    }
}

/// The bound of a measured error, relative to the true value. A constant environment (the
/// directional albedo) within 3 % at every view; up to 45 degrees the linear environment
/// within 4 % and the lobe within 8 %. At 70 to 88 degrees: GGX 6 % and 20 %, Blinn-Phong 25 %
/// and 32 %. Each width's light is read at its cosine-weighted centroid (`cosine_centroid`);
/// read at the mirror direction, GGX at grazing views was up to 38 % too dark (the test fails
/// so). What is left at grazing views is the truncated residual's: with the exact
/// cosine-weighted average of each Gaussian instead of the centroid the figures barely move
/// (docs/brdf-basis.md, "Shading basis").
///
/// The cap (a lamp of 6 degrees, 20 times brighter than the rest, 53 degrees from the normal:
/// 8 degrees past the mirror direction, on the grazing side, at the 45-degree view) is an open
/// defect, bounded so that it cannot grow: GGX (alpha 0.05-0.2) is 15-17 % too dark at the
/// 45-degree view and up to 40 % at grazing views, Blinn-Phong up to 11.5 % and (sharp lobes
/// at grazing views, where the truth is small) 57 %. The split's Gaussians are isotropic about
/// the mirror direction and read towards the normal (the cosine-weighted centroid), while the
/// true lobe reaches further to the grazing side: moved to the normal side of the mirror
/// direction the same cap is 4.5 % too dark, centred on it 5.2 % (GGX alpha 0.15, radius 6
/// degrees, a throwaway probe). Bounds: 20 % up to 45 degrees, 45 % (GGX) and 60 %
/// (Blinn-Phong) beyond; read at the mirror direction (planted) the cap is 48.7 % (GGX) and
/// 67 % (Blinn-Phong) too dark at grazing views, and they fail.
fn bound(x: &Measured) -> f64 {
    let grazing = x.view_deg > 45.0;
    match (x.env, grazing, x.family) {
        (Env::Constant, _, _) => 0.03,
        (Env::Linear, false, _) => 0.04,
        (Env::Lobe, false, _) => 0.08,
        (Env::Linear, true, Family::Ggx) => 0.06,
        (Env::Lobe, true, Family::Ggx) => 0.20,
        (Env::Linear, true, _) => 0.25,
        (Env::Lobe, true, _) => 0.32,
        (Env::Cap, false, _) => 0.20,
        (Env::Cap, true, Family::Ggx) => 0.45,
        (Env::Cap, true, _) => 0.60,
    }
}

fn check(m: &[Measured], bound: impl Fn(&Measured) -> f64) {
    print_table(m);
    let bad: Vec<String> = m
        .iter()
        .filter(|x| x.rel().is_nan() || x.rel() > bound(x))
        .map(|x| {
            format!(
                "{} {} {:?} {} deg: {:.4} vs {:.4} ({:.2} %, bound {:.1} %)",
                x.family.name(),
                x.param,
                x.env,
                x.view_deg,
                x.ours,
                x.truth,
                100.0 * x.rel(),
                100.0 * bound(x)
            )
        })
        .collect();
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

#[test]
fn ggx_shading_basis_matches_the_true_lobe() {
    let m = measure(Family::Ggx, &[0.05, 0.1, 0.2, 0.5, 1.0]);
    check(&m, bound);
}

#[test]
fn blinn_phong_shading_basis_matches_the_true_lobe() {
    let m = measure(Family::BlinnPhong, &[1.0, 10.0, 50.0, 100.0, 200.0]);
    check(&m, bound);
}
