//! The per-vertex bake schema (docs/vertex.md, docs/format.md "Vertex schema"): what the
//! baker writes and the runtime reads for the per-vertex mode (thesis ch. 5), and the
//! conventions both must share bit for bit: the vertex frame, the light bins, the meaning and
//! layout of every tensor.
//!
//! Per vertex x (normal n, frame [`vertex_frame`]) of material group g, the light arriving at
//! x is split by the number of reflections it made on the way (docs/vertex.md, section 1):
//!
//! - **T0** (direct, 5-7): for each row k (the `r_i` incident functions `U^i(., k)` of the
//!   material's shading basis, then one row for the irradiance), the function
//!   `T0~_k(w) = U^i(w_local, k) (w . n)+ V(w)` sampled at the centres of the
//!   [`DIRECT_CUBE`]-sized cube map's texels, area-weighted-Haar transformed
//!   (`lighting::HaarCube`), its largest coefficients kept (index u16, value; the group's
//!   [`VertexBakeMeta::group_t0_terms`] of them).
//!   `sum_t C0[index_t] value_t` is then `integral L T0~_k dw` for a light whose Haar
//!   coefficients are C0. Rows: `[U^i rows..., irradiance]`; a diffuse material has only the
//!   irradiance row. Padding terms have index 0 and value 0. From schema 4 a vertex's
//!   irradiance row may instead hold its occluded part `(w . n)+ (1 - V(w))` (its flag in
//!   [`names::t0_open`] is 1): the irradiance is then the open sky's at the vertex normal
//!   ([`crate::lighting::irradiance::irradiance_table`] of the light's cube, read bilinearly)
//!   minus the sparse dot.
//! - **Visibility**: per vertex, the visible fraction of each texel of a
//!   [`VISIBILITY_CUBE`]-sized cube map (u8, 255 = fully visible; texels below the tangent
//!   plane are 0), for the specular lobes' direct part.
//! - **T1** (one reflection, 5-8): `T1[l][j][s]`: the incident radiance at x after one
//!   reflection off slot j (global slot `active[j]`), for **unit radiance from light bin l**
//!   (texel l of a [`T1_LIGHT_CUBE`]-sized cube map) and zero elsewhere, projected onto the
//!   real SH basis of order 4 (`lighting::sh_eval`) **in the vertex frame**:
//!   `I1_s = integral over x's upper hemisphere of I1(w) Y_s(w_local) dw`.
//! - **T2** (two reflections, 5-10): `T2[l][j][i]`: the uniform radiance with the same
//!   irradiance, `(1/pi) integral I2(w) (w . n)+ dw`, of the light that left bin l (of a
//!   [`T2_LIGHT_CUBE`]-sized cube) and reflected off slot i (global slot `t2_slots[i]`) and then
//!   off slot j (global `active[j]`, the reflection nearer to x).
//!
//! With the RGB slot coefficients c (`pixel::slot_coefficients`) and light coefficients C1,
//! C2 (each bin's mean radiance), the runtime forms `I1_s = sum_j c_j sum_l C1[l] T1[l][j][s]`
//! and `I2 = sum_(j,i) c_j c_i sum_l C2[l] T2[l][j][i]`. Stored tensor values are the true
//! values divided by the group's scale (`VertexGroupMeta::scale_*`).
//!
//! Tensors are gray (`channels` = 1) unless a base-colour texture is baked into a slot at an
//! earlier reflection (then RGB, `channels` = 3, the last index).

use serde::{Deserialize, Serialize};

use crate::basis::ShadingBasis;
use crate::clustered::{CompressionSettings, GroupCompression};
use crate::family::Family;
use crate::pixel::{BasisMeta, MaterialMeta, Precision};

/// Version of the per-vertex schema (inside the container's own schema version). Version 2
/// added compressed T1 and T2 ([`crate::clustered`]); version 3 a per-group count of T0 terms
/// ([`VertexGroupMeta::t0_terms`]) and clusters chosen from the error target
/// ([`CompressionSettings::cluster_vertices`] absent); version 4 the open-sky flags of the
/// irradiance rows ([`names::t0_open`]; without them every row is the visible part); version 5
/// materials' normal maps ([`VertexBakeMeta::material_normal_maps`]). Versions 1 to 4 are still
/// read.
pub const VERTEX_SCHEMA_VERSION: u32 = 5;
/// The oldest per-vertex schema version this build reads.
pub const OLDEST_VERTEX_SCHEMA_VERSION: u32 = 1;

/// Face size of the cube map of T0 (direct light, Haar): 6 x 64 x 64 texels.
pub const DIRECT_CUBE: usize = 64;
/// Face size of the light bins of T1: 6 x 8 x 8 = 384 bins.
pub const T1_LIGHT_CUBE: usize = 8;
/// Face size of the light bins of T2: 6 x 2 x 2 = 24 bins.
pub const T2_LIGHT_CUBE: usize = 2;
/// Face size of the stored visibility: 6 x 16 x 16 texels.
pub const VISIBILITY_CUBE: usize = 16;
/// Default number of Haar terms kept per T0 row (the thesis' choice is in this range).
pub const DEFAULT_T0_TERMS: usize = 96;
/// Number of SH coefficients of T1 (order 4).
pub const SH_TERMS: usize = crate::lighting::sh::SH_COUNT;

/// Number of texels (bins) of a cube map with faces of `size`.
pub const fn cube_len(size: usize) -> usize {
    6 * size * size
}

/// The bake's kind, read from a container's metadata: which schema it follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BakeKind {
    /// A per-pixel bake (`pixel::PixelBakeMeta`).
    Pixel,
    /// A per-vertex bake ([`VertexBakeMeta`]).
    Vertex,
}

impl BakeKind {
    /// The kind of a bake from its metadata, by its schema-version key; None when neither.
    pub fn of_metadata(metadata: &serde_json::Value) -> Option<BakeKind> {
        if metadata.get("vertex_schema_version").is_some() {
            Some(BakeKind::Vertex)
        } else if metadata.get("pixel_schema_version").is_some() {
            Some(BakeKind::Pixel)
        } else {
            None
        }
    }

    /// "per-pixel" or "per-vertex", for messages.
    pub fn describe(self) -> &'static str {
        match self {
            BakeKind::Pixel => "per-pixel",
            BakeKind::Vertex => "per-vertex",
        }
    }
}

/// The orthonormal tangent frame `(t, b)` of a vertex or shading point with unit normal `n`,
/// such that `(t, b, n)` is right-handed. Every per-vertex quantity that depends on azimuth
/// (T0's `U^i` rows, T1's SH) is in this frame, and the runtime interpolates them across
/// triangles, so the frame must vary smoothly with `n`: it is built from a fixed reference
/// axis `A` (not a coordinate axis, so that floors and walls are far from it) as
/// `t = normalize(A x n)`, and from a second axis near `A` where `n` is within about 8 degrees
/// of `+-A` (a discontinuity confined to two small caps).
pub fn vertex_frame(n: [f32; 3]) -> ([f32; 3], [f32; 3]) {
    // normalize(1, 3, 7) and normalize(7, 1, -3): directions no scene axis is built along.
    const A: [f32; 3] = [0.130_188_91, 0.390_566_73, 0.911_322_4];
    const B: [f32; 3] = [0.911_322_4, 0.130_188_91, -0.390_566_73];
    let cross = |a: [f32; 3], b: [f32; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let mut t = cross(A, n);
    let mut len2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
    if len2 < 0.02 {
        t = cross(B, n);
        len2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
    }
    let inv = 1.0 / len2.sqrt();
    let t = [t[0] * inv, t[1] * inv, t[2] * inv];
    let b = cross(n, t);
    (t, b)
}

/// `d` in the frame `(t, b, n)`.
#[inline]
pub fn to_local(t: [f32; 3], b: [f32; 3], n: [f32; 3], d: [f32; 3]) -> [f32; 3] {
    let dot = |a: [f32; 3]| a[0] * d[0] + a[1] * d[1] + a[2] * d[2];
    [dot(t), dot(b), dot(n)]
}

/// The environment the scene was baked with (the runtime's default light).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum EnvironmentMeta {
    /// Constant radiance from every direction.
    Constant {
        /// Linear RGB radiance.
        radiance: [f32; 3],
    },
    /// A lat-long map (`latlong` convention), intensity applied, stored as the tensor
    /// [`names::ENVIRONMENT`] `[height, width, 3]` f32.
    LatLong {
        /// Map width in texels.
        width: u32,
        /// Map height in texels.
        height: u32,
        /// Rotation about +Y in degrees (`lighting::rotation_y`'s right-hand rule).
        rotation_deg: f32,
    },
}

/// A texture of a material, stored as [`names::texture`] `[height, width, 3]` f32, top row
/// first, sampled by [`crate::texture::sample_bilinear`]: linear RGB for a base colour, the
/// decoded tangent-space vectors ([`crate::normal_map::decode_texel`]) for a normal map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TextureMeta {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
}

/// The vertices of one material (object) and their tensors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VertexGroupMeta {
    /// Index of the material into [`VertexBakeMeta::materials`].
    pub material: u32,
    /// Number of vertices in the group (the first dimension of its tensors).
    pub vertices: u32,
    /// Rows of T0: the shading basis' `r_i` plus one (irradiance), or 1 for a material
    /// without a lobe.
    pub t0_rows: u32,
    /// Index into [`VertexBakeMeta::shading`] of the material's shading basis (materials
    /// with a specular lobe).
    pub shading: Option<u32>,
    /// Global slots that carry light into the group after one reflection (j of T1 and T2),
    /// ascending. Slots of objects the group's vertices never see are left out.
    pub active: Vec<u32>,
    /// Stored T0 value = true value / `scale_t0` (1 for f32 storage).
    pub scale_t0: f32,
    /// Stored T1 value = true value / `scale_t1`.
    pub scale_t1: f32,
    /// Stored T2 value = true value / `scale_t2`.
    pub scale_t2: f32,
    /// T1 and T2 stored compressed (clustered Tucker, [`crate::clustered`]; the scales then
    /// apply to the cores), or dense when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compression: Option<GroupCompression>,
    /// Haar terms stored per T0 row of this group, 1 ..= the bake's
    /// [`VertexBakeMeta::t0_terms`] (the group's T0 tensors are `[vertices, t0_rows, this]`);
    /// absent: the bake's (schema 1 and 2 files, and uncompressed bakes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t0_terms: Option<u32>,
}

/// A family's Tucker shading basis as stored: the [`ShadingBasis`] with its tables emptied
/// (they are the tensors [`names::shading_table`]; [`shading_tables`] lists them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShadingMeta {
    /// The basis without its tables.
    pub basis: ShadingBasis,
}

/// What a per-vertex bake did, as a function of its inputs alone (never timings).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VertexBakeStats {
    /// Rays traced.
    pub rays: u64,
    /// Why each material got the slots it has, and the tensors' channel count.
    pub allocation: Vec<String>,
    /// Per group, the relative L2 error of T0 rows from keeping the group's Haar terms
    /// ([`VertexBakeMeta::group_t0_terms`]; `||row - kept|| / ||row||` over the group, all
    /// rows).
    pub t0_truncation_error: Vec<f32>,
}

/// Everything the runtime needs besides the tensors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VertexBakeMeta {
    /// [`VERTEX_SCHEMA_VERSION`] of the writer; readers reject other versions.
    pub vertex_schema_version: u32,
    /// Number of mesh vertices ([`names::POSITIONS`] rows).
    pub vertices: u32,
    /// Number of triangles ([`names::TRIANGLES`] rows).
    pub triangles: u32,
    /// Directions traced from each vertex for T1 and T2 (N1).
    pub samples: u32,
    /// Directions sampled at each first hit (N2).
    pub secondary: u32,
    /// T1 also drew one direction in every light bin per first hit, combined with the N2
    /// BRDF directions by multiple importance sampling (false in files written before the
    /// option existed).
    #[serde(default)]
    pub light_bins: bool,
    /// Reflections modelled: 2 stores T0 and T1 (one reflection before the last), 3 adds T2.
    pub reflections: u32,
    /// The seed of the random streams.
    pub seed: u64,
    /// 1 (gray tensors) or 3 (RGB, a texture baked into a slot).
    pub channels: u32,
    /// Storage of T0 values, T1 and T2 (stored as "f32" or "f16").
    pub precision: Precision,
    /// Haar terms kept per T0 row by the trace: the most a group stores (a group may store
    /// fewer, [`VertexGroupMeta::t0_terms`]).
    pub t0_terms: u32,
    /// Every material of the scene, in scene order (slots numbered globally across them).
    pub materials: Vec<MaterialMeta>,
    /// The PCA bases of the editable glossy families (slots of earlier reflections).
    pub bases: Vec<BasisMeta>,
    /// The Tucker shading bases of every family with a lobe used by a group (the last
    /// reflection).
    pub shading: Vec<ShadingMeta>,
    /// Base-colour textures; `material_textures[m]` indexes them.
    pub textures: Vec<TextureMeta>,
    /// Per material, its base-colour texture (applied per pixel at the last reflection).
    pub material_textures: Vec<Option<u32>>,
    /// Per material, its normal map (index into `textures`), which bends the shading normal
    /// of the last reflection per pixel ([`crate::normal_map`]); empty when no material has
    /// one (and in files before schema 5).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub material_normal_maps: Vec<Option<u32>>,
    /// Global slots of the first reflection from the light in T2 (i), ascending.
    pub t2_slots: Vec<u32>,
    /// One group per material with vertices.
    pub groups: Vec<VertexGroupMeta>,
    /// The light the scene was baked with.
    pub environment: EnvironmentMeta,
    /// The scene's camera (the runtime's default view).
    pub camera: crate::pixel::CameraMeta,
    /// Figures of the bake that depend only on its inputs.
    pub stats: VertexBakeStats,
    /// The settings T1 and T2 were compressed with (absent: stored dense).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compression: Option<CompressionSettings>,
}

impl VertexBakeMeta {
    /// Whether the groups store open-sky flags ([`names::t0_open`]; schema 4 on).
    pub fn has_t0_open(&self) -> bool {
        self.vertex_schema_version >= 4
    }

    /// Haar terms stored per T0 row of group `g`: its own count, or the bake's.
    pub fn group_t0_terms(&self, g: &VertexGroupMeta) -> usize {
        g.t0_terms.unwrap_or(self.t0_terms) as usize
    }

    /// Values per vertex of group `g`'s T1 (`384 x J x 16 x channels`).
    pub fn t1_row_len(&self, g: &VertexGroupMeta) -> usize {
        cube_len(T1_LIGHT_CUBE) * g.active.len() * SH_TERMS * self.channels as usize
    }

    /// Values per vertex of group `g`'s T2 (`24 x J x I x channels`; 0 when `reflections` < 3).
    pub fn t2_row_len(&self, g: &VertexGroupMeta) -> usize {
        if self.reflections < 3 {
            return 0;
        }
        cube_len(T2_LIGHT_CUBE) * g.active.len() * self.t2_slots.len() * self.channels as usize
    }

    /// Checks what the tensors' shapes cannot: versions, index ranges, which shading basis
    /// each group uses. (The shading bases themselves are checked with
    /// `ShadingBasis::validate` once their tables are read back.)
    pub fn validate(&self) -> Result<(), String> {
        if !(OLDEST_VERTEX_SCHEMA_VERSION..=VERTEX_SCHEMA_VERSION)
            .contains(&self.vertex_schema_version)
        {
            return Err(format!(
                "vertex schema version {} (this build reads {OLDEST_VERTEX_SCHEMA_VERSION} to \
                 {VERTEX_SCHEMA_VERSION})",
                self.vertex_schema_version
            ));
        }
        if !(2..=3).contains(&self.reflections) {
            return Err(format!("reflections = {} (2 or 3)", self.reflections));
        }
        if self.channels != 1 && self.channels != 3 {
            return Err(format!("channels = {} (1 or 3)", self.channels));
        }
        if self.t0_terms == 0 || self.t0_terms as usize > cube_len(DIRECT_CUBE) {
            return Err(format!("t0_terms = {}", self.t0_terms));
        }
        let total_slots: u32 = self.materials.iter().map(|m| m.slots.len() as u32).sum();
        if self.material_textures.len() != self.materials.len() {
            return Err("material_textures does not have one entry per material".into());
        }
        if !self.material_normal_maps.is_empty()
            && self.material_normal_maps.len() != self.materials.len()
        {
            return Err("material_normal_maps does not have one entry per material".into());
        }
        for (what, list) in [
            ("texture", &self.material_textures),
            ("normal map", &self.material_normal_maps),
        ] {
            if let Some(t) = list
                .iter()
                .flatten()
                .find(|&&t| t as usize >= self.textures.len())
            {
                return Err(format!("material {what} {t} out of range"));
            }
        }
        let sorted = |v: &[u32]| v.windows(2).all(|w| w[0] < w[1]);
        if !sorted(&self.t2_slots) || self.t2_slots.iter().any(|&j| j >= total_slots) {
            return Err("t2_slots not ascending global slots".into());
        }
        for (gi, g) in self.groups.iter().enumerate() {
            let Some(m) = self.materials.get(g.material as usize) else {
                return Err(format!("group {gi}: material {} out of range", g.material));
            };
            if !sorted(&g.active) || g.active.iter().any(|&j| j >= total_slots) {
                return Err(format!(
                    "group {gi}: active slots not ascending global slots"
                ));
            }
            let expect_rows = match g.shading {
                Some(s) => {
                    let Some(sb) = self.shading.get(s as usize) else {
                        return Err(format!("group {gi}: shading basis {s} out of range"));
                    };
                    if sb.basis.family != m.family {
                        return Err(format!(
                            "group {gi}: shading basis is {} but the material is {}",
                            sb.basis.family, m.family
                        ));
                    }
                    sb.basis.ranks.i as u32 + 1
                }
                None => 1,
            };
            if g.t0_rows != expect_rows {
                return Err(format!(
                    "group {gi}: {} T0 rows, expected {expect_rows}",
                    g.t0_rows
                ));
            }
            if m.family != Family::Diffuse && g.shading.is_none() {
                return Err(format!(
                    "group {gi}: {} material without a shading basis",
                    m.family
                ));
            }
            if let Some(k) = g.t0_terms {
                if k == 0 || k > self.t0_terms {
                    return Err(format!(
                        "group {gi}: t0_terms = {k}, not in 1 ..= the bake's t0_terms {}",
                        self.t0_terms
                    ));
                }
            }
            if let Some(c) = &g.compression {
                if c.clusters == 0 && g.vertices > 0 {
                    return Err(format!("group {gi}: compressed with 0 clusters"));
                }
                if c.clusters > g.vertices {
                    return Err(format!(
                        "group {gi}: {} clusters for {} vertices",
                        c.clusters, g.vertices
                    ));
                }
                if c.t2.is_some() != (self.reflections >= 3) {
                    return Err(format!(
                        "group {gi}: compressed T2 present = {}, but reflections = {}",
                        c.t2.is_some(),
                        self.reflections
                    ));
                }
            }
            for s in [g.scale_t0, g.scale_t1, g.scale_t2] {
                if !(s.is_finite() && s > 0.0) {
                    return Err(format!("group {gi}: scale {s} is not finite and positive"));
                }
            }
        }
        Ok(())
    }
}

/// The tables of a shading basis by name, in a fixed order (the writer stores each as
/// [`names::shading_table`]; the reader puts them back with [`shading_tables_mut`]).
pub fn shading_tables(b: &ShadingBasis) -> [(&'static str, &[f32]); 8] {
    [
        ("u_h", &b.u_h),
        ("u_o", &b.u_o),
        ("u_o_pole", &b.u_o_pole),
        ("u_i", &b.u_i),
        ("u_i_pole", &b.u_i_pole),
        ("core", &b.core),
        ("reflectances", &b.reflectances),
        ("reflectances_pole", &b.reflectances_pole),
    ]
}

/// As [`shading_tables`], mutable (to fill a basis read from metadata).
pub fn shading_tables_mut(b: &mut ShadingBasis) -> [(&'static str, &mut Vec<f32>); 8] {
    [
        ("u_h", &mut b.u_h),
        ("u_o", &mut b.u_o),
        ("u_o_pole", &mut b.u_o_pole),
        ("u_i", &mut b.u_i),
        ("u_i_pole", &mut b.u_i_pole),
        ("core", &mut b.core),
        ("reflectances", &mut b.reflectances),
        ("reflectances_pole", &mut b.reflectances_pole),
    ]
}

/// Tensor names of the per-vertex schema: the one place the baker and the runtime take them
/// from. Group tensors have the group's vertex count as their first dimension.
pub mod names {
    /// Vertex positions, world space, `[vertices, 3]` f32.
    pub const POSITIONS: &str = "mesh.positions";
    /// Unit vertex normals (the side the vertex's data is for), `[vertices, 3]` f32.
    pub const NORMALS: &str = "mesh.normals";
    /// Vertex texture coordinates, `[vertices, 2]` f32.
    pub const UVS: &str = "mesh.uvs";
    /// Triangles as vertex indices, `[triangles, 3]` u32.
    pub const TRIANGLES: &str = "mesh.triangles";
    /// Material of each triangle, `[triangles]` u32.
    pub const TRIANGLE_MATERIAL: &str = "mesh.triangle_material";
    /// The baked lat-long environment, `[height, width, 3]` f32 (when the scene has one).
    pub const ENVIRONMENT: &str = "environment";
    /// Group `g`'s global vertex indices, ascending, `[vertices_g]` u32.
    pub fn vertices(g: usize) -> String {
        format!("v{g}.vertices")
    }
    /// Group `g`'s T0 Haar indices, `[vertices_g, t0_rows, t0_terms_g]` u16 (`t0_terms_g`:
    /// `VertexBakeMeta::group_t0_terms`).
    pub fn t0_index(g: usize) -> String {
        format!("v{g}.t0.index")
    }
    /// Group `g`'s T0 Haar values, `[vertices_g, t0_rows, t0_terms_g]` f32 or f16.
    pub fn t0_value(g: usize) -> String {
        format!("v{g}.t0.value")
    }
    /// Group `g`'s open-sky flags, `[vertices_g]` u8 (schema 4 on): 1 where the vertex's
    /// irradiance row (T0's last) holds the occluded part `(w . n)+ (1 - V)`, to be
    /// subtracted from the open sky's irradiance at the vertex normal
    /// ([`crate::lighting::irradiance`]); 0 where it holds the visible part `(w . n) V`.
    pub fn t0_open(g: usize) -> String {
        format!("v{g}.t0.open")
    }

    /// Group `g`'s visibility, `[vertices_g, 6 * 16 * 16]` u8.
    pub fn visibility(g: usize) -> String {
        format!("v{g}.visibility")
    }
    /// Group `g`'s T1, `[vertices_g, 384, J, 16, channels]` f32 or f16.
    pub fn t1(g: usize) -> String {
        format!("v{g}.t1")
    }
    /// Group `g`'s T2, `[vertices_g, 24, J, I, channels]` f32 or f16 (reflections = 3).
    pub fn t2(g: usize) -> String {
        format!("v{g}.t2")
    }
    /// Group `g`'s cluster of each vertex when T1 (and T2) are compressed, `[vertices_g]` u32
    /// (`crate::clustered`).
    pub fn clusters(g: usize) -> String {
        format!("v{g}.clusters")
    }
    /// The compressed tensor `tensor` ("t1" or "t2") of group `g`: its part `part`, one of
    /// [`TUCKER_RANKS`] (`[K, 3]` u32), [`TUCKER_FACTORS`] and [`TUCKER_CORE`] (flat, f32 or
    /// f16) and [`TUCKER_VERTEX`] (`[vertices_g, B]`, f32 or f16); layout in
    /// `crate::clustered`.
    pub fn tucker(g: usize, tensor: &str, part: &str) -> String {
        format!("v{g}.{tensor}.{part}")
    }
    /// T1's name in [`tucker`].
    pub const T1: &str = "t1";
    /// T2's name in [`tucker`].
    pub const T2: &str = "t2";
    /// Per-cluster ranks `(a, r, b)`.
    pub const TUCKER_RANKS: &str = "ranks";
    /// Light and element factors, cluster after cluster.
    pub const TUCKER_FACTORS: &str = "factors";
    /// Cores, cluster after cluster.
    pub const TUCKER_CORE: &str = "core";
    /// Each vertex's row of its cluster's vertex factor.
    pub const TUCKER_VERTEX: &str = "vertex";
    /// Table `table` of shading basis `b`, f32 (flat).
    pub fn shading_table(b: usize, table: &str) -> String {
        format!("shading.{b}.{table}")
    }
    /// Texture `t`, `[height, width, 3]` f32.
    pub fn texture(t: usize) -> String {
        format!("texture.{t}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    #[test]
    fn vertex_frame_is_orthonormal_right_handed_and_smooth() {
        let mut worst_jump = 0.0f32;
        for i in 0..2000 {
            let u = (i as f32 + 0.5) / 2000.0;
            let z = 1.0 - 2.0 * u;
            let phi = i as f32 * 2.399_963;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let n = [r * phi.cos(), z, r * phi.sin()];
            let (t, b) = vertex_frame(n);
            assert!((dot(t, t) - 1.0).abs() < 1e-5 && (dot(b, b) - 1.0).abs() < 1e-5);
            assert!(dot(t, n).abs() < 1e-5 && dot(b, n).abs() < 1e-5 && dot(t, b).abs() < 1e-5);
            // Right-handed: t x b = n.
            let c = [
                t[1] * b[2] - t[2] * b[1],
                t[2] * b[0] - t[0] * b[2],
                t[0] * b[1] - t[1] * b[0],
            ];
            assert!(dot(c, n) > 0.9999, "t x b != n at {n:?}");
            // Smoothness: a small turn of the normal turns the tangent by a small angle
            // (away from the two caps about +-A).
            let eps = 1e-3f32;
            let m = [n[0] + eps, n[1], n[2]];
            let len = dot(m, m).sqrt();
            let m = [m[0] / len, m[1] / len, m[2] / len];
            let (t2, _) = vertex_frame(m);
            let a = [0.130_188_91, 0.390_566_73, 0.911_322_4];
            if dot(n, a).abs() < 0.98 {
                let jump = 1.0 - dot(t, t2);
                worst_jump = worst_jump.max(jump);
            }
        }
        assert!(worst_jump < 1e-3, "tangent jumps by 1 - cos = {worst_jump}");
        // The floor and the walls get a regular frame.
        for n in [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]] {
            let (t, b) = vertex_frame(n);
            assert!(t.iter().chain(&b).all(|v| v.is_finite()));
        }
    }

    #[test]
    fn bake_kind_reads_the_schema_key() {
        let v = serde_json::json!({"vertex_schema_version": 1});
        let p = serde_json::json!({"pixel_schema_version": 1});
        assert_eq!(BakeKind::of_metadata(&v), Some(BakeKind::Vertex));
        assert_eq!(BakeKind::of_metadata(&p), Some(BakeKind::Pixel));
        assert_eq!(BakeKind::of_metadata(&serde_json::json!({})), None);
    }
}
