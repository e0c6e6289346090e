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

/// Sixteen lanes of f32, for [`intersect16`]: IEEE operations lane by lane, so every
/// implementation gives the same bits. [`Portable16`] is plain Rust, [`Avx2x16`] two AVX
/// 256-bit vectors, [`Avx512x16`] one 512-bit vector (left to itself the compiler
/// scalarized the portable code's lane masks, hence the intrinsics).
pub(super) trait Lanes: Copy {
    /// # Safety
    /// `p` must point to sixteen readable f32 (any alignment).
    unsafe fn load(p: *const f32) -> Self;
    fn splat(x: f32) -> Self;
    fn to_array(self) -> [f32; 16];
    fn from_array(a: [f32; 16]) -> Self;
    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn div(self, o: Self) -> Self;
    /// Bit i set where lane i of self == o (false on NaN), and so on.
    fn eq(self, o: Self) -> u32;
    fn lt(self, o: Self) -> u32;
    fn gt(self, o: Self) -> u32;
    /// Where `self != o` (true on NaN).
    fn ne(self, o: Self) -> u32;
    /// Where |self| < inf (false on NaN).
    fn finite(self) -> u32;
}

/// Plain Rust lanes.
#[derive(Clone, Copy)]
pub(super) struct Portable16([f32; 16]);

impl Portable16 {
    #[inline(always)]
    fn map(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let mut r = self.0;
        for (r, o) in r.iter_mut().zip(o.0) {
            *r = f(*r, o);
        }
        Portable16(r)
    }

    #[inline(always)]
    fn mask(self, o: Self, f: impl Fn(f32, f32) -> bool) -> u32 {
        let mut m = 0;
        for i in 0..16 {
            m |= (f(self.0[i], o.0[i]) as u32) << i;
        }
        m
    }
}

impl Lanes for Portable16 {
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        // SAFETY: the caller's.
        Portable16(unsafe { (p as *const [f32; 16]).read_unaligned() })
    }
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Portable16([x; 16])
    }
    #[inline(always)]
    fn to_array(self) -> [f32; 16] {
        self.0
    }
    #[inline(always)]
    fn from_array(a: [f32; 16]) -> Self {
        Portable16(a)
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self.map(o, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self.map(o, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.map(o, |a, b| a * b)
    }
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        self.map(o, |a, b| a / b)
    }
    #[inline(always)]
    fn eq(self, o: Self) -> u32 {
        self.mask(o, |a, b| a == b)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> u32 {
        self.mask(o, |a, b| a < b)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> u32 {
        self.mask(o, |a, b| a > b)
    }
    #[inline(always)]
    fn ne(self, o: Self) -> u32 {
        self.mask(o, |a, b| a != b)
    }
    #[inline(always)]
    fn finite(self) -> u32 {
        self.mask(self, |a, _| a.abs() < f32::INFINITY)
    }
}

/// Two AVX 256-bit vectors; only used inside `Accel`'s AVX2 path (the intrinsics are
/// inlined there), after the CPU was checked.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct Avx2x16([std::arch::x86_64::__m256; 2]);

/// One AVX-512 vector; only used inside `Accel`'s AVX-512 path, after the CPU was checked.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct Avx512x16(std::arch::x86_64::__m512);

#[cfg(target_arch = "x86_64")]
mod simd {
    // `crate::` rather than `super::`: this is a module inside triangle.rs, whose items it
    // implements (and .ci/import_circles.py reads `super::` as the file's parent).
    use crate::accel::triangle::{Avx2x16, Avx512x16, Lanes};
    use std::arch::x86_64::*;

    macro_rules! avx2_op {
        ($a:expr, $b:expr, $f:ident) => {
            Avx2x16([$f($a.0[0], $b.0[0]), $f($a.0[1], $b.0[1])])
        };
    }
    macro_rules! avx2_cmp {
        ($a:expr, $b:expr, $c:ident) => {
            (_mm256_movemask_ps(_mm256_cmp_ps::<$c>($a.0[0], $b.0[0]))
                | _mm256_movemask_ps(_mm256_cmp_ps::<$c>($a.0[1], $b.0[1])) << 8) as u32
        };
    }

    // SAFETY (all): an `Avx2x16` exists only on the AVX2 path, where the CPU has AVX.
    impl Lanes for Avx2x16 {
        #[inline(always)]
        unsafe fn load(p: *const f32) -> Self {
            unsafe { Avx2x16([_mm256_loadu_ps(p), _mm256_loadu_ps(p.add(8))]) }
        }
        #[inline(always)]
        fn splat(x: f32) -> Self {
            unsafe { Avx2x16([_mm256_set1_ps(x); 2]) }
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 16] {
            let mut a = [0.0; 16];
            unsafe {
                _mm256_storeu_ps(a.as_mut_ptr(), self.0[0]);
                _mm256_storeu_ps(a.as_mut_ptr().add(8), self.0[1]);
            }
            a
        }
        #[inline(always)]
        fn from_array(a: [f32; 16]) -> Self {
            unsafe { Self::load(a.as_ptr()) }
        }
        #[inline(always)]
        fn add(self, o: Self) -> Self {
            unsafe { avx2_op!(self, o, _mm256_add_ps) }
        }
        #[inline(always)]
        fn sub(self, o: Self) -> Self {
            unsafe { avx2_op!(self, o, _mm256_sub_ps) }
        }
        #[inline(always)]
        fn mul(self, o: Self) -> Self {
            unsafe { avx2_op!(self, o, _mm256_mul_ps) }
        }
        #[inline(always)]
        fn div(self, o: Self) -> Self {
            unsafe { avx2_op!(self, o, _mm256_div_ps) }
        }
        #[inline(always)]
        fn eq(self, o: Self) -> u32 {
            unsafe { avx2_cmp!(self, o, _CMP_EQ_OQ) }
        }
        #[inline(always)]
        fn lt(self, o: Self) -> u32 {
            unsafe { avx2_cmp!(self, o, _CMP_LT_OQ) }
        }
        #[inline(always)]
        fn gt(self, o: Self) -> u32 {
            unsafe { avx2_cmp!(self, o, _CMP_GT_OQ) }
        }
        #[inline(always)]
        fn ne(self, o: Self) -> u32 {
            unsafe { avx2_cmp!(self, o, _CMP_NEQ_UQ) }
        }
        #[inline(always)]
        fn finite(self) -> u32 {
            unsafe {
                let m = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
                let abs = Avx2x16([_mm256_and_ps(self.0[0], m), _mm256_and_ps(self.0[1], m)]);
                avx2_cmp!(abs, Self::splat(f32::INFINITY), _CMP_LT_OQ)
            }
        }
    }

    // SAFETY (all): an `Avx512x16` exists only on the AVX-512 path, where the CPU has
    // AVX-512 F.
    impl Lanes for Avx512x16 {
        #[inline(always)]
        unsafe fn load(p: *const f32) -> Self {
            unsafe { Avx512x16(_mm512_loadu_ps(p)) }
        }
        #[inline(always)]
        fn splat(x: f32) -> Self {
            unsafe { Avx512x16(_mm512_set1_ps(x)) }
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 16] {
            let mut a = [0.0; 16];
            unsafe { _mm512_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
        #[inline(always)]
        fn from_array(a: [f32; 16]) -> Self {
            unsafe { Self::load(a.as_ptr()) }
        }
        #[inline(always)]
        fn add(self, o: Self) -> Self {
            unsafe { Avx512x16(_mm512_add_ps(self.0, o.0)) }
        }
        #[inline(always)]
        fn sub(self, o: Self) -> Self {
            unsafe { Avx512x16(_mm512_sub_ps(self.0, o.0)) }
        }
        #[inline(always)]
        fn mul(self, o: Self) -> Self {
            unsafe { Avx512x16(_mm512_mul_ps(self.0, o.0)) }
        }
        #[inline(always)]
        fn div(self, o: Self) -> Self {
            unsafe { Avx512x16(_mm512_div_ps(self.0, o.0)) }
        }
        #[inline(always)]
        fn eq(self, o: Self) -> u32 {
            unsafe { _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(self.0, o.0) as u32 }
        }
        #[inline(always)]
        fn lt(self, o: Self) -> u32 {
            unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, o.0) as u32 }
        }
        #[inline(always)]
        fn gt(self, o: Self) -> u32 {
            unsafe { _mm512_cmp_ps_mask::<_CMP_GT_OQ>(self.0, o.0) as u32 }
        }
        #[inline(always)]
        fn ne(self, o: Self) -> u32 {
            unsafe { _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(self.0, o.0) as u32 }
        }
        #[inline(always)]
        fn finite(self) -> u32 {
            unsafe {
                let abs = _mm512_abs_ps(self.0);
                _mm512_cmp_ps_mask::<_CMP_LT_OQ>(abs, _mm512_set1_ps(f32::INFINITY)) as u32
            }
        }
    }
}

/// [`intersect`] on sixteen triangles at once: the lanes set in `active` of the block whose
/// row r (3 vertex + axis, lane = triangle) starts at `rows[r * stride]`, with the same
/// operations in the same order per lane, so a lane's t and barycentrics are bit for bit
/// those of [`intersect`] on its triangle. Closest hit (`ANY` false): the lane of least t
/// (the lowest lane of equal ones) as (lane, t, b1, b2); `ANY`: the first lane that hits.
///
/// # Safety
/// `rows` must hold `8 * stride + 16` values (sixteen lanes of each row), and `L`'s CPU
/// features must be present.
#[inline(always)]
pub(super) unsafe fn intersect16<const ANY: bool, L: Lanes>(
    rows: *const f32,
    stride: usize,
    active: u32,
    r: &RayTri,
    tmin: f32,
    tmax: f32,
) -> Option<(usize, f32, f32, f32)> {
    let (kx, ky, kz) = (r.kx, r.ky, r.kz);
    let [okx, oky, okz] = r.org_k;
    let row = |vertex: usize, axis: usize, o: f32| -> L {
        debug_assert!(vertex < 3 && axis < 3);
        // SAFETY: vertex, axis < 3 (`RayTri::new` makes kx, ky, kz so): at most row 8, whose
        // sixteen lanes the caller guarantees.
        unsafe { L::load(rows.add((3 * vertex + axis) * stride)) }.sub(L::splat(o))
    };
    let (sx, sy, sz) = (L::splat(r.sx), L::splat(r.sy), L::splat(r.sz));
    // Vertex k translated, sheared along the permuted x and y; its z unsheared.
    let (pz0, pz1, pz2) = (row(0, kz, okz), row(1, kz, okz), row(2, kz, okz));
    let ax = row(0, kx, okx).sub(sx.mul(pz0));
    let ay = row(0, ky, oky).sub(sy.mul(pz0));
    let bx = row(1, kx, okx).sub(sx.mul(pz1));
    let by = row(1, ky, oky).sub(sy.mul(pz1));
    let cx = row(2, kx, okx).sub(sx.mul(pz2));
    let cy = row(2, ky, oky).sub(sy.mul(pz2));
    let mut u = cx.mul(by).sub(cy.mul(bx));
    let mut v = ax.mul(cy).sub(ay.mul(cx));
    let mut w = bx.mul(ay).sub(by.mul(ax));
    let zero = L::splat(0.0);
    let on_edge = (u.eq(zero) | v.eq(zero) | w.eq(zero)) & active;
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
            let l = m.trailing_zeros() as usize & 15;
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
        (u, v, w) = (L::from_array(uu), L::from_array(vv), L::from_array(ww));
    }
    let negative = u.lt(zero) | v.lt(zero) | w.lt(zero);
    let positive = u.gt(zero) | v.gt(zero) | w.gt(zero);
    let det = u.add(v).add(w);
    // `intersect`'s checks; written so a NaN fails (an |det| of inf or NaN is not < inf).
    let inside = !(negative & positive) & det.ne(zero) & det.finite() & active;
    if inside == 0 {
        // Most leaf tests miss every triangle: skip the division.
        return None;
    }
    let t = u
        .mul(sz.mul(pz0))
        .add(v.mul(sz.mul(pz1)))
        .add(w.mul(sz.mul(pz2)))
        .div(det);
    let hit = inside & t.gt(L::splat(tmin)) & t.lt(L::splat(tmax));
    if hit == 0 {
        return None;
    }
    let (t, det, v, w) = (t.to_array(), det.to_array(), v.to_array(), w.to_array());
    let mut best = hit.trailing_zeros() as usize & 15;
    if !ANY {
        let mut rest = hit & (hit - 1);
        while rest != 0 {
            let l = rest.trailing_zeros() as usize & 15;
            rest &= rest - 1;
            if t[l] < t[best] {
                best = l;
            }
        }
    }
    Some((best, t[best], v[best] / det[best], w[best] / det[best]))
}
