//! The `reference` job as a library call: a config's scene with the caller's edits (materials,
//! environment map, its rotation, camera, image size, samples, seed), checked and rendered
//! with the true BRDFs ([`crate::reference::render_true`]). The `reference` binary and the
//! Python binding both call [`run_reference`], so a relit image from either is checked against
//! the same ground truth.

use glam::Vec3;
use prt_formats::envmap::LatLongMap;
use prt_formats::view::CameraFrame;
use prt_formats::MaterialOverride;

use crate::accel::Accel;
use crate::config::BakeConfig;
use crate::error::BakeError;
use crate::progress::Progress;
use crate::reference::{render_true, Render};
use crate::run::apply_override;
use crate::scene::{Environment, Scene};
use crate::view::{camera_from_frame, check_eye_outside, ViewError};

/// What a reference render changes of a config and its scene; `None` keeps the config's.
#[derive(Clone, Debug, Default)]
pub struct ReferenceSettings {
    /// Samples per pixel.
    pub spp: Option<u32>,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub seed: Option<u64>,
    /// Material edits, applied in order (as `--set`).
    pub overrides: Vec<MaterialOverride>,
    /// Light the scene with this lat-long map (already scaled by any intensity) instead of
    /// the config's environment; its rotation is then 0 unless `environment_rotation` says.
    pub environment: Option<LatLongMap>,
    /// The environment map's rotation about +Y in degrees, absolute (it replaces the config's
    /// `rotation`; the right-hand rule, docs/conventions.md). Needs a map: the config's or
    /// `environment`.
    pub environment_rotation: Option<f32>,
    /// View the scene through this camera instead of the config's.
    pub camera: Option<CameraFrame>,
}

/// Why a reference render failed: its settings were refused, or the config's scene or a
/// material edit was (a [`BakeError`]). Its own type, not a [`BakeError`] variant, so that
/// `error.rs` need not know this module (which calls `run.rs`, which returns `BakeError`).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReferenceError {
    /// A material edit, or the scene, was refused.
    #[error(transparent)]
    Bake(Box<BakeError>),
    /// The image size or the sample count is zero.
    #[error("the reference needs a width, height and spp of at least 1 (got {width}x{height} at {spp} spp)")]
    Empty {
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
        /// Samples per pixel.
        spp: u32,
    },
    /// An environment rotation that is not a finite number of degrees.
    #[error("environment rotation {0}: give a finite number of degrees")]
    Rotation(f32),
    /// A rotation for a scene lit by no environment map.
    #[error(
        "the scene's environment is not a map, so it cannot be rotated (give a map, or a \
         config with [environment] map)"
    )]
    RotationWithoutMap,
    /// The camera's eye is inside an object.
    #[error(transparent)]
    View(#[from] ViewError),
}

impl From<BakeError> for ReferenceError {
    fn from(e: BakeError) -> Self {
        // Boxed: a `BakeError` is large, and this error is otherwise small.
        ReferenceError::Bake(Box::new(e))
    }
}

/// Applies `s`'s edits to `scene` (loaded from `config`) and renders its camera view with the
/// true BRDFs; stages go to `progress`. Every setting is checked before the render starts.
pub fn run_reference(
    config: &BakeConfig,
    mut scene: Scene,
    s: &ReferenceSettings,
    progress: &dyn Progress,
) -> Result<Render, ReferenceError> {
    let width = s.width.unwrap_or(config.width);
    let height = s.height.unwrap_or(config.height);
    let spp = s.spp.unwrap_or(config.spp);
    if width == 0 || height == 0 || spp == 0 {
        return Err(ReferenceError::Empty { width, height, spp });
    }
    for o in &s.overrides {
        apply_override(&mut scene, o)?;
    }
    // An edit that reflects more light than it receives is rendered as given, and named.
    for m in &scene.materials {
        if s.overrides.iter().any(|o| o.material == m.name) {
            let (kd, ks) = (m.brdf.kd.to_array(), m.brdf.ks.to_array());
            if let Some(w) =
                prt_formats::family::reflectance_warning(&m.name, m.brdf.family, kd, ks)
            {
                progress.warn(&w);
            }
        }
    }
    if let Some(map) = &s.environment {
        scene.environment = Environment::LatLong {
            width: map.width as u32,
            height: map.height as u32,
            texels: map.texels.iter().map(|&t| Vec3::from_array(t)).collect(),
        };
        scene.environment_rotation = 0.0;
    }
    if let Some(deg) = s.environment_rotation {
        if !deg.is_finite() {
            return Err(ReferenceError::Rotation(deg));
        }
        if !matches!(scene.environment, Environment::LatLong { .. }) {
            return Err(ReferenceError::RotationWithoutMap);
        }
        scene.environment_rotation = deg;
    }
    if let Some(frame) = &s.camera {
        scene.camera = camera_from_frame(frame);
    }
    let accel = Accel::build(&scene);
    check_eye_outside(&scene, &accel, scene.camera.position)?;
    Ok(render_true(
        &scene,
        config.reflections as usize,
        width,
        height,
        spp,
        config.emission_oversampling,
        s.seed.unwrap_or(config.seed),
        Some(progress),
    ))
}
