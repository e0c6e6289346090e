//! The per-vertex runtime's tests (`prt_runtime::VertexRelighter`), on synthetic per-vertex
//! bake files written with the container writer (no baker): one test binary, one module per
//! concern.

mod bench;
mod common;
mod errors;
mod face;
mod incident;
mod shading;
mod stages;

// The per-pixel synthetic bakes, for the tests that open both kinds.
#[allow(dead_code)]
#[path = "../suite/synthetic.rs"]
mod pixel_synthetic;
