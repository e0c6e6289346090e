//! The family's lobe sampled as a 3-tensor `F(h, wo, wi)` (thesis 5.2.2): h = lobe parameter
//! sample, wo/wi = directions on the equal-area hemisphere grid. [`BrdfTensor`] stores every
//! entry; [`RingTensor`] stores only the ring rows of an isotropic lobe, and [`expand_rings`],
//! [`expand_slab`] and [`ring_offset`] give back the full tensor from them.
//!
//! Metric: entries are scaled by `sqrt(cos(theta_o) cos(theta_i) dwo dwi)` and every lobe is
//! normalized to unit norm, so the Frobenius norm is the cosine-weighted L2 norm of
//! docs/brdf-basis.md and a relative error `||F - F^|| / ||F||` is the RMS of the lobes'
//! relative errors. The scalings are per mode, so unscaling the factor matrices of a Tucker
//! decomposition gives one of the raw BRDF values.
//!
//! Why a file of its own: the specular split (`super::split`) and the Tucker decomposition
//! (`super::tucker`) both take the sampled tensor as given, so the sampling, the metric and the
//! ring layout live here, below both of them (tensor <- split <- tucker).

use super::grid::lobe_f64;
use super::FamilySpec;
use rayon::prelude::*;

/// The equal-area hemisphere grid of the tensor's direction modes; it lives in
/// `prt_formats::basis` because the shading basis persists tables over it.
pub use prt_formats::basis::HemiGrid;

/// The sampled, scaled tensor, layout `[h][o][i]` (i fastest).
pub struct BrdfTensor {
    pub spec: FamilySpec,
    pub params: Vec<f64>,
    pub dirs: HemiGrid,
    pub data: Vec<f64>,
    /// Per-direction scale `sqrt(cos(theta) dw)`.
    pub dir_scale: Vec<f64>,
    /// Per-lobe normalization applied (1 / cosine-weighted norm).
    pub lobe_scale: Vec<f64>,
}

impl BrdfTensor {
    /// The lobe sampled at the grid's nodes (both directions).
    pub fn new(spec: FamilySpec, params: Vec<f64>, dirs: HemiGrid) -> BrdfTensor {
        let dv: Vec<[f64; 3]> = (0..dirs.len()).map(|n| dirs.dir(n)).collect();
        BrdfTensor::from_rows(spec, params, dirs, |p, o, row| {
            for (v, wi) in row.iter_mut().zip(&dv) {
                *v = eval_pair(spec, p, dv[o], *wi);
            }
        })
    }

    /// A tensor whose raw (unscaled) values `F(p, o, .)` over the incident directions are
    /// written by `row(p, o, out)`; scaled and normalized as [`BrdfTensor::new`]. Slabs are
    /// computed in parallel, each value independently, so the result does not depend on the
    /// thread count.
    pub fn from_rows(
        spec: FamilySpec,
        params: Vec<f64>,
        dirs: HemiGrid,
        row: impl Fn(f64, usize, &mut [f64]) + Sync,
    ) -> BrdfTensor {
        let nd = dirs.len();
        let dir_scale: Vec<f64> = (0..nd)
            .map(|n| (dirs.dir(n)[2] * dirs.solid_angle()).sqrt())
            .collect();
        let slabs: Vec<(Vec<f64>, f64)> = params
            .par_iter()
            .map(|&p| {
                let mut s = vec![0.0; nd * nd];
                for (o, r) in s.chunks_exact_mut(nd).enumerate() {
                    row(p, o, r);
                    for (v, si) in r.iter_mut().zip(&dir_scale) {
                        *v *= dir_scale[o] * si;
                    }
                }
                let norm = s.iter().map(|x| x * x).sum::<f64>().sqrt();
                let sc = if norm > 0.0 { 1.0 / norm } else { 0.0 };
                for x in s.iter_mut() {
                    *x *= sc;
                }
                (s, sc)
            })
            .collect();
        let mut data = Vec::with_capacity(params.len() * nd * nd);
        let mut lobe_scale = Vec::new();
        for (s, sc) in slabs {
            data.extend_from_slice(&s);
            lobe_scale.push(sc);
        }
        BrdfTensor {
            spec,
            params,
            dirs,
            data,
            dir_scale,
            lobe_scale,
        }
    }

    pub fn dims(&self) -> (usize, usize, usize) {
        (self.params.len(), self.dirs.len(), self.dirs.len())
    }
}

/// The sampled, scaled tensor of an **isotropic** lobe, stored by its ring rows.
///
/// The grid turns onto itself by one column (`2 pi / n_phi` about the normal), cells onto
/// cells, and an isotropic lobe turns with `wo`; so the tensor is equivariant,
/// `F(h, (j, k), (j', k')) = F(h, (j, 0), (j', k' - k mod n_phi))`, and the fibres of the first
/// node of every ring (`n_phi` times fewer than the tensor's) hold all of it. Everything
/// built from it (the split, [`hosvd_rings`], [`tucker_rings`]) works on those rows and
/// expands a slab at a time where it needs one; scaled and normalized as [`BrdfTensor`].
///
/// [`hosvd_rings`]: super::tucker::hosvd_rings
/// [`tucker_rings`]: super::tucker::tucker_rings
pub struct RingTensor {
    pub spec: FamilySpec,
    pub params: Vec<f64>,
    pub dirs: HemiGrid,
    /// `[h][j][i]`: the fibres `F(h, (j, 0), .)` (see [`ring_offset`]).
    pub rings: Vec<f64>,
    /// Per-direction scale `sqrt(cos(theta) dw)`.
    pub dir_scale: Vec<f64>,
    /// Per-lobe normalization applied (1 / cosine-weighted norm).
    pub lobe_scale: Vec<f64>,
}

impl RingTensor {
    /// The tensor whose raw (unscaled) values `F(p, o, .)` over the incident directions are
    /// written by `row(p, o, out)`, which must be invariant under the grid's rotations (it is
    /// called for `o` the first node of every ring only). Rows are computed in parallel, each
    /// independently, so the result does not depend on the thread count.
    pub fn new(
        spec: FamilySpec,
        params: Vec<f64>,
        dirs: HemiGrid,
        row: impl Fn(f64, usize, &mut [f64]) + Sync,
    ) -> RingTensor {
        let (nd, nt, np) = (dirs.len(), dirs.n_theta, dirs.n_phi);
        let nh = params.len();
        let dir_scale: Vec<f64> = (0..nd)
            .map(|n| (dirs.dir(n)[2] * dirs.solid_angle()).sqrt())
            .collect();
        let mut rings = vec![0.0; nh * nt * nd];
        rings.par_chunks_mut(nd).enumerate().for_each(|(n, r)| {
            let (h, j) = (n / nt, n % nt);
            let o = dirs.index(j, 0);
            row(params[h], o, r);
            for (v, si) in r.iter_mut().zip(&dir_scale) {
                *v *= dir_scale[o] * si;
            }
        });
        // every ring row stands for n_phi rows of the slab with the same values
        let lobe_scale: Vec<f64> = rings
            .chunks_exact_mut(nt * nd)
            .map(|slab| {
                let norm = (np as f64 * slab.iter().map(|x| x * x).sum::<f64>()).sqrt();
                let sc = if norm > 0.0 { 1.0 / norm } else { 0.0 };
                for x in slab.iter_mut() {
                    *x *= sc;
                }
                sc
            })
            .collect();
        RingTensor {
            spec,
            params,
            dirs,
            rings,
            dir_scale,
            lobe_scale,
        }
    }

    pub fn dims(&self) -> (usize, usize, usize) {
        (self.params.len(), self.dirs.len(), self.dirs.len())
    }

    /// `F(h, o, i)`.
    pub fn at(&self, h: usize, o: usize, i: usize) -> f64 {
        let d = &self.dirs;
        self.rings[h * d.n_theta * d.len() + ring_offset(*d, o, i)]
    }

    /// The full tensor `[h][o][i]` ([`expand_rings`]).
    pub fn expand(&self) -> Vec<f64> {
        expand_rings(&self.rings, self.params.len(), self.dirs)
    }
}

/// Where `X(h, o, i)` of an equivariant tensor sits in slab `h` of its ring rows (`[j][i]`):
/// `X(h, (j, k), (j', k')) = rings(h, j, (j', k' - k mod n_phi))`.
pub fn ring_offset(dirs: HemiGrid, o: usize, i: usize) -> usize {
    let np = dirs.n_phi;
    let (j, k) = (o / np, o % np);
    let (jp, kp) = (i / np, i % np);
    j * dirs.len() + jp * np + (kp + np - k) % np
}

/// One slab `[o][i]` of an equivariant tensor from its ring rows `ring` (`[j][i]`): row
/// `(j, k)` is row `j` turned by `k` columns. Pure copies, so exact.
pub fn expand_slab(ring: &[f64], dirs: HemiGrid, out: &mut [f64]) {
    let (nd, np) = (dirs.len(), dirs.n_phi);
    for (o, row) in out.chunks_exact_mut(nd).enumerate() {
        let (j, k) = (o / np, o % np);
        rotate_row(&ring[j * nd..][..nd], k, np, row);
    }
}

/// Expands ring rows `[h][j][i]` (the fibres of the first node of every ring) into the full
/// tensor `[h][o][i]` by rotation: row `(h, (j, k))` is row `(h, j)` turned by `k` columns,
/// `out(j', k') = row(j', k' - k mod n_phi)`. Pure copies, so exact.
pub fn expand_rings(ring: &[f64], nh: usize, dirs: HemiGrid) -> Vec<f64> {
    let (nd, nt) = (dirs.len(), dirs.n_theta);
    assert_eq!(ring.len(), nh * nt * nd);
    let mut data = vec![0.0; nh * nd * nd];
    if nd > 0 {
        data.par_chunks_mut(nd * nd)
            .zip(ring.par_chunks(nt * nd))
            .for_each(|(slab, rows)| expand_slab(rows, dirs, slab));
    }
    data
}

/// `out(j', k') = row(j', k' - k mod n_phi)` over a grid with `np` columns per ring.
fn rotate_row(row: &[f64], k: usize, np: usize, out: &mut [f64]) {
    for (src, dst) in row.chunks_exact(np).zip(out.chunks_exact_mut(np)) {
        dst[k..].copy_from_slice(&src[..np - k]);
        dst[..k].copy_from_slice(&src[np - k..]);
    }
}

fn eval_pair(spec: FamilySpec, p: f64, wo: [f64; 3], wi: [f64; 3]) -> f64 {
    let to = wo[2].clamp(-1.0, 1.0).acos();
    let ti = wi[2].clamp(-1.0, 1.0).acos();
    let lo = (wo[0] * wo[0] + wo[1] * wo[1]).sqrt();
    let li = (wi[0] * wi[0] + wi[1] * wi[1]).sqrt();
    let cp = if lo * li > 1e-300 {
        ((wo[0] * wi[0] + wo[1] * wi[1]) / (lo * li)).clamp(-1.0, 1.0)
    } else {
        1.0
    };
    lobe_f64(spec.family, p, ti, to, cp.acos())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::Family;

    fn close(a: &[f64], b: &[f64], tol: f64) {
        assert_eq!(a.len(), b.len());
        let m = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= tol * m, "{x} vs {y}");
        }
    }

    /// An isotropic lobe sampled by its ring rows is the lobe sampled everywhere.
    #[test]
    fn ring_tensor_is_the_lobe_sampled_everywhere() {
        let dirs = HemiGrid {
            n_theta: 4,
            n_phi: 12,
        };
        let spec = FamilySpec::default_for(Family::Ggx).unwrap();
        let params = vec![0.1, 0.4];
        let dv: Vec<[f64; 3]> = (0..dirs.len()).map(|n| dirs.dir(n)).collect();
        let r = RingTensor::new(spec, params.clone(), dirs, |p, o, row| {
            for (v, wi) in row.iter_mut().zip(&dv) {
                *v = eval_pair(spec, p, dv[o], *wi);
            }
        });
        let t = BrdfTensor::new(spec, params, dirs);
        close(&r.expand(), &t.data, 1e-10);
        close(&r.lobe_scale, &t.lobe_scale, 1e-12);
        let nd = dirs.len();
        let at: Vec<f64> = (0..t.data.len())
            .map(|n| r.at(n / (nd * nd), n / nd % nd, n % nd))
            .collect();
        close(&at, &t.data, 1e-10);
    }
}
