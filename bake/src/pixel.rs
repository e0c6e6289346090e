//! The per-pixel baker (thesis ch. 4; DESIGN.md 2.1, 2.3, 2.5): traces the camera's paths once
//! and accumulates, per pixel and per visible material, the transfer tensors T0, T1, T2 over
//! the materials' slots (see `prt_formats::pixel` for the layout and its meaning).
//!
//! The paths are those of the shared [`Integrator`] under the [`BakeModel`]: fixed materials
//! are sampled by their true BRDF, editable ones by a density that does not depend on their
//! coefficients (a mixture of cosine and the family's lobes), so one trace serves every
//! coefficient setting, and the same model drives the projected-BRDF reference render.

use std::time::Instant;

use glam::Vec3;
use half::f16;
use prt_formats::basis::BrdfBasis;
use prt_formats::pixel::{
    row_len, slot_coefficients, BasisMeta, CameraMeta, GroupMeta, MaterialMeta, MaterialParams,
    PixelBakeMeta, SlotKind, PIXEL_SCHEMA_VERSION,
};
use rayon::prelude::*;

use crate::accel::Accel;
use crate::brdf::{
    cosine_hemisphere, reflect, sample_blinn_phong_half, sample_ggx_half, specular_lobe_pdf,
    BrdfSample, Family,
};
use crate::integrator::{Integrator, MaterialModel, PathSink, Slots, Surface, MAX_SLOTS};
use crate::lights::LightSet;
use crate::sampling::Rng;
use crate::scene::{Environment, Scene};

/// Storage type of the transfer tensors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Precision {
    F32,
    F16,
}

impl Precision {
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F16 => "f16",
        }
    }
}

#[derive(Clone, Debug)]
pub struct PixelBakeOptions {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub reflections: u32,
    pub seed: u64,
    pub precision: Precision,
    /// Refuse to bake when the estimated working memory exceeds this many bytes.
    pub max_memory: Option<u64>,
    /// Also store a rank-k PCA-over-pixels variant of every group.
    pub compress_rank: Option<usize>,
}

/// Which slots each material has, where they sit globally, and the bases they use.
#[derive(Clone, Debug)]
pub struct SlotLayout {
    pub materials: Vec<MaterialMeta>,
    pub bases: Vec<BrdfBasis>,
    /// Total number of global slots J.
    pub total_slots: usize,
    /// 1 when every tensor value is gray (colours live in coefficients), else 3.
    pub channels: usize,
    /// The lights' common colour, divided out of gray tensors (ONE for RGB tensors).
    pub tint: Vec3,
    /// Why each material got the slots it has (for the allocation report).
    pub reasons: Vec<String>,
}

/// The colour all non-black `colours` share up to a scale (normalised to a maximum component
/// of 1), or None when they differ. White when there is no light at all.
fn common_chromaticity(colours: &[Vec3]) -> Option<Vec3> {
    let mut common: Option<Vec3> = None;
    for &c in colours {
        let m = c.max_element();
        if m.is_nan() || m <= 0.0 {
            continue;
        }
        let k = c / m;
        match common {
            None => common = Some(k),
            Some(x) if (x - k).abs().max_element() <= 1e-5 => {}
            Some(_) => return None,
        }
    }
    Some(common.unwrap_or(Vec3::ONE))
}

impl SlotLayout {
    /// Slots per material: editable glossy materials get their family's basis (which must be
    /// in `bases`), editable diffuse ones a single Kd slot, fixed ones a Kd slot and/or a lobe
    /// slot (none for a black material). A material with a diffuse texture keeps Kd as its own
    /// slot (the texture is baked into it); otherwise Kd folds into basis 0.
    pub fn new(scene: &Scene, bases: &[BrdfBasis]) -> Result<SlotLayout, String> {
        let mut materials = Vec::with_capacity(scene.materials.len());
        let mut used_bases: Vec<BrdfBasis> = Vec::new();
        let mut reasons = Vec::new();
        let mut offset = 0u32;
        for m in &scene.materials {
            let b = &m.brdf;
            let textured = m.base_color_texture.is_some();
            let mut basis_index = None;
            let (slots, reason) = if m.editable && b.family != Family::Diffuse {
                let Some(basis) = bases.iter().find(|x| x.family == b.family.name()) else {
                    return Err(format!(
                        "material '{}' is editable with family {} but no basis for it was built",
                        m.name,
                        b.family.name()
                    ));
                };
                let idx = match used_bases.iter().position(|x| x.family == basis.family) {
                    Some(i) => i,
                    None => {
                        used_bases.push(basis.clone());
                        used_bases.len() - 1
                    }
                };
                basis_index = Some(idx as u32);
                let mut s = Vec::new();
                if textured {
                    s.push(SlotKind::Kd);
                }
                s.extend((0..basis.num_bases as u32).map(SlotKind::Basis));
                let why = format!(
                    "editable {}: {} basis BRDFs{}",
                    b.family.name(),
                    basis.num_bases,
                    if textured {
                        " + a textured Kd slot"
                    } else {
                        ""
                    }
                );
                (s, why)
            } else if m.editable {
                (
                    vec![SlotKind::Kd],
                    "editable diffuse: 1 slot (Kd)".to_string(),
                )
            } else {
                let mut s = Vec::new();
                if b.kd != Vec3::ZERO {
                    s.push(SlotKind::Kd);
                }
                if b.family != Family::Diffuse && b.ks != Vec3::ZERO {
                    s.push(SlotKind::Lobe);
                }
                let why = match s.len() {
                    0 => "fixed, black: no slot (reflects nothing)".to_string(),
                    1 => "fixed: 1 slot".to_string(),
                    _ => "fixed glossy: 2 slots (Kd, lobe)".to_string(),
                };
                (s, why)
            };
            if slots.len() > MAX_SLOTS {
                return Err(format!(
                    "material '{}' needs {} slots; at most {MAX_SLOTS} are supported (use fewer basis BRDFs)",
                    m.name,
                    slots.len()
                ));
            }
            reasons.push(format!("{}: {}", m.name, reason));
            materials.push(MaterialMeta {
                name: m.name.clone(),
                editable: m.editable,
                family: b.family.name().to_string(),
                kd: b.kd.to_array(),
                ks: b.ks.to_array(),
                param: b.param,
                textured,
                slot_offset: offset,
                basis: basis_index,
                slots,
            });
            offset += materials.last().map_or(0, |m| m.slots.len() as u32);
        }
        // Gray tensors when every light has one chromaticity (factored out as `tint`, which
        // the runtime multiplies back in) and no texture colours a slot; RGB otherwise.
        let mut colours: Vec<Vec3> = Vec::new();
        let mut emissive_texture = false;
        for m in &scene.materials {
            if m.is_emissive() {
                colours.push(m.emission);
                emissive_texture |= m.emissive_texture.is_some();
            }
        }
        for l in &scene.lights {
            colours.push(match *l {
                crate::scene::PunctualLight::Point { intensity, .. }
                | crate::scene::PunctualLight::Spot { intensity, .. } => intensity,
                crate::scene::PunctualLight::Directional { irradiance, .. } => irradiance,
            });
        }
        match &scene.environment {
            Environment::Constant(c) => colours.push(*c),
            Environment::LatLong { texels, .. } => colours.extend(texels.iter().copied()),
        }
        let tint = common_chromaticity(&colours);
        let textured = materials.iter().any(|m| m.textured && !m.slots.is_empty());
        let single_tint = tint.is_some() && !emissive_texture;
        let channels = if single_tint && !textured { 1 } else { 3 };
        let tint = if channels == 1 {
            tint.unwrap_or(Vec3::ONE)
        } else {
            Vec3::ONE
        };
        reasons.push(format!(
            "tensors: {} ({})",
            if channels == 1 {
                "gray (1 channel)"
            } else {
                "RGB (3 channels)"
            },
            if channels == 1 {
                "one light colour, factored out; no textures: colours live in the coefficients"
            } else if !single_tint {
                "lights of different colours"
            } else {
                "a diffuse texture is baked into slots"
            }
        ));
        Ok(SlotLayout {
            total_slots: offset as usize,
            materials,
            bases: used_bases,
            channels,
            tint,
            reasons,
        })
    }

    /// RGB coefficient of every global slot for the materials' baked (starting) parameters,
    /// with `overrides` replacing some materials' parameters.
    pub fn coefficients(&self, overrides: &[(usize, MaterialParams)]) -> Vec<[f32; 3]> {
        let mut out = Vec::with_capacity(self.total_slots);
        for (i, m) in self.materials.iter().enumerate() {
            let p = overrides
                .iter()
                .rev()
                .find(|(k, _)| *k == i)
                .map_or(m.params(), |(_, p)| *p);
            let lobe = match m.basis {
                Some(b) => self.bases[b as usize].coefficients(p.param).0,
                None => Vec::new(),
            };
            out.extend(slot_coefficients(m, &p, &lobe));
        }
        out
    }

    /// The same coefficients per material, as the reference renderer's contraction wants.
    pub fn coefficients_per_material(
        &self,
        overrides: &[(usize, MaterialParams)],
    ) -> Vec<Vec<Vec3>> {
        let flat = self.coefficients(overrides);
        self.materials
            .iter()
            .map(|m| {
                let o = m.slot_offset as usize;
                flat[o..o + m.slots.len()]
                    .iter()
                    .map(|c| Vec3::from_array(*c))
                    .collect()
            })
            .collect()
    }
}

/// Lobe parameters the sampling mixture of an editable family uses besides the material's
/// starting value: the sharpest lobe of the basis range and one in the middle, so that any
/// edit within the range has a sampling component near it.
fn mixture_params(family: Family, start: f32, basis: &BrdfBasis) -> [f32; 3] {
    let [lo, hi] = basis.param_range;
    match family {
        // Sharpness grows with s.
        Family::BlinnPhong => [start, hi, (lo.max(1.0) * hi).sqrt()],
        // Sharpness grows as alpha shrinks.
        _ => [start, lo, (lo * hi).sqrt()],
    }
}

/// Mixture weights: cosine, starting lobe, sharpest lobe, middle lobe.
const MIXTURE: [f32; 4] = [0.4, 0.3, 0.15, 0.15];

/// Slot evaluation and coefficient-independent sampling for the bake (and for the
/// projected-BRDF reference, which must use the very same paths).
pub struct BakeModel<'a> {
    scene: &'a Scene,
    layout: &'a SlotLayout,
    /// Per material: the parameters of its sampling mixture (editable glossy only).
    mixtures: Vec<Option<(Family, [f32; 3])>>,
}

impl<'a> BakeModel<'a> {
    pub fn new(scene: &'a Scene, layout: &'a SlotLayout) -> Self {
        let mixtures = scene
            .materials
            .iter()
            .zip(&layout.materials)
            .map(|(m, meta)| {
                let basis = meta.basis.map(|b| &layout.bases[b as usize])?;
                let f = m.brdf.family;
                let p = m
                    .brdf
                    .param
                    .clamp(basis.param_range[0], basis.param_range[1]);
                Some((f, mixture_params(f, p, basis)))
            })
            .collect();
        BakeModel {
            scene,
            layout,
            mixtures,
        }
    }

    #[inline]
    fn texture(&self, s: &Surface) -> Option<Vec3> {
        let m = &self.scene.materials[s.material as usize];
        m.base_color_texture
            .and_then(|t| self.scene.textures.get(t))
            .map(|t| t.sample(s.uv))
    }

    /// The true BRDF of a fixed material at `s` (texture applied).
    #[inline]
    fn fixed_brdf(&self, s: &Surface) -> crate::brdf::BrdfParams {
        let mut b = self.scene.materials[s.material as usize].brdf;
        if let Some(t) = self.texture(s) {
            b.kd *= t;
        }
        b
    }
}

impl MaterialModel for BakeModel<'_> {
    fn eval(&self, s: &Surface, _depth: usize, wo: Vec3, wi: Vec3, out: &mut Slots) {
        let meta = &self.layout.materials[s.material as usize];
        out.material = s.material;
        out.len = meta.slots.len();
        if wo.z <= 0.0 || wi.z <= 0.0 {
            out.values[..out.len].fill(Vec3::ZERO);
            return;
        }
        let mut basis_vals = [0.0f32; MAX_SLOTS];
        if let Some(b) = meta.basis {
            self.layout.bases[b as usize].eval_all_local(
                wi.to_array(),
                wo.to_array(),
                &mut basis_vals,
            );
        }
        let m = &self.scene.materials[s.material as usize];
        for (k, slot) in meta.slots.iter().enumerate() {
            out.values[k] = match *slot {
                SlotKind::Kd => self.texture(s).unwrap_or(Vec3::ONE) * std::f32::consts::FRAC_1_PI,
                SlotKind::Basis(b) => Vec3::splat(basis_vals[b as usize]),
                SlotKind::Lobe => Vec3::splat(m.brdf.family.specular_lobe(m.brdf.param, wo, wi)),
            };
        }
    }

    fn sample(&self, s: &Surface, wo: Vec3, rng: &mut Rng) -> Option<BrdfSample> {
        let u_lobe = rng.next_f32();
        let u = rng.next_vec2();
        match self.mixtures[s.material as usize] {
            None => self.fixed_brdf(s).sample(wo, u, u_lobe),
            Some((family, params)) => {
                if wo.z <= 0.0 {
                    return None;
                }
                let mut acc = MIXTURE[0];
                let wi = if u_lobe < acc {
                    cosine_hemisphere(u)
                } else {
                    let mut k = 0;
                    for (i, w) in MIXTURE[1..].iter().enumerate() {
                        acc += w;
                        k = i;
                        if u_lobe < acc {
                            break;
                        }
                    }
                    let h = match family {
                        Family::BlinnPhong => sample_blinn_phong_half(params[k], u),
                        _ => sample_ggx_half(params[k], u),
                    };
                    reflect(wo, h)
                };
                if wi.z <= 0.0 {
                    return None;
                }
                let pdf = self.pdf(s, wo, wi);
                (pdf > 0.0 && pdf.is_finite()).then_some(BrdfSample { wi, pdf })
            }
        }
    }

    fn pdf(&self, s: &Surface, wo: Vec3, wi: Vec3) -> f32 {
        match self.mixtures[s.material as usize] {
            None => self.fixed_brdf(s).pdf(wo, wi),
            Some((family, params)) => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return 0.0;
                }
                let mut pdf = MIXTURE[0] * wi.z * std::f32::consts::FRAC_1_PI;
                for (w, p) in MIXTURE[1..].iter().zip(params) {
                    pdf += w * specular_lobe_pdf(family, p, wo, wi);
                }
                pdf
            }
        }
    }
}

/// Accumulates one pixel's tensors, one dense row per visible material, over all slots J.
struct TensorSink<'a> {
    layout: &'a SlotLayout,
    inv_tint: Vec3,
    reflections: usize,
    /// (material, row) for the materials this pixel's samples saw first.
    rows: Vec<(u32, Vec<f32>)>,
    current: Option<usize>,
    emission: Vec3,
}

impl<'a> TensorSink<'a> {
    fn new(layout: &'a SlotLayout, reflections: usize) -> Self {
        TensorSink {
            layout,
            inv_tint: Vec3::ONE / layout.tint,
            reflections,
            rows: Vec::new(),
            current: None,
            emission: Vec3::ZERO,
        }
    }
}

impl PathSink for TensorSink<'_> {
    fn camera_emission(&mut self, radiance: Vec3) {
        if radiance.is_finite() {
            self.emission += radiance;
        }
    }

    fn first_hit(&mut self, s: &Surface) {
        let n0 = self.layout.materials[s.material as usize].slots.len();
        if n0 == 0 {
            self.current = None;
            return;
        }
        let idx = match self.rows.iter().position(|(m, _)| *m == s.material) {
            Some(i) => i,
            None => {
                let len = row_len(
                    n0,
                    self.layout.total_slots,
                    self.reflections,
                    self.layout.channels,
                );
                self.rows.push((s.material, vec![0.0; len]));
                self.rows.len() - 1
            }
        };
        self.current = Some(idx);
    }

    fn path(&mut self, prefix: &[Slots], last: &Slots, weight: Vec3) {
        let Some(row_idx) = self.current else {
            return;
        };
        let k = prefix.len();
        let c = self.layout.channels;
        let jn = self.layout.total_slots;
        let mats = &self.layout.materials;
        let row = &mut self.rows[row_idx].1;
        let v0 = if k == 0 { last } else { &prefix[0] };
        let n0 = v0.len;
        // Offset of the depth-k block.
        let mut off = 0usize;
        let mut pow = 1usize;
        for _ in 0..k {
            off += n0 * pow;
            pow *= jn;
        }
        // Vertices after the first, in path order.
        let mut chain: [&Slots; 4] = [last; 4];
        for (i, s) in prefix.iter().skip(1).enumerate() {
            chain[i] = s;
        }
        chain[k.saturating_sub(1)] = last;
        let chain = &chain[..k];
        if chain.iter().any(|v| v.len == 0) {
            // A vertex on a material without slots (black) reflects nothing.
            return;
        }
        // Enumerate every slot combination along the chain (j1 fastest).
        let mut choice = [0usize; 4];
        loop {
            let mut val = weight;
            let mut idx = 0usize;
            let mut mul = 1usize;
            for (d, v) in chain.iter().enumerate() {
                val *= v.values[choice[d]];
                idx += (mats[v.material as usize].slot_offset as usize + choice[d]) * mul;
                mul *= jn;
            }
            if val != Vec3::ZERO && val.is_finite() {
                for b0 in 0..n0 {
                    let x = val * v0.values[b0] * self.inv_tint;
                    let e = (off + b0 * pow + idx) * c;
                    if c == 1 {
                        row[e] += x.x;
                    } else {
                        row[e] += x.x;
                        row[e + 1] += x.y;
                        row[e + 2] += x.z;
                    }
                }
            }
            // Next combination.
            let mut d = 0;
            loop {
                if d == k {
                    return;
                }
                choice[d] += 1;
                if choice[d] < chain[d].len {
                    break;
                }
                choice[d] = 0;
                d += 1;
            }
        }
    }
}

/// The result of a per-pixel bake, ready to be written.
pub struct PixelBake {
    pub meta: PixelBakeMeta,
    /// Radiance reaching the camera without reflection, [H, W, 3].
    pub emission: Vec<f32>,
    pub groups: Vec<GroupData>,
    /// Basis tables per used basis (as stored in `basis.<i>.tables`).
    pub basis_tables: Vec<Vec<f32>>,
}

/// One group's tensors (f32, compacted to its active slots).
pub struct GroupData {
    pub pixels: Vec<u32>,
    /// [pixels, row_len].
    pub rows: Vec<f32>,
    /// Low-rank variant: mean [row_len], components [rank, row_len], weights [pixels, rank].
    pub compressed: Option<Compressed>,
}

pub struct Compressed {
    pub mean: Vec<f32>,
    pub components: Vec<f32>,
    pub weights: Vec<f32>,
    pub rank: usize,
}

/// Working-memory estimate of the bake: the dense rows of every (pixel, visible material).
pub struct MemoryEstimate {
    pub bytes: u64,
    pub pixels_per_material: Vec<u64>,
    pub values_per_pixel: Vec<usize>,
}

/// Counts the materials visible per pixel with a few primary rays per pixel, and sizes the
/// dense accumulation rows from that.
pub fn estimate_memory(
    integ: &Integrator,
    layout: &SlotLayout,
    reflections: usize,
) -> MemoryEstimate {
    let n = layout.materials.len();
    let (w, h) = (integ.width, integ.height);
    let counts = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut counts = vec![0u64; n];
            let mut seen = Vec::with_capacity(4);
            for x in 0..w {
                seen.clear();
                for (dx, dy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                    let (o, d) = integ.camera_ray(x as f32 + dx, y as f32 + dy);
                    if let Some(hit) = integ.accel.intersect(o, d, 0.0, f32::INFINITY) {
                        let m = integ.scene.triangle_material[hit.triangle as usize];
                        if !seen.contains(&m) {
                            seen.push(m);
                            counts[m as usize] += 1;
                        }
                    }
                }
            }
            counts
        })
        .reduce(
            || vec![0u64; n],
            |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
        );
    let values: Vec<usize> = layout
        .materials
        .iter()
        .map(|m| {
            row_len(
                m.slots.len(),
                layout.total_slots,
                reflections,
                layout.channels,
            )
        })
        .collect();
    let bytes = counts
        .iter()
        .zip(&values)
        .map(|(&p, &v)| p * v as u64 * 4)
        .sum::<u64>()
        + (w as u64 * h as u64 * 12);
    MemoryEstimate {
        bytes,
        pixels_per_material: counts,
        values_per_pixel: values,
    }
}

/// Runs the bake. `progress` (if any) is advanced once per image row.
pub fn bake(
    scene: &Scene,
    layout: &SlotLayout,
    opts: &PixelBakeOptions,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<PixelBake, String> {
    let start = Instant::now();
    let accel = Accel::build(scene);
    let lights = LightSet::new(scene);
    let reflections = opts.reflections as usize;
    let integ = Integrator::new(scene, &accel, &lights, reflections, opts.width, opts.height);
    let model = BakeModel::new(scene, layout);
    let (w, h) = (opts.width, opts.height);
    let spp = opts.spp.max(1);
    let inv = 1.0 / spp as f32;

    struct RowOut {
        emission: Vec<f32>,
        entries: Vec<(u32, u32, Vec<f32>)>,
        rays: u64,
    }
    let rows: Vec<RowOut> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut out = RowOut {
                emission: Vec::with_capacity(3 * w as usize),
                entries: Vec::new(),
                rays: 0,
            };
            for x in 0..w {
                let pixel = y as u64 * w as u64 + x as u64;
                let mut sink = TensorSink::new(layout, reflections);
                for s in 0..spp {
                    let mut rng = Rng::for_sample(opts.seed, pixel, s as u64);
                    sink.current = None;
                    out.rays += integ.trace_sample(&model, &mut sink, x, y, &mut rng) as u64;
                }
                out.emission.extend((sink.emission * inv).to_array());
                for (m, mut row) in sink.rows {
                    row.iter_mut().for_each(|v| *v *= inv);
                    out.entries.push((pixel as u32, m, row));
                }
            }
            if let Some(p) = progress {
                p.inc(1);
            }
            out
        })
        .collect();
    let trace_seconds = start.elapsed().as_secs_f64();

    // Gather per material, in pixel order.
    let nmat = layout.materials.len();
    let mut emission = Vec::with_capacity((w * h * 3) as usize);
    let mut per_mat: Vec<(Vec<u32>, Vec<Vec<f32>>)> = vec![(Vec::new(), Vec::new()); nmat];
    let mut rays = 0u64;
    for r in rows {
        emission.extend(r.emission);
        rays += r.rays;
        for (p, m, row) in r.entries {
            per_mat[m as usize].0.push(p);
            per_mat[m as usize].1.push(row);
        }
    }

    // Compact each group to the slots that carry light into it.
    let jn = layout.total_slots;
    let c = layout.channels;
    let mut groups_meta = Vec::new();
    let mut groups = Vec::new();
    let mut dense_values = 0u64;
    let mut stored_values = 0u64;
    for (m, (pixels, rows)) in per_mat.into_iter().enumerate() {
        if pixels.is_empty() {
            continue;
        }
        let n0 = layout.materials[m].slots.len();
        let active = active_slots(&rows, n0, jn, reflections, c);
        let (compact_len, compact) = compact_rows(&rows, n0, jn, &active, reflections, c);
        dense_values += rows.iter().map(|r| r.len() as u64).sum::<u64>();
        stored_values += compact.len() as u64;
        let compressed = opts
            .compress_rank
            .map(|k| compress(&compact, pixels.len(), compact_len, k));
        groups_meta.push(GroupMeta {
            material: m as u32,
            pixels: pixels.len() as u32,
            slots: n0 as u32,
            active: active.iter().map(|&j| j as u32).collect(),
            row_len: compact_len as u32,
            compressed_rank: compressed.as_ref().map(|c| c.rank as u32),
            scale: 1.0,
        });
        groups.push(GroupData {
            pixels,
            rows: compact,
            compressed,
        });
    }

    let mut bases_meta = Vec::new();
    let mut basis_tables = Vec::new();
    for b in &layout.bases {
        let mut meta = b.clone();
        basis_tables.push(std::mem::take(&mut meta.tables));
        bases_meta.push(BasisMeta { basis: meta });
    }
    let cam = &scene.camera;
    let seconds = start.elapsed().as_secs_f64();
    let stats = serde_json::json!({
        "bake_seconds": seconds,
        "trace_seconds": trace_seconds,
        "rays": rays,
        "rays_per_second": rays as f64 / trace_seconds.max(1e-9),
        "dense_values": dense_values,
        "stored_values": stored_values,
        "allocation": layout.reasons,
        "triangles": scene.triangles.len(),
    });
    let meta = PixelBakeMeta {
        pixel_schema_version: PIXEL_SCHEMA_VERSION,
        width: w,
        height: h,
        spp,
        reflections: opts.reflections,
        seed: opts.seed,
        channels: c as u32,
        tint: layout.tint.to_array(),
        precision: opts.precision.name().to_string(),
        materials: layout.materials.clone(),
        bases: bases_meta,
        groups: groups_meta,
        camera: CameraMeta {
            position: cam.position.to_array(),
            forward: cam.forward.to_array(),
            up: cam.up.to_array(),
            yfov: cam.yfov,
        },
        stats,
    };
    Ok(PixelBake {
        meta,
        emission,
        groups,
        basis_tables,
    })
}

/// Global slots j that appear with a nonzero value anywhere in the group's T1/T2 blocks.
fn active_slots(
    rows: &[Vec<f32>],
    n0: usize,
    jn: usize,
    reflections: usize,
    c: usize,
) -> Vec<usize> {
    let mut used = vec![false; jn];
    for row in rows {
        let mut off = n0 * c; // skip T0
        let mut pow = jn;
        for depth in 1..reflections {
            let block = &row[off..off + n0 * pow * c];
            for (i, v) in block.iter().enumerate() {
                if *v != 0.0 {
                    // Decompose the element into its active indices.
                    let mut idx = (i / c) % pow;
                    for _ in 0..depth {
                        used[idx % jn] = true;
                        idx /= jn;
                    }
                }
            }
            off += n0 * pow * c;
            pow *= jn;
        }
    }
    (0..jn).filter(|&j| used[j]).collect()
}

/// Rewrites dense rows over all J slots into rows over the active slots only.
fn compact_rows(
    rows: &[Vec<f32>],
    n0: usize,
    jn: usize,
    active: &[usize],
    reflections: usize,
    c: usize,
) -> (usize, Vec<f32>) {
    let ja = active.len();
    let len = row_len(n0, ja, reflections, c);
    let mut out = Vec::with_capacity(rows.len() * len);
    for row in rows {
        let mut src_off = 0usize;
        let mut src_pow = 1usize;
        let mut dst_pow = 1usize;
        for depth in 0..reflections {
            for b0 in 0..n0 {
                for idx in 0..dst_pow {
                    // Map the compact multi-index to the dense one.
                    let mut rest = idx;
                    let mut dense = 0usize;
                    let mut mul = 1usize;
                    for _ in 0..depth {
                        dense += active[rest % ja] * mul;
                        rest /= ja;
                        mul *= jn;
                    }
                    let e = (src_off + b0 * src_pow + dense) * c;
                    out.extend_from_slice(&row[e..e + c]);
                }
            }
            src_off += n0 * src_pow;
            src_pow *= jn;
            dst_pow *= ja;
        }
    }
    (len, out)
}

/// PCA over pixels: rows ~ mean + weights x components, rank k (capped by the data).
fn compress(rows: &[f32], n: usize, len: usize, k: usize) -> Compressed {
    crate::pixel_compress::pca_rows(rows, n, len, k)
}

/// Converts tensor values to f16 with a per-tensor scale so values beyond f16's range (sun-like
/// lights) survive: stored = value / scale, scale chosen so the largest magnitude maps to
/// 2^14. Returns (data, scale).
pub fn to_f16_scaled(values: &[f32]) -> (Vec<f16>, f32) {
    let max = values.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let scale = if max > 0.0 && max.is_finite() {
        max / 16384.0
    } else {
        1.0
    };
    let inv = 1.0 / scale;
    (
        values.iter().map(|v| f16::from_f32(v * inv)).collect(),
        scale,
    )
}

/// `[rows, cols]` row-major to `[cols, rows]` row-major.
fn transpose(data: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; data.len()];
    for (r, row) in data.chunks_exact(cols.max(1)).enumerate().take(rows) {
        for (c, v) in row.iter().enumerate() {
            out[c * rows + r] = *v;
        }
    }
    out
}

/// Tensor names of the per-pixel schema (docs/format.md, "Bake schema").
pub mod names {
    pub const EMISSION: &str = "emission";
    pub fn pixels(g: usize) -> String {
        format!("g{g}.pixels")
    }
    pub fn transfer(g: usize) -> String {
        format!("g{g}.t")
    }
    pub fn mean(g: usize) -> String {
        format!("g{g}.mean")
    }
    pub fn components(g: usize) -> String {
        format!("g{g}.components")
    }
    pub fn weights(g: usize) -> String {
        format!("g{g}.weights")
    }
    pub fn basis_tables(b: usize) -> String {
        format!("basis.{b}.tables")
    }
}

/// Writes the bake file atomically; returns its size in bytes.
pub fn write_bake_file(
    bake: &PixelBake,
    path: &std::path::Path,
    precision: Precision,
) -> Result<u64, String> {
    use prt_formats::BakeWriter;
    let mut meta = bake.meta.clone();
    // The file stores each group element-major ([row_len, pixels], pixels fastest) so the
    // runtime streams contiguous columns vectorised across pixels. Convert first: the writer
    // borrows the buffers.
    let transposed: Vec<Vec<f32>> = bake
        .groups
        .iter()
        .zip(&meta.groups)
        .map(|(g, gm)| transpose(&g.rows, g.pixels.len(), gm.row_len as usize))
        .collect();
    let weights_t: Vec<Option<Vec<f32>>> = bake
        .groups
        .iter()
        .map(|g| {
            g.compressed
                .as_ref()
                .map(|c| transpose(&c.weights, g.pixels.len(), c.rank))
        })
        .collect();
    let halves: Vec<Option<Vec<f16>>> = transposed
        .iter()
        .zip(meta.groups.iter_mut())
        .map(|(t, gm)| match precision {
            Precision::F32 => None,
            Precision::F16 => {
                let (h, scale) = to_f16_scaled(t);
                gm.scale = scale;
                Some(h)
            }
        })
        .collect();
    let mut w = BakeWriter::new();
    let err = |e: prt_formats::FormatError| e.to_string();
    let (wd, ht) = (meta.width as usize, meta.height as usize);
    w.add_f32(names::EMISSION, &[ht, wd, 3], &bake.emission)
        .map_err(err)?;
    let names_p: Vec<[String; 5]> = (0..bake.groups.len())
        .map(|g| {
            [
                names::pixels(g),
                names::transfer(g),
                names::mean(g),
                names::components(g),
                names::weights(g),
            ]
        })
        .collect();
    for (g, (data, gm)) in bake.groups.iter().zip(&meta.groups).enumerate() {
        let [np, nt, nm, nc, nw] = &names_p[g];
        let p = data.pixels.len();
        let len = gm.row_len as usize;
        w.add_u32(np, &[p], &data.pixels).map_err(err)?;
        match &halves[g] {
            Some(h) => w.add_f16(nt, &[len, p], h).map_err(err)?,
            None => w.add_f32(nt, &[len, p], &transposed[g]).map_err(err)?,
        }
        if let (Some(c), Some(wt)) = (&data.compressed, &weights_t[g]) {
            w.add_f32(nm, &[len], &c.mean).map_err(err)?;
            w.add_f32(nc, &[c.rank, len], &c.components).map_err(err)?;
            w.add_f32(nw, &[c.rank, p], wt).map_err(err)?;
        }
    }
    let basis_names: Vec<String> = (0..bake.basis_tables.len())
        .map(names::basis_tables)
        .collect();
    for (b, t) in bake.basis_tables.iter().enumerate() {
        let nb = meta.bases[b].basis.num_bases;
        w.add_f32(&basis_names[b], &[t.len() / nb.max(1), nb], t)
            .map_err(err)?;
    }
    w.set_metadata(meta.to_json());
    let size = w.file_len().map_err(err)?;
    w.write_atomic(path).map_err(err)?;
    Ok(size)
}
