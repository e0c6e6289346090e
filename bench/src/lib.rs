//! Measurements and generated reports of the PRT baker and runtime, run by the `bench` binary:
//!
//! ```text
//! cargo run --release -p prt-bench -- pixel        docs/report-pixel.md (per-pixel speed vs error)
//! cargo run --release -p prt-bench -- basis --report docs/brdf-basis.md
//! cargo run --release -p prt-bench -- rays         ray throughput
//! cargo run --release -p prt-bench -- container    bake file write/open/verify throughput
//! cargo run --release -p prt-bench -- vertex       docs/report-vertex.md (per-vertex compression, error, speed)
//! cargo run --release -p prt-bench --features gpu -- gpu --vertex V --pixel P   GPU backend vs goals (bench/gpu.sh)
//! ```
//!
//! Speed is measured here and printed or written into the reports, never asserted in tests.

pub mod basis;
pub mod container;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod pictures;
pub mod pixel;
pub mod plot;
pub mod rays;
pub mod template;
pub mod util;
pub mod vertex;
