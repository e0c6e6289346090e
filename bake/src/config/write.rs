//! A [`BakeConfig`] written back as TOML ([`BakeConfig::to_toml`]), e.g. for
//! `bake model.glb --print-config > bake.toml`. Parsing the text again (from the same config
//! path) gives the same config, value for value: every key is written explicitly (but
//! `emission_oversampling` at its default: the key is per-pixel only), paths relative to the
//! config's folder, and every float in a form that reads back to the same f32.

use std::fmt::Write as _;
use std::path::Path;

use glam::Vec3;

use super::{BakeConfig, EnvironmentConfig, MissingNormals, Mode};
use crate::film_emission::DEFAULT_EMISSION_OVERSAMPLING;

impl BakeConfig {
    /// The config as TOML text that [`BakeConfig::parse`] (given the same `config_path`) turns
    /// back into an equal config. Paths inside the config's folder are written relative to it,
    /// others absolute.
    pub fn to_toml(&self) -> String {
        let folder = self.folder();
        let mut t = String::new();
        let w = &mut t;
        let _ = writeln!(
            w,
            "scene = {}",
            string(&path_text(&self.scene_path, folder))
        );
        let _ = writeln!(w, "output = {}", string(&path_text(&self.output, folder)));
        let mode = match self.mode {
            Mode::Pixel => "pixel",
            Mode::Vertex => "vertex",
        };
        let _ = writeln!(w, "mode = {}", string(mode));
        let _ = writeln!(w, "width = {}", self.width);
        let _ = writeln!(w, "height = {}", self.height);
        let _ = writeln!(w, "spp = {}", self.spp);
        // Per-pixel only, so written only when it is not the default: then changing `mode` to
        // "vertex" is all a printed per-pixel config needs (the vertex parser refuses the key).
        if self.mode == Mode::Pixel && self.emission_oversampling != DEFAULT_EMISSION_OVERSAMPLING {
            let _ = writeln!(w, "emission_oversampling = {}", self.emission_oversampling);
        }
        let _ = writeln!(w, "reflections = {}", self.reflections);
        let _ = writeln!(w, "seed = {}", self.seed);
        if self.missing_normals == MissingNormals::Smooth {
            let _ = writeln!(w, "missing_normals = \"smooth\"");
        }

        let _ = writeln!(w, "\n[environment]");
        match &self.environment {
            EnvironmentConfig::Color(c) => {
                let _ = writeln!(w, "color = {}", vec3(*c));
            }
            EnvironmentConfig::Map {
                path,
                intensity,
                rotation,
            } => {
                let _ = writeln!(w, "map = {}", string(&path_text(path, folder)));
                let _ = writeln!(w, "intensity = {}", float(*intensity));
                if *rotation != 0.0 {
                    let _ = writeln!(w, "rotation = {}", float(*rotation));
                }
            }
        }

        if let Some(cam) = &self.camera {
            let _ = writeln!(w, "\n[camera]");
            let _ = writeln!(w, "position = {}", vec3(cam.position));
            let _ = writeln!(w, "target = {}", vec3(cam.target));
            let _ = writeln!(w, "fov = {}", float(cam.fov));
        }

        for (name, m) in &self.materials {
            let _ = writeln!(w, "\n[materials.{}]", key(name));
            let _ = writeln!(w, "editable = {}", m.editable);
            if let Some(f) = m.family {
                let _ = writeln!(w, "family = {}", string(f.name()));
            }
            if let Some(kd) = m.kd {
                let _ = writeln!(w, "kd = {}", vec3(kd));
            }
            if let Some(ks) = m.ks {
                let _ = writeln!(w, "ks = {}", vec3(ks));
            }
            if let Some(s) = m.shininess {
                let _ = writeln!(w, "shininess = {}", float(s));
            }
            if let Some(a) = m.alpha {
                let _ = writeln!(w, "alpha = {}", float(a));
            }
        }

        if let Some(b) = &self.basis {
            let _ = writeln!(w, "\n[basis]");
            if let Some(n) = b.count {
                let _ = writeln!(w, "count = {n}");
            }
            if let Some(e) = b.error_target {
                let _ = writeln!(w, "error_target = {}", float(e));
            }
        }

        if let Some(v) = &self.vertex {
            let _ = writeln!(w, "\n[vertex]");
            if let Some(n) = v.secondary {
                let _ = writeln!(w, "secondary = {n}");
            }
            if let Some(k) = v.t0_terms {
                let _ = writeln!(w, "t0_terms = {k}");
            }
            if let Some(b) = v.light_bins {
                let _ = writeln!(w, "light_bins = {b}");
            }
        }
        t
    }
}

/// `path` relative to `folder` when inside it, else as it is; `/` separated.
fn path_text(path: &Path, folder: &Path) -> String {
    let p = path.strip_prefix(folder).unwrap_or(path);
    let parts: Vec<String> = p
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if p.is_absolute() {
        // Keep absolute paths as the OS writes them.
        p.to_string_lossy().into_owned()
    } else if parts.is_empty() {
        // The folder itself (`scene = "."`): an empty string would not parse back.
        ".".to_owned()
    } else {
        parts.join("/")
    }
}

/// A TOML basic string (quoted, escaped).
fn string(s: &str) -> String {
    toml::Value::String(s.to_owned()).to_string()
}

/// A TOML key: bare when it may be, else quoted.
fn key(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        s.to_owned()
    } else {
        string(s)
    }
}

/// A TOML float that reads back (TOML floats are f64, narrowed to f32) as exactly `x`.
fn float(x: f32) -> String {
    let short = format!("{x:?}");
    if short.parse::<f64>().map(|v| v as f32) == Ok(x) {
        short
    } else {
        format!("{:?}", x as f64)
    }
}

fn vec3(v: Vec3) -> String {
    format!("[{}, {}, {}]", float(v.x), float(v.y), float(v.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_read_back_exactly() {
        for x in [
            0.0f32,
            1.0,
            0.1,
            1e-30,
            3.4028235e38,
            std::f32::consts::FRAC_PI_4,
            -2.5e-7,
            123456.79,
        ] {
            let s = float(x);
            assert_eq!(s.parse::<f64>().unwrap() as f32, x, "{s}");
            let v: toml::Value = toml::from_str(&format!("x = {s}")).unwrap();
            assert!(v["x"].is_float(), "{s}");
        }
    }

    #[test]
    fn vertex_table_round_trips() {
        let text =
            "scene = \"x.gltf\"\nmode = \"vertex\"\n[vertex]\nsecondary = 7\nt0_terms = 200\nlight_bins = false\n";
        let c = BakeConfig::parse(text, "/s/bake.toml").unwrap();
        let back = BakeConfig::parse(&c.to_toml(), "/s/bake.toml").unwrap();
        assert_eq!(back, c);
        assert!(c
            .to_toml()
            .contains("[vertex]\nsecondary = 7\nt0_terms = 200\nlight_bins = false"));
    }

    #[test]
    fn keys_are_quoted_when_needed() {
        assert_eq!(key("bunny_1"), "bunny_1");
        assert_eq!(key("tall box"), "\"tall box\"");
        assert_eq!(key("a.b"), "\"a.b\"");
        assert_eq!(key("default#3"), "\"default#3\"");
    }
}
