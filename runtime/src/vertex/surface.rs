//! What a GPU backend reads of a per-vertex relighter (feature `gpu-surface`; docs/gpu.md):
//! the results of the light and material stages, run here on the CPU, and the per-frame
//! inputs of the view stage, which the backend runs itself (rasterization and the per-pixel
//! last reflection). Read-only views of the relighter's own state: nothing is copied, and the
//! stages' run counters tell the backend when to upload a result again.

use prt_formats::basis::ShadingBasis;
use prt_formats::envmap::LatLongMap;
use prt_formats::lighting::sh::SH_BANDS;
use prt_formats::lighting::CubeMap;
use prt_formats::view::CameraFrame;

use super::incident::{E_AT, I1_AT, I2_AT, U_AT};
use super::shade::Prefiltered;
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
    /// Which of [`VertexSurface::prefiltered`] its `Ibar_w` is read from; `None` for width 0,
    /// which reads the environment map itself.
    pub prefiltered: Option<usize>,
    /// The normalized Gaussian's SH factor per band, applied to `I1`.
    pub sh_factors: [f32; SH_BANDS],
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
        let (_, light_s, material_s) = self.prepare_frame()?;
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
            prefiltered: match w.lookup {
                Prefiltered::Environment => None,
                Prefiltered::Cube(i) => Some(i),
            },
            sh_factors: w.sh_factors,
        })
    }

    /// The environment's prefiltered cubes (per nonzero split width), of the map **unturned**:
    /// a renderer reads them at `R_y(-rotation) d` for a world direction `d`.
    pub fn prefiltered(&self) -> &'a [CubeMap] {
        match &self.r.light {
            Some(l) => &l.coefficients.prefiltered,
            None => &[],
        }
    }

    /// The open sky's irradiance per normal of the light **turned** (read at world normals),
    /// when the bake has a normal map or open-sky irradiance rows: a pixel of a normal-mapped
    /// material scales its irradiance by this at the bent normal over this at the
    /// interpolated one.
    pub fn open_sky(&self) -> Option<&'a CubeMap> {
        self.r.light.as_ref()?.coefficients.open_sky.as_ref()
    }

    /// The map that lights the scene (intensity applied), unturned.
    pub fn environment(&self) -> &'a LatLongMap {
        self.r.lighting_map()
    }

    /// The environment's rotation about +Y in degrees: radiance from world direction `d` is
    /// the map's from `R_y(-rotation) d`.
    pub fn environment_rotation(&self) -> f32 {
        self.r.rotation_deg
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
