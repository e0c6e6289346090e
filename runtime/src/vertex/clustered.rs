//! The light and material stages of a group whose T1 and T2 are stored compressed
//! (`prt_formats::clustered`; docs/vertex.md "Compression").
//!
//! With `T[v][l][w] = scale sum_(a,r,b) u[v][b] core_c[b][a][r] light_c[l][a] element_c[w][r]`
//! the light contraction `sum_l C[l][ch] T[v][l][w]` never needs the dense tensor: per cluster,
//! `P[a] = sum_l C[l] light_c[l][a]`, `Q[b][r] = sum_a P[a] core_c[b][a][r]` and
//! `S[b][e] = scale sum_r Q[b][r] element_c[e][r]` (the **light stage**, per cluster, not per
//! vertex); the material stage contracts `S` with the slot coefficients per cluster
//! (`M[b][s] = sum_j c_j S[b][j, s]`) and only then goes to the vertices,
//! `I1[v][s] = sum_b u[v][b] M[b][s]`: B multiply-adds per vertex and output instead of
//! `384 J` (T1) or `24 J I` (T2).
//!
//! Every cluster and every vertex is computed on its own in a fixed order of operations, so the
//! results do not depend on the number of threads.

use prt_formats::clustered::TuckerLayout;
use prt_formats::lighting::sh::SH_COUNT;
use prt_formats::vertex::names;
use prt_formats::{BakeFile, Dtype};
use rayon::prelude::*;

use crate::error::RuntimeError;

/// A compressed group's tensors, validated and converted to f32 at opening (they are small:
/// converting them at every light change cost more than the contraction).
#[derive(Clone, Debug)]
pub(super) struct CompressedLayout {
    /// The cluster of each vertex of the group.
    pub clusters: Vec<u32>,
    /// T1.
    pub t1: CompressedTensor,
    /// T2 (reflections = 3).
    pub t2: Option<CompressedTensor>,
}

/// One compressed tensor: its layout and values.
#[derive(Clone, Debug)]
pub(super) struct CompressedTensor {
    pub layout: TuckerLayout,
    /// Per cluster, its first row in the per-cluster results (the vertex ranks before it),
    /// and the total: results are stored ragged, `b_c` rows per cluster, so their size is
    /// bounded by the vertices (`b_c` never exceeds the cluster's size, checked at opening).
    pub rows_at: Vec<usize>,
    pub rows: usize,
    /// Per cluster `light_c` (`L x a`) as stored, then `element_c` **transposed** to
    /// `r x W` (at opening), the layout the light stage reads.
    pub factors: Vec<f32>,
    pub core: Vec<f32>,
    /// `[V][B]`.
    pub vertex: Vec<f32>,
}

/// One compressed tensor contracted with a light: per cluster `S[b][e][ch]`, and the vertex
/// factor's rows.
#[derive(Clone, Debug, Default)]
pub(super) struct ClusterLight {
    /// Rows: the sum of the clusters' vertex ranks.
    pub rows: usize,
    /// Elements per channel E (`J x 16` for T1, `J x I` for T2).
    pub elements: usize,
    /// `[rows][E][3]`: cluster c's `S[b][e][ch]` from row `rows_at[c]`, `b_c` rows.
    pub per_cluster: Vec<f32>,
}

/// The light stage of compressed tensor `tensor` ("t1" or "t2") of group `g`: `c` holds one
/// RGB triple per light bin, `channels` is the tensor's (1 or 3), `elements` its elements per
/// channel.
pub(super) fn contract_light(
    t: &CompressedTensor,
    elements: usize,
    channels: usize,
    c: &[[f32; 3]],
    scale: f32,
) -> ClusterLight {
    let (layout, factors, core) = (&t.layout, &t.factors, &t.core);
    let bins = c.len();
    let row = elements * 3;
    let mut per_cluster = vec![0.0f32; t.rows * row];
    // One mutable slice per cluster (`b_c` rows each), computed in parallel.
    let mut slices = Vec::with_capacity(layout.clusters());
    let mut rest = per_cluster.as_mut_slice();
    for r in &layout.ranks {
        let (head, tail) = rest.split_at_mut(r[2] * row);
        slices.push(head);
        rest = tail;
    }
    if row > 0 {
        slices.into_par_iter().enumerate().for_each(|(k, out)| {
            let [a, r, b] = layout.ranks[k];
            let light = &factors[layout.factor_at[k]..][..bins * a];
            let element_t = &factors[layout.factor_at[k] + bins * a..][..elements * channels * r];
            let core = &core[layout.core_at[k]..][..b * a * r];
            let dims = ClusterDims {
                a,
                r,
                b,
                elements,
                channels,
            };
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above).
                unsafe { cluster_light_avx2(dims, c, light, core, element_t, scale, out) };
                return;
            }
            cluster_light(dims, c, light, core, element_t, scale, out)
        });
    }
    ClusterLight {
        rows: t.rows,
        elements,
        per_cluster,
    }
}

/// The ranks of one cluster and the shape of its tensor's elements.
#[derive(Clone, Copy)]
struct ClusterDims {
    a: usize,
    r: usize,
    b: usize,
    elements: usize,
    channels: usize,
}

/// [`cluster_light`] compiled for AVX2: the same operations in the same order, so the same
/// bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn cluster_light_avx2(
    d: ClusterDims,
    c: &[[f32; 3]],
    light: &[f32],
    core: &[f32],
    element_t: &[f32],
    scale: f32,
    out: &mut [f32],
) {
    cluster_light(d, c, light, core, element_t, scale, out)
}

/// One cluster's light contraction (see [`contract_light`]): `light` is `L x a`, `core`
/// `b x a x r`, `element_t` the element factor transposed, `r x (elements x channels)`; `out`
/// gets `S[b][e][ch]`. Channel-major intermediates make every inner loop an `y += s x` over
/// contiguous rows, which vectorizes; each output still adds its terms in the order of the
/// plain dot products (light bins, then `a`, then `r`, ascending), so the bits do not depend
/// on the instruction set.
#[inline(always)]
fn cluster_light(
    d: ClusterDims,
    c: &[[f32; 3]],
    light: &[f32],
    core: &[f32],
    element_t: &[f32],
    scale: f32,
    out: &mut [f32],
) {
    let ClusterDims {
        a,
        r,
        b,
        elements,
        channels,
    } = d;
    let axpy = |y: &mut [f32], s: f32, x: &[f32]| {
        for (y, &x) in y.iter_mut().zip(x) {
            *y += s * x;
        }
    };
    // P[ch][a] = sum_l C[l][ch] light[l][a].
    let mut p = vec![0.0f32; 3 * a];
    for (cl, row) in c.iter().zip(light.chunks_exact(a.max(1))) {
        for (ch, pc) in p.chunks_exact_mut(a.max(1)).enumerate() {
            axpy(pc, cl[ch], row);
        }
    }
    // Q[ch][b][r] = sum_a P[ch][a] core[b][a][r].
    let mut q = vec![0.0f32; 3 * b * r];
    for bb in 0..b {
        for aa in 0..a {
            let row = &core[(bb * a + aa) * r..][..r];
            for ch in 0..3 {
                axpy(&mut q[(ch * b + bb) * r..][..r], p[ch * a + aa], row);
            }
        }
    }
    // S[b][e][ch] = scale sum_r Q[ch][b][r] element[w][r], w = e (gray) or 3e + ch (RGB).
    let width = elements * channels;
    let mut acc = vec![0.0f32; 3 * width];
    for (bb, sb) in out.chunks_exact_mut(elements * 3).enumerate().take(b) {
        acc.iter_mut().for_each(|x| *x = 0.0);
        for (rr, et) in element_t.chunks_exact(width.max(1)).enumerate().take(r) {
            for (ch, ac) in acc.chunks_exact_mut(width.max(1)).enumerate() {
                axpy(ac, q[(ch * b + bb) * r + rr], et);
            }
        }
        for (e, se) in sb.chunks_exact_mut(3).enumerate() {
            for (ch, s) in se.iter_mut().enumerate() {
                let w = if channels == 1 { e } else { e * 3 + ch };
                *s = scale * acc[ch * width + w];
            }
        }
    }
}

/// Transposes each cluster's element factor (`W x r` as stored) to `r x W` in place, the
/// layout [`cluster_light`] reads.
fn transpose_element_factors(layout: &TuckerLayout, bins: usize, width: usize, f: &mut [f32]) {
    for (k, rk) in layout.ranks.iter().enumerate() {
        let r = rk[1];
        let at = layout.factor_at[k] + bins * rk[0];
        let block = &mut f[at..at + width * r];
        let stored = block.to_vec();
        for w in 0..width {
            for rr in 0..r {
                block[rr * width + w] = stored[w * r + rr];
            }
        }
    }
}

/// T1's material contraction per cluster: `M[k][b][s][ch] = sum_j c_j[ch] S[k][b][j, s][ch]`
/// (`cj` one RGB triple per active slot).
pub(super) fn one_bounce_per_cluster(light: &ClusterLight, cj: &[[f32; 3]]) -> Vec<f32> {
    let mut m = vec![0.0f32; light.rows * SH_COUNT * 3];
    m.par_chunks_mut(SH_COUNT * 3)
        .zip(light.per_cluster.par_chunks((light.elements * 3).max(1)))
        .for_each(|(mb, sb)| {
            for (sj, c) in sb.chunks_exact(SH_COUNT * 3).zip(cj) {
                for (acc, x) in mb.chunks_exact_mut(3).zip(sj.chunks_exact(3)) {
                    for ch in 0..3 {
                        acc[ch] += c[ch] * x[ch];
                    }
                }
            }
        });
    m
}

/// T2's material contraction per cluster: `M[k][b][ch] = sum_(j,i) c_j c_i S[k][b][j, i][ch]`.
pub(super) fn two_bounce_per_cluster(
    light: &ClusterLight,
    cj: &[[f32; 3]],
    ci: &[[f32; 3]],
) -> Vec<f32> {
    let n_i = ci.len();
    let mut m = vec![0.0f32; light.rows * 3];
    for (acc, sb) in m
        .chunks_exact_mut(3)
        .zip(light.per_cluster.chunks_exact((light.elements * 3).max(1)))
    {
        for (sj, a) in sb.chunks_exact((n_i * 3).max(1)).zip(cj) {
            for (x, b) in sj.chunks_exact(3).zip(ci) {
                for ch in 0..3 {
                    acc[ch] += a[ch] * b[ch] * x[ch];
                }
            }
        }
    }
    m
}

/// `sum_b u[v][b] M[cluster(v)][b][..]` for one vertex: `out` gets `width` values.
#[inline]
pub(super) fn expand_vertex(
    tensor: &CompressedTensor,
    per_cluster: &[f32],
    width: usize,
    cluster: usize,
    v: usize,
    out: &mut [f32],
) {
    let b = tensor.layout.ranks[cluster][2];
    let u = &tensor.vertex[v * tensor.layout.vertex_rank..][..b];
    let m = &per_cluster[tensor.rows_at[cluster] * width..][..b * width];
    out[..width].fill(0.0);
    for (&ub, mb) in u.iter().zip(m.chunks_exact(width)) {
        for (o, &x) in out.iter_mut().zip(mb) {
            *o += ub * x;
        }
    }
}

/// Checks a compressed group's tensors against the metadata (types, shapes, ranks, cluster
/// indices); returns its layout. `schema` makes the error.
#[allow(clippy::too_many_arguments)]
pub(super) fn validate_group(
    file: &BakeFile,
    g: usize,
    vertices: usize,
    clusters: u32,
    dtype: Dtype,
    t1: (usize, usize, u32),
    t2: Option<(usize, usize, u32)>,
    schema: &dyn Fn(String) -> RuntimeError,
) -> Result<CompressedLayout, RuntimeError> {
    let name = names::clusters(g);
    let t = file.tensor(&name)?;
    if t.dtype() != Dtype::U32 || t.shape() != [vertices] {
        return Err(schema(format!(
            "{name}: {} {:?}, expected u32 [{vertices}]",
            t.dtype(),
            t.shape()
        )));
    }
    let assign = t.as_u32()?.to_vec();
    if let Some(v) = assign.iter().position(|&c| c >= clusters) {
        return Err(schema(format!(
            "{name}: vertex {v} is in cluster {}, but there are {clusters}",
            assign[v]
        )));
    }
    let mut members = vec![0usize; clusters as usize];
    for &c in &assign {
        members[c as usize] += 1;
    }
    let tensor = |tensor: &str, (bins, width, rank): (usize, usize, u32)| {
        let ranks_name = names::tucker(g, tensor, names::TUCKER_RANKS);
        let t = file.tensor(&ranks_name)?;
        if t.dtype() != Dtype::U32 || t.shape() != [clusters as usize, 3] {
            return Err(schema(format!(
                "{ranks_name}: {} {:?}, expected u32 [{clusters}, 3]",
                t.dtype(),
                t.shape()
            )));
        }
        let layout = TuckerLayout::new(t.as_u32()?, bins, width)
            .map_err(|e| schema(format!("{ranks_name}: {e}")))?;
        let mut rows_at = Vec::with_capacity(layout.clusters());
        let mut rows = 0;
        for (c, r) in layout.ranks.iter().enumerate() {
            if r[2] > members[c] {
                return Err(schema(format!(
                    "{ranks_name}: cluster {c} has vertex rank {}, more than its {} vertices",
                    r[2], members[c]
                )));
            }
            rows_at.push(rows);
            rows += r[2];
        }
        if layout.vertex_rank != rank as usize {
            return Err(schema(format!(
                "{ranks_name}: largest vertex rank {}, but the metadata says {rank}",
                layout.vertex_rank
            )));
        }
        for (part, shape) in [
            (names::TUCKER_FACTORS, vec![layout.factors_len]),
            (names::TUCKER_CORE, vec![layout.core_len]),
            (names::TUCKER_VERTEX, vec![vertices, layout.vertex_rank]),
        ] {
            let n = names::tucker(g, tensor, part);
            let t = file.tensor(&n)?;
            if t.dtype() != dtype || t.shape() != shape.as_slice() {
                return Err(schema(format!(
                    "{n}: {} {:?}, expected {dtype} {shape:?} from the metadata and ranks",
                    t.dtype(),
                    t.shape()
                )));
            }
        }
        let read = |part| file.tensor(&names::tucker(g, tensor, part))?.to_f32_vec();
        let mut factors = read(names::TUCKER_FACTORS)?;
        transpose_element_factors(&layout, bins, width, &mut factors);
        Ok(CompressedTensor {
            rows_at,
            rows,
            factors,
            core: read(names::TUCKER_CORE)?,
            vertex: read(names::TUCKER_VERTEX)?,
            layout,
        })
    };
    let t1 = tensor(names::T1, t1)?;
    let t2 = match t2 {
        Some(s) => Some(tensor(names::T2, s)?),
        None => None,
    };
    Ok(CompressedLayout {
        clusters: assign,
        t1,
        t2,
    })
}
