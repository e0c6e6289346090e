//! How the library reports progress and notes on long work without printing: the caller (a
//! binary with a progress bar, a report generator, a test) implements [`Progress`].
//!
//! Every method has a no-op default, so an implementation handles only what it shows. Methods
//! take `&self` and the trait requires `Sync`, because work items finish on rayon's threads.

/// Receives progress and notes from long library calls.
pub trait Progress: Sync {
    /// A stage of `total` steps begins (e.g. "baking", one step per image row).
    fn start(&self, _stage: &str, _total: u64) {}
    /// `steps` more steps of the current stage are done.
    fn advance(&self, _steps: u64) {}
    /// `steps` more steps of the current stage were done by an earlier run (restored from a
    /// checkpoint): they count as done but took no time now, so a rate or ETA should leave
    /// them out. Defaults to [`Progress::advance`].
    fn restored(&self, steps: u64) {
        self.advance(steps);
    }
    /// The current stage is over.
    fn finish(&self) {}
    /// Something the user should know before the work goes on (the allocation report, the
    /// basis size chosen for an error target).
    fn note(&self, _text: &str) {}
    /// Something that may be wrong but does not stop the work.
    fn warn(&self, _text: &str) {}
    /// Whether the caller wants the work stopped (Ctrl-C in a notebook, a cancel button). Long
    /// calls ask between units of work (a per-pixel bake between rows, a per-vertex bake between
    /// batches of units) and return [`Cancelled`]: nothing is written, and a per-vertex bake's
    /// checkpoint keeps the finished units for a resume.
    fn cancelled(&self) -> bool {
        false
    }
}

/// The error a long call returns when [`Progress::cancelled`] said so.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("cancelled: nothing was written (a per-vertex bake keeps its finished units in its checkpoint; --resume continues it)")]
pub struct Cancelled;

/// Reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Progress for Silent {}

/// Runs `stage` over `total` steps on `progress` (if any), finishing it even on early return.
pub(crate) struct Stage<'a>(Option<&'a dyn Progress>);

impl<'a> Stage<'a> {
    pub(crate) fn start(progress: Option<&'a dyn Progress>, stage: &str, total: u64) -> Self {
        if let Some(p) = progress {
            p.start(stage, total);
        }
        Stage(progress)
    }

    pub(crate) fn advance(&self, steps: u64) {
        if let Some(p) = self.0 {
            p.advance(steps);
        }
    }

    pub(crate) fn restored(&self, steps: u64) {
        if let Some(p) = self.0 {
            p.restored(steps);
        }
    }

    /// [`Cancelled`] when the caller asked to stop.
    pub(crate) fn check(&self) -> Result<(), Cancelled> {
        match self.0 {
            Some(p) if p.cancelled() => Err(Cancelled),
            _ => Ok(()),
        }
    }
}

impl Drop for Stage<'_> {
    fn drop(&mut self) {
        if let Some(p) = self.0 {
            p.finish();
        }
    }
}
