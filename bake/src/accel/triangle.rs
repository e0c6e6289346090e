//! The watertight ray/triangle test of Woop, Benthin and Wald 2013 ("Watertight Ray/Triangle
//! Intersection", JCGT 2(1)), as in pbrt-v4 and Embree's robust mode.
//!
//! Why not Moeller-Trumbore: its edge tests are computed per triangle from different
//! quantities, so a ray through a shared edge or vertex can fail the test of every triangle
//! around it (a crack: measured 3 in 2M bounce rays on the 100K and 1M scenes, which then
//! found a farther surface). Here the ray is translated to the origin, its axes permuted so
//! that z is the largest direction component, and the triangle sheared so the ray is the +z
//! axis; the three 2D edge functions of a shared edge are then computed from the same
//! transformed vertices in every triangle that has it, with the same operations, so their
//! signs agree exactly (an exact zero is recomputed in f64). A point on an edge is inside one
//! of the two triangles, or both.

use glam::{Vec3, Vec3A, Vec4};

/// One triangle's vertices, for the one-at-a-time test (brute force, tests).
#[derive(Clone, Copy, Debug)]
pub(super) struct Tri {
    pub v: [Vec3A; 3],
}

/// The per-ray constants of the test: origin, axis permutation and shear.
#[derive(Clone, Copy, Debug)]
pub(super) struct RayTri {
    org: Vec3A,
    /// The origin's coordinates along kx, ky, kz.
    org_k: [f32; 3],
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

impl RayTri {
    #[inline(always)]
    pub fn new(origin: Vec3, dir: Vec3) -> RayTri {
        let a = dir.abs();
        let kz = if a.x > a.y {
            if a.x > a.z {
                0
            } else {
                2
            }
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Arrays: glam's `Vec3` indexing is a `match`, measurably slower per ray.
        let (d, o) = (dir.to_array(), origin.to_array());
        // Keep the winding: swapping x and y when the ray points down z.
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        RayTri {
            org: origin.into(),
            org_k: [o[kx], o[ky], o[kz]],
            kx,
            ky,
            kz,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }
}

/// Two-sided test. Returns (t, b1, b2) with t in (tmin, tmax) (strictly) and b1, b2 the
/// barycentrics of vertices 1 and 2.
#[inline(always)]
pub(super) fn intersect(tri: &Tri, r: &RayTri, tmin: f32, tmax: f32) -> Option<(f32, f32, f32)> {
    let a = (tri.v[0] - r.org).to_array();
    let b = (tri.v[1] - r.org).to_array();
    let c = (tri.v[2] - r.org).to_array();
    // `& 3` lets the compiler drop the bounds checks (the indices are below 3).
    let (kx, ky, kz) = (r.kx & 3, r.ky & 3, r.kz & 3);
    let (a, b, c) = (pad(a), pad(b), pad(c));
    let ax = a[kx] - r.sx * a[kz];
    let ay = a[ky] - r.sy * a[kz];
    let bx = b[kx] - r.sx * b[kz];
    let by = b[ky] - r.sy * b[kz];
    let cx = c[kx] - r.sx * c[kz];
    let cy = c[ky] - r.sy * c[kz];
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    if u == 0.0 || v == 0.0 || w == 0.0 {
        // On an edge in f32: decide in f64, where these products are exact.
        let (ax, ay, bx, by, cx, cy) = (
            ax as f64, ay as f64, bx as f64, by as f64, cx as f64, cy as f64,
        );
        u = (cx * by - cy * bx) as f32;
        v = (ax * cy - ay * cx) as f32;
        w = (bx * ay - by * ax) as f32;
    }
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let t_scaled = u * (r.sz * a[kz]) + v * (r.sz * b[kz]) + w * (r.sz * c[kz]);
    let t = t_scaled / det;
    // Written so a NaN fails.
    if !(t > tmin && t < tmax) {
        return None;
    }
    Some((t, v / det, w / det))
}

#[inline(always)]
fn pad(v: [f32; 3]) -> [f32; 4] {
    [v[0], v[1], v[2], 0.0]
}

/// [`intersect`] on the `n` (1 to 4) triangles of a leaf at once, four lanes, with the same
/// operations in the same order per lane, so a lane's t and barycentrics are bit for bit those
/// of [`intersect`] on its triangle. `rows` holds the leaf's coordinates as nine rows of `n`
/// (row 3 * vertex + axis, lane = triangle) and at least 4 - n more values, which fill the
/// unused lanes and are ignored. Closest hit (`ANY` false): the lane of least t (the lowest
/// lane of equal ones) as (lane, t, b1, b2); `ANY`: the first lane that hits.
#[inline(always)]
pub(super) fn intersect4<const ANY: bool>(
    rows: &[f32],
    n: usize,
    r: &RayTri,
    tmin: f32,
    tmax: f32,
) -> Option<(usize, f32, f32, f32)> {
    let (kx, ky, kz) = (r.kx, r.ky, r.kz);
    let [okx, oky, okz] = r.org_k;
    // One bounds check for the whole leaf: its nine rows of n and the lanes past them.
    let rows = &rows[..8 * n + 4];
    let row = |vertex: usize, axis: usize, o: f32| {
        let at = (3 * vertex + axis) * n;
        debug_assert!(vertex < 3 && axis < 3);
        // SAFETY: vertex < 3 and axis < 3 (`RayTri::new` makes kx, ky, kz so), hence
        // at <= 8 n and at + 4 <= 8 n + 4 = rows.len().
        Vec4::from_slice(unsafe { rows.get_unchecked(at..at + 4) }) - Vec4::splat(o)
    };
    let (sx, sy, sz) = (Vec4::splat(r.sx), Vec4::splat(r.sy), Vec4::splat(r.sz));
    // Vertex k translated, sheared along the permuted x and y; its z unsheared.
    let (pz0, pz1, pz2) = (row(0, kz, okz), row(1, kz, okz), row(2, kz, okz));
    let ax = row(0, kx, okx) - sx * pz0;
    let ay = row(0, ky, oky) - sy * pz0;
    let bx = row(1, kx, okx) - sx * pz1;
    let by = row(1, ky, oky) - sy * pz1;
    let cx = row(2, kx, okx) - sx * pz2;
    let cy = row(2, ky, oky) - sy * pz2;
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    let lanes = (1u32 << n) - 1;
    let zero = Vec4::ZERO;
    let on_edge = (u.cmpeq(zero) | v.cmpeq(zero) | w.cmpeq(zero)).bitmask() & lanes;
    if on_edge != 0 {
        // On an edge in f32: decide in f64, as `intersect` does (rare, so lane by lane).
        let (mut uu, mut vv, mut ww) = (u.to_array(), v.to_array(), w.to_array());
        let (ax, ay, bx, by, cx, cy) = (
            ax.to_array(),
            ay.to_array(),
            bx.to_array(),
            by.to_array(),
            cx.to_array(),
            cy.to_array(),
        );
        let mut m = on_edge;
        while m != 0 {
            let l = m.trailing_zeros() as usize;
            m &= m - 1;
            let (ax, ay, bx, by, cx, cy) = (
                ax[l] as f64,
                ay[l] as f64,
                bx[l] as f64,
                by[l] as f64,
                cx[l] as f64,
                cy[l] as f64,
            );
            uu[l] = (cx * by - cy * bx) as f32;
            vv[l] = (ax * cy - ay * cx) as f32;
            ww[l] = (bx * ay - by * ax) as f32;
        }
        (u, v, w) = (Vec4::from(uu), Vec4::from(vv), Vec4::from(ww));
    }
    let negative = u.cmplt(zero) | v.cmplt(zero) | w.cmplt(zero);
    let positive = u.cmpgt(zero) | v.cmpgt(zero) | w.cmpgt(zero);
    let det = u + v + w;
    let t = (u * (sz * pz0) + v * (sz * pz1) + w * (sz * pz2)) / det;
    // `intersect`'s checks; written so a NaN fails (an |det| of inf or NaN is not < inf).
    let ok = det.cmpne(zero)
        & det.abs().cmplt(Vec4::INFINITY)
        & t.cmpgt(Vec4::splat(tmin))
        & t.cmplt(Vec4::splat(tmax));
    let hit = ok.bitmask() & !(negative & positive).bitmask() & lanes;
    if hit == 0 {
        return None;
    }
    let (t, det, v, w) = (t.to_array(), det.to_array(), v.to_array(), w.to_array());
    let mut best = hit.trailing_zeros() as usize;
    if !ANY {
        let mut rest = hit & (hit - 1);
        while rest != 0 {
            let l = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            if t[l] < t[best] {
                best = l;
            }
        }
    }
    Some((best, t[best], v[best] / det[best], w[best] / det[best]))
}
