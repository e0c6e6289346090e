//! `bake merge SHARD... --out FILE` (docs/shards.md): the shard files checked
//! ([`ShardSet::open`]: whole, of one bake, each given once, all present and complete) and the
//! bake file written from their pieces by the mode's own assembly, byte-identical to the
//! unsharded bake. A refused set writes nothing.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::BakeError;
use crate::pixel::{self, PixelCommon, RowOut};
use crate::progress::{Progress, Stage};
use crate::shard::{PieceSource, ShardError, ShardSet};
use crate::vertex::{assemble_vertex_file, VertexCommon};

/// What a merge did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MergeSummary {
    pub output: PathBuf,
    pub file_bytes: u64,
    /// "vertex" or "pixel".
    pub mode: String,
    pub shards: u32,
    pub units: usize,
    pub seconds: f64,
    /// Groups that missed the compression's error target (per-vertex).
    pub warnings: Vec<String>,
}

/// Merges the shard files `shards` into `output`.
pub fn run_merge(
    shards: &[PathBuf],
    output: &Path,
    progress: &dyn Progress,
) -> Result<MergeSummary, BakeError> {
    let start = Instant::now();
    let set = ShardSet::open(shards)?;
    let bad_common = |e: serde_json::Error| ShardError::NotAShard {
        path: shards[0].clone(),
        why: format!("its common part: {e}"),
    };
    let (file_bytes, warnings) = match set.mode() {
        "vertex" => {
            let common: VertexCommon =
                serde_json::from_value(set.common().clone()).map_err(bad_common)?;
            let tensors = set.common_tensors()?;
            let a = assemble_vertex_file(&common, &tensors, &set, output)?;
            for n in &a.notes {
                progress.note(n);
            }
            for w in &a.warnings {
                progress.warn(w);
            }
            (a.file_bytes, a.warnings)
        }
        "pixel" => {
            let common: PixelCommon =
                serde_json::from_value(set.common().clone()).map_err(bad_common)?;
            let tables: Vec<Vec<f32>> = set
                .common_tensors()?
                .iter()
                .map(|t| {
                    t.bytes
                        .chunks_exact(4)
                        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                        .collect()
                })
                .collect();
            let stage = Stage::start(Some(progress), "reading rows", set.units() as u64);
            let mut rows: Vec<RowOut> = Vec::with_capacity(set.units());
            for y in 0..set.units() {
                rows.push(pixel::row_from_piece(&set.piece(y)?)?);
                stage.advance(1);
            }
            drop(stage);
            let precision = common.meta.precision;
            let bake = pixel::finish_rows(&common, rows, tables);
            (
                pixel::write_bake_file(&bake, output, precision)?,
                Vec::new(),
            )
        }
        other => {
            return Err(ShardError::NotAShard {
                path: shards[0].clone(),
                why: format!("mode '{other}', this program merges 'vertex' and 'pixel'"),
            }
            .into())
        }
    };
    Ok(MergeSummary {
        output: output.to_path_buf(),
        file_bytes,
        mode: set.mode().to_string(),
        shards: shards.len() as u32,
        units: set.units(),
        seconds: start.elapsed().as_secs_f64(),
        warnings,
    })
}
