//! The one relighter the server holds, brought to a tab's [`Settings`] and rendered.
//!
//! Tabs have their own settings but share one opened bake (a per-pixel bake's tensors are
//! held in memory once). Before a frame, only what differs from what the relighter has now is
//! set, so the per-vertex stages' caches survive: a camera move re-runs the view stage alone,
//! a material edit the material and view stages (docs/vertex.md). Environment maps from the
//! folder are read once and kept.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use prt_formats::envmap::load_latlong;
use prt_runtime::{LatLongMap, Relighter, RenderStats, RuntimeError, VertexRelighter};

use crate::reference::BakeTracing;
use crate::settings::{BakeInfo, MaterialValues, Settings, ViewSettings, BAKED_ENVIRONMENT};
use crate::ViewerError;

/// A linear frame and what it was rendered for.
#[derive(Clone, Debug)]
pub struct LinearFrame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 * width * height` floats, linear RGB, row-major, top row first.
    pub pixels: Vec<f32>,
    /// The settings it shows (exposure and tone as they were when it was rendered).
    pub settings: Settings,
    /// What the render cost.
    pub stats: RenderStats,
}

/// Where frames are relit: the CPU runtime, or (feature `gpu`) the GPU backend over it.
enum Engine {
    Cpu(Box<Relighter>),
    #[cfg(feature = "gpu")]
    Gpu(Box<prt_gpu::GpuRelighter>),
}

impl Engine {
    fn relighter(&self) -> &Relighter {
        match self {
            Engine::Cpu(r) => r,
            #[cfg(feature = "gpu")]
            Engine::Gpu(g) => g.relighter(),
        }
    }

    fn relighter_mut(&mut self) -> &mut Relighter {
        match self {
            Engine::Cpu(r) => r,
            #[cfg(feature = "gpu")]
            Engine::Gpu(g) => g.relighter_mut(),
        }
    }

    fn render_into(&mut self, out: &mut [f32]) -> Result<RenderStats, ViewerError> {
        match self {
            Engine::Cpu(r) => Ok(r.render_into(out)?),
            #[cfg(feature = "gpu")]
            Engine::Gpu(g) => {
                let s = g.render_into(out).map_err(gpu_error)?;
                Ok(RenderStats {
                    seconds: s.seconds,
                    light_s: s.light_s,
                    material_s: s.material_s,
                    bytes_read: s.bytes_read,
                    ..Default::default()
                })
            }
        }
    }
}

/// A GPU error as the viewer's: the runtime's own refusals keep their type (the page shows
/// them as the CPU path does).
#[cfg(feature = "gpu")]
fn gpu_error(e: prt_gpu::GpuError) -> ViewerError {
    match e {
        prt_gpu::GpuError::Runtime(r) => ViewerError::Runtime(r),
        e => ViewerError::Gpu(e.to_string()),
    }
}

/// The relighter of `bake` on the CPU, or with `gpu` on the default GPU adapter.
fn engine(bake: &Path, gpu: bool) -> Result<Engine, ViewerError> {
    let relighter = prt_runtime::open(bake)?;
    if !gpu {
        return Ok(Engine::Cpu(Box::new(relighter)));
    }
    #[cfg(feature = "gpu")]
    {
        let ctx = prt_gpu::GpuContext::new(&prt_gpu::GpuOptions::default()).map_err(gpu_error)?;
        let g = prt_gpu::GpuRelighter::new(&ctx, relighter).map_err(gpu_error)?;
        Ok(Engine::Gpu(Box::new(g)))
    }
    #[cfg(not(feature = "gpu"))]
    Err(ViewerError::Gpu(
        "this viewer was built without the GPU backend: cargo build --release -p prt-viewer \
         --features gpu --bin view (docs/gpu.md)"
            .into(),
    ))
}

/// The server's relighter, the environments it may load, and what it has set now.
pub struct Renderer {
    engine: Engine,
    /// Per-vertex: the folder the picker's maps come from.
    env_folder: Option<PathBuf>,
    /// Maps read so far, by picker name (the baked one from the start).
    env_cache: HashMap<String, LatLongMap>,
    /// What the relighter has set now: materials, and per vertex the environment's name.
    materials: Vec<MaterialValues>,
    environment: String,
}

/// The `.exr` and `.hdr` maps of a folder, by file name, sorted.
pub fn list_environments(folder: &Path) -> Result<Vec<String>, ViewerError> {
    let read = std::fs::read_dir(folder).map_err(|source| ViewerError::EnvFolder {
        path: folder.display().to_string(),
        source,
    })?;
    let mut names: Vec<String> = read
        .filter_map(Result::ok)
        .filter(|e| e.path().is_file())
        .filter_map(|e| e.file_name().into_string().ok())
        .filter(|n| {
            let lower = n.to_ascii_lowercase();
            lower.ends_with(".exr") || lower.ends_with(".hdr")
        })
        .collect();
    names.sort();
    Ok(names)
}

impl Renderer {
    /// Opens the bake (relit on the GPU with `gpu`); a per-vertex bake gets the maps of
    /// `env_folder` in its picker. Returns the renderer, what the bake offers and the
    /// settings it opens with.
    pub fn open(
        bake: &Path,
        env_folder: Option<&Path>,
        reference_unavailable: Option<String>,
        gpu: bool,
    ) -> Result<(Renderer, BakeInfo, Settings), ViewerError> {
        let engine = engine(bake, gpu)?;
        let relighter = engine.relighter();
        let mut env_cache = HashMap::new();
        let (environments, view) = match &relighter {
            Relighter::Pixel(_) => (None, None),
            Relighter::Vertex(v) => {
                let mut names = vec![BAKED_ENVIRONMENT.to_string()];
                if let Some(folder) = env_folder {
                    names.extend(list_environments(folder)?);
                }
                env_cache.insert(BAKED_ENVIRONMENT.to_string(), v.environment_map().clone());
                (Some(names), Some(initial_view(v)))
            }
        };
        let info = BakeInfo {
            bake: bake.display().to_string(),
            materials: relighter.materials(),
            environments,
            size: relighter.size(),
            reference_unavailable,
        };
        let settings = Settings::initial(&info, view);
        let renderer = Renderer {
            materials: settings.materials.clone(),
            environment: BAKED_ENVIRONMENT.to_string(),
            engine,
            env_folder: env_folder.map(Path::to_path_buf),
            env_cache,
        };
        Ok((renderer, info, settings))
    }

    /// Brings the relighter to `settings` (setting only what differs) and renders into
    /// `pixels` (resized as needed). On a refusal (an eye inside an object) the relighter
    /// keeps what it had for that setting and the error names it.
    pub fn render(
        &mut self,
        settings: &Settings,
        pixels: &mut Vec<f32>,
    ) -> Result<RenderStats, ViewerError> {
        for (want, have) in settings.materials.iter().zip(self.materials.iter_mut()) {
            if want.values != have.values {
                self.engine
                    .relighter_mut()
                    .set_params(&want.name, &want.values)?;
                have.values.clone_from(&want.values);
            }
        }
        if let (Relighter::Vertex(v), Some(view)) = (self.engine.relighter_mut(), &settings.view) {
            if view.environment != self.environment {
                let map = match self.env_cache.get(&view.environment) {
                    Some(map) => map.clone(),
                    None => {
                        let folder = self.env_folder.as_deref().unwrap_or(Path::new("."));
                        let path = folder.join(&view.environment);
                        // As `VertexRelighter::load_environment` reads it (and `relight --env`).
                        let (map, _) = load_latlong(&path, 1.0).map_err(|source| {
                            RuntimeError::EnvironmentFile {
                                path: path.display().to_string(),
                                source,
                            }
                        })?;
                        self.env_cache.insert(view.environment.clone(), map.clone());
                        map
                    }
                };
                v.set_environment(map)?;
                self.environment.clone_from(&view.environment);
            }
            v.set_environment_rotation(view.rotation)?;
            v.set_environment_intensity(view.intensity)?;
            if v.size() != (view.width, view.height) {
                v.set_size(view.width, view.height)?;
            }
            let frame = view.camera.frame().map_err(ViewerError::Camera)?;
            if v.camera() != frame {
                v.set_camera(frame)?;
            }
        }
        let (w, h) = self.engine.relighter().size();
        pixels.resize(3 * w as usize * h as usize, 0.0);
        let start = Instant::now();
        let mut stats = self.engine.render_into(pixels)?;
        // The camera's eye check and the setters' work belong to the frame too.
        stats.seconds = stats.seconds.max(start.elapsed().as_secs_f64());
        Ok(stats)
    }

    /// Antialiases silhouettes on the CPU (`on`, the runtime's default;
    /// `VertexRelighter::set_antialias`); the GPU backend does not antialias, and a per-pixel
    /// bake has nothing to antialias: both ignore it.
    // Without the feature `gpu` the engine is always the CPU's.
    #[allow(irrefutable_let_patterns)]
    pub fn set_antialias(&mut self, on: bool) {
        if let Engine::Cpu(r) = &mut self.engine {
            if let Relighter::Vertex(v) = r.as_mut() {
                v.set_antialias(on);
            }
        }
    }

    /// The image size now.
    pub fn size(&self) -> (u32, u32) {
        self.engine.relighter().size()
    }

    /// What the bake fixes about a reference render of it.
    pub fn tracing(&self) -> BakeTracing {
        match self.engine.relighter() {
            Relighter::Pixel(p) => BakeTracing {
                reflections: p.meta().reflections as usize,
                emission_oversampling: p.meta().emission_oversampling,
                seed: p.meta().seed,
            },
            Relighter::Vertex(v) => BakeTracing {
                reflections: v.meta().reflections as usize,
                emission_oversampling: None,
                seed: v.meta().seed,
            },
        }
    }
}

/// A per-vertex bake's view at open: the baked environment at its rotation and intensity 1,
/// the baked camera as an eye, a target and a field of view, the default image size.
fn initial_view(v: &VertexRelighter) -> ViewSettings {
    let frame = v.default_camera();
    // The baked camera stores no target: orbit about the point of its view ray nearest the
    // world's origin (the example scenes are built about it), at least half a metre ahead.
    let eye = frame.position;
    let along =
        -(eye[0] * frame.forward[0] + eye[1] * frame.forward[1] + eye[2] * frame.forward[2]);
    let t = along.max(0.5);
    let target = std::array::from_fn(|i| eye[i] + t * frame.forward[i]);
    let (width, height) = v.size();
    ViewSettings {
        environment: BAKED_ENVIRONMENT.to_string(),
        rotation: v.environment_rotation(),
        intensity: v.environment_intensity(),
        camera: prt_runtime::CameraSpec {
            eye,
            target,
            fov_deg: frame.yfov.to_degrees(),
        },
        width,
        height,
    }
}
