//! `prt.reference`, the ground truth (the baker's reference tracer, with the true BRDFs) for
//! a relighter's settings or for settings given, and `prt.compare`, the error of one image
//! against another.

use std::path::PathBuf;

use numpy::{PyArray1, PyArrayMethods};
use prt_bake::ground_truth::{run_reference, ReferenceSettings};
use prt_bake::metrics::{mean_difference, relative_l2};
use prt_bake::run::load;
use prt_formats::envmap::LatLongMap;
use prt_formats::MaterialOverride;
use prt_runtime::Relighter;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays;
use crate::camera::Camera;
use crate::errors::{self, message, raise, Kind};
use crate::materials;
use crate::progress;
use crate::relighter::PyRelighter;
use crate::vertex::PyVertexRelighter;

/// A reference's environment map before its intensity, and the intensity.
struct Light {
    map: Option<LatLongMap>,
    intensity: Option<f32>,
}

/// The settings `like`'s current state gives a reference: its size and every editable
/// material's parameters; for a per-vertex bake also its environment (when replaced or
/// scaled), its rotation (when changed) and its camera (when moved).
fn settings_like(like: &Bound<'_, PyRelighter>) -> PyResult<(ReferenceSettings, Light)> {
    let base = like.try_borrow()?;
    let r = &base.inner;
    let (width, height) = r.size();
    let mut s = ReferenceSettings {
        width: Some(width),
        height: Some(height),
        ..ReferenceSettings::default()
    };
    let mut light = Light {
        map: None,
        intensity: None,
    };
    for m in r.materials().into_iter().filter(|m| m.editable) {
        for p in &m.params {
            s.overrides.push(MaterialOverride {
                material: m.name.clone(),
                value: p.value,
            });
        }
    }
    if let Relighter::Vertex(v) = r {
        let state = like.cast::<PyVertexRelighter>()?.try_borrow()?;
        // The baked map is the config's (already scaled by its intensity), so the config's
        // environment serves until the map is replaced or scaled.
        if state.environment_replaced || v.environment_intensity() != 1.0 {
            light.map = Some(v.environment_map().clone());
            light.intensity = Some(v.environment_intensity());
        }
        if light.map.is_some() || v.environment_rotation() != state.baked_rotation {
            s.environment_rotation = Some(v.environment_rotation());
        }
        if v.camera() != v.default_camera() {
            s.camera = Some(v.camera());
        }
    }
    Ok((s, light))
}

/// Renders the ground truth: the scene of `config` (a bake config, a scene folder or a
/// glTF, as `bake` takes) path-traced with the true BRDFs, for the same settings as the
/// relighter `like` (its image size and materials; per vertex also its environment,
/// rotation, intensity and camera), or the config's. The keywords replace settings: `spp`,
/// `seed`, `width`, `height`; `set` edits materials, `{"bunny": {"kd": (0.8, 0.2, 0.2)}}`;
/// `env` a map file or `(height, width, 3)` array lighting the scene (times
/// `env_intensity`), `env_rotation` its rotation in degrees (absolute), `camera` a
/// `prt.Camera`. Returns a float32 array of shape `(height, width, 3)`. Progress and
/// cancellation as for `prt.bake`.
#[pyfunction]
#[pyo3(signature = (
    config, *, like = None, spp = None, seed = None, width = None, height = None, set = None,
    env = None, env_intensity = None, env_rotation = None, camera = None, progress = None
))]
#[allow(clippy::too_many_arguments)]
pub fn reference<'py>(
    py: Python<'py>,
    config: PathBuf,
    like: Option<Bound<'py, PyRelighter>>,
    spp: Option<u32>,
    seed: Option<u64>,
    width: Option<u32>,
    height: Option<u32>,
    set: Option<Bound<'py, PyDict>>,
    env: Option<Bound<'py, PyAny>>,
    env_intensity: Option<f32>,
    env_rotation: Option<f32>,
    camera: Option<Camera>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (mut s, mut light) = match &like {
        Some(r) => settings_like(r)?,
        None => (
            ReferenceSettings::default(),
            Light {
                map: None,
                intensity: None,
            },
        ),
    };
    s.spp = spp.or(s.spp);
    s.seed = seed.or(s.seed);
    s.width = width.or(s.width);
    s.height = height.or(s.height);
    if let Some(set) = set {
        for (material, params) in set.iter() {
            let material: String = material.extract()?;
            let params = params.cast::<PyDict>().map_err(|_| {
                message(
                    Kind::Parameter,
                    format!("set[{material:?}]: give a dict of parameters, e.g. {{\"kd\": 0.5}}"),
                )
            })?;
            for value in materials::values(Some(params))? {
                s.overrides.push(MaterialOverride {
                    material: material.clone(),
                    value,
                });
            }
        }
    }
    if let Some(env) = env {
        light.map = Some(if let Ok(path) = env.extract::<PathBuf>() {
            prt_formats::envmap::load_latlong(&path, 1.0)
                .map_err(|e| {
                    message(
                        Kind::File,
                        format!("environment map {}: {e}", path.display()),
                    )
                })?
                .0
        } else {
            let (w, h, texels) = arrays::rgb(py, &env, "env")?;
            LatLongMap::new(w, h, arrays::pixels(&texels), 1.0)
                .map_err(|e| message(Kind::Parameter, format!("env: {e}")))?
                .0
        });
    }
    light.intensity = env_intensity.or(light.intensity);
    match (light.map, light.intensity) {
        (Some(map), intensity) => {
            let scaled =
                LatLongMap::new(map.width, map.height, map.texels, intensity.unwrap_or(1.0));
            s.environment = Some(
                scaled
                    .map_err(|e| message(Kind::Parameter, format!("env: {e}")))?
                    .0,
            );
        }
        (None, Some(_)) => {
            return Err(message(
                Kind::Parameter,
                "env_intensity scales an environment map: give env too".into(),
            ))
        }
        (None, None) => {}
    }
    s.environment_rotation = env_rotation.or(s.environment_rotation);
    if let Some(c) = camera {
        s.camera = Some(c.frame);
    }
    let (width, height, pixels) = progress::run(py, progress, |reporter| {
        let (config, scene) = load(&config, reporter).map_err(errors::bake)?;
        let render = run_reference(&config, scene, &s, reporter).map_err(errors::reference)?;
        let flat: Vec<f32> = render.pixels.iter().flat_map(|p| p.to_array()).collect();
        PyResult::Ok((render.width as usize, render.height as usize, flat))
    })??;
    PyArray1::from_vec(py, pixels)
        .reshape([height, width, 3])
        .map(Bound::into_any)
}

/// How an image differs from a reference (`prt.compare`).
#[pyclass(module = "prt", frozen, get_all)]
pub struct Comparison {
    /// `||image - reference|| / ||reference||` over all pixels and channels.
    pub relative_l2: f64,
    /// The mean of `image - reference` over the pixels, per channel `(r, g, b)`.
    pub mean_difference: (f64, f64, f64),
    /// The standard error of each mean (the per-pixel differences' spread over the square
    /// root of the pixel count).
    pub standard_error: (f64, f64, f64),
    /// Each channel's mean difference in standard errors.
    pub z: (f64, f64, f64),
    /// The mean difference of the channel averages in standard errors: how many standard
    /// errors the image is brighter (+) or darker (-) than the reference on average. Beyond
    /// about 4 the difference is not noise.
    pub z_mean: f64,
}

#[pymethods]
impl Comparison {
    fn __repr__(&self) -> String {
        format!(
            "Comparison(relative_l2={:.5}, z_mean={:+.2}, z=({:+.2}, {:+.2}, {:+.2}))",
            self.relative_l2, self.z_mean, self.z.0, self.z.1, self.z.2
        )
    }
}

/// Compares `image` with `reference` (arrays of one shape `(height, width, 3)`): the
/// relative L2 error and the mean difference in standard errors (see `Comparison`). The
/// pixels' differences are taken as independent samples, as they are between a relit bake
/// and the reference tracer (each pixel owns its random streams); an error with structure
/// (an edge moved) widens their spread and shows as fewer standard errors than a uniform bias
/// of the same mean.
#[pyfunction]
pub fn compare(
    py: Python<'_>,
    image: Bound<'_, PyAny>,
    reference: Bound<'_, PyAny>,
) -> PyResult<Comparison> {
    let (w, h, a) = arrays::rgb(py, &image, "image")?;
    let (rw, rh, b) = arrays::rgb(py, &reference, "reference")?;
    if (w, h) != (rw, rh) {
        return Err(message(
            Kind::Parameter,
            format!("the image is {w}x{h} but the reference {rw}x{rh}"),
        ));
    }
    let (a, b) = (arrays::pixels(&a), arrays::pixels(&b));
    let m = mean_difference(&a, &b);
    let z = m.z();
    Ok(Comparison {
        relative_l2: relative_l2(&a, &b),
        mean_difference: (m.mean[0], m.mean[1], m.mean[2]),
        standard_error: (
            m.standard_error[0],
            m.standard_error[1],
            m.standard_error[2],
        ),
        z: (z[0], z[1], z[2]),
        z_mean: z[3],
    })
}

/// Writes `image` (`(height, width, 3)`, linear RGB) as `.exr` (32-bit float) or `.png`
/// (tone-mapped sRGB, times `exposure`), by the extension, atomically.
#[pyfunction]
#[pyo3(signature = (path, image, exposure = 1.0))]
pub fn write_image(
    py: Python<'_>,
    path: PathBuf,
    image: Bound<'_, PyAny>,
    exposure: f32,
) -> PyResult<()> {
    let (w, h, values) = arrays::rgb(py, &image, "image")?;
    let pixels = arrays::pixels(&values);
    prt_formats::write_image(&path, w, h, &pixels, exposure).map_err(|e| raise(Kind::File, &e))
}
