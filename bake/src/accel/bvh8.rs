//! Our BVH8 layout, written from the collapsed tree ([`super::collapse`]) at build; traversal
//! reads this.
//!
//! A node holds its eight child boxes as plain f32 in structure-of-arrays order (one 8-lane
//! load per slab plane) and one reference per inner child. (obvhs' compressed wide BVH, which
//! this replaced, stored each box as 8-bit offsets in a per-node grid: every node visit paid a
//! dequantisation and a bit-twiddling decode of the child order before the slab test.) A
//! node's leaf children are not referenced one by one: all their triangles (up to 24) sit
//! together as nine rows (vertex, axis) of one value per triangle, each tagged with its leaf's
//! slot, so the leaves a ray hits are tested in sixteen-lane passes
//! ([`super::triangle::intersect16`]) and never pushed on the stack: 36 bytes per triangle plus
//! its 4-byte id. A node is 256 bytes, four cache lines.
//!
//! Conservative boxes: obvhs' boxes are tight in f32, except that a pre-split triangle's boxes
//! come from clipping its edges, rounded either way. Each box grows on every side by 2^-20 of
//! its coordinates' magnitude (8 ulp) plus 2^-20 of the scene's extent: more than that
//! clipping's rounding, and than the rounding of the slab distances and of the triangle test's
//! t, so a triangle lying in a box face (axis-aligned walls: zero-thickness boxes) is never
//! culled by a rounding; see `traverse`. On a million-triangle scene that is a thousandth of a
//! triangle's size: no measurable extra culling work.

use super::collapse::{Collapsed, SlotKind, Wide};

/// Leaf triangles per node at most (what fits the node's 256 bytes); the collapse keeps to it.
pub(super) const NODE_TRIANGLES: usize = 24;
/// Triangle references must stay below this (the rows' offsets are 9 times them, in usize).
const TRIANGLE_LIMIT: usize = 1 << 29;
/// Child reference of an empty slot (its box is empty, so it is never hit).
pub(super) const EMPTY: u32 = u32::MAX;
/// Child boxes grow on each side by this fraction of their coordinates' magnitude (8 ulp)
/// plus this fraction of the scene's extent.
const BOX_PAD: f32 = 1.0 / (1 << 20) as f32;

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
    /// Lays out the collapsed tree over `tris` (scene triangles, indexed by its primitives);
    /// node i here is its node i.
    ///
    /// Panics past 2^29 triangle references (a scene far beyond what fits in memory here).
    pub fn from_collapsed(tree: &Collapsed, tris: &[[glam::Vec3A; 3]]) -> Bvh8 {
        assert!(
            tree.primitives.len() < TRIANGLE_LIMIT,
            "too many triangles for the BVH's leaf references"
        );
        let mut out = Bvh8 {
            nodes: Vec::with_capacity(tree.nodes.len()),
            rows: Vec::with_capacity(9 * tree.primitives.len() + ROWS_PAD),
            ids: Vec::with_capacity(tree.primitives.len()),
        };
        let pad = Pad::new(tree);
        for wide in &tree.nodes {
            let node = convert(wide, tree, tris, &pad, &mut out);
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

/// How much a box grows on each side (see the module's notes).
struct Pad {
    /// The scene's largest extent, times `BOX_PAD`.
    floor: f32,
}

impl Pad {
    fn new(tree: &Collapsed) -> Pad {
        let extent = tree
            .nodes
            .first()
            .into_iter()
            .flat_map(|n| n.slots.iter().flatten())
            .map(|s| (s.bounds.max - s.bounds.min).max_element())
            .fold(0.0f32, f32::max);
        Pad {
            floor: extent * BOX_PAD,
        }
    }

    /// `lo` and `hi` of one axis, grown by `BOX_PAD` of their magnitude plus `floor`.
    fn grow(&self, lo: f32, hi: f32) -> (f32, f32) {
        let d = lo.abs().max(hi.abs()) * BOX_PAD + self.floor;
        (lo - d, hi + d)
    }
}

fn convert(
    wide: &Wide,
    tree: &Collapsed,
    tris: &[[glam::Vec3A; 3]],
    pad: &Pad,
    out: &mut Bvh8,
) -> Node {
    let mut node = Node {
        bounds: [
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
        ],
        child: [EMPTY; 8],
        lane_slot: [0; NODE_TRIANGLES],
        first: out.ids.len() as u32,
        count: 0,
        leaves: 0,
        _pad: [0; 2],
    };
    let mut ids = Vec::with_capacity(NODE_TRIANGLES);
    for (i, slot) in wide.slots.iter().enumerate() {
        let Some(slot) = slot else { continue };
        let (lo, hi) = (slot.bounds.min.to_array(), slot.bounds.max.to_array());
        for axis in 0..3 {
            let (l, h) = pad.grow(lo[axis], hi[axis]);
            node.bounds[2 * axis][i] = l;
            node.bounds[2 * axis + 1][i] = h;
        }
        match slot.kind {
            SlotKind::Leaf { start, count } => {
                for &id in &tree.primitives[start as usize..(start + count) as usize] {
                    assert!(
                        ids.len() < NODE_TRIANGLES,
                        "a collapsed node with more than {NODE_TRIANGLES} leaf triangles"
                    );
                    node.lane_slot[ids.len()] = 1 << i;
                    ids.push(id);
                }
                node.leaves |= 1 << i;
            }
            SlotKind::Inner(c) => node.child[i] = c,
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
