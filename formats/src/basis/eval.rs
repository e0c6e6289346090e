//! Evaluation of the basis tables, identical in the baker and the runtime: the grid
//! coordinates of a direction pair, the trilinear weights ([`GridWeights`]) and the
//! interpolated values of all bases.

use std::f32::consts::{FRAC_PI_2, PI};

use super::{BrdfBasis, GridKind, HALF_DIFF_COS_OFFSET};

/// Bases up to this count are accumulated in registers by [`BrdfBasis::eval_weights`].
const MAX_REGISTER_BASES: usize = 16;

/// Fast `acos` (Abramowitz & Stegun 4.4.46, |error| <= 2e-8 in exact arithmetic), used so
/// that the baker and the runtime evaluate the tables identically and quickly. `x` is clamped
/// to [-1, 1].
#[inline]
#[allow(clippy::excessive_precision)]
pub fn fast_acos(x: f32) -> f32 {
    let x = x.clamp(-1.0, 1.0);
    let a = x.abs();
    let p = -0.001_262_491_1_f32;
    let p = p * a + 0.006_670_090_1;
    let p = p * a - 0.017_088_125_6;
    let p = p * a + 0.030_891_881_0;
    let p = p * a - 0.050_174_304_6;
    let p = p * a + 0.088_978_987_4;
    let p = p * a - 0.214_598_801_6;
    let p = p * a + 1.570_796_305_0;
    let r = (1.0 - a).max(0.0).sqrt() * p;
    if x >= 0.0 {
        r
    } else {
        PI - r
    }
}

/// `1 / (1 + c0)` and `1 / ln(c0 / (1 + c0))` of the `theta_d` axis, in f32.
const HD_INV_1C0: f32 = (1.0 / (1.0 + HALF_DIFF_COS_OFFSET)) as f32;
const HD_C0: f32 = HALF_DIFF_COS_OFFSET as f32;
/// `1 / ln(c0 / (1 + c0))` for `c0 = 0.01` (checked against f64 by a unit test).
pub(super) const HD_INV_LN: f32 = -0.216_679_07;

/// `x` clamped to `[lo, hi]`, or `nan` when `x` is NaN.
#[inline]
fn clamp_or(x: f32, lo: f32, hi: f32, nan: f32) -> f32 {
    if x.is_nan() {
        nan
    } else {
        x.clamp(lo, hi)
    }
}

/// [`GridKind::HalfDiff`] coordinates `(u1, u2, u3)` of the pair `(wi, wo)` given `wi` and the
/// unnormalized half vector `h = wi + wo` (directions of unit length, above the horizon).
/// `cos theta_d = |h| / 2`; `1 - cos theta_h = (hx^2 + hy^2) / (|h| (|h| + hz))` (stable at the
/// pole); `sin^2 phi_d = a^2 / (a^2 + b^2)` with `a = |h| (wi x h)_z` and
/// `b = hz (wi_xy . h_xy) - wi_z (hx^2 + hy^2)`, the components of `wi` along the `phi` and
/// `theta` directions of the half vector's frame, times `|h| |h_xy|`. At the pole (`h_xy = 0`)
/// `u3 = 0`; the tables do not depend on `phi_d` there.
#[inline]
fn half_diff_coords(wi: [f32; 3], h: [f32; 3]) -> [f32; 3] {
    let r2 = h[0] * h[0] + h[1] * h[1];
    let l = (r2 + h[2] * h[2]).sqrt();
    let den = l * (l + h[2]);
    // h = 0 only for opposite pairs on the horizon; along cos_phi = -1 the half vector tends
    // to the normal there (|h_xy| is quadratic, h_z linear in the elevations)
    let omc = if den > 0.0 { (r2 / den).min(1.0) } else { 0.0 };
    let u1 = omc.sqrt().sqrt();
    let cd = (0.5 * l).min(1.0);
    let u2 = ((cd + HD_C0) * HD_INV_1C0).ln() * HD_INV_LN;
    let a = l * (wi[1] * h[0] - wi[0] * h[1]);
    let b = h[2] * (wi[0] * h[0] + wi[1] * h[1]) - wi[2] * r2;
    let a2 = a * a;
    let d = a2 + b * b;
    let u3 = if d > 0.0 { (a2 / d).min(1.0) } else { 0.0 };
    [u1, u2, u3]
}

/// Trilinear interpolation weights over the angular grid, shared by all bases.
#[derive(Clone, Copy, Debug)]
pub struct GridWeights {
    /// Flat node index (without the basis factor) of the (i0, o0, k0) corner.
    pub base: usize,
    /// Node stride for +1 along the first axis (theta_i, or theta_h); the phi stride is 1.
    pub stride_i: usize,
    /// Node stride for +1 along the second axis (theta_o, or theta_d).
    pub stride_o: usize,
    /// Fraction, in `[0, 1]`, of the way from the `i0` node to the next along the first axis.
    pub fi: f32,
    /// The same along the second axis.
    pub fo: f32,
    /// The same along the third axis (phi, or phi_d).
    pub fp: f32,
}

#[inline]
fn axis(t: f32, n: usize) -> (usize, f32) {
    // t in node units, clamped to [0, n-1]
    let t = if t.is_nan() {
        0.0
    } else {
        t.clamp(0.0, (n - 1) as f32)
    };
    let i0 = (t as usize).min(n - 2);
    (i0, (t - i0 as f32).clamp(0.0, 1.0))
}

impl BrdfBasis {
    /// Interpolation weights for a direction pair given by cosines: `cos_theta_i`,
    /// `cos_theta_o` (clamped to [0, 1]) and `cos_phi`, the cosine of the angle between the
    /// tangent-plane projections of wi and wo (any value works when one is along the normal).
    #[inline]
    pub fn weights(&self, cos_theta_i: f32, cos_theta_o: f32, cos_phi: f32) -> GridWeights {
        match self.grid_kind {
            GridKind::Angles => self.weights_angles(cos_theta_i, cos_theta_o, cos_phi),
            GridKind::HalfDiff => {
                let ci = clamp_or(cos_theta_i, 0.0, 1.0, 0.0);
                let co = clamp_or(cos_theta_o, 0.0, 1.0, 0.0);
                let cp = clamp_or(cos_phi, -1.0, 1.0, 1.0);
                let si = (1.0 - ci * ci).max(0.0).sqrt();
                let so = (1.0 - co * co).max(0.0).sqrt();
                let sp = (1.0 - cp * cp).max(0.0).sqrt();
                let wi = [si, 0.0, ci];
                let h = [si + so * cp, so * sp, ci + co];
                self.grid_weights(half_diff_coords(wi, h))
            }
        }
    }

    /// [`BrdfBasis::weights`] for local-frame unit vectors (normal = +Z, both pointing away
    /// from the surface, both above the horizon).
    #[inline]
    pub fn weights_local(&self, wi: [f32; 3], wo: [f32; 3]) -> GridWeights {
        match self.grid_kind {
            GridKind::Angles => {
                let (cp, _) = cos_phi_local(wi, wo);
                self.weights_angles(wi[2], wo[2], cp)
            }
            GridKind::HalfDiff => {
                let h = [
                    wi[0] + wo[0],
                    wi[1] + wo[1],
                    wi[2].max(0.0) + wo[2].max(0.0),
                ];
                self.grid_weights(half_diff_coords(wi, h))
            }
        }
    }

    /// Weights from grid coordinates `u` in `[0, 1]` (nodes uniform in them).
    #[inline]
    fn grid_weights(&self, u: [f32; 3]) -> GridWeights {
        let g = &self.grid;
        let (i0, fi) = axis(u[0] * (g.n_theta_i - 1) as f32, g.n_theta_i);
        let (o0, fo) = axis(u[1] * (g.n_theta_o - 1) as f32, g.n_theta_o);
        let (k0, fp) = axis(u[2] * (g.n_phi - 1) as f32, g.n_phi);
        GridWeights {
            base: g.index(i0, o0, k0),
            stride_i: g.n_theta_o * g.n_phi,
            stride_o: g.n_phi,
            fi,
            fo,
            fp,
        }
    }

    #[inline]
    fn weights_angles(&self, cos_theta_i: f32, cos_theta_o: f32, cos_phi: f32) -> GridWeights {
        let ti = fast_acos(cos_theta_i.max(0.0));
        let to = fast_acos(cos_theta_o.max(0.0));
        let ph = fast_acos(cos_phi);
        self.grid_weights([ti / FRAC_PI_2, to / FRAC_PI_2, ph / PI])
    }

    /// All basis values at the interpolation point `w`; `out` must hold `num_bases` values.
    #[inline]
    pub fn eval_weights(&self, w: &GridWeights, out: &mut [f32]) {
        let nb = self.num_bases;
        let t = &self.tables;
        let corners = [
            (0, (1.0 - w.fi) * (1.0 - w.fo)),
            (w.stride_o, (1.0 - w.fi) * w.fo),
            (w.stride_i, w.fi * (1.0 - w.fo)),
            (w.stride_i + w.stride_o, w.fi * w.fo),
        ];
        if nb <= MAX_REGISTER_BASES {
            // accumulate in a local array (kept in registers) rather than through `out`
            let mut acc = [0.0f32; MAX_REGISTER_BASES];
            for (off, wio) in corners {
                let n0 = (w.base + off) * nb;
                let (lo, hi) = t[n0..n0 + 2 * nb].split_at(nb);
                let (w0, w1) = (wio * (1.0 - w.fp), wio * w.fp);
                for b in 0..nb {
                    acc[b] += w0 * lo[b] + w1 * hi[b];
                }
            }
            out[..nb].copy_from_slice(&acc[..nb]);
            return;
        }
        let out = &mut out[..nb];
        out.fill(0.0);
        for (off, wio) in corners {
            let n0 = (w.base + off) * nb;
            let (lo, hi) = t[n0..n0 + 2 * nb].split_at(nb);
            let (w0, w1) = (wio * (1.0 - w.fp), wio * w.fp);
            for b in 0..nb {
                out[b] += w0 * lo[b] + w1 * hi[b];
            }
        }
    }

    /// All basis values `basis_b(wi, wo)` for a direction pair given by cosines (see
    /// [`BrdfBasis::weights`]); `out` must hold `num_bases` values.
    #[inline]
    pub fn eval_all(&self, cos_theta_i: f32, cos_theta_o: f32, cos_phi: f32, out: &mut [f32]) {
        let w = self.weights(cos_theta_i, cos_theta_o, cos_phi);
        self.eval_weights(&w, out);
    }

    /// All basis values for local-frame unit vectors (normal = +Z, both pointing away from
    /// the surface). Directions below the horizon give zeros.
    #[inline]
    pub fn eval_all_local(&self, wi: [f32; 3], wo: [f32; 3], out: &mut [f32]) {
        if wi[2] <= 0.0 || wo[2] <= 0.0 || wi[2].is_nan() || wo[2].is_nan() {
            out[..self.num_bases].fill(0.0);
            return;
        }
        let w = self.weights_local(wi, wo);
        self.eval_weights(&w, out);
    }

    /// Value of the BRDF `Kd/pi + Ks lobe` reconstructed from the basis for one channel,
    /// given its coefficients `c` (from [`BrdfBasis::material_coefficients`] or
    /// `coefficients`). Convenience for tests and tools; the baker uses `eval_all`.
    pub fn reconstruct(&self, c: &[f32], cos_theta_i: f32, cos_theta_o: f32, cos_phi: f32) -> f32 {
        let mut v = vec![0.0; self.num_bases];
        self.eval_all(cos_theta_i, cos_theta_o, cos_phi, &mut v);
        v.iter().zip(c).map(|(a, b)| a * b).sum()
    }
}

/// Cosine of the azimuth difference of two local-frame directions, and whether it was
/// defined (false when either lies along the normal; then 1 is returned).
#[inline]
pub fn cos_phi_local(wi: [f32; 3], wo: [f32; 3]) -> (f32, bool) {
    let li = wi[0] * wi[0] + wi[1] * wi[1];
    let lo = wo[0] * wo[0] + wo[1] * wo[1];
    let d = li * lo;
    if d <= 1e-20 {
        return (1.0, false);
    }
    (
        ((wi[0] * wo[0] + wi[1] * wo[1]) / d.sqrt()).clamp(-1.0, 1.0),
        true,
    )
}
