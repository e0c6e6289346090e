//! PRT runtime: opens a bake file and produces images for any setting of its editable
//! materials (and, for a per-vertex bake, any environment, camera and image size), without
//! tracing a ray. It depends only on `prt-formats`, never on the baker.
//!
//! One way in for both kinds of bake: [`open`] reads the kind from the file and gives a
//! [`Relighter`]; materials are listed, read and set the same way for both; a render writes a
//! caller's flat buffer (`3 * width * height` floats, linear RGB, row-major, top row first)
//! or returns an [`Image`]. What only one kind has (the per-vertex environment, camera and
//! size; the per-pixel compressed variant) is reached by matching on the kind.
//!
//! ```no_run
//! use prt_runtime::{OverrideValue, Relighter, RuntimeError};
//!
//! fn main() -> Result<(), RuntimeError> {
//!     let mut r = prt_runtime::open("out/vitrine.prtbake")?;
//!     for m in r.materials() {
//!         println!("{} ({}): {:?}", m.name, m.family, m.params);
//!     }
//!     r.set_params("sphere", &[OverrideValue::Kd([0.8, 0.2, 0.2]), OverrideValue::Alpha(0.3)])?;
//!     if let Relighter::Vertex(v) = &mut r {
//!         v.load_environment("scenes/envmaps/studio.exr")?;
//!         v.set_environment_rotation(90.0)?;
//!         v.set_camera(v.default_camera().orbited(30.0))?;
//!         v.set_size(800, 600)?;
//!     }
//!     let image = r.render()?; // an owned image
//!     let (width, height) = r.size();
//!     let mut frame = vec![0.0f32; 3 * width as usize * height as usize];
//!     r.render_into(&mut frame)?; // the caller's memory, no copy
//!     assert_eq!(image.pixels.as_flattened(), &frame[..]);
//!     Ok(())
//! }
//! ```
//!
//! The two kinds (docs/design.md, "Inside `prt-runtime`"):
//! - [`PixelRelighter`] (`pixel/`): camera and light frozen into the file, materials edited
//!   (docs/pixel.md, "Storage and relighting").
//! - [`VertexRelighter`] (`vertex/`): environment, camera and materials all edited
//!   (docs/vertex.md).
//!
//! Both take material edits by the same rules (`materials.rs`) and render into the same image
//! layout (`image.rs`). Cargo features: `image-io` (default) lets a per-vertex bake load an
//! environment map from a file (EXR, HDR; without it `prt-formats` is linked without its
//! image codecs); `hooks` adds the measurement and inspection hooks of [`hooks`] for
//! `prt-bench` and the tests.

#![warn(missing_docs)]

mod error;
#[cfg(feature = "hooks")]
pub mod hooks;
/// With the feature `gpu-surface` only: what a GPU backend (`prt-gpu`) reads of a per-vertex
/// relighter besides its public face (docs/gpu.md): the light and material stages' results and
/// the view stage's per-frame inputs, as read-only views. A per-pixel relighter gives its
/// file and slot coefficients (`PixelRelighter::file`, `PixelRelighter::coefficients`).
#[cfg(feature = "gpu-surface")]
pub mod gpu_surface {
    pub use crate::vertex::compact_lights::CompactLight;
    pub use crate::vertex::surface::{
        ClusteredTensor, SplitWidth, StageConstants, StageGroup, StageTensor, Stages, StoredValues,
        SurfaceLobe, SurfaceMaterial, VertexSurface, RECORD_E, RECORD_I1, RECORD_I2, RECORD_U,
    };
}
mod image;
mod materials;
mod pixel;
mod vertex;

use std::path::Path;

pub use error::RuntimeError;
pub use image::{Image, RenderStats};
pub use materials::{MaterialInfo, ParamInfo, ParamRange};
pub use pixel::{PixelRelighter, Variant};
pub use vertex::{RasterError, VertexRelighter, DEFAULT_IMAGE_SIDE};

// The types the face's signatures (and its errors) use, and `CameraSpec`, which makes a
// `CameraFrame` from an eye, a target and a field of view, so a caller can name them without
// depending on `prt-formats` itself.
pub use prt_formats::envmap::{EnvMapError, EnvMapReport, LatLongMap};
pub use prt_formats::lighting::LightingError;
pub use prt_formats::overrides::{OverrideValue, Param};
pub use prt_formats::pixel::MaterialParams;
pub use prt_formats::vertex::BakeKind;
pub use prt_formats::view::{CameraFrame, CameraSpec};
pub use prt_formats::{BakeFile, Family, FormatError};

// A relighter moves between threads: the Python binding renders with the interpreter's lock
// released, and a server renders on a worker thread.
const _: () = {
    const fn sendable<T: Send>() {}
    sendable::<Relighter>();
};

/// Opens a bake file of either kind (checksums verified) and validates it as that kind: see
/// [`Relighter::open`].
pub fn open(path: impl AsRef<Path>) -> Result<Relighter, RuntimeError> {
    Relighter::open(path)
}

/// An opened bake of either kind, with its current settings.
///
/// An enum rather than a trait both kinds implement: the kinds are a closed set (the bake
/// file's own kind tag, [`BakeKind`]), so a caller holds one value without boxing, the shared
/// calls are a `match` each, and what one kind alone has is reached by matching on the
/// variant, with no downcast and no method that exists on one kind only to refuse.
// A caller holds one per opened bake and does not move it around in bulk, so the variants'
// different sizes cost nothing worth a box (which every match would then see).
#[allow(clippy::large_enum_variant)]
pub enum Relighter {
    /// A per-pixel bake.
    Pixel(PixelRelighter),
    /// A per-vertex bake.
    Vertex(VertexRelighter),
}

impl Relighter {
    /// Opens a bake file (checksums verified) and validates it as the kind its metadata
    /// names. A file that is no bake container is refused with [`RuntimeError::Format`] (the
    /// reason names the file), a container of neither kind with
    /// [`RuntimeError::UnknownKind`], an inconsistent bake with [`RuntimeError::Schema`] or
    /// [`RuntimeError::VertexSchema`].
    pub fn open(path: impl AsRef<Path>) -> Result<Relighter, RuntimeError> {
        Relighter::from_file(BakeFile::open(path)?)
    }

    /// Validates an opened bake file as the kind its metadata names (see
    /// [`Relighter::open`]).
    pub fn from_file(file: BakeFile) -> Result<Relighter, RuntimeError> {
        match BakeKind::of_metadata(file.metadata()) {
            Some(BakeKind::Pixel) => Ok(Relighter::Pixel(PixelRelighter::from_file(file)?)),
            Some(BakeKind::Vertex) => Ok(Relighter::Vertex(VertexRelighter::from_file(file)?)),
            None => Err(RuntimeError::UnknownKind {
                path: file.path().display().to_string(),
            }),
        }
    }

    /// The bake's kind.
    pub fn kind(&self) -> BakeKind {
        match self {
            Relighter::Pixel(_) => BakeKind::Pixel,
            Relighter::Vertex(_) => BakeKind::Vertex,
        }
    }

    /// Every material of the bake with its family, whether it is editable, its current
    /// parameters and each parameter's valid (and sampled) range, in the bake's order.
    pub fn materials(&self) -> Vec<MaterialInfo> {
        match self {
            Relighter::Pixel(r) => r.materials(),
            Relighter::Vertex(r) => r.materials(),
        }
    }

    /// Current parameters of material `name` ([`RuntimeError::UnknownMaterial`] when the bake
    /// has none of that name).
    pub fn params(&self, name: &str) -> Result<MaterialParams, RuntimeError> {
        match self {
            Relighter::Pixel(r) => r.params(name),
            Relighter::Vertex(r) => r.params(name),
        }
    }

    /// Sets parameters of the editable material `name`, all or none: each value is checked
    /// before any is applied, and a refused edit changes nothing. Refused, naming what is
    /// wrong: a material the bake does not have ([`RuntimeError::UnknownMaterial`]) or did not
    /// bake editable ([`RuntimeError::NotEditable`]), a parameter its family does not have
    /// ([`RuntimeError::WrongParam`]), a value outside the parameter's valid range
    /// ([`RuntimeError::OutOfRange`], the range as [`ParamInfo::range`] gives it). A lobe
    /// parameter outside the bake's sampled range is accepted and rendered clamped to it
    /// ([`ParamInfo::clamped`]). `relight --set MATERIAL.PARAM=VALUE` is
    /// `set_params(MATERIAL, &[VALUE])`.
    pub fn set_params(&mut self, name: &str, values: &[OverrideValue]) -> Result<(), RuntimeError> {
        match self {
            Relighter::Pixel(r) => r.set_params(name, values),
            Relighter::Vertex(r) => r.set_params(name, values),
        }
    }

    /// The size `(width, height)` of the images rendered now.
    pub fn size(&self) -> (u32, u32) {
        match self {
            Relighter::Pixel(r) => r.size(),
            Relighter::Vertex(r) => r.size(),
        }
    }

    /// Renders the image for the current settings into `out`: `3 * width * height` floats
    /// ([`Relighter::size`]), linear RGB, row-major, top row first; a buffer of any other
    /// length is refused with [`RuntimeError::BufferSize`]. Every float is written, none is
    /// read, nothing is allocated per frame once the sizes have settled.
    pub fn render_into(&mut self, out: &mut [f32]) -> Result<RenderStats, RuntimeError> {
        match self {
            Relighter::Pixel(r) => r.render_into(out),
            Relighter::Vertex(r) => r.render_into(out),
        }
    }

    /// Renders the image for the current settings into a new [`Image`] (the same bits as
    /// [`Relighter::render_into`]).
    pub fn render(&mut self) -> Result<Image, RuntimeError> {
        match self {
            Relighter::Pixel(r) => r.render(),
            Relighter::Vertex(r) => r.render(),
        }
    }
}
