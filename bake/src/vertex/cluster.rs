//! Clustering a group's vertices for compression (docs/vertex.md "Compression"): k-means on
//! position and normal. Nearby vertices facing the same way see nearly the same light paths,
//! so their transfer tensors share light and element factors (the thesis clusters by CPCA
//! error instead; spatial clusters cost nothing to find and keep each cluster's vertex
//! factor smooth). Deterministic: farthest-point seeds from the first vertex, a fixed number
//! of Lloyd iterations, sequential sums in vertex order.

/// Lloyd iterations after seeding: the assignment rarely changes after a few.
const ITERATIONS: usize = 8;

/// Assigns each of `positions.len()` vertices (with unit `normals`) one of at most `k`
/// clusters; returns the cluster of each vertex and the number of clusters (empty ones are
/// dropped and the rest numbered by first appearance in vertex order, so every cluster in
/// `0..count` has a vertex).
pub fn cluster_vertices(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    k: usize,
) -> (Vec<u32>, usize) {
    let n = positions.len();
    if n == 0 {
        return (Vec::new(), 0);
    }
    let k = k.clamp(1, n);
    let features = features(positions, normals, k);
    let mut centres = farthest_point_seeds(&features, k);
    let mut assign = vec![0u32; n];
    for _ in 0..ITERATIONS {
        for (a, f) in assign.iter_mut().zip(&features) {
            *a = nearest(&centres, f) as u32;
        }
        let mut sums = vec![[0.0f64; 6]; centres.len()];
        let mut counts = vec![0usize; centres.len()];
        for (&a, f) in assign.iter().zip(&features) {
            let s = &mut sums[a as usize];
            for (s, &x) in s.iter_mut().zip(f) {
                *s += f64::from(x);
            }
            counts[a as usize] += 1;
        }
        for ((c, s), &m) in centres.iter_mut().zip(&sums).zip(&counts) {
            if m > 0 {
                for (c, &s) in c.iter_mut().zip(s) {
                    *c = (s / m as f64) as f32;
                }
            }
        }
    }
    for (a, f) in assign.iter_mut().zip(&features) {
        *a = nearest(&centres, f) as u32;
    }
    // Renumber by first appearance, dropping empty clusters.
    let mut number = vec![u32::MAX; centres.len()];
    let mut count = 0u32;
    for a in assign.iter_mut() {
        let slot = &mut number[*a as usize];
        if *slot == u32::MAX {
            *slot = count;
            count += 1;
        }
        *a = *slot;
    }
    (assign, count as usize)
}

/// Position scaled to the group's bounding box diagonal, and the normal weighted so that a
/// normal turned by about 60 degrees counts like a cluster's typical width (`k^(-1/2)` of the
/// extent on a surface).
fn features(positions: &[[f32; 3]], normals: &[[f32; 3]], k: usize) -> Vec<[f32; 6]> {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in positions {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    let diag = (0..3).map(|i| (hi[i] - lo[i]).powi(2)).sum::<f32>().sqrt();
    let inv = if diag > 0.0 && diag.is_finite() {
        1.0 / diag
    } else {
        1.0
    };
    let w = 1.0 / (k as f32).sqrt();
    positions
        .iter()
        .zip(normals)
        .map(|(p, nrm)| {
            [
                (p[0] - lo[0]) * inv,
                (p[1] - lo[1]) * inv,
                (p[2] - lo[2]) * inv,
                nrm[0] * w,
                nrm[1] * w,
                nrm[2] * w,
            ]
        })
        .collect()
}

fn dist2(a: &[f32; 6], b: &[f32; 6]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Index of the centre nearest to `f` (the first on ties).
fn nearest(centres: &[[f32; 6]], f: &[f32; 6]) -> usize {
    let mut best = (f32::INFINITY, 0);
    for (i, c) in centres.iter().enumerate() {
        let d = dist2(c, f);
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1
}

/// `k` seeds: the first vertex, then repeatedly the vertex farthest from every seed so far
/// (the first on ties), which spreads seeds over the whole group.
fn farthest_point_seeds(features: &[[f32; 6]], k: usize) -> Vec<[f32; 6]> {
    let mut seeds = vec![features[0]];
    let mut d: Vec<f32> = features.iter().map(|f| dist2(f, &features[0])).collect();
    while seeds.len() < k {
        let (mut far, mut at) = (-1.0f32, 0);
        for (i, &x) in d.iter().enumerate() {
            if x > far {
                far = x;
                at = i;
            }
        }
        if far <= 0.0 {
            break; // every vertex coincides with a seed
        }
        let s = features[at];
        for (x, f) in d.iter_mut().zip(features) {
            *x = x.min(dist2(f, &s));
        }
        seeds.push(s);
    }
    seeds
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separated_blobs_become_one_cluster_each_numbered_by_first_vertex() {
        // Three blobs of 10 vertices, interleaved in vertex order.
        let centres = [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [0.0, 5.0, 0.0]];
        let mut p = Vec::new();
        for i in 0..30 {
            let c = centres[(i + 1) % 3];
            let o = (i / 3) as f32 * 0.01;
            p.push([c[0] + o, c[1] - o, c[2] + 0.5 * o]);
        }
        let n = vec![[0.0, 1.0, 0.0]; 30];
        let (a, k) = cluster_vertices(&p, &n, 3);
        assert_eq!(k, 3);
        for (i, &c) in a.iter().enumerate() {
            assert_eq!(c as usize, i % 3, "vertex {i}");
        }
    }

    #[test]
    fn opposite_normals_at_one_place_split_and_duplicates_never_leave_empty_clusters() {
        let p = vec![[0.0, 0.0, 0.0]; 8];
        let n: Vec<[f32; 3]> = (0..8)
            .map(|i| {
                if i < 4 {
                    [0.0, 1.0, 0.0]
                } else {
                    [0.0, -1.0, 0.0]
                }
            })
            .collect();
        let (a, k) = cluster_vertices(&p, &n, 5);
        assert_eq!(k, 2, "only two distinct vertices: {a:?}");
        assert!(a[..4].iter().all(|&c| c == 0) && a[4..].iter().all(|&c| c == 1));
        assert_eq!(cluster_vertices(&[], &[], 4), (Vec::new(), 0));
        assert_eq!(cluster_vertices(&p[..1], &n[..1], 4), (vec![0], 1));
    }
}
