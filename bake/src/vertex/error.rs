//! What can go wrong planning, baking or writing a per-vertex bake. Each message names what is
//! at fault (the lights, the key, the material, the vertex, the file).

use prt_formats::Family;

use crate::pixel::PixelError;

/// Why a per-vertex bake could not be made or written.
#[derive(Debug, thiserror::Error)]
pub enum VertexError {
    /// The scene has lights besides the environment (docs/vertex.md, "Only the environment").
    #[error(
        "the per-vertex mode relights the environment only, but the scene has {what}; remove \
         them or bake with mode = \"pixel\""
    )]
    Lights {
        /// The lights found, named (emissive materials) or described (punctual lights).
        what: String,
    },
    /// `reflections` is not one the per-vertex mode models.
    #[error(
        "reflections = {0}: the per-vertex mode models 2 (T0 and T1: direct light and one \
         reflection before the last) or 3 (adds T2) reflections"
    )]
    Reflections(u32),
    /// A numeric option is out of its range.
    #[error("{key} = {value} is outside the accepted range [{lo}, {hi}]")]
    OutOfRange {
        /// The option (as the config names it).
        key: &'static str,
        /// Its value.
        value: u64,
        /// Smallest accepted.
        lo: u64,
        /// Largest accepted.
        hi: u64,
    },
    /// A group's material has a lobe but no shading basis of its family was given.
    #[error(
        "material '{material}' is {family}: its vertices need the {family} shading basis, which \
         was not given"
    )]
    MissingShading {
        /// The material.
        material: String,
        /// Its family.
        family: Family,
    },
    /// A shading basis given to the bake is unusable.
    #[error("the {family} shading basis: {message}")]
    BadShading {
        /// Its family.
        family: Family,
        /// What is wrong.
        message: String,
    },
    /// A vertex asked for by [`super::VertexTracer::trace`] belongs to no group.
    #[error("vertex {vertex} is used by no triangle (or does not exist): it has no transfer")]
    NoGroup {
        /// The vertex.
        vertex: u32,
    },
    /// A vertex's transfer is not finite (a broken scene or material).
    #[error("vertex {vertex}: {message}")]
    NonFinite {
        /// The vertex.
        vertex: u32,
        /// What the Haar transform reported.
        message: String,
    },
    /// A compression setting is unusable.
    #[error("{key} = {value}: {reason}")]
    BadSetting {
        /// The option (as the config names it).
        key: &'static str,
        /// Its value.
        value: String,
        /// What it must be.
        reason: &'static str,
    },
    /// Compressing T1 or T2 failed (a non-finite value reached an eigendecomposition).
    #[error("compressing the transfer tensors: {0}")]
    Compression(String),
    /// The slot allocation failed (a missing or mis-sized PCA basis, too many slots).
    #[error(transparent)]
    Layout(#[from] PixelError),
    /// The assembled metadata fails the schema's own checks (a bug in the baker).
    #[error("the per-vertex bake's metadata is inconsistent: {0}")]
    Inconsistent(String),
    /// The checkpoint could not be made, resumed or read.
    #[error(transparent)]
    Checkpoint(#[from] crate::shard::CheckpointError),
    /// The caller cancelled the bake ([`crate::progress::Progress::cancelled`]).
    #[error(transparent)]
    Cancelled(#[from] crate::progress::Cancelled),
    /// A unit's piece could not be read (a damaged checkpoint or shard file).
    #[error(transparent)]
    Piece(#[from] crate::shard::ShardError),
    /// The bake file could not be written.
    #[error("writing {path}: {source}")]
    Write {
        /// The file.
        path: std::path::PathBuf,
        /// What went wrong (boxed: the container's error is large, and this is the cold path).
        source: Box<prt_formats::FormatError>,
    },
}
