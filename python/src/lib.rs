//! The native part of the `prt` Python package (`prt._prt`): the runtime's relighters and
//! the baker's bake and reference calls over numpy arrays. The package's Python layer
//! (`prt/__init__.py`) re-exports it with the exception classes and the progress helpers;
//! docs/python.md is the guide.

mod arrays;
mod bake;
mod camera;
mod errors;
mod materials;
mod open;
mod progress;
mod reference;
mod relighter;
mod vertex;

use pyo3::prelude::*;

/// PRT bake from Python: open a bake and relight it for any material (and, per vertex,
/// environment, camera and size) into numpy arrays; bake, render the ground truth and
/// compare.
#[pymodule]
mod _prt {
    #[pymodule_export]
    use super::bake::bake;
    #[pymodule_export]
    use super::camera::Camera;
    #[pymodule_export]
    use super::materials::{Material, Param};
    #[pymodule_export]
    use super::open::open;
    #[pymodule_export]
    use super::progress::ProgressEvent;
    #[pymodule_export]
    use super::reference::{compare, reference, write_image, Comparison};
    #[pymodule_export]
    use super::relighter::{PyPixelRelighter, PyRelighter};
    #[pymodule_export]
    use super::vertex::PyVertexRelighter;
}
