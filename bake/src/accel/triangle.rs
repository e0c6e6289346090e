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

use glam::{Vec3, Vec3A};

/// One triangle's vertices, for the one-at-a-time test (brute force, tests).
#[derive(Clone, Copy, Debug)]
pub(super) struct Tri {
    pub v: [Vec3A; 3],
}

/// Up to four triangles of one BVH leaf, structure of arrays, tested at once by
/// [`intersect4`]: `v[3 * vertex + axis][lane]`. Unused lanes hold NaN vertices, which never
/// pass the test (their t is NaN). 160 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(super) struct Tri4 {
    pub v: [[f32; 4]; 9],
    /// Scene triangle index of each lane.
    pub id: [u32; 4],
}

impl Tri4 {
    /// The triangles `ids` (at most four) of `tris`.
    pub fn new(ids: &[u32], tris: &[[Vec3A; 3]]) -> Tri4 {
        debug_assert!(ids.len() <= 4);
        let mut t = Tri4 {
            v: [[f32::NAN; 4]; 9],
            id: [u32::MAX; 4],
        };
        for (lane, &id) in ids.iter().enumerate().take(4) {
            for (k, vertex) in tris[id as usize].iter().enumerate() {
                for axis in 0..3 {
                    t.v[3 * k + axis][lane] = vertex[axis];
                }
            }
            t.id[lane] = id;
        }
        t
    }
}

/// The per-ray constants of the test: origin, axis permutation and shear.
#[derive(Clone, Copy, Debug)]
pub(super) struct RayTri {
    org: Vec3A,
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
        // Keep the winding: swapping x and y when the ray points down z.
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        RayTri {
            org: origin.into(),
            kx,
            ky,
            kz,
            sx: dir[kx] / dir[kz],
            sy: dir[ky] / dir[kz],
            sz: 1.0 / dir[kz],
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

/// [`intersect`] on the four lanes of a leaf at once, with the same operations in the same
/// order per lane, so a lane's t and barycentrics are bit for bit those of [`intersect`] on
/// its triangle. Closest hit (`ANY` false): the lane of least t (the lowest lane of equal
/// ones) as (lane, t, b1, b2); `ANY`: the first lane that hits.
#[inline(always)]
pub(super) fn intersect4<const ANY: bool>(
    tri: &Tri4,
    r: &RayTri,
    tmin: f32,
    tmax: f32,
) -> Option<(usize, f32, f32, f32)> {
    let o = r.org.to_array();
    // `% 3`/`& 3` let the compiler drop the bounds checks.
    let (kx, ky, kz) = (r.kx % 3, r.ky % 3, r.kz % 3);
    let sub = |vertex: usize, axis: usize| -> [f32; 4] {
        let p = &tri.v[(3 * vertex + axis) % 9];
        std::array::from_fn(|l| p[l] - o[axis])
    };
    // Vertex k translated (x, y along the permuted axes, z unsheared).
    let mut xs = [[0.0f32; 4]; 3];
    let mut ys = [[0.0f32; 4]; 3];
    let mut zs = [[0.0f32; 4]; 3];
    for k in 0..3 {
        let (px, py, pz) = (sub(k, kx), sub(k, ky), sub(k, kz));
        for l in 0..4 {
            xs[k][l] = px[l] - r.sx * pz[l];
            ys[k][l] = py[l] - r.sy * pz[l];
        }
        zs[k] = pz;
    }
    let ([ax, bx, cx], [ay, by, cy]) = (xs, ys);
    let mut u = [0.0f32; 4];
    let mut v = [0.0f32; 4];
    let mut w = [0.0f32; 4];
    let mut zero = false;
    for l in 0..4 {
        u[l] = cx[l] * by[l] - cy[l] * bx[l];
        v[l] = ax[l] * cy[l] - ay[l] * cx[l];
        w[l] = bx[l] * ay[l] - by[l] * ax[l];
        zero |= (u[l] == 0.0) | (v[l] == 0.0) | (w[l] == 0.0);
    }
    if zero {
        // On an edge in f32: decide in f64, as `intersect` does (rare, so not vectorized).
        for l in 0..4 {
            if u[l] == 0.0 || v[l] == 0.0 || w[l] == 0.0 {
                let (ax, ay, bx, by, cx, cy) = (
                    ax[l] as f64,
                    ay[l] as f64,
                    bx[l] as f64,
                    by[l] as f64,
                    cx[l] as f64,
                    cy[l] as f64,
                );
                u[l] = (cx * by - cy * bx) as f32;
                v[l] = (ax * cy - ay * cx) as f32;
                w[l] = (bx * ay - by * ax) as f32;
            }
        }
    }
    let mut t = [0.0f32; 4];
    let mut det = [0.0f32; 4];
    let mut hit = 0u32;
    for l in 0..4 {
        let outside =
            (u[l] < 0.0 || v[l] < 0.0 || w[l] < 0.0) && (u[l] > 0.0 || v[l] > 0.0 || w[l] > 0.0);
        det[l] = u[l] + v[l] + w[l];
        let t_scaled =
            u[l] * (r.sz * zs[0][l]) + v[l] * (r.sz * zs[1][l]) + w[l] * (r.sz * zs[2][l]);
        t[l] = t_scaled / det[l];
        // `intersect`'s checks; written so a NaN fails (an |det| of inf or NaN is not < inf).
        let ok =
            !outside && det[l] != 0.0 && det[l].abs() < f32::INFINITY && t[l] > tmin && t[l] < tmax;
        hit |= (ok as u32) << l;
    }
    if hit == 0 {
        return None;
    }
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
