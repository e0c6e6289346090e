//! The per-vertex runtime's tests (`prt_runtime::vertex`), on synthetic per-vertex bake files
//! written with the container writer (no baker): one test binary, one module per concern.

mod bench;
mod common;
mod errors;
mod incident;
mod shading;
mod stages;
