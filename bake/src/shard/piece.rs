//! A piece: what one unit of a bake produced (a per-vertex super-cluster's compressed tensors,
//! a per-pixel row's transfer rows), as named sections and a small JSON summary. Pieces are
//! written as small bake-file containers ([`prt_formats::BakeWriter`]: aligned, checksummed,
//! memory-mapped when read) into the checkpoint folder, and copied section by section into a
//! shard file; [`PieceSource`] reads them back from either, so the file assembled from them is
//! the same bytes whichever way they came.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use prt_formats::{BakeFile, BakeWriter, Dtype, Element, FormatError, TensorView};
use serde_json::Value;

use super::error::ShardError;

/// A piece being built: sections in order and a summary.
pub struct PieceOut {
    pub(crate) summary: Value,
    pub(crate) sections: Vec<(String, Dtype, Vec<usize>, Vec<u8>)>,
}

impl PieceOut {
    /// An empty piece with this summary (figures the assembly needs before reading sections).
    pub fn new(summary: Value) -> PieceOut {
        PieceOut {
            summary,
            sections: Vec::new(),
        }
    }

    /// Adds a section of typed values (shape `[len]`).
    pub fn add<T: Element>(&mut self, name: &str, values: &[T]) {
        let bytes = prt_formats::container::element_bytes(values).into_owned();
        self.sections
            .push((name.to_string(), T::DTYPE, vec![values.len()], bytes));
    }

    /// The piece as a container (for the checkpoint's files).
    pub(crate) fn writer(&self) -> Result<BakeWriter<'_>, FormatError> {
        let mut w = BakeWriter::new();
        for (name, dtype, shape, bytes) in &self.sections {
            w.add_tensor(name, *dtype, shape, bytes.as_slice())?;
        }
        w.set_metadata(self.summary.clone());
        Ok(w)
    }
}

/// Where the assembly reads pieces from: the checkpoint folder of this run, or merged shard
/// files. `Sync`: sections are converted in parallel.
pub trait PieceSource: Sync {
    /// The piece of unit `unit`.
    fn piece(&self, unit: usize) -> Result<Piece<'_>, ShardError>;
}

/// One unit's piece, read back: its summary and its sections, zero-copy.
pub struct Piece<'a> {
    backing: Backing<'a>,
    unit: usize,
}

enum Backing<'a> {
    /// A piece file of a checkpoint, mapped.
    File(Box<BakeFile>),
    /// Unit `unit` inside a shard file: sections named `u<unit>.<name>`, summary given.
    Shard {
        file: &'a BakeFile,
        summary: &'a Value,
    },
}

impl<'a> Piece<'a> {
    pub(crate) fn from_file(file: BakeFile, unit: usize) -> Piece<'a> {
        Piece {
            backing: Backing::File(Box::new(file)),
            unit,
        }
    }

    pub(crate) fn in_shard(file: &'a BakeFile, summary: &'a Value, unit: usize) -> Piece<'a> {
        Piece {
            backing: Backing::Shard { file, summary },
            unit,
        }
    }

    /// The unit this piece is of.
    pub fn unit(&self) -> usize {
        self.unit
    }

    fn path(&self) -> &Path {
        match &self.backing {
            Backing::File(f) => f.path(),
            Backing::Shard { file, .. } => file.path(),
        }
    }

    /// The summary.
    pub fn summary(&self) -> &Value {
        match &self.backing {
            Backing::File(f) => f.metadata(),
            Backing::Shard { summary, .. } => summary,
        }
    }

    /// A section, or an error naming the file and unit when it is absent.
    pub fn section(&self, name: &str) -> Result<TensorView<'_>, ShardError> {
        let found = match &self.backing {
            Backing::File(f) => f.tensor(name),
            Backing::Shard { file, .. } => file.tensor(&shard_section(self.unit, name)),
        };
        found.map_err(|e| self.bad(format!("section '{name}': {e}")))
    }

    /// A section's values as `T` (f32 sections are read as they are, aligned and zero-copy).
    pub fn values<T: Element>(&self, name: &str) -> Result<Cow<'_, [T]>, ShardError> {
        let view = self.section(name)?;
        view.as_slice::<T>()
            .map(Cow::Borrowed)
            .map_err(|e| self.bad(format!("section '{name}': {e}")))
    }

    /// An error about this piece.
    pub fn bad(&self, message: String) -> ShardError {
        ShardError::BadPiece {
            path: self.path().to_path_buf(),
            unit: self.unit,
            message,
        }
    }

    /// A summary field as `T`, or an error naming it.
    pub fn field<T: serde::de::DeserializeOwned>(&self, name: &str) -> Result<T, ShardError> {
        let v = self
            .summary()
            .get(name)
            .ok_or_else(|| self.bad(format!("its summary has no '{name}'")))?;
        serde_json::from_value(v.clone()).map_err(|e| self.bad(format!("'{name}': {e}")))
    }
}

/// The name of a unit's section inside a shard file.
pub(crate) fn shard_section(unit: usize, name: &str) -> String {
    format!("u{unit}.{name}")
}

/// The piece file of `unit` in a checkpoint folder.
pub(crate) fn piece_path(dir: &Path, unit: usize) -> PathBuf {
    dir.join(format!("unit{unit}.piece"))
}
