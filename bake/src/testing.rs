//! Scene construction in code, for tests, benchmarks and analytic checks (no glTF needed).

use glam::{Vec2, Vec3};

use crate::brdf::BrdfParams;
use crate::scene::{Camera, Environment, Material, PunctualLight, Scene};

/// Builds a [`Scene`] mesh by mesh.
pub struct SceneBuilder {
    scene: Scene,
}

impl Default for SceneBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl SceneBuilder {
    pub fn new() -> Self {
        SceneBuilder {
            scene: Scene {
                positions: Vec::new(),
                normals: Vec::new(),
                uvs: Vec::new(),
                triangles: Vec::new(),
                triangle_material: Vec::new(),
                materials: Vec::new(),
                textures: Vec::new(),
                lights: Vec::new(),
                camera: look_at(
                    Vec3::new(0.0, 0.0, 3.0),
                    Vec3::ZERO,
                    Vec3::Y,
                    45f32.to_radians(),
                ),
                environment: Environment::Constant(Vec3::ZERO),
                skipped_triangles: 0,
            },
        }
    }

    /// Adds a material; returns its index.
    pub fn material(
        &mut self,
        name: &str,
        brdf: BrdfParams,
        emission: Vec3,
        editable: bool,
    ) -> u32 {
        self.scene.materials.push(Material {
            name: name.to_string(),
            brdf,
            base_color_texture: None,
            emission,
            emissive_texture: None,
            editable,
        });
        (self.scene.materials.len() - 1) as u32
    }

    /// Adds a mesh with per-vertex normals (zero UVs).
    pub fn mesh(
        &mut self,
        positions: &[Vec3],
        normals: &[Vec3],
        triangles: &[[u32; 3]],
        material: u32,
    ) {
        let base = self.scene.positions.len() as u32;
        self.scene.positions.extend_from_slice(positions);
        self.scene.normals.extend_from_slice(normals);
        self.scene
            .uvs
            .extend(std::iter::repeat_n(Vec2::ZERO, positions.len()));
        for t in triangles {
            self.scene.triangles.push(t.map(|i| i + base));
            self.scene.triangle_material.push(material);
        }
    }

    /// A planar quad with corners in order (counter-clockwise seen from the side its normal
    /// `n` points to).
    pub fn quad(&mut self, corners: [Vec3; 4], material: u32) {
        let n = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .normalize();
        self.mesh(&corners, &[n; 4], &[[0, 1, 2], [0, 2, 3]], material);
    }

    /// A sphere (subdivided icosahedron, smooth normals).
    pub fn sphere(&mut self, center: Vec3, radius: f32, subdivisions: u32, material: u32) {
        let (p, t) = icosphere(subdivisions);
        let pos: Vec<Vec3> = p.iter().map(|&v| center + v * radius).collect();
        self.mesh(&pos, &p, &t, material);
    }

    pub fn light(&mut self, light: PunctualLight) {
        self.scene.lights.push(light);
    }

    pub fn camera(&mut self, camera: Camera) {
        self.scene.camera = camera;
    }

    pub fn environment(&mut self, env: Environment) {
        self.scene.environment = env;
    }

    pub fn build(self) -> Scene {
        self.scene
    }
}

/// A camera at `eye` looking at `target`.
pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, yfov: f32) -> Camera {
    let forward = (target - eye).normalize();
    let right = forward.cross(up).normalize();
    let up = right.cross(forward);
    Camera {
        position: eye,
        forward,
        up,
        right,
        yfov,
    }
}

/// Unit icosphere: vertices (also its normals) and triangles (outward, counter-clockwise).
pub fn icosphere(subdivisions: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut verts: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut cache = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, verts: &mut Vec<Vec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *cache.entry(key).or_insert_with(|| {
                verts.push(((verts[a as usize] + verts[b as usize]) * 0.5).normalize());
                (verts.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let ab = mid(a, b, &mut verts);
            let bc = mid(b, c, &mut verts);
            let ca = mid(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    (verts, tris)
}

/// The furnace test scene: a Lambert sphere of albedo `albedo` in a constant environment of
/// radiance `env`, seen by a camera on +Z.
pub fn furnace_scene(albedo: Vec3, env: Vec3) -> Scene {
    let mut b = SceneBuilder::new();
    let m = b.material("sphere", BrdfParams::diffuse(albedo), Vec3::ZERO, false);
    b.sphere(Vec3::ZERO, 1.0, 5, m);
    b.environment(Environment::Constant(env));
    b.camera(look_at(
        Vec3::new(0.0, 0.0, 4.0),
        Vec3::ZERO,
        Vec3::Y,
        35f32.to_radians(),
    ));
    b.build()
}
