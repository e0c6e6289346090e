//! Compression of a group's T1 and T2 by clustered Tucker approximation (thesis 5.3.3.4-5;
//! docs/vertex.md "Compression"; the layout is `prt_formats::clustered`).
//!
//! Per cluster of vertices (`cluster.rs`) the dense block `X[v][l][w]` is decomposed by the
//! sequentially truncated higher-order SVD: the element mode first (its Gram matrix is the
//! cheapest, `W x W`), then the light mode of the element-projected block, then the vertex
//! mode of what is left, which gives the core. Each step keeps the fewest leading eigenvectors
//! whose discarded eigenvalues fit its share of the error budget: with ST-HOSVD the squared
//! error of the result is exactly the sum of the energies discarded at the three steps, so a
//! cluster meets `error_target` (relative L2) whenever no rank cap binds, and the error
//! reported is the one made (before storage rounding).
//!
//! Every cluster is computed sequentially (faer with `Par::Seq`) from its own rows; clusters
//! run in parallel and are placed in cluster order, so the result does not depend on the
//! thread count.

use faer::Mat;
use glam::Vec3;
use prt_formats::clustered::{CompressionSettings, GroupCompression, TensorCompression};
use prt_formats::pixel::Precision;
use prt_formats::vertex::{cube_len, SH_TERMS, T1_LIGHT_CUBE, T2_LIGHT_CUBE};
use rayon::prelude::*;

use crate::basis::linalg::{matmul, matmul_tn, sign_fixed_columns, sym_eig_desc};
use crate::scene::Scene;

use super::cluster::cluster_vertices;
use super::cluster_choice::{describe, next_size, pick, ClusterCandidate};
use super::error::VertexError;
use super::write::{store, store_unscaled, value_bytes, StoredTucker};
use super::CompressedGroupData;

/// One cluster's Tucker factors (f32, row-major).
struct ClusterTucker {
    /// `(a, r, b)`.
    ranks: [usize; 3],
    /// `light (L x a)` then `element (W x r)`.
    factors: Vec<f32>,
    /// `b x a x r`.
    core: Vec<f32>,
    /// `n x b`: the cluster's vertices' rows of the vertex factor, in vertex order.
    vertex: Vec<f32>,
    /// Squared error made and squared norm of the block.
    sq_error: f64,
    sq_norm: f64,
}

/// A group's compressed tensor in f32 before storage.
pub(crate) struct CompressedTensor {
    /// `[K, 3]` `(a, r, b)`.
    pub ranks: Vec<u32>,
    pub factors: Vec<f32>,
    pub core: Vec<f32>,
    /// `[V, B]`.
    pub vertex: Vec<f32>,
    pub figures: TensorCompression,
}

impl CompressedTensor {
    /// Bytes it stores with `value_bytes` per value: the ranks (u32), factors, cores and
    /// vertex rows.
    pub(crate) fn stored_bytes(&self, value_bytes: u64) -> u64 {
        4 * self.ranks.len() as u64
            + value_bytes * (self.factors.len() + self.core.len() + self.vertex.len()) as u64
    }

    /// Converts to the storage precision; returns the stored tensor and the core's scale.
    pub(crate) fn store(self, precision: Precision) -> (StoredTucker, f32) {
        let (core, scale) = store(self.core, precision);
        (
            StoredTucker {
                ranks: self.ranks,
                factors: store_unscaled(self.factors, precision),
                core,
                vertex: store_unscaled(self.vertex, precision),
                vertex_rank: self.figures.vertex_rank as usize,
            },
            scale,
        )
    }
}

/// The shape of a group's T1 and T2 (their element counts).
#[derive(Clone, Copy, Debug)]
pub(crate) struct GroupShape {
    /// Active slots J.
    pub active: usize,
    /// Slots I of T2's first reflection.
    pub t2_slots: usize,
    /// 1 or 3.
    pub channels: usize,
    /// 2 or 3 (T2 only with 3).
    pub reflections: u32,
}

/// A compressed group: what is stored, its metadata, the core scales and a line saying what was
/// chosen.
pub(crate) struct CompressedGroup {
    pub data: CompressedGroupData,
    pub meta: GroupCompression,
    pub scale_t1: f32,
    pub scale_t2: f32,
    pub summary: String,
    /// Every cluster size tried (one when `cluster_vertices` is given), in order (what the
    /// summary describes; the tests check the choice against it).
    #[cfg_attr(not(test), allow(dead_code))]
    pub tried: Vec<ClusterCandidate>,
}

/// Clusters a group's vertices (`vertices`, global indices into the scene and `normals`) and
/// compresses its dense T1 and T2 (`[V][bins][J x elements x channels]` f32, T2 empty when
/// reflections = 2), borrowed: with `settings.cluster_vertices` None every candidate size
/// (`cluster_choice.rs`) compresses the same tensors, one candidate after another, and only
/// the best so far is kept beside them.
#[allow(clippy::too_many_arguments)]
pub(crate) fn compress_group(
    scene: &Scene,
    normals: &[Vec3],
    vertices: &[u32],
    t1: &[f32],
    t2: &[f32],
    shape: GroupShape,
    settings: &CompressionSettings,
    precision: Precision,
) -> Result<CompressedGroup, VertexError> {
    let positions: Vec<[f32; 3]> = vertices
        .iter()
        .map(|&v| scene.positions[v as usize].to_array())
        .collect();
    let nrm: Vec<[f32; 3]> = vertices
        .iter()
        .map(|&v| normals[v as usize].to_array())
        .collect();
    let value_bytes = value_bytes(precision) as u64;
    let mut tried: Vec<ClusterCandidate> = Vec::new();
    let mut best: Option<GroupTuckers> = None;
    while let Some(size) = next_size(
        settings.cluster_vertices,
        vertices.len(),
        &tried,
        settings.error_target,
    ) {
        let wanted = vertices.len().div_ceil(size.max(1) as usize);
        let (clusters, count) = cluster_vertices(&positions, &nrm, wanted);
        let w1 = shape.active * SH_TERMS * shape.channels;
        let c1 = compress_tensor(t1, cube_len(T1_LIGHT_CUBE), w1, &clusters, count, settings)?;
        let c2 = if shape.reflections >= 3 {
            let w2 = shape.active * shape.t2_slots * shape.channels;
            Some(compress_tensor(
                t2,
                cube_len(T2_LIGHT_CUBE),
                w2,
                &clusters,
                count,
                settings,
            )?)
        } else {
            None
        };
        let candidate = ClusterCandidate {
            cluster_vertices: size,
            clusters: count,
            bytes: 4 * clusters.len() as u64
                + c1.stored_bytes(value_bytes)
                + c2.as_ref().map_or(0, |c| c.stored_bytes(value_bytes)),
            errors: std::iter::once(c1.figures.error)
                .chain(c2.as_ref().map(|c| c.figures.error))
                .collect(),
        };
        tried.push(candidate);
        // Keep this candidate if it is the pick among those tried so far: the pick of all is
        // then the last one kept (`pick` prefers the earlier candidate on ties).
        if pick(&tried, settings.error_target) == Some(tried.len() - 1) {
            best = Some(GroupTuckers {
                clusters,
                count,
                t1: c1,
                t2: c2,
            });
        }
    }
    let chosen = pick(&tried, settings.error_target).unwrap_or(0);
    let Some(GroupTuckers {
        clusters,
        count,
        t1: c1,
        t2: c2,
    }) = best
    else {
        return Err(VertexError::Compression(
            "no cluster size to compress with".into(),
        ));
    };
    let describe_tensor = |name: &str, c: &CompressedTensor| {
        let k = (c.ranks.len() / 3).max(1);
        let mean = |i: usize| {
            c.ranks
                .iter()
                .skip(i)
                .step_by(3)
                .map(|&r| r as f64)
                .sum::<f64>()
                / k as f64
        };
        let max = |i: usize| {
            c.ranks
                .iter()
                .skip(i)
                .step_by(3)
                .copied()
                .max()
                .unwrap_or(0)
        };
        format!(
            "{name} ranks light {:.1} (max {}), element {:.1} (max {}), vertex {:.1} (max {}), \
             error {:.2} %",
            mean(0),
            max(0),
            mean(1),
            max(1),
            mean(2),
            max(2),
            100.0 * c.figures.error
        )
    };
    let mut summary = format!(
        "{count} clusters of {} vertices (target error {:.1} %); {}",
        vertices.len().div_ceil(count.max(1)),
        100.0 * settings.error_target,
        describe_tensor("T1", &c1)
    );
    if let Some(c2) = &c2 {
        summary.push_str(&format!("; {}", describe_tensor("T2", c2)));
    }
    let why = describe(&tried, chosen, settings.error_target);
    if !why.is_empty() {
        summary.push_str(&format!("; {why}"));
    }
    let meta = GroupCompression {
        clusters: count as u32,
        t1: c1.figures,
        t2: c2.as_ref().map(|c| c.figures),
    };
    let (t1, scale_t1) = c1.store(precision);
    let (t2, scale_t2) = match c2 {
        Some(c) => {
            let (t, s) = c.store(precision);
            (Some(t), s)
        }
        None => (None, 1.0),
    };
    Ok(CompressedGroup {
        data: CompressedGroupData { clusters, t1, t2 },
        meta,
        scale_t1,
        scale_t2,
        summary,
        tried,
    })
}

/// One candidate's clusters and compressed tensors.
struct GroupTuckers {
    clusters: Vec<u32>,
    count: usize,
    t1: CompressedTensor,
    t2: Option<CompressedTensor>,
}

/// Compresses a group's dense tensor `t` (`[V][bins][width]` f32) with the vertices'
/// `clusters` (`count` of them).
pub(crate) fn compress_tensor(
    t: &[f32],
    bins: usize,
    width: usize,
    clusters: &[u32],
    count: usize,
    settings: &CompressionSettings,
) -> Result<CompressedTensor, VertexError> {
    let n = clusters.len();
    let row = bins * width;
    debug_assert_eq!(t.len(), n * row);
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); count];
    for (v, &c) in clusters.iter().enumerate() {
        members[c as usize].push(v);
    }
    let parts: Vec<ClusterTucker> = members
        .par_iter()
        .map(|m| {
            let mut block = Vec::with_capacity(m.len() * row);
            for &v in m {
                block.extend(t[v * row..(v + 1) * row].iter().map(|&x| f64::from(x)));
            }
            tucker_block(&block, m.len(), bins, width, settings)
        })
        .collect::<Result<_, _>>()?;
    let vertex_rank = parts.iter().map(|p| p.ranks[2]).max().unwrap_or(0);
    let mut out = CompressedTensor {
        ranks: Vec::with_capacity(3 * count),
        factors: Vec::new(),
        core: Vec::new(),
        vertex: vec![0.0; n * vertex_rank],
        figures: TensorCompression {
            vertex_rank: vertex_rank as u32,
            error: 0.0,
        },
    };
    let (mut sq_error, mut sq_norm) = (0.0f64, 0.0f64);
    for (p, m) in parts.iter().zip(&members) {
        out.ranks.extend(p.ranks.iter().map(|&r| r as u32));
        out.factors.extend_from_slice(&p.factors);
        out.core.extend_from_slice(&p.core);
        let b = p.ranks[2];
        for (i, &v) in m.iter().enumerate() {
            out.vertex[v * vertex_rank..v * vertex_rank + b]
                .copy_from_slice(&p.vertex[i * b..(i + 1) * b]);
        }
        sq_error += p.sq_error;
        sq_norm += p.sq_norm;
    }
    out.figures.error = if sq_norm > 0.0 {
        (sq_error.max(0.0) / sq_norm).sqrt() as f32
    } else {
        0.0
    };
    Ok(out)
}

/// The fewest leading eigenvalues (nonincreasing `vals`) whose discarded rest is at most
/// `budget`, at most `cap` and at least 1 (when there is a dimension); returns the rank and
/// the discarded energy.
fn rank_for(vals: &[f64], budget: f64, cap: usize) -> (usize, f64) {
    let dim = vals.len();
    if dim == 0 {
        return (0, 0.0);
    }
    let mut rest: f64 = vals.iter().map(|v| v.max(0.0)).sum();
    let mut r = 0;
    while r < dim.min(cap.max(1)) && (r == 0 || rest > budget) {
        rest -= vals[r].max(0.0);
        r += 1;
    }
    (r, rest.max(0.0))
}

/// The leading eigenvectors (sign-fixed) of a Gram matrix that [`rank_for`] keeps, and the
/// energy discarded.
fn leading(g: &Mat<f64>, budget: f64, cap: usize) -> Result<(Mat<f64>, f64), VertexError> {
    let (vals, vecs) =
        sym_eig_desc(g.as_ref()).map_err(|e| VertexError::Compression(e.to_string()))?;
    let (r, discarded) = rank_for(&vals, budget, cap);
    Ok((sign_fixed_columns(vecs.as_ref(), r), discarded))
}

/// ST-HOSVD of one cluster's block `x` (`[n][bins][width]`), see the module documentation.
fn tucker_block(
    x: &[f64],
    n: usize,
    bins: usize,
    width: usize,
    s: &CompressionSettings,
) -> Result<ClusterTucker, VertexError> {
    let sq_norm: f64 = x.iter().map(|v| v * v).sum();
    if n == 0 || bins == 0 || width == 0 {
        // Nothing to store (a group no slot sends light to has no T1 elements).
        return Ok(ClusterTucker {
            ranks: [0, 0, 0],
            factors: Vec::new(),
            core: Vec::new(),
            vertex: Vec::new(),
            sq_error: 0.0,
            sq_norm,
        });
    }
    let budget = f64::from(s.error_target).powi(2) * sq_norm;
    // Element mode: rows (v, l), columns w.
    let xw = Mat::from_fn(n * bins, width, |i, j| x[i * width + j]);
    let gw = matmul_tn(xw.as_ref(), xw.as_ref());
    let (ue, d_e) = leading(&gw, budget / 3.0, s.max_element_rank as usize)?;
    let r = ue.ncols();
    let y = matmul(xw.as_ref(), ue.as_ref()); // (v, l) x r
    drop(xw);
    // Light mode: rows (v, k), columns l.
    let yl = Mat::from_fn(n * r, bins, |i, l| {
        y[((i / r.max(1)) * bins + l, i % r.max(1))]
    });
    drop(y);
    let gl = matmul_tn(yl.as_ref(), yl.as_ref());
    let (ul, d_l) = leading(
        &gl,
        (2.0 * budget / 3.0 - d_e).max(0.0),
        s.max_light_rank as usize,
    )?;
    let a = ul.ncols();
    let z = matmul(yl.as_ref(), ul.as_ref()); // (v, k) x a
    drop(yl);
    // Vertex mode: rows (a, k) of the core's order, columns v.
    let zv = Mat::from_fn(a * r, n, |i, v| z[(v * r + i % r.max(1), i / r.max(1))]);
    drop(z);
    let gv = matmul_tn(zv.as_ref(), zv.as_ref());
    let (uv, d_v) = leading(
        &gv,
        (budget - d_e - d_l).max(0.0),
        s.max_vertex_rank as usize,
    )?;
    let b = uv.ncols();
    let core = matmul_tn(uv.as_ref(), zv.as_ref().transpose()); // b x (a, k)

    let mut factors = Vec::with_capacity(bins * a + width * r);
    for l in 0..bins {
        factors.extend((0..a).map(|c| ul[(l, c)] as f32));
    }
    for w in 0..width {
        factors.extend((0..r).map(|c| ue[(w, c)] as f32));
    }
    let core_flat = (0..b)
        .flat_map(|i| (0..a * r).map(move |j| (i, j)))
        .map(|(i, j)| core[(i, j)] as f32)
        .collect();
    let vertex = (0..n)
        .flat_map(|v| (0..b).map(move |c| (v, c)))
        .map(|(v, c)| uv[(v, c)] as f32)
        .collect();
    Ok(ClusterTucker {
        ranks: [a, r, b],
        factors,
        core: core_flat,
        vertex,
        sq_error: d_e + d_l + d_v,
        sq_norm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use prt_formats::clustered::TuckerLayout;

    fn settings(target: f32, caps: [u32; 3]) -> CompressionSettings {
        CompressionSettings {
            error_target: target,
            cluster_vertices: Some(64),
            max_light_rank: caps[0],
            max_element_rank: caps[1],
            max_vertex_rank: caps[2],
        }
    }

    /// The dense tensor the compressed one stands for (the layout's formula).
    fn expand(c: &CompressedTensor, clusters: &[u32], bins: usize, width: usize) -> Vec<f32> {
        let layout = TuckerLayout::new(&c.ranks, bins, width).expect("layout");
        let bw = layout.vertex_rank;
        let mut out = Vec::new();
        for (v, &cl) in clusters.iter().enumerate() {
            let cl = cl as usize;
            let [a, r, b] = layout.ranks[cl];
            let light = &c.factors[layout.factor_at[cl]..][..bins * a];
            let elem = &c.factors[layout.factor_at[cl] + bins * a..][..width * r];
            let core = &c.core[layout.core_at[cl]..][..b * a * r];
            let u = &c.vertex[v * bw..v * bw + b];
            for l in 0..bins {
                for w in 0..width {
                    let mut s = 0.0f64;
                    for bb in 0..b {
                        for aa in 0..a {
                            for rr in 0..r {
                                s += f64::from(u[bb])
                                    * f64::from(core[(bb * a + aa) * r + rr])
                                    * f64::from(light[l * a + aa])
                                    * f64::from(elem[w * r + rr]);
                            }
                        }
                    }
                    out.push(s as f32);
                }
            }
        }
        out
    }

    fn rel(a: &[f32], b: &[f32]) -> f64 {
        let d: f64 = a.iter().zip(b).map(|(x, y)| f64::from(x - y).powi(2)).sum();
        let n: f64 = b.iter().map(|y| f64::from(*y).powi(2)).sum();
        (d / n).sqrt()
    }

    /// A pseudo-random tensor.
    fn noise(len: usize, seed: u64) -> Vec<f32> {
        let mut s = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        (0..len)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5
            })
            .collect()
    }

    #[test]
    fn full_ranks_reproduce_the_tensor_and_the_factors_are_orthonormal() {
        let (n, bins, width) = (7, 5, 4);
        let t = noise(n * bins * width, 3);
        let clusters = [0, 1, 0, 1, 1, 0, 1];
        let c =
            compress_tensor(&t, bins, width, &clusters, 2, &settings(0.0, [99, 99, 99])).unwrap();
        let back = expand(&c, &clusters, bins, width);
        assert!(rel(&back, &t) < 1e-5, "{}", rel(&back, &t));
        assert!(c.figures.error < 1e-5);
        // Light factor of cluster 0: orthonormal columns.
        let a = c.ranks[0] as usize;
        for i in 0..a {
            for j in 0..a {
                let d: f32 = (0..bins)
                    .map(|l| c.factors[l * a + i] * c.factors[l * a + j])
                    .sum();
                assert!((d - if i == j { 1.0 } else { 0.0 }).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn a_low_rank_tensor_is_found_with_its_ranks_and_the_target_bounds_the_error() {
        // Per vertex: T[v][l][w] = sum_q p_q(v) f_q(l) g_q(w) with 2 terms: ranks (2, 2, 2).
        let (n, bins, width) = (12, 9, 6);
        let f = noise(2 * bins, 1);
        let g = noise(2 * width, 2);
        let p = noise(2 * n, 4);
        let mut t = Vec::new();
        for v in 0..n {
            for l in 0..bins {
                for w in 0..width {
                    t.push(
                        (0..2)
                            .map(|q| p[2 * v + q] * f[2 * l + q] * g[2 * w + q])
                            .sum(),
                    );
                }
            }
        }
        let clusters = vec![0; n];
        let c =
            compress_tensor(&t, bins, width, &clusters, 1, &settings(1e-4, [99, 99, 99])).unwrap();
        assert_eq!(c.ranks, [2, 2, 2]);
        assert!(rel(&expand(&c, &clusters, bins, width), &t) < 1e-4);
        // On noise, the error made equals the error reported and stays under the target.
        let t = noise(n * bins * width, 9);
        for target in [0.1f32, 0.3, 0.6] {
            let c = compress_tensor(
                &t,
                bins,
                width,
                &clusters,
                1,
                &settings(target, [99, 99, 99]),
            )
            .unwrap();
            let made = rel(&expand(&c, &clusters, bins, width), &t);
            assert!(made <= f64::from(target) + 1e-4, "target {target}: {made}");
            assert!(
                (made - f64::from(c.figures.error)).abs() < 1e-3,
                "{made} vs {}",
                c.figures.error
            );
        }
        // Caps bind: the error grows past the target and is reported as it is.
        let c = compress_tensor(&t, bins, width, &clusters, 1, &settings(0.01, [1, 1, 1])).unwrap();
        assert_eq!(c.ranks, [1, 1, 1]);
        let made = rel(&expand(&c, &clusters, bins, width), &t);
        assert!(made > 0.5 && (made - f64::from(c.figures.error)).abs() < 1e-3);
    }
}
