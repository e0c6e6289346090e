//! What the report measures of each bake: its images under two lights against the reference
//! tracer (and against the scene's dense bake), and the three runtime paths' frame times in
//! interleaved rounds.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context as _, Result};
use prt_bake::config::{BakeConfig, EnvironmentConfig};
use prt_bake::metrics::relative_l2;
use prt_bake::scene::Scene;
use prt_formats::view::CameraFrame;
use prt_runtime::{Image, OverrideValue, RenderStats, VertexRelighter};

use crate::util::median;

/// A light of the comparison: `map: None` is the baked environment.
pub(crate) struct Light {
    pub name: &'static str,
    pub slug: &'static str,
    pub map: Option<(&'static str, f32)>,
}

pub(crate) const LIGHTS: [Light; 2] = [
    Light {
        name: "baked light",
        slug: "baked",
        map: None,
    },
    Light {
        name: "studio turned 120",
        slug: "studio-120",
        map: Some(("scenes/envmaps/studio.exr", 120.0)),
    },
];

pub(crate) type Pixels = Vec<[f32; 3]>;

/// The intensity the config lights its map with (the turned studio map uses it too).
pub(crate) fn map_intensity(config: &BakeConfig) -> f32 {
    match &config.environment {
        EnvironmentConfig::Map { intensity, .. } => *intensity,
        EnvironmentConfig::Color(_) => 1.0,
    }
}

/// The relighter of `path` lit by `light` at `intensity`.
pub(crate) fn lit(path: &Path, light: &Light, intensity: f32) -> Result<VertexRelighter> {
    let mut r =
        VertexRelighter::open(path).with_context(|| format!("opening {}", path.display()))?;
    if let Some((map, rotation)) = light.map {
        r.load_environment(map)?;
        r.set_environment_rotation(rotation)?;
        r.set_environment_intensity(intensity)?;
    }
    Ok(r)
}

/// One square frame from the bake's camera.
pub(crate) fn render(r: &mut VertexRelighter, size: u32) -> Result<(Pixels, RenderStats)> {
    r.set_camera(r.default_camera())?;
    r.set_size(size, size)?;
    let mut image = Image::new(size, size);
    let stats = r.render_into(image.pixels.as_flattened_mut())?;
    Ok((image.pixels, stats))
}

/// The reference tracer's image of `scene` under each light (true BRDFs, the config's
/// reflections and seed).
pub(crate) fn references(
    config: &BakeConfig,
    scene: &Scene,
    size: u32,
    spp: u32,
) -> Result<Vec<Pixels>> {
    let mut out = Vec::new();
    for light in &LIGHTS {
        eprintln!("reference: {} at {spp} spp", light.name);
        out.push(reference(config, scene, light, size, spp, config.seed)?);
    }
    Ok(out)
}

/// The reference tracer's image of `scene` under `light` (true BRDFs, the config's
/// reflections), square, with random streams keyed by `seed`.
pub(crate) fn reference(
    config: &BakeConfig,
    scene: &Scene,
    light: &Light,
    size: u32,
    spp: u32,
    seed: u64,
) -> Result<Pixels> {
    let mut sc = scene.clone();
    if let Some((map, rotation)) = light.map {
        sc.environment =
            prt_bake::scene::envmap::load_latlong(Path::new(map), map_intensity(config))?.0;
        sc.environment_rotation = rotation;
    }
    let r = prt_bake::reference::render_true(
        &sc,
        config.reflections as usize,
        size,
        size,
        spp,
        prt_bake::film_emission::DEFAULT_EMISSION_OVERSAMPLING,
        seed,
        None,
    );
    Ok(r.pixels.iter().map(|p| p.to_array()).collect())
}

/// A bake's images and their errors, per light.
pub(crate) struct Errors {
    /// Per light: relative L2 against the reference.
    pub vs_reference: Vec<f64>,
    /// Per light: relative L2 against the dense bake's relight (NaN without one).
    pub vs_dense: Vec<f64>,
    /// Per light: the image.
    pub images: Vec<Pixels>,
}

/// Relights every bake under every light and compares; `dense` is the index of the dense bake.
pub(crate) fn errors(
    bakes: &[&Path],
    dense: Option<usize>,
    references: &[Pixels],
    intensity: f32,
    size: u32,
) -> Result<Vec<Errors>> {
    let mut out: Vec<Errors> = bakes
        .iter()
        .map(|_| Errors {
            vs_reference: Vec::new(),
            vs_dense: Vec::new(),
            images: Vec::new(),
        })
        .collect();
    for (li, light) in LIGHTS.iter().enumerate() {
        for (b, e) in bakes.iter().zip(out.iter_mut()) {
            let img = render(&mut lit(b, light, intensity)?, size)?.0;
            e.vs_reference.push(relative_l2(&img, &references[li]));
            e.images.push(img);
        }
        let base = dense.map(|d| out[d].images[li].clone());
        for e in out.iter_mut() {
            let d = base
                .as_ref()
                .map_or(f64::NAN, |b| relative_l2(&e.images[li], b));
            e.vs_dense.push(d);
        }
    }
    Ok(out)
}

/// Median frame times (seconds) of the three paths, and parts of them.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PathTimes {
    /// Whole `render` calls (eye check, stages that ran, rasterization and shading).
    pub view: f64,
    pub view_brdf: f64,
    pub view_brdf_light: f64,
    /// The view stage of the view-only frames, and its rasterization part.
    pub view_stage: f64,
    pub raster: f64,
    /// The light stage alone (in the view + BRDF + light frames).
    pub light: f64,
    /// The material stage alone (in the view + BRDF frames).
    pub material: f64,
}

/// One frame from `camera`, timed as a whole (setting the camera checks a new eye).
fn frame(
    r: &mut VertexRelighter,
    camera: CameraFrame,
    out: &mut [f32],
) -> Result<(f64, RenderStats)> {
    let start = Instant::now();
    r.set_camera(camera)?;
    let stats = r.render_into(out)?;
    Ok((start.elapsed().as_secs_f64(), stats))
}

/// Times the three paths of every bake in `rounds` interleaved rounds. Every frame moves the
/// camera (an orbit step of a quarter degree about the scene's camera, so the eye check and
/// the rasterization run as in an interactive session); per round each bake renders a
/// view-only frame, a material edit, then a light turn with a material edit.
pub(crate) fn time_paths(
    bakes: &[&Path],
    edit_material: &str,
    intensity: f32,
    size: u32,
    rounds: usize,
) -> Result<Vec<PathTimes>> {
    let mut relighters = bakes
        .iter()
        .map(|p| lit(p, &LIGHTS[0], intensity))
        .collect::<Result<Vec<_>>>()?;
    for r in relighters.iter_mut() {
        render(r, size)?;
    }
    let edit = |k: usize| OverrideValue::Kd([0.3 + 0.1 * (k % 5) as f32, 0.3, 0.2]);
    let mut out = vec![0.0f32; 3 * (size * size) as usize];
    let mut samples = vec![[(); 7].map(|_| Vec::new()); bakes.len()];
    let mut step = 0u32;
    for round in 0..rounds {
        eprintln!("timing round {} of {rounds}", round + 1);
        for (r, t) in relighters.iter_mut().zip(samples.iter_mut()) {
            let base = r.default_camera();
            let mut camera = || {
                step += 1;
                base.orbited(0.25 * step as f32)
            };
            let (wall, s) = frame(r, camera(), &mut out)?;
            t[0].push(wall);
            t[3].push(s.view_s.unwrap_or(0.0));
            t[4].push(s.raster_s.unwrap_or(0.0));
            r.set_params(edit_material, &[edit(round)])?;
            let (wall, s) = frame(r, camera(), &mut out)?;
            t[1].push(wall);
            t[6].push(s.material_s.unwrap_or(0.0));
            r.set_environment_rotation(10.0 * (round + 1) as f32)?;
            r.set_params(edit_material, &[edit(round + 1)])?;
            let (wall, s) = frame(r, camera(), &mut out)?;
            t[2].push(wall);
            t[5].push(s.light_s.unwrap_or(0.0));
        }
    }
    Ok(samples
        .iter()
        .map(|t| PathTimes {
            view: median(&t[0]),
            view_brdf: median(&t[1]),
            view_brdf_light: median(&t[2]),
            view_stage: median(&t[3]),
            raster: median(&t[4]),
            light: median(&t[5]),
            material: median(&t[6]),
        })
        .collect())
}

/// The first editable material of the config (the one the timings edit).
pub(crate) fn editable_material(config: &BakeConfig) -> String {
    config
        .materials
        .iter()
        .find(|(_, m)| m.editable)
        .map(|(n, _)| n.clone())
        .unwrap_or_default()
}
