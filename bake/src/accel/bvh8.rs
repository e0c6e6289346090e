//! Our BVH8 layout, decompressed from obvhs' compressed wide BVH (CWBVH, Ylitie et al. 2017)
//! at build: obvhs builds the tree; traversal reads this.
//!
//! Why decompress: the CWBVH stores each child box as 8-bit offsets in a per-node grid, so
//! every node visit paid a dequantisation (u8 to float, scale, offset) and a bit-twiddling
//! decode of the child order before the slab test. Here a node holds its eight child boxes as
//! plain f32 in structure-of-arrays order (one 8-lane load per slab plane) and one reference
//! per child; a leaf's up-to-3 triangles sit together as nine rows (vertex, axis) of one value
//! per triangle, tested at once ([`super::triangle::intersect4`]): 36 bytes per triangle plus
//! its 4-byte id, against 48 before. Nodes cost more memory (256 bytes instead of 80).
//!
//! Conservative boxes: each dequantised CWBVH box grows by 1/64 of its grid cell on every side
//! (computed in f64, then rounded outwards to f32), more than the rounding of the slab
//! distances and of the triangle test's t, so a triangle lying in a box face (axis-aligned
//! walls: zero-thickness boxes) is never culled by a rounding; see `traverse`.

use obvhs::cwbvh::{node::CwBvhNode, CwBvh};

/// Child reference of a leaf: this bit | (triangles - 1) << `LEAF_COUNT_SHIFT` | index of its
/// first triangle in `Bvh8::ids` (its rows start at 9 times that in `Bvh8::rows`).
pub(super) const LEAF: u32 = 0x8000_0000;
pub(super) const LEAF_COUNT_SHIFT: u32 = 29;
/// Leaf triangle indices must stay below this (2^29, about 537M triangle references).
const LEAF_INDEX_LIMIT: usize = 1 << LEAF_COUNT_SHIFT;
/// Child reference of an empty slot (its box is empty, so it is never hit).
pub(super) const EMPTY: u32 = u32::MAX;
/// Child boxes grow by this many quantization cells on each side.
const BOX_PAD: f64 = 1.0 / 64.0;

/// One node: its children's boxes and references. 256 bytes, four cache lines.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct Node {
    /// Child boxes in structure-of-arrays order: rows lo x, hi x, lo y, hi y, lo z, hi z; an
    /// empty slot has lo = +inf and hi = -inf.
    pub bounds: [[f32; 8]; 6],
    /// Inner child: node index; leaf: a `LEAF` reference; empty slot: `EMPTY`.
    pub child: [u32; 8],
    _pad: [u32; 8],
}

/// The tree: node 0 is the root.
#[derive(Debug, Default)]
pub(super) struct Bvh8 {
    pub nodes: Vec<Node>,
    /// The leaves' coordinates (see `LEAF`), then 4 zeros so a four-lane load of a leaf's
    /// last row never reads past the end.
    pub rows: Vec<f32>,
    /// Scene triangle index of each leaf triangle, in leaf order.
    pub ids: Vec<u32>,
}

impl Bvh8 {
    /// Converts obvhs' CWBVH over `tris` (scene triangles, indexed by its primitive indices);
    /// node i here is CWBVH node i.
    ///
    /// Panics past 2^29 triangle references (a scene far beyond what fits in memory here).
    pub fn from_cwbvh(bvh: &CwBvh, tris: &[[glam::Vec3A; 3]]) -> Bvh8 {
        assert!(
            bvh.primitive_indices.len() < LEAF_INDEX_LIMIT,
            "too many triangles for the BVH's leaf references"
        );
        let mut out = Bvh8 {
            nodes: Vec::with_capacity(bvh.nodes.len()),
            rows: Vec::with_capacity(9 * bvh.primitive_indices.len() + 4),
            ids: Vec::with_capacity(bvh.primitive_indices.len()),
        };
        for n in &bvh.nodes {
            let node = convert(n, bvh, tris, &mut out);
            out.nodes.push(node);
        }
        out.rows.extend([0.0; 4]);
        out
    }

    /// Appends a leaf of the triangles `ids`; returns its child reference.
    fn push_leaf(&mut self, ids: &[u32], tris: &[[glam::Vec3A; 3]]) -> u32 {
        let first = self.ids.len() as u32;
        // Row 3 * vertex + axis: that coordinate of each triangle.
        for row in 0..9 {
            let (k, axis) = (row / 3, row % 3);
            self.rows
                .extend(ids.iter().map(|&i| tris[i as usize][k][axis]));
        }
        self.ids.extend_from_slice(ids);
        LEAF | ((ids.len() as u32 - 1) << LEAF_COUNT_SHIFT) | first
    }
}

fn convert(n: &CwBvhNode, bvh: &CwBvh, tris: &[[glam::Vec3A; 3]], out: &mut Bvh8) -> Node {
    let mut node = Node {
        bounds: [
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [0.0; 8],
            [0.0; 8],
            [0.0; 8],
            [0.0; 8],
        ],
        child: [EMPTY; 8],
        _pad: [0; 8],
    };
    for row in [2, 4] {
        node.bounds[row] = [f32::INFINITY; 8];
        node.bounds[row + 1] = [f32::NEG_INFINITY; 8];
    }
    let e = n.compute_extent().to_array();
    let p = n.p.to_array();
    let q = [
        (&n.child_min_x, &n.child_max_x),
        (&n.child_min_y, &n.child_max_y),
        (&n.child_min_z, &n.child_max_z),
    ];
    for i in 0..8 {
        if n.is_child_empty(i) {
            continue;
        }
        for axis in 0..3 {
            // In f64 (e is a power of two, q < 256: e (q -+ pad) is exact), then rounded outwards.
            let (e, p) = (e[axis] as f64, p[axis] as f64);
            let lo = p + e * (q[axis].0[i] as f64 - BOX_PAD);
            let hi = p + e * (q[axis].1[i] as f64 + BOX_PAD);
            node.bounds[2 * axis][i] = round_down(lo);
            node.bounds[2 * axis + 1][i] = round_up(hi);
        }
        node.child[i] = if n.is_leaf(i) {
            let (start, count) = n.child_primitives(i);
            let ids = &bvh.primitive_indices[start as usize..(start + count) as usize];
            out.push_leaf(ids, tris)
        } else {
            n.child_node_index(i)
        };
    }
    node
}

/// The largest f32 not above x.
fn round_down(x: f64) -> f32 {
    -round_up(-x)
}

/// The smallest f32 not below x (finite x; an x beyond f32's range gives infinity).
fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) >= x {
        f
    } else if f == 0.0 {
        f32::from_bits(1)
    } else if f > 0.0 {
        f32::from_bits(f.to_bits() + 1)
    } else {
        f32::from_bits(f.to_bits() - 1)
    }
}
