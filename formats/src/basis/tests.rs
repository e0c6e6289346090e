//! Unit tests of the basis: table evaluation against exact linear tables, coefficient
//! interpolation, validation and the serialized form.

use super::eval::HD_INV_LN;
use super::*;
use std::f32::consts::{FRAC_PI_2, PI};

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
        family: crate::family::Family::BlinnPhong,
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

/// Found by fuzzing (`prt-fuzz bake-file`): the runtime checked a stored basis' coefficient
/// table with an unchecked product and not its samples' order, so `coefficients` panicked in
/// `clamp` (samples decreasing) or allocated `num_bases` values of a wrapped-around product.
#[test]
fn validate_coefficients_refuses_what_coefficients_cannot_evaluate() {
    let mut b = tiny();
    b.tables.clear();
    b.validate_coefficients().unwrap();
    assert!(b.validate().is_err());
    let mut c = b.clone();
    c.param_samples = vec![5126.0, 200.0, 300.0];
    assert!(matches!(
        c.validate_coefficients(),
        Err(BasisError::Invalid(_))
    ));
    let mut c = b.clone();
    c.num_bases = usize::MAX / 3 + 1;
    c.coefficients.clear();
    assert!(matches!(
        c.validate_coefficients(),
        Err(BasisError::Shape { .. })
    ));
    let mut c = b.clone();
    c.coefficients[2] = f32::NAN;
    assert!(c.validate_coefficients().is_err());
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
