//! Light sources and their sampling for next-event estimation: emissive triangles (area
//! lights), punctual lights (point, spot, directional) and the environment.
//!
//! Each kind is sampled on its own at every shading point (one area-light sample, every
//! punctual light, one environment sample), so no selection probability between kinds is
//! needed and the densities used for multiple importance sampling are simple.

mod color;
mod environment;

pub use color::luminance;

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

use environment::LatLongSampler;
use prt_formats::lighting::cubemap::rotation_y;

use crate::sampling::{uniform_triangle, Distribution1D};
use crate::scene::{Environment, PunctualLight, Scene};

/// A sample of incident light at a point, for next-event estimation.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3,
    /// Distance to the light point (f32::INFINITY for directional/environment).
    pub distance: f32,
    /// Incident radiance divided by the solid-angle density (or the delta light's
    /// irradiance-equivalent): the estimator's light factor before BRDF x cosine.
    pub value: Vec3,
    /// Solid-angle density of the sample, for MIS; 0 for delta lights (no MIS).
    pub pdf: f32,
}

struct EmissiveTriangle {
    triangle: u32,
    area: f32,
}

pub struct LightSet {
    emissive: Vec<EmissiveTriangle>,
    emissive_pick: Option<Distribution1D>,
    /// For each scene triangle, its index into `emissive` (u32::MAX when not emissive).
    emissive_index: Vec<u32>,
    pub punctual: Vec<PunctualLight>,
    environment: Environment,
    env_sampler: Option<LatLongSampler>,
    /// The environment's rotation about +Y (`Scene::environment_rotation`), row-major, from
    /// the one definition of the convention (`prt_formats::lighting::cubemap::rotation_y`).
    env_rotation: [[f32; 3]; 3],
}

impl LightSet {
    pub fn new(scene: &Scene) -> LightSet {
        let mut emissive = Vec::new();
        let mut weights = Vec::new();
        let mut emissive_index = vec![u32::MAX; scene.triangles.len()];
        for (i, tri) in scene.triangles.iter().enumerate() {
            let m = &scene.materials[scene.triangle_material[i] as usize];
            if !m.is_emissive() {
                continue;
            }
            let [a, b, c] = tri.map(|v| scene.positions[v as usize]);
            let area = 0.5 * (b - a).cross(c - a).length();
            if !(area > 0.0 && area.is_finite()) {
                continue;
            }
            emissive_index[i] = emissive.len() as u32;
            emissive.push(EmissiveTriangle {
                triangle: i as u32,
                area,
            });
            weights.push(luminance(m.emission).max(1e-6) * area);
        }
        let emissive_pick = Distribution1D::new(&weights);
        let env_sampler = match &scene.environment {
            Environment::LatLong {
                width,
                height,
                texels,
            } => LatLongSampler::new(*width as usize, *height as usize, texels),
            Environment::Constant(_) => None,
        };
        LightSet {
            emissive,
            emissive_pick,
            emissive_index,
            punctual: scene.lights.clone(),
            environment: scene.environment.clone(),
            env_sampler,
            env_rotation: rotation_y(scene.environment_rotation as f64)
                .map(|row| row.map(|x| x as f32)),
        }
    }

    pub fn has_environment(&self) -> bool {
        match &self.environment {
            Environment::Constant(c) => c.max_element() > 0.0,
            Environment::LatLong { .. } => self.env_sampler.is_some(),
        }
    }

    /// Samples a point on an emissive triangle as seen from `p`. `Le` is the radiance the
    /// caller evaluates at the hit (it needs the UV for emissive textures); here `value` holds
    /// 1/pdf so the caller multiplies by Le. Returns the chosen triangle and its barycentrics.
    ///
    /// `u.x` picks the triangle and, rescaled within the triangle's share, places the point
    /// (as [`crate::sampling::pick_component`], for the same reason: a separate pick would
    /// break the stratification of the points over a light made of several triangles). The
    /// rescaled coordinate keeps about 24 - log2(emissive triangles) bits: 12 bits even for
    /// 4096 emissive triangles.
    pub fn sample_area(&self, scene: &Scene, p: Vec3, u: Vec2) -> Option<(LightSample, u32, Vec2)> {
        let pick = self.emissive_pick.as_ref()?;
        let (i, x) = pick.sample(u.x);
        let u = Vec2::new(x, u.y);
        let em = &self.emissive[i];
        let tri = scene.triangles[em.triangle as usize];
        let [a, b, c] = tri.map(|v| scene.positions[v as usize]);
        let bary = uniform_triangle(u);
        let q = a + (b - a) * bary.x + (c - a) * bary.y;
        let to = q - p;
        let d2 = to.length_squared();
        if !(d2 > 0.0 && d2.is_finite()) {
            return None;
        }
        let dist = d2.sqrt();
        let wi = to / dist;
        let ng = (b - a).cross(c - a).normalize();
        let ns = self.emitting_normal(scene, em.triangle, ng, bary);
        let cos_l = -wi.dot(ns);
        if cos_l <= 0.0 {
            return None;
        }
        let pdf = pick.pmf(i) / em.area * d2 / cos_l;
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some((
            LightSample {
                wi,
                distance: dist,
                value: Vec3::splat(1.0 / pdf),
                pdf,
            },
            em.triangle,
            bary,
        ))
    }

    /// The side an emissive triangle emits from: its geometric normal, flipped to agree with
    /// the interpolated vertex normals (robust to meshes with inconsistent winding).
    fn emitting_normal(&self, scene: &Scene, triangle: u32, ng: Vec3, bary: Vec2) -> Vec3 {
        let tri = scene.triangles[triangle as usize];
        let [na, nb, nc] = tri.map(|v| scene.normals[v as usize]);
        let ns = na * (1.0 - bary.x - bary.y) + nb * bary.x + nc * bary.y;
        if ns.dot(ng) < 0.0 {
            -ng
        } else {
            ng
        }
    }

    /// True when a ray arriving along `dir` at the given point of an emissive triangle sees
    /// its emitting side.
    pub fn emits_towards(
        &self,
        scene: &Scene,
        triangle: u32,
        ng: Vec3,
        bary: Vec2,
        dir: Vec3,
    ) -> bool {
        self.emitting_normal(scene, triangle, ng, bary).dot(dir) < 0.0
    }

    /// Solid-angle density with which [`LightSet::sample_area`] would pick the point at
    /// distance `dist` on `triangle` from direction `wi` (for MIS of BRDF-sampled hits).
    pub fn area_pdf(&self, triangle: u32, dist: f32, cos_l: f32) -> f32 {
        let Some(pick) = self.emissive_pick.as_ref() else {
            return 0.0;
        };
        let Some(&idx) = self.emissive_index.get(triangle as usize) else {
            return 0.0;
        };
        if idx == u32::MAX || cos_l <= 0.0 {
            return 0.0;
        }
        let em = &self.emissive[idx as usize];
        pick.pmf(idx as usize) / em.area * dist * dist / cos_l
    }

    /// Environment radiance arriving from direction `dir` (world space, towards the sky).
    pub fn environment_radiance(&self, dir: Vec3) -> Vec3 {
        match &self.environment {
            Environment::Constant(c) => *c,
            Environment::LatLong {
                width,
                height,
                texels,
            } => {
                let local = self.world_to_map(dir);
                environment::latlong_radiance(*width as usize, *height as usize, texels, local)
            }
        }
    }

    /// Samples the environment as seen from a point with normal `n`: cosine-weighted for a
    /// constant environment, by the map's luminance otherwise.
    pub fn sample_environment(&self, n: Vec3, u: Vec2) -> Option<LightSample> {
        if !self.has_environment() {
            return None;
        }
        let (wi, pdf) = match &self.env_sampler {
            None => {
                let local = crate::brdf::cosine_hemisphere(u);
                let (t, b) = orthonormal_basis(n);
                let wi = t * local.x + b * local.y + n * local.z;
                (wi, local.z / PI)
            }
            Some(s) => {
                let (local, pdf) = s.sample(u)?;
                (self.map_to_world(local), pdf)
            }
        };
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(LightSample {
            wi,
            distance: f32::INFINITY,
            value: self.environment_radiance(wi) / pdf,
            pdf,
        })
    }

    /// Density of [`LightSet::sample_environment`] for direction `wi` at a point with normal `n`.
    pub fn environment_pdf(&self, n: Vec3, wi: Vec3) -> f32 {
        if !self.has_environment() {
            return 0.0;
        }
        match &self.env_sampler {
            None => wi.dot(n).max(0.0) / PI,
            Some(s) => s.pdf(self.world_to_map(wi)),
        }
    }

    /// A world direction in the map's own frame: `R_y(-rotation) d = R^T d`.
    #[inline]
    fn world_to_map(&self, d: Vec3) -> Vec3 {
        let m = &self.env_rotation;
        Vec3::new(
            m[0][0] * d.x + m[1][0] * d.y + m[2][0] * d.z,
            m[0][1] * d.x + m[1][1] * d.y + m[2][1] * d.z,
            m[0][2] * d.x + m[1][2] * d.y + m[2][2] * d.z,
        )
    }

    /// A direction of the map's frame in the world: `R_y(rotation) d` (the right-hand rule
    /// about +Y takes +Z towards +X).
    #[inline]
    fn map_to_world(&self, d: Vec3) -> Vec3 {
        let m = &self.env_rotation;
        Vec3::new(
            m[0][0] * d.x + m[0][1] * d.y + m[0][2] * d.z,
            m[1][0] * d.x + m[1][1] * d.y + m[1][2] * d.z,
            m[2][0] * d.x + m[2][1] * d.y + m[2][2] * d.z,
        )
    }

    /// Incident light from punctual light `i` at `p`: direction, distance and the delta
    /// light's contribution factor (intensity / d^2, or irradiance).
    pub fn sample_punctual(&self, i: usize, p: Vec3) -> Option<LightSample> {
        match self.punctual[i] {
            PunctualLight::Point {
                position,
                intensity,
            } => {
                let to = position - p;
                let d2 = to.length_squared();
                if d2.is_nan() || d2 <= 0.0 {
                    return None;
                }
                let d = d2.sqrt();
                Some(LightSample {
                    wi: to / d,
                    distance: d,
                    value: intensity / d2,
                    pdf: 0.0,
                })
            }
            PunctualLight::Spot {
                position,
                direction,
                intensity,
                inner_cone,
                outer_cone,
            } => {
                let to = position - p;
                let d2 = to.length_squared();
                if d2.is_nan() || d2 <= 0.0 {
                    return None;
                }
                let d = d2.sqrt();
                let wi = to / d;
                let cd = (-wi).dot(direction);
                let (ci, co) = (inner_cone.cos(), outer_cone.cos());
                // glTF's recommended smooth falloff: linear in cos between the cones, squared.
                let t = if ci > co {
                    ((cd - co) / (ci - co)).clamp(0.0, 1.0)
                } else if cd >= co {
                    1.0
                } else {
                    0.0
                };
                let falloff = t * t;
                if falloff <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    distance: d,
                    value: intensity * falloff / d2,
                    pdf: 0.0,
                })
            }
            PunctualLight::Directional {
                direction,
                irradiance,
            } => Some(LightSample {
                wi: -direction,
                distance: f32::INFINITY,
                value: irradiance,
                pdf: 0.0,
            }),
        }
    }
}

/// Tangent and bitangent completing the unit normal `n` (Duff et al. 2017, branchless).
#[inline]
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}
