//! Ray queries over all scene triangles. obvhs builds a binary BVH (pre-split, PLOC,
//! reinsertion); we collapse it into an eight-wide tree ([`collapse`], with a cost model fitted
//! to our node) and lay that out for traversal ([`bvh8`]: float child boxes, a node's leaf
//! triangles in rows tested sixteen lanes at once); traversal ([`traverse`]) and the triangle
//! test ([`triangle`]) are ours, because the ray core must be watertight and as fast as
//! Embree, and obvhs' traversal is neither (see those modules).
//!
//! Answers are deterministic: one ray's hit (triangle, t, barycentrics) depends only on the
//! ray and the scene, not on the thread or on the SIMD path taken (AVX-512 or AVX2 when the
//! CPU has it, else the portable code; the same operations, so the same results bit for bit).

mod bvh8;
mod collapse;
mod traverse;
mod triangle;

#[cfg(test)]
mod tests;

use glam::{Vec2, Vec3, Vec3A};
use obvhs::{
    aabb::Aabb, bvh2::reinsertion::ReinsertionOptimizer, bvh2::Bvh2, ploc::PlocBuilder,
    splits::split_aabbs_preset, triangle::Triangle, BvhBuildParams,
};

use crate::scene::Scene;
use bvh8::Bvh8;
use collapse::CollapseCost;
use traverse::{Found, RayNode};
use triangle::{RayTri, Tri};

/// A closest hit: distance, triangle index into `Scene::triangles`, barycentrics of vertices
/// 1 and 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub triangle: u32,
    pub bary: Vec2,
}

/// A ray of a stream query ([`Accel::intersect_stream`], [`Accel::occluded_stream`]): origin,
/// direction, and the open interval (tmin, tmax) of distances along it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    pub tmin: f32,
    pub tmax: f32,
}

impl Ray {
    /// The ray over (0, +inf).
    pub fn new(origin: Vec3, dir: Vec3) -> Ray {
        Ray {
            origin,
            dir,
            tmin: 0.0,
            tmax: f32::INFINITY,
        }
    }
}

pub struct Accel {
    bvh: Bvh8,
    /// Triangles referenced by the leaves (spatial splits may repeat one).
    references: usize,
    /// The SIMD path taken (detected at build).
    simd: Simd,
}

/// The traversal's SIMD paths: the same operations in the same order on each, so the same
/// answers bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Simd {
    /// Plain Rust (whatever the compiler vectorizes for the baseline CPU).
    Portable,
    /// AVX2 node test, leaf test as two 256-bit vectors.
    Avx2,
    /// AVX2 node test, leaf test as one 512-bit vector.
    Avx512,
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
        let simd = detect_simd();
        if tris.is_empty() {
            return Accel {
                bvh: Bvh8::default(),
                references: 0,
                simd,
            };
        }
        Accel::from_bvh2(tris, &build_bvh2(tris), CollapseCost::DEFAULT, simd)
    }

    /// Collapses `bvh2` (over `tris`) and lays it out.
    fn from_bvh2(tris: &[Triangle], bvh2: &Bvh2, cost: CollapseCost, simd: Simd) -> Accel {
        let tree = collapse::collapse(bvh2, cost, bvh8::NODE_TRIANGLES);
        let vertices: Vec<[Vec3A; 3]> = tris.iter().map(|t| [t.v0, t.v1, t.v2]).collect();
        Accel {
            bvh: Bvh8::from_collapsed(&tree, &vertices),
            references: tree.primitives.len(),
            simd,
        }
    }

    /// Number of triangles referenced by the BVH's leaves (spatial splits may repeat one).
    pub fn triangle_count(&self) -> usize {
        self.references
    }

    /// Closest hit with t in (tmin, tmax).
    #[inline]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        self.query::<false>(origin, dir, tmin, tmax, self.simd)
            .map(to_hit)
    }

    /// True when anything blocks the open segment (tmin, tmax) along `dir` from `origin`.
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        self.query::<true>(origin, dir, tmin, tmax, self.simd)
            .is_some()
    }

    /// The closest hit of each ray: `hits[i]` is what `intersect` gives for `rays[i]`, bit
    /// for bit. Faster than one `intersect` after another where the tree does not fit in the
    /// caches: two rays are traversed in turns, so one's memory waits overlap the other's
    /// work.
    ///
    /// Panics if the slices' lengths differ.
    pub fn intersect_stream(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        self.stream::<false>(rays, self.simd, |i, found| hits[i] = found.map(to_hit));
    }

    /// Whether each ray is blocked: `blocked[i]` is what `occluded` gives for `rays[i]`
    /// (traversed in turns as in [`Accel::intersect_stream`]).
    ///
    /// Panics if the slices' lengths differ.
    pub fn occluded_stream(&self, rays: &[Ray], blocked: &mut [bool]) {
        assert_eq!(rays.len(), blocked.len(), "one answer per ray");
        self.stream::<true>(rays, self.simd, |i, found| blocked[i] = found.is_some());
    }

    fn stream<const ANY: bool>(
        &self,
        rays: &[Ray],
        simd: Simd,
        mut answer: impl FnMut(usize, Found),
    ) {
        if self.bvh.nodes.is_empty() {
            (0..rays.len()).for_each(|i| answer(i, None));
            return;
        }
        let ray = |i: usize| {
            let r = &rays[i];
            (
                RayNode::new(r.origin, r.dir, r.tmin),
                RayTri::new(r.origin, r.dir),
                r.tmax,
            )
        };
        let (bvh, len) = (&self.bvh, rays.len());
        // SAFETY: as in `query`.
        #[cfg(target_arch = "x86_64")]
        match simd {
            Simd::Avx512 => return unsafe { stream_avx512::<ANY>(bvh, len, ray, answer) },
            Simd::Avx2 => return unsafe { stream_avx2::<ANY>(bvh, len, ray, answer) },
            Simd::Portable => {}
        }
        let _ = simd;
        // SAFETY: the portable node test needs no CPU feature.
        unsafe { traverse::traverse_stream::<ANY, traverse::Portable>(bvh, len, ray, answer) }
    }

    #[inline(always)]
    fn query<const ANY: bool>(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        simd: Simd,
    ) -> Found {
        if self.bvh.nodes.is_empty() {
            return None;
        }
        let rn = RayNode::new(origin, dir, tmin);
        let rt = RayTri::new(origin, dir);
        // SAFETY: `simd` is Avx2 or Avx512 only when `detect_simd` found those features on
        // this CPU (or a test asked for a path no higher than that).
        #[cfg(target_arch = "x86_64")]
        match simd {
            Simd::Avx512 => return unsafe { traverse_avx512::<ANY>(&self.bvh, &rn, &rt, tmax) },
            Simd::Avx2 => return unsafe { traverse_avx2::<ANY>(&self.bvh, &rn, &rt, tmax) },
            Simd::Portable => {}
        }
        let _ = simd;
        // SAFETY: the portable node test needs no CPU feature.
        unsafe { traverse::traverse::<ANY, traverse::Portable>(&self.bvh, &rn, &rt, tmax) }
    }
}

/// obvhs' binary tree over `tris` (non-empty), as its CWBVH builder makes it before
/// collapsing: large triangles pre-split into several boxes, PLOC, then reinsertion. (Not
/// obvhs' `build_bvh2_from_tris`: that one also merges leaves, which [`collapse`] decides.)
///
/// Pre-splitting large triangles (slow_build and up) pays off on scenes mixing big walls
/// with fine meshes: measured up to 1.7x faster short (occlusion) rays, never slower.
/// very_slow_build's settings (a full pass of reinsertion instead of a fifth, PLOC's wider
/// search at the top only) gave the Cornell box a better tree still: 1.8x faster closest hit
/// and 1.5x faster occlusion (CPU time, interleaved), the same on 100K triangles, within 5 %
/// on 1M; it builds 1M triangles in about 4 s instead of 2. Reinsertion ratio 2 measured no
/// better; slow_build with ratio 1 got half the gain.
fn build_bvh2(tris: &[Triangle]) -> Bvh2 {
    let config = BvhBuildParams::very_slow_build();
    let mut aabbs: Vec<Aabb> = tris.iter().map(|t| t.aabb()).collect();
    let mut indices: Vec<u32> = (0..tris.len() as u32).collect();
    let (largest, sum) = aabbs.iter().fold((0.0f32, 0.0f32), |(m, s), b| {
        let a = b.half_area();
        (m.max(a), s + a)
    });
    split_aabbs_preset(
        &mut aabbs,
        &mut indices,
        tris,
        sum / tris.len() as f32,
        largest,
    );
    let mut bvh2 = PlocBuilder::with_capacity(aabbs.len()).build(
        config.ploc_search_distance,
        &aabbs,
        indices,
        config.sort_precision,
        config.search_depth_threshold,
    );
    bvh2.uses_spatial_splits = true;
    ReinsertionOptimizer::default().run(&mut bvh2, config.reinsertion_batch_ratio, None);
    bvh2
}

fn to_hit((triangle, t, b1, b2): (u32, f32, f32, f32)) -> Hit {
    Hit {
        t,
        triangle,
        bary: Vec2::new(b1, b2),
    }
}

fn detect_simd() -> Simd {
    #[cfg(target_arch = "x86_64")]
    {
        if is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx2") {
            return Simd::Avx512;
        }
        if is_x86_feature_detected!("avx2") {
            return Simd::Avx2;
        }
    }
    Simd::Portable
}

/// The same traversal compiled for AVX2, with the node test's eight lanes as one 256-bit vector
/// (`traverse::Avx2`). No FMA is used, so the arithmetic (and every answer) equals the
/// portable path's.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn traverse_avx2<const ANY: bool>(
    bvh: &Bvh8,
    rn: &RayNode,
    rt: &RayTri,
    tmax: f32,
) -> Found {
    traverse::traverse::<ANY, traverse::Avx2>(bvh, rn, rt, tmax)
}

/// The same traversal with AVX-512 enabled: the leaf test's sixteen lanes are one 512-bit
/// vector (`traverse::Avx512`). No FMA is used (Rust never contracts a * b + c), so every
/// answer equals the portable path's.
///
/// # Safety
/// The CPU must support AVX2 and AVX-512 F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f")]
unsafe fn traverse_avx512<const ANY: bool>(
    bvh: &Bvh8,
    rn: &RayNode,
    rt: &RayTri,
    tmax: f32,
) -> Found {
    traverse::traverse::<ANY, traverse::Avx512>(bvh, rn, rt, tmax)
}

/// `traverse_stream` compiled for AVX2, as `traverse_avx2`.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn stream_avx2<const ANY: bool>(
    bvh: &Bvh8,
    len: usize,
    ray: impl Fn(usize) -> (RayNode, RayTri, f32),
    answer: impl FnMut(usize, Found),
) {
    traverse::traverse_stream::<ANY, traverse::Avx2>(bvh, len, ray, answer)
}

/// `traverse_stream` compiled for AVX-512, as `traverse_avx512`.
///
/// # Safety
/// The CPU must support AVX2 and AVX-512 F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f")]
unsafe fn stream_avx512<const ANY: bool>(
    bvh: &Bvh8,
    len: usize,
    ray: impl Fn(usize) -> (RayNode, RayTri, f32),
    answer: impl FnMut(usize, Found),
) {
    traverse::traverse_stream::<ANY, traverse::Avx512>(bvh, len, ray, answer)
}

/// Brute-force closest hit over all triangles (the first of equal distances), with the same
/// triangle test as the BVH; the reference the BVH is tested against.
pub fn brute_force_intersect(
    tris: &[Triangle],
    origin: Vec3,
    dir: Vec3,
    tmin: f32,
    tmax: f32,
) -> Option<Hit> {
    let rt = RayTri::new(origin, dir);
    let mut best: Option<Hit> = None;
    let mut tmax = tmax;
    for (i, t) in tris.iter().enumerate() {
        let tri = Tri {
            v: [t.v0, t.v1, t.v2],
        };
        if let Some((t, b1, b2)) = triangle::intersect(&tri, &rt, tmin, tmax) {
            tmax = t;
            best = Some(Hit {
                t,
                triangle: i as u32,
                bary: Vec2::new(b1, b2),
            });
        }
    }
    best
}
