//! Target `config`: the bake-config parser (`prt_bake::config::BakeConfig::parse`), its
//! round trip through `BakeConfig::to_toml` (the text must parse back to an equal config,
//! as docs/config.md promises), and the config's resolution against its scene
//! (`prt_bake::run::load_scene`: material names and parameters checked against the glTF, the
//! environment map loaded) when it names one of the example scenes.
//!
//! The example scenes and a small environment map are copied into one scratch folder, where
//! the config is parsed as `bake.toml`, so every seed's relative paths resolve there.
//!
//! Mutations: raw bytes and lines of the text; numbers replaced by boundary spellings (nan,
//! inf, past u32/i64/u64); and the parsed TOML tree (values of the wrong type, huge, negative
//! or non-finite numbers, missing and unknown keys, extra material tables).

use std::path::{Path, PathBuf};

use prt_bake::config::{BakeConfig, EnvironmentConfig};
use prt_bake::progress::Silent;
use toml::{Table, Value};

use crate::engine::{outcome, Target};
use crate::mutate::{havoc, line_op, replace_number, Dice};

const MAX_LEN: usize = 64 << 10;

/// Keys of the config (every level) and names of the scenes' materials.
const KEYS: &[&str] = &[
    "scene",
    "output",
    "mode",
    "width",
    "height",
    "spp",
    "reflections",
    "seed",
    "environment",
    "color",
    "map",
    "intensity",
    "rotation",
    "materials",
    "editable",
    "family",
    "kd",
    "ks",
    "shininess",
    "alpha",
    "basis",
    "count",
    "error_target",
    "camera",
    "position",
    "target",
    "fov",
    "yfov",
    "bake",
    "bunny",
    "tall_box",
    "white",
    "light",
    "ring",
    "floor",
    "sphere",
    "default",
    "material0",
];

/// Strings worth trying as values.
const STRINGS: &[&str] = &[
    "cornell.gltf",
    "ring.gltf",
    "furnace.glb",
    "cornell.bin",
    "sky.exr",
    "sky.hdr",
    "missing.exr",
    "out/x.prtbake",
    "",
    " ",
    "/",
    ".",
    "..",
    "pixel",
    "vertex",
    "PIXEL",
    "diffuse",
    "lambert",
    "blinn-phong",
    "phong",
    "blinnphong",
    "ggx",
    "GGX",
    "x",
];

const SCENE_FILES: &[(&str, &str)] = &[
    ("cornell", "cornell.gltf"),
    ("cornell", "cornell.bin"),
    ("ring", "ring.gltf"),
    ("ring", "ring.bin"),
    ("furnace", "furnace.glb"),
];

/// Seeds beyond the example scenes' configs: every table and key, aliases, boundaries.
const EXTRA_SEEDS: &[&str] = &[
    r#"scene = "ring.gltf"
output = "out/x.prtbake"
mode = "vertex"
width = 3
height = 2
spp = 1
reflections = 64
seed = 9223372036854775807

[environment]
map = "sky.exr"
intensity = 0.5
rotation = -90

[materials.ring]
editable = true
family = "ggx"
kd = [0.1, 0.2, 0.3]
ks = 0.5
alpha = 0.0001

[materials.floor]
family = "lambert"
kd = 0.25

[basis]
error_target = 0.05

[camera]
position = [0.0, 1.0, 2.0]
target = [0.0, 0.0, 0.0]
yfov = 1.0
"#,
    r#"scene = "cornell.gltf"
width = 16384
height = 1
spp = 1048576
reflections = 1

[environment]
color = 0.5
intensity = 2

[materials.white]
editable = true
family = "phong"
ks = [0.0, 0.0, 0.0]
shininess = 1000000

[materials.light]
kd = 1

[basis]
count = 1024
"#,
    r#"scene = "furnace.glb"

[materials.sphere]
editable = true
family = "blinnphong"
ks = 0.04
shininess = 0
"#,
];

pub struct ConfigTarget {
    scenes: PathBuf,
    extra: Vec<PathBuf>,
    dir: tempfile::TempDir,
    config_path: PathBuf,
    /// The files a config may load (scenes and the environment map, in the scratch folder).
    loadable: Vec<PathBuf>,
}

impl ConfigTarget {
    pub fn new(scenes: &Path, extra: Vec<PathBuf>) -> anyhow::Result<Self> {
        let dir = tempfile::tempdir()?;
        let config_path = dir.path().join("bake.toml");
        Ok(ConfigTarget {
            scenes: scenes.to_path_buf(),
            extra,
            dir,
            config_path,
            loadable: Vec::new(),
        })
    }

    fn mutate_tree(&self, parent: &[u8], d: &mut Dice) -> Option<Vec<u8>> {
        let text = std::str::from_utf8(parent).ok()?;
        let mut table: Table = text.parse().ok()?;
        for _ in 0..1 + d.below(3) {
            mutate_table(&mut table, d);
        }
        toml::to_string(&table).ok().map(String::into_bytes)
    }
}

/// An interesting TOML value, of any type.
fn value(d: &mut Dice) -> Value {
    match d.below(12) {
        0 => Value::Integer(*d.pick(&[
            0,
            1,
            -1,
            2,
            64,
            65,
            16384,
            16385,
            1 << 20,
            (1 << 20) + 1,
            1024,
            1025,
            u32::MAX as i64,
            u32::MAX as i64 + 1,
            i64::MAX,
            i64::MIN,
        ])),
        1 => Value::Float(*d.pick(&[
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -0.0,
            0.0,
            1e39,
            -1e39,
            1e-46,
            std::f64::consts::PI,
            1e-4,
            9.9e-5,
            1e6,
            1.1e6,
            0.5,
        ])),
        2 | 3 => Value::String(d.pick(STRINGS).to_string()),
        4 => Value::Boolean(d.chance(0.5)),
        5 => Value::Array(vec![]),
        6 => Value::Array(
            (0..*d.pick(&[1, 2, 3, 4]))
                .map(|_| Value::Float(*d.pick(&[0.0, 1.0, -1.0, f64::NAN, 1e39])))
                .collect(),
        ),
        7 => Value::Array(vec![
            Value::String("a".into()),
            Value::Integer(1),
            Value::Float(2.0),
        ]),
        8 => Value::Table(Table::new()),
        9 => "1979-05-27T07:32:00Z"
            .parse()
            .map_or(Value::Integer(0), Value::Datetime),
        _ => {
            let mut t = Table::new();
            t.insert(
                d.pick(KEYS).to_string(),
                Value::Float(*d.pick(&[0.5, 1.0, f64::NAN])),
            );
            Value::Table(t)
        }
    }
}

/// One structural mutation somewhere in the tree (a random walk picks the node).
fn mutate_table(root: &mut Table, d: &mut Dice) {
    let mut table = root;
    loop {
        let keys: Vec<String> = table.keys().cloned().collect();
        if keys.is_empty() || d.chance(0.3) {
            break;
        }
        let k = d.pick(&keys).clone();
        match table.get_mut(&k) {
            Some(Value::Table(_)) => {}
            Some(v) => {
                mutate_value(v, d);
                return;
            }
            None => return,
        }
        match table.get_mut(&k) {
            Some(Value::Table(t)) => table = t,
            _ => return,
        }
    }
    let keys: Vec<String> = table.keys().cloned().collect();
    match d.below(5) {
        0 | 1 if !keys.is_empty() => {
            table.remove(d.pick(&keys));
        }
        2 if !keys.is_empty() => {
            // Rename a key (an unknown key, or another table's key).
            let k = d.pick(&keys).clone();
            if let Some(v) = table.remove(&k) {
                table.insert(d.pick(KEYS).to_string(), v);
            }
        }
        3 if !keys.is_empty() => {
            // Copy a value under another name (e.g. a second material table).
            let k = d.pick(&keys);
            if let Some(v) = table.get(k).cloned() {
                table.insert(d.pick(KEYS).to_string(), v);
            }
        }
        _ => {
            table.insert(d.pick(KEYS).to_string(), value(d));
        }
    }
}

fn mutate_value(v: &mut Value, d: &mut Dice) {
    if let Value::Array(a) = v {
        let n = a.len();
        match d.below(5) {
            0 if n > 0 => {
                a.remove(d.below(n));
                return;
            }
            1 if n > 0 => {
                let e = a[d.below(n)].clone();
                a.push(e);
                return;
            }
            2 if n > 0 => {
                let i = d.below(n);
                a[i] = value(d);
                return;
            }
            _ => {}
        }
    }
    *v = value(d);
}

impl Target for ConfigTarget {
    fn name(&self) -> &'static str {
        "config"
    }

    fn seeds(&mut self) -> anyhow::Result<Vec<Vec<u8>>> {
        let folder = self.dir.path();
        for (scene, file) in SCENE_FILES {
            let to = folder.join(file);
            std::fs::copy(self.scenes.join(scene).join(file), &to)?;
            self.loadable.push(to);
        }
        let sky = folder.join("sky.exr");
        let texels: Vec<[f32; 3]> = (0..8).map(|i| [i as f32 * 0.25, 1.0, 0.5]).collect();
        prt_formats::write_exr(&sky, 4, 2, &texels)?;
        self.loadable.push(sky);
        let mut seeds = Vec::new();
        for scene in ["cornell", "ring", "furnace"] {
            seeds.push(std::fs::read(self.scenes.join(scene).join("bake.toml"))?);
        }
        seeds.extend(EXTRA_SEEDS.iter().map(|s| s.as_bytes().to_vec()));
        seeds.extend(crate::targets::read_corpus_files(&self.extra)?);
        Ok(seeds)
    }

    fn mutate(&mut self, parent: &[u8], other: &[u8], d: &mut Dice) -> Vec<u8> {
        let mut child = parent.to_vec();
        match d.below(10) {
            0..=3 => {
                if let Some(c) = self.mutate_tree(parent, d) {
                    return c;
                }
                replace_number(&mut child, d);
            }
            4 | 5 => replace_number(&mut child, d),
            6 | 7 => line_op(&mut child, other, d),
            _ => havoc(&mut child, other, d, MAX_LEN),
        }
        child.truncate(MAX_LEN);
        child
    }

    fn run(&mut self, input: &[u8]) -> Result<String, String> {
        let dir = self.dir.path();
        let text = String::from_utf8_lossy(input);
        let config = match BakeConfig::parse(&text, &self.config_path) {
            Ok(c) => c,
            Err(e) => return Ok(outcome("parse", &e.to_string(), dir)),
        };
        // The printed config must read back as the same config (docs/config.md).
        let printed = config.to_toml();
        match BakeConfig::parse(&printed, &self.config_path) {
            Ok(back) if back == config => {}
            Ok(back) => {
                return Err(format!(
                    "to_toml does not round-trip: {config:?} printed as\n{printed}\nreads back \
                     as {back:?}"
                ))
            }
            Err(e) => {
                return Err(format!(
                    "to_toml printed a config that does not parse ({e}):\n{printed}"
                ))
            }
        }
        if !self.loadable.contains(&config.scene_path) {
            return Ok("ok: parsed; the scene is not an example scene".into());
        }
        if let EnvironmentConfig::Map { path, .. } = &config.environment {
            if !self.loadable.contains(path) {
                return Ok("ok: parsed; the environment map is not the seed map".into());
            }
        }
        match prt_bake::run::load_scene(&config, &Silent) {
            Ok(scene) => Ok(format!(
                "ok: loaded, {} materials, {} editable",
                scene.materials.len(),
                scene.materials.iter().filter(|m| m.editable).count()
            )),
            Err(e) => Ok(outcome("load", &e.to_string(), dir)),
        }
    }
}
