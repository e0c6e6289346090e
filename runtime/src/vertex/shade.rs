//! The view stage (docs/vertex.md, section 3): per pixel, the last reflection towards the eye.
//!
//! The rasterizer gives each pixel its triangle and perspective-correct barycentrics
//! (`crate::raster`). A pixel that sees no triangle shows the environment in its direction
//! (bilinear lat-long lookup, turned by the current rotation). Otherwise, with the weights
//! `w_v` of the triangle's three vertices:
//!
//! - `n = normalize(sum w_v n_v)`, `p = sum w_v p_v`, `wo = normalize(eye - p)`, the frame
//!   `(t, b) = vertex_frame(n)` and `wo` in it; the vertex records `E`, `U`, `I1`, `I2` and
//!   the texture coordinate are interpolated with the same weights;
//! - **a normal map** (the material's, `prt_formats::normal_map`) bends `n` per pixel to
//!   `n'`; the lobe below is then evaluated about `n'` (`wo`'s frame, the mirror direction)
//!   while I1's SH is read in the frame of `n`, where the records are, and `E` is scaled per
//!   channel by the open sky's irradiance at `n'` over that at `n`. Without one, `n' = n`;
//! - **the side without data**: the baker stores light arriving on the side the vertex normal
//!   points to. When `wo` is at or below the interpolated normal's horizon (the back of a
//!   surface, or a silhouette where the interpolated normal turns away), the pixel is black;
//! - `B = Kd tex / pi E + Ks [ sum_bc M[b][c] U^o(wo, b) U[c] + sum_w R_w(p, wo) S_w ]` for a
//!   material with a shading basis (`M` the core contracted with `U^h(p)`, `R_w` the split's
//!   reflectances), `Kd tex / pi E` otherwise; per colour channel;
//! - `S_w = V(c_w) Ibar_w(c_w) + sum_s g_w[band(s)] I1[s] Y_s(r_local) + I2` about the mirror
//!   direction `r`: `Ibar_w` the environment seen through the normalized Gaussian of width w
//!   (width 0 too: a cell's Gaussian, `ShadingBasis::rendered_width_deg`), read at the
//!   Gaussian's cosine-weighted centroid `c_w` (`cosine_centroid`: `r` raised towards the
//!   normal; at `r` a grazing view was too dark), `V(c_w)` the vertices' visible fraction there
//!   (the 6x16x16 cube bilinear between texel centres and across face edges, interpolated over
//!   the vertices), `g_w` the normalized Gaussian's per-band SH factors, read at `r`;
//! - **compact lights** (`compact_lights.rs`; `U` and `Ibar_w` are of the map less them):
//!   `Ks sum_k f(wo, l_k) (n' . l_k) V(l_k) P_k` with the family's true lobe `f`
//!   (`prt_formats::lobe`), `P_k` the light's power and `V` the visible fraction as above.
//!
//! This is `ShadingBasis::reflected` for the three channels at once (the parameter and `wo`
//! rows are evaluated once per pixel instead of once per channel; a unit test checks the two
//! agree).

use std::ops::Range;

use prt_formats::basis::{
    cosine_centroid, mirror, HemiWeights, ShadingBasis, MAX_SHADING_RANK, MAX_SPLIT_WIDTHS,
};
use prt_formats::envmap::LatLongMap;
use prt_formats::latlong;
use prt_formats::lighting::cubemap::{bilinear_taps, direction_to_face_st};
use prt_formats::lighting::sh::{sh_band, sh_eval_f32, SH_BANDS, SH_COUNT};
use prt_formats::lighting::Face;
use prt_formats::lobe::specular_lobe;
use prt_formats::normal_map::{perturb, triangle_uv_axes};
use prt_formats::pixel::MaterialParams;
use prt_formats::texture::sample_bilinear;
use prt_formats::vertex::{to_local, vertex_frame, VertexBakeMeta, VISIBILITY_CUBE};
use prt_formats::BakeFile;
use rayon::prelude::*;

use super::incident::{GroupShade, E_AT, I1_AT, I2_AT, U_AT};
use super::light::LightCoefficients;
use super::open::Scene;
use super::raster::{Fragment, VisibilityBuffer};
use super::true_lobe::TrueLobeSwitch;
use super::view::ViewRays;
use crate::error::RuntimeError;

/// The longest vertex record (`U_AT + 3 MAX_SHADING_RANK`).
const MAX_RECORD: usize = U_AT + 3 * MAX_SHADING_RANK;

/// One split width of a shading basis, as the view stage reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Width {
    /// The width in degrees (as the basis stores it).
    pub degrees: f32,
    /// Its `Ibar_w`: `LightCoefficients::prefiltered[cube]` (every width, 0 too, is a
    /// prefiltered cube: `ShadingBasis::rendered_width_deg`).
    pub cube: usize,
    /// `g_w[l]`: the normalized Gaussian's SH factor of band l.
    pub sh_factors: [f32; SH_BANDS],
    /// The rendered Gaussian's spread in radians (`ShadingBasis::rendered_width_deg`), which
    /// sets where its light is read (`cosine_centroid`).
    pub sigma: f32,
}

/// A material's lobe at its current parameter.
#[derive(Clone, Debug)]
pub(super) struct Lobe {
    /// Index of the shading basis.
    pub basis: usize,
    /// The core contracted with `U^h(param)`, `r_o x r_i`.
    pub core: Vec<f32>,
    /// The lobe parameter.
    pub param: f32,
}

/// The parameter samples a lobe's split reflectances are blended from, with their weights
/// (`ShadingBasis::reflectances_into`'s, skipping a zero weight): they depend on the material
/// only, so they are found once per frame instead of once per pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ParamTaps {
    taps: [(usize, f32); 2],
    len: usize,
}

impl ParamTaps {
    pub(super) fn new(basis: &ShadingBasis, param: f32) -> ParamTaps {
        let (pw, _) = basis.param_weights(param);
        let mut out = ParamTaps {
            taps: [(0, 0.0); 2],
            len: 0,
        };
        for (j, s) in [(pw.j0, 1.0 - pw.t), (pw.j1, pw.t)] {
            if s > 0.0 {
                out.taps[out.len] = (j, s);
                out.len += 1;
            }
        }
        out
    }

    fn taps(&self) -> &[(usize, f32)] {
        &self.taps[..self.len]
    }

    /// The taps and how many are used (for the GPU surface).
    #[cfg(feature = "gpu-surface")]
    pub(super) fn parts(&self) -> ([(usize, f32); 2], usize) {
        (self.taps, self.len)
    }
}

/// One material as the view stage reads it, gathered once per frame.
#[derive(Clone, Copy, Debug)]
pub(super) struct MaterialView {
    /// Its group (None: no data, shown black).
    pub(super) group: Option<usize>,
    pub(super) kd: [f32; 3],
    pub(super) ks: [f32; 3],
    /// Index into `Scene::textures`.
    pub(super) texture: Option<usize>,
    /// Index into `Scene::textures` of its normal map.
    pub(super) normal_map: Option<usize>,
    /// Its lobe's split reflectance taps (None: diffuse only).
    pub(super) taps: Option<ParamTaps>,
}

/// What the view stage keeps between frames so that a frame allocates nothing: the per-frame
/// material table and where each group's visibility tensor lies in the file.
#[derive(Default)]
pub(super) struct ViewCache {
    materials: Vec<MaterialView>,
    /// Per group, the byte range of its visibility tensor in `BakeFile::file_bytes`.
    visibility: Vec<Range<usize>>,
}

impl ViewCache {
    /// Material `m` as gathered for the current frame (for the GPU surface).
    #[cfg(feature = "gpu-surface")]
    pub(super) fn material(&self, m: usize) -> Option<&MaterialView> {
        self.materials.get(m)
    }

    /// Where group `g`'s visibility tensor lies in the file's bytes (for the GPU surface).
    #[cfg(feature = "gpu-surface")]
    pub(super) fn visibility_range(&self, g: usize) -> Option<Range<usize>> {
        self.visibility.get(g).cloned()
    }

    /// Finds the groups' visibility tensors (once per file) and gathers the materials (their
    /// textures from `meta`).
    pub(super) fn prepare(
        &mut self,
        file: &BakeFile,
        scene: &Scene,
        meta: &VertexBakeMeta,
        params: &[MaterialParams],
        lobes: &[Option<Lobe>],
    ) -> Result<(), RuntimeError> {
        let groups = meta.groups.len();
        if self.visibility.len() != groups {
            self.visibility.clear();
            for g in 0..groups {
                let t = file.tensor(&prt_formats::vertex::names::visibility(g))?;
                let bytes = t.as_u8()?;
                let at = t.file_offset();
                debug_assert_eq!(
                    file.file_bytes().get(at..at + bytes.len()),
                    Some(bytes),
                    "file_offset locates the tensor"
                );
                self.visibility.push(at..at + bytes.len());
            }
        }
        self.materials.clear();
        self.materials
            .extend(params.iter().enumerate().map(|(m, p)| {
                MaterialView {
                    group: scene.material_group[m].map(|g| g as usize),
                    kd: p.kd,
                    ks: p.ks,
                    texture: meta.material_textures[m].map(|t| t as usize),
                    normal_map: meta
                        .material_normal_maps
                        .get(m)
                        .copied()
                        .flatten()
                        .map(|t| t as usize),
                    taps: lobes[m]
                        .as_ref()
                        .map(|l| ParamTaps::new(&scene.shading[l.basis], l.param)),
                }
            }));
        Ok(())
    }
}

/// The environment as the view stage looks it up.
pub(super) struct Environment<'a> {
    pub map: &'a LatLongMap,
    /// `R_y(-rotation)`: radiance from `d` is the map's from `back d`.
    pub back: [[f64; 3]; 3],
    /// Whether the rotation is not 0: the prefiltered cubes are the unturned map's, so they
    /// are read at `back d` (`light_coefficients` in `mod.rs` says why).
    pub turned: bool,
}

impl Environment<'_> {
    /// A pixel that sees the environment: the map averaged over `k x k` film positions at the
    /// centres of a regular grid over pixel `(px, py)` (`k` from `view::background_samples`;
    /// 1: its centre), summed in that order.
    #[inline(always)]
    pub(super) fn pixel_average(&self, rays: &ViewRays, px: u32, py: u32, k: u32) -> [f32; 3] {
        if k <= 1 {
            return self.radiance(rays.pixel_direction(px, py));
        }
        let step = 1.0 / f64::from(k);
        let mut sum = [0.0f32; 3];
        for j in 0..k {
            for i in 0..k {
                let x = f64::from(px) + (f64::from(i) + 0.5) * step;
                let y = f64::from(py) + (f64::from(j) + 0.5) * step;
                let r = self.radiance(rays.direction(x, y).map(|c| c as f32));
                for c in 0..3 {
                    sum[c] += r[c];
                }
            }
        }
        let n = (k * k) as f32;
        sum.map(|v| v / n)
    }

    /// The radiance arriving from (unit) direction `d`.
    #[inline(always)]
    pub(super) fn radiance(&self, d: [f32; 3]) -> [f32; 3] {
        let d = d.map(f64::from);
        let m = &self.back;
        let r: [f32; 3] =
            std::array::from_fn(|i| (m[i][0] * d[0] + m[i][1] * d[1] + m[i][2] * d[2]) as f32);
        latlong::lookup_bilinear(&self.map.texels, self.map.width, self.map.height, r)
    }

    /// Where the prefiltered cubes are read for the world direction `d` that falls at
    /// `(face, s, t)`: there when the map is not turned, else at `back d`.
    #[inline(always)]
    pub(super) fn prefiltered_at(&self, d: [f32; 3], at: (Face, f64, f64)) -> (Face, f64, f64) {
        if !self.turned {
            return at;
        }
        let d = d.map(f64::from);
        let m = &self.back;
        direction_to_face_st(std::array::from_fn(|i| {
            m[i][0] * d[0] + m[i][1] * d[1] + m[i][2] * d[2]
        }))
    }
}

/// Everything the view stage reads.
pub(super) struct ViewInputs<'a> {
    pub scene: &'a Scene,
    pub shades: &'a [GroupShade],
    /// The bake file's bytes, which hold the visibility tensors (`cache`).
    pub file_bytes: &'a [u8],
    pub cache: &'a ViewCache,
    /// Per material, its lobe (None: diffuse only).
    pub lobes: &'a [Option<Lobe>],
    /// Per shading basis, its widths.
    pub widths: &'a [Vec<Width>],
    pub light: &'a LightCoefficients,
    pub environment: Environment<'a>,
    pub eye: [f32; 3],
    /// Sub-samples per side of a background pixel (`view::background_samples`).
    pub background_samples: u32,
    /// The budget's switch to the true lobe at the last reflection (`true_lobe.rs`).
    pub true_lobe: Option<TrueLobeSwitch<'a>>,
    /// Per compact light of `light`, the visibility cubes' bilinear taps in its direction
    /// (`compact_lights::light_taps`: the same for every pixel, so found once per frame).
    pub light_taps: Vec<[(usize, f64); 4]>,
}

/// Shades every pixel of `vis` into `out` (RGB rows, top row first), rows in parallel; `simd`
/// allows the AVX2 rows (the same pixels either way).
pub(super) fn view_stage(
    inputs: &ViewInputs,
    rays: &ViewRays,
    vis: &VisibilityBuffer,
    simd: bool,
    out: &mut [f32],
) {
    let width = vis.width as usize;
    #[cfg(target_arch = "x86_64")]
    let avx2 = simd && std::arch::is_x86_feature_detected!("avx2");
    #[cfg(not(target_arch = "x86_64"))]
    let _ = simd;
    out.par_chunks_mut(3 * width)
        .zip(vis.fragments.par_chunks(width))
        .enumerate()
        .for_each(|(y, (row, frags))| {
            #[cfg(target_arch = "x86_64")]
            if avx2 {
                // SAFETY: the CPU supports AVX2 (checked above).
                unsafe { shade_row_avx2(inputs, rays, y as u32, frags, row) };
                return;
            }
            shade_row(inputs, rays, y as u32, frags, row);
        });
}

/// [`shade_row`] compiled for AVX2: the same operations in the same order (Rust never fuses
/// a multiply and an add), so the same pixels bit for bit; the compiler gets wider vectors for
/// the record interpolation and rounding instructions instead of calls for `floor`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn shade_row_avx2(
    inputs: &ViewInputs,
    rays: &ViewRays,
    y: u32,
    frags: &[Fragment],
    row: &mut [f32],
) {
    shade_row(inputs, rays, y, frags, row);
}

/// Shades row `y`: its fragments `frags` into `row` (RGB).
#[inline(always)]
fn shade_row(inputs: &ViewInputs, rays: &ViewRays, y: u32, frags: &[Fragment], row: &mut [f32]) {
    for (x, (px, f)) in row.chunks_exact_mut(3).zip(frags).enumerate() {
        let rgb = if f.is_empty() {
            inputs
                .environment
                .pixel_average(rays, x as u32, y, inputs.background_samples)
        } else {
            inputs.shade(f.triangle as usize, f.bary)
        };
        px.copy_from_slice(&rgb);
    }
}

fn normalize(v: [f32; 3]) -> [f32; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / len)
}

impl ViewInputs<'_> {
    /// The radiance towards the eye from the point of triangle `t` at barycentrics `bary`.
    #[inline(always)]
    pub(super) fn shade(&self, t: usize, bary: [f32; 2]) -> [f32; 3] {
        let s = self.scene;
        let tri = s.triangles[t];
        let m = s.triangle_material[t] as usize;
        let w = [1.0 - bary[0] - bary[1], bary[0], bary[1]];
        let mix3 = |a: [[f32; 3]; 3]| -> [f32; 3] {
            std::array::from_fn(|i| w[0] * a[0][i] + w[1] * a[1][i] + w[2] * a[2][i])
        };
        let n = normalize(mix3(tri.map(|v| s.normals[v as usize])));
        let p = mix3(tri.map(|v| s.positions[v as usize]));
        let wo = normalize(std::array::from_fn(|i| self.eye[i] - p[i]));
        let material = &self.cache.materials[m];
        let Some(g) = material.group else {
            return [0.0; 3];
        };
        let glossy = self.lobes[m].is_some() && material.taps.is_some();
        // The texture coordinates, read by the texture and the normal map (only where either
        // is present: most pixels have neither).
        let uvs = tri.map(|v| s.uvs[v as usize]);
        let uv = || {
            [
                w[0] * uvs[0][0] + w[1] * uvs[1][0] + w[2] * uvs[2][0],
                w[0] * uvs[0][1] + w[1] * uvs[1][1] + w[2] * uvs[2][1],
            ]
        };
        // The shading normal: `n`, or `n` bent by the material's normal map. The records stay
        // in the frame of `n` (the data's); the BRDF is evaluated in the frame of `ns`.
        let bent = material.normal_map.and_then(|i| {
            let tx = &s.textures[i];
            let p = tri.map(|v| s.positions[v as usize]);
            let axes = triangle_uv_axes(p, uvs)?;
            Some(perturb(
                n,
                axes,
                sample_bilinear(&tx.texels, tx.width, tx.height, uv()),
            ))
        });
        let ns = bent.unwrap_or(n);
        // Whether the triangle's data side (the side its vertex normals are on) faces the eye.
        let data_side_faces_eye = || {
            let [a, b, c] = tri.map(|v| s.positions[v as usize]);
            let e1: [f32; 3] = std::array::from_fn(|i| b[i] - a[i]);
            let e2: [f32; 3] = std::array::from_fn(|i| c[i] - a[i]);
            let mut ng = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            if ng[0] * n[0] + ng[1] * n[1] + ng[2] * n[2] < 0.0 {
                ng = ng.map(|v| -v);
            }
            let facing = ng[0] * wo[0] + ng[1] * wo[1] + ng[2] * wo[2];
            facing > 0.0
        };
        if bent.is_some() {
            // A bent normal may face the eye from the side without data: black there too.
            let d = n[0] * wo[0] + n[1] * wo[1] + n[2] * wo[2];
            if (d.is_nan() || d <= 0.0) && !data_side_faces_eye() {
                return [0.0; 3];
            }
        }
        // `to_local(.., ns, wo)[2]`, the same operations: a diffuse pixel whose normal faces the
        // eye needs no tangent frame, only the irradiance (most pixels of most scenes).
        let n_dot_wo = ns[0] * wo[0] + ns[1] * wo[1] + ns[2] * wo[2];
        let mut frame = None;
        if glossy || n_dot_wo.is_nan() || n_dot_wo <= 0.0 {
            let (tangent, bitangent) = vertex_frame(ns);
            let wo_l = to_local(tangent, bitangent, ns, wo);
            // NaN (a degenerate normal) also takes this branch.
            if wo_l[2].is_nan() || wo_l[2] <= 0.0 {
                // Seen from below the shading normal's horizon: the back of a surface, or a
                // silhouette where the interpolated normal turns away from the eye while the
                // triangle faces it. Black, as the reference tracer (and Mitsuba) make it:
                // shading such a pixel as seen from just above the horizon drew the glossy
                // knot's rim twice as bright as the reference's (docs/vertex.md, "Accuracy as
                // measured").
                return [0.0; 3];
            }
            frame = Some((tangent, bitangent, wo_l));
        }
        // Every vertex of the triangle is in its material's group (checked on open).
        let local = tri.map(|v| s.vertex_group[v as usize].1 as usize);
        let shade = &self.shades[g];
        let stride = shade.stride;
        let recs = local.map(|l| &shade.data[l * stride..(l + 1) * stride]);
        let lerp = |k: usize| w[0] * recs[0][k] + w[1] * recs[1][k] + w[2] * recs[2][k];
        let tex = match material.texture {
            Some(i) => {
                let tx = &s.textures[i];
                sample_bilinear(&tx.texels, tx.width, tx.height, uv())
            }
            None => [1.0; 3],
        };
        let inv_pi = std::f32::consts::FRAC_1_PI;
        let e_scale = match (bent, &self.light.open_sky) {
            (Some(nb), Some(table)) => bent_irradiance_scale(table, n, nb),
            _ => [1.0; 3],
        };
        let mut b: [f32; 3] = std::array::from_fn(|c| {
            material.kd[c] * tex[c] * inv_pi * (lerp(E_AT + c) * e_scale[c])
        });
        let (Some(lobe), Some(taps), Some((tangent, bitangent, wo_l))) =
            (&self.lobes[m], &material.taps, frame)
        else {
            // The irradiance's kept Haar terms and SH can ring below 0 too (see below).
            return b.map(|v| v.max(0.0));
        };
        // A lobe reads the whole record (a diffuse material only E, above).
        // Zipped slices, so the loop has no bounds checks and vectorizes.
        let mut rec = [0.0f32; MAX_RECORD];
        let [r0, r1, r2] = recs;
        for (((r, a), b), c) in rec[..stride].iter_mut().zip(r0).zip(r1).zip(r2) {
            *r = w[0] * a + w[1] * b + w[2] * c;
        }
        let basis = &s.shading[lobe.basis];
        let widths = &self.widths[lobe.basis];
        // Local directions (about `ns`) into the world, and into the frame of the data's
        // normal `n`, where I1's SH is (the same frame when no normal map bends `n`).
        let to_world = |l: [f32; 3]| -> [f32; 3] {
            std::array::from_fn(|i| tangent[i] * l[0] + bitangent[i] * l[1] + ns[i] * l[2])
        };
        let data_frame = bent.map(|_| vertex_frame(n));
        let to_sh_frame = |l: [f32; 3], world: [f32; 3]| match data_frame {
            None => l,
            Some((t, b)) => to_local(t, b, n, world),
        };
        // Visible fraction at `(face, s, t)`: the 16-cube bilinear between texel centres,
        // across face edges as the prefiltered cubes are (nearest texels drew a nearby
        // object's reflection as a staircase of texel-sized blocks), interpolated over the
        // vertices.
        let rows = &self.file_bytes[self.cache.visibility[g].clone()];
        let per_vertex = 6 * VISIBILITY_CUBE * VISIBILITY_CUBE;
        let visible_with = |vis_taps: &[(usize, f64); 4]| -> f32 {
            (0..3)
                .map(|k| {
                    let row = &rows[local[k] * per_vertex..][..per_vertex];
                    let v: f64 = vis_taps.iter().map(|&(t, tw)| tw * f64::from(row[t])).sum();
                    w[k] * (v / 255.0) as f32
                })
                .sum()
        };
        let visible_at = |face: Face, fs: f64, ft: f64| -> f32 {
            visible_with(&bilinear_taps(VISIBILITY_CUBE, face, fs, ft))
        };
        if let Some(switch) = &self.true_lobe {
            // The budget's switch: the true lobe against the same incident light as the basis
            // sees, per direction (`true_lobe.rs`).
            let incident = |wi_l: [f32; 3]| -> [f32; 3] {
                let wi_w = to_world(wi_l);
                let (face, fs, ft) = direction_to_face_st(wi_w.map(f64::from));
                let visible = visible_at(face, fs, ft);
                let env = self.environment.radiance(wi_w);
                let y = sh_eval_f32(to_sh_frame(wi_l, wi_w));
                std::array::from_fn(|c| {
                    let sh: f32 = (0..SH_COUNT).map(|k| rec[I1_AT + 3 * k + c] * y[k]).sum();
                    visible * env[c] + sh + rec[I2_AT + c]
                })
            };
            let seed = p
                .iter()
                .fold(t as u32, |h, x| h.rotate_left(7) ^ x.to_bits());
            let back = &self.environment.back;
            let to_map = |wi_l: [f32; 3]| -> [f32; 3] {
                let d = to_world(wi_l).map(f64::from);
                std::array::from_fn(|i| {
                    (back[i][0] * d[0] + back[i][1] * d[1] + back[i][2] * d[2]) as f32
                })
            };
            let from_map = |m: [f32; 3]| -> [f32; 3] {
                let m = m.map(f64::from);
                // `back` is a rotation: its transpose turns the map's frame into the world's.
                let d: [f32; 3] = std::array::from_fn(|i| {
                    (back[0][i] * m[0] + back[1][i] * m[1] + back[2][i] * m[2]) as f32
                });
                to_local(tangent, bitangent, ns, d)
            };
            let spec = switch.reflected(
                (basis.family, lobe.param),
                wo_l,
                seed,
                incident,
                to_map,
                from_map,
            );
            for c in 0..3 {
                b[c] += material.ks[c] * spec[c];
            }
            return b.map(|v| v.max(0.0));
        }
        // The mirror direction; I1's SH at it, summed per band.
        let r_l = mirror(wo_l);
        let y = sh_eval_f32(to_sh_frame(r_l, to_world(r_l)));
        let mut bands = [[0.0f32; 3]; SH_BANDS];
        for (sidx, ys) in y.iter().enumerate().take(SH_COUNT) {
            let band = &mut bands[sh_band(sidx)];
            for c in 0..3 {
                band[c] += rec[I1_AT + 3 * sidx + c] * ys;
            }
        }
        // U^o(wo) and the split reflectances share wo's grid weights.
        let dw = basis.dir_weights(wo_l);
        let rw = split_reflectances(basis, taps, &dw);
        let mut prefiltered = [[0.0f32; 3]; MAX_SPLIT_WIDTHS];
        for ((pw, wd), &r) in prefiltered.iter_mut().zip(widths).zip(&rw) {
            // A width this lobe does not reflect through (the fit leaves most at 0 for a
            // given parameter) needs no light: its term is 0 whatever is read.
            if r == 0.0 {
                continue;
            }
            // The environment and the visibility are read where the width's Gaussian, weighted
            // by the cosine, looks: r raised towards the normal (`cosine_centroid`).
            let c_w = to_world(cosine_centroid(r_l, wd.sigma));
            // (Written out, not `map`: in this loop the array method was left uninlined.)
            let (face, fs, ft) =
                direction_to_face_st([f64::from(c_w[0]), f64::from(c_w[1]), f64::from(c_w[2])]);
            let visible = visible_at(face, fs, ft);
            let (pface, ps, pt) = self.environment.prefiltered_at(c_w, (face, fs, ft));
            let ibar = self.light.prefiltered[wd.cube].lookup_bilinear_face_st(pface, ps, pt);
            for c in 0..3 {
                let sh: f32 = (0..SH_BANDS).map(|l| wd.sh_factors[l] * bands[l][c]).sum();
                pw[c] = visible * ibar[c] + sh + rec[I2_AT + c];
            }
        }
        let incident = &rec[U_AT..U_AT + 3 * basis.ranks.i];
        let mut spec = reflected_rgb_with(
            basis,
            &lobe.core,
            &dw,
            &rw,
            incident,
            &prefiltered[..widths.len()],
        );
        // The compact lights, which the records' `U` and the prefiltered cubes leave out
        // (`compact_lights.rs`): each through the true lobe, shadowed by the same visibility.
        for (light, taps) in self.light.compact_lights.iter().zip(&self.light_taps) {
            let wi_l = to_local(tangent, bitangent, ns, light.direction);
            if wi_l[2].is_nan() || wi_l[2] <= 0.0 {
                continue;
            }
            let f = specular_lobe(basis.family, lobe.param, wo_l, wi_l) * wi_l[2];
            if f.is_nan() || f <= 0.0 {
                continue;
            }
            let reflected = f * visible_with(taps);
            for (s, p) in spec.iter_mut().zip(light.power) {
                *s += reflected * p;
            }
        }
        for c in 0..3 {
            b[c] += material.ks[c] * spec[c];
        }
        // Radiance is never negative, but its approximations can be: the Tucker residual, the
        // order-4 SH of I1 and the kept Haar terms each ring a little next to sharp features
        // (on vitrine under the sky map, 11 of 27 648 values, down to -0.02). Clamp them.
        b.map(|v| v.max(0.0))
    }
}

/// What a normal map does to the irradiance per channel: the open sky's irradiance at the bent
/// normal `nb` over that at the interpolated one `n` (`table`, the light's
/// `LightCoefficients::open_sky`), times the share of the bent hemisphere above the surface's
/// plane. Exact for a pixel under a uniform open sky; elsewhere it assumes the light below the
/// plane in the bent hemisphere is the hemisphere's average, and, under occlusion, that the
/// occlusion is the same around both normals. A channel the sky leaves dark at `n` keeps its
/// irradiance.
#[inline(always)]
fn bent_irradiance_scale(
    table: &prt_formats::lighting::CubeMap,
    n: [f32; 3],
    nb: [f32; 3],
) -> [f32; 3] {
    let at = |d: [f32; 3]| {
        let (face, s, t) = direction_to_face_st(d.map(f64::from));
        table.lookup_bilinear_face_st(face, s, t)
    };
    let (open_n, open_nb) = (at(n), at(nb));
    // The surface hides the part of the bent normal's hemisphere below its own plane (the
    // reference takes no light from there): under a uniform sky the rest receives the fraction
    // (1 + cos) / 2 of the hemisphere's irradiance, cos the angle between the two normals.
    let cos = n[0] * nb[0] + n[1] * nb[1] + n[2] * nb[2];
    let horizon = 0.5 * (1.0 + cos);
    std::array::from_fn(|c| {
        if open_n[c] > 1e-12 {
            horizon * open_nb[c] / open_n[c]
        } else {
            1.0
        }
    })
}

/// `ShadingBasis::reflected` for three channels: `incident` is `U[c][ch]` (`r_i x 3`),
/// `prefiltered[w][ch]` the `S_w`; `wo` above the horizon.
#[cfg(test)]
fn reflected_rgb(
    basis: &ShadingBasis,
    lobe: &Lobe,
    wo: [f32; 3],
    incident: &[f32],
    prefiltered: &[[f32; 3]],
) -> [f32; 3] {
    let taps = ParamTaps::new(basis, lobe.param);
    let dw = basis.dir_weights(wo);
    let rw = split_reflectances(basis, &taps, &dw);
    reflected_rgb_with(basis, &lobe.core, &dw, &rw, incident, prefiltered)
}

/// The split's reflectances `R_w(p, wo)` (`ShadingBasis::reflectances_into`) with the lobe's
/// parameter taps and `wo`'s grid weights found by the caller.
#[inline(always)]
fn split_reflectances(
    basis: &ShadingBasis,
    taps: &ParamTaps,
    dw: &HemiWeights,
) -> [f32; MAX_SPLIT_WIDTHS] {
    let nw = basis.n_widths();
    let slab = basis.n_dirs() * nw;
    let mut rw = [0.0f32; MAX_SPLIT_WIDTHS];
    for &(j, s) in taps.taps() {
        let table = &basis.reflectances[j * slab..][..slab];
        dw.add_rows(
            table,
            &basis.reflectances_pole[j * nw..][..nw],
            nw,
            s,
            &mut rw,
        );
    }
    rw
}

/// [`reflected_rgb`] with `wo`'s grid weights and the split reflectances (`rw`, from
/// [`split_reflectances`]) found by the caller.
#[inline(always)]
fn reflected_rgb_with(
    basis: &ShadingBasis,
    core: &[f32],
    dw: &HemiWeights,
    rw: &[f32; MAX_SPLIT_WIDTHS],
    incident: &[f32],
    prefiltered: &[[f32; 3]],
) -> [f32; 3] {
    let (ro, ri) = (basis.ranks.o, basis.ranks.i);
    let mut uo = [0.0f32; MAX_SHADING_RANK];
    dw.interpolate(&basis.u_o, &basis.u_o_pole, ro, &mut uo);
    let nw = basis.n_widths();
    let mut out = [0.0f32; 3];
    for (bo, &u) in uo[..ro].iter().enumerate() {
        let row = &core[bo * ri..(bo + 1) * ri];
        let mut s = [0.0f32; 3];
        for (d, x) in row.iter().zip(incident.chunks_exact(3)) {
            for c in 0..3 {
                s[c] += d * x[c];
            }
        }
        for c in 0..3 {
            out[c] += u * s[c];
        }
    }
    for (r, p) in rw[..nw].iter().zip(prefiltered) {
        for c in 0..3 {
            out[c] += r * p[c];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use prt_formats::basis::{HemiGrid, ParamWarp, TuckerRanks, SHADING_SCHEMA_VERSION};
    use prt_formats::Family;

    fn values(n: usize, seed: f32) -> Vec<f32> {
        (0..n)
            .map(|k| ((k as f32 * 0.731 + seed).sin() * 1.3).abs())
            .collect()
    }

    #[test]
    fn three_channels_at_once_equal_reflected_per_channel() {
        let dirs = HemiGrid {
            n_theta: 4,
            n_phi: 8,
        };
        let nd = dirs.len();
        let ranks = TuckerRanks { h: 2, o: 3, i: 4 };
        let np = 3;
        let b = ShadingBasis {
            version: SHADING_SCHEMA_VERSION,
            family: Family::Ggx,
            method: "test".into(),
            param_range: [0.1, 0.9],
            param_warp: ParamWarp::Linear,
            param_samples: vec![0.1, 0.4, 0.9],
            dirs,
            ranks,
            u_h: values(np * 2, 0.1),
            u_o: values(nd * 3, 0.2),
            u_o_pole: values(3, 0.3),
            u_i: values(nd * 4, 0.4),
            u_i_pole: values(4, 0.5),
            core: values(2 * 3 * 4, 0.6),
            split_widths_deg: vec![0.0, 7.0, 14.0],
            reflectances: values(np * nd * 3, 0.7),
            reflectances_pole: values(np * 3, 0.8),
        };
        b.validate().expect("valid");
        let param = 0.55;
        let mut uh = [0.0f32; MAX_SHADING_RANK];
        b.u_h_row(param, &mut uh);
        let mut core = vec![0.0f32; 12];
        b.contract_core(&uh, &mut core);
        let lobe = Lobe {
            basis: 0,
            core,
            param,
        };
        let incident: Vec<f32> = values(12, 1.9);
        let pre = [[0.5, 1.5, 2.5], [0.1, 0.2, 0.3], [3.0, 2.0, 1.0]];
        for wo in [[0.3f32, -0.2, 0.93], [0.0, 0.0, 1.0], [-0.7, 0.1, 0.2]] {
            let wo = normalize(wo);
            let rgb = reflected_rgb(&b, &lobe, wo, &incident, &pre);
            for c in 0..3 {
                let inc: Vec<f32> = (0..4).map(|k| incident[3 * k + c]).collect();
                let p: Vec<f32> = pre.iter().map(|x| x[c]).collect();
                let (want, _) = b.reflected(param, wo, &inc, &p);
                assert!(
                    (rgb[c] - want).abs() <= 1e-5 * want.abs().max(1.0),
                    "{wo:?} channel {c}: {} vs {want}",
                    rgb[c]
                );
            }
        }
    }
}
