//! The lighting bases (prt_formats::lighting): cube-map geometry and resampling, the
//! area-weighted Haar transform and sparse products, spherical harmonics and their rotation,
//! the Gaussian prefilter. Closed forms and exact quadratures, with stated tolerances; one
//! submodule per concern, sharing the helpers below.

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

mod cube;
mod haar;
mod prefilter;
mod sh;

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

/// Random SH coefficients in [-1, 1).
fn random_coeffs(g: &mut Gen) -> [f64; SH_COUNT] {
    [0; SH_COUNT].map(|_| g.signed())
}
