//! Measurement and inspection hooks, compiled with the `hooks` feature only (`prt-bench` and
//! the tests enable it): what a benchmark switches or times beside the frames, and the
//! intermediate results the tests check against sums of their own. Not part of the face an
//! application uses; it may change with the runtime's internals.
//!
//! The relighters' methods that take or give these are gated the same way:
//! `set_kernel` (both kinds), `coefficients` (both), `PixelRelighter::time_reads`,
//! `VertexRelighter::vertex_incident`, `VertexRelighter::prefilter_runs`,
//! `VertexRelighter::set_direct_light_only`, `VertexRelighter::set_true_lobe`.

pub use crate::vertex::incident::VertexIncident;
pub use crate::vertex::light::LightCoefficients;
pub use crate::vertex::true_lobe::TrueLobe;

/// Which inner loops a relighter runs. Both give bit-identical frames (the per-lane
/// arithmetic is the same); the switch exists so tests and measurements can run the portable
/// path on a CPU that has the vector instructions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Kernel {
    /// The fastest the CPU supports: AVX2 (and F16C for f16 bakes) on x86-64, else portable.
    #[default]
    Auto,
    /// The portable scalar code, whatever the CPU.
    Scalar,
}

/// The time of `PixelRelighter::time_reads`: a frame's reads without its arithmetic.
#[derive(Clone, Copy, Debug)]
pub struct ReadPass {
    /// Wall-clock time, in seconds.
    pub seconds: f64,
    /// Bytes of bake data read (the same count as the frame's `RenderStats::bytes_read`).
    pub bytes_read: u64,
}
