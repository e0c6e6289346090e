//! What a GPU backend reads of a per-vertex relighter (feature `gpu-surface`; docs/gpu.md):
//! the results of the light and material stages, run here on the CPU, and the per-frame
//! inputs of the view stage, which the backend runs itself (rasterization and the per-pixel
//! last reflection). Read-only views of the relighter's own state: nothing is copied, and the
//! stages' run counters tell the backend when to upload a result again.

use half::slice::HalfFloatSliceExt;
use prt_formats::basis::ShadingBasis;
use prt_formats::envmap::LatLongMap;
use prt_formats::lighting::sh::{SH_BANDS, SH_COUNT};
use prt_formats::lighting::CubeMap;
use prt_formats::vertex::names;
use prt_formats::view::CameraFrame;

use prt_formats::Family;

use super::compact_lights::CompactLight;
use super::incident::{E_AT, I1_AT, I2_AT, U_AT};
use super::VertexRelighter;
use crate::error::RuntimeError;

/// Offsets of a vertex record's parts (floats; each part RGB): the irradiance `E`, the
/// two-reflection radiance `I2`, the 16 SH coefficients of `I1`, then the `r_i` incident
/// projections `U` (docs/vertex.md, section 3).
pub const RECORD_E: usize = E_AT;
/// Offset of `I2` in a vertex record.
pub const RECORD_I2: usize = I2_AT;
/// Offset of `I1[0]` in a vertex record.
pub const RECORD_I1: usize = I1_AT;
/// Offset of `U[0]` in a vertex record.
pub const RECORD_U: usize = U_AT;

/// What [`VertexRelighter::prepare_stages`] ran.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stages {
    /// The light stage's wall-clock seconds, when it ran.
    pub light_s: Option<f64>,
    /// The material stage's wall-clock seconds, when it ran.
    pub material_s: Option<f64>,
}

/// One split width of a shading basis as the view stage reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitWidth {
    /// The Gaussian's width in degrees.
    pub degrees: f32,
    /// Which of [`VertexSurface::prefiltered`] its `Ibar_w` is read from (every width, 0 too:
    /// `ShadingBasis::rendered_width_deg`).
    pub prefiltered: usize,
    /// The normalized Gaussian's SH factor per band, applied to `I1`.
    pub sh_factors: [f32; SH_BANDS],
    /// The rendered Gaussian's spread in radians: its light is read at
    /// `prt_formats::basis::cosine_centroid(r, sigma)`, not at the mirror direction `r`.
    pub sigma: f32,
}

/// A material's lobe at its current parameter, as the view stage reads it.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceLobe<'a> {
    /// Its shading basis (index into [`VertexSurface::shading`]).
    pub basis: usize,
    /// The basis core contracted with `U^h(param)`: `r_o x r_i`, row-major.
    pub core: &'a [f32],
    /// The parameter samples its split reflectances are blended from, with their weights
    /// (zero weights left out): `taps[..taps_len]`.
    pub taps: [(usize, f32); 2],
    /// How many of `taps` are used.
    pub taps_len: usize,
    /// Its family, whose true lobe (`prt_formats::lobe::specular_lobe`) reflects the compact
    /// lights ([`VertexSurface::compact_lights`]).
    pub family: Family,
    /// Its parameter (shininess or alpha) as set.
    pub param: f32,
}

/// One material as the view stage reads it.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceMaterial<'a> {
    /// Its group (vertex records, visibility); `None`: no data, shown black.
    pub group: Option<usize>,
    /// Current diffuse albedo.
    pub kd: [f32; 3],
    /// Current specular albedo.
    pub ks: [f32; 3],
    /// Its base-colour texture (index into [`VertexSurface::texture`]).
    pub texture: Option<usize>,
    /// Its normal map (index into [`VertexSurface::texture`]: decoded tangent-space vectors,
    /// `prt_formats::normal_map`), which bends the normal its lobe is evaluated about.
    pub normal_map: Option<usize>,
    /// Its lobe, when it has one (else only `Kd tex / pi E` is shaded).
    pub lobe: Option<SurfaceLobe<'a>>,
}

/// Stored values of a T0, T1 or T2 tensor as the file holds them.
#[derive(Clone, Copy, Debug)]
pub enum StoredValues<'a> {
    /// 32-bit floats.
    F32(&'a [f32]),
    /// Half floats, as their bits.
    F16(&'a [u16]),
}

impl StoredValues<'_> {
    /// Whether the values are half floats.
    pub fn is_f16(&self) -> bool {
        matches!(self, StoredValues::F16(_))
    }

    /// The number of values.
    pub fn len(&self) -> usize {
        match self {
            StoredValues::F32(v) => v.len(),
            StoredValues::F16(v) => v.len(),
        }
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A compressed T1 or T2 (clustered Tucker, `prt_formats::clustered`), as the runtime holds it
/// after opening (f32).
#[derive(Clone, Copy, Debug)]
pub struct ClusteredTensor<'a> {
    /// Per cluster `(a, r, b)`: light, element and vertex ranks.
    pub ranks: &'a [[usize; 3]],
    /// Per cluster, its `light_c` (`bins x a`) in `factors`; its element factor follows at
    /// `+ bins * a`, **transposed** to `r x width` (width = elements x channels).
    pub factor_at: &'a [usize],
    /// Per cluster, its core (`b x a x r`) in `core`.
    pub core_at: &'a [usize],
    /// Per cluster, its first row of the per-cluster results (`b_c` rows each).
    pub rows_at: &'a [usize],
    /// The per-cluster results' rows in all.
    pub rows: usize,
    /// Floats per vertex of `vertex` (the largest `b`).
    pub vertex_rank: usize,
    /// The factors (see `factor_at`).
    pub factors: &'a [f32],
    /// The cores.
    pub core: &'a [f32],
    /// `[V][vertex_rank]`: each vertex's coefficients over its cluster's rows.
    pub vertex: &'a [f32],
}

/// T1 or T2 of one group.
#[derive(Clone, Copy, Debug)]
pub enum StageTensor<'a> {
    /// `[V][bins][width]` as stored (width = elements x channels).
    Dense(StoredValues<'a>),
    /// Clustered Tucker.
    Clustered(ClusteredTensor<'a>),
}

/// What the light and material stages read of one group (docs/vertex.md, sections 3 and 4),
/// for a backend that runs them itself ([`VertexRelighter::prepare_device_stages`]).
#[derive(Clone, Debug)]
pub struct StageGroup<'a> {
    /// Global indices of the group's vertices (its records are in this order).
    pub vertices: &'a [u32],
    /// T0 rows per vertex (`r_i + 1`, or 1): the last is the irradiance.
    pub rows: usize,
    /// Haar terms per T0 row.
    pub terms: usize,
    /// T0's Haar indices, `[V][rows][terms]`.
    pub t0_index: &'a [u16],
    /// T0's values, `[V][rows][terms]`.
    pub t0_values: StoredValues<'a>,
    /// Per vertex, whether its irradiance row is the occluded part, subtracted from the open
    /// sky's irradiance at its normal ([`VertexSurface::open_sky`]); empty: none is.
    pub t0_open: &'a [bool],
    /// Stored T0, T1, T2 values times these are the true values.
    pub scales: [f32; 3],
    /// Global slots of `J` (the active slots), in the tensors' order.
    pub active: &'a [u32],
    /// T1's elements per channel (`J x 16`) and T2's (`J x I`).
    pub elements: [usize; 2],
    /// Channels of T1 and T2 (1: gray, 3: RGB interleaved).
    pub channels: usize,
    /// T1.
    pub t1: StageTensor<'a>,
    /// T2 (reflections = 3).
    pub t2: Option<StageTensor<'a>>,
    /// For a compressed group: each vertex's cluster.
    pub clusters: Option<&'a [u32]>,
    /// The group's shading basis ([`VertexSurface::shading_constants`]), if any.
    pub shading: Option<usize>,
}

/// One shading basis' hemisphere constants (docs/vertex.md, section 3).
#[derive(Clone, Copy, Debug)]
pub struct StageConstants<'a> {
    /// `r_i`.
    pub rank: usize,
    /// `Cwi[s][c]`, `[16][rank]`.
    pub cwi: &'a [f32],
    /// `Cconst[c]`, `[rank]`.
    pub cconst: &'a [f32],
}

/// A read-only view of a prepared per-vertex relighter: see the module documentation.
pub struct VertexSurface<'a> {
    r: &'a VertexRelighter,
}

impl VertexRelighter {
    /// Runs what a frame needs before its view stage (feature `gpu-surface`): the camera
    /// and eye checks, the light and material stages when their inputs changed, and the view
    /// stage's material table; refuses what [`VertexRelighter::render_into`] refuses, with
    /// the same errors. Then [`VertexRelighter::surface`] shows the results.
    pub fn prepare_stages(&mut self) -> Result<Stages, RuntimeError> {
        let (_, light_s, material_s) = self.prepare_frame(true)?;
        Ok(Stages {
            light_s,
            material_s,
        })
    }

    /// [`VertexRelighter::prepare_stages`] for a backend that runs the light and material
    /// stages itself (from the lighting map and rotation, [`VertexSurface::stage_groups`] and
    /// [`VertexSurface::slot_coefficients`]): here only the checks, the prefiltered cubes
    /// (once per map: they are of the unturned map) and the materials' contracted cores;
    /// [`VertexSurface::records`] stays empty and [`VertexSurface::open_sky`] `None`. A CPU
    /// render afterwards runs the whole stages again.
    pub fn prepare_device_stages(&mut self) -> Result<Stages, RuntimeError> {
        let (_, light_s, material_s) = self.prepare_frame(false)?;
        Ok(Stages {
            light_s,
            material_s,
        })
    }

    /// The view stage's inputs (feature `gpu-surface`), once
    /// [`VertexRelighter::prepare_stages`] has run since the last change; `None` before.
    pub fn surface(&self) -> Option<VertexSurface<'_>> {
        (self.light.is_some() && self.shaded.is_some()).then_some(VertexSurface { r: self })
    }
}

impl<'a> VertexSurface<'a> {
    /// How many times the light stage has run: the environment's texels, rotation and
    /// prefiltered cubes are current for this count.
    pub fn light_runs(&self) -> u64 {
        self.r.light_runs
    }

    /// How many times the lighting map's texels have changed (a new map or intensity; a turn
    /// does not): [`VertexSurface::environment`] and [`VertexSurface::prefiltered`] are
    /// current for this count.
    pub fn map_runs(&self) -> u64 {
        self.r.map_runs
    }

    /// How many times the material stage has run: the vertex records and the materials are
    /// current for this count.
    pub fn material_runs(&self) -> u64 {
        self.r.material_runs
    }

    /// The camera frames are rendered from.
    pub fn camera(&self) -> CameraFrame {
        self.r.camera
    }

    /// The image size `(width, height)`.
    pub fn size(&self) -> (u32, u32) {
        (self.r.width, self.r.height)
    }

    /// Sub-samples per side a pixel that sees the environment averages, on a regular `k x k`
    /// grid of film positions at `(px + (i + 0.5) / k, py + (j + 0.5) / k)`, summed row by
    /// row and divided by `k^2` (1: the pixel's centre), for the current camera, size and
    /// map: the same count the CPU's view stage uses.
    pub fn background_samples(&self) -> u32 {
        let map = self.r.lighting_map();
        super::view::background_samples(
            (f64::from(self.r.camera.yfov) * 0.5).tan(),
            self.r.height,
            map.width,
            map.height,
        )
    }

    /// Vertex positions (world).
    pub fn positions(&self) -> &'a [[f32; 3]] {
        &self.r.scene.positions
    }

    /// Unit vertex normals (the side the data is for).
    pub fn normals(&self) -> &'a [[f32; 3]] {
        &self.r.scene.normals
    }

    /// Vertex texture coordinates.
    pub fn uvs(&self) -> &'a [[f32; 2]] {
        &self.r.scene.uvs
    }

    /// Triangles' vertex indices.
    pub fn triangles(&self) -> &'a [[u32; 3]] {
        &self.r.scene.triangles
    }

    /// Each triangle's material.
    pub fn triangle_material(&self) -> &'a [u32] {
        &self.r.scene.triangle_material
    }

    /// Per mesh vertex, its group and its index in the group (`u32::MAX` for the group of a
    /// vertex in none; every vertex of a triangle is in its material's group).
    pub fn vertex_group(&self) -> &'a [(u32, u32)] {
        &self.r.scene.vertex_group
    }

    /// The number of groups.
    pub fn groups(&self) -> usize {
        self.r.meta.groups.len()
    }

    /// Group `g`'s vertex records from the material stage: `(stride, records)`, `stride`
    /// floats per vertex of the group (offsets [`RECORD_E`] .. [`RECORD_U`]).
    pub fn records(&self, g: usize) -> (usize, &'a [f32]) {
        match self.r.shaded.as_ref().and_then(|s| s.groups.get(g)) {
            Some(shade) => (shade.stride, &shade.data),
            None => (RECORD_U, &[]),
        }
    }

    /// Group `g`'s visibility: per vertex of the group, the visible fraction of each 6x16x16
    /// cube texel (`u8`, 255 = all), or empty for a group without a shading basis.
    pub fn visibility(&self, g: usize) -> &'a [u8] {
        let file = &self.r.file;
        self.r
            .view
            .visibility_range(g)
            .and_then(|range| file.file_bytes().get(range))
            .unwrap_or(&[])
    }

    /// The number of materials.
    pub fn materials(&self) -> usize {
        self.r.meta.materials.len()
    }

    /// Material `m` at its current parameters (`None` past the last).
    pub fn material(&self, m: usize) -> Option<SurfaceMaterial<'a>> {
        let view = self.r.view.material(m)?;
        let lobe = self
            .r
            .shaded
            .as_ref()
            .and_then(|s| s.lobes.get(m))
            .and_then(|l| l.as_ref());
        let lobe = match (lobe, view.taps) {
            (Some(l), Some(taps)) => {
                let (taps, taps_len) = taps.parts();
                Some(SurfaceLobe {
                    basis: l.basis,
                    core: &l.core,
                    taps,
                    taps_len,
                    family: self.r.scene.shading[l.basis].family,
                    param: l.param,
                })
            }
            _ => None,
        };
        Some(SurfaceMaterial {
            group: view.group,
            kd: view.kd,
            ks: view.ks,
            texture: view.texture,
            normal_map: view.normal_map,
            lobe,
        })
    }

    /// The shading bases (Tucker tables, split reflectances), validated.
    pub fn shading(&self) -> &'a [ShadingBasis] {
        &self.r.scene.shading
    }

    /// Split width `k` of shading basis `b` (`None` past the last).
    pub fn split_width(&self, b: usize, k: usize) -> Option<SplitWidth> {
        let w = self.r.widths.get(b)?.get(k)?;
        Some(SplitWidth {
            degrees: w.degrees,
            prefiltered: w.cube,
            sh_factors: w.sh_factors,
            sigma: w.sigma,
        })
    }

    /// The environment's prefiltered cubes (per nonzero split width), of the map **unturned**:
    /// a renderer reads them at `R_y(-rotation) d` for a world direction `d`.
    pub fn prefiltered(&self) -> &'a [CubeMap] {
        self.r.light.as_ref().map_or(&[], |l| l.prefiltered())
    }

    /// The open sky's irradiance per normal of the light **turned** (read at world normals),
    /// when the bake has a normal map or open-sky irradiance rows: a pixel of a normal-mapped
    /// material scales its irradiance by this at the bent normal over this at the
    /// interpolated one.
    ///
    /// `None` when a device runs the light stage (`prepare_device_stages`): it makes the table
    /// itself, when [`VertexSurface::needs_open_sky`].
    pub fn open_sky(&self) -> Option<&'a CubeMap> {
        self.r.light.as_ref()?.host()?.0.open_sky.as_ref()
    }

    /// Whether the light needs the open sky's irradiance per normal (6 x 32 x 32,
    /// `prt_formats::lighting::irradiance::irradiance_table` of the turned light cube): for
    /// vertices whose irradiance row is the occluded part ([`StageGroup::t0_open`]) and for
    /// normal-mapped materials.
    pub fn needs_open_sky(&self) -> bool {
        self.r.needs_open_sky()
    }

    /// The map that lights the scene (intensity applied), unturned.
    pub fn environment(&self) -> &'a LatLongMap {
        self.r.lighting_map()
    }

    /// The map's compact lights (docs/vertex.md, "Compact lights"; empty when there are none
    /// or [`VertexRelighter::set_compact_lights`] turned them off): directions in the map's
    /// frame, **unturned** (a light at `d` is at `R_y(rotation) d` in the world), powers times
    /// the intensity. A glossy pixel adds `Ks f(wo, l) (n' . l) V(l) P` per light, with the
    /// family's true lobe `f` and the visible fraction `V` read as for the split's widths;
    /// the records' `U` and [`VertexSurface::prefiltered`] leave them out.
    pub fn compact_lights(&self) -> Vec<CompactLight> {
        let r = self.r;
        match r.prefiltered.kept_extraction() {
            Some(e) if r.compact_lights => e
                .lights
                .iter()
                .map(|l| CompactLight {
                    direction: l.direction,
                    power: l.power.map(|p| p * r.intensity),
                })
                .collect(),
            _ => Vec::new(),
        }
    }

    /// The map less its compact lights, **before** the intensity (multiply by the second
    /// value), when it has any: what a device's light stage dots the glossy rows of T0 (all
    /// rows but the last, the irradiance) with; `None`: they read the lighting map.
    pub fn glossy_environment(&self) -> Option<(&'a LatLongMap, f32)> {
        let r = self.r;
        match r.prefiltered.kept_extraction() {
            Some(e) if r.compact_lights && !e.lights.is_empty() => Some((&e.residual, r.intensity)),
            _ => None,
        }
    }

    /// The environment's rotation about +Y in degrees: radiance from world direction `d` is
    /// the map's from `R_y(-rotation) d`.
    pub fn environment_rotation(&self) -> f32 {
        self.r.rotation_deg
    }

    /// What the stages read of each group (for [`VertexRelighter::prepare_device_stages`]):
    /// the tensors as the file stores them (T0, dense T1 and T2) or as the runtime holds them
    /// after opening (compressed T1 and T2).
    pub fn stage_groups(&self) -> Result<Vec<StageGroup<'a>>, RuntimeError> {
        let r = self.r;
        let file = &r.file;
        let values = |name: String| -> Result<StoredValues<'a>, RuntimeError> {
            let t = file.tensor(&name)?;
            Ok(match t.dtype() {
                prt_formats::Dtype::F16 => StoredValues::F16(t.as_f16()?.reinterpret_cast()),
                _ => StoredValues::F32(t.as_f32()?),
            })
        };
        let n_i = r.meta.t2_slots.len();
        let mut out = Vec::with_capacity(r.meta.groups.len());
        for (g, (gm, layout)) in r.meta.groups.iter().zip(&r.scene.groups).enumerate() {
            let j = gm.active.len();
            let clustered = |t: &'a super::clustered::CompressedTensor| {
                StageTensor::Clustered(ClusteredTensor {
                    ranks: &t.layout.ranks,
                    factor_at: &t.layout.factor_at,
                    core_at: &t.layout.core_at,
                    rows_at: &t.rows_at,
                    rows: t.rows,
                    vertex_rank: t.layout.vertex_rank,
                    factors: &t.factors,
                    core: &t.core,
                    vertex: &t.vertex,
                })
            };
            let (t1, t2, clusters) = match &layout.compressed {
                Some(c) => (
                    clustered(&c.t1),
                    c.t2.as_ref().map(clustered),
                    Some(c.clusters.as_slice()),
                ),
                None => (
                    StageTensor::Dense(values(names::t1(g))?),
                    if r.meta.reflections >= 3 {
                        Some(StageTensor::Dense(values(names::t2(g))?))
                    } else {
                        None
                    },
                    None,
                ),
            };
            out.push(StageGroup {
                vertices: &layout.vertices,
                rows: layout.rows,
                terms: r.meta.group_t0_terms(gm),
                t0_index: file.tensor(&names::t0_index(g))?.as_u16()?,
                t0_values: values(names::t0_value(g))?,
                t0_open: &layout.t0_open,
                scales: [gm.scale_t0, gm.scale_t1, gm.scale_t2],
                active: &gm.active,
                elements: [j * SH_COUNT, j * n_i],
                channels: r.meta.channels as usize,
                t1,
                t2,
                clusters,
                shading: gm.shading.map(|b| b as usize),
            });
        }
        Ok(out)
    }

    /// The global slots of T2's second reflection (`I`), in its order.
    pub fn t2_slots(&self) -> &'a [u32] {
        &self.r.meta.t2_slots
    }

    /// `Ehat[s]`: the irradiance of SH coefficient `s` over the hemisphere.
    pub fn irradiance_sh(&self) -> [f32; SH_COUNT] {
        self.r.ehat
    }

    /// Shading basis `b`'s hemisphere constants (`None` past the last).
    pub fn shading_constants(&self, b: usize) -> Option<StageConstants<'a>> {
        let c = self.r.constants.get(b)?;
        Some(StageConstants {
            rank: c.rank,
            cwi: &c.cwi,
            cconst: &c.cconst,
        })
    }

    /// The RGB coefficient of every global slot at the current parameters (current for
    /// [`VertexSurface::material_runs`]).
    pub fn slot_coefficients(&self) -> Vec<[f32; 3]> {
        self.r.materials.coefficients().0
    }

    /// The number of textures (base colours and normal maps).
    pub fn textures(&self) -> usize {
        self.r.scene.textures.len()
    }

    /// Texture `t`: `(width, height, texels)`, top row first: linear RGB, or a normal map's
    /// decoded vectors.
    pub fn texture(&self, t: usize) -> Option<(usize, usize, &'a [[f32; 3]])> {
        let tx = self.r.scene.textures.get(t)?;
        Some((tx.width, tx.height, &tx.texels))
    }
}
