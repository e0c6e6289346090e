//! The runtime's error type (its own file so that every module can name it without importing
//! the crate root, which imports them).

use prt_formats::envmap::EnvMapError;
use prt_formats::lighting::LightingError;
use prt_formats::overrides::Param;
use prt_formats::FormatError;

use crate::vertex::view::RasterError;

/// Why a bake file could not be opened for relighting, or an edit or render was refused.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    /// The container itself is unreadable or corrupt (see [`FormatError`]).
    #[error(transparent)]
    Format(#[from] FormatError),
    /// The file is a valid container but not a consistent per-pixel bake (wrong schema
    /// version, metadata or tensor shapes).
    #[error("{path}: not a per-pixel bake file: {reason}")]
    Schema {
        /// The bake file, as given.
        path: String,
        /// What is inconsistent.
        reason: String,
    },
    /// An edit names a material the bake does not have.
    #[error("unknown material '{name}'; the bake has: {available}")]
    UnknownMaterial {
        /// The material name.
        name: String,
        /// The bake's material names, comma-separated.
        available: String,
    },
    /// An edit names a material that was not marked editable when baking.
    #[error("material '{name}' is not editable in this bake (editable: {editable})")]
    NotEditable {
        /// The material name.
        name: String,
        /// The editable materials, comma-separated.
        editable: String,
    },
    /// An edit sets a parameter the material's family does not have (e.g. `alpha` of a
    /// Blinn-Phong material).
    #[error("material '{name}' is {family}: it has no parameter '{param}' (it has {params})")]
    WrongParam {
        /// The material name.
        name: String,
        /// The material's BRDF family (`blinn-phong`, `ggx`, ...).
        family: String,
        /// The parameter given.
        param: String,
        /// The parameters the family has, comma-separated.
        params: String,
    },
    /// An edit's value lies outside the parameter's accepted range (a colour channel negative
    /// or not finite, a shininess or roughness outside its family's range).
    #[error("material '{name}': {param} = {value} is outside its valid range [{min}, {max}]")]
    OutOfRange {
        /// The material name.
        name: String,
        /// The parameter.
        param: Param,
        /// The value given, as text (a colour as `[r, g, b]`).
        value: String,
        /// The smallest value accepted (for a colour: per channel).
        min: f32,
        /// The largest value accepted (a colour's is infinite: any finite value).
        max: f32,
    },
    /// [`crate::Variant::Compressed`] was requested from a bake without a compressed variant.
    #[error("this bake file has no compressed variant (bake with a compression rank)")]
    NoCompressed,
    /// The file is a bake of the other kind (per-pixel opened as per-vertex, or the reverse).
    #[error("{path} is a {kind} bake, not a {expected} one: {hint}")]
    WrongKind {
        /// The bake file, as given.
        path: String,
        /// The kind the file is (`per-pixel`, `per-vertex`).
        kind: &'static str,
        /// The kind the caller reads.
        expected: &'static str,
        /// What to use instead.
        hint: &'static str,
    },
    /// The file is a valid container whose metadata names neither bake kind.
    #[error(
        "{path}: a PRT container but not a bake of a known kind (its metadata has neither \
         pixel_schema_version nor vertex_schema_version)"
    )]
    UnknownKind {
        /// The file, as given.
        path: String,
    },
    /// The file is a valid container but not a consistent per-vertex bake (wrong schema
    /// version, metadata, tensor types or shapes, indices out of range); the reason names the
    /// tensor or field.
    #[error("{path}: not a consistent per-vertex bake file: {reason}")]
    VertexSchema {
        /// The bake file, as given.
        path: String,
        /// What is inconsistent.
        reason: String,
    },
    /// The image size or the camera cannot be rendered (zero or non-finite field of view,
    /// non-finite frame, ...).
    #[error(transparent)]
    Raster(#[from] RasterError),
    /// The camera's eye is inside an object (the rule the baker applies to a view,
    /// [`prt_formats::view::judge_eye`]).
    #[error(
        "the eye ({}, {}, {}) is inside '{material}': {back} of {total} directions from it \
         meet the back of a surface first; place the camera outside the object",
        eye[0], eye[1], eye[2]
    )]
    EyeInside {
        /// The eye position.
        eye: [f32; 3],
        /// The material most seen from behind.
        material: String,
        /// Directions meeting a back side first.
        back: usize,
        /// Directions traced.
        total: usize,
    },
    /// An environment map handed over in memory is unusable (empty, wrong texel count,
    /// NaN or infinite texels, ...), or its intensity is negative or not finite.
    #[error("environment map: {0}")]
    Environment(#[from] EnvMapError),
    /// An environment map file cannot be read or used.
    #[error("environment map {path}: {source}")]
    EnvironmentFile {
        /// The file, as given.
        path: String,
        /// Why.
        source: EnvMapError,
    },
    /// The environment could not be turned into light coefficients (a non-finite rotation,
    /// a split width the prefilter refuses).
    #[error("environment: {0}")]
    Lighting(#[from] LightingError),
    /// A caller's buffer (the image rendered into, an environment's texels) does not hold
    /// `width * height` RGB pixels.
    #[error("{what} holds {got} floats; a {width}x{height} RGB image needs {expected}")]
    BufferSize {
        /// Which buffer.
        what: &'static str,
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
        /// Floats needed (`3 * width * height`).
        expected: usize,
        /// Floats given.
        got: usize,
    },
}
