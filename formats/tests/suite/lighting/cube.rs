//! Cube maps: texel geometry and solid angles, resampling a lat-long map, the rotation sign,
//! downsampling and lookups.

use super::*;

#[test]
fn texel_solid_angles_sum_to_four_pi() {
    for n in [1, 2, 3, 5, 8, 64, 256, 1024] {
        let per_face: f64 = face_solid_angles(n).iter().sum();
        let total = 6.0 * per_face;
        assert!(
            ((total - 4.0 * PI) / (4.0 * PI)).abs() < 1e-12,
            "{n}: {total}"
        );
        // The closed form per texel agrees with the table.
        let table = face_solid_angles(n);
        for j in 0..n {
            for i in 0..n {
                let one = texel_solid_angle(n, i, j);
                assert!((one - table[j * n + i]).abs() <= 1e-12 * one, "{n} {i} {j}");
            }
        }
        // The solid angle per unit face area is (1 + a^2 + b^2)^(-3/2): the corner texel
        // is smaller than the central one by about that ratio at their centres.
        if n >= 64 {
            let density = |k: usize| {
                let a = 2.0 * (k as f64 + 0.5) / n as f64 - 1.0;
                (1.0 + 2.0 * a * a).powf(-1.5)
            };
            let ratio = table[(n / 2) * n + n / 2] / table[0];
            let want = density(n / 2) / density(0);
            assert!((ratio / want - 1.0).abs() < 1e-3, "{n}: {ratio} vs {want}");
        }
    }
    let ones = CubeMap::constant(16, [1.0; 3]).unwrap();
    for c in ones.integral() {
        assert!((c - 4.0 * PI).abs() < 1e-12);
    }
}

#[test]
fn every_texel_centre_maps_back_to_its_texel() {
    for n in (1..=9).chain([16, 64]) {
        for face in Face::ALL {
            for j in 0..n {
                for i in 0..n {
                    let d = texel_centre_direction(n, face, i, j);
                    assert!((dot(d, d) - 1.0).abs() < 1e-14);
                    assert_eq!(direction_to_texel(n, d), (face, i, j), "{n}");
                    let (f2, s, t) = direction_to_face_st(d);
                    assert_eq!(f2, face);
                    assert!((s - (i as f64 + 0.5) / n as f64).abs() < 1e-12);
                    assert!((t - (j as f64 + 0.5) / n as f64).abs() < 1e-12);
                    assert_eq!(texel_index(n, face, i, j), (face.index() * n + j) * n + i);
                }
            }
        }
    }
}

#[test]
fn every_face_has_the_opengl_orientation() {
    // (face, centre, direction of growing s, direction of growing t) from the OpenGL table:
    // +X (1, -b, -a), -X (-1, -b, a), +Y (a, 1, b), -Y (a, -1, -b), +Z (a, -b, 1),
    // -Z (-a, -b, -1).
    let table = [
        (
            Face::PosX,
            [1.0, 0.0, 0.0],
            [0.0, 0.0, -1.0],
            [0.0, -1.0, 0.0],
        ),
        (
            Face::NegX,
            [-1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, -1.0, 0.0],
        ),
        (
            Face::PosY,
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
        ),
        (
            Face::NegY,
            [0.0, -1.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, -1.0],
        ),
        (
            Face::PosZ,
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
        ),
        (
            Face::NegZ,
            [0.0, 0.0, -1.0],
            [-1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
        ),
    ];
    let eps = 1e-6;
    for (face, centre, s_dir, t_dir) in table {
        assert_eq!(
            face.index(),
            Face::ALL.iter().position(|&f| f == face).unwrap()
        );
        let c = face_st_to_direction(face, 0.5, 0.5);
        assert!(close3(c, centre, 1e-15), "{}", face.name());
        let ds = face_st_to_direction(face, 0.5 + eps, 0.5);
        let dt = face_st_to_direction(face, 0.5, 0.5 + eps);
        let grad_s = [0, 1, 2].map(|k| (ds[k] - c[k]) / (2.0 * eps));
        let grad_t = [0, 1, 2].map(|k| (dt[k] - c[k]) / (2.0 * eps));
        assert!(close3(grad_s, s_dir, 1e-5), "{}: s {grad_s:?}", face.name());
        assert!(close3(grad_t, t_dir, 1e-5), "{}: t {grad_t:?}", face.name());
        // Seen from outside the cube every face is an unmirrored image: s x t points inwards.
        let cross = [
            s_dir[1] * t_dir[2] - s_dir[2] * t_dir[1],
            s_dir[2] * t_dir[0] - s_dir[0] * t_dir[2],
            s_dir[0] * t_dir[1] - s_dir[1] * t_dir[0],
        ];
        assert!(close3(cross, centre.map(|x| -x), 0.0), "{}", face.name());
    }
    // The top-left corner of +X is (1, 1, 1) / sqrt(3). The faces form the horizontal cross
    // of docs/lighting.md: -X +Z +X -Z in a row (each right edge is the next face's left
    // edge, and -Z wraps to -X), +Y above +Z and -Y below it, touching edges with the same
    // parameter.
    let r3 = 1.0 / 3f64.sqrt();
    assert!(close3(
        face_st_to_direction(Face::PosX, 0.0, 0.0),
        [r3, r3, r3],
        1e-15
    ));
    let row = [Face::NegX, Face::PosZ, Face::PosX, Face::NegZ];
    for k in 0..=10 {
        let p = k as f64 / 10.0;
        for w in 0..4 {
            let (left, right) = (row[w], row[(w + 1) % 4]);
            let a = face_st_to_direction(left, 1.0, p);
            let b = face_st_to_direction(right, 0.0, p);
            assert!(close3(a, b, 1e-15), "{left:?} | {right:?} at {p}");
        }
        let a = face_st_to_direction(Face::PosZ, p, 0.0);
        let b = face_st_to_direction(Face::PosY, p, 1.0);
        assert!(close3(a, b, 1e-15));
        let a = face_st_to_direction(Face::PosZ, p, 1.0);
        let b = face_st_to_direction(Face::NegY, p, 0.0);
        assert!(close3(a, b, 1e-15));
    }
}

#[test]
fn directions_round_trip_through_face_coordinates() {
    let mut g = Gen(7);
    for _ in 0..10_000 {
        let d = g.direction();
        let (face, s, t) = direction_to_face_st(d);
        assert!((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t));
        assert!(close3(face_st_to_direction(face, s, t), d, 1e-14), "{d:?}");
        // Length does not matter.
        assert_eq!(direction_to_face_st(d.map(|x| 3.0 * x)).0, face);
    }
    // Ties on edges and corners resolve to X before Y before Z, deterministically.
    assert_eq!(direction_to_face_st([1.0, 1.0, 0.0]).0, Face::PosX);
    assert_eq!(direction_to_face_st([0.0, -1.0, 1.0]).0, Face::NegY);
    assert_eq!(direction_to_face_st([-1.0, 1.0, -1.0]).0, Face::NegX);
}

#[test]
fn resampling_a_constant_gives_the_constant() {
    let value = [0.5f32, 1.0, 2.0];
    let map = vec![value; 64 * 32];
    for n in [1, 2, 4, 8, 16] {
        for rotation in [0.0, 33.0, -270.0] {
            let cube = CubeMap::from_latlong(&map, 64, 32, n, rotation).unwrap();
            assert_eq!(cube.size(), n);
            for t in cube.texels() {
                for c in 0..3 {
                    assert!(
                        (t[c] - value[c]).abs() <= 1e-6 * value[c],
                        "{n} {rotation}: {t:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn resampling_a_smooth_function_gives_its_texel_averages() {
    // The radiance (y + 2, x + 2, z + 2) in a 512 x 256 map. Each cube texel must be the
    // function's average over the texel; the error comes from the lat-long texels (bilinear
    // interpolation of a smooth function, about h^2 / 8 * |f''| with h = pi / 256) and is
    // below 1e-4 (measured: 2e-5).
    let f = |d: [f64; 3]| [d[1] + 2.0, d[0] + 2.0, d[2] + 2.0];
    let map = latlong_from_fn(512, 256, f);
    for (n, rotation) in [(8usize, 0.0), (64, 0.0), (8, 57.0)] {
        let cube = CubeMap::from_latlong(&map, 512, 256, n, rotation).unwrap();
        // The rotated environment's radiance from d is f(R_y(-angle) d).
        let back = rotation_y(-rotation);
        let g = |d: [f64; 3]| f(mat_vec(&back, d));
        let mut worst: f64 = 0.0;
        let step = if n > 8 { 7 } else { 1 };
        for face in Face::ALL {
            for j in (0..n).step_by(step) {
                for i in (0..n).step_by(step) {
                    let want = texel_average(n, face, i, j, 512 / n, &g);
                    let got = f64x3(cube.get(face, i, j).unwrap());
                    for c in 0..3 {
                        worst = worst.max((got[c] - want[c]).abs());
                    }
                }
            }
        }
        assert!(worst < 1e-4, "side {n}, rotation {rotation}: {worst}");
    }
}

#[test]
fn rotating_by_plus_90_degrees_turns_minus_z_to_minus_x() {
    // A map bright only towards -Z. The right-hand rule about +Y takes -Z to -X (and +Z to
    // +X): rotated by +90 degrees the bright spot is towards -X, by -90 towards +X.
    let spot = |d: [f64; 3]| {
        let v = (-d[2]).max(0.0).powi(16);
        [v, v, v]
    };
    let map = latlong_from_fn(256, 128, spot);
    let brightest = |cube: &CubeMap| -> [f64; 3] {
        let (k, _) = cube
            .texels()
            .iter()
            .enumerate()
            .max_by(|a, b| a.1[0].total_cmp(&b.1[0]))
            .unwrap();
        let n = cube.size();
        let face = Face::from_index(k / (n * n)).unwrap();
        texel_centre_direction(n, face, k % n, (k / n) % n)
    };
    let n = 16;
    let d0 = brightest(&CubeMap::from_latlong(&map, 256, 128, n, 0.0).unwrap());
    assert!(d0[2] < -0.99, "{d0:?}");
    let d = brightest(&CubeMap::from_latlong(&map, 256, 128, n, 90.0).unwrap());
    assert!(d[0] < -0.99, "+90: {d:?}");
    let d = brightest(&CubeMap::from_latlong(&map, 256, 128, n, -90.0).unwrap());
    assert!(d[0] > 0.99, "-90: {d:?}");
    // The matrix agrees: R_y(90) takes +Z to +X and -Z to -X.
    assert!(close3(
        mat_vec(&rotation_y(90.0), [0.0, 0.0, 1.0]),
        [1.0, 0.0, 0.0],
        1e-15
    ));
    // A full turn is no turn.
    let a = CubeMap::from_latlong(&map, 256, 128, 8, 0.0).unwrap();
    let b = CubeMap::from_latlong(&map, 256, 128, 8, 360.0).unwrap();
    for (x, y) in a.texels().iter().zip(b.texels()) {
        assert!(close3(f64x3(*x), f64x3(*y), 1e-5));
    }
}

#[test]
fn downsampling_preserves_the_integral() {
    let mut cube = random_cube(64, 3);
    let before = cube.integral();
    while cube.size() > 1 {
        cube = cube.downsample().unwrap();
        let now = cube.integral();
        for c in 0..3 {
            assert!(
                (now[c] - before[c]).abs() <= 1e-6 * before[c],
                "side {}: {now:?} vs {before:?}",
                cube.size()
            );
        }
    }
    // 64 -> 8 -> 2, the sides the lighting bases use; a constant stays that constant.
    let c = CubeMap::constant(64, [3.0, 2.0, 1.0]).unwrap();
    let c8 = c
        .downsample()
        .unwrap()
        .downsample()
        .unwrap()
        .downsample()
        .unwrap();
    let c2 = c8.downsample().unwrap().downsample().unwrap();
    assert_eq!((c8.size(), c2.size()), (8, 2));
    for t in c8.texels().iter().chain(c2.texels()) {
        assert!(close3(f64x3(*t), [3.0, 2.0, 1.0], 1e-6));
    }
    // Each parent texel is the solid-angle-weighted mean of its four children.
    let fine = random_cube(4, 9);
    let coarse = fine.downsample().unwrap();
    let w = face_solid_angles(4);
    let parent = coarse.get(Face::NegY, 1, 0).unwrap();
    let mut acc = [0.0; 3];
    let mut wsum = 0.0;
    for (i, j) in [(2, 0), (3, 0), (2, 1), (3, 1)] {
        let v = fine.get(Face::NegY, i, j).unwrap();
        for c in 0..3 {
            acc[c] += w[j * 4 + i] * v[c] as f64;
        }
        wsum += w[j * 4 + i];
    }
    assert!(close3(f64x3(parent), acc.map(|a| a / wsum), 1e-6));
}

#[test]
fn lookups_hit_texels_and_interpolate_between_centres() {
    let cube = random_cube(8, 5);
    for face in Face::ALL {
        for j in 0..8 {
            for i in 0..8 {
                let d = texel_centre_direction(8, face, i, j);
                let v = cube.get(face, i, j).unwrap();
                assert_eq!(cube.lookup_nearest(d), v);
                assert!(close3(f64x3(cube.lookup_bilinear(d)), f64x3(v), 1e-6));
            }
        }
    }
    // Half-way between the centres of (2, 3) and (3, 3) on +Z: the mean of the two.
    let d = face_st_to_direction(Face::PosZ, 3.0 / 8.0, 3.5 / 8.0);
    let a = f64x3(cube.get(Face::PosZ, 2, 3).unwrap());
    let b = f64x3(cube.get(Face::PosZ, 3, 3).unwrap());
    let mid = [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]));
    assert!(close3(f64x3(cube.lookup_bilinear(d)), mid, 1e-6));
    // Across a face edge the lookup blends the two faces' edge texels: on the edge between
    // +Z (its last column) and +X (its first column), at the height of row 3's centres, both
    // sides give the mean of the two texels, and points just either side agree.
    let edge_mean = {
        let a = f64x3(cube.get(Face::PosZ, 7, 3).unwrap());
        let b = f64x3(cube.get(Face::PosX, 0, 3).unwrap());
        [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]))
    };
    let on_edge = face_st_to_direction(Face::PosZ, 1.0, 3.5 / 8.0);
    assert!(close3(
        f64x3(cube.lookup_bilinear(on_edge)),
        edge_mean,
        1e-6
    ));
    let just_z = face_st_to_direction(Face::PosZ, 1.0 - 1e-9, 3.5 / 8.0);
    let just_x = face_st_to_direction(Face::PosX, 1e-9, 3.5 / 8.0);
    assert_eq!(direction_to_face_st(just_z).0, Face::PosZ);
    assert_eq!(direction_to_face_st(just_x).0, Face::PosX);
    assert!(close3(f64x3(cube.lookup_bilinear(just_z)), edge_mean, 1e-6));
    assert!(close3(f64x3(cube.lookup_bilinear(just_x)), edge_mean, 1e-6));
    // The lookup is continuous everywhere: along a circle crossing four faces, steps of about
    // 1/80 of a texel change it by at most about 1/50 of the largest value (a face edge that
    // clamped instead of blending would jump by a texel difference, typically ~1).
    let max_value = cube
        .texels()
        .iter()
        .flat_map(|t| t.iter())
        .fold(0.0f32, |m, &v| m.max(v)) as f64;
    let mut prev = f64x3(cube.lookup_bilinear([1.0, 0.3, 0.0]));
    for k in 1..=2000 {
        let phi = 2.0 * PI * k as f64 / 2000.0;
        let d = [phi.cos(), 0.3, phi.sin()];
        let v = f64x3(cube.lookup_bilinear(d));
        assert!(
            close3(v, prev, 0.05 * max_value),
            "{k}: {v:?} after {prev:?}"
        );
        prev = v;
    }
    // A zero direction does not panic.
    let _ = cube.lookup_bilinear([0.0; 3]);
    let _ = cube.lookup_nearest([f64::NAN; 3]);
}

#[test]
fn bad_input_is_refused_with_a_reason() {
    let map = vec![[1.0f32; 3]; 8 * 4];
    assert!(matches!(
        CubeMap::from_latlong(&map, 8, 3, 4, 0.0),
        Err(LightingError::LengthMismatch {
            expected: 24,
            got: 32,
            ..
        })
    ));
    assert!(matches!(
        CubeMap::from_latlong(&map, 0, 4, 4, 0.0),
        Err(LightingError::ZeroSize { .. })
    ));
    assert!(matches!(
        CubeMap::from_latlong(&map, 8, 4, 0, 0.0),
        Err(LightingError::ZeroSize { .. })
    ));
    assert!(matches!(
        CubeMap::from_latlong(&map, 8, 4, 1 << 20, 0.0),
        Err(LightingError::TooLarge { .. })
    ));
    assert!(matches!(
        CubeMap::from_latlong(&map, 8, 4, 4, f64::NAN),
        Err(LightingError::InvalidParameter { .. })
    ));
    assert!(matches!(
        CubeMap::from_latlong(&map, usize::MAX, 2, 4, 0.0),
        Err(LightingError::TooLarge { .. })
    ));
    let mut bad = map.clone();
    bad[17][2] = f32::INFINITY;
    let e = CubeMap::from_latlong(&bad, 8, 4, 4, 0.0).unwrap_err();
    assert!(
        matches!(e, LightingError::NonFinite { index: 17, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("not finite"), "{e}");
    assert!(CubeMap::from_channels(1, &[0.0; 6], &[0.0; 6], &[0.0; 5]).is_err());
    assert!(CubeMap::from_fn(2, |_| [f64::NAN, 0.0, 0.0]).is_err());
}
