//! T0 and the visibility of one vertex: a shadow ray through the centre of every 6x64x64
//! texel above the tangent plane; the rows `U^i(w_local, k) (w . n) V(w)` and the irradiance
//! row `(w . n) V(w)` at the texel centres; the visible fraction of each 6x16x16 texel's 4 x 4
//! block; and each row's area-weighted Haar transform truncated to its largest terms.
//!
//! **The open sky exactly** (docs/vertex.md, "T0: the open sky exactly"). Kept to a few Haar
//! terms, the irradiance row loses the cosine's fine detail, and under a map lit by small lamps
//! that loss is a bias (the gallery's open floor came out 6.4 % too dark at 96 terms). So a
//! vertex may store the row's occluded part `(w . n)+ (1 - V)` instead, zero wherever nothing
//! blocks the sky, and the runtime subtracts it from the open sky's irradiance at the normal,
//! which it tabulates exactly (`prt_formats::lighting::irradiance`). Each vertex keeps the form
//! whose truncation drops less (a vertex mostly in the open the occluded part, one mostly
//! enclosed the visible part) and says which with its `open` flag.

use glam::Vec3;
use prt_formats::basis::{ShadingBasis, MAX_SHADING_RANK};
use prt_formats::lighting::cubemap::{texel_centre_direction, texel_index, Face};
use prt_formats::lighting::{HaarCube, LightingError, SparseVector};
use prt_formats::vertex::{cube_len, DIRECT_CUBE, VISIBILITY_CUBE};

use crate::accel::{Accel, Ray};

use super::error::VertexError;
use super::frame::VertexFrame;

/// Texels of the direct cube (6 x 64 x 64).
pub const T0_TEXELS: usize = cube_len(DIRECT_CUBE);
/// Texels of the visibility cube (6 x 16 x 16).
const VIS_TEXELS: usize = cube_len(VISIBILITY_CUBE);
/// Direct texels per visibility texel along a side (4: a 4 x 4 block).
const VIS_BLOCK: usize = DIRECT_CUBE / VISIBILITY_CUBE;

/// A vertex's T0 rows as stored: each row's kept Haar terms and what the truncation dropped.
#[derive(Clone, Debug)]
pub struct HaarTerms {
    /// `[rows][terms]` Haar indices, padding (index 0, value 0) after the kept ones.
    pub index: Vec<u16>,
    pub value: Vec<f32>,
    /// Sum of squares of every coefficient of the rows (the irradiance row as the visible
    /// part), and of the dropped ones (of the form kept).
    pub total: f64,
    pub dropped: f64,
    /// Whether the irradiance row holds the occluded part (see the module documentation).
    pub open: bool,
}

/// The direct cube: every texel's centre direction and visibility texel, and the Haar
/// transform.
pub(crate) struct DirectCube {
    /// Per direct texel (cube-map order, `texel_index`): its centre direction and the
    /// visibility texel holding it (same face, column i/4, row j/4).
    texels: Vec<(Vec3, u16)>,
    haar: HaarCube,
}

impl DirectCube {
    pub fn new() -> Result<DirectCube, VertexError> {
        let mut texels = vec![(Vec3::ZERO, 0u16); T0_TEXELS];
        for face in Face::ALL {
            for j in 0..DIRECT_CUBE {
                for i in 0..DIRECT_CUBE {
                    let d = texel_centre_direction(DIRECT_CUBE, face, i, j);
                    let vis = texel_index(VISIBILITY_CUBE, face, i / VIS_BLOCK, j / VIS_BLOCK);
                    texels[texel_index(DIRECT_CUBE, face, i, j)] =
                        (Vec3::from_array(d.map(|x| x as f32)), vis as u16);
                }
            }
        }
        let haar =
            HaarCube::new(DIRECT_CUBE).map_err(|e| VertexError::Inconsistent(e.to_string()))?;
        Ok(DirectCube { texels, haar })
    }

    /// T0~ rows at the direct texels' centres (`[rows][texel]`; the shading basis' `r_i`
    /// rows, then the irradiance row), the irradiance row's occluded part `(w . n)+ (1 - V)`,
    /// and the visible fractions: one shadow ray per texel above the horizon. Returns (rows,
    /// row count, occluded part, visibility, rays).
    pub fn trace(
        &self,
        accel: &Accel,
        frame: &VertexFrame,
        shading: Option<&ShadingBasis>,
    ) -> (Vec<f32>, usize, Vec<f32>, Vec<f32>, u64) {
        let ri = shading.map_or(0, |b| b.ranks.i);
        let rows = ri + 1;
        let mut t0 = vec![0.0f32; rows * T0_TEXELS];
        let mut occluded = vec![0.0f32; T0_TEXELS];
        let mut visible = [0u16; VIS_TEXELS];
        let mut u = [0.0f32; MAX_SHADING_RANK];
        // The texels above the horizon and their shadow rays, traced as one stream (the rays
        // share an origin; several in flight hide the tree's memory waits).
        let (above, rays): (Vec<u32>, Vec<Ray>) = self
            .texels
            .iter()
            .enumerate()
            .filter(|(_, (d, _))| d.dot(frame.n) > 0.0)
            .map(|(t, &(d, _))| (t as u32, Ray::new(frame.origin, d)))
            .unzip();
        let mut blocked = vec![false; rays.len()];
        accel.occluded_stream(&rays, &mut blocked);
        for (k, &t) in above.iter().enumerate() {
            let (t, d) = (t as usize, rays[k].dir);
            let cos = d.dot(frame.n);
            if blocked[k] {
                occluded[t] = cos;
                continue;
            }
            visible[self.texels[t].1 as usize] += 1;
            if let Some(b) = shading {
                b.u_i_row(frame.to_local(d).to_array(), &mut u);
                for (k, uk) in u[..ri].iter().enumerate() {
                    t0[k * T0_TEXELS + t] = uk * cos;
                }
            }
            t0[ri * T0_TEXELS + t] = cos;
        }
        let rays = rays.len() as u64;
        let per = (VIS_BLOCK * VIS_BLOCK) as f32;
        let visibility = visible.iter().map(|&n| n as f32 / per).collect();
        (t0, rows, occluded, visibility, rays)
    }

    /// The area-weighted Haar transform of each row of `t0` and its `terms` largest terms,
    /// padded with (index 0, value 0), the irradiance row (the last) in the form that drops
    /// less: the visible part, or `occluded` (then `open` is true; see the module
    /// documentation). The transform is
    /// orthonormal in the solid-angle metric, so `sum_t C0[index_t] value_t` is
    /// `integral L T0~ dw` for a light whose Haar coefficients are C0, and the squares
    /// measure the truncation error of the function.
    pub fn haar_terms(
        &self,
        vertex: u32,
        t0: &[f32],
        occluded: &[f32],
        terms: usize,
    ) -> Result<HaarTerms, VertexError> {
        let rows = t0.len() / T0_TEXELS;
        let mut index = Vec::with_capacity(rows * terms);
        let mut value = Vec::with_capacity(rows * terms);
        let (mut total, mut dropped) = (0.0f64, 0.0f64);
        let bad = |e: LightingError| VertexError::NonFinite {
            vertex,
            message: e.to_string(),
        };
        let squares = |v: &[f32]| v.iter().map(|&c| c as f64 * c as f64).sum::<f64>();
        // (kept terms, all coefficients' energy, dropped energy) of one row.
        let truncate = |row: &[f32]| -> Result<(SparseVector, f64, f64), VertexError> {
            let coeffs = self.haar.forward(row).map_err(bad)?;
            let all = squares(&coeffs);
            let sparse = SparseVector::keep_largest(&coeffs, terms).map_err(bad)?;
            let kept = squares(sparse.values());
            Ok((sparse, all, (all - kept).max(0.0)))
        };
        let mut open = false;
        for (r, row) in t0.chunks_exact(T0_TEXELS).enumerate() {
            let (mut sparse, all, mut lost) = truncate(row)?;
            if r + 1 == rows && lost > 0.0 {
                let (occ, _, occ_lost) = truncate(occluded)?;
                // Ties (every term kept) stay visible: the exact form needs no table.
                if occ_lost < lost {
                    (sparse, lost, open) = (occ, occ_lost, true);
                }
            }
            total += all;
            dropped += lost;
            let n = sparse.nnz();
            index.extend(sparse.indices().iter().map(|&i| i as u16));
            value.extend_from_slice(sparse.values());
            index.extend(std::iter::repeat_n(0u16, terms - n));
            value.extend(std::iter::repeat_n(0.0f32, terms - n));
        }
        Ok(HaarTerms {
            index,
            value,
            total,
            dropped,
            open,
        })
    }
}
