//! `prt.bake`: the `bake` command's job from Python, through the baker's library API
//! (`prt_bake::run`), with progress and cancellation through [`crate::progress`]. Everything
//! the binding uses of the bake API is in this file.

use std::path::PathBuf;

use prt_bake::config::Mode;
use prt_bake::pixel::Precision;
use prt_bake::progress::Progress;
use prt_bake::run::{
    load, run_pixel, run_vertex, CheckpointMode, PixelRunSettings, VertexRunSettings,
};
use pyo3::prelude::*;

use crate::errors::{self, message, Kind};
use crate::progress::{self, Reporter};

impl Progress for Reporter {
    fn start(&self, stage: &str, total: u64) {
        Reporter::start(self, stage, total);
    }
    fn advance(&self, steps: u64) {
        Reporter::advance(self, steps);
    }
    fn restored(&self, steps: u64) {
        Reporter::restored(self, steps);
    }
    fn finish(&self) {
        Reporter::finish(self);
    }
    fn note(&self, text: &str) {
        Reporter::note(self, text);
    }
    fn warn(&self, text: &str) {
        Reporter::warn(self, text);
    }
    fn cancelled(&self) -> bool {
        Reporter::cancelled(self)
    }
}

/// `precision="f32"` or `"f16"`.
fn precision(name: Option<&str>) -> PyResult<Option<Precision>> {
    match name {
        None => Ok(None),
        Some("f32") => Ok(Some(Precision::F32)),
        Some("f16") => Ok(Some(Precision::F16)),
        Some(other) => Err(message(
            Kind::Parameter,
            format!("precision {other:?}: give \"f32\" or \"f16\""),
        )),
    }
}

/// Bakes a config, a scene folder holding `bake.toml`, or a glTF scene (baked with the
/// documented defaults), as the `bake` command does, and returns the run's figures (what
/// `bake --json` prints: `output`, `file_bytes`, `seconds`, ...).
///
/// `out` replaces the config's output file; the keywords replace the config's settings
/// (`spp` is N1, the directions per vertex, in a per-vertex bake; `width`, `height` and
/// `compress_rank` are per-pixel only). `max_memory` (bytes) refuses a bake whose estimate
/// exceeds it. A per-vertex bake saves its traced work in `<out>.partial/` as it goes
/// (`checkpoint=False`: not); `resume=True` continues an interrupted one.
///
/// `progress` is called with a `ProgressEvent` for every stage, step, note and warning, on
/// the calling thread (`prt.TqdmProgress()` draws bars); returning `False` or raising stops
/// the bake, as does Ctrl-C: nothing is written (a per-vertex bake keeps its checkpoint), and
/// `prt.Cancelled`, the callback's exception or `KeyboardInterrupt` is raised. Without
/// `progress`, warnings are issued as `prt.PrtWarning`.
#[pyfunction]
#[pyo3(signature = (
    config, out = None, *, progress = None, spp = None, width = None, height = None,
    precision = None, compress_rank = None, basis_count = None, max_memory = None,
    checkpoint = true, resume = false
))]
#[allow(clippy::too_many_arguments)]
pub fn bake(
    py: Python<'_>,
    config: PathBuf,
    out: Option<PathBuf>,
    progress: Option<Bound<'_, PyAny>>,
    spp: Option<u32>,
    width: Option<u32>,
    height: Option<u32>,
    precision: Option<&str>,
    compress_rank: Option<usize>,
    basis_count: Option<usize>,
    max_memory: Option<u64>,
    checkpoint: bool,
    resume: bool,
) -> PyResult<Py<PyAny>> {
    let precision = self::precision(precision)?;
    if resume && !checkpoint {
        return Err(message(
            Kind::Config,
            "resume=True continues from the checkpoint, which checkpoint=False turns off".into(),
        ));
    }
    let summary = progress::run(py, progress, |reporter| -> PyResult<String> {
        let (config, scene) = load(&config, reporter).map_err(errors::bake)?;
        let refuse = |given: &[(bool, &str)], applies: &str, mode: &str| {
            let named: Vec<&str> = given.iter().filter(|g| g.0).map(|g| g.1).collect();
            match named.is_empty() {
                true => Ok(()),
                false => Err(message(
                    Kind::Config,
                    format!(
                        "{} applies to {applies} bakes; {} has mode = \"{mode}\"",
                        named.join(", "),
                        config.config_path.display()
                    ),
                )),
            }
        };
        let json = match config.mode {
            Mode::Pixel => {
                refuse(
                    &[(resume, "resume"), (!checkpoint, "checkpoint=False")],
                    "per-vertex",
                    "pixel",
                )?;
                // Every field is given today; settings the baker adds later keep their
                // defaults rather than breaking the binding's build.
                #[allow(clippy::needless_update)]
                let settings = PixelRunSettings {
                    spp,
                    width,
                    height,
                    output: out,
                    precision: Some(precision.unwrap_or(Precision::F32)),
                    max_memory,
                    compress_rank,
                    basis_count,
                    ..PixelRunSettings::default()
                };
                let summary = run_pixel(&config, &scene, &settings, reporter);
                serde_json::to_string(&summary.map_err(errors::bake)?)
            }
            Mode::Vertex => {
                refuse(
                    &[
                        (width.is_some(), "width"),
                        (height.is_some(), "height"),
                        (compress_rank.is_some(), "compress_rank"),
                    ],
                    "per-pixel",
                    "vertex",
                )?;
                let settings = VertexRunSettings {
                    spp,
                    output: out,
                    precision,
                    max_memory,
                    basis_count,
                    checkpoint: match (checkpoint, resume) {
                        (_, true) => CheckpointMode::Resume,
                        (true, false) => CheckpointMode::Save,
                        (false, false) => CheckpointMode::Off,
                    },
                    ..VertexRunSettings::default()
                };
                let summary = run_vertex(&config, &scene, &settings, reporter);
                serde_json::to_string(&summary.map_err(errors::bake)?)
            }
        };
        json.map_err(|e| message(Kind::Other, format!("the bake's summary: {e}")))
    })??;
    py.import("json")?
        .getattr("loads")?
        .call1((summary,))
        .map(Bound::unbind)
}
