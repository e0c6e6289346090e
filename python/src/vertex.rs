//! `prt.VertexRelighter`: a per-vertex bake, whose environment (a map file or a numpy array,
//! its rotation and intensity), camera and image size are set from Python besides its
//! materials.

use std::path::PathBuf;

use numpy::PyArray1;
use numpy::PyArrayMethods;
use prt_runtime::{Relighter, VertexRelighter};
use pyo3::prelude::*;

use crate::arrays::{self, decimal};
use crate::camera::Camera;
use crate::errors::{self, message, Kind};
use crate::relighter::{detached, PyRelighter};

/// A per-vertex bake: environment, camera, image size and materials are all edited. A render
/// runs only the stages whose inputs changed: a new camera the view stage, a material edit
/// the material and view stages, a new environment, rotation or intensity all three.
#[pyclass(module = "prt", extends = PyRelighter, name = "VertexRelighter")]
pub struct PyVertexRelighter {
    /// Whether the environment map was replaced since the bake was opened (a reference for
    /// the same settings then lights the scene with it instead of the config's).
    pub environment_replaced: bool,
    /// The rotation the bake was opened with.
    pub baked_rotation: f32,
}

impl PyVertexRelighter {
    pub fn new(v: &VertexRelighter) -> Self {
        PyVertexRelighter {
            environment_replaced: false,
            baked_rotation: v.environment_rotation(),
        }
    }
}

/// The per-vertex relighter behind a `VertexRelighter`.
pub fn vertex(base: &mut PyRelighter) -> PyResult<&mut VertexRelighter> {
    match &mut base.inner {
        Relighter::Vertex(v) => Ok(v),
        Relighter::Pixel(_) => Err(message(Kind::Other, "not a per-vertex bake".into())),
    }
}

#[pymethods]
impl PyVertexRelighter {
    /// The environment map as set (before its intensity): a float32 array of shape
    /// `(height, width, 3)`, a copy. Set it to a map file (`.exr`, `.hdr`) or an array of that
    /// shape with a float dtype (lat-long, row 0 looking up +Y, linear RGB; NaN or infinite
    /// texels are refused, negative channels clamped to 0); the rotation and intensity stay.
    #[getter]
    fn environment<'py>(
        mut slf: PyRefMut<'py, Self>,
        py: Python<'py>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let map = vertex(slf.as_super())?.environment_map();
        let flat: Vec<f32> = map.texels.iter().flatten().copied().collect();
        PyArray1::from_vec(py, flat)
            .reshape([map.height, map.width, 3])
            .map(Bound::into_any)
    }

    #[setter(environment)]
    fn set_environment_attr(slf: PyRefMut<'_, Self>, source: Bound<'_, PyAny>) -> PyResult<()> {
        Self::set_environment(slf, source).map(|_| ())
    }

    /// Lights the scene with `source`, a map file or an array (see `environment`); returns
    /// how many texels had negative channels clamped to 0.
    fn set_environment(mut slf: PyRefMut<'_, Self>, source: Bound<'_, PyAny>) -> PyResult<usize> {
        let py = source.py();
        let report = if let Ok(path) = source.extract::<PathBuf>() {
            let v = vertex(slf.as_super())?;
            detached(py, move || v.load_environment(path))?
        } else {
            let (width, height, texels) = arrays::rgb(py, &source, "environment")?;
            let v = vertex(slf.as_super())?;
            detached(py, move || v.set_environment_texels(width, height, &texels))?
        }
        .map_err(errors::runtime)?;
        slf.environment_replaced = true;
        Ok(report.clamped_texels)
    }

    /// The environment's rotation about +Y in degrees (absolute; the right-hand rule: +90
    /// turns what was seen towards -Z to be seen towards -X).
    #[getter]
    fn environment_rotation(mut slf: PyRefMut<'_, Self>) -> PyResult<f64> {
        Ok(decimal(vertex(slf.as_super())?.environment_rotation()))
    }

    #[setter]
    fn set_environment_rotation(mut slf: PyRefMut<'_, Self>, degrees: f32) -> PyResult<()> {
        vertex(slf.as_super())?
            .set_environment_rotation(degrees)
            .map_err(errors::runtime)
    }

    /// The multiplier of the environment's radiance (absolute: 1 is the map as set; finite
    /// and >= 0).
    #[getter]
    fn environment_intensity(mut slf: PyRefMut<'_, Self>) -> PyResult<f64> {
        Ok(decimal(vertex(slf.as_super())?.environment_intensity()))
    }

    #[setter]
    fn set_environment_intensity(mut slf: PyRefMut<'_, Self>, intensity: f32) -> PyResult<()> {
        vertex(slf.as_super())?
            .set_environment_intensity(intensity)
            .map_err(errors::runtime)
    }

    /// Whether the map's compact lights (a sun, a studio lamp) are reflected per pixel through
    /// each glossy material's true lobe (True, the default) or left to the shading basis
    /// (cheaper glossy pixels, broader highlights; docs/vertex.md, "Compact lights").
    #[getter]
    fn compact_lights(mut slf: PyRefMut<'_, Self>) -> PyResult<bool> {
        Ok(vertex(slf.as_super())?.compact_lights())
    }

    #[setter]
    fn set_compact_lights(mut slf: PyRefMut<'_, Self>, on: bool) -> PyResult<()> {
        vertex(slf.as_super())?.set_compact_lights(on);
        Ok(())
    }

    /// Whether the pixels on silhouettes and creases are sampled 16 times (True, the default)
    /// or shaded at their centre alone (jagged outlines; docs/vertex.md, "Silhouettes are
    /// antialiased").
    #[getter]
    fn antialias(mut slf: PyRefMut<'_, Self>) -> PyResult<bool> {
        Ok(vertex(slf.as_super())?.antialias())
    }

    #[setter]
    fn set_antialias(mut slf: PyRefMut<'_, Self>, on: bool) -> PyResult<()> {
        vertex(slf.as_super())?.set_antialias(on);
        Ok(())
    }

    /// The current camera (a `prt.Camera`). Setting one whose eye is inside an object, or
    /// whose frame is not finite, raises `prt.ParameterError` and keeps the camera.
    #[getter]
    fn camera(mut slf: PyRefMut<'_, Self>) -> PyResult<Camera> {
        Ok(Camera {
            frame: vertex(slf.as_super())?.camera(),
        })
    }

    #[setter]
    fn set_camera(mut slf: PyRefMut<'_, Self>, camera: Camera) -> PyResult<()> {
        let py = slf.py();
        let v = vertex(slf.as_super())?;
        detached(py, move || v.set_camera(camera.frame))?.map_err(errors::runtime)
    }

    /// The camera the scene was baked with.
    #[getter]
    fn default_camera(mut slf: PyRefMut<'_, Self>) -> PyResult<Camera> {
        Ok(Camera {
            frame: vertex(slf.as_super())?.default_camera(),
        })
    }

    /// The image size `(width, height)`; set it to render other sizes (each 1 to 16384).
    #[getter]
    fn size(mut slf: PyRefMut<'_, Self>) -> PyResult<(u32, u32)> {
        Ok(vertex(slf.as_super())?.size())
    }

    #[setter]
    fn set_size(mut slf: PyRefMut<'_, Self>, size: (u32, u32)) -> PyResult<()> {
        vertex(slf.as_super())?
            .set_size(size.0, size.1)
            .map_err(errors::runtime)
    }
}
