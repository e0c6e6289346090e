//! Traversal of our BVH8 ([`super::bvh8`]): all eight child boxes of a node against the ray at
//! once ([`NodeTest`]: one 256-bit vector with AVX2, else eight lanes the compiler vectorizes;
//! see `Accel`'s dispatch in `mod.rs`). The leaves hit are tested at once, all their
//! triangles in sixteen lanes ([`triangle::intersect16`]; one 512-bit vector with AVX-512),
//! before the inner children: measured 5-10 % faster on 100K and 1M triangles than pushing
//! each leaf and testing it four lanes at a time when popped, and no slower on cornell.
//! Closest hit then visits the inner children hit nearest first (sorted by entry distance);
//! occlusion pushes them unsorted (sorting measured slower there: any hit ends the query).
//!
//! The node test is conservative in floating point: the boxes are already grown by a few ulp
//! of their coordinates ([`super::bvh8`]), and the exit distance, after clamping to the ray's
//! current tmax, grows by 16 ulp: more than the rounding of the slab distances and of the
//! triangle test's t, so a triangle lying in a box face (axis-aligned walls: zero-thickness
//! boxes) is never culled by a rounding, not even when it is a hair closer than the hit found
//! so far; the watertight triangle test decides. Entry distances are clamped to the ray's own
//! tmin (obvhs' traversal clamped them to 1e-4, so a ray leaving a wall near a corner missed
//! the adjacent wall when it was closer than that: 196 of 2M rays on the Cornell box).
//!
//! Since culling never drops a triangle closer than the current tmax, the closest hit is the
//! least t over all triangles whatever the visiting order; only between triangles at exactly
//! the same t can the order decide (the first found is kept). Plain `if a > b` min/max: the
//! vectorized and scalar code give the same answers bit for bit (Rust never contracts a*b+c
//! into an FMA).
//!
//! Closest hit shrinks tmax as it finds hits; occlusion (`ANY`) stops at the first.

use std::mem::MaybeUninit;

use glam::Vec3;

use super::bvh8::{Bvh8, Node, NODE_TRIANGLES, ROWS_PAD};
use super::triangle::{self, RayTri};

/// Exit distances (clamped to the ray's tmax) grow by this factor (16 ulp).
const EXIT_GROW: f32 = 1.0 + 16.0 * f32::EPSILON;
/// Traversal stack entries: at most 7 per level pushed (the collapsed trees stay under 32
/// levels: 1M triangles make about 8).
const STACK: usize = 256;

/// The per-ray constants of the node test.
#[derive(Clone, Copy, Debug)]
pub(super) struct RayNode {
    org: [f32; 3],
    inv_dir: [f32; 3],
    /// Rows of `Node::bounds` holding the near and far planes along x, y, z: (near x, far x,
    /// near y, far y, near z, far z), each below 6.
    rows: [usize; 6],
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
        let (x, y, z) = (
            (dir.x < 0.0) as usize,
            (dir.y < 0.0) as usize,
            (dir.z < 0.0) as usize,
        );
        RayNode {
            org: origin.to_array(),
            inv_dir: [inv(dir.x), inv(dir.y), inv(dir.z)],
            rows: [x, 1 - x, 2 + y, 3 - y, 4 + z, 5 - z],
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

/// The node test: bit i of the result set when child i's box overlaps the ray in
/// (tmin, tmax), its entry distance in `tn[i]`. Two implementations with the same operations
/// in the same order, so the same answers bit for bit: [`Portable`] and [`Avx2`].
pub(super) trait NodeTest {
    /// The leaf test's lanes on the same path.
    type Lanes: triangle::Lanes;
    /// # Safety
    /// The implementation's CPU features must be present.
    unsafe fn hits(node: &Node, r: &RayNode, tmax: f32, tn: &mut [f32; 8]) -> u32;
}

/// Plain Rust, eight lanes the compiler vectorizes as it can.
pub(super) struct Portable;

impl NodeTest for Portable {
    type Lanes = triangle::Portable16;
    #[inline(always)]
    unsafe fn hits(node: &Node, r: &RayNode, tmax: f32, tn: &mut [f32; 8]) -> u32 {
        let b = &node.bounds;
        let [nx, fx, ny, fy, nz, fz] = r.rows.map(|k| &b[k]);
        let [ox, oy, oz] = r.org;
        let [ix, iy, iz] = r.inv_dir;
        let mut mask = 0u32;
        for i in 0..8 {
            let tnx = (nx[i] - ox) * ix;
            let tny = (ny[i] - oy) * iy;
            let tnz = (nz[i] - oz) * iz;
            let tfx = (fx[i] - ox) * ix;
            let tfy = (fy[i] - oy) * iy;
            let tfz = (fz[i] - oz) * iz;
            let near = max(max(tnx, tny), max(tnz, r.tmin));
            let far = min(min(min(tfx, tfy), tfz), tmax) * EXIT_GROW;
            tn[i] = near;
            mask |= ((near <= far) as u32) << i;
        }
        mask
    }
}

/// The eight lanes as one AVX 256-bit vector. `_mm256_max_ps(a, b)` is `if a > b { a } else
/// { b }` and `_mm256_min_ps(a, b)` `if a < b { a } else { b }` (NaN included), as `max` and
/// `min` above.
#[cfg(target_arch = "x86_64")]
pub(super) struct Avx2;

#[cfg(target_arch = "x86_64")]
impl NodeTest for Avx2 {
    type Lanes = triangle::Avx2x16;
    #[inline(always)]
    unsafe fn hits(node: &Node, r: &RayNode, tmax: f32, tn: &mut [f32; 8]) -> u32 {
        node_hits_avx2(node, r, tmax, tn)
    }
}

/// The AVX2 node test (one node is eight lanes), with the leaf test's sixteen lanes as one
/// AVX-512 vector.
#[cfg(target_arch = "x86_64")]
pub(super) struct Avx512;

#[cfg(target_arch = "x86_64")]
impl NodeTest for Avx512 {
    type Lanes = triangle::Avx512x16;
    #[inline(always)]
    unsafe fn hits(node: &Node, r: &RayNode, tmax: f32, tn: &mut [f32; 8]) -> u32 {
        node_hits_avx2(node, r, tmax, tn)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn node_hits_avx2(node: &Node, r: &RayNode, tmax: f32, tn: &mut [f32; 8]) -> u32 {
    use std::arch::x86_64::*;
    // SAFETY (loads): `bounds` is six rows of 8 f32 at a 64-byte aligned address (`Node` is
    // `align(64)`), and `RayNode::new` makes every row index below 6.
    let b = node.bounds.as_ptr() as *const f32;
    let row = |k: usize| _mm256_load_ps(b.add(r.rows[k] * 8));
    let (nx, fx, ny, fy, nz, fz) = (row(0), row(1), row(2), row(3), row(4), row(5));
    let (ox, oy, oz) = (
        _mm256_set1_ps(r.org[0]),
        _mm256_set1_ps(r.org[1]),
        _mm256_set1_ps(r.org[2]),
    );
    let (ix, iy, iz) = (
        _mm256_set1_ps(r.inv_dir[0]),
        _mm256_set1_ps(r.inv_dir[1]),
        _mm256_set1_ps(r.inv_dir[2]),
    );
    let tnx = _mm256_mul_ps(_mm256_sub_ps(nx, ox), ix);
    let tny = _mm256_mul_ps(_mm256_sub_ps(ny, oy), iy);
    let tnz = _mm256_mul_ps(_mm256_sub_ps(nz, oz), iz);
    let tfx = _mm256_mul_ps(_mm256_sub_ps(fx, ox), ix);
    let tfy = _mm256_mul_ps(_mm256_sub_ps(fy, oy), iy);
    let tfz = _mm256_mul_ps(_mm256_sub_ps(fz, oz), iz);
    let near = _mm256_max_ps(
        _mm256_max_ps(tnx, tny),
        _mm256_max_ps(tnz, _mm256_set1_ps(r.tmin)),
    );
    let far = _mm256_mul_ps(
        _mm256_min_ps(
            _mm256_min_ps(_mm256_min_ps(tfx, tfy), tfz),
            _mm256_set1_ps(tmax),
        ),
        _mm256_set1_ps(EXIT_GROW),
    );
    _mm256_storeu_ps(tn.as_mut_ptr(), near);
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32
}

/// A query's answer: (scene triangle, t, b1, b2).
pub(super) type Found = Option<(u32, f32, f32, f32)>;

/// A walk's stack of (node, entry distance), nearest on top; uninitialised (a 2 KB memset per
/// ray cost 3 %), read only below the walk's `sp`, where written. Indices are taken modulo
/// STACK, which removes the bounds checks and cannot be reached (at most 7 entries per level).
type Stack = [MaybeUninit<(u32, f32)>; STACK];

/// An empty stack.
const NEW_STACK: Stack = [const { MaybeUninit::uninit() }; STACK];

/// One ray's traversal in progress, a node at a time ([`Walk::step`]), so a stream can keep
/// several in flight ([`traverse_stream`]) and a single query runs the same steps
/// ([`traverse`]). The stack is kept apart so this small state stays in registers (with the
/// stack inside, single queries measured 8 % slower).
#[derive(Clone, Copy)]
pub(super) struct Walk {
    rn: RayNode,
    rt: RayTri,
    tmax: f32,
    /// The closest hit so far (with `ANY`, the hit that ended the walk).
    best: Found,
    /// Entries on the stack.
    sp: usize,
    /// The node the next step visits.
    cur: u32,
}

impl Walk {
    /// A walk from the root (node 0), for the ray of `rn` and `rt` over (tmin, tmax).
    #[inline(always)]
    pub fn new(rn: RayNode, rt: RayTri, tmax: f32) -> Walk {
        Walk {
            rn,
            rt,
            tmax,
            best: None,
            sp: 0,
            cur: 0,
        }
    }

    /// Visits node `cur`: tests its leaves hit, then moves `cur` to the next node to visit.
    /// False when the walk has ended; `best` is then the answer.
    ///
    /// # Safety
    /// `T`'s CPU features must be present.
    #[inline(always)]
    pub unsafe fn step<const ANY: bool, T: NodeTest>(
        &mut self,
        stack: &mut Stack,
        bvh: &Bvh8,
    ) -> bool {
        let node = &bvh.nodes[self.cur as usize];
        // The child references are the node's last cache line, read only after the box
        // test: ask for it now so its miss overlaps the box rows'.
        prefetch(node.child.as_ptr() as *const u8);
        let mut tn = [0f32; 8];
        let mut mask = T::hits(node, &self.rn, self.tmax, &mut tn);
        let leaves = mask & node.leaves as u32;
        if leaves != 0 {
            // All the leaves hit at once, before the inner children (a hit only lowers tmax).
            if let Some(hit) =
                node_leaves::<ANY, T::Lanes>(bvh, node, leaves, &self.rt, self.rn.tmin, self.tmax)
            {
                self.best = Some(hit);
                if ANY {
                    return false;
                }
                self.tmax = hit.1;
            }
            mask &= !leaves;
        }
        if mask != 0 && mask & (mask - 1) == 0 {
            // One child hit: descend, nothing to push.
            self.cur = node.child[mask.trailing_zeros() as usize & 7];
            return true;
        }
        if ANY && mask != 0 {
            // Occlusion: push the children unsorted (sorting measured slower there: any hit
            // ends the query) and descend into the last.
            while mask != 0 {
                let i = mask.trailing_zeros() as usize & 7;
                mask &= mask - 1;
                let c = node.child[i];
                prefetch_node(bvh, c);
                stack[self.sp % STACK].write((c, tn[i]));
                self.sp += 1;
            }
            self.sp -= 1;
            // SAFETY: sp < the count written.
            self.cur = unsafe { stack[self.sp % STACK].assume_init() }.0;
            return true;
        } else if mask != 0 {
            let i0 = mask.trailing_zeros() as usize & 7;
            let m = mask & (mask - 1);
            let i1 = m.trailing_zeros() as usize & 7;
            if m & (m - 1) == 0 {
                // Two children hit (the commonest case after one): descend into the nearer,
                // push the other. On a tie the later slot goes first, as the sort below.
                let (c0, c1) = (node.child[i0], node.child[i1]);
                let (push, t) = if tn[i0] < tn[i1] {
                    self.cur = c0;
                    (c1, tn[i1])
                } else {
                    self.cur = c1;
                    (c0, tn[i0])
                };
                prefetch_node(bvh, push);
                stack[self.sp % STACK].write((push, t));
                self.sp += 1;
                return true;
            }
            // Push the children hit, sorted (insertion sort, stable: ties keep slot order)
            // so the nearest is on top, and descend into it.
            let base = self.sp;
            let mut sp = self.sp;
            while mask != 0 {
                let i = mask.trailing_zeros() as usize & 7;
                mask &= mask - 1;
                let e = (node.child[i], tn[i]);
                let mut j = sp;
                while j > base {
                    // SAFETY: base <= j - 1 < sp: written above.
                    let below = unsafe { stack[(j - 1) % STACK].assume_init() };
                    if below.1 >= e.1 {
                        break;
                    }
                    stack[j % STACK].write(below);
                    j -= 1;
                }
                stack[j % STACK].write(e);
                sp += 1;
            }
            sp -= 1;
            // SAFETY: sp < the count written.
            self.cur = unsafe { stack[sp % STACK].assume_init() }.0;
            // The others are visited later: start loading them now.
            for k in base..sp {
                // SAFETY: base <= k < sp: written above.
                prefetch_node(bvh, unsafe { stack[k % STACK].assume_init() }.0);
            }
            self.sp = sp;
            return true;
        }
        // Pop the nearest entry still in reach.
        loop {
            if self.sp == 0 {
                return false;
            }
            self.sp -= 1;
            // SAFETY: sp < the count written.
            let (c, t) = unsafe { stack[self.sp % STACK].assume_init() };
            if ANY || t <= self.tmax * EXIT_GROW {
                self.cur = c;
                return true;
            }
        }
    }
}

/// Closest hit in (tmin, tmax) as (scene triangle, t, b1, b2); with `ANY`, the first hit
/// found.
///
/// # Safety
/// `T`'s CPU features must be present.
#[inline(always)]
pub(super) unsafe fn traverse<const ANY: bool, T: NodeTest>(
    bvh: &Bvh8,
    rn: &RayNode,
    rt: &RayTri,
    tmax: f32,
) -> Found {
    let mut stack = NEW_STACK;
    let mut walk = Walk::new(*rn, *rt, tmax);
    while walk.step::<ANY, T>(&mut stack, bvh) {}
    walk.best
}

/// Walks in flight at once in [`traverse_stream`]: four measured slower than two on cornell
/// (about 10 %) and no faster on 100K and 1M triangles.
const STREAM_WALKS: usize = 2;

/// The answers of many rays, each the same as [`traverse`]'s, given to `answer` (ray index,
/// answer) as each ends, in no set order. `STREAM_WALKS` walks take turns a node at a time,
/// and each turn ends by asking for the walk's next node, so that node's cache misses overlap
/// the other walks' work instead of stalling the core; a walk that ends takes the next ray.
///
/// # Safety
/// `T`'s CPU features must be present.
#[inline(always)]
pub(super) unsafe fn traverse_stream<const ANY: bool, T: NodeTest>(
    bvh: &Bvh8,
    len: usize,
    ray: impl Fn(usize) -> (RayNode, RayTri, f32),
    mut answer: impl FnMut(usize, Found),
) {
    if len == 0 {
        return;
    }
    let mut stacks = [NEW_STACK; STREAM_WALKS];
    // Walks beyond the rays start on the last ray and stay inactive.
    let mut walks: [Walk; STREAM_WALKS] = std::array::from_fn(|k| {
        let (rn, rt, tmax) = ray(k.min(len - 1));
        Walk::new(rn, rt, tmax)
    });
    let mut index = [0usize; STREAM_WALKS];
    let mut next = 0;
    let mut active = 0u32;
    for (k, i) in index.iter_mut().enumerate() {
        if next < len {
            *i = next;
            next += 1;
            active |= 1 << k;
        }
    }
    while active != 0 {
        for (k, (walk, stack)) in walks.iter_mut().zip(&mut stacks).enumerate() {
            if active & (1 << k) == 0 {
                continue;
            }
            if walk.step::<ANY, T>(stack, bvh) {
                prefetch_node(bvh, walk.cur);
                continue;
            }
            answer(index[k], walk.best);
            if next < len {
                let (rn, rt, tmax) = ray(next);
                *walk = Walk::new(rn, rt, tmax);
                index[k] = next;
                next += 1;
            } else {
                active &= !(1 << k);
            }
        }
    }
}

/// The triangle test of the leaves `slots` (bits of leaf slots) of `node`: (scene triangle,
/// t, b1, b2), sixteen triangles at a time (a node has up to 24).
///
/// # Safety
/// `L`'s CPU features must be present.
#[inline(always)]
unsafe fn node_leaves<const ANY: bool, L: triangle::Lanes>(
    bvh: &Bvh8,
    node: &Node,
    slots: u32,
    rt: &RayTri,
    tmin: f32,
    mut tmax: f32,
) -> Option<(u32, f32, f32, f32)> {
    let first = node.first as usize;
    let n = (node.count as usize).min(NODE_TRIANGLES);
    // One bounds check for the node: its nine rows of n and the lanes past them.
    let rows = &bvh.rows[9 * first..9 * first + 9 * n + ROWS_PAD];
    let ids = &bvh.ids[first..first + n];
    // Eight copies of the slot bits, to test eight lanes' `lane_slot` bytes at once.
    let slots8 = (slots & 0xff) as u64 * 0x0101_0101_0101_0101;
    let byte_lanes = |k: usize| {
        let bytes = u64::from_le_bytes(
            node.lane_slot[8 * k..8 * k + 8]
                .try_into()
                .unwrap_or([0; 8]),
        );
        nonzero_bytes(bytes & slots8)
    };
    let mut best = None;
    for block in 0..n.div_ceil(16) {
        let active = if block == 0 {
            byte_lanes(0) | byte_lanes(1) << 8
        } else {
            byte_lanes(2)
        };
        if active == 0 {
            continue;
        }
        // SAFETY: row r's sixteen lanes of this block end at r n + 16 block + 16 <= 9 n + 15,
        // within `rows` (see `ROWS_PAD`); `L`'s features: the caller's.
        let hit = unsafe {
            triangle::intersect16::<ANY, L>(
                rows.as_ptr().add(16 * block),
                n,
                active,
                rt,
                tmin,
                tmax,
            )
        };
        if let Some((lane, t, b1, b2)) = hit {
            let id = ids.get(16 * block + lane).copied().unwrap_or(u32::MAX);
            best = Some((id, t, b1, b2));
            if ANY {
                return best;
            }
            tmax = t;
        }
    }
    best
}

/// Bit i set when byte i of x is not zero.
#[inline(always)]
fn nonzero_bytes(x: u64) -> u32 {
    const LOW7: u64 = 0x7f7f_7f7f_7f7f_7f7f;
    // High bit of each byte: set when the byte is not zero (no carries between bytes).
    let high = ((x & LOW7).wrapping_add(LOW7) | x) & !LOW7;
    // Gather the eight high bits into the top byte.
    (high.wrapping_mul(0x0002_0408_1020_4081) >> 56) as u32
}

/// Asks for the first cache lines of a node: its box rows.
#[inline(always)]
fn prefetch_node(bvh: &Bvh8, node: u32) {
    let p = bvh.nodes.as_ptr().wrapping_add(node as usize) as *const u8;
    prefetch(p);
    prefetch(p.wrapping_add(64));
    prefetch(p.wrapping_add(128));
}

/// A cache hint; it never faults, whatever the address.
#[inline(always)]
fn prefetch(p: *const u8) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch only hints the cache and never faults.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(p as *const i8);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
