//! [`FormatError`]: everything that can go wrong writing or reading a bake file.

use std::io;
use std::path::PathBuf;

use super::{keys, Dtype, FORMAT_NAME, MAX_HEADER_LEN};

/// Everything that can go wrong writing or reading a bake file. Reading errors name the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FormatError {
    /// The file could not be opened, inspected or mapped.
    #[error("cannot open bake file {}: {source}", .path.display())]
    Open {
        /// The file concerned.
        path: PathBuf,
        /// The underlying I/O error.
        source: io::Error,
    },
    /// The path exists but is not a regular file (a folder, a device, ...).
    #[error("{}: not a regular file", .path.display())]
    NotAFile {
        /// The file concerned.
        path: PathBuf,
    },
    /// The file is shorter than the 8-byte header length field.
    #[error(
        "{}: file is {len} bytes, too short to be a bake file (it must start with an 8-byte \
         header length)",
        .path.display()
    )]
    TooShort {
        /// The file concerned.
        path: PathBuf,
        /// Length of the file or header, in bytes.
        len: u64,
    },
    /// The file cannot be a bake file, even a truncated one (its header length field does not
    /// fit it and no JSON header starts after it): a scene, a config or an image opened by
    /// mistake.
    #[error(
        "{}: not a PRT bake file: it looks like {looks_like}; a bake file is what `bake` \
         writes (a .prtbake file)",
        .path.display()
    )]
    NotABakeFile {
        /// The file concerned.
        path: PathBuf,
        /// What the file looks like, e.g. "a glTF JSON scene (.gltf)".
        looks_like: String,
    },
    /// The header length field points past the end of the file.
    #[error(
        "{}: truncated: the header length field says {header_len} bytes, but only {available} \
         bytes follow it (file is {file_len} bytes)",
        .path.display()
    )]
    HeaderTruncated {
        /// The file concerned.
        path: PathBuf,
        /// The header length the file claims, in bytes.
        header_len: u64,
        /// Bytes present after the length field.
        available: u64,
        /// Length of the file, in bytes.
        file_len: u64,
    },
    /// The header length exceeds [`MAX_HEADER_LEN`](super::MAX_HEADER_LEN).
    #[error(
        "{}: header is {header_len} bytes, more than the {MAX_HEADER_LEN}-byte limit",
        .path.display()
    )]
    HeaderTooLarge {
        /// The file concerned.
        path: PathBuf,
        /// The header length the file claims, in bytes.
        header_len: u64,
    },
    /// The JSON header is not valid UTF-8 or JSON, or breaks the safetensors or container rules.
    #[error("{}: invalid safetensors header: {reason}", .path.display())]
    InvalidHeader {
        /// The file concerned.
        path: PathBuf,
        /// What exactly is wrong.
        reason: String,
    },
    /// `__metadata__.format` is missing or not [`FORMAT_NAME`](super::FORMAT_NAME): not a PRT
    /// bake file.
    #[error(
        "{}: not a PRT bake file: __metadata__.{} is {}, expected '{FORMAT_NAME}'",
        .path.display(), keys::FORMAT,
        .found.as_deref().map_or("missing (a plain safetensors file?)".to_string(), |f| format!("'{f}'"))
    )]
    WrongFormat {
        /// The file concerned.
        path: PathBuf,
        /// What the file has.
        found: Option<String>,
    },
    /// The file has a schema version other than [`SCHEMA_VERSION`](super::SCHEMA_VERSION).
    #[error(
        "{}: bake file has schema version {found}, but this build reads only version \
         {expected}; re-bake the scene or use a runtime built for version {found}",
        .path.display()
    )]
    WrongVersion {
        /// The file concerned.
        path: PathBuf,
        /// What the file has.
        found: u32,
        /// What was expected.
        expected: u32,
    },
    /// A tensor entry of the header is malformed (dtype, shape, offsets or a reserved name).
    #[error("{}: tensor '{tensor}': {reason}", .path.display())]
    InvalidTensor {
        /// The file concerned.
        path: PathBuf,
        /// Name of the tensor concerned.
        tensor: String,
        /// What exactly is wrong.
        reason: String,
    },
    /// A tensor's byte range reaches past the end of the data section (truncated file).
    #[error(
        "{}: truncated or corrupt: tensor '{tensor}' occupies data bytes {begin}..{end}, but \
         the data section has only {data_len} bytes",
        .path.display()
    )]
    TensorOutOfBounds {
        /// The file concerned.
        path: PathBuf,
        /// Name of the tensor concerned.
        tensor: String,
        /// First byte of the tensor, relative to the data section.
        begin: u64,
        /// One past its last byte, relative to the data section.
        end: u64,
        /// Length of the data section, in bytes.
        data_len: u64,
    },
    /// The tensors do not tile the data section exactly (a gap, an overlap or trailing bytes).
    #[error("{}: corrupt layout: {reason}", .path.display())]
    Layout {
        /// The file concerned.
        path: PathBuf,
        /// What exactly is wrong.
        reason: String,
    },
    /// A tensor has no entry in `__metadata__.crc32`.
    #[error("{}: tensor '{tensor}' has no checksum in __metadata__.crc32", .path.display())]
    MissingChecksum {
        /// The file concerned.
        path: PathBuf,
        /// Name of the tensor concerned.
        tensor: String,
    },
    /// A tensor's bytes do not match its stored CRC-32.
    #[error(
        "{}: checksum mismatch in tensor '{tensor}': stored crc32 {expected:08x}, computed \
         {actual:08x}; the file is corrupt",
        .path.display()
    )]
    ChecksumMismatch {
        /// The file concerned.
        path: PathBuf,
        /// Name of the tensor concerned.
        tensor: String,
        /// What was expected.
        expected: u32,
        /// What was found.
        actual: u32,
    },
    /// The header digest does not match `header_crc32`.
    #[error(
        "{}: header checksum mismatch: stored {expected:08x}, computed {actual:08x}; the \
         header (metadata, names, shapes or offsets) is corrupt",
        .path.display()
    )]
    HeaderChecksumMismatch {
        /// The file concerned.
        path: PathBuf,
        /// What was expected.
        expected: u32,
        /// What was found.
        actual: u32,
    },
    /// A padding tensor holds a nonzero byte.
    #[error("{}: padding tensor '{tensor}' is not all zeros; the file is corrupt", .path.display())]
    PaddingNotZero {
        /// The file concerned.
        path: PathBuf,
        /// Name of the tensor concerned.
        tensor: String,
    },
    /// The bake schema metadata (`__metadata__.metadata`) is missing or not JSON.
    #[error("{}: invalid bake metadata: {reason}", .path.display())]
    BadMetadata {
        /// The file concerned.
        path: PathBuf,
        /// What exactly is wrong.
        reason: String,
    },
    /// A requested tensor does not exist.
    #[error("{}: no tensor named '{tensor}' (the file has {available})", .path.display())]
    MissingTensor {
        /// The file concerned.
        path: PathBuf,
        /// Name of the tensor concerned.
        tensor: String,
        /// A short human-readable list of the tensors present.
        available: String,
    },
    /// A tensor was requested as a dtype it does not have.
    #[error(
        "{}: tensor '{tensor}' has dtype {actual}, but {requested} was requested",
        .path.display()
    )]
    WrongDtype {
        /// The file concerned.
        path: PathBuf,
        /// Name of the tensor concerned.
        tensor: String,
        /// The dtype (or dtypes) asked for.
        requested: String,
        /// What was found.
        actual: Dtype,
    },
    /// A tensor does not have the shape a schema requires ([`super::TensorView::require_shape`]).
    #[error(
        "{}: tensor '{tensor}' has shape {actual:?}, expected {expected:?}",
        .path.display()
    )]
    WrongShape {
        /// The file concerned.
        path: PathBuf,
        /// Name of the tensor concerned.
        tensor: String,
        /// What was expected.
        expected: Vec<usize>,
        /// What was found.
        actual: Vec<usize>,
    },
    /// A tensor is not aligned for zero-copy typed access (the file was not written by this crate).
    #[error(
        "{}: tensor '{tensor}' starts at file offset {offset}, which is not {align}-byte \
         aligned as zero-copy {dtype} access needs (file not written by this crate?)",
        .path.display()
    )]
    Misaligned {
        /// The file concerned.
        path: PathBuf,
        /// Name of the tensor concerned.
        tensor: String,
        /// The element type.
        dtype: Dtype,
        /// Offset of the tensor's first byte in the file.
        offset: usize,
        /// The alignment needed, in bytes.
        align: usize,
    },
    /// Zero-copy typed access was requested on a big-endian host.
    #[error(
        "{}: tensor '{tensor}': zero-copy typed access needs a little-endian host; use bytes()",
        .path.display()
    )]
    BigEndianHost {
        /// The file concerned.
        path: PathBuf,
        /// Name of the tensor concerned.
        tensor: String,
    },
    /// Writer: a tensor name is empty, reserved (`__` prefix) or holds control characters.
    #[error("invalid tensor name '{name}': {reason}")]
    InvalidName {
        /// The name given.
        name: String,
        /// What exactly is wrong.
        reason: String,
    },
    /// Writer: two tensors with the same name.
    #[error("tensor '{name}' was added twice")]
    DuplicateTensor {
        /// The name given.
        name: String,
    },
    /// Writer: the data's length does not match the dtype and shape.
    #[error(
        "tensor '{tensor}': shape {shape:?} of {dtype} needs {expected} bytes, but {actual} \
         were given"
    )]
    DataSize {
        /// Name of the tensor concerned.
        tensor: String,
        /// The element type.
        dtype: Dtype,
        /// The shape given.
        shape: Vec<usize>,
        /// What was expected.
        expected: u128,
        /// What was found.
        actual: usize,
    },
    /// Writer: the JSON header would exceed [`MAX_HEADER_LEN`](super::MAX_HEADER_LEN).
    #[error("the JSON header would be {len} bytes, more than the {MAX_HEADER_LEN}-byte limit")]
    WriterHeaderTooLarge {
        /// Length of the file or header, in bytes.
        len: usize,
    },
    /// Writer: a streamed tensor's source failed or wrote another number of bytes than it
    /// declared ([`TensorSource`](super::TensorSource)).
    #[error("cannot produce tensor '{tensor}': {source}")]
    Source {
        /// The tensor concerned.
        tensor: String,
        /// What the source reported.
        source: io::Error,
    },
    /// Writer: writing, syncing or renaming the file failed.
    #[error("cannot write bake file {}: {source}", .path.display())]
    Write {
        /// The file concerned.
        path: PathBuf,
        /// The underlying I/O error.
        source: io::Error,
    },
}
