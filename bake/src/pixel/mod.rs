//! The per-pixel baker (thesis ch. 4; docs/pixel.md): traces the camera's paths once
//! and accumulates, per pixel and per visible material, the transfer tensors T0, T1, T2 over
//! the materials' slots (see `prt_formats::pixel` for the layout and its meaning).
//!
//! The paths are those of the shared [`Integrator`](crate::integrator::Integrator) under the [`BakeModel`]: fixed materials
//! are sampled by their true BRDF, editable ones by a density that does not depend on their
//! coefficients (a mixture of cosine and the family's lobes), so one trace serves every
//! coefficient setting, and the same model drives the projected-BRDF reference render.
//!
//! The files: [`SlotLayout`] (which slots each material gets), [`BakeModel`] (slot evaluation
//! and sampling), the accumulation sink, compaction to active slots, the low-rank variant
//! ([`pca_rows`]), the memory estimate and the file writer.

mod bake;
mod compact;
mod compress;
mod error;
mod layout;
pub(crate) mod memory;
mod model;
mod pieces;
mod sink;
mod write;

pub(crate) use bake::persisted_bases;
pub use bake::{
    bake, bake_with, finish_rows, pixel_common, trace_rows, BakeTimings, GroupData, PixelBake,
    PixelBakeOptions, PixelCommon, RowOut,
};
pub use compress::{pca_rows, Compressed};
pub use error::PixelError;
pub use layout::{SlotLayout, SlotPlan};
pub use memory::{estimate_memory, MemoryEstimate};
pub use model::BakeModel;
pub use pieces::{pixel_fingerprints, row_from_piece, row_piece};
pub use prt_formats::pixel::{names, Precision};
pub use write::{to_f16_scaled, write_bake_file};
