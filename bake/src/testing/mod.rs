//! Scene construction in code, for tests, benchmarks and analytic checks (no glTF needed),
//! and generated glTF scenes (`gltf_writer.rs`, `yard.rs`) that go through the user's loader.

mod gltf_writer;
mod yard;

pub use gltf_writer::{GltfMaterial, GltfMesh, GltfWriter};
pub use yard::Yard;

use glam::{DVec3, Vec2, Vec3};

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
                environment_rotation: 0.0,
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
            normal_texture: None,
            metallic_roughness: None,
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

impl SceneBuilder {
    /// A flat-shaded sphere: every icosphere triangle gets its own three vertices carrying its
    /// face normal, so shading and geometric normals agree everywhere. (With smooth normals a
    /// thin wedge of directions lies above the shading horizon but below the facet; the
    /// integrator drops paths there, a bias of order (normal tilt)^2 that closed forms for a
    /// true sphere do not have.) `inward` turns the sphere inside out (front faces and normals
    /// towards the centre, for scenes seen from inside); `material` picks each triangle's
    /// material from its centroid on the unit sphere.
    pub fn flat_sphere(
        &mut self,
        center: Vec3,
        radius: f32,
        subdivisions: u32,
        inward: bool,
        material: impl Fn(Vec3) -> u32,
    ) {
        let (p, t) = icosphere(subdivisions);
        for [a, b, c] in t {
            let [a, b, c] = if inward { [a, c, b] } else { [a, b, c] }.map(|i| p[i as usize]);
            let n = (b - a).cross(c - a).normalize();
            let corners = [a, b, c].map(|v| center + v * radius);
            self.mesh(&corners, &[n; 3], &[[0, 1, 2]], material((a + b + c) / 3.0));
        }
    }
}

/// Inside a closed sphere of radius 1 (flat-shaded, 5120 facets) whose whole inner surface is
/// Lambert and emits `emission`: the upper half (facets with centroid y > 0) is material
/// `upper` with albedo `upper_kd`, the lower half `lower` with `lower_kd`; both are `editable`
/// or both fixed. No environment. The camera sits at the centre looking along -Z with a 90°
/// field of view, the upper half in the top of the picture.
///
/// With one albedo `a` everywhere, radiance is `emission (1 + a + ... + a^N)` at every point
/// for N reflections, for any closed enclosure (every direction from a point sees emitting
/// surface of the same radiance). With two albedos the integrating-sphere result (the form
/// factor from any point of a sphere's interior to a patch is the patch's area over the
/// sphere's) gives, for a true sphere, `emission (1 + a_half (1 + m + ... + m^(N-1)))` with m
/// the area-weighted mean albedo; the polyhedron follows it up to its flatness.
pub fn inside_sphere_scene(
    upper_kd: Vec3,
    lower_kd: Vec3,
    emission: Vec3,
    editable: bool,
) -> Scene {
    let mut b = SceneBuilder::new();
    let up = b.material("upper", BrdfParams::diffuse(upper_kd), emission, editable);
    let low = b.material("lower", BrdfParams::diffuse(lower_kd), emission, editable);
    // The icosphere is symmetric about y = 0 and about x = 0, and mirror images are computed
    // exactly, so the halves have equal areas when the facets centred on y = 0 (mapped to
    // themselves by the mirror) are split by the sign of x.
    b.flat_sphere(Vec3::ZERO, 1.0, 5, true, |c| {
        if c.y > 0.0 || (c.y == 0.0 && c.x > 0.0) {
            up
        } else {
            low
        }
    });
    b.camera(look_at(
        Vec3::ZERO,
        Vec3::NEG_Z,
        Vec3::Y,
        90f32.to_radians(),
    ));
    b.build()
}

/// A flat-shaded convex sphere of radius 1 (5120 facets) of material `sphere` with `brdf`,
/// under a constant environment `env`, seen by a camera on +Z. With one reflection (and any
/// number: a convex object never sees itself) every camera sample that hits it has radiance
/// `env` times the BRDF's directional albedo for the view direction in its facet's frame.
pub fn convex_furnace_scene(brdf: BrdfParams, editable: bool, env: Vec3) -> Scene {
    let mut b = SceneBuilder::new();
    let m = b.material("sphere", brdf, Vec3::ZERO, editable);
    b.flat_sphere(Vec3::ZERO, 1.0, 4, false, |_| m);
    b.environment(Environment::Constant(env));
    b.camera(look_at(
        Vec3::new(0.0, 0.0, 4.0),
        Vec3::ZERO,
        Vec3::Y,
        35f32.to_radians(),
    ));
    b.build()
}

/// One camera sample of a render or bake, replayed.
#[derive(Clone, Copy, Debug)]
pub struct CameraSample {
    /// Pixel index (row-major, top row first).
    pub pixel: u32,
    /// Sample index within the pixel.
    pub sample: u32,
    /// The primary ray's direction (it starts at the camera).
    pub dir: Vec3,
    /// What the primary ray hits (shading normal facing the camera), if anything.
    pub hit: Option<crate::integrator::Surface>,
    /// The reference tracer's radiance for this sample (true BRDFs), or zero when not traced.
    pub radiance: Vec3,
}

/// Replays the camera samples of a `width` x `height` render or bake with `spp` samples per
/// pixel and streams keyed by `seed`: sample s of pixel p uses the stream
/// sample s of a `PixelSampler` started at (seed, p), and its first draw is the film jitter (the
/// integrator's fixed drawing order), so the primary ray of every sample is known exactly and
/// a closed form can be evaluated for it. With `trace`, each sample is also traced with the
/// true BRDFs and `reflections` reflections, exactly as [`crate::reference::render`] does
/// (the mean of a pixel's radiances is its rendered value). Ordered by pixel, then sample.
pub fn camera_samples(
    scene: &Scene,
    reflections: usize,
    (width, height): (u32, u32),
    spp: u32,
    seed: u64,
    trace: bool,
) -> Vec<CameraSample> {
    use crate::integrator::Integrator;
    use crate::reference::{unit_coefficients, ContractSink, TrueBrdfModel};
    use crate::sampling::PixelSampler;
    use rayon::prelude::*;

    let accel = crate::accel::Accel::build(scene);
    let lights = crate::lights::LightSet::new(scene);
    let integ = Integrator::new(scene, &accel, &lights, reflections, width, height);
    let model = TrueBrdfModel::new(scene);
    let coefficients = unit_coefficients(scene.materials.len());
    (0..height)
        .into_par_iter()
        .flat_map_iter(|y| {
            let mut row = Vec::with_capacity((width * spp) as usize);
            // One per row: it keeps the shuffle tables' memory between pixels.
            let mut sampler = PixelSampler::new(spp, integ.draws_per_sample());
            for x in 0..width {
                let pixel = y * width + x;
                sampler.start(seed, pixel as u64);
                for s in 0..spp {
                    let mut rng = sampler.sample(s);
                    let jitter = rng.clone().next_vec2();
                    let (origin, dir) = integ.camera_ray(x as f32 + jitter.x, y as f32 + jitter.y);
                    let hit = accel
                        .intersect(origin, dir, 0.0, f32::INFINITY)
                        .map(|h| integ.surface(&h, dir));
                    let radiance = if trace {
                        let mut sink = ContractSink::new(&coefficients);
                        integ.trace_sample(&model, &mut sink, x, y, &mut rng);
                        sink.value()
                    } else {
                        Vec3::ZERO
                    };
                    row.push(CameraSample {
                        pixel,
                        sample: s,
                        dir,
                        hit,
                        radiance,
                    });
                }
            }
            row
        })
        .collect()
}

/// Directional albedos `a(wo) = ∫ f(wo, wi) cos_i dwi` of the specular lobes (Ks = 1, Kd = 0)
/// by deterministic quadrature in f64, written from the formulas of docs/brdf.md and
/// independent of `crate::brdf`: tests check the code's evaluation, sampling and renders
/// against them.
///
/// All integrate over the half vector h, `a = ∫∫ f(wo, wi) cos_i 4 (wo.h) sin(theta_h)
/// dtheta_h dphi_h` (`dwi = 4 (wo.h) dh`, wi the mirror of wo about h), with a midpoint rule in
/// phi over [0, pi] (the integrand is symmetric about the plane of wo and the normal) and in x
/// over [0, 1] where `tan(theta_h) = w tan(pi x / 2)`, w the lobe's width: the peak (theta_h
/// up to a few w) and the tail out to the horizon both get a share of the nodes. The integrand
/// is continuous (it vanishes linearly where wi or wo.h reaches the horizon), so the rule
/// converges quadratically (measured: about 1e-5 at n = 512 for alpha >= 0.05 and theta_o <=
/// 85 degrees); `bake/tests/suite/brdf.rs` checks it against the closed forms at alpha = 1 and
/// at normal incidence.
pub mod albedo {
    use glam::DVec3;
    use std::f64::consts::PI;

    /// `∫ f(wo, wi) cos_i dwi` over the upper hemisphere for `wo = (sin, 0, cos_o)`, on `n` x
    /// `n` half-vector nodes; `width` is the width of the lobe in tan(theta_h) (the nodes
    /// crowd within it). `f` gets local unit vectors (normal +Z) with both cosines positive.
    /// The integrand must be symmetric about the plane of wo and the normal (isotropic BRDFs).
    pub fn hemisphere(width: f64, cos_o: f64, n: usize, f: impl Fn(DVec3, DVec3) -> f64) -> f64 {
        hemisphere_many(width, cos_o, n, 1, |wo, wi, out| out[0] = f(wo, wi))[0]
    }

    /// [`hemisphere`] for `k` functions at once: `f` writes their values into its slice.
    pub fn hemisphere_many(
        width: f64,
        cos_o: f64,
        n: usize,
        k: usize,
        f: impl Fn(DVec3, DVec3, &mut [f64]),
    ) -> Vec<f64> {
        let wo = DVec3::new((1.0 - cos_o * cos_o).max(0.0).sqrt(), 0.0, cos_o);
        let mut sum = vec![0.0; k];
        let mut row = vec![0.0; k];
        let mut values = vec![0.0; k];
        for i in 0..n {
            let x = (i as f64 + 0.5) / n as f64;
            let t = (0.5 * PI * x).tan();
            let theta = (width * t).atan();
            // dtheta/dx for tan(theta) = w tan(pi x / 2)
            let jac = width * 0.5 * PI * (1.0 + t * t) / (1.0 + width * width * t * t);
            let (sh, ch) = theta.sin_cos();
            row.fill(0.0);
            for j in 0..n {
                let phi = PI * (j as f64 + 0.5) / n as f64;
                let h = DVec3::new(sh * phi.cos(), sh * phi.sin(), ch);
                let oh = wo.dot(h);
                let wi = 2.0 * oh * h - wo;
                if oh <= 0.0 || wi.z <= 0.0 {
                    continue;
                }
                f(wo, wi, &mut values);
                // dwi = 4 (wo.h) dh
                for (r, v) in row.iter_mut().zip(&values) {
                    *r += v * wi.z * 4.0 * oh;
                }
            }
            for (s, r) in sum.iter_mut().zip(&row) {
                *s += r * sh * jac;
            }
        }
        // dx = 1/n; phi over [0, pi] with n nodes, doubled for [0, 2 pi].
        sum.iter().map(|s| s * 2.0 * PI / (n * n) as f64).collect()
    }

    /// GGX with separable Smith masking and F = 1, roughness `alpha`, at `cos_o =
    /// cos(theta_o)`: `f = D(h) G1(wi) G1(wo) / (4 cos_i cos_o)`, on `n` x `n` nodes.
    pub fn ggx(alpha: f64, cos_o: f64, n: usize) -> f64 {
        let a2 = alpha * alpha;
        let d = |c: f64| a2 / (PI * (a2 * c * c + 1.0 - c * c).powi(2));
        let g1 = |c: f64| 2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt());
        hemisphere(alpha, cos_o, n, |wo, wi| {
            let h = (wo + wi).normalize();
            d(h.z) * g1(wi.z) * g1(wo.z) / (4.0 * wi.z * wo.z)
        })
    }

    /// Blinn-Phong `f = (s + 2) / (2 pi) cos^s(theta_h)` at `cos_o`, on `n` x `n` nodes.
    pub fn blinn_phong(s: f64, cos_o: f64, n: usize) -> f64 {
        // The lobe falls to 1/e at tan(theta_h) ~ sqrt(2 / s).
        let width = (2.0 / (s + 2.0)).sqrt();
        hemisphere(width, cos_o, n, |wo, wi| {
            (s + 2.0) / (2.0 * PI) * (wo + wi).normalize().z.powf(s)
        })
    }

    /// A directional albedo tabulated over theta_o in [0, 90] degrees and interpolated
    /// linearly, for closed forms evaluated at many view directions.
    #[derive(Clone, Debug)]
    pub struct Table {
        values: Vec<f64>,
    }

    impl Table {
        /// `albedo(cos_o)` at `nodes` angles evenly spaced in theta_o (nodes >= 2).
        pub fn new(nodes: usize, albedo: impl Fn(f64) -> f64) -> Table {
            let nodes = nodes.max(2);
            let values = (0..nodes)
                .map(|k| albedo((0.5 * PI * k as f64 / (nodes - 1) as f64).cos()))
                .collect();
            Table { values }
        }

        /// The albedo at `cos_o` (clamped to [0, 1]).
        pub fn at(&self, cos_o: f64) -> f64 {
            let n = self.values.len() - 1;
            let x = cos_o.clamp(0.0, 1.0).acos() / (0.5 * PI) * n as f64;
            let k = (x.floor() as usize).min(n - 1);
            let f = x - k as f64;
            self.values[k] * (1.0 - f) + self.values[k + 1] * f
        }
    }
}

/// Radiance on a half of albedo `a_half` inside the closed sphere of [`inside_sphere_scene`],
/// with `m` the mean albedo of the two halves, emission `le` and `n` reflections:
/// `le (1 + a_half (1 + m + ... + m^(n-1)))`. Integrating sphere: the radiance arriving at any
/// point is the area-weighted mean of the radiance leaving the sphere, so after the first
/// reflection each bounce multiplies by the mean albedo. With one albedo this is
/// `le (1 + a + ... + a^n)`, exact for any closed enclosure.
pub fn closed_sphere_radiance(le: Vec3, a_half: Vec3, m: Vec3, n: usize) -> DVec3 {
    let (mut series, mut power) = (DVec3::ZERO, DVec3::ONE);
    for _ in 0..n {
        series += power;
        power *= m.as_dvec3();
    }
    le.as_dvec3() * (DVec3::ONE + a_half.as_dvec3() * series)
}

/// Relative allowance, on the reflected part `L - Le`, for the polyhedron's deviation from a
/// sphere when the two halves of [`inside_sphere_scene`] differ. Measured with 131 000 samples
/// per half and N = 1..4: within 7e-4 and 1.3 standard errors, i.e. not resolved.
pub const SPLIT_GEOMETRY: f64 = 1e-3;
