//! Traversal of obvhs' compressed wide BVH (CWBVH, Ylitie et al. 2017) with our own node test:
//! all eight children of a node against the ray at once, in lanes the compiler vectorizes
//! (8-wide with AVX2, 2 x 4 with the SSE2 baseline; see `Accel`'s dispatch in `mod.rs`).
//!
//! The traversal order and the node/leaf bookkeeping are obvhs' (its `traverse!` macro: child
//! groups ordered by the ray's octant, leaves as bit groups of primitives); what differs is the
//! node test:
//!
//! - obvhs clamps every child's entry distance to at least 1e-4, so a ray leaving a wall near a
//!   corner missed the adjacent wall when it was closer than that (196 of 2M rays on the
//!   Cornell box); we clamp to the ray's own tmin;
//! - it is conservative in floating point: each quantized child box is grown by 1/64 of its
//!   grid cell on every side, and the exit distance, after clamping to the ray's current tmax,
//!   by 16 ulp: more than the rounding of the slab distances and of the triangle test's t, so
//!   a triangle lying in a box face (axis-aligned walls: zero-thickness boxes) is never culled
//!   by a rounding, not even when it is a hair closer than the hit found so far (obvhs' test
//!   missed such hits at the corners of a closed box); the watertight triangle test decides;
//! - one ray, eight lanes of plain `if a > b` min/max, so the vectorized and scalar code give
//!   the same answers bit for bit (Rust never contracts a*b+c into an FMA).
//!
//! Closest hit shrinks tmax as it finds hits; occlusion (`ANY`) stops at the first.

use glam::{Vec3, Vec3A};
use obvhs::cwbvh::node::CwBvhNode;

use super::triangle::{self, RayTri, Tri};

/// Child boxes grow by this many quantization cells on each side.
const BOX_PAD: f32 = 1.0 / 64.0;
/// Exit distances (clamped to the ray's tmax) grow by this factor (16 ulp).
const EXIT_GROW: f32 = 1.0 + 16.0 * f32::EPSILON;
/// Stack of child groups: one entry per BVH level at most (obvhs' BVH8s stay under 32).
const STACK: usize = 64;

/// The per-ray constants of the node test.
#[derive(Clone, Copy, Debug)]
pub(super) struct RayNode {
    origin: Vec3A,
    inv_dir: Vec3A,
    neg: [bool; 3],
    oct_inv4: u32,
    tmin: f32,
}

impl RayNode {
    #[inline(always)]
    pub fn new(origin: Vec3, dir: Vec3, tmin: f32) -> RayNode {
        // A zero component gets a huge finite inverse: no inf * 0 = NaN in the slabs.
        let inv = |d: f32| {
            1.0 / if d.abs() < 1e-20 {
                1e-20f32.copysign(d)
            } else {
                d
            }
        };
        let oct_inv4 = (if dir.x < 0.0 { 0 } else { 0x04040404 })
            | (if dir.y < 0.0 { 0 } else { 0x02020202 })
            | (if dir.z < 0.0 { 0 } else { 0x01010101 });
        RayNode {
            origin: origin.into(),
            inv_dir: Vec3A::new(inv(dir.x), inv(dir.y), inv(dir.z)),
            neg: [dir.x < 0.0, dir.y < 0.0, dir.z < 0.0],
            oct_inv4,
            tmin,
        }
    }
}

#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// The node's hit mask in obvhs' layout: bits 24..32 the internal children hit (by traversal
/// priority), bits 0..24 the primitives of the leaf children hit.
#[inline(always)]
fn node_hits(node: &CwBvhNode, r: &RayNode, tmax: f32) -> u32 {
    // Child plane at quantized q along an axis: t = q * a + b.
    let a = node.compute_extent() * r.inv_dir;
    let b = (Vec3A::from(node.p) - r.origin) * r.inv_dir;
    let pad = a.abs() * BOX_PAD;
    let (bn, bf) = (b - pad, b + pad);
    let pick = |neg: bool, lo: &[u8; 8], hi: &[u8; 8]| if neg { (*hi, *lo) } else { (*lo, *hi) };
    let (nx, fx) = pick(r.neg[0], &node.child_min_x, &node.child_max_x);
    let (ny, fy) = pick(r.neg[1], &node.child_min_y, &node.child_max_y);
    let (nz, fz) = pick(r.neg[2], &node.child_min_z, &node.child_max_z);
    let mut hit = [0u8; 8];
    for i in 0..8 {
        let tnx = nx[i] as f32 * a.x + bn.x;
        let tny = ny[i] as f32 * a.y + bn.y;
        let tnz = nz[i] as f32 * a.z + bn.z;
        let tfx = fx[i] as f32 * a.x + bf.x;
        let tfy = fy[i] as f32 * a.y + bf.y;
        let tfz = fz[i] as f32 * a.z + bf.z;
        let tn = max(max(tnx, tny), max(tnz, r.tmin));
        let tf = min(min(min(tfx, tfy), tfz), tmax) * EXIT_GROW;
        hit[i] = if tn <= tf { 0xff } else { 0 };
    }
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(r.oct_inv4);
    let sel = child_bits8 & u64::from_le_bytes(hit);
    let mut mask = 0u32;
    for i in 0..8 {
        let bits = ((sel >> (8 * i)) & 0xff) as u32;
        let index = ((bit_index8 >> (8 * i)) & 0x1f) as u32;
        mask |= bits << index;
    }
    mask
}

/// Closest hit in (tmin, tmax) as (leaf-order triangle, t, b1, b2); with `ANY`, the first hit
/// found.
#[inline(always)]
pub(super) fn traverse<const ANY: bool>(
    nodes: &[CwBvhNode],
    tris: &[Tri],
    rn: &RayNode,
    rt: &RayTri,
    mut tmax: f32,
) -> Option<(u32, f32, f32, f32)> {
    let mut best: Option<(u32, f32, f32, f32)> = None;
    let mut stack = [(0u32, 0u32); STACK];
    let mut sp = 0usize;
    // (child base index, hit bits 24..32 | imask) and (primitive base index, primitive bits).
    let mut group = (0u32, 0x8000_0000u32);
    let mut prims = (0u32, 0u32);
    loop {
        while prims.1 != 0 {
            let local = 31 - prims.1.leading_zeros();
            prims.1 &= !(1u32 << local);
            let id = prims.0 + local;
            if let Some((t, b1, b2)) = triangle::intersect(&tris[id as usize], rt, rn.tmin, tmax) {
                best = Some((id, t, b1, b2));
                if ANY {
                    return best;
                }
                tmax = t;
            }
        }
        if group.1 & 0xff00_0000 != 0 {
            let hits_imask = group.1;
            let offset = 31 - hits_imask.leading_zeros();
            group.1 &= !(1u32 << offset);
            if group.1 & 0xff00_0000 != 0 {
                stack[sp] = group;
                sp += 1;
            }
            let slot = (offset - 24) ^ (rn.oct_inv4 & 0xff);
            let relative = (hits_imask & !(0xffff_ffffu32 << slot)).count_ones();
            let node = &nodes[(group.0 + relative) as usize];
            let mask = node_hits(node, rn, tmax);
            group = (
                node.child_base_idx,
                (mask & 0xff00_0000) | node.imask as u32,
            );
            prims = (node.primitive_base_idx, mask & 0x00ff_ffff);
            prefetch_triangles(tris, prims);
        } else {
            group = (0, 0);
        }
        if prims.1 == 0 && group.1 & 0xff00_0000 == 0 {
            if sp == 0 {
                return best;
            }
            sp -= 1;
            group = stack[sp];
        }
    }
}

/// Asks for the cache lines of all the triangles a node's leaves will test, before testing the
/// first, so their misses overlap. Triangle and node loads are the hottest instructions in
/// `perf` (the ray core is memory-bound at 100K and 1M triangles); measured a few percent,
/// within the noise of the shared machine. Prefetching the child nodes hit as well measured
/// nothing, so it is not done.
#[inline(always)]
fn prefetch_triangles(tris: &[Tri], prims: (u32, u32)) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let mut bits = prims.1;
        while bits != 0 {
            let i = (prims.0 + bits.trailing_zeros()) as usize;
            bits &= bits - 1;
            if let Some(t) = tris.get(i) {
                let p = t as *const Tri as *const i8;
                // SAFETY: a prefetch only hints the cache and never faults; p and p + 32 lie
                // inside the 48-byte triangle (its two cache lines at most).
                unsafe {
                    _mm_prefetch::<_MM_HINT_T0>(p);
                    _mm_prefetch::<_MM_HINT_T0>(p.add(32));
                }
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (tris, prims);
}
