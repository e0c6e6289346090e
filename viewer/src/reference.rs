//! The reference toggle: the reference path tracer (`prt_bake::reference`, what the `reference`
//! tool runs) for a tab's current settings, one sample per pixel per pass, averaged as the
//! passes come in, so the page sees the ground truth converge beside the relit image.
//!
//! The bake file keeps no scene (no geometry, lights or true BRDFs beyond its materials), so
//! the tracer needs the bake's config, given to the viewer on the command line; the scene,
//! its ray-query structure and lights are built once (the geometry never changes, only
//! materials, environment and camera do). The bake's own reflection count, seed and (per
//! pixel) camera and image size are used, so the reference is the one `reference` renders
//! for that bake.

use std::path::{Path, PathBuf};

use glam::Vec3;
use prt_bake::accel::Accel;
use prt_bake::integrator::Integrator;
use prt_bake::lights::LightSet;
use prt_bake::progress::Silent;
use prt_bake::reference::{render, unit_coefficients, TrueBrdfModel};
use prt_bake::scene::{Environment, Scene};
use prt_formats::MaterialOverride;

use crate::settings::{Settings, BAKED_ENVIRONMENT};
use crate::ViewerError;

/// What the bake fixes about its reference renders.
#[derive(Clone, Copy, Debug)]
pub struct BakeTracing {
    /// Reflections traced.
    pub reflections: usize,
    /// What the camera sees directly is sampled this many times as often.
    pub emission_oversampling: Option<u32>,
    /// The bake's random seed (pass `k` uses a stream keyed from it).
    pub seed: u64,
}

/// The loaded scene of the bake's config, ready to trace.
pub struct ReferenceScene {
    scene: Scene,
    accel: Accel,
    tracing: BakeTracing,
    emission_oversampling: u32,
    env_folder: Option<PathBuf>,
}

impl ReferenceScene {
    /// Loads the config's scene and builds its ray-query structure (seconds for a large
    /// scene; done once, when the toggle is first switched on). Refuses a config whose scene
    /// lacks a material the bake has (a config of another scene).
    pub fn load(
        config: &Path,
        bake_materials: &[String],
        tracing: BakeTracing,
        env_folder: Option<&Path>,
    ) -> Result<ReferenceScene, ViewerError> {
        let reference = |reason: String| ViewerError::Reference {
            config: config.display().to_string(),
            reason,
        };
        let (config_read, scene) =
            prt_bake::run::load(config, &Silent).map_err(|e| reference(e.to_string()))?;
        if let Some(missing) = bake_materials
            .iter()
            .find(|m| scene.material_index(m).is_none())
        {
            return Err(reference(format!(
                "its scene has no material '{missing}', which the bake has: give the config \
                 the bake was made from"
            )));
        }
        let accel = Accel::build(&scene);
        Ok(ReferenceScene {
            emission_oversampling: tracing
                .emission_oversampling
                .unwrap_or(config_read.emission_oversampling),
            scene,
            accel,
            tracing,
            env_folder: env_folder.map(Path::to_path_buf),
        })
    }

    /// The scene as `settings` show it: the materials' values, and per vertex the
    /// environment (map, rotation, intensity) and camera; with the image size to render.
    pub fn scene_for(
        &self,
        settings: &Settings,
        pixel_size: (u32, u32),
    ) -> Result<(Scene, u32, u32), ViewerError> {
        let mut scene = self.scene.clone();
        let err = |reason: String| ViewerError::Reference {
            config: "the reference scene".into(),
            reason,
        };
        for m in &settings.materials {
            for &value in &m.values {
                let o = MaterialOverride {
                    material: m.name.clone(),
                    value,
                };
                prt_bake::run::apply_override(&mut scene, &o).map_err(|e| err(e.to_string()))?;
            }
        }
        let Some(view) = &settings.view else {
            return Ok((scene, pixel_size.0, pixel_size.1));
        };
        if view.environment != BAKED_ENVIRONMENT {
            let folder = self.env_folder.as_deref().unwrap_or(Path::new("."));
            let path = folder.join(&view.environment);
            let (env, _) = prt_bake::scene::envmap::load_latlong(&path, view.intensity)
                .map_err(|e| err(format!("{}: {e}", path.display())))?;
            scene.environment = env;
        } else if view.intensity != 1.0 {
            match &mut scene.environment {
                Environment::LatLong { texels, .. } => {
                    texels.iter_mut().for_each(|t| *t *= view.intensity)
                }
                Environment::Constant(c) => *c *= view.intensity,
            }
        }
        scene.environment_rotation = view.rotation;
        let frame = view.camera.frame().map_err(|e| err(e.to_string()))?;
        scene.camera = prt_bake::view::camera_from_frame(&frame);
        Ok((scene, view.width, view.height))
    }

    /// Pass `pass` (from 0) of `scene`: one sample per pixel with its own random streams,
    /// linear RGB, row-major.
    pub fn pass(&self, scene: &Scene, width: u32, height: u32, pass: u32) -> Vec<[f32; 3]> {
        let lights = LightSet::new(scene);
        let integrator = Integrator::new(
            scene,
            &self.accel,
            &lights,
            self.tracing.reflections,
            width,
            height,
        );
        let model = TrueBrdfModel::new(scene);
        // Passes are independent renders: streams keyed by the bake's seed and the pass.
        let seed = self
            .tracing
            .seed
            .wrapping_add(u64::from(pass).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let r = render(
            &integrator,
            &model,
            &unit_coefficients(scene.materials.len()),
            1,
            self.emission_oversampling,
            seed,
            None,
        );
        r.pixels.iter().map(|p: &Vec3| p.to_array()).collect()
    }
}

/// The running mean of passes.
#[derive(Clone, Debug, Default)]
pub struct Accumulator {
    sum: Vec<[f64; 3]>,
    passes: u32,
}

impl Accumulator {
    /// Adds a pass.
    pub fn add(&mut self, pass: &[[f32; 3]]) {
        if self.sum.len() != pass.len() {
            self.sum = vec![[0.0; 3]; pass.len()];
            self.passes = 0;
        }
        for (s, p) in self.sum.iter_mut().zip(pass) {
            for c in 0..3 {
                s[c] += f64::from(p[c]);
            }
        }
        self.passes += 1;
    }

    /// Passes added (samples per pixel so far).
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// The mean so far, flat linear RGB.
    pub fn mean(&self) -> Vec<f32> {
        let n = f64::from(self.passes.max(1));
        self.sum
            .iter()
            .flat_map(|s| s.map(|v| (v / n) as f32))
            .collect()
    }
}
