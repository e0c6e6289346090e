//! Our BVH8 layout, decompressed from obvhs' compressed wide BVH (CWBVH, Ylitie et al. 2017)
//! at build: obvhs builds the tree; traversal reads this.
//!
//! Why decompress: the CWBVH stores each child box as 8-bit offsets in a per-node grid, so
//! every node visit paid a dequantisation (u8 to float, scale, offset) and a bit-twiddling
//! decode of the child order before the slab test. Here a node holds its eight child boxes as
//! plain f32 in structure-of-arrays order (one 8-lane load per slab plane) and one reference
//! per child; a leaf's up-to-3 triangles sit in one [`Tri4`] block tested at once. It costs
//! memory (256 bytes per node instead of 80, 160 bytes per leaf instead of 48 per triangle),
//! which the measurements in docs/compare.md weigh against the instructions saved.
//!
//! Conservative boxes: each dequantised CWBVH box grows by 1/64 of its grid cell on every side
//! (computed exactly in f64, then rounded outwards to f32), more than the rounding of the slab
//! distances and of the triangle test's t, so a triangle lying in a box face (axis-aligned
//! walls: zero-thickness boxes) is never culled by a rounding; see `traverse`.

use obvhs::cwbvh::{node::CwBvhNode, CwBvh};

use super::triangle::Tri4;

/// Child reference of a leaf: this bit | index into `Bvh8::leaves`.
pub(super) const LEAF: u32 = 0x8000_0000;
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
    /// Inner child: node index; leaf: `LEAF` | leaf index; empty slot: `EMPTY`.
    pub child: [u32; 8],
    _pad: [u32; 8],
}

/// The tree: node 0 is the root.
#[derive(Debug, Default)]
pub(super) struct Bvh8 {
    pub nodes: Vec<Node>,
    pub leaves: Vec<Tri4>,
}

impl Bvh8 {
    /// Converts obvhs' CWBVH over `tris` (scene triangles, indexed by its primitive indices);
    /// node i here is CWBVH node i.
    pub fn from_cwbvh(bvh: &CwBvh, tris: &[[glam::Vec3A; 3]]) -> Bvh8 {
        let mut leaves = Vec::new();
        let nodes = bvh
            .nodes
            .iter()
            .map(|n| convert(n, bvh, tris, &mut leaves))
            .collect();
        Bvh8 { nodes, leaves }
    }
}

fn convert(n: &CwBvhNode, bvh: &CwBvh, tris: &[[glam::Vec3A; 3]], leaves: &mut Vec<Tri4>) -> Node {
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
            // p + e q is exact in f64 (e is a power of two, q < 256); the pad too.
            let (e, p) = (e[axis] as f64, p[axis] as f64);
            let lo = p + e * (q[axis].0[i] as f64 - BOX_PAD);
            let hi = p + e * (q[axis].1[i] as f64 + BOX_PAD);
            node.bounds[2 * axis][i] = round_down(lo);
            node.bounds[2 * axis + 1][i] = round_up(hi);
        }
        node.child[i] = if n.is_leaf(i) {
            let (start, count) = n.child_primitives(i);
            let ids = &bvh.primitive_indices[start as usize..(start + count) as usize];
            leaves.push(Tri4::new(ids, tris));
            LEAF | (leaves.len() - 1) as u32
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
