//! The lighting bases (prt_formats::lighting): cube-map geometry and resampling, the
//! area-weighted Haar transform and sparse products, spherical harmonics and their rotation,
//! the Gaussian prefilter. Closed forms and exact quadratures, with stated tolerances.

use prt_formats::latlong;
use prt_formats::lighting::cubemap::{
    direction_to_face_st, direction_to_texel, face_rect_solid_angle, face_solid_angles,
    face_st_to_direction, rotation_y, texel_centre_direction, texel_index, texel_solid_angle,
};
use prt_formats::lighting::haar::{haar_coefficient, haar_index};
use prt_formats::lighting::prefilter::{
    kernel, kernel_integral, output_size, prefilter, prefilter_to_size, sh_factors,
};
use prt_formats::lighting::quadrature::{gauss_legendre, sphere_rule};
use prt_formats::lighting::sh::{
    project_cube, sh_band, sh_eval, sh_reconstruct, ShRotation, SH_COUNT,
};
use prt_formats::lighting::{
    CubeMap, Face, HaarCoefficient, HaarCube, HaarKind, LightingError, SparseVector,
};
use std::f64::consts::PI;

// ---------------------------------------------------------------------------------------------
// Helpers

/// A small deterministic generator (SplitMix64) for test data.
struct Gen(u64);

impl Gen {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [-1, 1).
    fn signed(&mut self) -> f64 {
        2.0 * self.unit() - 1.0
    }
    fn direction(&mut self) -> [f64; 3] {
        let z = self.signed();
        let phi = 2.0 * PI * self.unit();
        let r = (1.0 - z * z).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    }
    /// A random rotation (axis-angle with a random axis and angle).
    fn rotation(&mut self) -> [[f64; 3]; 3] {
        axis_angle(self.direction(), 2.0 * PI * self.unit())
    }
}

fn axis_angle(k: [f64; 3], angle: f64) -> [[f64; 3]; 3] {
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    let [x, y, z] = k;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

fn mat_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

fn transpose(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    [0, 1, 2].map(|i| [m[0][i], m[1][i], m[2][i]])
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn close3(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
}

fn f64x3(v: [f32; 3]) -> [f64; 3] {
    v.map(|x| x as f64)
}

/// A lat-long RGB map holding `f` at each texel centre.
fn latlong_from_fn(w: usize, h: usize, f: impl Fn([f64; 3]) -> [f64; 3]) -> Vec<[f32; 3]> {
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = latlong::texel_centre(x, y, w, h);
            let d = latlong::uv_to_direction(u, v);
            out.push(f(f64x3(d)).map(|c| c as f32));
        }
    }
    out
}

/// The exact texel average of `f` over texel (face, i, j) of side n, by an m x m sub-sample
/// grid with exact solid angles.
fn texel_average(
    n: usize,
    face: Face,
    i: usize,
    j: usize,
    m: usize,
    f: &impl Fn([f64; 3]) -> [f64; 3],
) -> [f64; 3] {
    let ns = (n * m) as f64;
    let (mut acc, mut wsum) = ([0.0; 3], 0.0);
    for l in 0..m {
        for k in 0..m {
            let (kk, ll) = ((i * m + k) as f64, (j * m + l) as f64);
            let w = face_rect_solid_angle(
                2.0 * kk / ns - 1.0,
                2.0 * (kk + 1.0) / ns - 1.0,
                2.0 * ll / ns - 1.0,
                2.0 * (ll + 1.0) / ns - 1.0,
            );
            let v = f(face_st_to_direction(face, (kk + 0.5) / ns, (ll + 0.5) / ns));
            for c in 0..3 {
                acc[c] += w * v[c];
            }
            wsum += w;
        }
    }
    acc.map(|a| a / wsum)
}

fn random_cube(n: usize, seed: u64) -> CubeMap {
    let mut g = Gen(seed);
    let texels = (0..6 * n * n)
        .map(|_| [g.unit() as f32, g.unit() as f32, (2.0 * g.unit()) as f32])
        .collect();
    CubeMap::new(n, texels).unwrap()
}

// ---------------------------------------------------------------------------------------------
// Cube-map geometry

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

// ---------------------------------------------------------------------------------------------
// Resampling, rotation, downsampling, lookups

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

// ---------------------------------------------------------------------------------------------
// Haar

#[test]
fn haar_inverse_undoes_forward() {
    for n in [1, 2, 4, 8, 64] {
        let h = HaarCube::new(n).unwrap();
        let mut g = Gen(n as u64);
        let x: Vec<f64> = (0..h.len()).map(|_| g.signed()).collect();
        let back = h.inverse_f64(&h.forward_f64(&x).unwrap()).unwrap();
        for (a, b) in x.iter().zip(&back) {
            assert!((a - b).abs() < 1e-12, "{n}: {a} vs {b}");
        }
        let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        let back = h.inverse(&h.forward(&xf).unwrap()).unwrap();
        for (a, b) in xf.iter().zip(&back) {
            assert!((a - b).abs() < 1e-5, "{n}: {a} vs {b}");
        }
    }
}

#[test]
fn haar_of_unit_texels_is_orthonormal() {
    // The function that is 1 / sqrt(solid angle) on one texel and 0 elsewhere has unit norm in
    // the solid-angle metric; the transforms of all of them must be orthonormal vectors.
    let n = 4;
    let h = HaarCube::new(n).unwrap();
    let omega = face_solid_angles(n);
    let len = h.len();
    let columns: Vec<Vec<f64>> = (0..len)
        .map(|t| {
            let mut e = vec![0.0; len];
            e[t] = 1.0 / omega[t % (n * n)].sqrt();
            h.forward_f64(&e).unwrap()
        })
        .collect();
    for a in 0..len {
        for b in 0..len {
            let d: f64 = columns[a].iter().zip(&columns[b]).map(|(x, y)| x * y).sum();
            let want = if a == b { 1.0 } else { 0.0 };
            assert!((d - want).abs() < 1e-12, "{a} {b}: {d}");
        }
    }
}

#[test]
fn haar_parseval_and_products_in_the_solid_angle_metric() {
    let n = 16;
    let h = HaarCube::new(n).unwrap();
    let omega = face_solid_angles(n);
    let mut g = Gen(11);
    let a: Vec<f64> = (0..h.len()).map(|_| g.signed()).collect();
    let b: Vec<f64> = (0..h.len()).map(|_| g.unit()).collect();
    let (wa, wb) = (h.forward_f64(&a).unwrap(), h.forward_f64(&b).unwrap());
    let integral = |x: &[f64], y: &[f64]| -> f64 {
        (0..x.len()).map(|t| x[t] * y[t] * omega[t % (n * n)]).sum()
    };
    let energy: f64 = wa.iter().map(|c| c * c).sum();
    assert!((energy - integral(&a, &a)).abs() < 1e-12 * energy);
    let prod: f64 = wa.iter().zip(&wb).map(|(x, y)| x * y).sum();
    assert!((prod - integral(&a, &b)).abs() < 1e-12 * energy);
}

#[test]
fn haar_layout_means_what_it_says() {
    // One DetailS coefficient at level 0 on +Y: the weighted values (value * sqrt(solid
    // angle)) are +1/N on the left half of the face and -1/N on the right half.
    let n = 8;
    let h = HaarCube::new(n).unwrap();
    let omega = face_solid_angles(n);
    let c = HaarCoefficient {
        face: Face::PosY,
        kind: HaarKind::DetailS,
        level: 0,
        row: 0,
        col: 0,
    };
    let idx = haar_index(n, c).unwrap();
    assert_eq!(idx, 2 * n * n + 1);
    assert_eq!(haar_coefficient(n, idx), Some(c));
    let mut coeffs = vec![0.0; h.len()];
    coeffs[idx] = 1.0;
    let v = h.inverse_f64(&coeffs).unwrap();
    for face in Face::ALL {
        for j in 0..n {
            for i in 0..n {
                let k = texel_index(n, face, i, j);
                let weighted = v[k] * omega[j * n + i].sqrt();
                let want = match (face, i < n / 2) {
                    (Face::PosY, true) => 1.0 / n as f64,
                    (Face::PosY, false) => -1.0 / n as f64,
                    _ => 0.0,
                };
                assert!(
                    (weighted - want).abs() < 1e-14,
                    "{face:?} {i} {j}: {weighted}"
                );
            }
        }
    }
    // The finest DetailT of square (row 1, col 2) on -Z: +1/2 on texel row 2, -1/2 on row 3,
    // columns 4 and 5 only.
    let c = HaarCoefficient {
        face: Face::NegZ,
        kind: HaarKind::DetailT,
        level: 2,
        row: 1,
        col: 2,
    };
    let mut coeffs = vec![0.0; h.len()];
    coeffs[haar_index(n, c).unwrap()] = 1.0;
    let v = h.inverse_f64(&coeffs).unwrap();
    for j in 0..n {
        for i in 0..n {
            let k = texel_index(n, Face::NegZ, i, j);
            let weighted = v[k] * omega[j * n + i].sqrt();
            let want = match (i, j) {
                (4 | 5, 2) => 0.5,
                (4 | 5, 3) => -0.5,
                _ => 0.0,
            };
            assert!((weighted - want).abs() < 1e-14, "{i} {j}: {weighted}");
        }
    }
    // A map constant on each face has an exact scaling coefficient: value * sum sqrt(omega) / N.
    let face_values = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    let x: Vec<f64> = (0..h.len()).map(|k| face_values[k / (n * n)]).collect();
    let w = h.forward_f64(&x).unwrap();
    let root_sum: f64 = omega.iter().map(|o| o.sqrt()).sum();
    for (f, v) in face_values.iter().enumerate() {
        assert!((w[f * n * n] - v * root_sum / n as f64).abs() < 1e-12);
    }
}

#[test]
fn keep_k_keeps_the_largest_and_reconstructs_maps_it_holds() {
    let n = 8;
    let h = HaarCube::new(n).unwrap();
    let len = h.len();
    let mut g = Gen(21);
    // A lighting with exactly k = 12 non-zero wavelet terms (distinct magnitudes).
    let mut coeffs = vec![0.0f32; len];
    let mut chosen = Vec::new();
    while chosen.len() < 12 {
        let i = (g.next_u64() % len as u64) as usize;
        if !chosen.contains(&i) {
            chosen.push(i);
            coeffs[i] =
                ((1.0 + chosen.len() as f64) * if g.unit() < 0.5 { -1.0 } else { 1.0 }) as f32;
        }
    }
    let map = h.inverse(&coeffs).unwrap();
    let w = h.forward(&map).unwrap();
    let kept = SparseVector::keep_largest(&w, 12).unwrap();
    chosen.sort_unstable();
    assert_eq!(
        kept.indices(),
        chosen.iter().map(|&i| i as u32).collect::<Vec<_>>()
    );
    let back = h.inverse(&kept.to_dense()).unwrap();
    for (a, b) in map.iter().zip(&back) {
        assert!((a - b).abs() <= 1e-5 * a.abs().max(1.0), "{a} vs {b}");
    }

    // On a random map: the kept magnitudes are the k largest, indices sorted and unique.
    let x: Vec<f32> = (0..len).map(|_| g.signed() as f32).collect();
    let w = h.forward(&x).unwrap();
    for k in [0, 1, 10, 100, len] {
        let s = SparseVector::keep_largest(&w, k).unwrap();
        assert_eq!(s.nnz(), k.min(len));
        assert!(s.indices().windows(2).all(|p| p[0] < p[1]));
        let smallest_kept = s
            .values()
            .iter()
            .map(|v| v.abs())
            .fold(f32::INFINITY, f32::min);
        let dense = s.to_dense();
        for (i, &v) in w.iter().enumerate() {
            if dense[i] == 0.0 {
                assert!(
                    v.abs() <= smallest_kept,
                    "k {k}: dropped {v} > kept {smallest_kept}"
                );
            } else {
                assert_eq!(dense[i], v);
            }
        }
    }
}

#[test]
fn sparse_products_are_the_lighting_integral() {
    let n = 8;
    let h = HaarCube::new(n).unwrap();
    let omega = face_solid_angles(n);
    let mut g = Gen(31);
    let light: Vec<f32> = (0..h.len()).map(|_| (4.0 * g.unit()) as f32).collect();
    let transfer: Vec<f32> = (0..h.len()).map(|_| g.unit() as f32).collect();
    let integral: f64 = (0..h.len())
        .map(|t| light[t] as f64 * transfer[t] as f64 * omega[t % (n * n)])
        .sum();
    let (wl, wt) = (h.forward(&light).unwrap(), h.forward(&transfer).unwrap());
    let all_l = SparseVector::keep_largest(&wl, h.len()).unwrap();
    let all_t = SparseVector::keep_largest(&wt, h.len()).unwrap();
    assert!((all_l.dot_dense(&wt).unwrap() - integral).abs() < 1e-5 * integral);
    assert!((all_l.dot(&all_t).unwrap() - integral).abs() < 1e-5 * integral);
    // Truncated lighting: the product is the integral of the truncated lighting's map.
    let some_l = SparseVector::keep_largest(&wl, 40).unwrap();
    let approx = h.inverse(&some_l.to_dense()).unwrap();
    let want: f64 = (0..h.len())
        .map(|t| approx[t] as f64 * transfer[t] as f64 * omega[t % (n * n)])
        .sum();
    assert!((some_l.dot_dense(&wt).unwrap() - want).abs() < 1e-5 * integral);
    let some_t = SparseVector::keep_largest(&wt, 60).unwrap();
    let by_merge = some_l.dot(&some_t).unwrap();
    let by_dense = some_l.dot_dense(&some_t.to_dense()).unwrap();
    assert!((by_merge - by_dense).abs() < 1e-12 * integral);
}

// ---------------------------------------------------------------------------------------------
// Spherical harmonics

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

fn random_coeffs(g: &mut Gen) -> [f64; SH_COUNT] {
    [0; SH_COUNT].map(|_| g.signed())
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

// ---------------------------------------------------------------------------------------------
// Prefilter

const WIDTHS_DEG: [f64; 3] = [7.0, 14.0, 21.0];

#[test]
fn funk_hecke_factors_match_direct_integration() {
    // integral G(angle(w, r)) Y_i(w) dw = lambda_l Y_i(r), integrated in polar coordinates
    // about r (Gauss–Legendre in the angle, uniform azimuth).
    let mut g = Gen(61);
    for deg in WIDTHS_DEG.iter().chain(&[2.0, 60.0]) {
        let sigma = deg.to_radians();
        let lambda = sh_factors(sigma).unwrap();
        let r = g.direction();
        // An orthonormal frame (e1, e2, r).
        let helper = if r[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let e1 = {
            let d = dot(helper, r);
            let v = [0, 1, 2].map(|k| helper[k] - d * r[k]);
            let n = dot(v, v).sqrt();
            v.map(|x| x / n)
        };
        let e2 = [
            r[1] * e1[2] - r[2] * e1[1],
            r[2] * e1[0] - r[0] * e1[2],
            r[0] * e1[1] - r[1] * e1[0],
        ];
        let end = (12.0 * sigma).min(PI);
        let (x, w) = gauss_legendre(48);
        let mut acc = [0.0; SH_COUNT];
        let panels = 16;
        for p in 0..panels {
            for (xi, wi) in x.iter().zip(&w) {
                let a = end * (p as f64 + 0.5 + 0.5 * xi) / panels as f64;
                let wa = wi * 0.5 * end / panels as f64 * a.sin() * kernel(sigma, a);
                for k in 0..16 {
                    let phi = 2.0 * PI * k as f64 / 16.0;
                    let (s, c) = phi.sin_cos();
                    let d = [0, 1, 2].map(|q| a.cos() * r[q] + a.sin() * (c * e1[q] + s * e2[q]));
                    for (o, y) in acc.iter_mut().zip(sh_eval(d)) {
                        *o += wa * 2.0 * PI / 16.0 * y;
                    }
                }
            }
        }
        let y = sh_eval(r);
        for i in 0..SH_COUNT {
            let want = lambda[sh_band(i)] * y[i];
            assert!(
                (acc[i] - want).abs() < 1e-10,
                "{deg} {i}: {} vs {want}",
                acc[i]
            );
        }
    }
}

#[test]
fn width_zero_is_the_identity() {
    let cube = random_cube(8, 71);
    assert_eq!(prefilter(&cube, 0.0).unwrap(), cube);
    assert_eq!(prefilter_to_size(&cube, 0.0, 8).unwrap(), cube);
    assert_eq!(sh_factors(0.0).unwrap(), [1.0; 4]);
    assert_eq!(kernel_integral(0.0).unwrap(), 1.0);
    // At another side it is a plain bilinear resampling (a constant stays constant).
    let c = CubeMap::constant(8, [2.0; 3]).unwrap();
    for t in prefilter_to_size(&c, 0.0, 5).unwrap().texels() {
        assert!(close3(f64x3(*t), [2.0; 3], 1e-6));
    }
}

#[test]
fn a_constant_environment_gives_the_kernel_integral() {
    let value = [1.0, 2.0, 0.5];
    let cube = CubeMap::constant(64, value.map(|v| v as f32)).unwrap();
    for deg in WIDTHS_DEG {
        let sigma = deg.to_radians();
        let k = kernel_integral(sigma).unwrap();
        let e = prefilter(&cube, sigma).unwrap();
        assert_eq!(e.size(), output_size(sigma).unwrap());
        let mut worst: f64 = 0.0;
        for t in e.texels() {
            for c in 0..3 {
                worst = worst.max((t[c] as f64 / (value[c] * k) - 1.0).abs());
            }
        }
        // Measured: 1.2e-4, 1.7e-4, 0.9e-4 for 7, 14, 21 degrees (the cube grid's midpoint
        // rule; the truncation is compensated).
        assert!(worst < 3e-4, "{deg}: {worst}");
    }
}

#[test]
fn a_band_limited_environment_is_filtered_by_the_sh_factors() {
    let mut g = Gen(73);
    let c = random_coeffs(&mut g);
    let rgb: [[f64; 3]; SH_COUNT] = c.map(|v| [v, 0.5 * v, 0.0]);
    let mut rgb = rgb;
    rgb[0] = [3.0, 3.0, 1.0];
    let cube = CubeMap::from_fn(64, |d| sh_reconstruct(&rgb, d)).unwrap();
    for deg in WIDTHS_DEG {
        let sigma = deg.to_radians();
        let lambda = sh_factors(sigma).unwrap();
        let filtered: [[f64; 3]; SH_COUNT] =
            std::array::from_fn(|i| rgb[i].map(|v| v * lambda[sh_band(i)]));
        let e = prefilter(&cube, sigma).unwrap();
        let n = e.size();
        let (mut worst, mut largest): (f64, f64) = (0.0, 0.0);
        for face in Face::ALL {
            for j in 0..n {
                for i in 0..n {
                    let want = sh_reconstruct(&filtered, texel_centre_direction(n, face, i, j));
                    let got = f64x3(e.get(face, i, j).unwrap());
                    for k in 0..3 {
                        worst = worst.max((got[k] - want[k]).abs());
                        largest = largest.max(want[k].abs());
                    }
                }
            }
        }
        // Measured: 1.1e-4, 2.8e-4, 1.9e-4 of the largest value.
        assert!(worst < 5e-4 * largest, "{deg}: {worst} of {largest}");
    }
}

/// The exact `E(r)` of a piecewise-constant cube map (f64, every texel split into m x m
/// sub-samples, no truncation).
fn reference_prefilter(cube: &CubeMap, sigma: f64, r: [f64; 3], m: usize) -> [f64; 3] {
    let n = cube.size();
    let ns = n * m;
    let omega = face_solid_angles(ns);
    let cos_far = if 8.0 * sigma < PI {
        (8.0 * sigma).cos()
    } else {
        -2.0
    };
    let mut acc = [0.0; 3];
    for face in Face::ALL {
        for l in 0..ns {
            for k in 0..ns {
                let d = texel_centre_direction(ns, face, k, l);
                let c = dot(d, r);
                // Beyond 8 widths the kernel is below e^-32: nothing to add.
                if c < cos_far {
                    continue;
                }
                let a = c.clamp(-1.0, 1.0).acos();
                let w = kernel(sigma, a) * omega[l * ns + k];
                let v = cube.get(face, k / m, l / m).unwrap();
                for c in 0..3 {
                    acc[c] += w * v[c] as f64;
                }
            }
        }
    }
    acc
}

/// A smooth sky (red 1 + y/2, green 1, blue 0.2 + x^2) with one bright red texel, a "sun",
/// side 64.
fn sky_with_sun() -> CubeMap {
    let mut texels = CubeMap::from_fn(64, |d| [1.0 + 0.5 * d[1], 1.0, 0.2 + d[0] * d[0]])
        .unwrap()
        .into_texels();
    texels[texel_index(64, Face::PosY, 18, 41)] = [2000.0, 0.0, 0.0];
    CubeMap::new(64, texels).unwrap()
}

#[test]
fn prefilter_accuracy_against_a_fine_reference() {
    // The sky with a sun, against the exact E of the piecewise-constant map: the largest
    // error over sampled output texels relative to the largest output (as docs/lighting.md
    // states it).
    let cube = sky_with_sun();
    let sun_dir = texel_centre_direction(64, Face::PosY, 18, 41);
    for deg in WIDTHS_DEG {
        let sigma = deg.to_radians();
        let e = prefilter(&cube, sigma).unwrap();
        let n = e.size();
        let mut worst = [0.0f64; 3];
        let mut largest = [0.0f64; 3];
        let mut g = Gen(deg as u64);
        // Output texels near the sun (where the error is largest) and elsewhere.
        for probe in 0..40 {
            let (face, i, j) = if probe < 20 {
                let d = [0, 1, 2].map(|k| sun_dir[k] + 1.5 * sigma * g.signed());
                direction_to_texel(n, d)
            } else {
                let d = g.direction();
                direction_to_texel(n, d)
            };
            let r = texel_centre_direction(n, face, i, j);
            let want = reference_prefilter(&cube, sigma, r, 4);
            let got = f64x3(e.get(face, i, j).unwrap());
            for c in 0..3 {
                worst[c] = worst[c].max((got[c] - want[c]).abs());
                largest[c] = largest[c].max(want[c].abs());
            }
        }
        for c in 0..3 {
            let rel = worst[c] / largest[c];
            // Red holds the sun (measured 9.5e-4, 9.1e-4, 3.7e-4 for 7, 14, 21 degrees);
            // green and blue are smooth (measured at most 1.8e-4).
            let bound = if c == 0 { 2e-3 } else { 4e-4 };
            assert!(rel < bound, "{deg} channel {c}: {rel}");
        }
    }
}

#[test]
fn prefilter_refuses_what_it_cannot_resolve() {
    let cube = CubeMap::constant(16, [1.0; 3]).unwrap();
    let e = prefilter(&cube, 0.01).unwrap_err();
    assert!(
        matches!(e, LightingError::WidthTooNarrow { size: 16, .. }),
        "{e}"
    );
    assert!(prefilter(&cube, -0.1).is_err());
    assert!(prefilter(&cube, f64::NAN).is_err());
    assert!(prefilter_to_size(&cube, 0.2, 0).is_err());
}

/// The speed the runtime needs (the light changes while it runs): all three widths of a
/// 6x64x64 environment. Ignored by default (timings on a shared machine are noisy); run with
/// `cargo test --release -p prt-formats --test suite prefilter_speed -- --ignored --nocapture`.
#[test]
#[ignore]
fn prefilter_speed_on_6x64x64() {
    let cube = random_cube(64, 81);
    let start = std::time::Instant::now();
    for deg in WIDTHS_DEG {
        let t = std::time::Instant::now();
        let e = prefilter(&cube, deg.to_radians()).unwrap();
        eprintln!(
            "prefilter {deg} degrees: 6x{n}x{n} output in {:.3} s",
            t.elapsed().as_secs_f64(),
            n = e.size()
        );
    }
    let total = start.elapsed().as_secs_f64();
    eprintln!("all three widths: {total:.3} s");
    assert!(total < 5.0, "{total} s");
}

#[test]
fn prefiltered_maps_are_fine_enough_for_bilinear_lookups() {
    // The default output (texels at most sigma / 2 across) looked up bilinearly anywhere, not
    // only at texel centres. Interpolating a Gaussian peak between points sigma / 2 apart
    // errs by up to about (sigma/2)^2 / (8 sigma^2) = 3 % of the peak; smooth light much less.
    let cube = sky_with_sun();
    let sun_dir = texel_centre_direction(64, Face::PosY, 18, 41);
    for deg in WIDTHS_DEG {
        let sigma = deg.to_radians();
        let e = prefilter(&cube, sigma).unwrap();
        let mut g = Gen(5);
        let (mut worst, mut largest) = ([0.0f64; 3], [0.0f64; 3]);
        for probe in 0..60 {
            let d = if probe < 30 {
                let d = [0, 1, 2].map(|k| sun_dir[k] + 1.5 * sigma * g.signed());
                let n = dot(d, d).sqrt();
                d.map(|x| x / n)
            } else {
                g.direction()
            };
            let want = reference_prefilter(&cube, sigma, d, 2);
            let got = f64x3(e.lookup_bilinear(d));
            for c in 0..3 {
                worst[c] = worst[c].max((got[c] - want[c]).abs());
                largest[c] = largest[c].max(want[c].abs());
            }
        }
        // Measured: sun 3.3 %, 1.3 %, 1.7 %; smooth channels at most 0.7 % (21 degrees).
        let rel = [0, 1, 2].map(|c| worst[c] / largest[c]);
        assert!(rel[0] < 0.05, "{deg}: {rel:?}");
        assert!(rel[1] < 0.015 && rel[2] < 0.015, "{deg}: {rel:?}");
    }
}
