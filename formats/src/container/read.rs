//! [`BakeFile`] and [`TensorView`]: the validated, memory-mapped, zero-copy reader.

use std::collections::HashMap;
use std::fs::{self, File};
use std::path::{Path, PathBuf};

use memmap2::Mmap;
use serde_json::Value;

use super::parse::{parse, TensorEntry};
use super::{Dtype, Element, FormatError, Result};

/// An open bake file: a validated, memory-mapped safetensors container.
///
/// The mapping is read-only. As with any memory map, the file must not be modified in place
/// while it is open (our writers never do: they replace files by rename); truncating it under a
/// reader would make the OS kill the process with SIGBUS on access.
#[derive(Debug)]
pub struct BakeFile {
    path: PathBuf,
    mmap: Mmap,
    schema_version: u32,
    metadata: Value,
    /// Tensors in file order, padding excluded.
    tensors: Vec<TensorEntry>,
    index: HashMap<String, usize>,
    /// Names and absolute ranges of padding tensors.
    pads: Vec<(String, usize, usize)>,
}

impl BakeFile {
    /// Opens, validates and fully verifies a bake file (structure, header checksum and a CRC-32
    /// pass over all tensor data). Verification reads the whole file once; at memory/page-cache
    /// speed this is tens of milliseconds per 100 MB (see `docs/format.md`).
    pub fn open(path: impl AsRef<Path>) -> Result<BakeFile> {
        let file = Self::open_unchecked(path)?;
        file.verify_checksums()?;
        Ok(file)
    }

    /// Like [`open`](Self::open) but skips the CRC pass over the data (every structural check
    /// and the header checksum still run, so all accessors stay safe). For callers that open big
    /// files repeatedly; call [`verify_checksums`](Self::verify_checksums) or
    /// [`verify_tensor`](Self::verify_tensor) when integrity matters.
    pub fn open_unchecked(path: impl AsRef<Path>) -> Result<BakeFile> {
        let path = path.as_ref().to_path_buf();
        let open_err = |source| FormatError::Open {
            path: path.clone(),
            source,
        };
        let meta = fs::metadata(&path).map_err(open_err)?;
        if !meta.is_file() {
            return Err(FormatError::NotAFile { path });
        }
        let file = File::open(&path).map_err(open_err)?;
        // The length of the file we actually opened (the path may have been replaced since).
        let len = file.metadata().map_err(open_err)?.len();
        if len < 8 {
            return Err(FormatError::TooShort { path, len });
        }
        // SAFETY: the map is read-only and lives as long as `BakeFile`, which hands out only
        // borrows of it. Soundness additionally needs the file not to be modified while mapped;
        // that is documented on `BakeFile`, and our writers replace files atomically instead of
        // writing in place.
        let mmap = unsafe { Mmap::map(&file) }.map_err(open_err)?;
        Self::from_mmap(path, mmap)
    }

    fn from_mmap(path: PathBuf, mmap: Mmap) -> Result<BakeFile> {
        let parsed = parse(&path, &mmap)?;
        Ok(BakeFile {
            path,
            mmap,
            schema_version: parsed.schema_version,
            metadata: parsed.metadata,
            index: parsed
                .tensors
                .iter()
                .enumerate()
                .map(|(i, t)| (t.name.clone(), i))
                .collect(),
            tensors: parsed.tensors,
            pads: parsed.pads,
        })
    }

    /// Verifies every tensor's CRC-32 and that padding is zero.
    pub fn verify_checksums(&self) -> Result<()> {
        for t in &self.tensors {
            self.verify_entry(t)?;
        }
        for (name, start, end) in &self.pads {
            if self.mmap[*start..*end].iter().any(|&b| b != 0) {
                return Err(FormatError::PaddingNotZero {
                    path: self.path.clone(),
                    tensor: name.clone(),
                });
            }
        }
        Ok(())
    }

    /// Verifies one tensor's CRC-32 (for lazy verification after `open_unchecked`).
    pub fn verify_tensor(&self, name: &str) -> Result<()> {
        let t = self.entry(name)?;
        self.verify_entry(t)
    }

    fn verify_entry(&self, t: &TensorEntry) -> Result<()> {
        let actual = crc32fast::hash(&self.mmap[t.start..t.end]);
        if actual != t.crc {
            return Err(FormatError::ChecksumMismatch {
                path: self.path.clone(),
                tensor: t.name.clone(),
                expected: t.crc,
                actual,
            });
        }
        Ok(())
    }

    /// The path the file was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The schema version stored in the file (always
    /// [`SCHEMA_VERSION`](super::SCHEMA_VERSION) for an open file).
    pub fn schema_version(&self) -> u32 {
        self.schema_version
    }

    /// The bake schema's metadata, as given to
    /// [`BakeWriter::set_metadata`](super::BakeWriter::set_metadata).
    pub fn metadata(&self) -> &Value {
        &self.metadata
    }

    /// Tensor names in file order (padding excluded).
    pub fn tensor_names(&self) -> impl ExactSizeIterator<Item = &str> + '_ {
        self.tensors.iter().map(|t| t.name.as_str())
    }

    /// Whether the file has a tensor named `name` (padding tensors are never reported).
    pub fn contains(&self, name: &str) -> bool {
        self.index.contains_key(name)
    }

    /// A zero-copy view of a tensor.
    pub fn tensor(&self, name: &str) -> Result<TensorView<'_>> {
        let t = self.entry(name)?;
        Ok(TensorView {
            path: &self.path,
            name: &t.name,
            dtype: t.dtype,
            shape: &t.shape,
            bytes: &self.mmap[t.start..t.end],
            file_offset: t.start,
        })
    }

    /// The whole mapped file.
    pub fn file_bytes(&self) -> &[u8] {
        &self.mmap
    }

    fn entry(&self, name: &str) -> Result<&TensorEntry> {
        match self.index.get(name) {
            Some(&i) => Ok(&self.tensors[i]),
            None => Err(FormatError::MissingTensor {
                path: self.path.clone(),
                tensor: name.to_string(),
                available: self.describe_names(),
            }),
        }
    }

    fn describe_names(&self) -> String {
        const SHOWN: usize = 12;
        let n = self.tensors.len();
        if n == 0 {
            return "no tensors".to_string();
        }
        let mut names: Vec<&str> = self.tensor_names().collect();
        names.sort_unstable();
        let list = names
            .iter()
            .take(SHOWN)
            .map(|s| format!("'{s}'"))
            .collect::<Vec<_>>()
            .join(", ");
        if n > SHOWN {
            format!("{n} tensors: {list}, ...")
        } else {
            format!("{n} tensor{}: {list}", if n == 1 { "" } else { "s" })
        }
    }
}

/// A zero-copy view of one tensor inside a [`BakeFile`].
#[derive(Debug, Clone, Copy)]
pub struct TensorView<'a> {
    path: &'a Path,
    name: &'a str,
    dtype: Dtype,
    shape: &'a [usize],
    bytes: &'a [u8],
    file_offset: usize,
}

impl<'a> TensorView<'a> {
    /// The tensor's name.
    pub fn name(&self) -> &'a str {
        self.name
    }
    /// The tensor's element type.
    pub fn dtype(&self) -> Dtype {
        self.dtype
    }
    /// The tensor's shape, outermost axis first (row-major; empty for a scalar).
    pub fn shape(&self) -> &'a [usize] {
        self.shape
    }
    /// The raw little-endian bytes, borrowed from the memory map.
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }
    /// Number of elements (product of the shape; 1 for a scalar).
    pub fn num_elements(&self) -> usize {
        self.bytes.len() / self.dtype.size()
    }
    /// Offset of the first byte in the file.
    pub fn file_offset(&self) -> usize {
        self.file_offset
    }

    /// Errors unless the shape is exactly `expected` (for callers validating a schema).
    pub fn require_shape(&self, expected: &[usize]) -> Result<()> {
        if self.shape == expected {
            Ok(())
        } else {
            Err(FormatError::WrongShape {
                path: self.path.to_path_buf(),
                tensor: self.name.to_string(),
                expected: expected.to_vec(),
                actual: self.shape.to_vec(),
            })
        }
    }

    /// Zero-copy typed access: a slice pointing into the memory map.
    pub fn as_slice<T: Element>(&self) -> Result<&'a [T]> {
        if self.dtype != T::DTYPE {
            return Err(self.wrong_dtype(T::DTYPE.name()));
        }
        if cfg!(target_endian = "big") {
            return Err(FormatError::BigEndianHost {
                path: self.path.to_path_buf(),
                tensor: self.name.to_string(),
            });
        }
        let size = std::mem::size_of::<T>();
        let align = std::mem::align_of::<T>();
        if self.bytes.is_empty() {
            return Ok(&[]);
        }
        // The writer aligns every tensor to TENSOR_ALIGN, but the file may come from elsewhere:
        // check the actual pointer rather than trusting the layout.
        // (align is a power of two; `is_multiple_of` would need Rust 1.87, above our MSRV.)
        if (self.bytes.as_ptr() as usize) & (align - 1) != 0 {
            return Err(FormatError::Misaligned {
                path: self.path.to_path_buf(),
                tensor: self.name.to_string(),
                dtype: self.dtype,
                offset: self.file_offset,
                align,
            });
        }
        debug_assert_eq!(
            self.bytes.len() % size,
            0,
            "validated when the file was opened"
        );
        // SAFETY: the pointer is non-null and aligned for `T` (checked above); the length is a
        // whole number of elements (validated at open: byte length == elements * size); every
        // bit pattern is a valid `T` and `T` has no padding (sealed `Element`); the slice
        // borrows the read-only map for `'a`, so it cannot outlive it or alias a `&mut`.
        Ok(unsafe {
            std::slice::from_raw_parts(self.bytes.as_ptr().cast::<T>(), self.bytes.len() / size)
        })
    }

    /// Zero-copy `F32` access (see [`as_slice`](Self::as_slice)).
    pub fn as_f32(&self) -> Result<&'a [f32]> {
        self.as_slice()
    }
    /// Zero-copy `F16` access (see [`as_slice`](Self::as_slice)).
    pub fn as_f16(&self) -> Result<&'a [half::f16]> {
        self.as_slice()
    }
    /// Zero-copy `U32` access (see [`as_slice`](Self::as_slice)).
    pub fn as_u32(&self) -> Result<&'a [u32]> {
        self.as_slice()
    }
    /// Zero-copy `U16` access (see [`as_slice`](Self::as_slice)).
    pub fn as_u16(&self) -> Result<&'a [u16]> {
        self.as_slice()
    }
    /// Zero-copy `U8` access (see [`as_slice`](Self::as_slice)).
    pub fn as_u8(&self) -> Result<&'a [u8]> {
        self.as_slice()
    }
    /// Zero-copy `I32` access (see [`as_slice`](Self::as_slice)).
    pub fn as_i32(&self) -> Result<&'a [i32]> {
        self.as_slice()
    }

    /// A converted copy as f32, for F32 or F16 tensors (works on any host and alignment).
    pub fn to_f32_vec(&self) -> Result<Vec<f32>> {
        match self.dtype {
            Dtype::F32 => Ok(self
                .bytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect()),
            Dtype::F16 => Ok(self
                .bytes
                .chunks_exact(2)
                .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
                .collect()),
            _ => Err(self.wrong_dtype("F32 or F16")),
        }
    }

    fn wrong_dtype(&self, requested: &str) -> FormatError {
        FormatError::WrongDtype {
            path: self.path.to_path_buf(),
            tensor: self.name.to_string(),
            requested: requested.to_string(),
            actual: self.dtype,
        }
    }
}
