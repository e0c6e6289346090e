//! BRDF bases (docs/brdf-basis.md): PCA basis, persistence, runtime evaluation, numerical
//! stability, reproducibility, Tucker. Reduced grids keep every test fast.
#![allow(clippy::needless_range_loop)]

use faer::Mat;
use glam::Vec3;
use prt_bake::basis::grid::{cosine_weights, lobe_f64, tabulate};
use prt_bake::basis::pca::{dot_w, PcaBuilder, PcaOptions};
use prt_bake::basis::select::{family_report, select_count};
use prt_bake::basis::{build_basis, tucker, BasisConfig, FamilySpec};
use prt_bake::brdf::{Family, Lobe};
use prt_formats::basis::{AngularGrid, BrdfBasis, GridKind, GridSpec};

/// A small half/difference grid (768 nodes) keeps the tests fast.
const SMALL: GridSpec = GridSpec {
    kind: GridKind::HalfDiff,
    dims: AngularGrid {
        n_theta_i: 16,
        n_theta_o: 12,
        n_phi: 4,
    },
};

/// A small thesis-style grid (2000 nodes).
const SMALL_ANGLES: GridSpec = GridSpec {
    kind: GridKind::Angles,
    dims: AngularGrid {
        n_theta_i: 10,
        n_theta_o: 10,
        n_phi: 20,
    },
};

fn small_config(family: Family, nb: usize) -> BasisConfig {
    let mut c = BasisConfig::new(family, nb).unwrap().with_grid(SMALL);
    c.param_samples = 32;
    c.options.minimax_iters = 8;
    c
}

#[test]
fn lobe_tables_match_the_brdf_module() {
    for (family, p) in [
        (Family::BlinnPhong, 1.0),
        (Family::BlinnPhong, 150.0),
        (Family::Ggx, 0.05),
        (Family::Ggx, 0.7),
    ] {
        for &(ti, to, ph) in &[
            (0.1f64, 0.2f64, 3.0f64),
            (0.7, 0.6, 3.1),
            (1.2, 0.3, 1.0),
            (1.5, 1.5, 3.1),
        ] {
            let wi = Vec3::new(ti.sin() as f32, 0.0, ti.cos() as f32);
            let wo = Vec3::new(
                (to.sin() * ph.cos()) as f32,
                (to.sin() * ph.sin()) as f32,
                to.cos() as f32,
            );
            let a = family.specular_lobe(p as f32, wo, wi) as f64;
            let b = lobe_f64(family, p, ti, to, ph);
            assert!(
                (a - b).abs() <= 2e-4 * b.abs().max(1e-3),
                "{family:?} {p}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn basis_is_orthonormal_and_errors_drop_with_nb() {
    let cfg = small_config(Family::BlinnPhong, 6);
    let b = build_basis(cfg.clone()).unwrap();
    assert_eq!(b.num_bases(), 6);
    let w = cosine_weights(&SMALL);
    let d = vec![std::f64::consts::FRAC_1_PI; SMALL.len()];
    for (i, x) in b.model.bases.iter().enumerate() {
        assert!(x.iter().all(|v| v.is_finite()));
        assert!(
            dot_w(&w, x, &d).abs() < 1e-9,
            "basis {i} not orthogonal to Lambert"
        );
        for (j, y) in b.model.bases.iter().enumerate() {
            let want = if i == j { 1.0 } else { 0.0 };
            assert!((dot_w(&w, x, y) - want).abs() < 1e-9);
        }
        // sign convention: largest-magnitude entry positive
        let m = x
            .iter()
            .copied()
            .fold(0.0f64, |a, v| if v.abs() > a.abs() { v } else { a });
        assert!(m > 0.0);
    }
    let counts = [2, 4, 6, 8];
    let (rep, _) = family_report(&cfg, &counts, 4, 20).unwrap();
    for w in rep.rows.windows(2) {
        assert!(
            w[1].ours.mean < w[0].ours.mean,
            "{:?}",
            rep.rows.iter().map(|r| r.ours.mean).collect::<Vec<_>>()
        );
    }
    assert_eq!(select_count(&rep, 1.0, false), Some(2));
    assert_eq!(select_count(&rep, 1e-12, false), None);
}

#[test]
fn persisted_basis_round_trips_and_interpolates() {
    let b = build_basis(small_config(Family::Ggx, 5)).unwrap();
    let p = b.to_persisted();
    p.validate().unwrap();
    let json = serde_json::to_string(&p).unwrap();
    let q: BrdfBasis = serde_json::from_str(&json).unwrap();
    assert_eq!(p, q);
    // coefficients at a sample equal the stored projection
    for j in [0, 7, 31] {
        let (c, clamped) = p.coefficients(p.param_samples[j]);
        assert!(!clamped);
        for k in 0..p.num_bases {
            assert!((c[k] as f64 - b.coeffs[j][k]).abs() < 1e-5 * b.coeffs[j][k].abs().max(1.0));
        }
    }
    // outside the range: clamped to the end, flagged
    let (c, clamped) = p.coefficients(5.0);
    assert!(clamped);
    assert_eq!(c, p.coefficients(1.0).0);
    assert!(p.coefficients(0.001).1);
    // eval_all reproduces the tables at nodes
    let g = p.grid;
    assert_eq!(p.grid_spec(), SMALL);
    let mut out = vec![0.0f32; p.num_bases];
    let mut checked = 0;
    for i in 0..g.n_theta_i {
        for o in 0..g.n_theta_o {
            for k in 0..g.n_phi {
                let nd = p.grid_spec().node(i, o, k);
                if nd.cos_theta_i.min(nd.cos_theta_o) < 1e-3 {
                    continue;
                }
                checked += 1;
                // vectors (the baker's entry point): near the mirror direction an f32 cos_phi
                // close to -1 resolves phi only to ~3e-4 rad, too coarse for theta_h nodes
                // 0.006 rad from the pole
                let (si, so) = (
                    (1.0 - nd.cos_theta_i.powi(2)).max(0.0).sqrt(),
                    (1.0 - nd.cos_theta_o.powi(2)).max(0.0).sqrt(),
                );
                let sp = (1.0 - nd.cos_phi.powi(2)).max(0.0).sqrt();
                let wi = [si as f32, 0.0, nd.cos_theta_i as f32];
                let wo = [
                    (so * nd.cos_phi) as f32,
                    (so * sp) as f32,
                    nd.cos_theta_o as f32,
                ];
                p.eval_all_local(wi, wo, &mut out);
                let n = g.index(i, o, k);
                for bb in 0..p.num_bases {
                    let t = p.tables[n * p.num_bases + bb];
                    assert!(
                        (out[bb] - t).abs() <= 2e-3 * t.abs().max(1.0),
                        "node ({i},{o},{k}) basis {bb}: {} vs {t}",
                        out[bb]
                    );
                }
            }
        }
    }
    assert!(checked > g.len() / 3, "{checked}");
    // diffuse material: c = (Kd, 0, ..)
    let (m, _) = p.material_coefficients([0.2, 0.4, 0.6], [0.0; 3], 0.3);
    assert_eq!(m[0], [0.2, 0.4, 0.6]);
    assert!(m[1..].iter().all(|c| *c == [0.0; 3]));
}

/// The thesis' `angles` grid kind (schema 1's only grid) still builds, persists and
/// evaluates: `eval_all` at the node angles reproduces the tables.
#[test]
fn angles_grid_kind_still_builds_and_evaluates() {
    let cfg = small_config(Family::Ggx, 4).with_grid(SMALL_ANGLES);
    let p = build_basis(cfg).unwrap().to_persisted();
    p.validate().unwrap();
    assert_eq!(p.grid_spec(), SMALL_ANGLES);
    let q: BrdfBasis = serde_json::from_str(&serde_json::to_string(&p).unwrap()).unwrap();
    assert_eq!(p, q);
    let g = p.grid;
    let mut out = vec![0.0f32; p.num_bases];
    for &(i, o, k) in &[(0usize, 0usize, 0usize), (3, 4, 5), (9, 9, 19), (9, 2, 7)] {
        let (ti, to, ph) = (
            AngularGrid::theta(g.n_theta_i, i),
            AngularGrid::theta(g.n_theta_o, o),
            AngularGrid::phi(g.n_phi, k),
        );
        p.eval_all(ti.cos() as f32, to.cos() as f32, ph.cos() as f32, &mut out);
        let n = g.index(i, o, k);
        for bb in 0..p.num_bases {
            let t = p.tables[n * p.num_bases + bb];
            assert!(
                (out[bb] - t).abs() <= 2e-3 * t.abs().max(1.0),
                "node ({i},{o},{k}) basis {bb}: {} vs {t}",
                out[bb]
            );
        }
    }
}

#[test]
fn rank_deficient_input_gives_basis_of_true_rank() {
    let params = [5.0, 20.0, 80.0];
    let l = tabulate(Family::BlinnPhong, &SMALL, &params);
    let n = SMALL.len();
    // columns: l0, l0, l1, l0 + l1, 2 l2, l2 (rank 3)
    let cols: Vec<Vec<f64>> = vec![
        l.col_as_slice(0).to_vec(),
        l.col_as_slice(0).to_vec(),
        l.col_as_slice(1).to_vec(),
        l.col_as_slice(0)
            .iter()
            .zip(l.col_as_slice(1))
            .map(|(a, b)| a + b)
            .collect(),
        l.col_as_slice(2).iter().map(|v| 2.0 * v).collect(),
        l.col_as_slice(2).to_vec(),
    ];
    let m = Mat::from_fn(n, cols.len(), |i, j| cols[j][i]);
    for opts in [PcaOptions::ours(), PcaOptions::thesis()] {
        let b = PcaBuilder::new(m.as_ref(), SMALL, opts.clone()).unwrap();
        let model = b.build(8).unwrap();
        assert_eq!(model.rank, 3, "{opts:?}");
        assert_eq!(model.num_bases(), 4);
        for x in &model.bases {
            assert!(x.iter().all(|v| v.is_finite()));
        }
        for c in &cols {
            let r = model.reconstruct(&model.project(c));
            let e = prt_bake::basis::pca::rel_err_w(&model.weights, c, &r);
            assert!(e < 1e-8, "{e}");
        }
    }
    // all-zero and non-finite input
    let z = Mat::<f64>::zeros(n, 3);
    let model = PcaBuilder::new(z.as_ref(), SMALL, PcaOptions::ours())
        .unwrap()
        .build(4)
        .unwrap();
    assert_eq!(model.num_bases(), 1);
    let mut bad = m.clone();
    bad[(3, 2)] = f64::NAN;
    assert!(PcaBuilder::new(bad.as_ref(), SMALL, PcaOptions::ours()).is_err());
}

#[test]
fn evaluation_is_continuous_at_grazing_angles_and_the_pole() {
    let p = build_basis(small_config(Family::BlinnPhong, 4))
        .unwrap()
        .to_persisted();
    let nb = p.num_bases;
    let (mut a, mut b) = (vec![0.0f32; nb], vec![0.0f32; nb]);
    // grazing: cos -> 0 (and slightly negative, clamped)
    for cp in [-1.0f32, -0.3, 0.5, 1.0] {
        p.eval_all(0.0, 0.5, cp, &mut a);
        p.eval_all(1e-6, 0.5, cp, &mut b);
        for k in 0..nb {
            assert!(a[k].is_finite() && (a[k] - b[k]).abs() <= 1e-3 * a[k].abs().max(1.0));
        }
        p.eval_all(-0.2, 0.5, cp, &mut b);
        assert_eq!(a, b);
    }
    // pole: theta_i -> 0, phi arbitrary
    let ci = (1e-4f32).cos();
    p.eval_all(ci, 0.6, 1.0, &mut a);
    for cp in [-1.0f32, 0.0, 0.7] {
        p.eval_all(ci, 0.6, cp, &mut b);
        for k in 0..nb {
            assert!(
                (a[k] - b[k]).abs() <= 1e-3 * a[k].abs().max(1.0),
                "pole basis {k}: {} vs {}",
                a[k],
                b[k]
            );
        }
    }
    // NaN input does not poison the output
    p.eval_all(f32::NAN, 0.5, f32::NAN, &mut a);
    assert!(a.iter().all(|v| v.is_finite()));
    // local-frame entry point agrees with the cosine one
    let wi = [0.3f32, 0.4, (1.0f32 - 0.25).sqrt()];
    let wo = [-0.6f32, 0.0, 0.8];
    p.eval_all_local(wi, wo, &mut a);
    let cphi = (0.3 * -0.6) / (0.5 * 0.6);
    p.eval_all(wi[2], wo[2], cphi, &mut b);
    for k in 0..nb {
        assert!((a[k] - b[k]).abs() < 1e-5 * a[k].abs().max(1.0));
    }
    p.eval_all_local([0.0, 0.0, -1.0], wo, &mut a);
    assert!(a.iter().all(|v| *v == 0.0));
}

#[test]
fn signed_bases_reconstruct_close_to_non_negative() {
    let cfg = small_config(Family::BlinnPhong, 6);
    let (rep, p) = family_report(&cfg, &[6], 6, 20).unwrap();
    // some basis values are negative; evaluation handles them
    assert!(p.tables.iter().any(|v| *v < 0.0));
    let neg = &rep.rows[0].negativity;
    assert!(neg.min_rel <= 0.0 && neg.min_rel > -0.2, "{neg:?}");
    assert!(neg.neg_mass < 0.05);
    // linear in the coefficients, including negative ones
    let c = [0.5f32, -2.0, 1.5, -0.25, 0.0, 3.0];
    let mut v = vec![0.0f32; 6];
    p.eval_all(0.8, 0.6, -0.9, &mut v);
    let direct: f32 = v.iter().zip(&c).map(|(a, b)| a * b).sum();
    assert!((p.reconstruct(&c, 0.8, 0.6, -0.9) - direct).abs() < 1e-5 * direct.abs().max(1.0));
}

#[test]
fn builds_are_bit_reproducible_across_runs_and_thread_counts() {
    let cfg = small_config(Family::Ggx, 6);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| build_basis(cfg.clone()).unwrap().to_persisted())
    };
    let a = run(1);
    let b = run(2);
    let c = run(3);
    assert!(a
        .tables
        .iter()
        .zip(&b.tables)
        .all(|(x, y)| x.to_bits() == y.to_bits()));
    assert!(a
        .coefficients
        .iter()
        .zip(&c.coefficients)
        .all(|(x, y)| x.to_bits() == y.to_bits()));
    assert_eq!(a, b);
    assert_eq!(a, c);
}

#[test]
fn tucker_split_lowers_the_error() {
    let spec = FamilySpec::default_for(Family::BlinnPhong).unwrap();
    let r = tucker::tucker_report(
        spec,
        8,
        tucker::HemiGrid {
            n_theta: 4,
            n_phi: 12,
        },
        &[1, 3],
        &[4, 8],
    )
    .unwrap();
    assert_eq!(r.cells.len(), 4);
    for c in &r.cells {
        assert!(c.plain.is_finite() && c.split.is_finite());
        assert!(c.split < c.plain, "{c:?}");
    }
    // more rank, less error
    let e = |nh: usize, nd: usize| {
        r.cells
            .iter()
            .find(|c| c.n_h == nh && c.n_dir == nd)
            .unwrap()
            .plain
    };
    assert!(e(3, 8) <= e(1, 4));
}

/// A GGX basis on the half/difference grid is finite for every input, including exactly
/// grazing, both-grazing mirror pairs, NaN and out-of-range cosines, and continuous as a
/// direction approaches the horizon or the pole.
#[test]
fn ggx_half_diff_basis_is_finite_and_continuous_at_grazing() {
    let p = build_basis(small_config(Family::Ggx, 6))
        .unwrap()
        .to_persisted();
    let nb = p.num_bases;
    let (mut a, mut b) = (vec![0.0f32; nb], vec![0.0f32; nb]);
    let vals = [-1.0f32, 0.0, 1e-7, 1e-4, 1e-2, 0.3, 1.0, 1.2, f32::NAN];
    for &ci in &vals {
        for &co in &vals {
            for cp in [-1.0f32, -0.999, 0.0, 0.5, 1.0, f32::NAN] {
                p.eval_all(ci, co, cp, &mut a);
                assert!(a.iter().all(|v| v.is_finite()), "{ci} {co} {cp}: {a:?}");
            }
        }
    }
    let close = |a: &[f32], b: &[f32], tol: f32| {
        let scale = a.iter().fold(1.0f32, |m, v| m.max(v.abs()));
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol * scale)
    };
    for co in [0.0f32, 1e-3, 0.2, 0.9] {
        for cp in [-1.0f32, -0.5, 0.5] {
            // wi -> horizon
            p.eval_all(0.0, co, cp, &mut a);
            p.eval_all(1e-6, co, cp, &mut b);
            assert!(close(&a, &b, 1e-3), "co {co} cp {cp}: {a:?} vs {b:?}");
            // reciprocity of the folded grid: swapping wi and wo changes nothing
            p.eval_all(0.4, co, cp, &mut a);
            p.eval_all(co, 0.4, cp, &mut b);
            assert!(close(&a, &b, 1e-3), "swap co {co} cp {cp}: {a:?} vs {b:?}");
        }
    }
    // both directions grazing, in mirror configuration, from slightly above to exactly on the
    // horizon (cos theta_d -> 0 along the theta_d axis)
    let pair = |c: f32| {
        let s = (1.0 - c * c).sqrt();
        ([s, 0.0, c], [-s, 0.0, c])
    };
    let (wi, wo) = pair(1e-6);
    p.eval_all_local(wi, wo, &mut a);
    let (wi, wo) = pair(1e-5);
    p.eval_all_local(wi, wo, &mut b);
    assert!(a.iter().chain(&b).all(|v| v.is_finite()));
    assert!(close(&a, &b, 5e-3), "{a:?} vs {b:?}");
    p.eval_all_local([1.0, 0.0, 1e-30], [-1.0, 0.0, 1e-30], &mut a);
    assert!(a.iter().all(|v| v.is_finite()));
}
