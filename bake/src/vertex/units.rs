//! The units of a per-vertex bake (docs/vertex.md, "Bounded memory"): each group's vertices
//! split into **super-clusters** of at most [`UNIT_VERTICES`] by recursive bisection on
//! position and normal, each super-cluster split twice more, into halves and quarters, for the
//! compression's cluster candidates.
//!
//! The clusters of the compression depend only on positions and normals, so they are chosen
//! here, before any tracing. A unit is then traced, compressed and written out on its own:
//! the bake holds only the units in flight, never a group's dense tensors, and a unit is also
//! what a checkpoint saves and what a shard bakes.
//!
//! Bisection rather than k-means: it is O(V log V) for any vertex count (k-means with
//! `V / 128` centres is O(V^2 / 128) per iteration: hours at a million vertices), it gives the
//! nested halves and quarters the candidates need, and its clusters are as compact. Each split
//! cuts at the median of the feature with the largest spread, so halves differ by at most one
//! vertex; the features are the position scaled to the group's extent and the normal weighted
//! so that a turn of about 60 degrees counts like a cluster's width (the k-means' weighting
//! before). Deterministic: ties are broken by vertex index.

use glam::Vec3;

/// Largest super-cluster: the unit of tracing, compression, checkpoints and shards.
pub const UNIT_VERTICES: usize = 256;

/// Vertices per cluster the normal weighting is scaled for (a cluster's typical width).
const CLUSTER_WIDTH_VERTICES: usize = 128;

/// One super-cluster of a group.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Unit {
    /// The group (index into `VertexPlan::groups`).
    pub group: usize,
    /// Its vertices (global indices), quarter after quarter: `vertices[..half]` is the first
    /// half, `vertices[half..]` the second; `quarters` gives the four quarters' ends.
    pub vertices: Vec<u32>,
    /// End of the first half in `vertices`.
    pub half: usize,
    /// Ends of the four quarters in `vertices` (the last is `vertices.len()`; a quarter may be
    /// empty for a unit of fewer than four vertices).
    pub quarters: [usize; 4],
}

impl Unit {
    /// The unit's clusters when split into `parts` (1, 2 or 4) clusters: the ranges of
    /// `vertices` each covers, empty ones left out.
    pub fn clusters(&self, parts: usize) -> Vec<std::ops::Range<usize>> {
        let n = self.vertices.len();
        let ends: Vec<usize> = match parts {
            1 => vec![n],
            2 => vec![self.half, n],
            _ => self.quarters.to_vec(),
        };
        let mut out = Vec::with_capacity(ends.len());
        let mut start = 0;
        for e in ends {
            if e > start {
                out.push(start..e);
            }
            start = e;
        }
        out
    }
}

/// Splits each group's vertices (`groups[g]`, global indices) into units of at most
/// `max_unit` vertices ([`UNIT_VERTICES`] by default), group after group. `positions` and
/// `normals` are per global vertex.
pub fn plan_units(
    groups: &[&[u32]],
    positions: &[Vec3],
    normals: &[Vec3],
    max_unit: usize,
) -> Vec<Unit> {
    let mut out = Vec::new();
    for (g, vertices) in groups.iter().enumerate() {
        if vertices.is_empty() {
            continue;
        }
        let features = Features::new(vertices, positions, normals);
        let mut items: Vec<Item> = vertices
            .iter()
            .map(|&v| Item {
                vertex: v,
                f: features.of(v, positions, normals),
            })
            .collect();
        split_into_units(&mut items, g, max_unit.max(1), &mut out);
    }
    out
}

/// A vertex with its six features.
#[derive(Clone, Copy)]
struct Item {
    vertex: u32,
    f: [f32; 6],
}

/// The group-wide feature scaling.
struct Features {
    lo: Vec3,
    inv: f32,
    normal_weight: f32,
}

impl Features {
    fn new(vertices: &[u32], positions: &[Vec3], _normals: &[Vec3]) -> Features {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for &v in vertices {
            lo = lo.min(positions[v as usize]);
            hi = hi.max(positions[v as usize]);
        }
        let diag = (hi - lo).length();
        let inv = if diag > 0.0 && diag.is_finite() {
            1.0 / diag
        } else {
            1.0
        };
        // A cluster of CLUSTER_WIDTH_VERTICES on a surface spans about k^(-1/2) of the extent.
        let k = vertices.len().div_ceil(CLUSTER_WIDTH_VERTICES).max(1);
        Features {
            lo: if lo.is_finite() { lo } else { Vec3::ZERO },
            inv,
            normal_weight: 1.0 / (k as f32).sqrt(),
        }
    }

    fn of(&self, v: u32, positions: &[Vec3], normals: &[Vec3]) -> [f32; 6] {
        let p = (positions[v as usize] - self.lo) * self.inv;
        let n = normals[v as usize] * self.normal_weight;
        [p.x, p.y, p.z, n.x, n.y, n.z]
    }
}

/// Bisects `items` until every part has at most `max_unit`; each part becomes a unit (in
/// order: first half's units before the second half's).
fn split_into_units(items: &mut [Item], group: usize, max_unit: usize, out: &mut Vec<Unit>) {
    if items.len() <= max_unit {
        out.push(unit(items, group));
        return;
    }
    let mid = bisect(items);
    let (a, b) = items.split_at_mut(mid);
    split_into_units(a, group, max_unit, out);
    split_into_units(b, group, max_unit, out);
}

/// A unit from its items: split into halves, each half into quarters.
fn unit(items: &mut [Item], group: usize) -> Unit {
    let n = items.len();
    let half = if n >= 2 { bisect(items) } else { n };
    let (a, b) = items.split_at_mut(half);
    let qa = if a.len() >= 2 { bisect(a) } else { a.len() };
    let qb = if b.len() >= 2 { bisect(b) } else { b.len() };
    Unit {
        group,
        vertices: items.iter().map(|i| i.vertex).collect(),
        half,
        quarters: [qa, half, half + qb, n],
    }
}

/// Reorders `items` so that the first `n / 2` are those with the smaller values of the feature
/// with the largest spread (ties by vertex index), and returns `n / 2`.
fn bisect(items: &mut [Item]) -> usize {
    let mut lo = [f32::INFINITY; 6];
    let mut hi = [f32::NEG_INFINITY; 6];
    for it in items.iter() {
        for k in 0..6 {
            lo[k] = lo[k].min(it.f[k]);
            hi[k] = hi[k].max(it.f[k]);
        }
    }
    let mut axis = 0;
    let mut best = -1.0f32;
    for k in 0..6 {
        let spread = hi[k] - lo[k];
        if spread > best {
            best = spread;
            axis = k;
        }
    }
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| {
        a.f[axis]
            .total_cmp(&b.f[axis])
            .then(a.vertex.cmp(&b.vertex))
    });
    // Each side in vertex order: the selection leaves them in an order that depends on the
    // algorithm's internals, and a deterministic, stable order is what the file stores.
    items[..mid].sort_unstable_by_key(|i| i.vertex);
    items[mid..].sort_unstable_by_key(|i| i.vertex);
    mid
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize) -> (Vec<Vec3>, Vec<Vec3>) {
        let mut p = Vec::new();
        for j in 0..n {
            for i in 0..n {
                p.push(Vec3::new(i as f32, 0.0, j as f32));
            }
        }
        let nrm = vec![Vec3::Y; p.len()];
        (p, nrm)
    }

    #[test]
    fn every_vertex_lands_in_exactly_one_unit_of_bounded_size_with_nested_parts() {
        let (p, n) = grid(70); // 4900 vertices
        let all: Vec<u32> = (0..p.len() as u32).collect();
        let odd: Vec<u32> = all.iter().copied().filter(|v| v % 7 == 3).collect();
        let units = plan_units(&[&all, &odd], &p, &n, UNIT_VERTICES);
        let mut seen = vec![0u8; p.len() * 2];
        for u in &units {
            assert!(u.vertices.len() <= UNIT_VERTICES && !u.vertices.is_empty());
            assert!(u.vertices.len() > UNIT_VERTICES / 2 || u.group == 1);
            for &v in &u.vertices {
                seen[u.group * p.len() + v as usize] += 1;
            }
            // Halves differ by at most one vertex, quarters likewise within their half.
            let n = u.vertices.len();
            assert!(u.half == n / 2);
            assert_eq!(u.quarters[1], u.half);
            assert_eq!(u.quarters[3], n);
            assert_eq!(u.clusters(4).iter().map(|r| r.len()).sum::<usize>(), n);
            assert_eq!(u.clusters(1), vec![0..n]);
        }
        for v in 0..p.len() {
            assert_eq!(seen[v], 1, "vertex {v}");
            assert_eq!(seen[p.len() + v], u8::from(v % 7 == 3), "odd vertex {v}");
        }
        // Units are compact: on a grid, a unit of ~150-256 vertices spans far less than the
        // whole 70 x 70.
        for u in units.iter().filter(|u| u.group == 0) {
            let (mut lo, mut hi) = (Vec3::splat(1e9), Vec3::splat(-1e9));
            for &v in &u.vertices {
                lo = lo.min(p[v as usize]);
                hi = hi.max(p[v as usize]);
            }
            assert!((hi - lo).length() < 30.0, "{lo} {hi}");
        }
    }

    #[test]
    fn opposite_normals_at_one_place_are_split_before_position() {
        // Two coincident sheets facing away from each other: the halves are the sheets.
        let (p, _) = grid(10);
        let mut pos = p.clone();
        pos.extend(&p);
        let mut nrm = vec![Vec3::Y; p.len()];
        nrm.extend(vec![Vec3::NEG_Y; p.len()]);
        let all: Vec<u32> = (0..pos.len() as u32).collect();
        let units = plan_units(&[&all], &pos, &nrm, UNIT_VERTICES);
        assert_eq!(units.len(), 1);
        let u = &units[0];
        let first: Vec<bool> = u.vertices[..u.half]
            .iter()
            .map(|&v| (v as usize) < p.len())
            .collect();
        assert!(first.iter().all(|&f| f == first[0]), "{:?}", u.vertices);
    }

    #[test]
    fn tiny_groups_and_the_same_input_give_the_same_units() {
        let p = vec![Vec3::ZERO, Vec3::X];
        let n = vec![Vec3::Y; 2];
        let units = plan_units(&[&[1], &[], &[0, 1]], &p, &n, UNIT_VERTICES);
        assert_eq!(units.len(), 2);
        assert_eq!(units[0].vertices, [1]);
        assert_eq!(units[0].clusters(2), vec![0..1]);
        assert_eq!(units[0].clusters(4), vec![0..1]);
        assert_eq!(units[1].group, 2);
        assert_eq!(units[1].clusters(2).len(), 2);
        let (p, n) = grid(40);
        let all: Vec<u32> = (0..p.len() as u32).collect();
        assert_eq!(
            plan_units(&[&all], &p, &n, UNIT_VERTICES),
            plan_units(&[&all], &p, &n, UNIT_VERTICES)
        );
    }
}
