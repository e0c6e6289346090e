//! The baker's top-level error: what a bake run (load, bases, bake, write) can fail with. Each
//! variant's message names the file, key or value at fault.

use std::path::PathBuf;

use prt_formats::Family;

use crate::config::ConfigError;
use crate::pixel::PixelError;
use crate::scene::SceneError;
use crate::vertex::VertexError;

/// Why a bake (or a reference render's setup) failed.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// The bake config is unreadable or invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The scene could not be loaded.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// What the user named is not a config, a scene folder or a glTF.
    #[error(transparent)]
    Input(#[from] crate::config::input::InputError),
    /// The scene loaded but has nothing to trace.
    #[error("{0}: the scene has no valid triangles")]
    NoTriangles(PathBuf),
    /// A config was given to the run of the other mode (`run_pixel` with `mode = "vertex"`,
    /// or the reverse).
    #[error("{}: mode = \"{mode}\" is baked by run_{mode}, not run_{called}", config.display())]
    WrongMode {
        /// The config file.
        config: PathBuf,
        /// The config's mode.
        mode: &'static str,
        /// The mode of the run that was called.
        called: &'static str,
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
    /// Planning, baking or writing the per-vertex tensors failed.
    #[error(transparent)]
    Vertex(#[from] VertexError),
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
