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
//!
//! # Files of this module
//! * `error.rs`: [`FormatError`], every way writing or reading can fail.
//! * `dtype.rs`: [`Dtype`] and the sealed [`Element`] trait behind zero-copy typed access.
//! * `atomic.rs`: [`write_file_atomic`], the temporary-file-and-rename writer (also used for
//!   images).
//! * `write.rs`: [`BakeWriter`], which lays out and serializes a bake file.
//! * `read.rs`: [`BakeFile`] and [`TensorView`], the memory-mapped reader.
//! * `parse.rs`: validation of a whole file image (header, tensor table, layout, checksums).
//! * `digest.rs`: the canonical header digest behind `header_crc32`.
//! * `sniff.rs`: what a file that is not a bake file looks like (a glTF, a config, an image).

mod atomic;
mod digest;
mod dtype;
mod error;
mod parse;
mod read;
mod sniff;
mod write;

pub use atomic::write_file_atomic;
pub use dtype::{element_bytes, Dtype, Element};
pub use error::FormatError;
pub use read::{BakeFile, TensorView};
pub use write::{BakeWriter, TensorSource};

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

/// Result of the container's fallible operations.
type Result<T, E = FormatError> = std::result::Result<T, E>;
