//! `prt.Camera`: a pinhole camera as the runtime's `CameraFrame`, made from an eye, a target
//! and a vertical field of view as `--camera "eye=.. target=.. fov=.."` makes it.

use prt_runtime::{CameraFrame, CameraSpec};
use pyo3::prelude::*;

use crate::arrays::{decimal, decimals};
use crate::errors::{raise, Kind};

/// A pinhole camera: `Camera(eye, target, fov)` looks from `eye` at `target` with a vertical
/// field of view of `fov` degrees, +Y up (the frame `relight --camera` makes).
#[pyclass(module = "prt", frozen, eq, from_py_object)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub frame: CameraFrame,
}

#[pymethods]
impl Camera {
    #[new]
    #[pyo3(signature = (eye, target, fov))]
    fn new(eye: [f32; 3], target: [f32; 3], fov: f32) -> PyResult<Self> {
        let spec = CameraSpec {
            eye,
            target,
            fov_deg: fov,
        };
        let frame = spec.frame().map_err(|e| raise(Kind::Parameter, &e))?;
        Ok(Camera { frame })
    }

    /// The pinhole's position.
    #[getter]
    fn eye(&self) -> (f64, f64, f64) {
        decimals(self.frame.position)
    }

    /// The unit viewing direction.
    #[getter]
    fn forward(&self) -> (f64, f64, f64) {
        decimals(self.frame.forward)
    }

    /// The unit vector to the image's right.
    #[getter]
    fn right(&self) -> (f64, f64, f64) {
        decimals(self.frame.right)
    }

    /// The unit vector to the image's top.
    #[getter]
    fn up(&self) -> (f64, f64, f64) {
        decimals(self.frame.up)
    }

    /// The vertical field of view in degrees.
    #[getter]
    fn fov(&self) -> f64 {
        decimal(self.frame.yfov.to_degrees())
    }

    /// This camera turned `degrees` about the world's +Y axis through the origin (the
    /// right-hand rule, as environment rotations): an orbit step.
    fn orbited(&self, degrees: f32) -> Camera {
        Camera {
            frame: self.frame.orbited(degrees),
        }
    }

    fn __repr__(&self) -> String {
        let [x, y, z] = self.frame.position;
        let [a, b, c] = self.frame.forward;
        format!(
            "Camera(eye=({x}, {y}, {z}), forward=({a}, {b}, {c}), fov={})",
            self.fov()
        )
    }
}
