//! Spherical harmonics: orthonormality, rotation, projection, and the rotation sign shared
//! with the cube maps.

use super::*;

/// Gauss–Legendre in cos(theta) x uniform phi, built here (not the library's rule).
fn test_sphere_rule(n_theta: usize, n_phi: usize) -> Vec<([f64; 3], f64)> {
    let (zs, ws) = gauss_legendre(n_theta);
    let mut out = Vec::new();
    for (z, w) in zs.iter().zip(&ws) {
        let r = (1.0 - z * z).sqrt();
        for k in 0..n_phi {
            let phi = 2.0 * PI * k as f64 / n_phi as f64;
            out.push((
                [r * phi.cos(), r * phi.sin(), *z],
                w * 2.0 * PI / n_phi as f64,
            ));
        }
    }
    out
}

#[test]
fn sh_basis_is_orthonormal() {
    for rule in [test_sphere_rule(12, 25), sphere_rule(6)] {
        let mut gram = [[0.0; SH_COUNT]; SH_COUNT];
        for (d, w) in &rule {
            let y = sh_eval(*d);
            for i in 0..SH_COUNT {
                for j in 0..SH_COUNT {
                    gram[i][j] += w * y[i] * y[j];
                }
            }
        }
        for (i, row) in gram.iter().enumerate() {
            for (j, g) in row.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((g - want).abs() < 1e-10, "{i} {j}: {g}");
            }
        }
    }
    // f32 evaluation agrees.
    let d = [0.36f32, -0.48, 0.8];
    let (a, b) = (prt_formats::lighting::sh::sh_eval_f32(d), sh_eval(f64x3(d)));
    for i in 0..SH_COUNT {
        assert!((a[i] as f64 - b[i]).abs() < 1e-6);
    }
}

fn band_energy(c: &[f64; SH_COUNT]) -> [f64; 4] {
    let mut e = [0.0; 4];
    for (i, v) in c.iter().enumerate() {
        e[sh_band(i)] += v * v;
    }
    e
}

#[test]
fn sh_rotation_keeps_band_energy_and_is_block_diagonal() {
    let mut g = Gen(41);
    for _ in 0..20 {
        let rot = ShRotation::from_matrix(g.rotation()).unwrap();
        let c = random_coeffs(&mut g);
        let (e0, e1) = (band_energy(&c), band_energy(&rot.apply(&c)));
        for l in 0..4 {
            assert!((e0[l] - e1[l]).abs() < 1e-12, "band {l}: {e0:?} vs {e1:?}");
        }
        for (i, row) in rot.matrix().iter().enumerate() {
            for (j, m) in row.iter().enumerate() {
                if sh_band(i) != sh_band(j) {
                    assert_eq!(*m, 0.0);
                }
            }
        }
    }
}

#[test]
fn sh_rotation_equals_projecting_the_rotated_function() {
    // f' (d) = f(R^T d) projected with a quadrature exact for degree 6 (f' is of degree 3).
    let mut g = Gen(43);
    let rule = test_sphere_rule(8, 17);
    for _ in 0..10 {
        let r = g.rotation();
        let rt = transpose(&r);
        let c = random_coeffs(&mut g);
        let f = |d: [f64; 3]| -> f64 { sh_eval(d).iter().zip(&c).map(|(y, c)| y * c).sum() };
        let mut projected = [0.0; SH_COUNT];
        for (d, w) in &rule {
            let v = f(mat_vec(&rt, *d));
            for (p, y) in projected.iter_mut().zip(sh_eval(*d)) {
                *p += w * v * y;
            }
        }
        let rotated = ShRotation::from_matrix(r).unwrap().apply(&c);
        for i in 0..SH_COUNT {
            assert!((rotated[i] - projected[i]).abs() < 1e-12, "{i}");
        }
    }
}

#[test]
fn sh_rotations_compose_and_a_full_turn_is_the_identity() {
    let mut g = Gen(47);
    for _ in 0..10 {
        let (r1, r2) = (g.rotation(), g.rotation());
        let m1 = ShRotation::from_matrix(r1).unwrap();
        let m2 = ShRotation::from_matrix(r2).unwrap();
        let m12 = ShRotation::from_matrix(mat_mul(&r1, &r2)).unwrap();
        let c = random_coeffs(&mut g);
        let (a, b) = (m1.apply(&m2.apply(&c)), m12.apply(&c));
        for i in 0..SH_COUNT {
            assert!((a[i] - b[i]).abs() < 1e-12);
        }
    }
    let full = ShRotation::about_y_deg(360.0).unwrap();
    let quarter = ShRotation::about_y_deg(90.0).unwrap();
    let c = random_coeffs(&mut g);
    let four = (0..4).fold(c, |acc, _| quarter.apply(&acc));
    let once = full.apply(&c);
    for i in 0..SH_COUNT {
        assert!((once[i] - c[i]).abs() < 1e-12 && (four[i] - c[i]).abs() < 1e-12);
    }
    assert_eq!(
        ShRotation::about_y_deg(33.0).unwrap(),
        ShRotation::from_matrix(rotation_y(33.0)).unwrap()
    );
}

#[test]
fn sh_rotation_about_y_matches_the_cube_map_rotation() {
    // The same sign convention on both sides: projecting an environment resampled with a
    // rotation equals rotating the projection of the unrotated one. The environment is band
    // limited (degree <= 3) so the two agree up to the resampling's and projection's
    // quadrature error (measured 2e-5; allowed 1e-3).
    let mut g = Gen(53);
    let c = random_coeffs(&mut g);
    let f = |d: [f64; 3]| {
        let v: f64 = 2.0
            + sh_eval(d)
                .iter()
                .zip(&c)
                .map(|(y, c)| 0.3 * y * c)
                .sum::<f64>();
        [v, 1.0, d[1]]
    };
    let map = latlong_from_fn(512, 256, f);
    let base = CubeMap::from_latlong(&map, 512, 256, 32, 0.0).unwrap();
    let turned = CubeMap::from_latlong(&map, 512, 256, 32, 37.0).unwrap();
    let want = ShRotation::about_y_deg(37.0)
        .unwrap()
        .apply_rgb(&project_cube(&base));
    let got = project_cube(&turned);
    for i in 0..SH_COUNT {
        for k in 0..3 {
            assert!((got[i][k] - want[i][k]).abs() < 1e-3, "{i} {k}");
        }
    }
    // And the wrong sign would not pass: rotating by -37 degrees differs clearly.
    let wrong = ShRotation::about_y_deg(-37.0)
        .unwrap()
        .apply_rgb(&project_cube(&base));
    let diff: f64 = (0..SH_COUNT).map(|i| (wrong[i][0] - got[i][0]).abs()).sum();
    assert!(diff > 1e-2, "{diff}");
}

#[test]
fn sh_projection_of_a_cube_recovers_the_coefficients() {
    let mut g = Gen(59);
    let c = random_coeffs(&mut g);
    let rgb: [[f64; 3]; SH_COUNT] = c.map(|v| [v, 2.0 * v, -v]);
    let cube = CubeMap::from_fn(64, |d| sh_reconstruct(&rgb, d)).unwrap();
    let p = project_cube(&cube);
    for i in 0..SH_COUNT {
        for k in 0..3 {
            assert!((p[i][k] - rgb[i][k]).abs() < 2e-3, "{i} {k}: {:?}", p[i]);
        }
    }
}
