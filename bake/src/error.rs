//! The baker's top-level error: what a bake run (load, bases, bake, write) can fail with. Each
//! variant's message names the file, key or value at fault.

use std::path::PathBuf;

use prt_formats::Family;

use crate::config::ConfigError;
use crate::pixel::PixelError;
use crate::scene::SceneError;

/// Why a bake (or a reference render's setup) failed.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// The bake config is unreadable or invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The scene could not be loaded.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The scene loaded but has nothing to trace.
    #[error("{0}: the scene has no valid triangles")]
    NoTriangles(PathBuf),
    /// The config asks for a bake mode this version cannot make.
    #[error("{config}: mode = \"{mode}\" is not implemented yet; use mode = \"pixel\"")]
    ModeNotImplemented {
        /// The config file.
        config: PathBuf,
        /// The mode asked for.
        mode: &'static str,
    },
    /// A basis of an editable family could not be built.
    #[error("building the {family} basis: {message}")]
    Basis {
        /// The family.
        family: Family,
        /// What went wrong.
        message: String,
    },
    /// The basis error target is not a positive relative error.
    #[error("the basis error target must be a positive relative error, e.g. 0.01 (got {0})")]
    BadErrorTarget(f64),
    /// The estimated working memory exceeds the caller's limit.
    #[error("the bake needs about {} but --max-memory is {}: lower the resolution, the reflections or the basis count", crate::units::human_bytes(*.needed), crate::units::human_bytes(*.limit))]
    MemoryLimit {
        /// Estimated bytes.
        needed: u64,
        /// The limit in bytes.
        limit: u64,
    },
    /// Laying out, baking or writing the per-pixel tensors failed.
    #[error(transparent)]
    Pixel(#[from] PixelError),
    /// A `--set` edit names an unknown material or is malformed.
    #[error(transparent)]
    Override(#[from] prt_formats::OverrideError),
    /// A `--set` edit names a parameter the material's family does not have.
    #[error("material '{material}' is {family}: it has no parameter '{param}' (it has {valid})")]
    WrongParam {
        /// The material.
        material: String,
        /// Its family.
        family: Family,
        /// The parameter asked for.
        param: &'static str,
        /// The parameters it has.
        valid: String,
    },
}
