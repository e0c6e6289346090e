//! The measurement hooks of the per-vertex relighter (feature `hooks`): switches the error
//! budget and the kernel benchmarks turn, kept apart from the relighter's user-facing setters.

use super::VertexRelighter;

impl VertexRelighter {
    /// Chooses the view stage's inner loops (default [`crate::hooks::Kernel::Auto`]: AVX2
    /// when the CPU has it); the frames are the same bit for bit, only the speed differs.
    #[cfg(feature = "hooks")]
    pub fn set_kernel(&mut self, kernel: crate::hooks::Kernel) {
        self.simd = kernel == crate::hooks::Kernel::Auto;
    }

    /// Lights the scene with the direct light alone (`on`), or with every path the bake
    /// holds: the light after one and two reflections before the last (I1 and I2) is made
    /// zero by lighting their tensors with black coarse cubes `C1` and `C2`, so each vertex's
    /// irradiance and incident projections are T0's alone. The error budget compares this
    /// with a reference tracer of one reflection. Runs the stages here (not on a device).
    #[cfg(feature = "hooks")]
    pub fn set_direct_light_only(&mut self, on: bool) {
        self.set_host_vertex_stages(true);
        if self.direct_light_only != on {
            self.direct_light_only = on;
            self.light = None;
            self.shaded = None;
        }
    }

    /// Shades the last reflection's specular part with the true lobe (`Some`: the caller's
    /// sampler, `side x side` stratified draws per pixel) instead of the Tucker shading basis
    /// and the specular split, against the same incident light (the environment through the
    /// vertices' visibility cubes, I1's SH, I2): the error budget's measure of the shading
    /// basis. `None` goes back to the basis. Only this relighter's (CPU) view stage changes;
    /// a GPU backend's frames do not.
    #[cfg(feature = "hooks")]
    pub fn set_true_lobe(
        &mut self,
        lobe: Option<(std::sync::Arc<dyn crate::hooks::TrueLobe>, u32)>,
    ) {
        self.true_lobe = lobe;
    }

    /// How many times the environment's prefilter has run (once per map: a turn or an
    /// intensity change reuses its cubes).
    #[cfg(feature = "hooks")]
    pub fn prefilter_runs(&self) -> u64 {
        self.prefiltered.runs
    }
}
