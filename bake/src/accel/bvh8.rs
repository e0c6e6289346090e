//! Our BVH8 layout, decompressed from obvhs' compressed wide BVH (CWBVH, Ylitie et al. 2017)
//! at build: obvhs builds the tree; traversal reads this.
//!
//! Why decompress: the CWBVH stores each child box as 8-bit offsets in a per-node grid, so
//! every node visit paid a dequantisation (u8 to float, scale, offset) and a bit-twiddling
//! decode of the child order before the slab test. Here a node holds its eight child boxes as
//! plain f32 in structure-of-arrays order (one 8-lane load per slab plane) and one reference
//! per inner child. A node's leaf children (up to 8 of up to 3 triangles) are not referenced
//! one by one: all their triangles sit together as nine rows (vertex, axis) of one value per
//! triangle, each tagged with its leaf's slot, so the leaves a ray hits are tested in one
//! sixteen-lane pass ([`super::triangle::intersect16`]) and never pushed on the stack: 36 bytes
//! per triangle plus its 4-byte id, against 48 before. Nodes cost more memory (256 bytes
//! instead of 80).
//!
//! Conservative boxes: each dequantised CWBVH box grows by 1/64 of its grid cell on every side
//! (computed in f64, then rounded outwards to f32), more than the rounding of the slab
//! distances and of the triangle test's t, so a triangle lying in a box face (axis-aligned
//! walls: zero-thickness boxes) is never culled by a rounding; see `traverse`.

use obvhs::cwbvh::{node::CwBvhNode, CwBvh};

/// Leaf triangles per node at most: obvhs' CWBVH gives a node up to 24 (8 leaves of up to 3).
pub(super) const NODE_TRIANGLES: usize = 24;
/// Triangle references must stay below this (the rows' offsets are 9 times them, in usize).
const TRIANGLE_LIMIT: usize = 1 << 29;
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
    /// Inner child: node index; leaf or empty slot: `EMPTY`.
    pub child: [u32; 8],
    /// The node's leaf triangles, all its leaves' together in slot order: triangle j has the
    /// bit of its leaf's slot in `lane_slot[j]` (0 past the last), its scene index in
    /// `Bvh8::ids[first + j]`, and its coordinates at `Bvh8::rows[9 first + r count + j]`
    /// for row r = 3 vertex + axis (rows of `count`, so sixteen lanes load at once).
    pub lane_slot: [u8; NODE_TRIANGLES],
    pub first: u32,
    pub count: u8,
    /// Bit i set when slot i is a leaf.
    pub leaves: u8,
    _pad: [u8; 2],
}

/// The tree: node 0 is the root.
#[derive(Debug, Default)]
pub(super) struct Bvh8 {
    pub nodes: Vec<Node>,
    /// The nodes' leaf triangles' coordinates (see `Node::lane_slot`), then `ROWS_PAD` zeros
    /// so a sixteen-lane load of a node's last row never reads past the end.
    pub rows: Vec<f32>,
    /// Scene triangle index of each leaf triangle, in node order.
    pub ids: Vec<u32>,
}

impl Bvh8 {
    /// Converts obvhs' CWBVH over `tris` (scene triangles, indexed by its primitive indices);
    /// node i here is CWBVH node i.
    ///
    /// Panics past 2^29 triangle references (a scene far beyond what fits in memory here).
    pub fn from_cwbvh(bvh: &CwBvh, tris: &[[glam::Vec3A; 3]]) -> Bvh8 {
        assert!(
            bvh.primitive_indices.len() < TRIANGLE_LIMIT,
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
        out.rows.extend([0.0; ROWS_PAD]);
        out
    }
}

/// Zeros after the last row: the last sixteen-lane load of a node of n triangles starts at
/// most at 8 n + 16 ((n - 1) / 16) <= 9 n - 1 (row 8, its last block), so it reads up to
/// 15 values past the node's 9 n.
pub(super) const ROWS_PAD: usize = 16;

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
        lane_slot: [0; NODE_TRIANGLES],
        first: out.ids.len() as u32,
        count: 0,
        leaves: 0,
        _pad: [0; 2],
    };
    let mut ids = Vec::with_capacity(NODE_TRIANGLES);
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
        if n.is_leaf(i) {
            let (start, count) = n.child_primitives(i);
            for &id in &bvh.primitive_indices[start as usize..(start + count) as usize] {
                assert!(
                    ids.len() < NODE_TRIANGLES,
                    "a CWBVH node with more than 24 leaf triangles"
                );
                node.lane_slot[ids.len()] = 1 << i;
                ids.push(id);
            }
            node.leaves |= 1 << i;
        } else {
            node.child[i] = n.child_node_index(i);
        }
    }
    // Row 3 * vertex + axis: that coordinate of each triangle.
    for row in 0..9 {
        let (k, axis) = (row / 3, row % 3);
        out.rows
            .extend(ids.iter().map(|&i| tris[i as usize][k][axis]));
    }
    out.ids.extend_from_slice(&ids);
    node.count = ids.len() as u8;
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
