//! The path integrator shared by the reference tracer and the bakers.
//!
//! A path from the camera reflects at vertices x_0 .. x_k and ends on a light. Its contribution
//! factors into (a) a *weight* that depends only on geometry, lights, sampling densities and
//! MIS, and (b) one *slot vector* per vertex: the values of the BRDF functions that a material
//! is expressed in (one slot holding the true BRDF for a fixed material; one slot per basis
//! BRDF for an editable one). A [`MaterialModel`] says how vertices are evaluated and sampled,
//! and a [`PathSink`] decides what to do with each finished path: the reference tracer
//! contracts the slots with coefficients into a colour, the baker accumulates their products
//! into transfer tensors. Because the sampling never depends on the coefficients, both see the
//! very same paths from the same random streams: relighting with coefficients c equals the
//! reference render with the projected BRDFs, to float rounding (docs/pixel.md, "Exactness").
//!
//! Numbers are drawn from a [`PathSampler`] in a fixed order whatever happens (a 2D draw for
//! the camera jitter; per vertex a 1D and a 2D draw for the area light, a 2D draw for the
//! environment, a 1D and a 2D draw for the continuation), so draw d of every sample of a pixel
//! estimates the same dimension of the path integral (which is what lets the sampler stratify
//! it) and the draws of two runs stay aligned.

use glam::{Vec2, Vec3};

use crate::accel::{Accel, Hit};
use crate::brdf::BrdfSample;
use crate::lights::{orthonormal_basis, LightSet};
use crate::sampling::{Draw, PathSampler};
use crate::scene::Scene;

/// Most slots a material may have at one vertex.
pub const MAX_SLOTS: usize = 16;
pub use crate::sampling::MAX_REFLECTIONS;

/// A shading point: hit position, normals facing the side the ray came from, frame, UV.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    pub p: Vec3,
    /// Geometric normal, on the side of the incoming ray.
    pub ng: Vec3,
    /// Shading normal (interpolated), on the same side as `ng`.
    pub ns: Vec3,
    pub tangent: Vec3,
    pub bitangent: Vec3,
    pub uv: Vec2,
    pub material: u32,
    pub triangle: u32,
    pub bary: Vec2,
}

impl Surface {
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.tangent), v.dot(self.bitangent), v.dot(self.ns))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.tangent * v.x + self.bitangent * v.y + self.ns * v.z
    }
}

/// The BRDF function values of one vertex, one per slot of its material (RGB).
#[derive(Clone, Copy, Debug)]
pub struct Slots {
    pub material: u32,
    pub len: usize,
    pub values: [Vec3; MAX_SLOTS],
}

impl Slots {
    pub const EMPTY: Slots = Slots {
        material: 0,
        len: 0,
        values: [Vec3::ZERO; MAX_SLOTS],
    };

    pub fn as_slice(&self) -> &[Vec3] {
        &self.values[..self.len]
    }
}

/// How vertices are evaluated and sampled. Directions are local (normal = +Z).
pub trait MaterialModel: Sync {
    /// Fills `out` with the slot values of the vertex for directions (wo, wi). `depth` is the
    /// vertex index along the path (0 = the point the camera sees).
    fn eval(&self, surface: &Surface, depth: usize, wo: Vec3, wi: Vec3, out: &mut Slots);
    /// Samples a continuation direction. Must draw exactly one point, `rng.next_vec2()`
    /// (callers keep streams aligned by it).
    fn sample<D: Draw>(&self, surface: &Surface, wo: Vec3, rng: &mut D) -> Option<BrdfSample>;
    /// The density of `sample`.
    fn pdf(&self, surface: &Surface, wo: Vec3, wi: Vec3) -> f32;
}

/// Receives what one camera sample contributes.
pub trait PathSink {
    /// Radiance reaching the camera without any reflection (an emitter or the environment).
    fn camera_emission(&mut self, radiance: Vec3);
    /// The surface the camera sample sees (for coverage and per-pixel data).
    fn first_hit(&mut self, surface: &Surface);
    /// A path with `prefix.len() + 1` reflections: the vertices' slot values along it, and
    /// the weight every product of slot values is multiplied by.
    fn path(&mut self, prefix: &[Slots], last: &Slots, weight: Vec3);
}

/// Power heuristic (beta = 2) for two strategies.
#[inline]
fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a + b <= 0.0 || !(a + b).is_finite() {
        // Either density overflowed (a near-delta lobe): trust the larger one.
        return if pdf_a >= pdf_b { 1.0 } else { 0.0 };
    }
    a / (a + b)
}

/// Camera, geometry, lights and the reflection count: everything a path needs.
pub struct Integrator<'a> {
    pub scene: &'a Scene,
    pub accel: &'a Accel,
    pub lights: &'a LightSet,
    pub reflections: usize,
    pub width: u32,
    pub height: u32,
    /// Ray origin offset, scaled to the scene.
    eps: f32,
    tan_half_fov: f32,
    aspect: f32,
}

impl<'a> Integrator<'a> {
    pub fn new(
        scene: &'a Scene,
        accel: &'a Accel,
        lights: &'a LightSet,
        reflections: usize,
        width: u32,
        height: u32,
    ) -> Self {
        let extent = scene
            .positions
            .iter()
            .fold(0.0f32, |m, p| m.max(p.abs().max_element()));
        Integrator {
            scene,
            accel,
            lights,
            reflections: reflections.clamp(1, MAX_REFLECTIONS),
            width,
            height,
            eps: 1e-4 * extent.max(1e-3),
            tan_half_fov: (scene.camera.yfov * 0.5).tan(),
            aspect: width as f32 / height.max(1) as f32,
        }
    }

    /// The ray-origin offset along the normal, scaled to the scene (1e-4 of its extent): the
    /// per-vertex baker starts its rays with the same offset.
    #[inline]
    pub fn eps(&self) -> f32 {
        self.eps
    }

    /// The draws one camera sample makes from its [`PathSampler`]: the film jitter, and five
    /// per reflection (see the module comment).
    pub fn draws_per_sample(&self) -> usize {
        1 + 5 * self.reflections
    }

    /// Primary ray direction through film position (x, y) in pixels (y down).
    #[inline]
    pub fn camera_ray(&self, x: f32, y: f32) -> (Vec3, Vec3) {
        let cam = &self.scene.camera;
        let sx = (2.0 * x / self.width as f32 - 1.0) * self.tan_half_fov * self.aspect;
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.tan_half_fov;
        let dir = (cam.forward + cam.right * sx + cam.up * sy).normalize();
        (cam.position, dir)
    }

    /// The shading point of a hit by a ray travelling along `dir`.
    pub fn surface(&self, hit: &Hit, dir: Vec3) -> Surface {
        let scene = self.scene;
        let tri = scene.triangles[hit.triangle as usize];
        let [a, b, c] = tri.map(|v| scene.positions[v as usize]);
        let (u, v) = (hit.bary.x, hit.bary.y);
        let w = 1.0 - u - v;
        let p = a * w + b * u + c * v;
        let mut ng = (b - a).cross(c - a).normalize_or_zero();
        let [na, nb, nc] = tri.map(|i| scene.normals[i as usize]);
        let mut ns = (na * w + nb * u + nc * v).normalize_or_zero();
        if ns == Vec3::ZERO {
            ns = ng;
        }
        let [ua, ub, uc] = tri.map(|i| scene.uvs[i as usize]);
        let uv = ua * w + ub * u + uc * v;
        // The material's normal map bends the shading normal (before the sides are chosen:
        // the map is drawn on the surface's front).
        ns = scene.bent_normal(hit.triangle, uv, ns);
        // Two-sided surfaces: face the normals towards the incoming ray.
        if ng.dot(dir) > 0.0 {
            ng = -ng;
        }
        if ns.dot(ng) < 0.0 {
            ns = -ns;
        }
        let (tangent, bitangent) = orthonormal_basis(ns);
        Surface {
            p,
            ng,
            ns,
            tangent,
            bitangent,
            uv,
            material: scene.triangle_material[hit.triangle as usize],
            triangle: hit.triangle,
            bary: hit.bary,
        }
    }

    /// Emitted radiance at barycentrics `bary` of `triangle`. A light sample needs only this,
    /// not a whole [`Surface`] (normals, frame): building one per shadow ray cost about 5 % of
    /// a reference render.
    #[inline]
    fn emission_at(&self, triangle: u32, bary: Vec2) -> Vec3 {
        let scene = self.scene;
        let m = &scene.materials[scene.triangle_material[triangle as usize] as usize];
        if !m.is_emissive() {
            return Vec3::ZERO;
        }
        let tex = m
            .emissive_texture
            .and_then(|t| scene.textures.get(t))
            .map_or(Vec3::ONE, |t| {
                let tri = scene.triangles[triangle as usize];
                let [ua, ub, uc] = tri.map(|i| scene.uvs[i as usize]);
                t.sample(ua * (1.0 - bary.x - bary.y) + ub * bary.x + uc * bary.y)
            });
        m.emission * tex
    }

    /// Emitted radiance leaving surface `s` towards the ray that arrived along `dir`.
    #[inline]
    fn emission_towards(&self, s: &Surface, dir: Vec3) -> Vec3 {
        self.hit_emission(s.triangle, s.bary, dir)
            .map_or(Vec3::ZERO, |(le, _)| le)
    }

    /// Emitted radiance leaving `triangle` at `bary` towards the ray that arrived along
    /// `dir`, with the triangle's unit geometric normal (either side), or `None` where it
    /// emits nothing that way. Needs no shading point: the path's last hit is only looked at
    /// for what it emits, and building its [`Surface`] (normals, frame, uv) cost about 5 %
    /// of a reference render.
    #[inline]
    pub(crate) fn hit_emission(
        &self,
        triangle: u32,
        bary: Vec2,
        dir: Vec3,
    ) -> Option<(Vec3, Vec3)> {
        let le = self.emission_at(triangle, bary);
        if le == Vec3::ZERO {
            return None;
        }
        let tri = self.scene.triangles[triangle as usize];
        let [a, b, c] = tri.map(|v| self.scene.positions[v as usize]);
        let ng = (b - a).cross(c - a).normalize_or_zero();
        self.lights
            .emits_towards(self.scene, triangle, ng, bary, dir)
            .then_some((le, ng))
    }

    /// Traces one camera sample of pixel (px, py). Returns the number of rays cast.
    pub fn trace_sample<M: MaterialModel, S: PathSink>(
        &self,
        model: &M,
        sink: &mut S,
        px: u32,
        py: u32,
        rng: &mut PathSampler<'_>,
    ) -> u32 {
        let jitter = rng.next_vec2();
        let (origin, dir) = self.camera_ray(px as f32 + jitter.x, py as f32 + jitter.y);
        let mut rays = 1u32;
        let Some(hit) = self.accel.intersect(origin, dir, 0.0, f32::INFINITY) else {
            sink.camera_emission(self.lights.environment_radiance(dir));
            return rays;
        };
        let mut surf = self.surface(&hit, dir);
        let le = self.emission_towards(&surf, dir);
        if le != Vec3::ZERO {
            sink.camera_emission(le);
        }
        sink.first_hit(&surf);

        let mut prefix = [Slots::EMPTY; MAX_REFLECTIONS];
        let mut weight = Vec3::ONE;
        let mut dir = dir;
        let mut slots = Slots::EMPTY;
        for depth in 0..self.reflections {
            let wo_world = -dir;
            let wo = surf.to_local(wo_world);
            let origin = surf.p + surf.ng * self.eps;
            let u_area = rng.next_vec2();
            let u_env = rng.next_vec2();
            if wo.z <= 0.0 {
                // Seen from below its shading hemisphere (shading-normal artefact): black.
                break;
            }

            // Next-event estimation: area lights.
            if let Some((ls, tri, bary)) = self.lights.sample_area(self.scene, surf.p, u_area) {
                let wi = surf.to_local(ls.wi);
                if wi.z > 0.0 && ls.wi.dot(surf.ng) > 0.0 {
                    let le = self.emission_at(tri, bary);
                    rays += 1;
                    if le != Vec3::ZERO
                        && !self.accel.occluded(
                            origin,
                            ls.wi,
                            0.0,
                            ls.distance * (1.0 - 1e-4) - self.eps,
                        )
                    {
                        let pdf_b = model.pdf(&surf, wo, wi);
                        let mis = power_heuristic(ls.pdf, pdf_b);
                        model.eval(&surf, depth, wo, wi, &mut slots);
                        sink.path(
                            &prefix[..depth],
                            &slots,
                            weight * le * ls.value * (wi.z * mis),
                        );
                    }
                }
            }
            // Punctual lights: no MIS (delta distributions).
            for i in 0..self.lights.punctual.len() {
                let Some(ls) = self.lights.sample_punctual(i, surf.p) else {
                    continue;
                };
                let wi = surf.to_local(ls.wi);
                if wi.z <= 0.0 || ls.wi.dot(surf.ng) <= 0.0 {
                    continue;
                }
                rays += 1;
                let tmax = if ls.distance.is_finite() {
                    ls.distance * (1.0 - 1e-4) - self.eps
                } else {
                    f32::INFINITY
                };
                if self.accel.occluded(origin, ls.wi, 0.0, tmax) {
                    continue;
                }
                model.eval(&surf, depth, wo, wi, &mut slots);
                sink.path(&prefix[..depth], &slots, weight * ls.value * wi.z);
            }
            // Environment.
            if let Some(ls) = self.lights.sample_environment(surf.ns, u_env) {
                let wi = surf.to_local(ls.wi);
                if wi.z > 0.0 && ls.wi.dot(surf.ng) > 0.0 {
                    rays += 1;
                    if !self.accel.occluded(origin, ls.wi, 0.0, f32::INFINITY) {
                        let pdf_b = model.pdf(&surf, wo, wi);
                        let mis = power_heuristic(ls.pdf, pdf_b);
                        model.eval(&surf, depth, wo, wi, &mut slots);
                        sink.path(&prefix[..depth], &slots, weight * ls.value * (wi.z * mis));
                    }
                }
            }

            // Continuation by sampling the model's density (also finds emitters by chance).
            let Some(bs) = model.sample(&surf, wo, rng) else {
                break;
            };
            let wi_world = surf.to_world(bs.wi).normalize();
            if bs.wi.z <= 0.0 || wi_world.dot(surf.ng) <= 0.0 || bs.pdf.is_nan() || bs.pdf <= 0.0 {
                break;
            }
            model.eval(&surf, depth, wo, bs.wi, &mut slots);
            let step = weight * (bs.wi.z / bs.pdf);
            if !step.is_finite() {
                break;
            }
            rays += 1;
            let Some(next_hit) = self.accel.intersect(origin, wi_world, 0.0, f32::INFINITY) else {
                let le = self.lights.environment_radiance(wi_world);
                if le != Vec3::ZERO {
                    let pdf_l = self.lights.environment_pdf(surf.ns, wi_world);
                    let mis = power_heuristic(bs.pdf, pdf_l);
                    sink.path(&prefix[..depth], &slots, step * le * mis);
                }
                break;
            };
            if let Some((le, ng)) = self.hit_emission(next_hit.triangle, next_hit.bary, wi_world) {
                let cos_l = ng.dot(-wi_world).abs();
                let pdf_l = self.lights.area_pdf(next_hit.triangle, next_hit.t, cos_l);
                let mis = power_heuristic(bs.pdf, pdf_l);
                sink.path(&prefix[..depth], &slots, step * le * mis);
            }
            if depth + 1 >= self.reflections {
                break;
            }
            let next = self.surface(&next_hit, wi_world);
            prefix[depth] = slots;
            weight = step;
            surf = next;
            dir = wi_world;
        }
        rays
    }
}
