//! From obvhs' binary BVH to a tree of eight-wide nodes, by the cost-based collapse of Ylitie,
//! Karras and Laine (2017, "Efficient incoherent ray traversal on GPUs through compressed
//! wide BVHs"): a dynamic programme over the binary tree picks, for each subtree, the cheapest
//! of "one leaf", "one wide node" and "spread over i slots of the parent" under a surface-area
//! cost.
//!
//! Why not obvhs' own collapse (its CWBVH conversion): its compressed node encodes at most 3
//! triangles per leaf and its cost charges each triangle a fixed 0.3 of a node, both fitted to
//! a GPU that tests one triangle at a time. Our node tests all its leaf triangles together in
//! sixteen-lane passes ([`super::bvh8`]), so a triangle costs far less than a node visit, and
//! bigger leaves buy a shallower tree: fewer dependent node loads per ray, which is what bounds
//! traversal once the tree outgrows the caches.

use obvhs::{aabb::Aabb, bvh2::Bvh2};

/// Cost of visiting a node, per unit of its half area (the surface-area heuristic's weight).
const NODE_COST: f32 = 1.0;

/// One wide node: up to eight slots (unused ones are `None`).
#[derive(Clone, Debug, Default)]
pub(super) struct Wide {
    pub slots: [Option<Slot>; 8],
}

/// A wide node's child: its box and what it holds.
#[derive(Clone, Debug)]
pub(super) struct Slot {
    pub bounds: Aabb,
    pub kind: SlotKind,
}

#[derive(Clone, Debug)]
pub(super) enum SlotKind {
    /// Index of the child's wide node.
    Inner(u32),
    /// The leaf's primitives: `Collapsed::primitives[start..start + count]`.
    Leaf { start: u32, count: u32 },
}

/// The wide tree: `nodes[0]` is the root; each leaf's scene triangles in `primitives` (a
/// triangle split by obvhs' spatial splits may sit in several leaves).
#[derive(Debug, Default)]
pub(super) struct Collapsed {
    pub nodes: Vec<Wide>,
    pub primitives: Vec<u32>,
}

/// The collapse's cost model: at most `max_leaf` triangles per leaf, each costing `tri_cost`
/// of a node visit (both weighted by the box's half area).
#[derive(Clone, Copy, Debug)]
pub(super) struct CollapseCost {
    pub max_leaf: u32,
    pub tri_cost: f32,
}

impl CollapseCost {
    /// Measured on incoherent bounce rays against the CWBVH's 3 and 0.3 (which this collapse
    /// reproduces, at the same speed): in `bench/compare/run.sh`'s interleaved rounds (eight
    /// figures per scene: closest hit and occlusion, one ray and streams, one and two
    /// threads) 100K triangles +0 to +13 %, 1M -2 to +16 %, the Cornell box -6 to +10 %
    /// (its noise). The tree has a quarter fewer nodes (1M: 76K instead of 102K; 1.9
    /// triangles per leaf instead of 1.45). A cap of 6, 12 or 16, or a triangle cost of 0.15
    /// or 0.3, measured within the noise of this one; above 8 the cap hardly binds.
    pub const DEFAULT: CollapseCost = CollapseCost {
        max_leaf: 8,
        tri_cost: 0.2,
    };
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Leaf,
    Inner,
    /// Spread over several of the parent's slots: the two binary children take `left` and
    /// the rest.
    Spread,
}

/// The best way to hold one binary subtree in at most `i + 1` of its parent's slots (entry i).
#[derive(Clone, Copy, Debug)]
struct Decision {
    cost: f32,
    kind: Kind,
    /// Slots given to the left binary child (for `Inner` at entry 0, out of eight).
    left: u8,
}

const NONE: Decision = Decision {
    cost: f32::INFINITY,
    kind: Kind::Leaf,
    left: 0,
};

/// Collapses `bvh2` (non-empty, one primitive per leaf, as obvhs' PLOC builds it) into nodes
/// whose leaves hold at most `node_triangles` triangles together (the layout's capacity).
pub(super) fn collapse(bvh2: &Bvh2, cost: CollapseCost, node_triangles: usize) -> Collapsed {
    let max_leaf = cost.max_leaf.clamp(1, node_triangles as u32);
    let n = bvh2.nodes.len();
    let mut decisions = vec![[NONE; 7]; n];
    let mut counts = vec![0u32; n];
    // Children before parents: a post-order walk with an explicit stack (obvhs' trees can be
    // deep on degenerate input).
    let mut stack = vec![(0usize, false)];
    while let Some((i, children_done)) = stack.pop() {
        let node = &bvh2.nodes[i];
        if node.is_leaf() {
            counts[i] = node.prim_count;
            let leaf = Decision {
                cost: node.aabb().half_area() * cost.tri_cost * node.prim_count as f32,
                kind: Kind::Leaf,
                left: 0,
            };
            decisions[i] = [leaf; 7];
            continue;
        }
        let (l, r) = (node.first_index as usize, node.first_index as usize + 1);
        if !children_done {
            stack.extend([(i, true), (l, false), (r, false)]);
            continue;
        }
        counts[i] = counts[l] + counts[r];
        decisions[i] = decide(
            node.aabb().half_area(),
            counts[i],
            &decisions[l],
            &decisions[r],
            max_leaf,
            cost.tri_cost,
        );
    }
    let mut out = Collapsed::default();
    Emitter {
        bvh2,
        decisions: &decisions,
        counts: &counts,
        node_triangles,
        out: &mut out,
    }
    .emit();
    out
}

/// The decisions of a binary node of half area `area` and `count` primitives, from its
/// children's.
fn decide(
    area: f32,
    count: u32,
    l: &[Decision; 7],
    r: &[Decision; 7],
    max_leaf: u32,
    tri_cost: f32,
) -> [Decision; 7] {
    let mut d = [NONE; 7];
    // Entry 0: a leaf, or a node whose eight slots the children share (k to the left).
    let (mut spread8, mut left8) = (f32::INFINITY, 1);
    for k in 1..8 {
        let c = l[k - 1].cost + r[7 - k].cost;
        if c < spread8 {
            (spread8, left8) = (c, k as u8);
        }
    }
    let inner = area * NODE_COST + spread8;
    let leaf = if count <= max_leaf {
        area * tri_cost * count as f32
    } else {
        f32::INFINITY
    };
    // The inner split is kept even when the leaf wins: a wide node that cannot fit all its
    // leaves' triangles turns a leaf child into a node (`Emitter::children`).
    d[0] = Decision {
        cost: leaf.min(inner),
        kind: if leaf < inner {
            Kind::Leaf
        } else {
            Kind::Inner
        },
        left: left8,
    };
    // Entry i: up to i + 1 slots; spreading gives k to the left and i + 1 - k to the right.
    for i in 1..7 {
        d[i] = d[i - 1];
        for k in 1..=i {
            let c = l[k - 1].cost + r[i - k].cost;
            if c < d[i].cost {
                d[i] = Decision {
                    cost: c,
                    kind: Kind::Spread,
                    left: k as u8,
                };
            }
        }
    }
    d
}

struct Emitter<'a> {
    bvh2: &'a Bvh2,
    decisions: &'a [[Decision; 7]],
    counts: &'a [u32],
    node_triangles: usize,
    out: &'a mut Collapsed,
}

impl Emitter<'_> {
    /// Writes the wide nodes depth first, each node's inner children next to each other.
    fn emit(&mut self) {
        let root = &self.bvh2.nodes[0];
        self.out.nodes.push(Wide::default());
        if root.is_leaf() {
            // A single primitive: one node with one leaf.
            let slot = self.leaf_slot(0);
            self.out.nodes[0].slots[0] = Some(slot);
            return;
        }
        let mut todo = vec![(0u32, 0usize)];
        while let Some((wide, binary)) = todo.pop() {
            let children = self.children(binary);
            let first = self.out.nodes.len() as u32;
            let mut inner = 0;
            for (s, &(c, is_leaf)) in children.iter().enumerate() {
                let slot = if is_leaf {
                    self.leaf_slot(c)
                } else {
                    inner += 1;
                    Slot {
                        bounds: *self.bvh2.nodes[c].aabb(),
                        kind: SlotKind::Inner(first + inner - 1),
                    }
                };
                self.out.nodes[wide as usize].slots[s] = Some(slot);
            }
            self.out
                .nodes
                .resize(self.out.nodes.len() + inner as usize, Wide::default());
            // Reversed, so the first inner child is written next.
            let inner_children = children.iter().filter(|c| !c.1).map(|c| c.0);
            let pending: Vec<_> = (first..).zip(inner_children).collect();
            todo.extend(pending.into_iter().rev());
        }
    }

    /// The slots of the wide node made of binary node `i`: (binary node, is a leaf), at most
    /// eight, their leaves' triangles at most `node_triangles` together.
    fn children(&self, i: usize) -> Vec<(usize, bool)> {
        let mut slots = Vec::with_capacity(8);
        let node = &self.bvh2.nodes[i];
        let left = self.decisions[i][0].left as usize;
        let l = node.first_index as usize;
        self.gather(l, left - 1, &mut slots);
        self.gather(l + 1, 8 - left - 1, &mut slots);
        // Too many triangles for one node (possible with leaves above 3): the biggest leaves
        // become nodes of their own. Such a leaf holds more than one primitive, so it is an
        // inner binary node and has an inner split.
        loop {
            let total: u32 = slots.iter().filter(|s| s.1).map(|s| self.counts[s.0]).sum();
            if total as usize <= self.node_triangles {
                break;
            }
            if let Some(s) = slots
                .iter_mut()
                .filter(|s| s.1 && !self.bvh2.nodes[s.0].is_leaf())
                .max_by_key(|s| self.counts[s.0])
            {
                s.1 = false;
            } else {
                break;
            }
        }
        slots
    }

    /// The slots binary node `i` fills when given entry `e` of its decisions.
    fn gather(&self, i: usize, e: usize, slots: &mut Vec<(usize, bool)>) {
        let d = self.decisions[i][e];
        if d.kind != Kind::Spread {
            // A slot of its own; its kind is entry 0's (entries that do not spread copy it).
            slots.push((i, self.decisions[i][0].kind == Kind::Leaf));
            return;
        }
        let l = self.bvh2.nodes[i].first_index as usize;
        let left = d.left as usize;
        self.gather(l, left - 1, slots);
        self.gather(l + 1, e + 1 - left - 1, slots);
    }

    /// A leaf slot holding every primitive under binary node `i`.
    fn leaf_slot(&mut self, i: usize) -> Slot {
        let start = self.out.primitives.len() as u32;
        let mut stack = vec![i];
        while let Some(j) = stack.pop() {
            let node = &self.bvh2.nodes[j];
            if node.is_leaf() {
                let first = node.first_index as usize;
                self.out.primitives.extend_from_slice(
                    &self.bvh2.primitive_indices[first..first + node.prim_count as usize],
                );
            } else {
                stack.extend([node.first_index as usize + 1, node.first_index as usize]);
            }
        }
        Slot {
            bounds: *self.bvh2.nodes[i].aabb(),
            kind: SlotKind::Leaf {
                start,
                count: self.out.primitives.len() as u32 - start,
            },
        }
    }
}
