//! Why a scene could not be loaded: [`SceneError`] names the file and the object at fault
//! (mesh and primitive, buffer, image, material, ...) and carries the typed cause.

use std::path::PathBuf;

use super::envmap::EnvMapError;
use super::gltf::accessors::AccessorError;
use super::gltf::material::BrdfConfigError;
use super::gltf::source::{GltfParseError, UriError};

/// Why a scene could not be loaded. Every message names the file at fault and the problem.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The glTF/GLB file itself could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The glTF/GLB container or JSON is malformed or fails validation.
    #[error("{}: {source}", path.display())]
    Parse {
        path: PathBuf,
        #[source]
        source: GltfParseError,
    },
    /// A buffer could not be read or is shorter than declared.
    #[error("{}: buffer {index} ({source_label}): {source}", path.display())]
    Buffer {
        path: PathBuf,
        index: usize,
        /// Where the bytes come from: a quoted URI, "embedded data URI" or "GLB BIN chunk".
        source_label: String,
        #[source]
        source: Box<ResourceError>,
    },
    /// A texture image could not be read or decoded.
    #[error("{}: image {index} ({source_label}): {source}", path.display())]
    Image {
        path: PathBuf,
        index: usize,
        /// Where the bytes come from: a quoted URI, "embedded data URI" or "buffer view N".
        source_label: String,
        #[source]
        source: Box<ResourceError>,
    },
    /// A mesh primitive's data is malformed (bad accessor, out-of-range index, ...).
    #[error("{}: mesh \"{mesh}\" primitive {primitive}: {source}", path.display())]
    Mesh {
        path: PathBuf,
        mesh: String,
        primitive: usize,
        #[source]
        source: Box<MeshError>,
    },
    /// A material's glTF data or its config overrides are unusable; `path` is the file at
    /// fault (the glTF or the bake config).
    #[error("{}: material \"{material}\": {source}", path.display())]
    Material {
        path: PathBuf,
        material: String,
        #[source]
        source: Box<MaterialError>,
    },
    /// The config names materials that the glTF does not have.
    #[error(
        "{}: [materials.{name}] names no material of {}; available: {}",
        config.display(),
        scene.display(),
        available.join(", ")
    )]
    UnknownMaterial {
        config: PathBuf,
        scene: PathBuf,
        name: String,
        available: Vec<String>,
    },
    /// Anything else wrong with the scene (nodes, lights, camera).
    #[error("{}: {message}", path.display())]
    Invalid { path: PathBuf, message: String },
    /// The environment map could not be used.
    #[error("environment map {}: {source}", path.display())]
    Environment {
        path: PathBuf,
        #[source]
        source: Box<EnvMapError>,
    },
}

/// Why the bytes of a buffer or an image could not be had.
#[derive(Debug, thiserror::Error)]
pub enum ResourceError {
    /// The URI is malformed or of an unsupported kind.
    #[error(transparent)]
    Uri(#[from] UriError),
    /// The file the URI names could not be read.
    #[error("cannot read {}: {source}", file.display())]
    Read {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Buffer 0 has no URI but the file has no GLB `BIN` chunk.
    #[error("the buffer has no URI and the file has no GLB BIN chunk")]
    NoBinChunk,
    /// A buffer other than 0 has no URI.
    #[error("only buffer 0 may use the GLB BIN chunk; this one has no URI")]
    BinChunkNotFirst,
    /// The data is shorter than the buffer's declared `byteLength`.
    #[error("holds {len} bytes but the glTF declares byteLength {declared}")]
    Short { len: usize, declared: usize },
    /// An image's buffer view is malformed.
    #[error(transparent)]
    View(#[from] AccessorError),
    /// The image bytes are not a decodable PNG/JPEG/....
    #[error("cannot decode: {0}")]
    Decode(#[source] image::ImageError),
}

/// What is wrong with a mesh primitive.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// An attribute or index accessor is malformed.
    #[error(transparent)]
    Accessor(#[from] AccessorError),
    #[error("no POSITION attribute")]
    NoPosition,
    /// An attribute has a different element count than POSITION.
    #[error("{attribute} has {found} elements but POSITION has {positions}")]
    CountMismatch {
        attribute: &'static str,
        found: usize,
        positions: usize,
    },
    #[error(
        "index {index} (entry {entry} of accessor {accessor}) is out of range: the primitive \
         has {vertices} vertices"
    )]
    IndexOutOfRange {
        index: u32,
        entry: usize,
        accessor: usize,
        vertices: usize,
    },
    /// The index (or, non-indexed, vertex) count is not a multiple of 3.
    #[error("{count} {what} is not a multiple of 3 (mode TRIANGLES)")]
    NotTriangles { count: usize, what: &'static str },
    #[error("{0} vertices is too many")]
    TooManyVertices(usize),
    #[error("the scene has more than 2^32 vertices")]
    SceneTooLarge,
}

/// What is wrong with a material's glTF values or its config overrides.
#[derive(Debug, thiserror::Error)]
pub enum MaterialError {
    #[error("baseColorFactor {0:?} must be finite and >= 0")]
    BaseColor([f32; 4]),
    #[error("metallicFactor/roughnessFactor must be finite")]
    Factors,
    #[error("emission {0:?} (emissiveFactor x emissiveStrength) must be finite and >= 0")]
    Emission(glam::Vec3),
    /// The config's overrides do not fit the material (see [`super::resolve_brdf`]).
    #[error(transparent)]
    Brdf(#[from] BrdfConfigError),
}
