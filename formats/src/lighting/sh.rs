//! Real spherical harmonics of order 4 (bands l = 0..3, 16 functions), orthonormal over the
//! sphere: evaluation, projection of a cube map and rotation.
//!
//! # Convention
//!
//! The functions are Sloan's Cartesian polynomials ("Stupid Spherical Harmonics (SH)
//! Tricks", 2008, appendix), evaluated on the **world** direction `(x, y, z)` as it is, so
//! their polar axis is world +Z (not the up axis +Y; nothing depends on the choice because
//! every band is closed under rotation). Coefficient `l^2 + l + m` holds `Y_l^m`
//! (`m = -l..l`), and the Condon–Shortley phase is included, as in Sloan's table: the
//! functions with odd `m` carry a minus sign.
//!
//! ```text
//!  0  Y_0^0  =  1 / (2 sqrt(pi))
//!  1  Y_1^-1 = -sqrt(3/(4pi)) y          2  Y_1^0 = sqrt(3/(4pi)) z
//!  3  Y_1^1  = -sqrt(3/(4pi)) x
//!  4  Y_2^-2 =  1/2 sqrt(15/pi) x y      5  Y_2^-1 = -1/2 sqrt(15/pi) y z
//!  6  Y_2^0  =  1/4 sqrt(5/pi) (3z^2 - 1)
//!  7  Y_2^1  = -1/2 sqrt(15/pi) x z      8  Y_2^2 =  1/4 sqrt(15/pi) (x^2 - y^2)
//!  9  Y_3^-3 = -1/4 sqrt(35/(2pi)) y (3x^2 - y^2)
//! 10  Y_3^-2 =  1/2 sqrt(105/pi) x y z
//! 11  Y_3^-1 = -1/4 sqrt(21/(2pi)) y (5z^2 - 1)
//! 12  Y_3^0  =  1/4 sqrt(7/pi) (5z^3 - 3z)
//! 13  Y_3^1  = -1/4 sqrt(21/(2pi)) x (5z^2 - 1)
//! 14  Y_3^2  =  1/4 sqrt(105/pi) z (x^2 - y^2)
//! 15  Y_3^3  = -1/4 sqrt(35/(2pi)) x (x^2 - 3y^2)
//! ```
//!
//! A function `f` has coefficients `c_i = integral f Y_i dw` and is reconstructed as
//! `sum_i c_i Y_i`. Rotating `f` by a rotation `R` gives `f'(d) = f(R^T d)` (what was seen in
//! direction `d0` is seen in `R d0` afterwards), whose coefficients are `M c` with the matrix
//! of [`ShRotation`]. [`ShRotation::about_y_deg`] uses the sign of the cube-map resampling
//! ([`super::cubemap::CubeMap::from_latlong`]): +angle is counterclockwise seen from above.

use super::cubemap::{face_solid_angles, mat_vec, texel_centre_direction, CubeMap, Face};
use super::error::LightingError;
use super::quadrature::sphere_rule;

/// The number of bands (l = 0..SH_BANDS-1).
pub const SH_BANDS: usize = 4;
/// The number of coefficients, `SH_BANDS^2`.
pub const SH_COUNT: usize = SH_BANDS * SH_BANDS;

// Normalization constants (checked by the orthonormality tests).
const C00: f64 = 0.282_094_791_773_878_14; // 1 / (2 sqrt(pi))
const C1: f64 = 0.488_602_511_902_919_9; // sqrt(3 / (4 pi))
const C2A: f64 = 1.092_548_430_592_079_2; // 1/2 sqrt(15 / pi)
const C20: f64 = 0.315_391_565_252_520_05; // 1/4 sqrt(5 / pi)
const C22: f64 = 0.546_274_215_296_039_6; // 1/4 sqrt(15 / pi)
const C33: f64 = 0.590_043_589_926_643_5; // 1/4 sqrt(35 / (2 pi))
const C32: f64 = 2.890_611_442_640_554; // 1/2 sqrt(105 / pi)
const C31: f64 = 0.457_045_799_464_465_8; // 1/4 sqrt(21 / (2 pi))
const C30: f64 = 0.373_176_332_590_115_4; // 1/4 sqrt(7 / pi)
const C32B: f64 = 1.445_305_721_320_277; // 1/4 sqrt(105 / pi)

/// The coefficient index `l^2 + l + m` of `Y_l^m`; `None` unless `l < 4` and `|m| <= l`.
pub fn sh_index(l: usize, m: i32) -> Option<usize> {
    if l >= SH_BANDS || m.unsigned_abs() as usize > l {
        return None;
    }
    (l * l + l).checked_add_signed(m as isize)
}

/// The band `l` of coefficient index `i` (`i < 16`).
#[inline]
pub fn sh_band(i: usize) -> usize {
    match i {
        0 => 0,
        1..=3 => 1,
        4..=8 => 2,
        _ => 3,
    }
}

/// The 16 basis functions at direction `d` (unit; other lengths give the polynomials' value).
#[inline]
pub fn sh_eval(d: [f64; 3]) -> [f64; SH_COUNT] {
    let [x, y, z] = d;
    let (x2, y2, z2) = (x * x, y * y, z * z);
    [
        C00,
        -C1 * y,
        C1 * z,
        -C1 * x,
        C2A * x * y,
        -C2A * y * z,
        C20 * (3.0 * z2 - 1.0),
        -C2A * x * z,
        C22 * (x2 - y2),
        -C33 * y * (3.0 * x2 - y2),
        C32 * x * y * z,
        -C31 * y * (5.0 * z2 - 1.0),
        C30 * z * (5.0 * z2 - 3.0),
        -C31 * x * (5.0 * z2 - 1.0),
        C32B * z * (x2 - y2),
        -C33 * x * (x2 - 3.0 * y2),
    ]
}

/// [`sh_eval`] in f32, for runtime loops (the same polynomials, rounded once).
#[inline]
pub fn sh_eval_f32(d: [f32; 3]) -> [f32; SH_COUNT] {
    let v = sh_eval([d[0] as f64, d[1] as f64, d[2] as f64]);
    v.map(|x| x as f32)
}

/// The RGB value at direction `d` of the function with coefficients `coeffs`.
pub fn sh_reconstruct(coeffs: &[[f64; 3]; SH_COUNT], d: [f64; 3]) -> [f64; 3] {
    let y = sh_eval(d);
    let mut out = [0.0; 3];
    for (c, yi) in coeffs.iter().zip(y) {
        for k in 0..3 {
            out[k] += c[k] * yi;
        }
    }
    out
}

/// The SH coefficients of a cube map: `c_i = sum_t value_t Y_i(centre_t) solid_angle_t` per
/// channel (the midpoint rule on the cube's texels, with exact texel solid angles).
pub fn project_cube(cube: &CubeMap) -> [[f64; 3]; SH_COUNT] {
    let n = cube.size();
    let omega = face_solid_angles(n);
    let mut out = [[0.0f64; 3]; SH_COUNT];
    let texels = cube.texels();
    for face in Face::ALL {
        for j in 0..n {
            for i in 0..n {
                let w = omega[j * n + i];
                let y = sh_eval(texel_centre_direction(n, face, i, j));
                let v = texels[(face.index() * n + j) * n + i];
                for (o, yi) in out.iter_mut().zip(y) {
                    for k in 0..3 {
                        o[k] += v[k] as f64 * yi * w;
                    }
                }
            }
        }
    }
    out
}

/// The rotation of SH coefficients for one 3x3 rotation: a 16x16 block-diagonal matrix (one
/// block per band). For a function `f` with coefficients `c`, `M c` are the coefficients of
/// `f'(d) = f(R^T d)`, the function turned by `R`.
#[derive(Clone, Debug, PartialEq)]
pub struct ShRotation {
    m: [[f64; SH_COUNT]; SH_COUNT],
}

impl ShRotation {
    /// The SH rotation of `r` (row-major, acting on column vectors: `d' = r d`). `r` must be
    /// finite, orthonormal to within 1e-5 per entry of `r r^T - I`, and have determinant +1
    /// (a reflection is refused).
    ///
    /// The entries are `M_ij = integral Y_i(d) Y_j(R^T d) dw` for `i`, `j` in the same band,
    /// computed with a sphere quadrature that is exact for polynomials of degree 6 (the
    /// product is a polynomial of degree at most 6), so they are exact to rounding; entries
    /// across bands are exactly 0.
    pub fn from_matrix(r: [[f64; 3]; 3]) -> Result<Self, LightingError> {
        if let Some((index, &value)) = r.iter().flatten().enumerate().find(|(_, v)| !v.is_finite())
        {
            return Err(LightingError::NonFinite {
                what: "rotation matrix",
                index,
                value,
            });
        }
        let mut dev: f64 = 0.0;
        for a in 0..3 {
            for b in 0..3 {
                let dot: f64 = (0..3).map(|k| r[a][k] * r[b][k]).sum();
                let want = if a == b { 1.0 } else { 0.0 };
                dev = dev.max((dot - want).abs());
            }
        }
        if dev > 1e-5 {
            return Err(LightingError::NotARotation {
                reason: "r r^T is not the identity",
                deviation: dev,
            });
        }
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        if det < 0.0 {
            return Err(LightingError::NotARotation {
                reason: "determinant -1 (a reflection)",
                deviation: (det - 1.0).abs(),
            });
        }
        let rt = [
            [r[0][0], r[1][0], r[2][0]],
            [r[0][1], r[1][1], r[2][1]],
            [r[0][2], r[1][2], r[2][2]],
        ];
        let mut m = [[0.0f64; SH_COUNT]; SH_COUNT];
        for (d, w) in sphere_rule(2 * (SH_BANDS - 1)) {
            let y = sh_eval(d);
            let yr = sh_eval(mat_vec(&rt, d));
            for i in 0..SH_COUNT {
                let band = sh_band(i);
                let start = band * band;
                for j in start..start + 2 * band + 1 {
                    m[i][j] += w * y[i] * yr[j];
                }
            }
        }
        Ok(ShRotation { m })
    }

    /// The SH rotation turning the environment by `angle_deg` degrees about +Y by the
    /// right-hand rule (counterclockwise seen from above), the sign of
    /// [`super::cubemap::CubeMap::from_latlong`]: projecting a map resampled with a rotation
    /// equals rotating the projection of the unrotated map.
    pub fn about_y_deg(angle_deg: f64) -> Result<Self, LightingError> {
        if !angle_deg.is_finite() {
            return Err(LightingError::InvalidParameter {
                what: "rotation angle",
                expected: "finite",
                value: angle_deg,
            });
        }
        ShRotation::from_matrix(super::cubemap::rotation_y(angle_deg))
    }

    /// The 16x16 matrix, row-major (`matrix()[i][j]` multiplies coefficient j into i).
    pub fn matrix(&self) -> &[[f64; SH_COUNT]; SH_COUNT] {
        &self.m
    }

    /// The rotated coefficients of one channel.
    pub fn apply(&self, c: &[f64; SH_COUNT]) -> [f64; SH_COUNT] {
        let mut out = [0.0; SH_COUNT];
        for (o, row) in out.iter_mut().zip(&self.m) {
            *o = row.iter().zip(c).map(|(a, b)| a * b).sum();
        }
        out
    }

    /// The rotated coefficients of an RGB function.
    pub fn apply_rgb(&self, c: &[[f64; 3]; SH_COUNT]) -> [[f64; 3]; SH_COUNT] {
        let mut out = [[0.0; 3]; SH_COUNT];
        for (o, row) in out.iter_mut().zip(&self.m) {
            for (a, v) in row.iter().zip(c) {
                for k in 0..3 {
                    o[k] += a * v[k];
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_order() {
        assert_eq!(sh_index(0, 0), Some(0));
        assert_eq!(sh_index(1, -1), Some(1));
        assert_eq!(sh_index(2, 2), Some(8));
        assert_eq!(sh_index(3, -3), Some(9));
        assert_eq!(sh_index(3, 3), Some(15));
        assert_eq!(sh_index(4, 0), None);
        assert_eq!(sh_index(1, 2), None);
        for i in 0..SH_COUNT {
            let l = sh_band(i);
            assert!(l * l <= i && i < (l + 1) * (l + 1));
        }
    }

    #[test]
    fn signs_follow_sloan() {
        // Y_1^1 = -c x: negative towards +X; Y_1^0 = c z: positive towards +Z.
        let y = sh_eval([1.0, 0.0, 0.0]);
        assert!(y[3] < 0.0 && y[2] == 0.0);
        let y = sh_eval([0.0, 0.0, 1.0]);
        assert!(y[2] > 0.0 && y[12] > 0.0 && y[6] > 0.0);
    }

    #[test]
    fn reflections_and_non_finite_matrices_are_refused() {
        let mirror = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(matches!(
            ShRotation::from_matrix(mirror),
            Err(LightingError::NotARotation { .. })
        ));
        let skew = [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(matches!(
            ShRotation::from_matrix(skew),
            Err(LightingError::NotARotation { .. })
        ));
        let nan = [[1.0, 0.0, 0.0], [0.0, f64::NAN, 0.0], [0.0, 0.0, 1.0]];
        assert!(matches!(
            ShRotation::from_matrix(nan),
            Err(LightingError::NonFinite { index: 4, .. })
        ));
        assert!(ShRotation::about_y_deg(f64::INFINITY).is_err());
    }
}
