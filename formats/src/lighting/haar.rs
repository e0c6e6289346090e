//! The area-weighted 2D Haar wavelet basis on the cube (Ng, Ramamoorthi and Hanrahan 2003,
//! "All-frequency shadows using non-linear wavelet lighting approximation"): the non-standard
//! decomposition of each N x N face (N a power of two), one scaling coefficient per face and
//! three wavelets per square at every level.
//!
//! # Area weighting
//!
//! The transform is applied to `value_t * sqrt(solid_angle_t)`. The per-face Haar transform
//! is orthonormal, so for two piecewise-constant functions `a`, `b` on the cube
//! `dot(W(a), W(b)) = sum_t a_t b_t solid_angle_t`, the integral of `a b` over the sphere:
//! Parseval holds in the solid-angle metric, and the product of a lighting's and a transfer
//! vector's coefficients is the lighting integral.
//!
//! # One step
//!
//! A 2x2 block of (weighted) values `p q / r s` (top row `p q`, `s` growing to the right)
//! becomes
//!
//! ```text
//! scaling  = (p + q + r + s) / 2
//! detail_s = (p - q + r - s) / 2   (left half minus right half)
//! detail_t = (p + q - r - s) / 2   (top half minus bottom half)
//! diagonal = (p - q - r + s) / 2
//! ```
//!
//! an orthogonal, symmetric 4x4 matrix (its own inverse). Repeating on the scaling values
//! halves the face until one value is left.
//!
//! # Coefficient layout
//!
//! Face `f` owns the indices `[f N^2, (f + 1) N^2)`, faces in cube-map order (+X, -X, +Y, -Y,
//! +Z, -Z). Within a face (offset `o`):
//!
//! * `o = 0`: the scaling coefficient, `sum_t value_t sqrt(solid_angle_t) / N` over the
//!   face's texels;
//! * level `l = 0 .. log2 N` (coarse to fine) has `2^l x 2^l` squares of `N / 2^l` texels and
//!   occupies `[4^l, 4^(l+1))`: first the `detail_s` of all its squares, then `detail_t`, then
//!   `diagonal`, each block `4^l` long and row-major over the squares (`row * 2^l + col`).
//!
//! [`haar_index`] and [`haar_coefficient`] convert between an index and its meaning.

use super::cubemap::{check_size, face_solid_angles, CubeMap, Face};
use super::error::LightingError;

/// What a Haar coefficient measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HaarKind {
    /// The face's scaling coefficient (its weighted mean).
    Scaling,
    /// Left half minus right half of a square (a difference along s).
    DetailS,
    /// Top half minus bottom half of a square (a difference along t).
    DetailT,
    /// The diagonal (checkerboard) difference of a square.
    Diagonal,
}

/// The meaning of one Haar coefficient (see the module documentation for the layout).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct HaarCoefficient {
    /// The face.
    pub face: Face,
    /// What it measures.
    pub kind: HaarKind,
    /// The level `l`: the face is cut into `2^l x 2^l` squares (0 for the scaling coefficient).
    pub level: u32,
    /// The square's row (0 for the scaling coefficient).
    pub row: usize,
    /// The square's column (0 for the scaling coefficient).
    pub col: usize,
}

/// The index of a coefficient in a cube of side `size`, `None` if it does not exist there
/// (`size` not a power of two, level too deep, square outside the level, or a scaling
/// coefficient with a level or square other than 0).
pub fn haar_index(size: usize, c: HaarCoefficient) -> Option<usize> {
    if size == 0 || !size.is_power_of_two() {
        return None;
    }
    let face_offset = c.face.index() * size * size;
    let kind = match c.kind {
        HaarKind::Scaling => {
            return (c.level == 0 && c.row == 0 && c.col == 0).then_some(face_offset);
        }
        HaarKind::DetailS => 0,
        HaarKind::DetailT => 1,
        HaarKind::Diagonal => 2,
    };
    if c.level >= size.trailing_zeros() {
        return None;
    }
    let side = 1usize << c.level;
    if c.row >= side || c.col >= side {
        return None;
    }
    let block = side * side;
    Some(face_offset + block + kind * block + c.row * side + c.col)
}

/// The meaning of coefficient `index` in a cube of side `size`, `None` past the end or for a
/// size that is not a power of two.
pub fn haar_coefficient(size: usize, index: usize) -> Option<HaarCoefficient> {
    if size == 0 || !size.is_power_of_two() || index >= 6 * size * size {
        return None;
    }
    let face = Face::from_index(index / (size * size))?;
    let o = index % (size * size);
    if o == 0 {
        return Some(HaarCoefficient {
            face,
            kind: HaarKind::Scaling,
            level: 0,
            row: 0,
            col: 0,
        });
    }
    // Level l occupies [4^l, 4^(l+1)): l = floor(log4 o).
    let level = (usize::BITS - 1 - o.leading_zeros()) / 2;
    let side = 1usize << level;
    let block = side * side;
    let within = o - block;
    let kind = [HaarKind::DetailS, HaarKind::DetailT, HaarKind::Diagonal][within / block];
    let square = within % block;
    Some(HaarCoefficient {
        face,
        kind,
        level,
        row: square / side,
        col: square % side,
    })
}

/// The area-weighted Haar transform of single-channel cube maps of one side N (a power of
/// two): holds the `sqrt(solid angle)` weights of a face. Values and coefficients are slices
/// of `6 N^2` in storage order (cube-map order for values, the module's layout for
/// coefficients). O(N^2) per face.
#[derive(Clone, Debug)]
pub struct HaarCube {
    size: usize,
    sqrt_omega: Vec<f64>,
}

impl HaarCube {
    /// The transform for cube maps of side `size` (a power of two, at most
    /// [`super::cubemap::MAX_CUBE_SIZE`]).
    pub fn new(size: usize) -> Result<Self, LightingError> {
        check_size(size)?;
        if !size.is_power_of_two() {
            return Err(LightingError::NotPowerOfTwo {
                what: "cube-map side of a Haar transform",
                value: size,
            });
        }
        let sqrt_omega = face_solid_angles(size).iter().map(|w| w.sqrt()).collect();
        Ok(HaarCube { size, sqrt_omega })
    }

    /// The side N.
    pub fn size(&self) -> usize {
        self.size
    }

    /// The number of values and of coefficients, `6 N^2`.
    pub fn len(&self) -> usize {
        6 * self.size * self.size
    }

    /// Always false (a cube has at least 6 texels); for clippy's `len` convention.
    pub fn is_empty(&self) -> bool {
        false
    }

    fn check(&self, what: &'static str, got: usize) -> Result<(), LightingError> {
        if got != self.len() {
            return Err(LightingError::LengthMismatch {
                what,
                expected: self.len(),
                got,
            });
        }
        Ok(())
    }

    /// The coefficients of a single-channel cube map (f32 in and out, f64 inside).
    pub fn forward(&self, values: &[f32]) -> Result<Vec<f32>, LightingError> {
        self.check("Haar input values", values.len())?;
        check_finite("Haar input values", values.iter().map(|&v| v as f64))?;
        let v: Vec<f64> = values.iter().map(|&v| v as f64).collect();
        Ok(self
            .forward_unchecked(&v)
            .iter()
            .map(|&c| c as f32)
            .collect())
    }

    /// [`HaarCube::forward`] in f64.
    pub fn forward_f64(&self, values: &[f64]) -> Result<Vec<f64>, LightingError> {
        self.check("Haar input values", values.len())?;
        check_finite("Haar input values", values.iter().copied())?;
        Ok(self.forward_unchecked(values))
    }

    /// The single-channel cube map of the coefficients (the inverse of
    /// [`HaarCube::forward`]).
    pub fn inverse(&self, coeffs: &[f32]) -> Result<Vec<f32>, LightingError> {
        self.check("Haar coefficients", coeffs.len())?;
        check_finite("Haar coefficients", coeffs.iter().map(|&v| v as f64))?;
        let c: Vec<f64> = coeffs.iter().map(|&v| v as f64).collect();
        Ok(self
            .inverse_unchecked(&c)
            .iter()
            .map(|&v| v as f32)
            .collect())
    }

    /// [`HaarCube::inverse`] in f64.
    pub fn inverse_f64(&self, coeffs: &[f64]) -> Result<Vec<f64>, LightingError> {
        self.check("Haar coefficients", coeffs.len())?;
        check_finite("Haar coefficients", coeffs.iter().copied())?;
        Ok(self.inverse_unchecked(coeffs))
    }

    /// The coefficients of each channel of an RGB cube map, `[red, green, blue]`.
    pub fn forward_cube(&self, cube: &CubeMap) -> Result<[Vec<f32>; 3], LightingError> {
        if cube.size() != self.size {
            return Err(LightingError::LengthMismatch {
                what: "cube-map texels for this Haar transform",
                expected: self.len(),
                got: cube.texels().len(),
            });
        }
        let channel =
            |c: usize| -> Vec<f64> { cube.texels().iter().map(|t| t[c] as f64).collect() };
        let to_f32 = |v: Vec<f64>| -> Vec<f32> { v.iter().map(|&x| x as f32).collect() };
        Ok([
            to_f32(self.forward_unchecked(&channel(0))),
            to_f32(self.forward_unchecked(&channel(1))),
            to_f32(self.forward_unchecked(&channel(2))),
        ])
    }

    fn forward_unchecked(&self, values: &[f64]) -> Vec<f64> {
        let n = self.size;
        let per_face = n * n;
        let mut out = vec![0.0; 6 * per_face];
        let mut cur = vec![0.0; per_face];
        let mut next = vec![0.0; per_face / 4 + 1];
        for face in 0..6 {
            let coeffs = &mut out[face * per_face..(face + 1) * per_face];
            for (c, (v, w)) in cur
                .iter_mut()
                .zip(values[face * per_face..].iter().zip(&self.sqrt_omega))
            {
                *c = v * w;
            }
            // m: the side of the current grid of scaling values; h = m / 2 = 2^level.
            let mut m = n;
            while m > 1 {
                let h = m / 2;
                let block = h * h;
                for r in 0..h {
                    for c in 0..h {
                        let p = cur[2 * r * m + 2 * c];
                        let q = cur[2 * r * m + 2 * c + 1];
                        let rr = cur[(2 * r + 1) * m + 2 * c];
                        let s = cur[(2 * r + 1) * m + 2 * c + 1];
                        let k = r * h + c;
                        next[k] = 0.5 * (p + q + rr + s);
                        coeffs[block + k] = 0.5 * (p - q + rr - s);
                        coeffs[2 * block + k] = 0.5 * (p + q - rr - s);
                        coeffs[3 * block + k] = 0.5 * (p - q - rr + s);
                    }
                }
                cur[..block].copy_from_slice(&next[..block]);
                m = h;
            }
            coeffs[0] = cur[0];
        }
        out
    }

    fn inverse_unchecked(&self, coeffs: &[f64]) -> Vec<f64> {
        let n = self.size;
        let per_face = n * n;
        let mut out = vec![0.0; 6 * per_face];
        let mut cur = vec![0.0; per_face];
        let mut next = vec![0.0; per_face];
        for face in 0..6 {
            let c = &coeffs[face * per_face..(face + 1) * per_face];
            cur[0] = c[0];
            let mut h = 1;
            while h < n {
                let m = 2 * h;
                let block = h * h;
                for r in 0..h {
                    for col in 0..h {
                        let k = r * h + col;
                        let (sc, ds, dt, dd) =
                            (cur[k], c[block + k], c[2 * block + k], c[3 * block + k]);
                        next[2 * r * m + 2 * col] = 0.5 * (sc + ds + dt + dd);
                        next[2 * r * m + 2 * col + 1] = 0.5 * (sc - ds + dt - dd);
                        next[(2 * r + 1) * m + 2 * col] = 0.5 * (sc + ds - dt - dd);
                        next[(2 * r + 1) * m + 2 * col + 1] = 0.5 * (sc - ds - dt + dd);
                    }
                }
                cur[..m * m].copy_from_slice(&next[..m * m]);
                h = m;
            }
            for (o, (v, w)) in out[face * per_face..(face + 1) * per_face]
                .iter_mut()
                .zip(cur.iter().zip(&self.sqrt_omega))
            {
                *o = v / w;
            }
        }
        out
    }
}

fn check_finite(
    what: &'static str,
    values: impl Iterator<Item = f64>,
) -> Result<(), LightingError> {
    for (index, value) in values.enumerate() {
        if !value.is_finite() {
            return Err(LightingError::NonFinite { what, index, value });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_round_trips() {
        for n in [1, 2, 4, 8] {
            for i in 0..6 * n * n {
                let c = haar_coefficient(n, i).unwrap();
                assert_eq!(haar_index(n, c), Some(i), "{n} {i} {c:?}");
            }
            assert_eq!(haar_coefficient(n, 6 * n * n), None);
        }
        let c = haar_coefficient(4, 16 + 1).unwrap();
        assert_eq!(
            c,
            HaarCoefficient {
                face: Face::NegX,
                kind: HaarKind::DetailS,
                level: 0,
                row: 0,
                col: 0,
            }
        );
        let c = haar_coefficient(4, 4 + 4 + 3).unwrap();
        assert_eq!(
            (c.kind, c.level, c.row, c.col),
            (HaarKind::DetailT, 1, 1, 1)
        );
        assert_eq!(haar_coefficient(3, 0), None);
        let deep = HaarCoefficient {
            face: Face::PosX,
            kind: HaarKind::Diagonal,
            level: 2,
            row: 0,
            col: 0,
        };
        assert_eq!(haar_index(4, deep), None);
    }

    #[test]
    fn refuses_bad_sizes_and_lengths() {
        assert!(matches!(
            HaarCube::new(6),
            Err(LightingError::NotPowerOfTwo { value: 6, .. })
        ));
        assert!(HaarCube::new(0).is_err());
        let h = HaarCube::new(2).unwrap();
        assert!(matches!(
            h.forward(&[0.0; 23]),
            Err(LightingError::LengthMismatch { expected: 24, .. })
        ));
        let mut v = vec![0.0f32; 24];
        v[5] = f32::NAN;
        assert!(matches!(
            h.forward(&v),
            Err(LightingError::NonFinite { index: 5, .. })
        ));
        assert!(h.inverse(&v).is_err());
    }

    #[test]
    fn a_single_face_value_of_one_texel_cube() {
        // N = 1: the coefficient is value * sqrt(4 pi / 6).
        let h = HaarCube::new(1).unwrap();
        let c = h.forward_f64(&[1.0, 0.0, 0.0, 0.0, 0.0, 2.0]).unwrap();
        let w = (4.0 * std::f64::consts::PI / 6.0).sqrt();
        assert!((c[0] - w).abs() < 1e-15 && (c[5] - 2.0 * w).abs() < 1e-15);
    }
}
