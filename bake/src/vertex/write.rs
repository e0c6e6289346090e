//! Storage precision (f16 with a per-group, per-tensor scale, or f32) and the per-vertex bake
//! file (`prt_formats::vertex::names`, docs/format.md "Vertex schema"), written atomically.

use half::f16;
use prt_formats::pixel::Precision;
use prt_formats::vertex::{
    cube_len, names, shading_tables, SH_TERMS, T1_LIGHT_CUBE, T2_LIGHT_CUBE,
};
use prt_formats::{BakeWriter, FormatError};

use crate::pixel::{add_basis_tables, to_f16_scaled};

use super::error::VertexError;
use super::VertexBake;

/// Tensor values in their storage type.
#[derive(Clone, Debug, PartialEq)]
pub enum Stored {
    /// 32-bit floats (scale 1).
    F32(Vec<f32>),
    /// 16-bit floats, true value = stored x the group's scale.
    F16(Vec<f16>),
}

impl Stored {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            Stored::F32(v) => v.len(),
            Stored::F16(v) => v.len(),
        }
    }

    /// Whether there are no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The stored values as f32 (not multiplied by the scale).
    pub fn to_f32(&self) -> Vec<f32> {
        match self {
            Stored::F32(v) => v.clone(),
            Stored::F16(v) => v.iter().map(|h| h.to_f32()).collect(),
        }
    }
}

/// A compressed tensor in its storage precision (the core scaled, the factors not).
#[derive(Clone, Debug, PartialEq)]
pub struct StoredTucker {
    /// `[K, 3]` `(a, r, b)`.
    pub ranks: Vec<u32>,
    /// Light and element factors, cluster after cluster.
    pub factors: Stored,
    /// Cores, cluster after cluster, divided by the scale.
    pub core: Stored,
    /// `[V, B]`.
    pub vertex: Stored,
    /// B, the width of `vertex`.
    pub vertex_rank: usize,
}

/// Converts values to their storage: f32 as they are (scale 1), or f16 with the per-pixel
/// writer's rule (the largest magnitude maps to 2^14, [`to_f16_scaled`]). Returns the stored
/// values and the scale (true value = stored x scale).
pub(crate) fn store(values: Vec<f32>, precision: Precision) -> (Stored, f32) {
    match precision {
        Precision::F32 => (Stored::F32(values), 1.0),
        Precision::F16 => {
            let (h, scale) = to_f16_scaled(&values);
            (Stored::F16(h), scale)
        }
    }
}

/// Values whose magnitude is at most 1 (orthonormal factors) in their storage type, unscaled:
/// f16 keeps its full relative precision there.
pub(crate) fn store_unscaled(values: Vec<f32>, precision: Precision) -> Stored {
    match precision {
        Precision::F32 => Stored::F32(values),
        Precision::F16 => Stored::F16(values.iter().map(|&v| f16::from_f32(v)).collect()),
    }
}

fn add_stored<'a>(
    w: &mut BakeWriter<'a>,
    name: &str,
    shape: &[usize],
    data: &'a Stored,
) -> Result<(), FormatError> {
    match data {
        Stored::F32(v) => w.add_f32(name, shape, v),
        Stored::F16(v) => w.add_f16(name, shape, v),
    }
}

/// Writes the bake file atomically (nothing is written on failure); returns its size in
/// bytes.
pub fn write_vertex_file(bake: &VertexBake, path: &std::path::Path) -> Result<u64, VertexError> {
    let err = |source: FormatError| VertexError::Write {
        path: path.to_path_buf(),
        source: Box::new(source),
    };
    let w = writer(bake).map_err(err)?;
    let size = w.file_len().map_err(err)?;
    w.write_atomic(path).map_err(err)?;
    Ok(size)
}

/// The bake file's bytes (what [`write_vertex_file`] writes), for tests and in-memory use.
pub fn vertex_file_bytes(bake: &VertexBake) -> Result<Vec<u8>, FormatError> {
    writer(bake)?.to_bytes()
}

/// Lays out every tensor and the metadata (borrowing the bake's buffers).
fn writer(bake: &VertexBake) -> Result<BakeWriter<'_>, FormatError> {
    let meta = &bake.meta;
    let mut w = BakeWriter::new();
    let (nv, nt) = (meta.vertices as usize, meta.triangles as usize);
    let m = &bake.mesh;
    w.add_f32(names::POSITIONS, &[nv, 3], &m.positions)?;
    w.add_f32(names::NORMALS, &[nv, 3], &m.normals)?;
    w.add_f32(names::UVS, &[nv, 2], &m.uvs)?;
    w.add_u32(names::TRIANGLES, &[nt, 3], &m.triangles)?;
    w.add_u32(names::TRIANGLE_MATERIAL, &[nt], &m.triangle_material)?;
    if let prt_formats::vertex::EnvironmentMeta::LatLong { width, height, .. } = meta.environment {
        w.add_f32(
            names::ENVIRONMENT,
            &[height as usize, width as usize, 3],
            &bake.environment,
        )?;
    }
    let c = meta.channels as usize;
    let i_n = meta.t2_slots.len();
    for (g, (data, gm)) in bake.groups.iter().zip(&meta.groups).enumerate() {
        let v = gm.vertices as usize;
        let (rows, terms) = (gm.t0_rows as usize, meta.group_t0_terms(gm));
        let j = gm.active.len();
        w.add_u32(&names::vertices(g), &[v], &data.vertices)?;
        w.add_u16(&names::t0_index(g), &[v, rows, terms], &data.t0_index)?;
        add_stored(
            &mut w,
            &names::t0_value(g),
            &[v, rows, terms],
            &data.t0_value,
        )?;
        w.add_u8(
            &names::visibility(g),
            &[v, data.visibility.len().checked_div(v).unwrap_or(0)],
            &data.visibility,
        )?;
        if let Some(comp) = &data.compressed {
            w.add_u32(&names::clusters(g), &[v], &comp.clusters)?;
            add_tucker(&mut w, g, names::T1, v, &comp.t1)?;
            if let Some(t2) = &comp.t2 {
                add_tucker(&mut w, g, names::T2, v, t2)?;
            }
            continue;
        }
        add_stored(
            &mut w,
            &names::t1(g),
            &[v, cube_len(T1_LIGHT_CUBE), j, SH_TERMS, c],
            &data.t1,
        )?;
        if meta.reflections >= 3 {
            add_stored(
                &mut w,
                &names::t2(g),
                &[v, cube_len(T2_LIGHT_CUBE), j, i_n, c],
                &data.t2,
            )?;
        }
    }
    for (b, basis) in bake.shading.iter().enumerate() {
        for (table, values) in shading_tables(basis) {
            w.add_f32(&names::shading_table(b, table), &[values.len()], values)?;
        }
    }
    add_basis_tables(&mut w, &meta.bases, &bake.basis_tables)?;
    for (t, (tm, texels)) in meta.textures.iter().zip(&bake.textures).enumerate() {
        w.add_f32(
            &names::texture(t),
            &[tm.height as usize, tm.width as usize, 3],
            texels,
        )?;
    }
    // The metadata is plain numbers, strings and lists: it always serializes.
    w.set_metadata(serde_json::to_value(meta).unwrap_or(serde_json::Value::Null));
    Ok(w)
}

/// Adds the four tensors of a compressed T1 or T2 (`prt_formats::clustered`).
fn add_tucker<'a>(
    w: &mut BakeWriter<'a>,
    g: usize,
    tensor: &str,
    vertices: usize,
    t: &'a StoredTucker,
) -> Result<(), FormatError> {
    let name = |part| names::tucker(g, tensor, part);
    w.add_u32(
        &name(names::TUCKER_RANKS),
        &[t.ranks.len() / 3, 3],
        &t.ranks,
    )?;
    add_stored(
        w,
        &name(names::TUCKER_FACTORS),
        &[t.factors.len()],
        &t.factors,
    )?;
    add_stored(w, &name(names::TUCKER_CORE), &[t.core.len()], &t.core)?;
    add_stored(
        w,
        &name(names::TUCKER_VERTEX),
        &[vertices, t.vertex_rank],
        &t.vertex,
    )
}

/// Bytes of one stored T0 value, T1 or T2 value.
pub(crate) fn value_bytes(p: Precision) -> usize {
    match p {
        Precision::F32 => 4,
        Precision::F16 => 2,
    }
}
