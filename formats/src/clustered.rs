//! The clustered Tucker layout of a compressed per-vertex tensor (thesis 5.3.3.4-5;
//! docs/vertex.md "Compression", docs/format.md "Vertex schema"): what the baker writes and the
//! runtime reads when a group's T1 or T2 is stored compressed.
//!
//! A group's dense tensor `T[v][l][w]` (V vertices, `L` light bins, `W` elements per bin:
//! `J x 16 x channels` for T1, `J x I x channels` for T2, in the dense tensor's order) is
//! approximated per **cluster** of vertices c by a three-mode Tucker product
//!
//! ```text
//! T[v][l][w] ~ scale * sum_(a, r, b) vertex[v][b] core_c[b][a][r] light_c[l][a] element_c[w][r]
//! ```
//!
//! with orthonormal columns in `light_c` (`L x a_c`), `element_c` (`W x r_c`) and the cluster's
//! vertex factor (whose rows, one per vertex of the cluster, are stored in `vertex`, padded with
//! zeros to the group's largest vertex rank). `scale` is the group's `scale_t1` / `scale_t2`:
//! only the core carries magnitude, so the factors are stored unscaled (their entries lie in
//! [-1, 1]).
//!
//! Tensors (names in `vertex::names`): the cluster of each vertex (`[V]` u32, shared by T1 and
//! T2); per compressed tensor its per-cluster ranks `[K, 3]` u32 as `(a, r, b)`; the factors,
//! flat, cluster after cluster, each `light_c` (`L x a_c`, row-major) then `element_c`
//! (`W x r_c`); the cores, flat, cluster after cluster (`b_c x a_c x r_c`); and `vertex`
//! (`[V, B]`, B the largest `b_c`). [`TuckerLayout`] computes the offsets from the ranks.

use serde::{Deserialize, Serialize};

/// Settings the baker compressed with, kept in the metadata so a user can see what was chosen
/// (they do not change how the file is read).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompressionSettings {
    /// Relative L2 (Frobenius) error allowed per cluster and tensor.
    pub error_target: f32,
    /// Vertices per cluster aimed at (clusters = ceil(vertices / this)), or None (absent):
    /// chosen per group from `error_target`, the smallest stored size among a few candidates
    /// that meets it (the count chosen is [`GroupCompression::clusters`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cluster_vertices: Option<u32>,
    /// Largest light rank `a`.
    pub max_light_rank: u32,
    /// Largest element rank `r`.
    pub max_element_rank: u32,
    /// Largest vertex rank `b`.
    pub max_vertex_rank: u32,
}

/// How one group's T1 and T2 are stored compressed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroupCompression {
    /// Number of clusters K.
    pub clusters: u32,
    /// T1's factors.
    pub t1: TensorCompression,
    /// T2's factors (when the bake has T2).
    pub t2: Option<TensorCompression>,
}

/// Figures of one compressed tensor of a group.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TensorCompression {
    /// The largest vertex rank over the clusters: the width of the `vertex` tensor.
    pub vertex_rank: u32,
    /// Relative L2 (Frobenius) error of the approximation over the group, before storage
    /// rounding, against the dense tensor.
    pub error: f32,
    /// The dense tensor's estimated Monte Carlo noise relative to its norm (docs/vertex.md,
    /// "What the error target means"); absent in files from before the estimate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<f32>,
    /// The approximation's error beyond that noise, relative to the dense tensor's signal:
    /// what `error_target` bounds; absent in files from before the estimate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beyond_noise: Option<f32>,
}

/// Where each cluster's factors and core lie in the flat tensors.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TuckerLayout {
    /// Per cluster `(a, r, b)`.
    pub ranks: Vec<[usize; 3]>,
    /// Per cluster, the offset of `light_c` in the factors (`element_c` follows at
    /// `+ bins * a`).
    pub factor_at: Vec<usize>,
    /// Per cluster, the offset of `core_c` in the cores.
    pub core_at: Vec<usize>,
    /// Length of the factors tensor.
    pub factors_len: usize,
    /// Length of the cores tensor.
    pub core_len: usize,
    /// The largest vertex rank.
    pub vertex_rank: usize,
}

impl TuckerLayout {
    /// The layout of per-cluster `ranks` (`[K, 3]` flat, `(a, r, b)` each) for `bins` light
    /// bins and `width` elements. Refuses ranks above the dimensions they reduce (`a <= bins`,
    /// `r <= width`) and sizes that overflow, naming the cluster.
    pub fn new(ranks: &[u32], bins: usize, width: usize) -> Result<TuckerLayout, String> {
        if !ranks.len().is_multiple_of(3) {
            return Err(format!("{} rank values, not a multiple of 3", ranks.len()));
        }
        let k = ranks.len() / 3;
        let mut out = TuckerLayout {
            ranks: Vec::with_capacity(k),
            factor_at: Vec::with_capacity(k),
            core_at: Vec::with_capacity(k),
            factors_len: 0,
            core_len: 0,
            vertex_rank: 0,
        };
        let overflow = |c: usize| format!("cluster {c}: the factor sizes overflow");
        for (c, r) in ranks.chunks_exact(3).enumerate() {
            let (a, e, b) = (r[0] as usize, r[1] as usize, r[2] as usize);
            if a > bins || e > width {
                return Err(format!(
                    "cluster {c}: ranks (light {a}, element {e}) exceed the tensor's \
                     {bins} light bins or {width} elements"
                ));
            }
            let factors = bins
                .checked_mul(a)
                .and_then(|x| width.checked_mul(e).and_then(|y| x.checked_add(y)))
                .ok_or_else(|| overflow(c))?;
            let core = b
                .checked_mul(a)
                .and_then(|x| x.checked_mul(e))
                .ok_or_else(|| overflow(c))?;
            out.factor_at.push(out.factors_len);
            out.core_at.push(out.core_len);
            out.factors_len = out
                .factors_len
                .checked_add(factors)
                .ok_or_else(|| overflow(c))?;
            out.core_len = out.core_len.checked_add(core).ok_or_else(|| overflow(c))?;
            out.vertex_rank = out.vertex_rank.max(b);
            out.ranks.push([a, e, b]);
        }
        Ok(out)
    }

    /// Number of clusters.
    pub fn clusters(&self) -> usize {
        self.ranks.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cluster_vertices_reads_old_metadata_and_auto_is_absent() {
        let old = r#"{"error_target":0.1,"cluster_vertices":128,"max_light_rank":64,
            "max_element_rank":64,"max_vertex_rank":32}"#;
        let s: CompressionSettings = serde_json::from_str(old).unwrap();
        assert_eq!(s.cluster_vertices, Some(128));
        // An explicit count is written as before.
        let text = serde_json::to_string(&s).unwrap();
        assert!(text.contains("\"cluster_vertices\":128"), "{text}");
        let auto = CompressionSettings {
            cluster_vertices: None,
            ..s
        };
        let text = serde_json::to_string(&auto).unwrap();
        assert!(!text.contains("cluster_vertices"), "{text}");
        let back: CompressionSettings = serde_json::from_str(&text).unwrap();
        assert_eq!(back, auto);
    }

    #[test]
    fn offsets_follow_the_ranks_cluster_after_cluster() {
        let l = TuckerLayout::new(&[2, 3, 4, 1, 1, 5], 10, 7).unwrap();
        assert_eq!(l.factor_at, [0, 10 * 2 + 7 * 3]);
        assert_eq!(l.core_at, [0, 4 * 2 * 3]);
        assert_eq!(l.factors_len, 41 + 10 + 7);
        assert_eq!(l.core_len, 24 + 5);
        assert_eq!(l.vertex_rank, 5);
        assert_eq!(l.clusters(), 2);
    }

    #[test]
    fn ranks_beyond_the_dimensions_or_sizes_that_overflow_are_refused() {
        assert!(TuckerLayout::new(&[11, 1, 1], 10, 7)
            .unwrap_err()
            .contains("cluster 0"));
        assert!(TuckerLayout::new(&[1, 1, 1, 1, 8, 1], 10, 7)
            .unwrap_err()
            .contains("cluster 1"));
        assert!(TuckerLayout::new(&[1, 1], 10, 7).is_err());
        let big = u32::MAX;
        assert!(TuckerLayout::new(&[10, 7, big, 10, 7, big, 10, 7, big], 10, 7).is_ok());
        assert!(TuckerLayout::new(&[1, 1, big], usize::MAX, usize::MAX).is_err());
    }
}
