//! One group's traced results in f32, in vertex order, before their conversion to storage: what
//! a block of vertices produces, what a group accumulates, and what a checkpoint saves.

/// Traced results of consecutive vertices of one group, in vertex order.
#[derive(Debug, Default, PartialEq)]
pub(crate) struct GroupBuffers {
    pub(crate) t0_index: Vec<u16>,
    pub(crate) t0_value: Vec<f32>,
    pub(crate) visibility: Vec<u8>,
    pub(crate) t1: Vec<f32>,
    pub(crate) t2: Vec<f32>,
    pub(crate) rays: u64,
    /// Sums of squares of the T0 coefficients, all and dropped (for the truncation error).
    pub(crate) t0_total: f64,
    pub(crate) t0_dropped: f64,
}

impl GroupBuffers {
    /// Appends `other`'s vertices. The f64 sums are added in call order, so appending the
    /// same blocks in the same order gives the same bits whatever ran them.
    pub(crate) fn append(&mut self, other: GroupBuffers) {
        self.t0_index.extend(other.t0_index);
        self.t0_value.extend(other.t0_value);
        self.visibility.extend(other.visibility);
        self.t1.extend(other.t1);
        self.t2.extend(other.t2);
        self.rays += other.rays;
        self.t0_total += other.t0_total;
        self.t0_dropped += other.t0_dropped;
    }
}
