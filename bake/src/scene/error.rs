//! Why a scene could not be loaded: [`SceneError`] names the file and the object at fault
//! (mesh and primitive, buffer, image, material, ...) and carries the typed cause.

use std::path::PathBuf;

use gltf::accessor::DataType;
use prt_formats::Family;

use super::envmap::EnvMapError;

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
    /// The URI names a device, pipe or folder rather than a file: reading one could block or
    /// never end (`/dev/zero`).
    #[error("{} is not a regular file", file.display())]
    NotAFile { file: PathBuf },
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
    #[error("normalTexture scale {0} must be finite")]
    NormalScale(f32),
    #[error("emission {0:?} (emissiveFactor x emissiveStrength) must be finite and >= 0")]
    Emission(glam::Vec3),
    /// The config's overrides do not fit the material (see [`super::resolve_brdf`]).
    #[error(transparent)]
    Brdf(#[from] BrdfConfigError),
}

/// Why an accessor or buffer view cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum AccessorError {
    #[error("buffer view {view} refers to missing buffer {buffer}")]
    MissingBuffer { view: usize, buffer: usize },
    #[error("buffer view {view}: offset + length overflows")]
    ViewOverflow { view: usize },
    #[error(
        "buffer view {view} (bytes {start}..{end}) runs past the end of buffer {buffer} \
         ({len} bytes)"
    )]
    ViewPastEnd {
        view: usize,
        start: usize,
        end: usize,
        buffer: usize,
        len: usize,
    },
    /// The accessor's type (SCALAR, VEC2, ...) is not the one the attribute needs.
    #[error("{what} accessor {accessor} has type {found}, expected {expected}")]
    WrongType {
        what: &'static str,
        accessor: usize,
        found: &'static str,
        expected: String,
    },
    #[error(
        "{what} accessor {accessor} has component type {component:?}{}, which is not \
         supported here",
        if *normalized { " (normalized)" } else { "" }
    )]
    UnsupportedComponent {
        what: &'static str,
        accessor: usize,
        component: DataType,
        normalized: bool,
    },
    #[error(
        "index accessor {accessor} has component type {component:?}; indices must be unsigned \
         bytes, shorts or ints"
    )]
    IndexComponent {
        accessor: usize,
        component: DataType,
    },
    #[error("size overflows")]
    SizeOverflow,
    #[error("{count} elements need {needed} bytes but its buffer view has {len}")]
    TooShort {
        count: usize,
        needed: usize,
        len: usize,
    },
    #[error("byteStride {stride} is smaller than the element size {element}")]
    StrideTooSmall { stride: usize, element: usize },
    #[error("{0} elements without a buffer view is implausibly large")]
    TooManyVirtual(usize),
    #[error("sparse index {index} is out of range (count {count})")]
    SparseIndexOutOfRange { index: usize, count: usize },
    /// One of the above, in a named part of an accessor (e.g. "POSITION accessor 3 sparse
    /// indices").
    #[error("{context}: {source}")]
    In {
        context: String,
        #[source]
        source: Box<AccessorError>,
    },
}

/// Why a material's config overrides do not fit it (see [`resolve_brdf`]).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BrdfConfigError {
    /// A parameter the resolved family does not use.
    #[error(
        "`{key}` does not apply to family \"{}\"{}; set `family` to one that uses it",
        family.name(),
        if *family_from_gltf {
            format!(" (the glTF material maps to {})", family.name())
        } else {
            String::new()
        }
    )]
    StrayParameter {
        key: &'static str,
        family: Family,
        /// The family is the glTF mapping's (the config gave none).
        family_from_gltf: bool,
    },
    /// An editable specular family whose glTF material supplies no specular lobe, without the
    /// config keys (`missing`: "ks", "alpha" or "shininess") that would give it one.
    #[error(
        "editable family \"{}\" needs {} in the config: {} and supplies no specular lobe",
        family.name(),
        missing.iter().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(" and "),
        if *default_material {
            "the default material is plain diffuse"
        } else {
            "the glTF material is a fully rough dielectric (it maps to diffuse)"
        }
    )]
    MissingSpecular {
        family: Family,
        missing: Vec<&'static str>,
        /// The material is the `default` one (primitives without a material).
        default_material: bool,
    },
}

/// Why a `.gltf`/`.glb` byte string is not a usable glTF document.
#[derive(Debug, thiserror::Error)]
pub enum GltfParseError {
    #[error("the file is empty")]
    Empty,
    /// Fewer bytes than a GLB header plus one chunk header.
    #[error("truncated GLB: {len} bytes, a GLB needs at least a 12-byte header and a chunk")]
    TooShort { len: usize },
    #[error("corrupt GLB header: declared length {declared} < 20")]
    BadLength { declared: usize },
    #[error("truncated GLB: the header declares {declared} bytes but the file has {len}")]
    Truncated { declared: usize, len: usize },
    /// Schema validation failed; the first few problems, as `path: problem`.
    #[error("invalid glTF: {}{}", problems.join("; "), more_label(*more))]
    Invalid {
        problems: Vec<String>,
        /// How many further problems were left out.
        more: usize,
    },
    #[error("malformed glTF JSON: {0}")]
    Json(#[source] gltf::json::Error),
    /// Any other error of the glTF crate (bad GLB chunk, ...).
    #[error("{0}")]
    Other(#[source] gltf::Error),
    /// The glTF crate panicked on this input.
    #[error("the glTF parser failed on this input (malformed file)")]
    ParserPanicked,
}

/// Why a buffer or image URI cannot be resolved.
#[derive(Debug, thiserror::Error)]
pub enum UriError {
    #[error("malformed data URI (no ',')")]
    MalformedData,
    #[error("only base64 data URIs are supported")]
    NotBase64,
    #[error(transparent)]
    Base64(#[from] Base64Error),
    #[error("URI scheme \"{0}:\" is not supported (only relative paths, file:// and data:)")]
    UnsupportedScheme(String),
    #[error("bad percent-encoding in URI \"{0}\"")]
    BadPercent(String),
    #[error("URI \"{0}\" is not UTF-8 after decoding")]
    NotUtf8(String),
}

/// Why a base64 payload cannot be decoded.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum Base64Error {
    #[error("invalid base64: data after '=' padding at byte {0}")]
    AfterPadding(usize),
    #[error("invalid base64 character {ch:?} at byte {pos}")]
    BadCharacter { ch: char, pos: usize },
    #[error("invalid base64: truncated data")]
    Truncated,
}

/// " (and N more)" for lists cut short in messages.
fn more_label(more: usize) -> String {
    if more > 0 {
        format!(" (and {more} more)")
    } else {
        String::new()
    }
}
