//! [`HemiGrid`], the equal-area hemisphere grid of the shading basis (both `wo` and `wi` are
//! tabulated on it), and [`HemiWeights`], the bilinear interpolation over it that the baker's
//! tests and the runtime share (docs/brdf-basis.md, "Shading basis").
//!
//! Cell `(j, k)` (ring `j` from the pole, azimuth `k`) spans `z = cos(theta)` in
//! `[1 - (j + 1)/n_theta, 1 - j/n_theta]` and `phi` in `[2 pi k/n_phi, 2 pi (k + 1)/n_phi]`; its
//! node is its centre, `z_j = 1 - (j + 0.5)/n_theta`, `phi_k = 2 pi (k + 0.5)/n_phi`, and every
//! cell covers `2 pi / (n_theta n_phi)` sr. Flat index `n = j n_phi + k`.
//!
//! Interpolation is bilinear in `(z, phi)` between the four surrounding nodes, with three rules
//! where the nodes run out:
//!
//! * **azimuth**: `phi` wraps (node `n_phi - 1` neighbours node 0);
//! * **polar cap** (`z > z_0`, within half a ring of the pole): the ring-0 value (bilinear in
//!   `phi`) is blended linearly in `z` towards the table's **pole row**, its value at the pole
//!   (`z = 1`, where `phi` is undefined), stored beside the nodes' rows; so the interpolant is
//!   continuous at the pole instead of turning with `phi`, and a view straight down the normal
//!   gets the pole's own value rather than ring 0's (14 degrees away on a 16-ring grid);
//! * **horizon** (`z < z_last`, the outer half of the last ring, and anything below): `z` is
//!   clamped to the last ring's node, so values are held constant down to the horizon.
//!
//! A zero, infinite or NaN direction gets the pole's weights.

use serde::{Deserialize, Serialize};
use std::f32::consts::TAU;

use super::BasisError;

/// Most directions a [`HemiGrid`] may have (the tables hold a few floats per direction and
/// the baker a `n_dirs x n_dirs` slab per parameter sample).
pub const MAX_HEMI_DIRS: usize = 1 << 16;

/// Equal-area hemisphere grid: `n_theta` rings uniform in `cos(theta)`, `n_phi` azimuths,
/// nodes at cell centres, each cell covering `2 pi / (n_theta n_phi)` steradians (see the
/// module docs for the node positions and the interpolation rules).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct HemiGrid {
    /// Rings, uniform in `cos(theta)` from the pole (ring 0) to the horizon; at least 2.
    pub n_theta: usize,
    /// Azimuths per ring; at least 3 (even, so that the mirror image of a node is a node).
    pub n_phi: usize,
}

impl HemiGrid {
    /// Number of directions (cells), saturating on absurd sizes (refused by
    /// [`HemiGrid::validate`]).
    pub fn len(&self) -> usize {
        self.n_theta.saturating_mul(self.n_phi)
    }

    /// Whether the grid has no cells (never the case for a valid grid).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Flat index of the node of ring `j`, azimuth `k`.
    #[inline]
    pub fn index(&self, j: usize, k: usize) -> usize {
        j * self.n_phi + k
    }

    /// `cos(theta)` of ring `j`'s nodes: `1 - (j + 0.5)/n_theta`.
    pub fn z(&self, j: usize) -> f64 {
        1.0 - (j as f64 + 0.5) / self.n_theta as f64
    }

    /// Azimuth of column `k`'s nodes: `2 pi (k + 0.5)/n_phi`.
    pub fn phi(&self, k: usize) -> f64 {
        std::f64::consts::TAU * (k as f64 + 0.5) / self.n_phi as f64
    }

    /// Unit direction of node `n` (local frame, +Z normal), f64.
    pub fn dir(&self, n: usize) -> [f64; 3] {
        let (j, k) = (n / self.n_phi, n % self.n_phi);
        let z = self.z(j);
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (s, c) = self.phi(k).sin_cos();
        [r * c, r * s, z]
    }

    /// Solid angle of every cell, `2 pi / len()` sr.
    pub fn solid_angle(&self) -> f64 {
        std::f64::consts::TAU / self.len() as f64
    }

    /// Checks `n_theta >= 2`, `n_phi >= 3` and at most [`MAX_HEMI_DIRS`] directions.
    pub fn validate(&self) -> Result<(), BasisError> {
        if self.n_theta < 2
            || self.n_phi < 3
            || self.n_theta.checked_mul(self.n_phi).is_none()
            || self.len() > MAX_HEMI_DIRS
        {
            return Err(BasisError::HemiGrid {
                n_theta: self.n_theta,
                n_phi: self.n_phi,
            });
        }
        Ok(())
    }

    /// Interpolation weights of the local direction `w` (need not be normalized; see the
    /// module docs for the rules at the pole, the horizon and the azimuth seam). The grid must
    /// be valid.
    #[inline]
    pub fn weights(&self, w: [f32; 3]) -> HemiWeights {
        let (nt, np) = (self.n_theta, self.n_phi);
        let len2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
        if !(len2 > 0.0 && len2.is_finite()) {
            return HemiWeights {
                taps: [(0, 0.0); 4],
                pole: 1.0,
            };
        }
        let z = (w[2] / len2.sqrt()).clamp(-1.0, 1.0);
        // ring coordinate: ring j's node at v = j
        let v = (1.0 - z) * nt as f32 - 0.5;
        let (j0, j1, fz, pole) = if v <= 0.0 {
            (0, 0, 0.0, (-2.0 * v).min(1.0))
        } else if v >= (nt - 1) as f32 {
            (nt - 1, nt - 1, 0.0, 0.0)
        } else {
            let j0 = (v as usize).min(nt - 2);
            (j0, j0 + 1, (v - j0 as f32).clamp(0.0, 1.0), 0.0)
        };
        // column coordinate: column k's node at u = k, wrapped
        let u = w[1].atan2(w[0]) * (np as f32 / TAU) - 0.5;
        let uf = u.floor();
        let fp = (u - uf).clamp(0.0, 1.0);
        let k0 = (uf as i64).rem_euclid(np as i64) as usize;
        let k1 = if k0 + 1 >= np { 0 } else { k0 + 1 };
        let ring = 1.0 - pole;
        let (a, b) = (ring * (1.0 - fz), ring * fz);
        HemiWeights {
            taps: [
                (self.index(j0, k0), a * (1.0 - fp)),
                (self.index(j0, k1), a * fp),
                (self.index(j1, k0), b * (1.0 - fp)),
                (self.index(j1, k1), b * fp),
            ],
            pole,
        }
    }
}

/// Interpolation weights of one direction over a [`HemiGrid`]: four node taps, plus the weight
/// `pole` of the table's pole row (nonzero only in the polar cap). The weights are nonnegative
/// and sum to 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HemiWeights {
    /// `(node index, weight)` of the four surrounding nodes (a clamped tap repeats an index
    /// with weight 0).
    pub taps: [(usize, f32); 4],
    /// Weight of the pole row.
    pub pole: f32,
}

impl HemiWeights {
    /// `out[..width] += scale * (sum_n weight_n table[n * width..][..width] + pole pole_row)`,
    /// for a table of `width` values per node (it must hold the grid's `len() * width` values)
    /// and its pole row (`width` values).
    #[inline]
    pub fn add_rows(
        &self,
        table: &[f32],
        pole_row: &[f32],
        width: usize,
        scale: f32,
        out: &mut [f32],
    ) {
        let out = &mut out[..width];
        for &(n, w) in &self.taps {
            let w = w * scale;
            if w != 0.0 {
                let row = &table[n * width..(n + 1) * width];
                for (o, r) in out.iter_mut().zip(row) {
                    *o += w * r;
                }
            }
        }
        let w = self.pole * scale;
        if w != 0.0 {
            for (o, r) in out.iter_mut().zip(&pole_row[..width]) {
                *o += w * r;
            }
        }
    }

    /// The interpolated row: `out[..width] = sum_n weight_n table[n * width..][..width] +
    /// pole pole_row` (see [`HemiWeights::add_rows`]).
    #[inline]
    pub fn interpolate(&self, table: &[f32], pole_row: &[f32], width: usize, out: &mut [f32]) {
        out[..width].fill(0.0);
        self.add_rows(table, pole_row, width, 1.0, out);
    }
}
