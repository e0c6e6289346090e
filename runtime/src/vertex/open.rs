//! Reading and validating a per-vertex bake file (`prt_formats::vertex`): the metadata, every
//! tensor's type and shape against it, index ranges, finiteness of the geometry, the shading
//! bases' tables, textures and the baked environment. What is validated here is what the
//! stages index without further checks. Errors name the tensor (or field) and what is wrong.

use prt_formats::basis::ShadingBasis;
use prt_formats::envmap::LatLongMap;
use prt_formats::lighting::prefilter;
use prt_formats::pixel::Precision;
use prt_formats::vertex::{
    cube_len, names, shading_tables_mut, BakeKind, EnvironmentMeta, VertexBakeMeta, DIRECT_CUBE,
    SH_TERMS, T1_LIGHT_CUBE, T2_LIGHT_CUBE, VISIBILITY_CUBE,
};
use prt_formats::{BakeFile, Dtype};

use super::clustered::{validate_group, CompressedLayout};
use crate::error::RuntimeError;

/// Marks a vertex that belongs to no group.
pub(super) const NO_GROUP: u32 = u32::MAX;

/// A base-colour texture, linear RGB, top row first.
#[derive(Clone, Debug)]
pub(super) struct Texture {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<[f32; 3]>,
}

/// The shape of one group's tensors.
#[derive(Clone, Debug)]
pub(super) struct GroupLayout {
    /// Global vertex indices, ascending.
    pub vertices: Vec<u32>,
    /// T0 rows (`r_i + 1`, or 1).
    pub rows: usize,
    /// Active slots J.
    pub active: usize,
    /// Where T1 and T2 lie when they are stored compressed.
    pub compressed: Option<CompressedLayout>,
    /// Per vertex, whether its irradiance row is the occluded part (subtracted from the open
    /// sky's irradiance); empty before schema 4 (every row the visible part).
    pub t0_open: Vec<bool>,
}

/// Everything of a validated bake besides the big group tensors (read at each stage from the
/// file's memory map).
#[derive(Clone, Debug)]
pub(super) struct Scene {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    pub triangles: Vec<[u32; 3]>,
    pub triangle_material: Vec<u32>,
    /// Per material, its group (every material with a triangle has one).
    pub material_group: Vec<Option<u32>>,
    /// Per global vertex, its group ([`NO_GROUP`] when none) and its index in it.
    pub vertex_group: Vec<(u32, u32)>,
    pub groups: Vec<GroupLayout>,
    /// The shading bases with their tables restored and validated.
    pub shading: Vec<ShadingBasis>,
    pub textures: Vec<Texture>,
    /// The baked environment and its rotation (degrees).
    pub environment: (LatLongMap, f32),
}

/// The storage type the metadata's precision implies.
pub(super) fn stored_dtype(p: Precision) -> Dtype {
    match p {
        Precision::F32 => Dtype::F32,
        Precision::F16 => Dtype::F16,
    }
}

/// Reads and checks everything (see the module documentation).
pub(super) fn validate(file: &BakeFile) -> Result<(VertexBakeMeta, Scene), RuntimeError> {
    let path = file.path().display().to_string();
    let schema = |reason: String| RuntimeError::VertexSchema {
        path: path.clone(),
        reason,
    };
    match BakeKind::of_metadata(file.metadata()) {
        Some(BakeKind::Vertex) => {}
        Some(BakeKind::Pixel) => {
            return Err(RuntimeError::WrongKind {
                path: path.clone(),
                kind: BakeKind::Pixel.describe(),
                expected: BakeKind::Vertex.describe(),
                hint: "open it with prt_runtime::open or PixelRelighter (`relight` chooses \
                       the kind by itself): its light and view are frozen, only materials can \
                       be edited",
            })
        }
        None => {
            return Err(schema(
                "the metadata has neither 'vertex_schema_version' nor \
                 'pixel_schema_version'"
                    .into(),
            ))
        }
    }
    let meta: VertexBakeMeta = serde_json::from_value(file.metadata().clone()).map_err(|e| {
        schema(format!(
            "metadata does not match the per-vertex schema: {e}"
        ))
    })?;
    meta.validate()
        .map_err(|e| schema(format!("metadata: {e}")))?;
    let c = Checker { file, path: &path };

    // Geometry.
    let nv = meta.vertices as usize;
    let nt = meta.triangles as usize;
    let positions = c.vec3(names::POSITIONS, nv)?;
    let normals = c.vec3(names::NORMALS, nv)?;
    let uvs_flat = c.f32s(names::UVS, &[nv, 2])?;
    let uvs: Vec<[f32; 2]> = uvs_flat.chunks_exact(2).map(|u| [u[0], u[1]]).collect();
    if let Some(v) = positions
        .iter()
        .position(|p| !p.iter().all(|x| x.is_finite()))
    {
        return Err(schema(format!(
            "{}: vertex {v} is not finite",
            names::POSITIONS
        )));
    }
    if let Some(v) = normals.iter().position(|n| {
        let len2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
        !(len2.is_finite() && len2 > 1e-12)
    }) {
        return Err(schema(format!(
            "{}: normal {v} is not finite or has zero length",
            names::NORMALS
        )));
    }
    let tri_flat = c.u32s(names::TRIANGLES, &[nt, 3])?;
    let triangles: Vec<[u32; 3]> = tri_flat
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    if let Some((t, i)) = triangles
        .iter()
        .enumerate()
        .find_map(|(t, tri)| tri.iter().find(|&&i| i as usize >= nv).map(|&i| (t, i)))
    {
        return Err(schema(format!(
            "{}: triangle {t} refers to vertex {i}, but there are {nv} vertices",
            names::TRIANGLES
        )));
    }
    let triangle_material = c.u32s(names::TRIANGLE_MATERIAL, &[nt])?.to_vec();
    let nm = meta.materials.len();
    if let Some(t) = triangle_material.iter().position(|&m| m as usize >= nm) {
        return Err(schema(format!(
            "{}: triangle {t} has material {}, but there are {nm} materials",
            names::TRIANGLE_MATERIAL,
            triangle_material[t]
        )));
    }

    // Groups: their vertices, then every tensor's type and shape.
    let mut material_group = vec![None; nm];
    let mut vertex_group = vec![(NO_GROUP, 0u32); nv];
    let mut groups = Vec::with_capacity(meta.groups.len());
    let dtype = stored_dtype(meta.precision);
    let ch = meta.channels as usize;
    for (g, gm) in meta.groups.iter().enumerate() {
        let m = gm.material as usize;
        if let Some(other) = material_group[m] {
            return Err(schema(format!(
                "groups {other} and {g} are both for material {m}"
            )));
        }
        material_group[m] = Some(g as u32);
        let vg = gm.vertices as usize;
        let name = names::vertices(g);
        let vertices = c.u32s(&name, &[vg])?.to_vec();
        if vertices.windows(2).any(|w| w[0] >= w[1]) {
            return Err(schema(format!(
                "{name}: indices are not strictly ascending"
            )));
        }
        for (local, &v) in vertices.iter().enumerate() {
            let Some(slot) = vertex_group.get_mut(v as usize) else {
                return Err(schema(format!(
                    "{name}: vertex {v}, but there are {nv} vertices"
                )));
            };
            if slot.0 != NO_GROUP {
                return Err(schema(format!(
                    "{name}: vertex {v} is also in group {}",
                    slot.0
                )));
            }
            *slot = (g as u32, local as u32);
        }
        let rows = gm.t0_rows as usize;
        let terms = meta.group_t0_terms(gm);
        c.typed(&names::t0_index(g), Dtype::U16, &[vg, rows, terms])?;
        let index = file.tensor(&names::t0_index(g))?.as_u16()?;
        let limit = cube_len(DIRECT_CUBE);
        if let Some(k) = index.iter().position(|&i| i as usize >= limit) {
            return Err(schema(format!(
                "{}: Haar index {} at element {k} is not below {limit}",
                names::t0_index(g),
                index[k]
            )));
        }
        c.typed(&names::t0_value(g), dtype, &[vg, rows, terms])?;
        let t0_open = if meta.has_t0_open() {
            c.typed(&names::t0_open(g), Dtype::U8, &[vg])?;
            let flags = file.tensor(&names::t0_open(g))?.as_u8()?;
            if let Some(k) = flags.iter().position(|&f| f > 1) {
                return Err(schema(format!(
                    "{}: flag {} at vertex {k} is neither 0 nor 1",
                    names::t0_open(g),
                    flags[k]
                )));
            }
            flags.iter().map(|&f| f == 1).collect()
        } else {
            Vec::new()
        };
        // Only a group with a specular lobe needs its visibility; one without stores none
        // (schema 2) or a full one (schema 1).
        let vis = names::visibility(g);
        let full = [vg, cube_len(VISIBILITY_CUBE)];
        if gm.shading.is_some() || file.tensor(&vis)?.shape() != [vg, 0] {
            c.typed(&vis, Dtype::U8, &full)?;
        } else {
            c.typed(&vis, Dtype::U8, &[vg, 0])?;
        }
        let j = gm.active.len();
        let compressed = match &gm.compression {
            Some(comp) => {
                let t1 = (
                    cube_len(T1_LIGHT_CUBE),
                    j * SH_TERMS * ch,
                    comp.t1.vertex_rank,
                );
                let t2 = comp.t2.map(|t2| {
                    (
                        cube_len(T2_LIGHT_CUBE),
                        j * meta.t2_slots.len() * ch,
                        t2.vertex_rank,
                    )
                });
                Some(validate_group(
                    file,
                    g,
                    vg,
                    comp.clusters,
                    dtype,
                    t1,
                    t2,
                    &schema,
                )?)
            }
            None => {
                c.typed(
                    &names::t1(g),
                    dtype,
                    &[vg, cube_len(T1_LIGHT_CUBE), j, SH_TERMS, ch],
                )?;
                if meta.reflections >= 3 {
                    c.typed(
                        &names::t2(g),
                        dtype,
                        &[vg, cube_len(T2_LIGHT_CUBE), j, meta.t2_slots.len(), ch],
                    )?;
                }
                None
            }
        };
        groups.push(GroupLayout {
            vertices,
            rows,
            active: j,
            compressed,
            t0_open,
        });
    }
    // Every triangle's vertices carry the data of its own material.
    for (t, (tri, &m)) in triangles.iter().zip(&triangle_material).enumerate() {
        let Some(g) = material_group[m as usize] else {
            return Err(schema(format!(
                "triangle {t} has material '{}', which has no vertex group",
                meta.materials[m as usize].name
            )));
        };
        if let Some(&v) = tri.iter().find(|&&v| vertex_group[v as usize].0 != g) {
            return Err(schema(format!(
                "triangle {t} (material '{}', group {g}) uses vertex {v}, which is not in \
                 {}",
                meta.materials[m as usize].name,
                names::vertices(g as usize)
            )));
        }
    }

    // Shading bases: tables back from their tensors, then the basis' own checks.
    let mut shading = Vec::with_capacity(meta.shading.len());
    let min_width = prefilter::min_width(DIRECT_CUBE).to_degrees();
    for (b, sm) in meta.shading.iter().enumerate() {
        let mut basis = sm.basis.clone();
        for (table, slot) in shading_tables_mut(&mut basis) {
            let name = names::shading_table(b, table);
            let t = file.tensor(&name)?;
            if t.dtype() != Dtype::F32 || t.shape().len() != 1 {
                return Err(schema(format!(
                    "{name}: {} {:?}, expected a flat f32 table",
                    t.dtype(),
                    t.shape()
                )));
            }
            *slot = t.as_f32()?.to_vec();
        }
        basis
            .validate()
            .map_err(|e| schema(format!("shading basis {b} ({}): {e}", basis.family)))?;
        if let Some(&w) = basis
            .split_widths_deg
            .iter()
            .find(|&&w| w != 0.0 && f64::from(w) < min_width)
        {
            return Err(schema(format!(
                "shading basis {b}: split width {w} degrees is narrower than the \
                 {min_width:.2} degrees a 6x{DIRECT_CUBE}x{DIRECT_CUBE} environment can be \
                 prefiltered at"
            )));
        }
        shading.push(basis);
    }

    // Textures.
    let mut textures = Vec::with_capacity(meta.textures.len());
    for (i, tm) in meta.textures.iter().enumerate() {
        let (w, h) = (tm.width as usize, tm.height as usize);
        let name = names::texture(i);
        let flat = c.f32s(&name, &[h, w, 3])?;
        if let Some(k) = flat.iter().position(|v| !v.is_finite()) {
            return Err(schema(format!("{name}: value {k} is not finite")));
        }
        textures.push(Texture {
            width: w,
            height: h,
            texels: flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        });
    }

    // The baked environment.
    let environment = match meta.environment {
        EnvironmentMeta::Constant { radiance } => {
            let map = LatLongMap::new(1, 1, vec![radiance], 1.0)
                .map_err(|e| schema(format!("environment: constant radiance: {e}")))?
                .0;
            (map, 0.0)
        }
        EnvironmentMeta::LatLong {
            width,
            height,
            rotation_deg,
        } => {
            let (w, h) = (width as usize, height as usize);
            let flat = c.f32s(names::ENVIRONMENT, &[h, w, 3])?;
            let texels = flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
            let map = LatLongMap::new(w, h, texels, 1.0)
                .map_err(|e| schema(format!("{}: {e}", names::ENVIRONMENT)))?
                .0;
            if !rotation_deg.is_finite() {
                return Err(schema(format!(
                    "environment rotation {rotation_deg} is not finite"
                )));
            }
            (map, rotation_deg)
        }
    };

    Ok((
        meta,
        Scene {
            positions,
            normals,
            uvs,
            triangles,
            triangle_material,
            material_group,
            vertex_group,
            groups,
            shading,
            textures,
            environment,
        },
    ))
}

/// Type and shape checks of named tensors, with messages naming them.
struct Checker<'a> {
    file: &'a BakeFile,
    path: &'a str,
}

impl<'a> Checker<'a> {
    fn typed(&self, name: &str, dtype: Dtype, shape: &[usize]) -> Result<(), RuntimeError> {
        let t = self.file.tensor(name)?;
        if t.dtype() != dtype {
            return Err(RuntimeError::VertexSchema {
                path: self.path.to_string(),
                reason: format!(
                    "{name}: stored as {}, expected {} (the metadata's precision and the \
                     schema)",
                    t.dtype(),
                    dtype
                ),
            });
        }
        if t.shape() != shape {
            return Err(RuntimeError::VertexSchema {
                path: self.path.to_string(),
                reason: format!(
                    "{name}: shape {:?}, expected {shape:?} from the metadata",
                    t.shape()
                ),
            });
        }
        Ok(())
    }

    fn f32s(&self, name: &str, shape: &[usize]) -> Result<&'a [f32], RuntimeError> {
        self.typed(name, Dtype::F32, shape)?;
        Ok(self.file.tensor(name)?.as_f32()?)
    }

    fn u32s(&self, name: &str, shape: &[usize]) -> Result<&'a [u32], RuntimeError> {
        self.typed(name, Dtype::U32, shape)?;
        Ok(self.file.tensor(name)?.as_u32()?)
    }

    fn vec3(&self, name: &str, n: usize) -> Result<Vec<[f32; 3]>, RuntimeError> {
        let flat = self.f32s(name, &[n, 3])?;
        Ok(flat.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect())
    }
}
