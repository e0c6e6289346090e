//! A bake file laid out before it is written, holding the sources of its streamed tensors
//! ([`TensorSource`]): the assembly of a per-vertex bake and a shard file add tensors as they
//! go, some produced on demand from pieces, then write the file in one go
//! ([`prt_formats::BakeWriter`] borrows the sources, so something must own them until then).

use std::borrow::Cow;
use std::path::Path;

use prt_formats::container::TensorSource;
use prt_formats::{BakeWriter, Dtype, FormatError};
use serde_json::Value;

enum Entry<'a> {
    Bytes(Cow<'a, [u8]>),
    Streamed(usize, Box<dyn TensorSource + 'a>),
}

/// Tensors in file order and the metadata, written by [`StreamedFile::write`].
pub struct StreamedFile<'a> {
    entries: Vec<(String, Dtype, Vec<usize>, Entry<'a>)>,
    metadata: Value,
}

impl Default for StreamedFile<'_> {
    fn default() -> Self {
        Self::new()
    }
}

impl<'a> StreamedFile<'a> {
    pub fn new() -> Self {
        StreamedFile {
            entries: Vec::new(),
            metadata: Value::Null,
        }
    }

    /// A tensor whose bytes are at hand (borrowed or owned).
    pub fn add_bytes(
        &mut self,
        name: &str,
        dtype: Dtype,
        shape: &[usize],
        bytes: impl Into<Cow<'a, [u8]>>,
    ) {
        self.entries.push((
            name.to_string(),
            dtype,
            shape.to_vec(),
            Entry::Bytes(bytes.into()),
        ));
    }

    /// A tensor of `len` bytes produced by `source` when the file is written (twice: for its
    /// checksum, then into the file).
    pub fn add_streamed(
        &mut self,
        name: &str,
        dtype: Dtype,
        shape: &[usize],
        len: usize,
        source: Box<dyn TensorSource + 'a>,
    ) {
        self.entries.push((
            name.to_string(),
            dtype,
            shape.to_vec(),
            Entry::Streamed(len, source),
        ));
    }

    pub fn set_metadata(&mut self, metadata: Value) {
        self.metadata = metadata;
    }

    /// Writes the file atomically (nothing is left on failure); returns its size. Errors
    /// name the tensor (a bad shape, a failing source) or the file.
    pub fn write(&self, path: &Path) -> Result<u64, FormatError> {
        let mut w = BakeWriter::new();
        for (name, dtype, shape, entry) in &self.entries {
            match entry {
                Entry::Bytes(b) => w.add_tensor(name, *dtype, shape, b.as_ref())?,
                Entry::Streamed(len, source) => {
                    w.add_streamed(name, *dtype, shape, *len, source.as_ref())?
                }
            }
        }
        w.set_metadata(self.metadata.clone());
        let size = w.file_len()?;
        w.write_atomic(path)?;
        Ok(size)
    }
}

/// A tensor produced by a closure.
pub struct FnSource<F>(pub F);

impl<F: Fn(&mut dyn std::io::Write) -> std::io::Result<()>> TensorSource for FnSource<F> {
    fn write_to(&self, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        (self.0)(out)
    }
}
