//! [`BakeWriter`]: lays out tensors and metadata as a bake file and writes it.

use std::borrow::Cow;
use std::collections::{BTreeMap, HashSet};
use std::io::{self, Write};
use std::path::Path;

use serde_json::Value;

use super::digest::header_digest;
use super::dtype::element_bytes;
use super::{
    keys, write_file_atomic, Dtype, Element, FormatError, Result, FORMAT_NAME, MAX_HEADER_LEN,
    PAD_PREFIX, RESERVED_PREFIX, SCHEMA_VERSION, ST_METADATA, TENSOR_ALIGN,
};

struct PendingTensor<'a> {
    name: String,
    dtype: Dtype,
    shape: Vec<usize>,
    data: TensorData<'a>,
}

/// A tensor's bytes: in memory, or produced on demand by a [`TensorSource`].
enum TensorData<'a> {
    Bytes(Cow<'a, [u8]>),
    Streamed {
        len: usize,
        source: &'a dyn TensorSource,
    },
}

impl TensorData<'_> {
    fn len(&self) -> usize {
        match self {
            TensorData::Bytes(b) => b.len(),
            TensorData::Streamed { len, .. } => *len,
        }
    }
}

/// Produces a tensor's bytes on demand, so that a file larger than memory can be written from
/// pieces held elsewhere (a per-vertex bake's units on disk). The writer calls
/// [`write_to`](Self::write_to) twice: once to compute the tensor's CRC-32 for the header, once
/// to write it, and checks both times that exactly the declared number of bytes came.
pub trait TensorSource {
    /// Writes the tensor's raw little-endian bytes to `out`, the same bytes every call.
    fn write_to(&self, out: &mut dyn Write) -> io::Result<()>;
}

/// A [`Write`] that counts bytes and hashes them, for a streamed tensor's checksum pass.
struct CrcSink {
    hasher: crc32fast::Hasher,
    len: usize,
}

impl Write for CrcSink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.hasher.update(buf);
        self.len += buf.len();
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// A [`Write`] that passes bytes through and counts them.
struct Counted<'w, W: Write> {
    inner: &'w mut W,
    len: usize,
}

impl<W: Write> Write for Counted<'_, W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.len += n;
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

/// Builds a bake file. Tensors are written in the order they were added (so a caller can keep
/// data that is read together close together), each starting at a multiple of [`TENSOR_ALIGN`].
///
/// Data is borrowed where possible (`'a`), so writing a multi-gigabyte bake does not double its
/// memory footprint.
pub struct BakeWriter<'a> {
    tensors: Vec<PendingTensor<'a>>,
    names: HashSet<String>,
    metadata: Value,
}

impl Default for BakeWriter<'_> {
    fn default() -> Self {
        Self::new()
    }
}

/// One entry of the data section: a tensor of the writer, or zero padding.
enum Slot {
    Tensor(usize),
    Pad(usize),
}

struct Layout {
    header: Vec<u8>,
    slots: Vec<Slot>,
}

impl<'a> BakeWriter<'a> {
    /// An empty writer; metadata defaults to `{}`.
    pub fn new() -> Self {
        BakeWriter {
            tensors: Vec::new(),
            names: HashSet::new(),
            metadata: Value::Object(Default::default()),
        }
    }

    /// Sets the bake schema's metadata (opaque to the container; stored as a JSON string).
    pub fn set_metadata(&mut self, metadata: Value) {
        self.metadata = metadata;
    }

    /// Adds a tensor from raw little-endian bytes (borrowed or owned).
    pub fn add_tensor(
        &mut self,
        name: &str,
        dtype: Dtype,
        shape: &[usize],
        data: impl Into<Cow<'a, [u8]>>,
    ) -> Result<()> {
        self.add_data(name, dtype, shape, TensorData::Bytes(data.into()))
    }

    /// Adds a tensor of `len` bytes whose bytes `source` (borrowed, like every tensor's data)
    /// produces when the file is laid out and written (see [`TensorSource`]); nothing is read
    /// until then.
    pub fn add_streamed(
        &mut self,
        name: &str,
        dtype: Dtype,
        shape: &[usize],
        len: usize,
        source: &'a dyn TensorSource,
    ) -> Result<()> {
        self.add_data(name, dtype, shape, TensorData::Streamed { len, source })
    }

    fn add_data(
        &mut self,
        name: &str,
        dtype: Dtype,
        shape: &[usize],
        data: TensorData<'a>,
    ) -> Result<()> {
        check_name(name)?;
        if self.names.contains(name) {
            return Err(FormatError::DuplicateTensor {
                name: name.to_string(),
            });
        }
        // u128 cannot overflow for any realistic rank; checked anyway so no input panics.
        let expected = shape
            .iter()
            .try_fold(dtype.size() as u128, |acc, &d| acc.checked_mul(d as u128));
        if expected != Some(data.len() as u128) {
            return Err(FormatError::DataSize {
                tensor: name.to_string(),
                dtype,
                shape: shape.to_vec(),
                expected: expected.unwrap_or(u128::MAX),
                actual: data.len(),
            });
        }
        self.names.insert(name.to_string());
        self.tensors.push(PendingTensor {
            name: name.to_string(),
            dtype,
            shape: shape.to_vec(),
            data,
        });
        Ok(())
    }

    /// Adds a typed tensor; on little-endian hosts the data is borrowed, not copied.
    pub fn add_slice<T: Element>(
        &mut self,
        name: &str,
        shape: &[usize],
        data: &'a [T],
    ) -> Result<()> {
        self.add_tensor(name, T::DTYPE, shape, element_bytes(data))
    }

    /// Adds an `F32` tensor (see [`add_slice`](Self::add_slice)).
    pub fn add_f32(&mut self, name: &str, shape: &[usize], data: &'a [f32]) -> Result<()> {
        self.add_slice(name, shape, data)
    }
    /// Adds an `F16` tensor (see [`add_slice`](Self::add_slice)).
    pub fn add_f16(&mut self, name: &str, shape: &[usize], data: &'a [half::f16]) -> Result<()> {
        self.add_slice(name, shape, data)
    }
    /// Adds a `U32` tensor (see [`add_slice`](Self::add_slice)).
    pub fn add_u32(&mut self, name: &str, shape: &[usize], data: &'a [u32]) -> Result<()> {
        self.add_slice(name, shape, data)
    }
    /// Adds a `U16` tensor (see [`add_slice`](Self::add_slice)).
    pub fn add_u16(&mut self, name: &str, shape: &[usize], data: &'a [u16]) -> Result<()> {
        self.add_slice(name, shape, data)
    }
    /// Adds a `U8` tensor (see [`add_slice`](Self::add_slice)).
    pub fn add_u8(&mut self, name: &str, shape: &[usize], data: &'a [u8]) -> Result<()> {
        self.add_slice(name, shape, data)
    }
    /// Adds an `I32` tensor (see [`add_slice`](Self::add_slice)).
    pub fn add_i32(&mut self, name: &str, shape: &[usize], data: &'a [i32]) -> Result<()> {
        self.add_slice(name, shape, data)
    }

    /// Number of tensors added so far.
    pub fn len(&self) -> usize {
        self.tensors.len()
    }

    /// Whether no tensor was added yet (an empty bake is still a valid file).
    pub fn is_empty(&self) -> bool {
        self.tensors.is_empty()
    }

    /// Size of the file [`write_atomic`](Self::write_atomic) would write, in bytes.
    pub fn file_len(&self) -> Result<u64> {
        let layout = self.layout()?;
        Ok(8 + layout.header.len() as u64 + self.data_len(&layout) as u64)
    }

    /// Writes the file atomically (temporary file, fsync, rename); see [`write_file_atomic`].
    pub fn write_atomic(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let layout = self.layout()?;
        write_file_atomic(path, |w| self.write_layout(&layout, w)).map_err(|source| {
            FormatError::Write {
                path: path.to_path_buf(),
                source,
            }
        })
    }

    /// The complete file as bytes (for tests and in-memory use).
    pub fn to_bytes(&self) -> Result<Vec<u8>> {
        let layout = self.layout()?;
        let mut out = Vec::new();
        // Writing into a Vec cannot fail.
        let _ = self.write_layout(&layout, &mut out);
        Ok(out)
    }

    fn data_len(&self, layout: &Layout) -> usize {
        layout
            .slots
            .iter()
            .map(|s| match s {
                Slot::Tensor(i) => self.tensors[*i].data.len(),
                Slot::Pad(n) => *n,
            })
            .sum()
    }

    fn write_layout(&self, layout: &Layout, w: &mut impl Write) -> io::Result<()> {
        w.write_all(&(layout.header.len() as u64).to_le_bytes())?;
        w.write_all(&layout.header)?;
        for slot in &layout.slots {
            match slot {
                Slot::Tensor(i) => match &self.tensors[*i].data {
                    TensorData::Bytes(b) => w.write_all(b)?,
                    TensorData::Streamed { len, source } => {
                        let mut counted = Counted { inner: w, len: 0 };
                        source.write_to(&mut counted)?;
                        if counted.len != *len {
                            return Err(io::Error::other(format!(
                                "tensor '{}': its source wrote {} bytes, {len} declared",
                                self.tensors[*i].name, counted.len
                            )));
                        }
                    }
                },
                Slot::Pad(n) => w.write_all(&[0u8; TENSOR_ALIGN][..*n])?,
            }
        }
        Ok(())
    }

    fn layout(&self) -> Result<Layout> {
        // Data section: tensors in insertion order, each preceded by zero padding (a `U8`
        // padding tensor, since safetensors forbids holes) if its offset is not aligned.
        let mut slots = Vec::with_capacity(self.tensors.len() * 2);
        let mut entries: Vec<(String, Dtype, Vec<usize>, usize, usize)> = Vec::new();
        let mut offset = 0usize;
        for (i, t) in self.tensors.iter().enumerate() {
            let pad = (TENSOR_ALIGN - offset % TENSOR_ALIGN) % TENSOR_ALIGN;
            if pad > 0 {
                let name = format!("{PAD_PREFIX}{}", slots.len());
                entries.push((name, Dtype::U8, vec![pad], offset, offset + pad));
                slots.push(Slot::Pad(pad));
                offset += pad;
            }
            let end = offset + t.data.len();
            entries.push((t.name.clone(), t.dtype, t.shape.clone(), offset, end));
            slots.push(Slot::Tensor(i));
            offset = end;
        }

        let mut crcs: BTreeMap<&str, String> = BTreeMap::new();
        for t in &self.tensors {
            let crc = match &t.data {
                TensorData::Bytes(b) => crc32fast::hash(b),
                TensorData::Streamed { len, source } => {
                    let mut sink = CrcSink {
                        hasher: crc32fast::Hasher::new(),
                        len: 0,
                    };
                    source
                        .write_to(&mut sink)
                        .map_err(|source| FormatError::Source {
                            tensor: t.name.clone(),
                            source,
                        })?;
                    if sink.len != *len {
                        return Err(FormatError::Source {
                            tensor: t.name.clone(),
                            source: io::Error::other(format!(
                                "its source wrote {} bytes, {len} declared",
                                sink.len
                            )),
                        });
                    }
                    sink.hasher.finalize()
                }
            };
            crcs.insert(t.name.as_str(), hex32(crc));
        }
        let mut meta: BTreeMap<String, String> = BTreeMap::new();
        meta.insert(keys::FORMAT.into(), FORMAT_NAME.into());
        meta.insert(keys::SCHEMA_VERSION.into(), SCHEMA_VERSION.to_string());
        meta.insert(keys::METADATA.into(), self.metadata.to_string());
        meta.insert(keys::CRC32.into(), json_string(&crcs));
        let digest = header_digest(
            meta.iter().map(|(k, v)| (k.as_str(), v.as_str())),
            entries
                .iter()
                .map(|(n, d, s, b, e)| (n.as_str(), *d, s.as_slice(), *b, *e)),
        );
        meta.insert(keys::HEADER_CRC32.into(), hex32(digest));

        let mut header = serde_json::Map::new();
        header.insert(ST_METADATA.into(), serde_json::json!(meta));
        for (name, dtype, shape, begin, end) in &entries {
            header.insert(
                name.clone(),
                serde_json::json!({
                    "dtype": dtype.name(),
                    "shape": shape,
                    "data_offsets": [begin, end],
                }),
            );
        }
        let mut header = Value::Object(header).to_string().into_bytes();
        // Spaces after the JSON are allowed by the safetensors spec; they put the data section
        // on an aligned file offset.
        let pad = (TENSOR_ALIGN - (8 + header.len()) % TENSOR_ALIGN) % TENSOR_ALIGN;
        header.resize(header.len() + pad, b' ');
        if header.len() > MAX_HEADER_LEN {
            return Err(FormatError::WriterHeaderTooLarge { len: header.len() });
        }
        Ok(Layout { header, slots })
    }
}

fn check_name(name: &str) -> Result<()> {
    let reason = if name.is_empty() {
        "names must not be empty"
    } else if name.starts_with(RESERVED_PREFIX) {
        "names starting with '__' are reserved for the container"
    } else if name.chars().any(char::is_control) {
        "names must not contain control characters"
    } else {
        return Ok(());
    };
    Err(FormatError::InvalidName {
        name: name.to_string(),
        reason: reason.to_string(),
    })
}

fn hex32(v: u32) -> String {
    format!("{v:08x}")
}

fn json_string<T: serde::Serialize>(v: &T) -> String {
    // Serializing string maps cannot fail.
    serde_json::to_string(v).unwrap_or_default()
}
