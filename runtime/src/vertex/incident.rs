//! The per-vertex stages that do not depend on the view (docs/vertex.md, sections 3 and 4):
//!
//! - the **light stage**, when the environment changes: per vertex, T0's sparse Haar rows
//!   dotted with C0 (`T0dot`), and T1 and T2 contracted with the coarse light cubes C1 and C2
//!   over their light bins (`L1[j][s]`, `L2[j][i]`), all RGB and scaled back by the group's
//!   scales; they do not change with materials or the view;
//! - the **material stage**, when materials change: the light-contracted tensors contracted
//!   with the slot coefficients into `I1[s]` (SH of the one-reflection light) and `I2`
//!   (uniform radiance of the two-reflection light), then the irradiance `E` and the incident
//!   projections `U[c]` onto the shading basis' `U^i` rows, with the hemisphere constants of
//!   `constants.rs`.
//!
//! Every vertex is computed on its own in a fixed order of operations, so the results do not
//! depend on the number of threads.

use half::f16;
use half::slice::HalfFloatSliceExt;
use prt_formats::lighting::sh::SH_COUNT;
use prt_formats::vertex::{cube_len, names, VertexBakeMeta, T1_LIGHT_CUBE, T2_LIGHT_CUBE};
use prt_formats::{BakeFile, Dtype};
use rayon::prelude::*;

use super::clustered::{
    contract_light, expand_vertex, one_bounce_per_cluster, two_bounce_per_cluster, ClusterLight,
};
use super::constants::ShadingConstants;
use super::light::LightCoefficients;
use super::open::Scene;
use crate::error::RuntimeError;

/// Offset of the irradiance `E` (RGB) in a vertex's record.
pub(super) const E_AT: usize = 0;
/// Offset of `I2` (RGB).
pub(super) const I2_AT: usize = 3;
/// Offset of `I1[s]` (16 x RGB).
pub(super) const I1_AT: usize = 6;
/// Offset of `U[c]` (r_i x RGB).
pub(super) const U_AT: usize = I1_AT + 3 * SH_COUNT;

/// Light bins converted from f16 at a time (keeps the converted block in L1).
const BINS_PER_BLOCK: usize = 16;

/// One group's light-stage results.
#[derive(Clone, Debug, Default)]
pub(super) struct GroupLight {
    /// `T0dot[v][k]`, RGB, `[V_g][rows]`.
    pub t0dot: Vec<[f32; 3]>,
    /// `L1[v][j][s][ch]`, `[V_g][J][16][3]`.
    pub l1: Vec<f32>,
    /// `L2[v][j][i][ch]`, `[V_g][J][I][3]` (empty when reflections < 3).
    pub l2: Vec<f32>,
    /// For a compressed group (then `l1` and `l2` are empty): T1 and T2 contracted per
    /// cluster (`clustered.rs`).
    pub clustered: Option<(ClusterLight, Option<ClusterLight>)>,
}

/// One group's material-stage results: per vertex a record `[E, I2, I1[16], U[rank]]`, RGB
/// each ([`E_AT`], [`I2_AT`], [`I1_AT`], [`U_AT`]; `rank` is `r_i` of the group's shading
/// basis, 0 without one).
#[derive(Clone, Debug, Default)]
pub(super) struct GroupShade {
    /// Floats per vertex: `U_AT + 3 rank`.
    pub stride: usize,
    /// `[V_g][stride]`.
    pub data: Vec<f32>,
}

/// The light arriving at one vertex for the current environment and materials, in the
/// vertex's frame (`prt_formats::vertex::vertex_frame`), RGB: what the material stage made
/// of it (a hook for the tests, which check it against sums of their own).
#[cfg(feature = "hooks")]
#[derive(Clone, Debug, PartialEq)]
pub struct VertexIncident {
    /// The group (material) the vertex belongs to.
    pub group: usize,
    /// `E`: the irradiance, `integral I (w . n)+ dw`.
    pub irradiance: [f32; 3],
    /// `I1[s]`: the SH coefficients (order 4) of the light after one reflection.
    pub one_bounce_sh: [[f32; 3]; 16],
    /// `I2`: the uniform radiance with the irradiance of the light after two reflections.
    pub two_bounce: [f32; 3],
    /// `U[c] = integral I U^i(w_local, c) (w . n)+ dw` for the rows of the material's shading
    /// basis (empty for a material without a lobe).
    pub incident: Vec<[f32; 3]>,
}

#[cfg(feature = "hooks")]
impl VertexIncident {
    /// The record of vertex `local` of group `group` in the material stage's `shades`, or
    /// `None` for a vertex in no group.
    pub(super) fn of(shades: &[GroupShade], group: u32, local: u32) -> Option<VertexIncident> {
        if group == super::open::NO_GROUP {
            return None;
        }
        let shade = &shades[group as usize];
        let rec = &shade.data[local as usize * shade.stride..][..shade.stride];
        let rgb = |at: usize| [rec[at], rec[at + 1], rec[at + 2]];
        Some(VertexIncident {
            group: group as usize,
            irradiance: rgb(E_AT),
            one_bounce_sh: std::array::from_fn(|s| rgb(I1_AT + 3 * s)),
            two_bounce: rgb(I2_AT),
            incident: (U_AT..shade.stride).step_by(3).map(rgb).collect(),
        })
    }
}

/// Stored values of a T0, T1 or T2 tensor.
#[derive(Clone, Copy)]
enum Values<'a> {
    F32(&'a [f32]),
    F16(&'a [f16]),
}

impl<'a> Values<'a> {
    fn read(file: &'a BakeFile, name: &str) -> Result<Values<'a>, RuntimeError> {
        let t = file.tensor(name)?;
        Ok(match t.dtype() {
            Dtype::F16 => Values::F16(t.as_f16()?),
            _ => Values::F32(t.as_f32()?),
        })
    }

    /// `n` values from `start` as f32: borrowed, or converted into `scratch`.
    #[inline]
    fn block<'s>(&'s self, start: usize, n: usize, scratch: &'s mut Vec<f32>) -> &'s [f32] {
        match self {
            Values::F32(v) => &v[start..start + n],
            Values::F16(v) => {
                scratch.resize(n, 0.0);
                v[start..start + n].convert_to_f32_slice(scratch);
                scratch
            }
        }
    }
}

/// `acc[c][k] += C[l][c] x_l[k]` (gray values, `acc` channel-major `3 x width`) or
/// `acc[k] += C[l][k % 3] x_l[k]` (RGB values interleaved, `acc` `width` long) for the bins
/// `l` of `x` (`bins x width` values, `c` one RGB triple per bin). With AVX2 when the CPU has
/// it: the same multiplies and adds in the same order (no fused multiply-add), so the result
/// is the same bit for bit.
#[inline]
fn contract_bins(x: &[f32], width: usize, gray: bool, c: &[[f32; 3]], acc: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { contract_bins_avx2(x, width, gray, c, acc) };
        return;
    }
    contract_bins_impl(x, width, gray, c, acc);
}

/// [`contract_bins`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn contract_bins_avx2(x: &[f32], width: usize, gray: bool, c: &[[f32; 3]], acc: &mut [f32]) {
    contract_bins_impl(x, width, gray, c, acc);
}

#[inline(always)]
fn contract_bins_impl(x: &[f32], width: usize, gray: bool, c: &[[f32; 3]], acc: &mut [f32]) {
    if gray {
        let (r, rest) = acc.split_at_mut(width);
        let (g, b) = rest.split_at_mut(width);
        for (xb, cl) in x.chunks_exact(width).zip(c) {
            let [c0, c1, c2] = *cl;
            for (((r, g), b), &v) in r.iter_mut().zip(g.iter_mut()).zip(b.iter_mut()).zip(xb) {
                *r += c0 * v;
                *g += c1 * v;
                *b += c2 * v;
            }
        }
    } else {
        // The light's colour repeated along the interleaved channels.
        let mut pattern = [0.0f32; 48];
        for (xb, cl) in x.chunks_exact(width).zip(c) {
            for (k, p) in pattern.iter_mut().enumerate() {
                *p = cl[k % 3];
            }
            for (a, xs) in acc.chunks_mut(48).zip(xb.chunks(48)) {
                for ((a, &v), &p) in a.iter_mut().zip(xs).zip(&pattern) {
                    *a += p * v;
                }
            }
        }
    }
}

/// One vertex's `out[e][ch] = scale sum_l C[l][ch] T[v][l][e][ch']` over `bins` light bins of
/// `elements` elements each (`out` is `elements x 3`, interleaved).
#[allow(clippy::too_many_arguments)]
fn contract_vertex(
    values: Values,
    v: usize,
    bins: usize,
    elements: usize,
    channels: usize,
    c: &[[f32; 3]],
    scale: f32,
    scratch: &mut (Vec<f32>, Vec<f32>),
    out: &mut [f32],
) {
    let width = elements * channels;
    let gray = channels == 1;
    let (acc, conv) = scratch;
    acc.clear();
    acc.resize(3 * elements, 0.0);
    let row = v * bins * width;
    #[cfg(target_arch = "x86_64")]
    if let Values::F16(h) = values {
        if gray
            && width & 7 == 0
            && std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("f16c")
        {
            // SAFETY: the CPU supports AVX2 and F16C (checked just above).
            unsafe { contract_gray_f16_avx2(&h[row..row + bins * width], width, c, acc) };
            write_out(acc, elements, gray, scale, out);
            return;
        }
    }
    let mut l0 = 0;
    while l0 < bins {
        let n = BINS_PER_BLOCK.min(bins - l0);
        let x = values.block(row + l0 * width, n * width, conv);
        contract_bins(x, width, gray, &c[l0..l0 + n], acc);
        l0 += n;
    }
    write_out(acc, elements, gray, scale, out);
}

/// The accumulators, scaled, as `[element][channel]`.
fn write_out(acc: &[f32], elements: usize, gray: bool, scale: f32, out: &mut [f32]) {
    if gray {
        for (k, o) in out.chunks_exact_mut(3).enumerate() {
            for (ch, oc) in o.iter_mut().enumerate() {
                *oc = scale * acc[ch * elements + k];
            }
        }
    } else {
        for (o, a) in out.iter_mut().zip(acc.iter()) {
            *o = scale * a;
        }
    }
}

/// [`contract_bins`] for gray f16 values whose width is a multiple of 8, in AVX2 registers,
/// converting 8 values at a time (F16C; exact, as `f16::to_f32`) and multiplying then adding
/// (no fused multiply-add), so the result is the same bit for bit as the portable path.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,f16c")]
unsafe fn contract_gray_f16_avx2(x: &[f16], width: usize, c: &[[f32; 3]], acc: &mut [f32]) {
    use std::arch::x86_64::{
        __m128i, _mm256_add_ps, _mm256_cvtph_ps, _mm256_loadu_ps, _mm256_mul_ps, _mm256_set1_ps,
        _mm256_storeu_ps, _mm_loadu_si128,
    };
    // The pointer arithmetic below stays inside these bounds.
    assert!(width & 7 == 0 && acc.len() >= 3 * width);
    let bins = c.len().min(x.len() / width.max(1));
    let (r, rest) = acc.split_at_mut(width);
    let (g, b) = rest.split_at_mut(width);
    // Bin after bin (the row is read in storage order, which the memory prefetchers follow),
    // 8 elements at a time; each accumulator gets its bins' terms in bin order.
    for (l, cl) in c[..bins].iter().enumerate() {
        // SAFETY: every slice read or written holds `width` values from the offsets used, a
        // multiple of 8 (checked above and by the caller); unaligned loads and stores; AVX2
        // and F16C are enabled for this function.
        unsafe {
            let (c0, c1, c2) = (
                _mm256_set1_ps(cl[0]),
                _mm256_set1_ps(cl[1]),
                _mm256_set1_ps(cl[2]),
            );
            let src = x.as_ptr().add(l * width);
            for k in (0..width).step_by(8) {
                let v = _mm256_cvtph_ps(_mm_loadu_si128(src.add(k) as *const __m128i));
                let (pr, pg, pb) = (
                    r.as_mut_ptr().add(k),
                    g.as_mut_ptr().add(k),
                    b.as_mut_ptr().add(k),
                );
                _mm256_storeu_ps(pr, _mm256_add_ps(_mm256_loadu_ps(pr), _mm256_mul_ps(c0, v)));
                _mm256_storeu_ps(pg, _mm256_add_ps(_mm256_loadu_ps(pg), _mm256_mul_ps(c1, v)));
                _mm256_storeu_ps(pb, _mm256_add_ps(_mm256_loadu_ps(pb), _mm256_mul_ps(c2, v)));
            }
        }
    }
}

/// The light stage of every group for the light `light` (see the module documentation).
pub(super) fn light_stage(
    file: &BakeFile,
    meta: &VertexBakeMeta,
    scene: &Scene,
    light: &LightCoefficients,
) -> Result<Vec<GroupLight>, RuntimeError> {
    let channels = meta.channels as usize;
    let c1 = light.one_bounce.texels();
    let c2 = light.two_bounce.texels();
    let n_i = meta.t2_slots.len();
    // C0 interleaved, one 16-byte entry per Haar coefficient: each sparse term gathers one
    // entry instead of three from separate arrays.
    let interleave = |c: &[Vec<f32>; 3]| -> Vec<[f32; 4]> {
        (0..c[0].len())
            .map(|i| [c[0][i], c[1][i], c[2][i], 0.0])
            .collect()
    };
    let haar = interleave(&light.haar);
    // The glossy rows `U` read the map less its compact lights when it has any (they are
    // shaded per pixel, `compact_lights.rs`); the irradiance row the whole map.
    let glossy_haar = light.glossy_haar.as_ref().map(interleave);
    let glossy_haar = glossy_haar.as_ref().unwrap_or(&haar);
    // The open sky's irradiance per normal, for vertices whose irradiance row is the
    // occluded part (`open` flags, schema 4): computed only when some vertex needs it.
    let open_sky = &light.open_sky;
    let mut out = Vec::with_capacity(meta.groups.len());
    for (g, (gm, layout)) in meta.groups.iter().zip(&scene.groups).enumerate() {
        let nv = layout.vertices.len();
        let rows = layout.rows;
        let j = layout.active;
        let terms = meta.group_t0_terms(gm);

        // T0: sparse Haar dots, per row.
        let index = file.tensor(&names::t0_index(g))?.as_u16()?;
        let value = Values::read(file, &names::t0_value(g))?;
        let mut t0dot = vec![[0.0f32; 3]; nv * rows];
        t0dot
            .par_chunks_mut(rows.max(1))
            .enumerate()
            .with_min_len(64)
            .for_each_init(Vec::new, |scratch, (v, o)| {
                let at = v * rows * terms;
                let values = value.block(at, rows * terms, scratch);
                let indices = &index[at..at + rows * terms];
                for (k, ok) in o.iter_mut().enumerate() {
                    let mut acc = [0.0f32; 3];
                    let row = k * terms..(k + 1) * terms;
                    let light = if k + 1 < rows { glossy_haar } else { &haar };
                    for (&x, &i) in values[row.clone()].iter().zip(&indices[row]) {
                        let c = light[i as usize];
                        acc[0] += x * c[0];
                        acc[1] += x * c[1];
                        acc[2] += x * c[2];
                    }
                    *ok = acc.map(|a| a * gm.scale_t0);
                }
                // E = the open sky's irradiance at the normal - the occluded part's dot.
                if let (Some(table), Some(true)) = (open_sky, layout.t0_open.get(v)) {
                    let n = scene.normals[layout.vertices[v] as usize].map(f64::from);
                    let open = table.lookup_bilinear(n);
                    if let Some(e) = o.last_mut() {
                        *e = std::array::from_fn(|c| open[c] - e[c]);
                    }
                }
            });

        // T1 and T2: dense contractions over the light bins.
        let contract = |name: String, bins: usize, elements: usize, c: &[[f32; 3]], scale| {
            let values = Values::read(file, &name)?;
            let mut o = vec![0.0f32; nv * elements * 3];
            if elements > 0 {
                o.par_chunks_mut(elements * 3).enumerate().for_each_init(
                    || (Vec::new(), Vec::new()),
                    |scratch, (v, ov)| {
                        contract_vertex(values, v, bins, elements, channels, c, scale, scratch, ov)
                    },
                );
            }
            Ok::<_, RuntimeError>(o)
        };
        if let Some(comp) = &layout.compressed {
            let t1 = contract_light(&comp.t1, j * SH_COUNT, channels, c1, gm.scale_t1);
            let t2 = comp
                .t2
                .as_ref()
                .map(|t| contract_light(t, j * n_i, channels, c2, gm.scale_t2));
            out.push(GroupLight {
                t0dot,
                l1: Vec::new(),
                l2: Vec::new(),
                clustered: Some((t1, t2)),
            });
            continue;
        }
        let l1 = contract(
            names::t1(g),
            cube_len(T1_LIGHT_CUBE),
            j * SH_COUNT,
            c1,
            gm.scale_t1,
        )?;
        let l2 = if meta.reflections >= 3 {
            contract(
                names::t2(g),
                cube_len(T2_LIGHT_CUBE),
                j * n_i,
                c2,
                gm.scale_t2,
            )?
        } else {
            Vec::new()
        };
        out.push(GroupLight {
            t0dot,
            l1,
            l2,
            clustered: None,
        });
    }
    Ok(out)
}

/// The material stage of every group for slot coefficients `coeff` (one RGB triple per
/// global slot). `constants[b]` belongs to shading basis b; `ehat` is `Ehat[s]`.
pub(super) fn material_stage(
    meta: &VertexBakeMeta,
    scene: &Scene,
    lights: &[GroupLight],
    constants: &[ShadingConstants],
    ehat: &[f32; SH_COUNT],
    coeff: &[[f32; 3]],
) -> Vec<GroupShade> {
    let slot = |j: u32| coeff.get(j as usize).copied().unwrap_or([0.0; 3]);
    let ci: Vec<[f32; 3]> = meta.t2_slots.iter().map(|&i| slot(i)).collect();
    let n_i = ci.len();
    let pi = std::f32::consts::PI;
    let mut out = Vec::with_capacity(meta.groups.len());
    for ((gm, layout), light) in meta.groups.iter().zip(&scene.groups).zip(lights) {
        let cj: Vec<[f32; 3]> = gm.active.iter().map(|&j| slot(j)).collect();
        let nj = cj.len();
        let consts = gm.shading.map(|b| &constants[b as usize]);
        let rank = consts.map_or(0, |c| c.rank);
        let stride = U_AT + 3 * rank;
        let rows = layout.rows;
        let nv = layout.vertices.len();
        let mut data = vec![0.0f32; nv * stride];
        // A compressed group: the slot contraction per cluster first (`clustered.rs`).
        let clustered = light.clustered.as_ref().map(|(t1, t2)| {
            (
                one_bounce_per_cluster(t1, &cj),
                t2.as_ref().map(|t2| two_bounce_per_cluster(t2, &cj, &ci)),
            )
        });
        data.par_chunks_mut(stride)
            .enumerate()
            .with_min_len(64)
            .for_each(|(v, rec)| {
                let mut i1 = [[0.0f32; 3]; SH_COUNT];
                let mut i2 = [0.0f32; 3];
                if let (Some((m1, m2)), Some(comp)) = (&clustered, &layout.compressed) {
                    // I1[s] = sum_b u[v][b] M1[b][s], I2 = sum_b u2[v][b] M2[b].
                    let k = comp.clusters[v] as usize;
                    let mut flat = [0.0f32; SH_COUNT * 3];
                    expand_vertex(&comp.t1, m1, SH_COUNT * 3, k, v, &mut flat);
                    for (acc, x) in i1.iter_mut().zip(flat.chunks_exact(3)) {
                        acc.copy_from_slice(x);
                    }
                    if let (Some(m2), Some(t2)) = (m2, &comp.t2) {
                        expand_vertex(t2, m2, 3, k, v, &mut i2);
                    }
                } else {
                    // I1[s] = sum_j c_j L1[j][s].
                    let l1 = &light.l1[v * nj * SH_COUNT * 3..][..nj * SH_COUNT * 3];
                    for (lj, c) in l1.chunks_exact(SH_COUNT * 3).zip(&cj) {
                        for (acc, x) in i1.iter_mut().zip(lj.chunks_exact(3)) {
                            acc[0] += c[0] * x[0];
                            acc[1] += c[1] * x[1];
                            acc[2] += c[2] * x[2];
                        }
                    }
                    // I2 = sum_(j,i) c_j c_i L2[j][i].
                    if !light.l2.is_empty() {
                        let l2 = &light.l2[v * nj * n_i * 3..][..nj * n_i * 3];
                        for (lj, a) in l2.chunks_exact((n_i * 3).max(1)).zip(&cj) {
                            for (x, b) in lj.chunks_exact(3).zip(&ci) {
                                for ch in 0..3 {
                                    i2[ch] += a[ch] * b[ch] * x[ch];
                                }
                            }
                        }
                    }
                }
                let t0 = &light.t0dot[v * rows..][..rows];
                // E = T0dot[last] + sum_s Ehat[s] I1[s] + pi I2.
                let mut e = t0[rows - 1];
                for (x, &h) in i1.iter().zip(ehat) {
                    for ch in 0..3 {
                        e[ch] += h * x[ch];
                    }
                }
                for ch in 0..3 {
                    e[ch] += pi * i2[ch];
                }
                rec[E_AT..E_AT + 3].copy_from_slice(&e);
                rec[I2_AT..I2_AT + 3].copy_from_slice(&i2);
                for (s, x) in i1.iter().enumerate() {
                    rec[I1_AT + 3 * s..I1_AT + 3 * s + 3].copy_from_slice(x);
                }
                // U[c] = T0dot[c] + sum_s Cwi[s][c] I1[s] + Cconst[c] I2.
                if let Some(k) = consts {
                    for c in 0..rank {
                        let mut u = t0[c];
                        for (s, x) in i1.iter().enumerate() {
                            let w = k.cwi[s * rank + c];
                            for ch in 0..3 {
                                u[ch] += w * x[ch];
                            }
                        }
                        for ch in 0..3 {
                            u[ch] += k.cconst[c] * i2[ch];
                        }
                        rec[U_AT + 3 * c..U_AT + 3 * c + 3].copy_from_slice(&u);
                    }
                }
            });
        out.push(GroupShade { stride, data });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gray_and_rgb_contractions_weigh_each_bin_by_its_light() {
        // Two bins, two elements.
        let c = [[1.0, 2.0, 3.0], [10.0, 20.0, 30.0]];
        let gray = [1.0f32, 2.0, 3.0, 4.0];
        let mut acc = vec![0.0; 6];
        contract_bins(&gray, 2, true, &c, &mut acc);
        // Channel-major: element 0: 1*c0 + 3*c1, element 1: 2*c0 + 4*c1.
        assert_eq!(acc, [31.0, 42.0, 62.0, 84.0, 93.0, 126.0]);
        let rgb = [
            1.0f32, 1.0, 1.0, 2.0, 2.0, 2.0, 0.5, 0.0, 0.0, 0.0, 0.0, 1.0,
        ];
        let mut acc = vec![0.0; 6];
        contract_bins(&rgb, 6, false, &c, &mut acc);
        assert_eq!(acc, [6.0, 2.0, 3.0, 2.0, 4.0, 36.0]);
    }

    #[test]
    fn the_f16_kernel_equals_the_portable_path_bit_for_bit() {
        let (bins, elements) = (384usize, 2 * 16);
        let h: Vec<f16> = (0..2 * bins * elements)
            .map(|i| f16::from_f32(((i * 7919) % 1013) as f32 * 1e-3 - 0.3))
            .collect();
        let f: Vec<f32> = h.iter().map(|x| x.to_f32()).collect();
        let c: Vec<[f32; 3]> = (0..bins)
            .map(|l| [l as f32 * 0.01, 1.0 / (l + 1) as f32, 0.3])
            .collect();
        for v in 0..2 {
            let mut a = vec![0.0f32; elements * 3];
            let mut b = a.clone();
            let mut scratch = (Vec::new(), Vec::new());
            contract_vertex(
                Values::F16(&h),
                v,
                bins,
                elements,
                1,
                &c,
                0.7,
                &mut scratch,
                &mut a,
            );
            let mut acc = vec![0.0f32; 3 * elements];
            contract_bins_impl(
                &f[v * bins * elements..][..bins * elements],
                elements,
                true,
                &c,
                &mut acc,
            );
            write_out(&acc, elements, true, 0.7, &mut b);
            let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&a), bits(&b), "vertex {v}");
        }
    }

    #[test]
    fn f16_blocks_convert_like_single_values() {
        let h: Vec<f16> = (0..40)
            .map(|i| f16::from_f32(i as f32 * 0.37 - 3.0))
            .collect();
        let v = Values::F16(&h);
        let mut scratch = Vec::new();
        let b = v.block(3, 30, &mut scratch).to_vec();
        for (k, x) in b.iter().enumerate() {
            assert_eq!(x.to_bits(), h[3 + k].to_f32().to_bits());
        }
    }
}
