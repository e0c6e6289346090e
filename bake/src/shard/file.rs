//! Shard files (docs/shards.md): what `bake CONFIG --shard I/N` writes and `bake merge` reads.
//!
//! A shard file is a bake-file container ([`prt_formats::BakeWriter`]) holding
//!
//! - in its metadata, under `prt_shard`: the format version, the mode, the shard's index and
//!   count, the bake's unit count, the [`Fingerprint`] of everything the bake depends on, and
//!   each of its units' piece summaries; under `common`: what the mode needs to assemble the
//!   bake file besides the pieces (its metadata without the per-group figures);
//! - the mode's common tensors (the mesh, the environment, the bases: every shard carries them,
//!   so any one can be merged with the others without the scene or the config);
//! - each of its units' piece sections, named `u<unit>.<section>`.
//!
//! Every shard of a bake holds the same fingerprint and common part; [`ShardSet::open`] checks
//! that the files given are the complete, unique shards of one bake and serves their pieces to
//! the mode's assembly, which writes the same bytes as the unsharded bake.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use prt_formats::container::TensorSource;
use prt_formats::{BakeFile, Dtype};
use serde_json::{json, Value};

use super::error::ShardError;
use super::fingerprint::Fingerprint;
use super::piece::{piece_path, shard_section, Piece, PieceSource};
use super::spec::ShardSpec;
use super::store::PieceStore;
use super::streamed::StreamedFile;

/// Version of the shard layout; merge refuses other versions.
pub const SHARD_VERSION: u32 = 1;

/// A tensor every shard carries (the mesh, the environment, the bases), in memory or borrowed
/// from a shard file.
#[derive(Clone, Debug)]
pub struct CommonTensor<'a> {
    pub name: String,
    pub dtype: Dtype,
    pub shape: Vec<usize>,
    pub bytes: Cow<'a, [u8]>,
}

/// What identifies a shard, as stored under `prt_shard`.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct ShardHeader {
    version: u32,
    mode: String,
    index: u32,
    count: u32,
    units: usize,
    fingerprint: Fingerprint,
    /// The names of the common tensors, in order.
    common_tensors: Vec<String>,
    /// Per unit of this shard (in order), its piece's summary.
    summaries: Vec<Value>,
}

/// Streams one section of a checkpoint's piece file into the shard file.
struct SectionFromPiece {
    path: PathBuf,
    name: String,
}

impl TensorSource for SectionFromPiece {
    fn write_to(&self, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        let f = BakeFile::open_unchecked(&self.path).map_err(std::io::Error::other)?;
        let t = f.tensor(&self.name).map_err(std::io::Error::other)?;
        out.write_all(t.bytes())
    }
}

/// Writes shard `spec` of a bake of `units` units in `mode` to `path` (atomically): the
/// common part, then every unit of the shard's piece from `store`, section by section (never
/// more than one piece in memory).
#[allow(clippy::too_many_arguments)]
pub fn write_shard_file(
    path: &Path,
    mode: &str,
    spec: ShardSpec,
    units: usize,
    fingerprint: &Fingerprint,
    common: Value,
    common_tensors: &[CommonTensor<'_>],
    store: &PieceStore,
) -> Result<u64, ShardError> {
    let err = |e: prt_formats::FormatError| ShardError::Write {
        path: path.to_path_buf(),
        source: Box::new(e),
    };
    let mut w = StreamedFile::new();
    for t in common_tensors {
        w.add_bytes(&t.name, t.dtype, &t.shape, t.bytes.as_ref());
    }
    let mut summaries = Vec::new();
    for u in spec.units(units) {
        let piece = store.piece(u)?;
        summaries.push(piece.summary().clone());
        let file = piece_path(store.dir(), u);
        let names: Vec<(String, Dtype, Vec<usize>, usize)> = {
            let f = BakeFile::open_unchecked(&file).map_err(|e| ShardError::Unreadable {
                path: file.clone(),
                source: Box::new(e),
            })?;
            f.tensor_names()
                .filter(|n| !n.starts_with("__"))
                .map(|n| {
                    let t = f.tensor(n).map_err(|e| ShardError::Unreadable {
                        path: file.clone(),
                        source: Box::new(e),
                    })?;
                    Ok((
                        n.to_string(),
                        t.dtype(),
                        t.shape().to_vec(),
                        t.bytes().len(),
                    ))
                })
                .collect::<Result<_, ShardError>>()?
        };
        for (name, dtype, shape, len) in names {
            w.add_streamed(
                &shard_section(u, &name),
                dtype,
                &shape,
                len,
                Box::new(SectionFromPiece {
                    path: file.clone(),
                    name,
                }),
            );
        }
    }
    let header = ShardHeader {
        version: SHARD_VERSION,
        mode: mode.to_string(),
        index: spec.index,
        count: spec.count,
        units,
        fingerprint: fingerprint.clone(),
        common_tensors: common_tensors.iter().map(|t| t.name.clone()).collect(),
        summaries,
    };
    w.set_metadata(json!({ "prt_shard": header, "common": common }));
    w.write(path).map_err(err)
}

/// The shards of one bake, checked and ready to merge.
pub struct ShardSet {
    files: Vec<(PathBuf, BakeFile, ShardHeader)>,
    mode: String,
    count: u32,
    units: usize,
}

impl ShardSet {
    /// Opens and checks the shard files `paths`: each one whole (checksums), a shard, of the
    /// same bake as the first (fingerprint), given once, all of the bake's shards present,
    /// each holding all of its units. Every refusal names the file.
    pub fn open(paths: &[PathBuf]) -> Result<ShardSet, ShardError> {
        if paths.is_empty() {
            return Err(ShardError::BadSpec(
                "give the shard files to merge (`bake merge SHARD... --out FILE`)".into(),
            ));
        }
        let mut files: Vec<(PathBuf, BakeFile, ShardHeader)> = Vec::new();
        for p in paths {
            let f = BakeFile::open(p).map_err(|e| ShardError::Unreadable {
                path: p.clone(),
                source: Box::new(e),
            })?;
            let not = |why: String| ShardError::NotAShard {
                path: p.clone(),
                why,
            };
            let Some(h) = f.metadata().get("prt_shard") else {
                let what = match prt_formats::vertex::BakeKind::of_metadata(f.metadata()) {
                    Some(k) => format!("it is a whole {} bake file", k.describe()),
                    None => "its metadata has no prt_shard entry".into(),
                };
                return Err(not(what));
            };
            let h: ShardHeader =
                serde_json::from_value(h.clone()).map_err(|e| not(format!("prt_shard: {e}")))?;
            if h.version != SHARD_VERSION {
                return Err(not(format!(
                    "shard version {}, this program merges version {SHARD_VERSION}",
                    h.version
                )));
            }
            if let Some((first, _, fh)) = files.first() {
                let mut changes = h.fingerprint.differences_from(&fh.fingerprint, "in it");
                if h.mode != fh.mode {
                    changes.insert(0, format!("mode {} (the first: {})", h.mode, fh.mode));
                }
                if h.count != fh.count {
                    changes.insert(0, format!("{} shards (the first: {})", h.count, fh.count));
                }
                if !changes.is_empty() {
                    return Err(ShardError::Foreign {
                        path: p.clone(),
                        first: first.clone(),
                        changes,
                    });
                }
            }
            if let Some((a, _, _)) = files.iter().find(|(_, _, o)| o.index == h.index) {
                return Err(ShardError::Duplicate {
                    a: a.clone(),
                    b: p.clone(),
                    index: h.index,
                    count: h.count,
                });
            }
            let spec = ShardSpec::new(h.index, h.count).map_err(|e| not(e.to_string()))?;
            let expected = spec.units(h.units).count();
            if h.summaries.len() != expected {
                return Err(ShardError::Incomplete {
                    path: p.clone(),
                    index: h.index,
                    count: h.count,
                    expected,
                    found: h.summaries.len(),
                });
            }
            files.push((p.clone(), f, h));
        }
        let (mode, count, units) = {
            let h = &files[0].2;
            (h.mode.clone(), h.count, h.units)
        };
        let given: Vec<u32> = files.iter().map(|(_, _, h)| h.index).collect();
        let missing: Vec<u32> = (0..count).filter(|i| !given.contains(i)).collect();
        if !missing.is_empty() {
            return Err(ShardError::Missing { count, missing });
        }
        files.sort_by_key(|(_, _, h)| h.index);
        Ok(ShardSet {
            files,
            mode,
            count,
            units,
        })
    }

    /// The bake's mode ("vertex" or "pixel").
    pub fn mode(&self) -> &str {
        &self.mode
    }

    /// Units of the bake.
    pub fn units(&self) -> usize {
        self.units
    }

    /// The bake's fingerprint.
    pub fn fingerprint(&self) -> &Fingerprint {
        &self.files[0].2.fingerprint
    }

    /// The common part (the first shard's; every shard's is the same).
    pub fn common(&self) -> &Value {
        self.files[0]
            .1
            .metadata()
            .get("common")
            .unwrap_or(&Value::Null)
    }

    /// The common tensors, in order, borrowed from the first shard.
    pub fn common_tensors(&self) -> Result<Vec<CommonTensor<'_>>, ShardError> {
        let (path, f, h) = &self.files[0];
        h.common_tensors
            .iter()
            .map(|n| {
                let t = f.tensor(n).map_err(|e| ShardError::Unreadable {
                    path: path.clone(),
                    source: Box::new(e),
                })?;
                Ok(CommonTensor {
                    name: n.clone(),
                    dtype: t.dtype(),
                    shape: t.shape().to_vec(),
                    bytes: Cow::Borrowed(t.bytes()),
                })
            })
            .collect()
    }

    /// Bytes per shard file, for the summary.
    pub fn files(&self) -> impl Iterator<Item = (&Path, u64)> {
        self.files
            .iter()
            .map(|(p, f, _)| (p.as_path(), f.file_bytes().len() as u64))
    }
}

impl PieceSource for ShardSet {
    fn piece(&self, unit: usize) -> Result<Piece<'_>, ShardError> {
        let shard = unit % self.count as usize;
        let (path, f, h) = &self.files[shard];
        let k = unit / self.count as usize;
        let summary = h.summaries.get(k).ok_or_else(|| ShardError::BadPiece {
            path: path.clone(),
            unit,
            message: "the shard has no summary for it".into(),
        })?;
        Ok(Piece::in_shard(f, summary, unit))
    }
}
