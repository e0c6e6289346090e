//! The shading basis' persisted form (docs/brdf-basis.md, "Shading basis"): the hemisphere
//! grid's interpolation (nodes, partition of unity, linear reproduction, the azimuth seam, the
//! pole and the horizon), evaluation of a hand-made basis against its tables, and validation.
#![allow(clippy::needless_range_loop)]

use prt_formats::basis::{
    mirror, BasisError, HemiGrid, ParamWarp, ShadingBasis, TuckerRanks, MAX_HEMI_DIRS,
    MAX_SHADING_RANK, SHADING_SCHEMA_VERSION,
};
use prt_formats::family::Family;
use std::f64::consts::TAU;

const GRID: HemiGrid = HemiGrid {
    n_theta: 5,
    n_phi: 12,
};

fn dir(z: f64, phi: f64) -> [f32; 3] {
    let r = (1.0 - z * z).max(0.0).sqrt();
    [(r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32]
}

fn node(g: &HemiGrid, n: usize) -> [f32; 3] {
    g.dir(n).map(|x| x as f32)
}

/// Weight per node (and the pole's, last) of a direction.
fn dense(g: &HemiGrid, w: [f32; 3]) -> Vec<f64> {
    let hw = g.weights(w);
    let mut d = vec![0.0; g.len() + 1];
    for (n, x) in hw.taps {
        assert!(n < g.len(), "tap {n} outside the grid");
        d[n] += x as f64;
    }
    d[g.len()] += hw.pole as f64;
    d
}

#[test]
fn weights_at_nodes_select_the_node() {
    for n in 0..GRID.len() {
        let d = dense(&GRID, node(&GRID, n));
        assert!((d[n] - 1.0).abs() < 1e-5, "node {n}: {}", d[n]);
    }
}

#[test]
fn weights_are_a_partition_of_unity() {
    let mut dirs: Vec<[f32; 3]> = Vec::new();
    for a in 0..40 {
        for b in 0..23 {
            let z = 1.0 - 1.1 * a as f64 / 39.0; // past the horizon too
            dirs.push(dir(z.max(-1.0), TAU * b as f64 / 23.0 - 1.0));
        }
    }
    dirs.extend([
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        [1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [3.0, 4.0, 5.0],
        [0.0, 0.0, 0.0],
        [f32::NAN, 0.0, 1.0],
        [f32::INFINITY, 0.0, 1.0],
        [1e-30, 1e-30, 1e-30],
    ]);
    for w in dirs {
        let d = dense(&GRID, w);
        let sum: f64 = d.iter().sum();
        assert!((sum - 1.0).abs() < 1e-6, "{w:?}: sum {sum}");
        assert!(d.iter().all(|&x| x >= 0.0), "{w:?}: {d:?}");
    }
}

/// Between the first and last rings and away from the seam the interpolation is bilinear in
/// `(z, phi)`: it reproduces `a + b z + c phi` exactly.
#[test]
fn weights_reproduce_linear_functions_of_z_and_phi() {
    let f = |z: f64, phi: f64| 0.3 + 1.7 * z - 0.4 * phi;
    let table: Vec<f32> = (0..GRID.len())
        .map(|n| f(GRID.z(n / GRID.n_phi), GRID.phi(n % GRID.n_phi)) as f32)
        .collect();
    // only rounding puts weight on the pole row at z_0
    let pole = [0.0f32];
    let (z0, z1) = (GRID.z(GRID.n_theta - 1), GRID.z(0));
    let (p0, p1) = (GRID.phi(0), GRID.phi(GRID.n_phi - 1));
    let mut out = [0.0f32];
    for a in 0..=20 {
        for b in 0..=30 {
            let z = z0 + (z1 - z0) * a as f64 / 20.0;
            let phi = p0 + (p1 - p0) * b as f64 / 30.0;
            GRID.weights(dir(z, phi))
                .interpolate(&table, &pole, 1, &mut out);
            let want = f(z, phi);
            assert!(
                (out[0] as f64 - want).abs() < 2e-5,
                "z {z} phi {phi}: {} vs {want}",
                out[0]
            );
        }
    }
}

/// Across `phi = 0` the last column neighbours the first: half way (phi = 0) each gets half.
#[test]
fn azimuth_wraps_across_the_seam() {
    let last = GRID.n_phi - 1;
    for j in 0..GRID.n_theta {
        let w = dir(GRID.z(j), 0.0);
        let d = dense(&GRID, w);
        for (k, want) in [(0, 0.5), (last, 0.5)] {
            let n = GRID.index(j, k);
            assert!((d[n] - want).abs() < 1e-5, "ring {j} column {k}: {}", d[n]);
        }
        // a quarter cell below the seam: three quarters on the last column
        let w = dir(GRID.z(j), -0.25 * TAU / GRID.n_phi as f64);
        let d = dense(&GRID, w);
        assert!((d[GRID.index(j, last)] - 0.75).abs() < 1e-5);
        assert!((d[GRID.index(j, 0)] - 0.25).abs() < 1e-5);
    }
}

/// In the polar cap the pole row's weight grows linearly in z from 0 at ring 0 to 1 at the
/// pole, whatever the azimuth, so the interpolant is continuous at the pole.
#[test]
fn polar_cap_blends_to_the_pole_row() {
    let z0 = GRID.z(0);
    for k in 0..7 {
        let phi = 0.9 * k as f64;
        for (z, want) in [(z0, 0.0), (0.5 * (z0 + 1.0), 0.5), (1.0, 1.0)] {
            let hw = GRID.weights(dir(z, phi));
            assert!(
                (hw.pole as f64 - want).abs() < 1e-4,
                "z {z} phi {phi}: {}",
                hw.pole
            );
            // the rest stays on ring 0
            assert!(hw.taps.iter().all(|&(n, w)| n < GRID.n_phi || w == 0.0));
        }
    }
    let table: Vec<f32> = (0..GRID.len()).map(|n| n as f32).collect();
    let pole_row = [-7.0f32];
    let mut out = [0.0f32];
    for k in 0..9 {
        let w = dir(1.0 - 1e-7, 0.7 * k as f64);
        GRID.weights(w).interpolate(&table, &pole_row, 1, &mut out);
        assert!((out[0] + 7.0).abs() < 1e-3, "{}", out[0]);
    }
}

/// Below the last ring's nodes (and below the horizon) z is clamped: the weights are those of
/// the last ring at the same azimuth.
#[test]
fn horizon_clamps_to_the_last_ring() {
    let zl = GRID.z(GRID.n_theta - 1);
    for phi in [0.1, 1.0, 3.0, 5.9] {
        let at_node = dense(&GRID, dir(zl, phi));
        for z in [0.5 * zl, 1e-6, 0.0, -0.3, -0.99] {
            let d = dense(&GRID, dir(z, phi));
            for (a, b) in d.iter().zip(&at_node) {
                assert!((a - b).abs() < 1e-5, "z {z} phi {phi}");
            }
        }
    }
}

// ---- a hand-made basis --------------------------------------------------------------------

const TINY: HemiGrid = HemiGrid {
    n_theta: 3,
    n_phi: 8,
};
const RANKS: TuckerRanks = TuckerRanks { h: 2, o: 3, i: 2 };
const NW: usize = 4;

/// Distinct, irregular values so that a wrong index or stride shows.
fn values(n: usize, seed: f32) -> Vec<f32> {
    (0..n)
        .map(|k| ((k as f32 * 0.731 + seed).sin() * 1.3 + 0.1 * seed).abs() - 0.2 * seed.fract())
        .collect()
}

fn tiny() -> ShadingBasis {
    let nd = TINY.len();
    let params = vec![0.05f32, 0.2, 0.8];
    let np = params.len();
    ShadingBasis {
        version: SHADING_SCHEMA_VERSION,
        family: Family::Ggx,
        method: "hand-made".into(),
        param_range: [0.05, 0.8],
        param_warp: ParamWarp::Log { offset: 0.0 },
        param_samples: params,
        dirs: TINY,
        ranks: RANKS,
        u_h: values(np * RANKS.h, 0.3),
        u_o: values(nd * RANKS.o, 1.1),
        u_o_pole: values(RANKS.o, 2.2),
        u_i: values(nd * RANKS.i, 3.7),
        u_i_pole: values(RANKS.i, 4.1),
        core: values(RANKS.h * RANKS.o * RANKS.i, 5.3),
        split_widths_deg: vec![0.0, 7.0, 14.0, 21.0],
        reflectances: values(np * nd * NW, 6.5).iter().map(|v| v.abs()).collect(),
        reflectances_pole: values(np * NW, 7.9).iter().map(|v| v.abs()).collect(),
    }
}

fn close(a: &[f32], b: &[f32], tol: f32) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= tol * (1.0 + y.abs()))
}

#[test]
fn tiny_basis_validates_and_round_trips() {
    let b = tiny();
    b.validate().unwrap();
    let json = serde_json::to_string(&b).unwrap();
    let back: ShadingBasis = serde_json::from_str(&json).unwrap();
    assert_eq!(back, b);
    assert!(json.contains("\"family\":\"ggx\""));
}

/// At the nodes, the pole and the parameter samples the evaluation returns the stored rows.
#[test]
fn evaluation_at_nodes_reproduces_the_stored_rows() {
    let b = tiny();
    let nd = TINY.len();
    let mut row = [0.0f32; MAX_SHADING_RANK];
    for (j, &p) in b.param_samples.iter().enumerate() {
        let clamped = b.u_h_row(p, &mut row);
        assert!(!clamped);
        assert!(close(&row[..2], &b.u_h[j * 2..j * 2 + 2], 1e-6));
        for n in 0..=nd {
            let w = if n < nd {
                node(&TINY, n)
            } else {
                [0.0, 0.0, 1.0]
            };
            let mut r = [0.0f32; NW];
            b.reflectances_into(p, w, &mut r);
            let want = if n < nd {
                &b.reflectances[(j * nd + n) * NW..][..NW]
            } else {
                &b.reflectances_pole[j * NW..][..NW]
            };
            assert!(close(&r, want, 1e-5), "p {p} node {n}: {r:?} vs {want:?}");
        }
    }
    for n in 0..=nd {
        let (w, o_want, i_want) = if n < nd {
            (
                node(&TINY, n),
                &b.u_o[n * 3..n * 3 + 3],
                &b.u_i[n * 2..n * 2 + 2],
            )
        } else {
            ([0.0, 0.0, 1.0], &b.u_o_pole[..], &b.u_i_pole[..])
        };
        b.u_o_row(w, &mut row);
        assert!(
            close(&row[..3], o_want, 1e-5),
            "node {n}: {:?} vs {o_want:?}",
            &row[..3]
        );
        b.u_i_row(w, &mut row);
        assert!(
            close(&row[..2], i_want, 1e-5),
            "node {n}: {:?} vs {i_want:?}",
            &row[..2]
        );
    }
}

/// The residual is the core contracted with the three rows; `contract_core` is the first
/// contraction; below the horizon the lobe is 0.
#[test]
fn residual_is_the_core_contraction() {
    let b = tiny();
    let (wo, wi) = (dir(0.7, 0.4), dir(0.3, 2.5));
    for p in [0.05f32, 0.1, 0.33, 0.8] {
        let (mut uh, mut uo, mut ui) = ([0.0f32; 2], [0.0f32; 3], [0.0f32; 2]);
        b.u_h_row(p, &mut uh);
        b.u_o_row(wo, &mut uo);
        b.u_i_row(wi, &mut ui);
        let mut want = 0.0f64;
        for a in 0..2 {
            for o in 0..3 {
                for i in 0..2 {
                    want += (b.core[(a * 3 + o) * 2 + i] * uh[a] * uo[o] * ui[i]) as f64;
                }
            }
        }
        let (v, clamped) = b.residual(p, wo, wi);
        assert!(!clamped);
        assert!(
            (v as f64 - want).abs() < 1e-5 * (1.0 + want.abs()),
            "{v} vs {want}"
        );
        let mut m = [0.0f32; 6];
        b.contract_core(&uh, &mut m);
        let via: f64 = (0..3)
            .map(|o| {
                (0..2)
                    .map(|i| (m[o * 2 + i] * uo[o] * ui[i]) as f64)
                    .sum::<f64>()
            })
            .sum();
        assert!((via - want).abs() < 1e-5 * (1.0 + want.abs()));
        assert_eq!(b.residual(p, [0.3, 0.0, -0.9], wi).0, 0.0);
        assert_eq!(b.residual(p, wo, [0.3, 0.0, 0.0]).0, 0.0);
    }
}

/// `reflected` is the residual with the incident projections plus the reflectances times the
/// prefiltered radiance.
#[test]
fn reflected_is_residual_plus_specular() {
    let b = tiny();
    let (p, wo) = (0.3f32, dir(0.55, 1.9));
    let incident = [0.7f32, -0.2];
    let prefiltered = [1.5f32, 0.25, 2.0, 0.125];
    let (mut uh, mut uo) = ([0.0f32; 2], [0.0f32; 3]);
    b.u_h_row(p, &mut uh);
    b.u_o_row(wo, &mut uo);
    let mut r = [0.0f32; NW];
    b.reflectances_into(p, wo, &mut r);
    let mut want = 0.0f64;
    for a in 0..2 {
        for o in 0..3 {
            for i in 0..2 {
                want += (b.core[(a * 3 + o) * 2 + i] * uh[a] * uo[o] * incident[i]) as f64;
            }
        }
    }
    want += (0..NW).map(|k| (r[k] * prefiltered[k]) as f64).sum::<f64>();
    let (v, clamped) = b.reflected(p, wo, &incident, &prefiltered);
    assert!(!clamped);
    assert!(
        (v as f64 - want).abs() < 1e-5 * (1.0 + want.abs()),
        "{v} vs {want}"
    );
    assert_eq!(
        b.reflected(p, [0.0, 1.0, -0.1], &incident, &prefiltered).0,
        0.0
    );
    assert_eq!(mirror([0.2, -0.3, 0.9]), [-0.2, 0.3, 0.9]);
}

/// Linear in `ln(alpha)` between samples; clamped (and reported) outside the range and for NaN.
#[test]
fn parameters_interpolate_in_the_warped_parameter_and_clamp() {
    let b = tiny();
    let (p0, p1) = (0.2f32, 0.8f32);
    let p = 0.4f32;
    let t = (p.ln() - p0.ln()) / (p1.ln() - p0.ln());
    let mut row = [0.0f32; 2];
    assert!(!b.u_h_row(p, &mut row));
    let want: Vec<f32> = (0..2)
        .map(|a| b.u_h[2 + a] + t * (b.u_h[4 + a] - b.u_h[2 + a]))
        .collect();
    assert!(close(&row, &want, 1e-5), "{row:?} vs {want:?}");
    for (q, j) in [
        (0.01f32, 0),
        (5.0, 2),
        (f32::NAN, 0),
        (f32::NEG_INFINITY, 0),
    ] {
        assert!(b.u_h_row(q, &mut row), "{q} must be reported as clamped");
        assert!(close(&row, &b.u_h[j * 2..j * 2 + 2], 1e-6), "{q}");
        let mut r = [0.0f32; NW];
        assert!(b.reflectances_into(q, dir(0.5, 0.5), &mut r));
        assert!(r.iter().all(|v| v.is_finite()));
    }
}

/// Odd directions and parameters give finite values, never a panic.
#[test]
fn evaluation_is_finite_for_odd_inputs() {
    let b = tiny();
    let odd = [
        [0.0f32, 0.0, 0.0],
        [f32::NAN, 0.0, 0.5],
        [0.0, f32::INFINITY, 0.5],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],
        [1e-30, -1e-30, 1e-30],
    ];
    for &w in &odd {
        for p in [f32::NAN, 0.0, 0.3, 1e30] {
            let (v, _) = b.residual(p, w, dir(0.5, 1.0));
            assert!(v.is_finite());
            let (v, _) = b.residual(p, dir(0.5, 1.0), w);
            assert!(v.is_finite());
            let mut r = [0.0f32; NW];
            b.reflectances_into(p, w, &mut r);
            assert!(r.iter().all(|v| v.is_finite()));
        }
    }
}

#[test]
fn validation_refuses_bad_tables() {
    type Edit = fn(&mut ShadingBasis);
    let cases: Vec<(&str, Edit, BasisError)> = vec![
        (
            "version",
            |b| b.version = 9,
            BasisError::ShadingVersion {
                found: 9,
                expected: SHADING_SCHEMA_VERSION,
            },
        ),
        (
            "diffuse",
            |b| b.family = Family::Diffuse,
            BasisError::NoLobe { family: "diffuse" },
        ),
        (
            "no params",
            |b| b.param_samples.clear(),
            BasisError::Empty {
                field: "param_samples",
            },
        ),
        (
            "NaN param",
            |b| b.param_samples[1] = f32::NAN,
            BasisError::NonFinite {
                field: "param_samples",
                index: 1,
            },
        ),
        (
            "unordered",
            |b| b.param_samples[2] = 0.1,
            BasisError::NotIncreasing {
                field: "param_samples",
                index: 2,
            },
        ),
        (
            "range",
            |b| b.param_range = [0.05, 1.0],
            BasisError::ParamRange {
                range: [0.05, 1.0],
                first: 0.05,
                last: 0.8,
            },
        ),
        (
            "log warp",
            |b| b.param_warp = ParamWarp::Log { offset: -0.05 },
            BasisError::LogWarp {
                offset: -0.05,
                first: 0.05,
            },
        ),
        (
            "grid",
            |b| b.dirs.n_theta = 1,
            BasisError::HemiGrid {
                n_theta: 1,
                n_phi: 8,
            },
        ),
        (
            "huge grid",
            |b| {
                b.dirs = HemiGrid {
                    n_theta: MAX_HEMI_DIRS,
                    n_phi: 8,
                }
            },
            BasisError::HemiGrid {
                n_theta: MAX_HEMI_DIRS,
                n_phi: 8,
            },
        ),
        (
            "overflowing grid",
            |b| {
                b.dirs = HemiGrid {
                    n_theta: usize::MAX,
                    n_phi: 8,
                }
            },
            BasisError::HemiGrid {
                n_theta: usize::MAX,
                n_phi: 8,
            },
        ),
        (
            "rank 0",
            |b| b.ranks.o = 0,
            BasisError::Rank {
                mode: "o",
                rank: 0,
                max: 24,
            },
        ),
        (
            "rank above samples",
            |b| b.ranks.h = 4,
            BasisError::Rank {
                mode: "h",
                rank: 4,
                max: 3,
            },
        ),
        (
            "u_o short",
            |b| {
                b.u_o.pop();
            },
            BasisError::Shape {
                field: "u_o",
                found: 71,
                expected: 72,
            },
        ),
        (
            "core long",
            |b| b.core.push(0.0),
            BasisError::Shape {
                field: "core",
                found: 13,
                expected: 12,
            },
        ),
        (
            "pole row",
            |b| b.u_i_pole.push(0.0),
            BasisError::Shape {
                field: "u_i_pole",
                found: 3,
                expected: 2,
            },
        ),
        (
            "reflectances",
            |b| {
                b.reflectances.pop();
            },
            BasisError::Shape {
                field: "reflectances",
                found: 287,
                expected: 288,
            },
        ),
        (
            "NaN core",
            |b| b.core[5] = f32::NAN,
            BasisError::NonFinite {
                field: "core",
                index: 5,
            },
        ),
        (
            "inf u_o_pole",
            |b| b.u_o_pole[1] = f32::INFINITY,
            BasisError::NonFinite {
                field: "u_o_pole",
                index: 1,
            },
        ),
        (
            "NaN reflectance",
            |b| b.reflectances[7] = f32::NAN,
            BasisError::NonFinite {
                field: "reflectances",
                index: 7,
            },
        ),
        (
            "negative reflectance",
            |b| b.reflectances[3] = -0.1,
            BasisError::Negative {
                field: "reflectances",
                index: 3,
            },
        ),
        (
            "negative pole",
            |b| b.reflectances_pole[2] = -1e-3,
            BasisError::Negative {
                field: "reflectances_pole",
                index: 2,
            },
        ),
        (
            "no widths",
            |b| b.split_widths_deg.clear(),
            BasisError::Empty {
                field: "split_widths_deg",
            },
        ),
        (
            "widths order",
            |b| b.split_widths_deg[2] = 7.0,
            BasisError::SplitWidth {
                index: 2,
                value: 7.0,
            },
        ),
        (
            "negative width",
            |b| b.split_widths_deg[0] = -1.0,
            BasisError::SplitWidth {
                index: 0,
                value: -1.0,
            },
        ),
        (
            "wide width",
            |b| b.split_widths_deg[3] = 90.0,
            BasisError::SplitWidth {
                index: 3,
                value: 90.0,
            },
        ),
    ];
    for (what, edit, want) in cases {
        let mut b = tiny();
        edit(&mut b);
        assert_eq!(b.validate(), Err(want), "{what}");
    }
    // NaN width: the error carries the NaN, which is not equal to itself
    let mut b = tiny();
    b.split_widths_deg[1] = f32::NAN;
    assert!(matches!(
        b.validate(),
        Err(BasisError::SplitWidth { index: 1, .. })
    ));
    let mut b = tiny();
    b.split_widths_deg = vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0];
    assert!(matches!(
        b.validate(),
        Err(BasisError::TooMany {
            field: "split_widths_deg",
            ..
        })
    ));
    let mut b = tiny();
    b.ranks = TuckerRanks {
        h: 2,
        o: MAX_SHADING_RANK + 1,
        i: 2,
    };
    assert!(matches!(
        b.validate(),
        Err(BasisError::Rank { mode: "o", .. })
    ));
    // a refused basis never panics in validation, whatever the lengths
    let mut b = tiny();
    b.u_h.clear();
    b.u_o.clear();
    b.core.clear();
    assert!(b.validate().is_err());
}
