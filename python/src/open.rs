//! `prt.open`: a bake file of either kind as the relighter class of its kind.

use std::path::PathBuf;

use prt_runtime::{Relighter, RuntimeError};
use pyo3::prelude::*;

use crate::errors;
use crate::relighter::{detached, PyPixelRelighter, PyRelighter};
use crate::vertex::PyVertexRelighter;

/// Opens a bake file of either kind (checksums verified) and returns a `PixelRelighter` or a
/// `VertexRelighter`, with the materials at their baked parameters (and, per vertex, the
/// baked environment and camera at 512x512). Raises `prt.FileError` for a missing,
/// unreadable or corrupt file, or one that is no bake.
#[pyfunction]
pub fn open(py: Python<'_>, path: PathBuf) -> PyResult<Py<PyAny>> {
    let opened: Result<Relighter, RuntimeError> = detached(py, || prt_runtime::open(&path))?;
    let inner = opened.map_err(errors::runtime)?;
    let base = PyRelighter { inner, path };
    let object = match &base.inner {
        Relighter::Pixel(_) => {
            let init = PyClassInitializer::from(base).add_subclass(PyPixelRelighter);
            Bound::new(py, init)?.into_any()
        }
        Relighter::Vertex(v) => {
            let vertex = PyVertexRelighter::new(v);
            let init = PyClassInitializer::from(base).add_subclass(vertex);
            Bound::new(py, init)?.into_any()
        }
    };
    Ok(object.unbind())
}
