//! Ray queries over all scene triangles: a compressed wide BVH (obvhs' CWBVH) for traversal and
//! our own Moeller-Trumbore test, which also returns the barycentrics we need for shading.

use glam::{Vec2, Vec3, Vec3A};
use obvhs::{
    cwbvh::{builder::build_cwbvh_from_tris, CwBvh},
    ray::{Ray, RayHit},
    triangle::Triangle,
    BvhBuildParams,
};

use crate::scene::Scene;

/// A closest hit: distance, triangle index into `Scene::triangles`, barycentrics of vertices
/// 1 and 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub triangle: u32,
    pub bary: Vec2,
}

/// Triangle in the layout the intersection test wants, in BVH leaf order.
#[derive(Clone, Copy, Debug)]
struct PackedTriangle {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
}

pub struct Accel {
    bvh: CwBvh,
    /// Triangles reordered so the BVH's primitive ids index them directly (cache friendly).
    packed: Vec<PackedTriangle>,
    /// Scene triangle index of each packed triangle.
    original: Vec<u32>,
}

impl Accel {
    pub fn build(scene: &Scene) -> Accel {
        let tris: Vec<Triangle> = scene
            .triangles
            .iter()
            .map(|t| Triangle {
                v0: scene.positions[t[0] as usize].into(),
                v1: scene.positions[t[1] as usize].into(),
                v2: scene.positions[t[2] as usize].into(),
            })
            .collect();
        Accel::from_triangles(&tris)
    }

    /// Builds from raw triangles (scene triangle i = `tris[i]`).
    pub fn from_triangles(tris: &[Triangle]) -> Accel {
        if tris.is_empty() {
            return Accel {
                bvh: CwBvh::default(),
                packed: Vec::new(),
                original: Vec::new(),
            };
        }
        // Pre-splitting large triangles (slow_build) pays off on scenes mixing big walls with
        // fine meshes: measured up to 1.7x faster short (occlusion) rays, never slower.
        let bvh = build_cwbvh_from_tris(
            tris,
            BvhBuildParams::slow_build(),
            &mut std::time::Duration::default(),
        );
        let original: Vec<u32> = bvh.primitive_indices.clone();
        let packed = original
            .iter()
            .map(|&i| {
                let t = &tris[i as usize];
                PackedTriangle {
                    v0: t.v0,
                    e1: t.v1 - t.v0,
                    e2: t.v2 - t.v0,
                }
            })
            .collect();
        Accel {
            bvh,
            packed,
            original,
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.packed.len()
    }

    /// Closest hit with t in (tmin, tmax).
    #[inline]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        if self.packed.is_empty() {
            return None;
        }
        let ray = Ray::new(origin.into(), dir.into(), tmin, tmax);
        let mut hit = RayHit::none();
        let mut best_bary = Vec2::ZERO;
        let packed = &self.packed;
        let found = self.bvh.ray_traverse(ray, &mut hit, |r, id| {
            match intersect_triangle(&packed[id], r) {
                Some((t, b)) if t < r.tmax => {
                    best_bary = b;
                    t
                }
                _ => f32::INFINITY,
            }
        });
        if !found {
            return None;
        }
        Some(Hit {
            t: hit.t,
            triangle: self.original[hit.primitive_id as usize],
            bary: best_bary,
        })
    }

    /// True when anything blocks the segment (tmin, tmax) along `dir` from `origin`.
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        if self.packed.is_empty() {
            return false;
        }
        let ray = Ray::new(origin.into(), dir.into(), tmin, tmax);
        let packed = &self.packed;
        !self.bvh.ray_traverse_miss(ray, |r, id| {
            intersect_triangle(&packed[id], r).map_or(f32::INFINITY, |(t, _)| t)
        })
    }
}

/// Moeller-Trumbore, two-sided. Returns t within the ray's [tmin, tmax] and the barycentrics of
/// vertices 1 and 2. Computed in f32 with the edge vectors precomputed.
#[inline(always)]
fn intersect_triangle(tri: &PackedTriangle, ray: &Ray) -> Option<(f32, Vec2)> {
    let p = ray.direction.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = ray.origin - tri.v0;
    let u = s.dot(p) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(tri.e1);
    let v = ray.direction.dot(q) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = tri.e2.dot(q) * inv_det;
    if t > ray.tmin && t <= ray.tmax {
        Some((t, Vec2::new(u, v)))
    } else {
        None
    }
}

/// Brute-force closest hit over all triangles; the reference the BVH is tested against.
pub fn brute_force_intersect(
    tris: &[Triangle],
    origin: Vec3,
    dir: Vec3,
    tmin: f32,
    tmax: f32,
) -> Option<Hit> {
    let ray = Ray::new(origin.into(), dir.into(), tmin, tmax);
    let mut best: Option<Hit> = None;
    for (i, t) in tris.iter().enumerate() {
        let packed = PackedTriangle {
            v0: t.v0,
            e1: t.v1 - t.v0,
            e2: t.v2 - t.v0,
        };
        if let Some((th, b)) = intersect_triangle(&packed, &ray) {
            if best.is_none_or(|h| th < h.t) {
                best = Some(Hit {
                    t: th,
                    triangle: i as u32,
                    bary: b,
                });
            }
        }
    }
    best
}
