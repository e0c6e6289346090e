//! Per-vertex relighting (docs/vertex.md, sections 1, 3 and 4; thesis ch. 5): a per-vertex
//! bake rendered for any environment (a new lat-long map, or a rotation of the current one),
//! any camera and any material parameters, without tracing a ray.
//!
//! A frame runs three stages, each cached until what it depends on changes:
//!
//! | stage | runs when | work |
//! | --- | --- | --- |
//! | light | the environment or its rotation changes | light coefficients (cube map, Haar C0, coarse cubes C1 and C2, prefiltered cubes), then per vertex T0's sparse dots, `C1 . T1` (the big one) and `C2 . T2` (`incident.rs`) |
//! | material | a material parameter changes (or the light stage ran) | per vertex: the light-contracted T1, T2 with the slot coefficients, then the irradiance `E` and the incident projections `U` (`incident.rs`, constants in `constants.rs`) |
//! | view | every frame | rasterize (`raster.rs`; the film formula and the eye check in `view.rs`), interpolate the vertex records, shade each pixel's last reflection (`shade.rs`) |
//!
//! So a view-only change re-runs the view stage, a material change the material and view
//! stages, a light change all three; the image is the same bit for bit either way, and on any
//! number of threads (every vertex and every pixel is computed on its own, in a fixed order
//! of operations).
//!
//! An environment's light coefficients (cube map, Haar, coarse cubes, prefiltered cubes) are
//! computed in `light.rs`.
//!
//! Opening validates the whole file (`open.rs`); a per-pixel bake is refused with
//! [`RuntimeError::WrongKind`]. A camera is refused when its frame is not finite, its field of
//! view is not in (0, 180) degrees ([`RuntimeError::Raster`]) or its eye is inside an object
//! (the baker's rule, `view::eye_verdict`; [`RuntimeError::EyeInside`]).
//!
//! Surfaces are seen from the side of their vertex normals only: the baker stores the light
//! arriving on that side, so a pixel looking at the other side (or at a silhouette where the
//! interpolated normal turns away from the eye) is black.

mod antialias;
mod clustered;
pub(crate) mod compact_lights;
mod constants;
#[cfg(feature = "hooks")]
mod hooks;
pub(crate) mod incident;
pub(crate) mod light;
mod light_state;
mod open;
mod raster;
mod shade;
#[cfg(feature = "gpu-surface")]
pub(crate) mod surface;
pub(crate) mod true_lobe;
pub(crate) mod view;

pub use view::RasterError;

use std::time::Instant;

use prt_formats::envmap::{EnvMapReport, LatLongMap};
use prt_formats::lighting::cubemap::rotation_y;
use prt_formats::lighting::{prefilter, LightingError};
use prt_formats::overrides::OverrideValue;
use prt_formats::pixel::MaterialParams;
use prt_formats::vertex::VertexBakeMeta;
use prt_formats::view::CameraFrame;
use prt_formats::BakeFile;

use crate::error::RuntimeError;
use crate::image::{check_len, Image, RenderStats};
use crate::materials::{MaterialInfo, Materials};
use constants::ShadingConstants;
use incident::GroupShade;
use light_state::{light_coefficients, LightState, PrefilterCache};
use open::Scene;
use raster::{Rasterizer, VisibilityBuffer};
use shade::{Environment, Lobe, ViewCache, ViewInputs, Width};
use view::{eye_verdict, ViewRays};

/// The image side of a per-vertex bake until [`VertexRelighter::set_size`] changes it (the
/// bake stores a camera but no image size).
pub const DEFAULT_IMAGE_SIDE: u32 = 512;

/// The material stage's results.
struct ShadeState {
    groups: Vec<GroupShade>,
    /// Per material, its lobe at the current parameter.
    lobes: Vec<Option<Lobe>>,
}

/// An opened per-vertex bake with the current environment, camera, image size and materials
/// (docs/vertex.md; a frame runs only the stages whose inputs changed).
pub struct VertexRelighter {
    file: BakeFile,
    meta: VertexBakeMeta,
    scene: Scene,
    /// Per shading basis.
    constants: Vec<ShadingConstants>,
    ehat: [f32; 16],
    /// Per shading basis, its split widths as the view stage reads them.
    widths: Vec<Vec<Width>>,
    /// The nonzero split widths of all bases (degrees, ascending): the light's prefilters.
    prefilter_widths: Vec<f64>,
    materials: Materials,
    /// The environment as set (the baked one at open), before its intensity.
    environment: LatLongMap,
    /// The multiplier of the environment's radiance.
    intensity: f32,
    /// `environment` times `intensity`, when the intensity is not 1: what lights the scene.
    scaled_environment: Option<LatLongMap>,
    rotation_deg: f32,
    /// The current map's prefiltered cubes (per `prefilter_widths`), unturned and at
    /// intensity 1: a turn or an intensity change reuses them ([`PrefilterCache`] says why).
    prefiltered: PrefilterCache,
    light: Option<LightState>,
    shaded: Option<ShadeState>,
    rasterizer: Rasterizer,
    visibility: VisibilityBuffer,
    /// The view stage's memory kept between frames.
    view: ViewCache,
    /// Whether the view stage's vector loops may run (the hooks' `Kernel` switches them off).
    simd: bool,
    camera: CameraFrame,
    width: u32,
    height: u32,
    /// The last eye that passed the inside-geometry check.
    eye_checked: Option<[f32; 3]>,
    /// How many times the light stage and the material stage have run: a GPU backend
    /// (feature `gpu-surface`) uploads their results again only when these move.
    light_runs: u64,
    material_runs: u64,
    /// How many times the lighting map's texels have changed (a new map or intensity; not a
    /// turn): a GPU backend uploads the map and its prefiltered cubes again only then.
    map_runs: u64,
    /// Whether the light and material stages' per-vertex work runs here (the default), or
    /// a GPU backend runs it on its device (feature `gpu-surface`,
    /// `VertexRelighter::prepare_device_stages`): then only their per-environment and
    /// per-material parts run here.
    host_vertex_stages: bool,
    /// Whether only the direct light (I0) lights the scene: the measurement hook
    /// `set_direct_light_only` sets it for the error budget, which compares it with a
    /// reference of one reflection.
    direct_light_only: bool,
    /// The true lobe at the last reflection and its samples per pixel per side: the
    /// measurement hook `set_true_lobe` sets it for the error budget (`true_lobe.rs`).
    true_lobe: Option<(std::sync::Arc<dyn true_lobe::TrueLobe>, u32)>,
    /// Whether the map's compact lights are shaded per pixel with the true lobe
    /// (`compact_lights.rs`; on unless [`VertexRelighter::set_compact_lights`] turns it off).
    compact_lights: bool,
    /// Whether silhouettes and creases are sampled 16 times per pixel (`antialias.rs`; on
    /// unless [`VertexRelighter::set_antialias`] turns it off).
    antialias: bool,
}

impl VertexRelighter {
    /// Opens and validates a per-vertex bake file (checksums verified). A per-pixel bake is
    /// refused with [`RuntimeError::WrongKind`].
    pub fn open(path: impl AsRef<std::path::Path>) -> Result<VertexRelighter, RuntimeError> {
        VertexRelighter::from_file(BakeFile::open(path)?)
    }

    /// Validates an opened bake file as a per-vertex bake (see [`VertexRelighter::open`]).
    /// The environment is the one baked with (intensity 1, its baked rotation), the camera
    /// the baked one, the image [`DEFAULT_IMAGE_SIDE`] square, the materials at their baked
    /// parameters.
    pub fn from_file(file: BakeFile) -> Result<VertexRelighter, RuntimeError> {
        let (meta, scene) = open::validate(&file)?;
        let path = file.path().display().to_string();
        let schema = |reason: String| RuntimeError::VertexSchema {
            path: path.clone(),
            reason,
        };
        let mut materials = Materials::new(&meta.materials, &meta.bases).map_err(&schema)?;
        // A material's lobe is also evaluated with its group's shading basis, whose sampled
        // range clamps it too.
        for (m, group) in scene.material_group.iter().enumerate() {
            let shading = group.and_then(|g| meta.groups[g as usize].shading);
            if let Some(b) = shading {
                materials.narrow_sampled(m, &scene.shading[b as usize].param_samples);
            }
        }
        let constants = scene.shading.iter().map(ShadingConstants::new).collect();
        // Every width is a prefiltered cube, width 0 too (`ShadingBasis::spike_width_deg`).
        let mut prefilter_widths: Vec<f64> = scene
            .shading
            .iter()
            .flat_map(|b| (0..b.n_widths()).filter_map(|k| b.rendered_width_deg(k)))
            .map(f64::from)
            .collect();
        prefilter_widths.sort_by(f64::total_cmp);
        prefilter_widths.dedup();
        let mut widths = Vec::with_capacity(scene.shading.len());
        for b in &scene.shading {
            let mut ws = Vec::with_capacity(b.split_widths_deg.len());
            for w in (0..b.n_widths()).filter_map(|k| b.rendered_width_deg(k)) {
                let sigma = f64::from(w).to_radians();
                let f = prefilter::sh_factors(sigma)?;
                let k = prefilter::kernel_integral(sigma)?;
                let i = prefilter_widths
                    .iter()
                    .position(|&x| x == f64::from(w))
                    .unwrap_or(usize::MAX);
                ws.push(Width {
                    degrees: w,
                    cube: i,
                    sh_factors: f.map(|x| (x / k) as f32),
                    sigma: sigma as f32,
                });
            }
            widths.push(ws);
        }
        let (environment, rotation_deg) = scene.environment.clone();
        let camera = default_camera(&meta);
        Ok(VertexRelighter {
            file,
            meta,
            scene,
            constants,
            ehat: constants::irradiance_sh(),
            widths,
            prefilter_widths,
            materials,
            environment,
            intensity: 1.0,
            scaled_environment: None,
            rotation_deg,
            prefiltered: PrefilterCache::default(),
            light: None,
            shaded: None,
            rasterizer: Rasterizer::new(),
            visibility: VisibilityBuffer {
                width: 0,
                height: 0,
                near: 0.0,
                fragments: Vec::new(),
            },
            view: ViewCache::default(),
            simd: true,
            camera,
            width: DEFAULT_IMAGE_SIDE,
            height: DEFAULT_IMAGE_SIDE,
            eye_checked: None,
            light_runs: 0,
            material_runs: 0,
            map_runs: 0,
            host_vertex_stages: true,
            direct_light_only: false,
            true_lobe: None,
            antialias: true,
            compact_lights: true,
        })
    }

    /// The bake's per-vertex metadata (materials, groups, the baked environment and camera).
    pub fn meta(&self) -> &VertexBakeMeta {
        &self.meta
    }

    /// Every material with its family, current parameters and their ranges.
    pub fn materials(&self) -> Vec<MaterialInfo> {
        self.materials.info()
    }

    /// Current parameters of material `name`.
    pub fn params(&self, name: &str) -> Result<MaterialParams, RuntimeError> {
        self.materials.params(name)
    }

    /// Sets parameters of the editable material `name`, all or none (see
    /// [`crate::Relighter::set_params`]). The material stage runs at the next render.
    pub fn set_params(&mut self, name: &str, values: &[OverrideValue]) -> Result<(), RuntimeError> {
        self.materials.set(name, values)?;
        self.shaded = None;
        Ok(())
    }

    /// The image size `(width, height)` in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Renders `width` x `height` images from now on; a size outside
    /// `1..=16384` is refused ([`RuntimeError::Raster`]).
    pub fn set_size(&mut self, width: u32, height: u32) -> Result<(), RuntimeError> {
        ViewRays::new(&self.camera, width, height)?;
        (self.width, self.height) = (width, height);
        Ok(())
    }

    /// The current camera.
    pub fn camera(&self) -> CameraFrame {
        self.camera
    }

    /// The camera the scene was baked with, as a frame (right = forward x up).
    pub fn default_camera(&self) -> CameraFrame {
        default_camera(&self.meta)
    }

    /// Views the scene through `camera` from now on (a view-only change: only the view stage
    /// runs at the next render). Refused, and the camera kept, when its frame is not finite,
    /// its field of view is not in (0, 180) degrees ([`RuntimeError::Raster`]) or its eye is
    /// inside an object ([`RuntimeError::EyeInside`]).
    pub fn set_camera(&mut self, camera: CameraFrame) -> Result<(), RuntimeError> {
        ViewRays::new(&camera, self.width, self.height)?;
        self.check_eye(camera.position)?;
        self.camera = camera;
        Ok(())
    }

    /// The current environment map as set (before its intensity; the baked one at open).
    pub fn environment_map(&self) -> &LatLongMap {
        &self.environment
    }

    /// The current environment's rotation about +Y, in degrees.
    pub fn environment_rotation(&self) -> f32 {
        self.rotation_deg
    }

    /// The current environment's intensity multiplier.
    pub fn environment_intensity(&self) -> f32 {
        self.intensity
    }

    /// Lights the scene with `map`, at the current rotation and intensity. The light stage
    /// runs at the next render.
    pub fn set_environment(&mut self, map: LatLongMap) -> Result<(), RuntimeError> {
        let scaled = scaled(&map, self.intensity)?;
        self.environment = map;
        self.scaled_environment = scaled;
        self.prefiltered.clear();
        self.map_runs += 1;
        self.light = None;
        Ok(())
    }

    /// [`VertexRelighter::set_environment`] from texels in memory: `3 * width * height`
    /// floats, a `height` x `width` x 3 array (row-major, top row first, linear RGB), checked
    /// as `LatLongMap::new` checks them: NaN or infinite texels are refused, negative channels
    /// clamped to 0 (counted in the report).
    pub fn set_environment_texels(
        &mut self,
        width: usize,
        height: usize,
        texels: &[f32],
    ) -> Result<EnvMapReport, RuntimeError> {
        if texels.len() != 3 * width * height {
            return Err(RuntimeError::BufferSize {
                what: "the environment's texels",
                width: width as u32,
                height: height as u32,
                expected: 3 * width * height,
                got: texels.len(),
            });
        }
        let texels = texels.as_chunks::<3>().0.to_vec();
        let (map, report) = LatLongMap::new(width, height, texels, 1.0)?;
        self.set_environment(map)?;
        Ok(report)
    }

    /// [`VertexRelighter::set_environment`] from a lat-long map file (`.exr` or `.hdr`),
    /// checked as [`VertexRelighter::set_environment_texels`] checks texels.
    #[cfg(feature = "image-io")]
    pub fn load_environment(
        &mut self,
        path: impl AsRef<std::path::Path>,
    ) -> Result<EnvMapReport, RuntimeError> {
        let path = path.as_ref();
        let (map, report) = prt_formats::envmap::load_latlong(path, 1.0).map_err(|source| {
            RuntimeError::EnvironmentFile {
                path: path.display().to_string(),
                source,
            }
        })?;
        self.set_environment(map)?;
        Ok(report)
    }

    /// Turns the environment to `rotation_deg` degrees about +Y (absolute, not added to the
    /// current rotation; the right-hand rule, docs/conventions.md). The light stage runs at
    /// the next render unless the rotation is unchanged.
    pub fn set_environment_rotation(&mut self, rotation_deg: f32) -> Result<(), RuntimeError> {
        check_rotation(rotation_deg)?;
        if rotation_deg != self.rotation_deg {
            self.rotation_deg = rotation_deg;
            self.light = None;
        }
        Ok(())
    }

    /// Multiplies the environment's radiance by `intensity` (absolute: 1 is the map as set;
    /// finite and >= 0). The light stage runs at the next render unless it is unchanged.
    pub fn set_environment_intensity(&mut self, intensity: f32) -> Result<(), RuntimeError> {
        if intensity == self.intensity {
            return Ok(());
        }
        self.scaled_environment = scaled(&self.environment, intensity)?;
        self.intensity = intensity;
        self.map_runs += 1;
        self.light = None;
        Ok(())
    }

    /// Renders the current view into a new [`Image`] (see [`VertexRelighter::render_into`]).
    pub fn render(&mut self) -> Result<Image, RuntimeError> {
        let mut image = Image::new(self.width, self.height);
        self.render_into(image.pixels.as_flattened_mut())?;
        Ok(image)
    }

    /// Renders the current camera's view at the current size into `out`: `3 * width *
    /// height` floats, linear RGB, row-major, top row first (anything else is refused with
    /// [`RuntimeError::BufferSize`]), running the stages whose inputs changed (see the module
    /// documentation). Every float is written and none is read; nothing is written on error.
    pub fn render_into(&mut self, out: &mut [f32]) -> Result<RenderStats, RuntimeError> {
        let start = Instant::now();
        let (camera, width, height) = (self.camera, self.width, self.height);
        check_len("the output buffer", out, width, height)?;
        let (rays, light_s, material_s) = self.prepare_frame(true)?;
        let view_start = Instant::now();
        self.rasterizer.render(
            &self.scene.positions,
            &self.scene.triangles,
            &camera,
            width,
            height,
            &mut self.visibility,
        )?;
        let raster_s = view_start.elapsed().as_secs_f64();
        let (Some((light, _)), Some(shaded)) =
            (self.light.as_ref().and_then(LightState::host), &self.shaded)
        else {
            return Err(self.no_stage_result());
        };
        // The true lobe's switch draws directions of the map too (built per frame: the
        // budget's measurement, not a user's path).
        let env_sampler = self
            .true_lobe
            .as_ref()
            .and_then(|_| true_lobe::EnvSampler::new(self.lighting_map()));
        let inputs = ViewInputs {
            scene: &self.scene,
            shades: &shaded.groups,
            file_bytes: self.file.file_bytes(),
            cache: &self.view,
            lobes: &shaded.lobes,
            widths: &self.widths,
            light,
            environment: Environment {
                map: self.lighting_map(),
                back: rotation_y(-f64::from(self.rotation_deg)),
                turned: self.rotation_deg != 0.0,
            },
            eye: camera.position,
            background_samples: rays
                .background_samples(self.lighting_map().width, self.lighting_map().height),
            true_lobe: self
                .true_lobe
                .as_ref()
                .map(|(lobe, side)| true_lobe::TrueLobeSwitch {
                    lobe: lobe.as_ref(),
                    side: *side,
                    env: env_sampler.as_ref(),
                }),
            light_taps: compact_lights::light_taps(&light.compact_lights),
        };
        shade::view_stage(&inputs, &rays, &self.visibility, self.simd, out);
        let mut antialiased_pixels = None;
        if self.antialias {
            let mut edges = Vec::new();
            antialias::edge_pixels(&self.visibility, &self.scene.triangles, out, &mut edges);
            let mut parts = Vec::new();
            self.rasterizer.samples(
                &self.scene.triangles,
                &camera,
                &self.visibility,
                &edges,
                &mut parts,
            )?;
            antialias::resolve(&inputs, &rays, &self.visibility, &parts, out);
            antialiased_pixels = Some(edges.len() as u32);
        }
        Ok(RenderStats {
            seconds: start.elapsed().as_secs_f64(),
            light_s,
            material_s,
            view_s: Some(view_start.elapsed().as_secs_f64()),
            raster_s: Some(raster_s),
            antialiased_pixels,
            bytes_read: None,
        })
    }

    /// What a frame needs before its view stage: the camera's rays at the current size, the
    /// eye check, the light and material stages (each when its inputs changed; their times
    /// when they ran), the split widths' check against the light's prefiltered cubes and the
    /// view stage's per-frame material table.
    /// `host_vertex_stages`: whether the stages' per-vertex work runs here (see the field).
    fn prepare_frame(
        &mut self,
        host_vertex_stages: bool,
    ) -> Result<(ViewRays, Option<f64>, Option<f64>), RuntimeError> {
        let rays = ViewRays::new(&self.camera, self.width, self.height)?;
        self.check_eye(self.camera.position)?;
        self.set_host_vertex_stages(host_vertex_stages);
        let light_s = self.ensure_light()?;
        let material_s = self.ensure_shaded();
        let (Some(light), Some(shaded)) = (&self.light, &self.shaded) else {
            // Both were just made.
            return Err(self.no_stage_result());
        };
        for (b, ws) in self.widths.iter().enumerate() {
            for w in ws {
                if light.widths_deg().get(w.cube) != Some(&f64::from(w.degrees)) {
                    return Err(RuntimeError::VertexSchema {
                        path: self.file.path().display().to_string(),
                        reason: format!(
                            "shading basis {b}: split width {} degrees does not match the \
                             light's prefiltered widths {:?}",
                            w.degrees,
                            light.widths_deg()
                        ),
                    });
                }
            }
        }
        self.view.prepare(
            &self.file,
            &self.scene,
            &self.meta,
            self.materials.all(),
            &shaded.lobes,
        )?;
        Ok((rays, light_s, material_s))
    }

    /// Moves the stages' per-vertex work here or to a device; their results are made again
    /// at the next frame when it moves.
    fn set_host_vertex_stages(&mut self, on: bool) {
        if self.host_vertex_stages != on {
            self.host_vertex_stages = on;
            self.light = None;
            self.shaded = None;
        }
    }

    /// The map that lights the scene: the environment as set, times its intensity.
    fn lighting_map(&self) -> &LatLongMap {
        self.scaled_environment
            .as_ref()
            .unwrap_or(&self.environment)
    }

    /// The error of a frame whose light or material stage left no result (never expected:
    /// `prepare_frame` runs both).
    fn no_stage_result(&self) -> RuntimeError {
        RuntimeError::VertexSchema {
            path: self.file.path().display().to_string(),
            reason: "the light or material stage has no result".into(),
        }
    }

    /// Shades the map's compact lights (a sun, a studio lamp: its few bright texels, taken out
    /// of the map) per pixel with each glossy material's true lobe (`on`, the default), or
    /// leaves the whole map to the shading basis (docs/vertex.md, "Compact lights"). The
    /// lights cost a lobe evaluation and a visibility lookup per light per glossy pixel (a
    /// GPU backend's frames shade them too: `gpu_surface::VertexSurface::compact_lights`).
    pub fn set_compact_lights(&mut self, on: bool) {
        if self.compact_lights != on {
            self.compact_lights = on;
            // The prefiltered cubes change (of the map or of the map less its lights).
            self.map_runs += 1;
            self.light = None;
            self.shaded = None;
        }
    }

    /// Whether the map's compact lights are shaded per pixel
    /// ([`VertexRelighter::set_compact_lights`]).
    pub fn compact_lights(&self) -> bool {
        self.compact_lights
    }

    /// Samples the pixels on silhouettes and creases 16 times (`on`, the default) instead of
    /// shading each pixel at its centre alone (docs/vertex.md, "Silhouettes are
    /// antialiased"): the pixels where a neighbour sees another surface and looks different
    /// become the average of what the pixel holds, as a path tracer's jittered rays see it.
    /// A GPU backend's frames are not antialiased (docs/gpu.md).
    pub fn set_antialias(&mut self, on: bool) {
        self.antialias = on;
    }

    /// Whether silhouettes and creases are antialiased ([`VertexRelighter::set_antialias`]).
    pub fn antialias(&self) -> bool {
        self.antialias
    }

    /// RGB coefficient of every global slot for the current parameters, and whether any
    /// parameter lay outside its basis' sampled range (and was clamped).
    #[cfg(any(feature = "hooks", feature = "gpu-surface"))]
    pub fn coefficients(&self) -> (Vec<[f32; 3]>, bool) {
        self.materials.coefficients()
    }

    /// The light arriving at mesh vertex `vertex` for the current environment and materials
    /// (running the light and material stages if needed); `None` for a vertex out of range or
    /// in no group.
    #[cfg(feature = "hooks")]
    pub fn vertex_incident(
        &mut self,
        vertex: usize,
    ) -> Result<Option<incident::VertexIncident>, RuntimeError> {
        self.set_host_vertex_stages(true);
        self.ensure_light()?;
        self.ensure_shaded();
        let Some(&(g, local)) = self.scene.vertex_group.get(vertex) else {
            return Ok(None);
        };
        let Some(shaded) = &self.shaded else {
            return Ok(None);
        };
        Ok(incident::VertexIncident::of(&shaded.groups, g, local))
    }

    /// Refuses an eye inside an object (checked once per eye position).
    fn check_eye(&mut self, eye: [f32; 3]) -> Result<(), RuntimeError> {
        if self.eye_checked == Some(eye) {
            return Ok(());
        }
        let s = &self.scene;
        let verdict = eye_verdict(
            &s.positions,
            &s.normals,
            &s.triangles,
            &s.triangle_material,
            eye,
        )?;
        if verdict.inside {
            let material = verdict
                .material
                .and_then(|m| self.meta.materials.get(m))
                .map_or_else(|| "an object".to_string(), |m| m.name.clone());
            return Err(RuntimeError::EyeInside {
                eye,
                material,
                back: verdict.back,
                total: verdict.total,
            });
        }
        self.eye_checked = Some(eye);
        Ok(())
    }

    /// Runs the light stage unless its result is current; its time when it ran.
    fn ensure_light(&mut self) -> Result<Option<f64>, RuntimeError> {
        if self.light.is_some() {
            return Ok(None);
        }
        let start = Instant::now();
        let compact = self.compact_lights;
        let prefiltered = self.prefiltered.scaled(
            &self.environment,
            &self.prefilter_widths,
            self.intensity,
            compact,
        )?;
        if !self.host_vertex_stages {
            self.light = Some(LightState::Device {
                widths_deg: self.prefilter_widths.clone(),
                prefiltered,
            });
            self.light_runs += 1;
            self.shaded = None;
            return Ok(Some(start.elapsed().as_secs_f64()));
        }
        let mut coefficients = light_coefficients(
            self.lighting_map(),
            self.rotation_deg,
            &self.prefilter_widths,
            prefiltered,
            self.prefiltered
                .kept_extraction()
                .filter(|_| compact)
                .map(|e| (e, self.intensity)),
        )?;
        if self.needs_open_sky() {
            coefficients.open_sky = Some(light::open_sky(&coefficients.cube)?);
        }
        if self.direct_light_only {
            for cube in [&mut coefficients.one_bounce, &mut coefficients.two_bounce] {
                let size = cube.size();
                *cube = prt_formats::lighting::cubemap::CubeMap::constant(size, [0.0; 3])?;
            }
        }
        let groups = incident::light_stage(&self.file, &self.meta, &self.scene, &coefficients)?;
        self.light = Some(LightState::Host {
            coefficients: Box::new(coefficients),
            groups,
        });
        self.light_runs += 1;
        self.shaded = None;
        Ok(Some(start.elapsed().as_secs_f64()))
    }

    /// Whether the light needs the open sky's irradiance per normal: for vertices whose
    /// irradiance row is the occluded part, and for the view stage's bent normals.
    fn needs_open_sky(&self) -> bool {
        let open_rows = self.scene.groups.iter().any(|l| l.t0_open.contains(&true));
        let normal_maps = self.meta.material_normal_maps.iter().any(Option::is_some);
        open_rows || normal_maps
    }

    /// Runs the material stage unless its result is current (the light stage must have run);
    /// its time when it ran.
    fn ensure_shaded(&mut self) -> Option<f64> {
        if self.shaded.is_some() {
            return None;
        }
        let light = self.light.as_ref()?;
        let start = Instant::now();
        // Whether a parameter was clamped is told by `MaterialInfo` (its sampled range).
        let (coeff, _) = self.materials.coefficients();
        let groups = match light.host() {
            Some((_, light_groups)) if self.host_vertex_stages => incident::material_stage(
                &self.meta,
                &self.scene,
                light_groups,
                &self.constants,
                &self.ehat,
                &coeff,
            ),
            _ => Vec::new(),
        };
        let params = self.materials.all();
        let mut lobes = Vec::with_capacity(params.len());
        for (m, p) in params.iter().enumerate() {
            let basis = self.scene.material_group[m]
                .and_then(|g| self.meta.groups[g as usize].shading)
                .map(|b| b as usize);
            lobes.push(basis.map(|b| {
                let sb = &self.scene.shading[b];
                let mut uh = [0.0f32; prt_formats::basis::MAX_SHADING_RANK];
                sb.u_h_row(p.param, &mut uh);
                let mut core = vec![0.0f32; sb.ranks.o * sb.ranks.i];
                sb.contract_core(&uh, &mut core);
                Lobe {
                    basis: b,
                    core,
                    param: p.param,
                }
            }));
        }
        self.shaded = Some(ShadeState { groups, lobes });
        self.material_runs += 1;
        Some(start.elapsed().as_secs_f64())
    }
}

/// The camera a bake was made with, as a frame (right = forward x up).
fn default_camera(meta: &VertexBakeMeta) -> CameraFrame {
    let c = &meta.camera;
    let (f, u) = (c.forward, c.up);
    let r = [
        f[1] * u[2] - f[2] * u[1],
        f[2] * u[0] - f[0] * u[2],
        f[0] * u[1] - f[1] * u[0],
    ];
    let len = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    CameraFrame {
        position: c.position,
        forward: f,
        right: r.map(|x| x / len),
        up: u,
        yfov: c.yfov,
    }
}

/// `map` times `intensity` (checked as `LatLongMap::new` checks a map), or `None` at 1, where
/// the map lights the scene as it is.
fn scaled(map: &LatLongMap, intensity: f32) -> Result<Option<LatLongMap>, RuntimeError> {
    if intensity == 1.0 {
        return Ok(None);
    }
    let (map, _) = LatLongMap::new(map.width, map.height, map.texels.clone(), intensity)?;
    Ok(Some(map))
}

fn check_rotation(rotation_deg: f32) -> Result<(), RuntimeError> {
    if rotation_deg.is_finite() {
        return Ok(());
    }
    Err(RuntimeError::Lighting(LightingError::InvalidParameter {
        what: "environment rotation (degrees)",
        expected: "a finite number",
        value: f64::from(rotation_deg),
    }))
}

#[cfg(test)]
mod tests;
