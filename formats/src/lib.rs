//! Shared infrastructure of the baker and the runtime (which must never depend on the baker):
//! the bake-file container, image output, and the material-override syntax of the CLIs.
//!
//! * [`container`]: the bake file (safetensors layout, checksums, versioning, zero-copy reads).
//! * [`envmap`]: loading and checking lat-long environment maps (EXR, HDR, in memory).
//! * [`family`]: the BRDF families and which parameter fits which family.
//! * [`image_io`]: EXR/PNG writing (atomic) and EXR reading (feature `image-io`, on by
//!   default, as is loading environment maps from files; without it the crate links no image
//!   codecs).
//! * [`latlong`]: the lat-long (equirectangular) environment mapping, uv <-> direction.
//! * [`lobe`]: the families' specular lobes (the baker's and the runtime's formulas).
//! * [`lighting`]: the lighting bases of the per-vertex mode (cube maps, Haar wavelets,
//!   spherical harmonics, the Gaussian prefilter).
//! * [`normal_map`]: tangent-space normal maps (the bent shading normal every part uses).
//! * [`overrides`]: `--set MATERIAL.PARAM=VALUE` parsing.
//! * [`basis`]: the persisted BRDF basis of editable materials and its evaluation.
//! * [`pixel`]: the per-pixel bake schema (metadata, slots, relighting weights).
//! * [`texture`]: the bilinear texture lookup both the baker and the runtime use.
//! * [`vertex`]: the per-vertex bake schema (metadata, tensor names, the vertex frame).
//! * [`view`]: the `--camera eye=.. target=.. fov=..` syntax and the camera frame it gives.

#![warn(missing_docs)]

pub mod basis;
pub mod clustered;
pub mod container;
pub mod envmap;
pub mod family;
#[cfg(feature = "image-io")]
pub mod image_io;
pub mod latlong;
pub mod lighting;
pub mod lobe;
pub mod normal_map;
pub mod overrides;
pub mod pixel;
pub mod texture;
pub mod vertex;
pub mod view;

pub use container::{
    BakeFile, BakeWriter, Dtype, Element, FormatError, TensorView, FORMAT_NAME, SCHEMA_VERSION,
    TENSOR_ALIGN,
};
pub use family::Family;
#[cfg(feature = "image-io")]
pub use image_io::{
    read_exr_rgb, write_exr, write_image, write_image_with, write_png, write_png_with,
    ImageIoError, Srgb8Table, ToneCurve,
};
pub use overrides::{
    check_material, parse_override, MaterialOverride, OverrideError, OverrideValue, Param,
};

/// One line for an error and its causes, for the CLIs: each cause is appended unless its text
/// already appears in what is written (many of our errors quote their source).
pub fn describe_error(e: &(dyn std::error::Error + 'static)) -> String {
    let mut out = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let text = s.to_string();
        if !out.contains(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
        source = s.source();
    }
    out
}
