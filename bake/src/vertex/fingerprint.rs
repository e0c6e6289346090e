//! What a per-vertex bake's traced data depends on, recorded in its checkpoint so that a resume
//! with anything changed is refused, naming what changed: the program, every option, and
//! hashes of the scene as loaded (mesh, materials, textures, environment, camera) and of the
//! plan (groups and the pre-pass's active slots). Hashing the loaded scene rather than its
//! files covers the config's material edits and the environment's intensity and rotation, and
//! ignores what does not reach the bake (comments, the output path).

use prt_formats::vertex::VERTEX_SCHEMA_VERSION;

use crate::scene::{Environment, Scene};

use super::plan::VertexPlan;
use super::VertexBakeOptions;

/// Prefix of a hashed entry's value (a literal entry's value is the setting itself).
const HASH_PREFIX: &str = "fnv64:";

/// Named entries, in a fixed order: literal settings (`seed = 3`) and hashes of bulk inputs.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Fingerprint {
    entries: Vec<(String, String)>,
}

impl Fingerprint {
    /// The fingerprint of baking `plan` (made from `scene`) with `opts`.
    pub fn new(scene: &Scene, plan: &VertexPlan, opts: &VertexBakeOptions) -> Fingerprint {
        let mut entries = Vec::new();
        let mut literal = |name: &str, value: String| entries.push((name.to_string(), value));
        literal(
            "program",
            format!(
                "prt-bake {} (vertex schema {VERTEX_SCHEMA_VERSION})",
                env!("CARGO_PKG_VERSION")
            ),
        );
        literal("spp", opts.samples.to_string());
        literal("vertex.secondary", opts.secondary.to_string());
        literal("reflections", opts.reflections.to_string());
        literal("seed", opts.seed.to_string());
        literal("vertex.t0_terms", opts.t0_terms.to_string());
        literal("precision", opts.precision.name().to_string());
        literal("vertex.light_bins", opts.light_bins.to_string());

        let mut mesh = Fnv::new();
        for p in &scene.positions {
            mesh.f32s(&p.to_array());
        }
        for n in &plan.normals {
            mesh.f32s(&n.to_array());
        }
        for uv in &scene.uvs {
            mesh.f32s(&uv.to_array());
        }
        for t in &scene.triangles {
            mesh.u32s(t);
        }
        mesh.u32s(&scene.triangle_material);

        // Debug output of floats is their shortest round-trip form: it tells every bit apart.
        let mut materials = Fnv::new();
        materials.str(&format!(
            "{:?} {:?} {:?}",
            scene.materials, plan.slots.materials, plan.slots.basis_families
        ));

        let mut textures = Fnv::new();
        for t in &scene.textures {
            textures.str(&t.name);
            textures.u32s(&[t.width, t.height]);
            for c in &t.texels {
                textures.f32s(&c.to_array());
            }
        }

        let mut environment = Fnv::new();
        environment.f32s(&[scene.environment_rotation]);
        match &scene.environment {
            Environment::Constant(c) => environment.f32s(&c.to_array()),
            Environment::LatLong {
                width,
                height,
                texels,
            } => {
                environment.u32s(&[*width, *height]);
                for c in texels {
                    environment.f32s(&c.to_array());
                }
            }
        }

        let mut camera = Fnv::new();
        camera.str(&format!("{:?}", scene.camera));

        let mut groups = Fnv::new();
        groups.str(&format!("{:?}", plan.groups));

        for (name, h) in [
            ("mesh", mesh),
            ("materials", materials),
            ("textures", textures),
            ("environment", environment),
            ("camera", camera),
            ("groups and active slots", groups),
        ] {
            entries.push((name.to_string(), format!("{HASH_PREFIX}{:016x}", h.0)));
        }
        Fingerprint { entries }
    }

    /// What differs between `self` (this run) and `saved` (a checkpoint's), one phrase per
    /// entry: `seed (3 in the checkpoint, 4 now)`, `materials`. Empty when they agree.
    pub fn differences(&self, saved: &Fingerprint) -> Vec<String> {
        let mut out = Vec::new();
        for (name, now) in &self.entries {
            match saved.entries.iter().find(|(n, _)| n == name) {
                Some((_, then)) if then == now => {}
                Some((_, then)) if !now.starts_with(HASH_PREFIX) => {
                    out.push(format!("{name} ({then} in the checkpoint, {now} now)"))
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
}

/// 64-bit FNV-1a: small, stable across platforms and releases (unlike std's hasher), and fast
/// enough for a scene's arrays; it guards against accidents, not adversaries.
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }

    fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn str(&mut self, s: &str) {
        self.bytes(&(s.len() as u64).to_le_bytes());
        self.bytes(s.as_bytes());
    }

    fn f32s(&mut self, values: &[f32]) {
        for v in values {
            self.bytes(&v.to_bits().to_le_bytes());
        }
    }

    fn u32s(&mut self, values: &[u32]) {
        for v in values {
            self.bytes(&v.to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Fingerprint;

    fn fp(entries: &[(&str, &str)]) -> Fingerprint {
        Fingerprint {
            entries: entries
                .iter()
                .map(|(a, b)| (a.to_string(), b.to_string()))
                .collect(),
        }
    }

    #[test]
    fn differences_name_each_changed_entry_with_literal_values() {
        let saved = fp(&[("seed", "3"), ("mesh", "fnv64:01"), ("spp", "4")]);
        assert!(saved.differences(&saved).is_empty());
        let now = fp(&[("seed", "4"), ("mesh", "fnv64:02"), ("spp", "4")]);
        assert_eq!(
            now.differences(&saved),
            ["seed (3 in the checkpoint, 4 now)", "mesh"]
        );
        // An entry only one side has (another program version's) counts as a difference.
        let older = fp(&[("seed", "3"), ("spp", "4"), ("gone", "x")]);
        assert_eq!(older.differences(&saved), ["gone", "mesh"]);
    }
}
