//! The runtime's own tests, on synthetic bake files written with the container writer (no
//! baker): one test binary, one module per concern.

mod edits;
mod face;
mod fuzzed;
mod relight;
mod synthetic;
mod validation;
