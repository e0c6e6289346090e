//! Validation of the config as written (`raw.rs`): every value checked against its range,
//! relative paths resolved against the config's folder, deprecated keys accepted with a
//! warning; the result is the [`super::BakeConfig`].

use super::raw::*;
use super::*;

impl BakeConfig {
    /// Like [`BakeConfig::parse`], with the warnings about deprecated keys (e.g. `[camera]
    /// yfov` in radians, now `fov` in degrees): each names the config, the key to write
    /// instead and the converted value.
    pub fn parse_with_warnings(
        text: &str,
        config_path: impl AsRef<Path>,
    ) -> Result<(BakeConfig, Vec<String>), ConfigError> {
        let config_path = config_path.as_ref().to_path_buf();
        let raw: RawConfig = toml::from_str(text).map_err(|source| ConfigError::Parse {
            path: config_path.clone(),
            source,
        })?;
        raw.validate(config_path)
    }
}

pub(super) struct Checker<'a> {
    path: &'a Path,
    /// Deprecation warnings, each naming the config.
    warnings: std::cell::RefCell<Vec<String>>,
}

impl Checker<'_> {
    pub(super) fn warn(&self, key: &str, message: impl std::fmt::Display) {
        self.warnings.borrow_mut().push(format!(
            "bake config {}: `{key}`: {message}",
            self.path.display()
        ));
    }

    pub(super) fn err(&self, key: &str, message: impl Into<String>) -> ConfigError {
        ConfigError::Invalid {
            path: self.path.to_path_buf(),
            key: key.to_owned(),
            message: message.into(),
        }
    }

    pub(super) fn range_u32(
        &self,
        key: &str,
        v: u32,
        lo: u32,
        hi: u32,
    ) -> Result<u32, ConfigError> {
        if v < lo || v > hi {
            return Err(self.err(
                key,
                format!("{v} is outside the accepted range [{lo}, {hi}]"),
            ));
        }
        Ok(v)
    }

    pub(super) fn range_f32(
        &self,
        key: &str,
        v: f32,
        lo: f32,
        hi: f32,
    ) -> Result<f32, ConfigError> {
        if !v.is_finite() {
            return Err(self.err(key, format!("{v} is not a finite number")));
        }
        if v < lo || v > hi {
            return Err(self.err(
                key,
                format!("{v} is outside the accepted range [{lo}, {hi}]"),
            ));
        }
        Ok(v)
    }

    /// A radiance or reflectance: every channel finite and >= 0.
    pub(super) fn color(&self, key: &str, c: Vec3) -> Result<Vec3, ConfigError> {
        if !c.is_finite() {
            return Err(self.err(key, format!("{c:?} has a non-finite channel")));
        }
        if c.min_element() < 0.0 {
            return Err(self.err(key, format!("{c:?} has a negative channel")));
        }
        Ok(c)
    }

    pub(super) fn file_path(&self, key: &str, written: &str) -> Result<PathBuf, ConfigError> {
        if written.trim().is_empty() {
            return Err(self.err(key, "the path is empty"));
        }
        Ok(resolve(self.path, written))
    }
}

impl RawConfig {
    pub(super) fn validate(
        self,
        config_path: PathBuf,
    ) -> Result<(BakeConfig, Vec<String>), ConfigError> {
        let c = Checker {
            path: &config_path,
            warnings: Default::default(),
        };
        let scene_path = c.file_path("scene", &self.scene)?;
        let output = match &self.output {
            Some(o) => c.file_path("output", o)?,
            None => default_output(&config_path),
        };
        let width = c.range_u32(
            "width",
            self.width.unwrap_or(DEFAULT_WIDTH),
            1,
            MAX_IMAGE_SIDE,
        )?;
        let height = c.range_u32(
            "height",
            self.height.unwrap_or(DEFAULT_HEIGHT),
            1,
            MAX_IMAGE_SIDE,
        )?;
        let spp = c.range_u32("spp", self.spp.unwrap_or(DEFAULT_SPP), 1, MAX_SPP)?;
        let reflections = c.range_u32(
            "reflections",
            self.reflections.unwrap_or(DEFAULT_REFLECTIONS),
            1,
            MAX_REFLECTIONS,
        )?;

        let environment = match self.environment {
            None => EnvironmentConfig::Color(Vec3::ZERO),
            Some(env) => {
                let intensity = match env.intensity {
                    Some(i) => c.range_f32("environment.intensity", i, 0.0, f32::MAX)?,
                    None => 1.0,
                };
                match (env.color, env.map) {
                    (Some(_), Some(_)) => {
                        return Err(c.err("environment", "give either `color` or `map`, not both"))
                    }
                    (None, None) => {
                        return Err(c.err(
                            "environment",
                            "the table needs `color = [r, g, b]` or `map = \"file.exr\"`",
                        ))
                    }
                    (Some(Rgb(col)), None) => {
                        if env.rotation.is_some() {
                            return Err(c.err(
                                "environment.rotation",
                                "only a `map` can be rotated (a constant colour is the same \
                                 from every direction)",
                            ));
                        }
                        let col = c.color("environment.color", col)?;
                        let scaled = c.color("environment.color", col * intensity)?;
                        EnvironmentConfig::Color(scaled)
                    }
                    (None, Some(map)) => {
                        let path = c.file_path("environment.map", &map)?;
                        let ext = path
                            .extension()
                            .map(|e| e.to_string_lossy().to_ascii_lowercase())
                            .unwrap_or_default();
                        if ext != "exr" && ext != "hdr" {
                            return Err(c.err(
                                "environment.map",
                                format!(
                                    "{} is neither an OpenEXR (.exr) nor a Radiance (.hdr) file",
                                    path.display()
                                ),
                            ));
                        }
                        let rotation = match env.rotation {
                            Some(r) => c.range_f32("environment.rotation", r, -360.0, 360.0)?,
                            None => 0.0,
                        };
                        EnvironmentConfig::Map {
                            path,
                            intensity,
                            rotation,
                        }
                    }
                }
            }
        };

        let mut materials = Vec::with_capacity(self.materials.0.len());
        for (name, m) in self.materials.0 {
            materials.push((name.clone(), validate_material(&c, &name, m)?));
        }

        if let Some(b) = &self.basis {
            if let Some(n) = b.count {
                c.range_u32("basis.count", n, 1, MAX_BASIS_COUNT)?;
            }
            if let Some(e) = b.error_target {
                if !(e.is_finite() && e > 0.0) {
                    return Err(c.err(
                        "basis.error_target",
                        format!("{e} must be a finite number > 0 (a relative error, e.g. 0.01)"),
                    ));
                }
            }
        }

        let camera = self
            .camera
            .map(|cam| validate_camera(&c, cam))
            .transpose()?;

        let mode = self.mode.unwrap_or(Mode::Pixel);
        let emission_oversampling = match self.emission_oversampling {
            Some(_) if mode == Mode::Vertex => {
                return Err(c.err(
                    "emission_oversampling",
                    "per-pixel only: remove this key for mode = \"vertex\" (it sets the \
                     camera's samples of a per-pixel bake; a per-vertex bake has none)",
                ))
            }
            Some(k) => c.range_u32("emission_oversampling", k, 1, MAX_EMISSION_OVERSAMPLING)?,
            None => DEFAULT_EMISSION_OVERSAMPLING,
        };
        if let Some(v) = &self.vertex {
            v.validate(&c, mode)?;
        }

        let config = BakeConfig {
            config_path: config_path.clone(),
            scene_path,
            output,
            mode,
            width,
            height,
            spp,
            emission_oversampling,
            reflections,
            seed: self.seed.unwrap_or(0),
            missing_normals: self.missing_normals.unwrap_or_default(),
            environment,
            materials,
            basis: self.basis,
            camera,
            vertex: self.vertex,
        };
        Ok((config, c.warnings.take()))
    }
}

fn validate_camera(c: &Checker, cam: RawCamera) -> Result<CameraConfig, ConfigError> {
    let position = Vec3::from_array(cam.position);
    let target = Vec3::from_array(cam.target);
    if !position.is_finite() {
        return Err(c.err("camera.position", format!("{position:?} is not finite")));
    }
    if !target.is_finite() {
        return Err(c.err("camera.target", format!("{target:?} is not finite")));
    }
    if target == position {
        return Err(c.err("camera.target", "must differ from `camera.position`"));
    }
    let fov = match (cam.fov, cam.yfov) {
        (Some(_), Some(_)) => {
            return Err(c.err(
                "camera.yfov",
                "give `fov` (degrees) only: `yfov` is its deprecated form in radians",
            ))
        }
        (Some(fov), None) => {
            if !(fov.is_finite() && fov > 0.0 && fov < 180.0) {
                return Err(c.err(
                    "camera.fov",
                    format!("{fov} must be in (0, 180) degrees (the vertical field of view)"),
                ));
            }
            fov
        }
        (None, Some(yfov)) => {
            if !(yfov.is_finite() && yfov > 0.0 && yfov < std::f32::consts::PI) {
                return Err(c.err(
                    "camera.yfov",
                    format!(
                        "{yfov} radians is not in (0, pi); `yfov` is deprecated: write the \
                         vertical field of view in degrees as `fov` (e.g. `fov = {yfov}` for \
                         {yfov} degrees)"
                    ),
                ));
            }
            // To 1e-4 degree, so that 40 degrees written in radians reads back as 40 (and
            // `--print-config` writes `fov = 40.0`), not 39.999996; unrounded where rounding
            // would reach 0 or 180.
            let degrees = yfov.to_degrees();
            let rounded = (degrees * 1e4).round() / 1e4;
            let fov = if rounded > 0.0 && rounded < 180.0 {
                rounded
            } else {
                degrees
            };
            c.warn(
                "camera.yfov",
                format!(
                    "deprecated (radians): write `fov = {fov}` (degrees) instead of \
                     `yfov = {yfov}`"
                ),
            );
            fov
        }
        (None, None) => DEFAULT_FOV,
    };
    let camera = CameraConfig {
        position,
        target,
        fov,
    };
    // The frame `--camera` would give this view: refused for the same views (straight up or
    // down), so a config and a command line accept the same cameras and render the same one.
    if let Err(e) = camera.spec().frame() {
        let reason = match e {
            prt_formats::view::CameraSpecError::Invalid { reason, .. } => reason,
            other => other.to_string(),
        };
        return Err(c.err("camera.target", reason));
    }
    Ok(camera)
}

fn validate_material(
    c: &Checker,
    name: &str,
    m: RawMaterial,
) -> Result<MaterialConfig, ConfigError> {
    let key = |k: &str| format!("materials.{name}.{k}");
    let family = match &m.family {
        None => None,
        Some(f) => Some(Family::parse(f).ok_or_else(|| {
            c.err(
                &key("family"),
                format!(
                    "unknown family \"{f}\" (expected \"diffuse\", \"blinn-phong\" or \"ggx\")"
                ),
            )
        })?),
    };
    let kd = m.kd.map(|Rgb(v)| c.color(&key("kd"), v)).transpose()?;
    let ks = m.ks.map(|Rgb(v)| c.color(&key("ks"), v)).transpose()?;
    let shininess = m
        .shininess
        .map(|s| c.range_f32(&key("shininess"), s, SHININESS_RANGE.0, SHININESS_RANGE.1))
        .transpose()?;
    let alpha = m
        .alpha
        .map(|a| c.range_f32(&key("alpha"), a, ALPHA_RANGE.0, ALPHA_RANGE.1))
        .transpose()?;

    // Parameters that the named family has no use for are almost always a mistake (e.g. a
    // `shininess` left behind after switching to ggx); say so instead of ignoring them.
    // Without `family`, the family comes from the glTF (diffuse or ggx), checked on load.
    if let Some(f) = family {
        let stray = |k: &str| {
            c.err(
                &key(k),
                format!("family \"{}\" has no `{k}` parameter", f.name()),
            )
        };
        match f {
            Family::Diffuse => {
                if ks.is_some() {
                    return Err(stray("ks"));
                }
                if shininess.is_some() {
                    return Err(stray("shininess"));
                }
                if alpha.is_some() {
                    return Err(stray("alpha"));
                }
            }
            Family::BlinnPhong => {
                if alpha.is_some() {
                    return Err(stray("alpha"));
                }
            }
            Family::Ggx => {
                if shininess.is_some() {
                    return Err(stray("shininess"));
                }
            }
        }
    } else if shininess.is_some() {
        // glTF materials never map to Blinn-Phong, so a shininess needs an explicit family.
        return Err(c.err(
            &key("shininess"),
            "`shininess` needs `family = \"blinn-phong\"` (glTF materials map to diffuse or ggx)",
        ));
    }

    Ok(MaterialConfig {
        editable: m.editable,
        family,
        kd,
        ks,
        shininess,
        alpha,
    })
}
