//! The runtime's own tests, on synthetic bake files written with the container writer (no
//! baker): one test binary, one module per concern.

mod edits;
mod fuzzed;
mod raster;
mod relight;
mod synthetic;
mod validation;
