//! The relighters: `Relighter`, what both kinds of bake share (materials, size, render), and
//! `PixelRelighter`, a per-pixel bake (its variant); `VertexRelighter` is in `vertex.rs`,
//! `prt.open` in `open.rs`. A render writes the numpy array's own memory with the interpreter's lock
//! released, so Python threads rendering different relighters run at once.

use std::path::PathBuf;

use numpy::{PyArray3, PyArrayMethods};
use prt_runtime::{Relighter, Variant};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays;
use crate::errors::{self, message, Kind};
use crate::materials::{self, Material};

/// Runs `f` with the interpreter's lock released (other Python threads run meanwhile); a
/// panic in it is raised as an error instead of crossing into Python.
pub fn detached<T: Send>(py: Python<'_>, f: impl FnOnce() -> T + Send) -> PyResult<T> {
    py.detach(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)))
        .map_err(|p| errors::panic(p.as_ref()))
}

/// An opened bake of either kind (`prt.open` gives a `PixelRelighter` or a
/// `VertexRelighter`): its materials, the image size, and renders as numpy arrays.
///
/// A relighter is used by one thread at a time (a second thread calling it meanwhile gets a
/// `RuntimeError`, "already borrowed"); different relighters render in parallel.
#[pyclass(module = "prt", subclass, name = "Relighter")]
pub struct PyRelighter {
    pub inner: Relighter,
    pub path: PathBuf,
}

#[pymethods]
impl PyRelighter {
    /// `"pixel"` or `"vertex"`.
    #[getter]
    fn kind(&self) -> &'static str {
        match self.inner {
            Relighter::Pixel(_) => "pixel",
            Relighter::Vertex(_) => "vertex",
        }
    }

    /// The bake file.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// Every material of the bake, in its order, with its family, whether it is editable, and
    /// its parameters (current value, accepted range, sampled range).
    #[getter]
    fn materials(&self, py: Python<'_>) -> PyResult<Vec<Material>> {
        materials::materials(py, &self.inner.materials())
    }

    /// Sets parameters of the editable material `material` by name: `kd` and `ks` as
    /// `(r, g, b)` or one number (gray), `shininess` (Blinn-Phong) or `alpha` (GGX) as a
    /// number; e.g. `r.set("bunny", kd=(0.8, 0.2, 0.2), alpha=0.3)`. All or none: a refused
    /// value (an unknown material or parameter, a value outside its range) raises
    /// `prt.ParameterError` and changes nothing. A lobe parameter outside the bake's sampled
    /// range is accepted and rendered clamped to it (`Param.clamped`).
    #[pyo3(signature = (material, **params))]
    fn set(&mut self, material: &str, params: Option<&Bound<'_, PyDict>>) -> PyResult<()> {
        let values = materials::values(params)?;
        self.inner
            .set_params(material, &values)
            .map_err(errors::runtime)
    }

    /// The size `(width, height)` of the images rendered now.
    #[getter]
    fn size(&self) -> (u32, u32) {
        self.inner.size()
    }

    /// Renders the image for the current settings: a float32 array of shape
    /// `(height, width, 3)`, linear RGB, top row first. The render writes the array's memory
    /// directly, with the interpreter's lock released. `out`, an array of that shape, dtype
    /// and C order, is rendered into and returned instead of a new one.
    #[pyo3(signature = (out = None))]
    fn render<'py>(
        &mut self,
        py: Python<'py>,
        out: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let (width, height) = self.inner.size();
        let array = match out {
            Some(out) => arrays::output(&out, width, height)?,
            // SAFETY: render_into below writes every element, or fails and the array is
            // dropped without reaching Python.
            None => unsafe { arrays::new_image(py, width, height) },
        };
        {
            let mut view = array
                .try_readwrite()
                .map_err(|e| message(Kind::Parameter, format!("out: the array is in use: {e}")))?;
            let buffer = view
                .as_slice_mut()
                .map_err(|e| message(Kind::Parameter, format!("out: {e}")))?;
            let relighter = &mut self.inner;
            detached(py, move || relighter.render_into(buffer))?.map_err(errors::runtime)?;
        }
        Ok(array)
    }

    fn __repr__(&self) -> String {
        let (w, h) = self.inner.size();
        format!(
            "<prt.{} {} {w}x{h}, {} materials>",
            match self.inner {
                Relighter::Pixel(_) => "PixelRelighter",
                Relighter::Vertex(_) => "VertexRelighter",
            },
            self.path.display(),
            self.inner.materials().len()
        )
    }
}

/// A per-pixel bake: camera, light and image size are frozen into the file; materials are
/// edited. Relights from the stored transfer (`variant = "full"`) or its low-rank
/// approximation (`"compressed"`, when baked with `compress_rank`).
#[pyclass(module = "prt", extends = PyRelighter, name = "PixelRelighter")]
pub struct PyPixelRelighter;

/// The per-pixel relighter behind `slf`.
fn pixel(base: &mut PyRelighter) -> PyResult<&mut prt_runtime::PixelRelighter> {
    match &mut base.inner {
        Relighter::Pixel(p) => Ok(p),
        Relighter::Vertex(_) => Err(message(Kind::Other, "not a per-pixel bake".into())),
    }
}

#[pymethods]
impl PyPixelRelighter {
    /// Whether the bake has a low-rank variant (baked with `compress_rank`).
    #[getter]
    fn has_compressed(mut slf: PyRefMut<'_, Self>) -> PyResult<bool> {
        Ok(pixel(slf.as_super())?.has_compressed())
    }

    /// What frames are relit from: `"full"` (the stored transfer) or `"compressed"` (its
    /// low-rank approximation; refused when the bake has none).
    #[getter]
    fn variant(mut slf: PyRefMut<'_, Self>) -> PyResult<&'static str> {
        Ok(match pixel(slf.as_super())?.variant() {
            Variant::Full => "full",
            Variant::Compressed => "compressed",
        })
    }

    #[setter]
    fn set_variant(mut slf: PyRefMut<'_, Self>, variant: &str) -> PyResult<()> {
        let v = match variant {
            "full" => Variant::Full,
            "compressed" => Variant::Compressed,
            other => {
                return Err(message(
                    Kind::Parameter,
                    format!("variant {other:?}: give \"full\" or \"compressed\""),
                ))
            }
        };
        pixel(slf.as_super())?
            .set_variant(v)
            .map_err(errors::runtime)
    }
}
