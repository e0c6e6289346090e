//! The crate's integration tests, one module per concern, compiled as one test binary (one
//! link instead of one per file keeps CI's build short).

mod container;
mod image_io;
mod lighting;
mod metadata;
mod overrides;
mod python_compat;
mod shading_basis;
