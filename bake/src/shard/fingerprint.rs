//! What a bake's traced data depends on, recorded in its checkpoint and in every shard file so
//! that a resume or a merge with anything changed is refused, naming what changed: the
//! program, every option that reaches the traced data, and hashes of the scene as loaded.
//! Hashing the loaded scene rather than its files covers the config's material edits and the
//! environment's intensity and rotation, and ignores what does not reach the bake (comments,
//! the output path). Each mode builds its entries (`vertex::vertex_fingerprint`,
//! `pixel::pixel_fingerprint`); [`scene_entries`] are the scene's, shared by both.

use crate::scene::{Environment, Scene};

/// Prefix of a hashed entry's value (a literal entry's value is the setting itself).
const HASH_PREFIX: &str = "fnv64:";

/// Named entries, in a fixed order: literal settings (`seed = 3`) and hashes of bulk inputs.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Fingerprint {
    entries: Vec<(String, String)>,
}

impl Fingerprint {
    /// An empty fingerprint, to add entries to.
    pub fn new() -> Fingerprint {
        Fingerprint {
            entries: Vec::new(),
        }
    }

    /// Adds a literal entry (`seed = 3`): a difference names both values.
    pub fn literal(&mut self, name: &str, value: impl ToString) {
        self.entries.push((name.to_string(), value.to_string()));
    }

    /// Adds the hash of bulk input fed to `feed`: a difference names the entry only.
    pub fn hashed(&mut self, name: &str, feed: impl FnOnce(&mut Fnv)) {
        let mut h = Fnv::new();
        feed(&mut h);
        self.entries
            .push((name.to_string(), format!("{HASH_PREFIX}{:016x}", h.0)));
    }

    /// The value of entry `name`.
    pub fn get(&self, name: &str) -> Option<&str> {
        self.entries
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// What differs between `self` (this run) and `saved` (a checkpoint's or another shard's),
    /// one phrase per entry: `seed (3 in the checkpoint, 4 now)`, `materials`; `then` names
    /// the other side ("in the checkpoint", "in shard 0"). Empty when they agree.
    pub fn differences_from(&self, saved: &Fingerprint, then: &str) -> Vec<String> {
        let mut out = Vec::new();
        for (name, now) in &self.entries {
            match saved.entries.iter().find(|(n, _)| n == name) {
                Some((_, was)) if was == now => {}
                Some((_, was)) if !now.starts_with(HASH_PREFIX) => {
                    out.push(format!("{name} ({was} {then}, {now} now)"))
                }
                _ => out.push(name.clone()),
            }
        }
        for (name, _) in &saved.entries {
            if !self.entries.iter().any(|(n, _)| n == name) {
                out.push(name.clone());
            }
        }
        out
    }

    /// [`Fingerprint::differences_from`] a checkpoint's.
    pub fn differences(&self, saved: &Fingerprint) -> Vec<String> {
        self.differences_from(saved, "in the checkpoint")
    }
}

impl Default for Fingerprint {
    fn default() -> Self {
        Self::new()
    }
}

/// The scene's entries: mesh (positions, `normals` as the bake uses them, UVs, triangles and
/// their materials), materials (with `extra`: the mode's slot plan and basis sizes), textures,
/// environment (with its intensity baked in and its rotation), camera, lights.
pub fn scene_entries(fp: &mut Fingerprint, scene: &Scene, normals: &[glam::Vec3], extra: &str) {
    fp.hashed("mesh", |h| {
        for p in &scene.positions {
            h.f32s(&p.to_array());
        }
        for n in normals {
            h.f32s(&n.to_array());
        }
        for uv in &scene.uvs {
            h.f32s(&uv.to_array());
        }
        for t in &scene.triangles {
            h.u32s(t);
        }
        h.u32s(&scene.triangle_material);
    });
    // Debug output of floats is their shortest round-trip form: it tells every bit apart.
    fp.hashed("materials", |h| {
        h.str(&format!("{:?} {extra}", scene.materials))
    });
    fp.hashed("textures", |h| {
        for t in &scene.textures {
            h.str(&t.name);
            h.u32s(&[t.width, t.height]);
            for c in &t.texels {
                h.f32s(&c.to_array());
            }
        }
    });
    fp.hashed("environment", |h| {
        h.f32s(&[scene.environment_rotation]);
        match &scene.environment {
            Environment::Constant(c) => h.f32s(&c.to_array()),
            Environment::LatLong {
                width,
                height,
                texels,
            } => {
                h.u32s(&[*width, *height]);
                for c in texels {
                    h.f32s(&c.to_array());
                }
            }
        }
    });
    fp.hashed("camera", |h| h.str(&format!("{:?}", scene.camera)));
    fp.hashed("lights", |h| h.str(&format!("{:?}", scene.lights)));
}

/// 64-bit FNV-1a: small, stable across platforms and releases (unlike std's hasher), and fast
/// enough for a scene's arrays; it guards against accidents, not adversaries.
pub struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }

    pub fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    pub fn str(&mut self, s: &str) {
        self.bytes(&(s.len() as u64).to_le_bytes());
        self.bytes(s.as_bytes());
    }

    pub fn f32s(&mut self, values: &[f32]) {
        for v in values {
            self.bytes(&v.to_bits().to_le_bytes());
        }
    }

    pub fn u32s(&mut self, values: &[u32]) {
        for v in values {
            self.bytes(&v.to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Fingerprint;

    fn fp(entries: &[(&str, &str)]) -> Fingerprint {
        let mut f = Fingerprint::new();
        for (a, b) in entries {
            f.literal(a, b);
        }
        f
    }

    #[test]
    fn differences_name_each_changed_entry_with_literal_values() {
        let mut saved = fp(&[("seed", "3"), ("spp", "4")]);
        saved.hashed("mesh", |h| h.str("a"));
        assert!(saved.differences(&saved).is_empty());
        let mut now = fp(&[("seed", "4"), ("spp", "4")]);
        now.hashed("mesh", |h| h.str("b"));
        assert_eq!(
            now.differences(&saved),
            ["seed (3 in the checkpoint, 4 now)", "mesh"]
        );
        assert_eq!(
            now.differences_from(&saved, "in shard 0"),
            ["seed (3 in shard 0, 4 now)", "mesh"]
        );
        // An entry only one side has (another program version's) counts as a difference.
        let mut older = fp(&[("seed", "3"), ("spp", "4"), ("gone", "x")]);
        older.hashed("mesh", |h| h.str("a"));
        assert_eq!(older.differences(&saved), ["gone"]);
        assert_eq!(saved.differences(&older), ["gone"]);
        assert_eq!(saved.get("seed"), Some("3"));
    }
}
