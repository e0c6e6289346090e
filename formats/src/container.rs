//! The bake-file container: a safetensors file with PRT-specific metadata, per-tensor CRC-32
//! checksums, a header checksum and 16-byte tensor alignment, read zero-copy through a memory map.
//!
//! The byte-level layout is specified in `docs/format.md`. In short:
//!
//! ```text
//! [u64 LE: N] [N bytes: JSON header, padded with spaces] [data section: raw little-endian tensors]
//! ```
//!
//! # Why the layout is written here and not by `safetensors::serialize`
//! The safetensors crate's serializer pads the header to 8 bytes and orders tensors by dtype so
//! that each tensor is aligned to its own element size, but it cannot align every tensor to 16
//! bytes (the runtime wants that for SIMD-friendly, zero-copy access), and it takes owned
//! views. The safetensors format forbids holes in the data section, so the only spec-conforming
//! way to align is to fill the gaps with small `U8` *padding tensors* (named `__pad<k>`). We write
//! that layout ourselves (it is a few dozen lines; the format is documented and tiny) and use the
//! crate on the read side as an independent check that every file we accept is one that the
//! reference safetensors parser (the one behind Python's `safetensors.numpy.load_file`) accepts.
//!
//! # Integrity
//! * Every tensor has a CRC-32 (`crc32` in `__metadata__`); padding must be zero.
//! * `header_crc32` is a CRC-32 over a canonical digest of the header (all `__metadata__` entries
//!   except itself, and every tensor's name, dtype, shape and offsets). It is computed from the
//!   parsed values rather than the raw JSON bytes, so it catches corrupted metadata (which no
//!   structural check would) while staying independent of JSON formatting.
//! * [`BakeFile::open`] verifies everything, including a full CRC pass over the data;
//!   [`BakeFile::open_unchecked`] does every check except the data CRC pass (the header checksum
//!   and all structural checks still run), for callers that open large files often and verify
//!   separately or lazily ([`BakeFile::verify_checksums`], [`BakeFile::verify_tensor`]).

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use memmap2::Mmap;
use serde_json::Value;

/// Value of `__metadata__.format` in every PRT bake file.
pub const FORMAT_NAME: &str = "prt-bake";

/// Version of the bake schema. Bump it on any change a reader of the previous version would
/// misinterpret; readers reject every other version (see `docs/format.md`, "Versioning").
pub const SCHEMA_VERSION: u32 = 1;

/// Alignment, in bytes, of the data section and of every tensor's first byte (relative to the
/// start of the file, and therefore in memory too, since a memory map starts page-aligned).
pub const TENSOR_ALIGN: usize = 16;

/// Largest JSON header accepted, the same limit as the reference safetensors parser, so that
/// every file we write is one Python can read.
pub const MAX_HEADER_LEN: usize = 100_000_000;

/// Keys of the safetensors `__metadata__` map used by the container.
pub mod keys {
    /// Always [`super::FORMAT_NAME`].
    pub const FORMAT: &str = "format";
    /// [`super::SCHEMA_VERSION`] as a decimal string.
    pub const SCHEMA_VERSION: &str = "schema_version";
    /// The bake schema's JSON metadata (materials, bases, camera, ...) as a JSON string.
    pub const METADATA: &str = "metadata";
    /// JSON object (as a string): tensor name -> CRC-32 of its bytes as 8 lowercase hex digits.
    pub const CRC32: &str = "crc32";
    /// CRC-32 of the canonical header digest, 8 lowercase hex digits.
    pub const HEADER_CRC32: &str = "header_crc32";
}

/// Key of the safetensors metadata map inside the JSON header.
const ST_METADATA: &str = "__metadata__";
/// Prefix of padding tensors. Every name starting with `__` is reserved for the container.
const PAD_PREFIX: &str = "__pad";
const RESERVED_PREFIX: &str = "__";
/// Domain separator of the header digest; changing the digest definition means changing this.
const HEADER_DIGEST_TAG: &[u8] = b"prt-bake header digest v1\0";

/// Element types a bake file may hold (spelled as in safetensors).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Dtype {
    F32,
    F16,
    U32,
    U16,
    U8,
    I32,
}

impl Dtype {
    pub const ALL: [Dtype; 6] = [
        Dtype::F32,
        Dtype::F16,
        Dtype::U32,
        Dtype::U16,
        Dtype::U8,
        Dtype::I32,
    ];

    /// Size of one element in bytes.
    pub const fn size(self) -> usize {
        match self {
            Dtype::F32 | Dtype::U32 | Dtype::I32 => 4,
            Dtype::F16 | Dtype::U16 => 2,
            Dtype::U8 => 1,
        }
    }

    /// The safetensors spelling ("F32", ...).
    pub const fn name(self) -> &'static str {
        match self {
            Dtype::F32 => "F32",
            Dtype::F16 => "F16",
            Dtype::U32 => "U32",
            Dtype::U16 => "U16",
            Dtype::U8 => "U8",
            Dtype::I32 => "I32",
        }
    }

    /// Parses the safetensors spelling; `None` for dtypes bake files do not use.
    pub fn from_name(name: &str) -> Option<Dtype> {
        Dtype::ALL.into_iter().find(|d| d.name() == name)
    }
}

impl std::fmt::Display for Dtype {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

mod sealed {
    pub trait Sealed {}
}

/// Rust types that can be viewed zero-copy as tensor elements.
///
/// Sealed: the zero-copy casts in this module are sound only because every implementor is a
/// plain number type (or `repr(transparent)` over one) with no padding and no invalid bit
/// patterns, whose size equals `DTYPE.size()`.
pub trait Element: sealed::Sealed + Copy + 'static {
    const DTYPE: Dtype;
    /// Appends the little-endian bytes of `values` (used on big-endian hosts only).
    fn extend_le_bytes(values: &[Self], out: &mut Vec<u8>);
}

macro_rules! impl_element {
    ($($t:ty => $d:ident),* $(,)?) => {$(
        impl sealed::Sealed for $t {}
        impl Element for $t {
            const DTYPE: Dtype = Dtype::$d;
            fn extend_le_bytes(values: &[Self], out: &mut Vec<u8>) {
                for v in values {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
    )*};
}

impl_element!(f32 => F32, half::f16 => F16, u32 => U32, u16 => U16, u8 => U8, i32 => I32);

/// Little-endian bytes of a typed slice: a borrowed reinterpretation on little-endian hosts
/// (no copy), a converted copy on big-endian ones.
fn element_bytes<T: Element>(data: &[T]) -> Cow<'_, [u8]> {
    if cfg!(target_endian = "little") {
        // SAFETY: `T` is a sealed plain number type without padding (see `Element`), so its
        // memory is `size_of_val(data)` initialized bytes; `u8` has alignment 1, and the
        // returned slice borrows `data`, so it cannot outlive it.
        let bytes = unsafe {
            std::slice::from_raw_parts(data.as_ptr().cast::<u8>(), std::mem::size_of_val(data))
        };
        Cow::Borrowed(bytes)
    } else {
        let mut out = Vec::with_capacity(std::mem::size_of_val(data));
        T::extend_le_bytes(data, &mut out);
        Cow::Owned(out)
    }
}

/// Everything that can go wrong writing or reading a bake file. Reading errors name the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FormatError {
    #[error("cannot open bake file {}: {source}", .path.display())]
    Open { path: PathBuf, source: io::Error },
    #[error("{}: not a regular file", .path.display())]
    NotAFile { path: PathBuf },
    #[error(
        "{}: file is {len} bytes, too short to be a bake file (it must start with an 8-byte \
         header length)",
        .path.display()
    )]
    TooShort { path: PathBuf, len: u64 },
    #[error(
        "{}: truncated: the header length field says {header_len} bytes, but only {available} \
         bytes follow it (file is {file_len} bytes)",
        .path.display()
    )]
    HeaderTruncated {
        path: PathBuf,
        header_len: u64,
        available: u64,
        file_len: u64,
    },
    #[error(
        "{}: header is {header_len} bytes, more than the {MAX_HEADER_LEN}-byte limit",
        .path.display()
    )]
    HeaderTooLarge { path: PathBuf, header_len: u64 },
    #[error("{}: invalid safetensors header: {reason}", .path.display())]
    InvalidHeader { path: PathBuf, reason: String },
    #[error(
        "{}: not a PRT bake file: __metadata__.{} is {}, expected '{FORMAT_NAME}'",
        .path.display(), keys::FORMAT,
        .found.as_deref().map_or("missing (a plain safetensors file?)".to_string(), |f| format!("'{f}'"))
    )]
    WrongFormat {
        path: PathBuf,
        found: Option<String>,
    },
    #[error(
        "{}: bake file has schema version {found}, but this build reads only version \
         {expected}; re-bake the scene or use a runtime built for version {found}",
        .path.display()
    )]
    WrongVersion {
        path: PathBuf,
        found: u32,
        expected: u32,
    },
    #[error("{}: tensor '{tensor}': {reason}", .path.display())]
    InvalidTensor {
        path: PathBuf,
        tensor: String,
        reason: String,
    },
    #[error(
        "{}: truncated or corrupt: tensor '{tensor}' occupies data bytes {begin}..{end}, but \
         the data section has only {data_len} bytes",
        .path.display()
    )]
    TensorOutOfBounds {
        path: PathBuf,
        tensor: String,
        begin: u64,
        end: u64,
        data_len: u64,
    },
    #[error("{}: corrupt layout: {reason}", .path.display())]
    Layout { path: PathBuf, reason: String },
    #[error("{}: tensor '{tensor}' has no checksum in __metadata__.crc32", .path.display())]
    MissingChecksum { path: PathBuf, tensor: String },
    #[error(
        "{}: checksum mismatch in tensor '{tensor}': stored crc32 {expected:08x}, computed \
         {actual:08x}; the file is corrupt",
        .path.display()
    )]
    ChecksumMismatch {
        path: PathBuf,
        tensor: String,
        expected: u32,
        actual: u32,
    },
    #[error(
        "{}: header checksum mismatch: stored {expected:08x}, computed {actual:08x}; the \
         header (metadata, names, shapes or offsets) is corrupt",
        .path.display()
    )]
    HeaderChecksumMismatch {
        path: PathBuf,
        expected: u32,
        actual: u32,
    },
    #[error("{}: padding tensor '{tensor}' is not all zeros; the file is corrupt", .path.display())]
    PaddingNotZero { path: PathBuf, tensor: String },
    #[error("{}: invalid bake metadata: {reason}", .path.display())]
    BadMetadata { path: PathBuf, reason: String },
    #[error("{}: no tensor named '{tensor}' (the file has {available})", .path.display())]
    MissingTensor {
        path: PathBuf,
        tensor: String,
        /// A short human-readable list of the tensors present.
        available: String,
    },
    #[error(
        "{}: tensor '{tensor}' has dtype {actual}, but {requested} was requested",
        .path.display()
    )]
    WrongDtype {
        path: PathBuf,
        tensor: String,
        requested: String,
        actual: Dtype,
    },
    #[error(
        "{}: tensor '{tensor}' has shape {actual:?}, expected {expected:?}",
        .path.display()
    )]
    WrongShape {
        path: PathBuf,
        tensor: String,
        expected: Vec<usize>,
        actual: Vec<usize>,
    },
    #[error(
        "{}: tensor '{tensor}' starts at file offset {offset}, which is not {align}-byte \
         aligned as zero-copy {dtype} access needs (file not written by this crate?)",
        .path.display()
    )]
    Misaligned {
        path: PathBuf,
        tensor: String,
        dtype: Dtype,
        offset: usize,
        align: usize,
    },
    #[error(
        "{}: tensor '{tensor}': zero-copy typed access needs a little-endian host; use bytes()",
        .path.display()
    )]
    BigEndianHost { path: PathBuf, tensor: String },
    #[error("invalid tensor name '{name}': {reason}")]
    InvalidName { name: String, reason: String },
    #[error("tensor '{name}' was added twice")]
    DuplicateTensor { name: String },
    #[error(
        "tensor '{tensor}': shape {shape:?} of {dtype} needs {expected} bytes, but {actual} \
         were given"
    )]
    DataSize {
        tensor: String,
        dtype: Dtype,
        shape: Vec<usize>,
        expected: u128,
        actual: usize,
    },
    #[error("the JSON header would be {len} bytes, more than the {MAX_HEADER_LEN}-byte limit")]
    WriterHeaderTooLarge { len: usize },
    #[error("cannot write bake file {}: {source}", .path.display())]
    Write { path: PathBuf, source: io::Error },
}

type Result<T, E = FormatError> = std::result::Result<T, E>;

// ---------------------------------------------------------------------------------------------
// Atomic file writing (shared with image_io)
// ---------------------------------------------------------------------------------------------

/// Writes a file atomically: `write` fills a temporary file in the destination folder, which is
/// then flushed, fsynced and renamed over `path`. On any error (or panic) the temporary file is
/// removed and an existing file at `path` is left untouched. Missing parent folders are created.
///
/// Readers that memory-mapped the old file keep seeing it: rename replaces the directory entry,
/// never the old file's bytes, which is what makes our `mmap` reads safe against our own writers.
pub fn write_file_atomic<F>(path: impl AsRef<Path>, write: F) -> io::Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> io::Result<()>,
{
    static COUNTER: AtomicU64 = AtomicU64::new(0);

    let path = path.as_ref();
    let file_name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("'{}' does not name a file", path.display()),
        )
    })?;
    // The temporary file must be in the same folder so the rename stays on one filesystem
    // (and is therefore atomic).
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    fs::create_dir_all(dir)
        .map_err(|e| with_context(e, format!("creating folder {}", dir.display())))?;
    let tmp = dir.join(format!(
        ".{}.{}-{}.tmp",
        file_name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(|e| with_context(e, format!("creating temporary file {}", tmp.display())))?;
    let guard = TempFileGuard(Some(tmp));

    let mut writer = BufWriter::with_capacity(1 << 20, file);
    write(&mut writer)?;
    let file = writer.into_inner().map_err(|e| e.into_error())?;
    file.sync_all()
        .map_err(|e| with_context(e, "syncing the temporary file".to_string()))?;
    drop(file);

    let tmp = guard.path();
    fs::rename(tmp, path).map_err(|e| {
        with_context(
            e,
            format!("renaming {} to {}", tmp.display(), path.display()),
        )
    })?;
    guard.disarm();
    // Make the rename itself durable. Best effort: not every filesystem or platform lets a
    // folder be opened and synced, and the data is already safely in place.
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

fn with_context(e: io::Error, what: String) -> io::Error {
    io::Error::new(e.kind(), format!("{what}: {e}"))
}

/// Removes the temporary file unless disarmed (also on panic inside the write closure).
struct TempFileGuard(Option<PathBuf>);

impl TempFileGuard {
    fn path(&self) -> &Path {
        self.0.as_deref().unwrap_or(Path::new(""))
    }
    fn disarm(mut self) {
        self.0 = None;
    }
}

impl Drop for TempFileGuard {
    fn drop(&mut self) {
        if let Some(p) = self.0.take() {
            let _ = fs::remove_file(p);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Writer
// ---------------------------------------------------------------------------------------------

struct PendingTensor<'a> {
    name: String,
    dtype: Dtype,
    shape: Vec<usize>,
    data: Cow<'a, [u8]>,
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
        let data = data.into();
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

    pub fn add_f32(&mut self, name: &str, shape: &[usize], data: &'a [f32]) -> Result<()> {
        self.add_slice(name, shape, data)
    }
    pub fn add_f16(&mut self, name: &str, shape: &[usize], data: &'a [half::f16]) -> Result<()> {
        self.add_slice(name, shape, data)
    }
    pub fn add_u32(&mut self, name: &str, shape: &[usize], data: &'a [u32]) -> Result<()> {
        self.add_slice(name, shape, data)
    }
    pub fn add_u16(&mut self, name: &str, shape: &[usize], data: &'a [u16]) -> Result<()> {
        self.add_slice(name, shape, data)
    }
    pub fn add_u8(&mut self, name: &str, shape: &[usize], data: &'a [u8]) -> Result<()> {
        self.add_slice(name, shape, data)
    }
    pub fn add_i32(&mut self, name: &str, shape: &[usize], data: &'a [i32]) -> Result<()> {
        self.add_slice(name, shape, data)
    }

    /// Number of tensors added so far.
    pub fn len(&self) -> usize {
        self.tensors.len()
    }

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
                Slot::Tensor(i) => w.write_all(&self.tensors[*i].data)?,
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

        let crcs: BTreeMap<&str, String> = self
            .tensors
            .iter()
            .map(|t| (t.name.as_str(), hex32(crc32fast::hash(&t.data))))
            .collect();
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

/// CRC-32 of the canonical header digest (see `docs/format.md`, "Header checksum"): every
/// `__metadata__` entry except `header_crc32` in key order, then every tensor (padding included)
/// in name order. Strings are length-prefixed and numbers are u64 LE, so the encoding is
/// unambiguous.
fn header_digest<'s>(
    meta: impl Iterator<Item = (&'s str, &'s str)>,
    tensors: impl Iterator<Item = (&'s str, Dtype, &'s [usize], usize, usize)>,
) -> u32 {
    fn put_u64(h: &mut crc32fast::Hasher, v: u64) {
        h.update(&v.to_le_bytes());
    }
    fn put_str(h: &mut crc32fast::Hasher, s: &str) {
        put_u64(h, s.len() as u64);
        h.update(s.as_bytes());
    }
    let mut h = crc32fast::Hasher::new();
    h.update(HEADER_DIGEST_TAG);
    let mut meta: Vec<_> = meta.filter(|(k, _)| *k != keys::HEADER_CRC32).collect();
    meta.sort_unstable();
    put_u64(&mut h, meta.len() as u64);
    for (k, v) in meta {
        put_str(&mut h, k);
        put_str(&mut h, v);
    }
    let mut tensors: Vec<_> = tensors.collect();
    tensors.sort_unstable_by(|a, b| a.0.cmp(b.0));
    put_u64(&mut h, tensors.len() as u64);
    for (name, dtype, shape, begin, end) in tensors {
        put_str(&mut h, name);
        put_str(&mut h, dtype.name());
        put_u64(&mut h, shape.len() as u64);
        for &d in shape {
            put_u64(&mut h, d as u64);
        }
        put_u64(&mut h, begin as u64);
        put_u64(&mut h, end as u64);
    }
    h.finalize()
}

// ---------------------------------------------------------------------------------------------
// Reader
// ---------------------------------------------------------------------------------------------

#[derive(Debug)]
struct TensorEntry {
    name: String,
    dtype: Dtype,
    shape: Vec<usize>,
    /// Absolute byte range in the file.
    start: usize,
    end: usize,
    crc: u32,
}

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

    /// The schema version stored in the file (always [`SCHEMA_VERSION`] for an open file).
    pub fn schema_version(&self) -> u32 {
        self.schema_version
    }

    /// The bake schema's metadata, as given to [`BakeWriter::set_metadata`].
    pub fn metadata(&self) -> &Value {
        &self.metadata
    }

    /// Tensor names in file order (padding excluded).
    pub fn tensor_names(&self) -> impl ExactSizeIterator<Item = &str> + '_ {
        self.tensors.iter().map(|t| t.name.as_str())
    }

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
    pub fn name(&self) -> &'a str {
        self.name
    }
    pub fn dtype(&self) -> Dtype {
        self.dtype
    }
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

    pub fn as_f32(&self) -> Result<&'a [f32]> {
        self.as_slice()
    }
    pub fn as_f16(&self) -> Result<&'a [half::f16]> {
        self.as_slice()
    }
    pub fn as_u32(&self) -> Result<&'a [u32]> {
        self.as_slice()
    }
    pub fn as_u16(&self) -> Result<&'a [u16]> {
        self.as_slice()
    }
    pub fn as_u8(&self) -> Result<&'a [u8]> {
        self.as_slice()
    }
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

// ---------------------------------------------------------------------------------------------
// Parsing and validation
// ---------------------------------------------------------------------------------------------

struct Parsed {
    schema_version: u32,
    metadata: Value,
    tensors: Vec<TensorEntry>,
    pads: Vec<(String, usize, usize)>,
}

/// Validates a whole file image. Never panics: every index is checked, every number parsed
/// with overflow checks.
fn parse(path: &Path, bytes: &[u8]) -> Result<Parsed> {
    let pathbuf = || path.to_path_buf();
    let invalid = |reason: String| FormatError::InvalidHeader {
        path: pathbuf(),
        reason,
    };
    let file_len = bytes.len() as u64;
    let Some(len_bytes) = bytes.first_chunk::<8>() else {
        return Err(FormatError::TooShort {
            path: pathbuf(),
            len: file_len,
        });
    };
    let header_len = u64::from_le_bytes(*len_bytes);
    let available = file_len - 8;
    if header_len > available {
        return Err(FormatError::HeaderTruncated {
            path: pathbuf(),
            header_len,
            available,
            file_len,
        });
    }
    if header_len > MAX_HEADER_LEN as u64 {
        return Err(FormatError::HeaderTooLarge {
            path: pathbuf(),
            header_len,
        });
    }
    // header_len <= available <= bytes.len(), so these conversions and slices are in range.
    let data_start = 8 + header_len as usize;
    let header = &bytes[8..data_start];
    let data_len = bytes.len() - data_start;
    let header = std::str::from_utf8(header).map_err(|e| {
        invalid(format!(
            "not UTF-8 (at header byte {}); the header is damaged",
            e.valid_up_to()
        ))
    })?;
    let header: serde_json::Map<String, Value> =
        serde_json::from_str(header).map_err(|e| invalid(format!("bad JSON: {e}")))?;

    // __metadata__: format and version first, so that a file from another version gets the
    // version error rather than whatever structural difference it has.
    let st_meta = match header.get(ST_METADATA) {
        None => {
            return Err(FormatError::WrongFormat {
                path: pathbuf(),
                found: None,
            })
        }
        Some(Value::Object(m)) => m,
        Some(_) => return Err(invalid(format!("{ST_METADATA} is not a JSON object"))),
    };
    let mut meta: BTreeMap<&str, &str> = BTreeMap::new();
    for (k, v) in st_meta {
        match v {
            Value::String(s) => {
                meta.insert(k, s);
            }
            _ => {
                return Err(invalid(format!(
                    "{ST_METADATA}.{k} is not a string (safetensors metadata values are strings)"
                )))
            }
        }
    }
    match meta.get(keys::FORMAT) {
        Some(&FORMAT_NAME) => {}
        other => {
            return Err(FormatError::WrongFormat {
                path: pathbuf(),
                found: other.map(|s| s.to_string()),
            })
        }
    }
    let version_str = meta
        .get(keys::SCHEMA_VERSION)
        .ok_or_else(|| invalid(format!("{ST_METADATA}.{} is missing", keys::SCHEMA_VERSION)))?;
    let schema_version: u32 = version_str.parse().map_err(|_| {
        invalid(format!(
            "{ST_METADATA}.{} is '{version_str}', not a non-negative integer",
            keys::SCHEMA_VERSION
        ))
    })?;
    if schema_version != SCHEMA_VERSION {
        return Err(FormatError::WrongVersion {
            path: pathbuf(),
            found: schema_version,
            expected: SCHEMA_VERSION,
        });
    }

    // Tensor table.
    struct Raw<'h> {
        name: &'h str,
        dtype: Dtype,
        shape: Vec<usize>,
        begin: usize,
        end: usize,
    }
    let mut raw: Vec<Raw<'_>> = Vec::with_capacity(header.len());
    for (name, info) in &header {
        if name == ST_METADATA {
            continue;
        }
        let bad = |reason: String| FormatError::InvalidTensor {
            path: pathbuf(),
            tensor: name.clone(),
            reason,
        };
        let info = info
            .as_object()
            .ok_or_else(|| bad("entry is not a JSON object".into()))?;
        let dtype_str = info
            .get("dtype")
            .and_then(Value::as_str)
            .ok_or_else(|| bad("missing or non-string 'dtype'".into()))?;
        let dtype = Dtype::from_name(dtype_str).ok_or_else(|| {
            bad(format!(
                "dtype '{dtype_str}' is not used by PRT bake files (expected one of {})",
                Dtype::ALL.map(Dtype::name).join(", ")
            ))
        })?;
        let shape = info
            .get("shape")
            .and_then(Value::as_array)
            .ok_or_else(|| bad("missing or non-array 'shape'".into()))?
            .iter()
            .map(|d| d.as_u64().and_then(|d| usize::try_from(d).ok()))
            .collect::<Option<Vec<usize>>>()
            .ok_or_else(|| bad("'shape' must hold non-negative integers".into()))?;
        let offsets = info
            .get("data_offsets")
            .and_then(Value::as_array)
            .and_then(|a| match a.as_slice() {
                [b, e] => Some((b.as_u64()?, e.as_u64()?)),
                _ => None,
            })
            .ok_or_else(|| {
                bad("'data_offsets' must be [begin, end] (non-negative integers)".into())
            })?;
        let (begin, end) = offsets;
        if begin > end {
            return Err(bad(format!("data_offsets [{begin}, {end}] run backwards")));
        }
        if end > data_len as u64 {
            return Err(FormatError::TensorOutOfBounds {
                path: pathbuf(),
                tensor: name.clone(),
                begin,
                end,
                data_len: data_len as u64,
            });
        }
        // Both offsets are <= data_len, so they fit in usize.
        let (begin, end) = (begin as usize, end as usize);
        let needed = shape
            .iter()
            .try_fold(dtype.size() as u128, |acc, &d| acc.checked_mul(d as u128));
        if needed != Some((end - begin) as u128) {
            return Err(bad(format!(
                "shape {shape:?} of {dtype} needs {} bytes, but data_offsets span {}",
                needed.map_or("too many".to_string(), |n| n.to_string()),
                end - begin
            )));
        }
        if name.starts_with(RESERVED_PREFIX)
            && (!name.starts_with(PAD_PREFIX) || dtype != Dtype::U8)
        {
            return Err(bad(
                "names starting with '__' are reserved (only U8 '__pad' padding is allowed)".into(),
            ));
        }
        raw.push(Raw {
            name,
            dtype,
            shape,
            begin,
            end,
        });
    }

    // The data section must be tiled exactly: no gaps (the safetensors spec forbids holes, which
    // keeps the file from hiding data), no overlaps, nothing after the last tensor.
    raw.sort_unstable_by_key(|r| (r.begin, r.end));
    let layout_err = |reason: String| FormatError::Layout {
        path: pathbuf(),
        reason,
    };
    let mut pos = 0usize;
    for r in &raw {
        if r.begin != pos {
            return Err(layout_err(if r.begin > pos {
                format!(
                    "gap of {} bytes before tensor '{}' (data bytes {pos}..{})",
                    r.begin - pos,
                    r.name,
                    r.begin
                )
            } else {
                format!(
                    "tensor '{}' (data bytes {}..{}) overlaps the previous tensor, which ends at {pos}",
                    r.name, r.begin, r.end
                )
            }));
        }
        pos = r.end;
    }
    if pos != data_len {
        return Err(layout_err(format!(
            "{} bytes after the last tensor (tensors end at data byte {pos}, the file has {data_len})",
            data_len - pos
        )));
    }

    // Checksums.
    let crc_str = meta
        .get(keys::CRC32)
        .ok_or_else(|| invalid(format!("{ST_METADATA}.{} is missing", keys::CRC32)))?;
    let crc_map: BTreeMap<String, String> = serde_json::from_str(crc_str).map_err(|e| {
        invalid(format!(
            "{ST_METADATA}.{} is not a JSON object of strings: {e}",
            keys::CRC32
        ))
    })?;
    let parse_hex = |what: &str, s: &str| {
        // Exactly the canonical spelling (8 lowercase hex digits), so that the stored text
        // has one form and any change to it is detected.
        if s.len() == 8 && s.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f')) {
            u32::from_str_radix(s, 16).ok()
        } else {
            None
        }
        .ok_or_else(|| invalid(format!("{what} '{s}' is not 8 lowercase hex digits")))
    };
    let stored_header_crc = meta
        .get(keys::HEADER_CRC32)
        .ok_or_else(|| invalid(format!("{ST_METADATA}.{} is missing", keys::HEADER_CRC32)))?;
    let stored_header_crc = parse_hex("header checksum", stored_header_crc)?;
    let actual = header_digest(
        meta.iter().map(|(k, v)| (*k, *v)),
        raw.iter()
            .map(|r| (r.name, r.dtype, r.shape.as_slice(), r.begin, r.end)),
    );
    if actual != stored_header_crc {
        return Err(FormatError::HeaderChecksumMismatch {
            path: pathbuf(),
            expected: stored_header_crc,
            actual,
        });
    }

    let mut tensors = Vec::with_capacity(raw.len());
    let mut pads = Vec::new();
    for r in raw {
        let (start, end) = (data_start + r.begin, data_start + r.end);
        if r.name.starts_with(PAD_PREFIX) {
            pads.push((r.name.to_string(), start, end));
            continue;
        }
        let crc = match crc_map.get(r.name) {
            Some(s) => parse_hex(&format!("checksum of tensor '{}'", r.name), s)?,
            None => {
                return Err(FormatError::MissingChecksum {
                    path: pathbuf(),
                    tensor: r.name.to_string(),
                })
            }
        };
        tensors.push(TensorEntry {
            name: r.name.to_string(),
            dtype: r.dtype,
            shape: r.shape,
            start,
            end,
            crc,
        });
    }
    if let Some(extra) = crc_map
        .keys()
        .find(|k| !tensors.iter().any(|t| &t.name == *k))
    {
        return Err(invalid(format!(
            "{ST_METADATA}.{} lists a checksum for '{extra}', which is not a tensor in the file",
            keys::CRC32
        )));
    }

    let metadata_str = meta
        .get(keys::METADATA)
        .ok_or_else(|| FormatError::BadMetadata {
            path: pathbuf(),
            reason: format!("{ST_METADATA}.{} is missing", keys::METADATA),
        })?;
    let metadata: Value =
        serde_json::from_str(metadata_str).map_err(|e| FormatError::BadMetadata {
            path: pathbuf(),
            reason: format!("not valid JSON: {e}"),
        })?;

    // Independent check with the reference parser: whatever we accept, Python must accept too.
    // It only reads the header (no data is touched).
    if let Err(e) = safetensors::SafeTensors::read_metadata(bytes) {
        return Err(invalid(format!("rejected by the safetensors parser: {e}")));
    }

    Ok(Parsed {
        schema_version,
        metadata,
        tensors,
        pads,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A write that fails half-way must leave the previous file untouched and no temp file.
    #[test]
    fn failed_write_keeps_old_file_and_removes_temp() {
        let dir = std::env::temp_dir().join(format!("prt-atomic-unit-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let target = dir.join("a.bin");
        fs::write(&target, b"old contents").unwrap();
        let r = write_file_atomic(&target, |w| {
            w.write_all(&[7u8; 3 << 20])?;
            Err(io::Error::other("injected failure"))
        });
        assert!(r.unwrap_err().to_string().contains("injected failure"));
        assert_eq!(fs::read(&target).unwrap(), b"old contents");
        let entries: Vec<_> = fs::read_dir(&dir).unwrap().collect();
        assert_eq!(entries.len(), 1, "temp file left behind");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn header_digest_depends_on_every_field() {
        let base = || {
            header_digest(
                [("format", "prt-bake"), ("metadata", "{}")].into_iter(),
                [("a", Dtype::F32, &[2usize][..], 0usize, 8usize)].into_iter(),
            )
        };
        let d0 = base();
        assert_eq!(d0, base());
        let d1 = header_digest(
            [("format", "prt-bake"), ("metadata", "{ }")].into_iter(),
            [("a", Dtype::F32, &[2usize][..], 0usize, 8usize)].into_iter(),
        );
        let d2 = header_digest(
            [("format", "prt-bake"), ("metadata", "{}")].into_iter(),
            [("a", Dtype::U32, &[2usize][..], 0usize, 8usize)].into_iter(),
        );
        // header_crc32 itself is excluded.
        let d3 = header_digest(
            [
                ("format", "prt-bake"),
                ("metadata", "{}"),
                ("header_crc32", "x"),
            ]
            .into_iter(),
            [("a", Dtype::F32, &[2usize][..], 0usize, 8usize)].into_iter(),
        );
        assert_ne!(d0, d1);
        assert_ne!(d0, d2);
        assert_eq!(d0, d3);
    }
}
