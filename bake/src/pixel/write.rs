//! Writing a per-pixel bake to its file: element-major tensors, optional f16 storage with a
//! per-group scale, written atomically.

use half::f16;
use prt_formats::pixel::{names, BasisMeta, Precision};
use prt_formats::{BakeWriter, FormatError};

use super::bake::PixelBake;
use super::error::PixelError;

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

/// Adds the tables of each basis as the tensor `basis.<i>.tables`, `[cells, num_bases]` (the
/// per-vertex bake stores its PCA bases the same way).
pub(crate) fn add_basis_tables<'a>(
    w: &mut BakeWriter<'a>,
    metas: &[BasisMeta],
    tables: &'a [Vec<f32>],
) -> Result<(), FormatError> {
    for (b, (m, t)) in metas.iter().zip(tables).enumerate() {
        let nb = m.basis.num_bases;
        w.add_f32(&names::basis_tables(b), &[t.len() / nb.max(1), nb], t)?;
    }
    Ok(())
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

/// Writes the bake file atomically; returns its size in bytes.
pub fn write_bake_file(
    bake: &PixelBake,
    path: &std::path::Path,
    precision: Precision,
) -> Result<u64, PixelError> {
    let mut meta = bake.meta.clone();
    // The metadata must say how this file stores its tensors, whatever the bake was made for
    // (the runtime checks the two agree).
    meta.precision = precision;
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
    let err = |source: FormatError| PixelError::Write {
        path: path.to_path_buf(),
        source: Box::new(source),
    };
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
    add_basis_tables(&mut w, &meta.bases, &bake.basis_tables).map_err(err)?;
    w.set_metadata(meta.to_json());
    let size = w.file_len().map_err(err)?;
    w.write_atomic(path).map_err(err)?;
    Ok(size)
}
