//! What a camera sees from where it stands, before any triangle is drawn: the ray through each
//! pixel (the film formula, written once for the rasterizer's coverage and a shader's view
//! directions), the checks of a mesh's indices, and whether the eye is inside an object, by
//! the rule the baker applies to a `--camera` view ([`prt_formats::view::judge_eye`]), here
//! with the 26 rays traced by brute force over all triangles (the runtime has no BVH; 26 rays
//! against ~100K triangles take milliseconds).

use prt_formats::view::{judge_eye, CameraFrame, EyeVerdict, EYE_TEST_DIRECTIONS};
use rayon::prelude::*;

/// Largest image width or height accepted (the rasterizer stores pixel rectangles as `u16`).
pub(crate) const MAX_IMAGE_SIDE: u32 = 16384;

/// The triangle index of a pixel that sees no triangle (a mesh has fewer triangles than this).
pub(crate) const NO_TRIANGLE: u32 = u32::MAX;

/// Why a frame could not be rasterized (or the eye checked).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RasterError {
    /// The image is empty or absurdly large.
    #[error("image size {width}x{height}: width and height must be between 1 and {max}")]
    ImageSize {
        /// Width asked for.
        width: u32,
        /// Height asked for.
        height: u32,
        /// [`MAX_IMAGE_SIDE`].
        max: u32,
    },
    /// The camera frame is not finite, its field of view is outside (0, 180) degrees, or its
    /// axes do not span space.
    #[error("camera {camera:?}: {reason}")]
    Camera {
        /// The frame, as given.
        camera: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "triangle {triangle} refers to vertex {index}, but there are only {vertices} vertices"
    )]
    VertexIndex {
        /// The triangle.
        triangle: usize,
        /// The vertex index it holds.
        index: u32,
        /// The number of vertices.
        vertices: usize,
    },
    /// More triangles than a `u32` index can name (one value is reserved for [`NO_TRIANGLE`]).
    #[error("{triangles} triangles: at most {max} can be rasterized")]
    TooManyTriangles {
        /// The number given.
        triangles: usize,
        /// The most accepted.
        max: usize,
    },
    /// Two per-vertex or per-triangle arrays that must have the same length do not.
    #[error("{what}: {got} entries, expected {expected}")]
    Length {
        /// Which array.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The length it must have.
        expected: usize,
    },
    /// The eye position is not finite.
    #[error("eye ({}, {}, {}) is not finite", eye[0], eye[1], eye[2])]
    Eye {
        /// The eye.
        eye: [f32; 3],
    },
}

/// The primary rays of a camera at an image size: the one place the film formula is written,
/// used by the rasterizer for coverage and by a shader for each pixel's view direction.
///
/// Film position `(x, y)` (pixels, y down; a pixel's centre is `(px + 0.5, py + 0.5)`) looks
/// along `normalize(forward + right sx + up sy)` with `sx = (2 x / W - 1) tan(yfov / 2) W / H`
/// and `sy = (1 - 2 y / H) tan(yfov / 2)`, the reference tracer's `camera_ray`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ViewRays {
    pub(super) position: [f64; 3],
    pub(super) forward: [f64; 3],
    pub(super) right: [f64; 3],
    pub(super) up: [f64; 3],
    pub(super) tan_half_fov: f64,
    pub(super) aspect: f64,
    pub(super) width: u32,
    pub(super) height: u32,
}

impl ViewRays {
    /// The rays of `camera` for a `width` x `height` image, or why there are none: an image
    /// size outside `1..=MAX_IMAGE_SIDE`, a non-finite frame, a field of view outside
    /// (0, 180) degrees, or axes that do not span space.
    pub(crate) fn new(
        camera: &CameraFrame,
        width: u32,
        height: u32,
    ) -> Result<ViewRays, RasterError> {
        if !(1..=MAX_IMAGE_SIDE).contains(&width) || !(1..=MAX_IMAGE_SIDE).contains(&height) {
            return Err(RasterError::ImageSize {
                width,
                height,
                max: MAX_IMAGE_SIDE,
            });
        }
        let bad = |reason| RasterError::Camera {
            camera: format!("{camera:?}"),
            reason,
        };
        let vectors = [camera.position, camera.forward, camera.right, camera.up];
        if !vectors.iter().flatten().all(|c| c.is_finite()) || !camera.yfov.is_finite() {
            return Err(bad("the frame is not finite"));
        }
        if !(camera.yfov > 0.0 && camera.yfov < std::f32::consts::PI) {
            return Err(bad(
                "the vertical field of view must be in (0, 180) degrees",
            ));
        }
        let [position, forward, right, up] = vectors.map(|v| v.map(f64::from));
        // A frame from `CameraSpec::frame` is orthonormal (|det| = 1); one that is far from it
        // would make the film formula describe a different camera than the caller meant.
        if dot(cross(right, up), forward).abs() < 0.5 {
            return Err(bad(
                "forward, right and up must be unit vectors spanning space",
            ));
        }
        Ok(ViewRays {
            position,
            forward,
            right,
            up,
            tan_half_fov: (f64::from(camera.yfov) * 0.5).tan(),
            aspect: f64::from(width) / f64::from(height),
            width,
            height,
        })
    }

    /// The film offsets `(sx, sy)` of film position `(x, y)` in pixels: the ray is
    /// `forward + right sx + up sy`.
    #[inline]
    pub(crate) fn film(&self, x: f64, y: f64) -> (f64, f64) {
        let sx = (2.0 * x / f64::from(self.width) - 1.0) * self.tan_half_fov * self.aspect;
        let sy = (1.0 - 2.0 * y / f64::from(self.height)) * self.tan_half_fov;
        (sx, sy)
    }

    /// The unnormalized world direction `forward + right sx + up sy` of film offsets.
    #[inline]
    pub(super) fn world(&self, sx: f64, sy: f64) -> [f64; 3] {
        std::array::from_fn(|i| self.forward[i] + self.right[i] * sx + self.up[i] * sy)
    }

    /// The unit view direction through film position `(x, y)` in pixels.
    pub(crate) fn direction(&self, x: f64, y: f64) -> [f64; 3] {
        let (sx, sy) = self.film(x, y);
        let d = self.world(sx, sy);
        let len = dot(d, d).sqrt();
        d.map(|c| c / len)
    }

    /// How many sub-samples per side a background pixel averages for a lat-long map of
    /// `map_width` x `map_height` texels ([`background_samples`]).
    pub(crate) fn background_samples(&self, map_width: usize, map_height: usize) -> u32 {
        background_samples(self.tan_half_fov, self.height, map_width, map_height)
    }

    /// The unit view direction through the centre of pixel `(px, py)` (row 0 at the top).
    pub(crate) fn pixel_direction(&self, px: u32, py: u32) -> [f32; 3] {
        self.direction(f64::from(px) + 0.5, f64::from(py) + 0.5)
            .map(|c| c as f32)
    }

    /// The eye position.
    #[cfg(test)]
    pub(crate) fn eye(&self) -> [f64; 3] {
        self.position
    }
}

/// Most sub-samples per side of a background pixel (16 lookups): a map much finer than the
/// pixels is still averaged well enough at a bounded cost per pixel.
pub const MAX_BACKGROUND_SAMPLES: u32 = 4;

/// How many sub-samples per side (`k`; `k x k` in all, at the centres of a regular grid over
/// the pixel) a pixel that sees the environment averages, for a camera with `tan(yfov / 2) =
/// tan_half_fov` at `height` pixels and a lat-long map of `map_width` x `map_height` texels.
///
/// Why: a path tracer (the reference, Mitsuba) shows the average of the map over each pixel;
/// one lookup at the pixel's centre misses or hits a lamp narrower than a pixel by chance
/// (5.5 % of the lamp's peak per pixel in the unit test below). The samples
/// are at most a quarter of a texel apart: `k = ceil(4 p / t)` for a pixel `p = 2 tan(yfov /
/// 2) / height` radians across at the image centre and a texel `t = min(2 pi / W, pi / H)`,
/// between 1 (a pixel under a quarter of a texel: its centre is the average within the
/// bilinear lookup's own error) and [`MAX_BACKGROUND_SAMPLES`] (a pixel over a texel across
/// is then sampled more coarsely: a map much finer than the image would want a mip level).
/// The GPU backend reads the same number.
pub fn background_samples(
    tan_half_fov: f64,
    height: u32,
    map_width: usize,
    map_height: usize,
) -> u32 {
    let pixel = 2.0 * tan_half_fov / f64::from(height.max(1));
    let texel = (std::f64::consts::TAU / map_width.max(1) as f64)
        .min(std::f64::consts::PI / map_height.max(1) as f64);
    let k = (4.0 * pixel / texel).ceil();
    if k.is_finite() && k > 1.0 {
        (k as u32).min(MAX_BACKGROUND_SAMPLES)
    } else {
        1
    }
}

/// Refuses vertex indices out of range and more triangles than a `u32` can name.
pub(crate) fn check_indices(vertices: usize, triangles: &[[u32; 3]]) -> Result<(), RasterError> {
    let max = NO_TRIANGLE as usize;
    if triangles.len() > max {
        return Err(RasterError::TooManyTriangles {
            triangles: triangles.len(),
            max,
        });
    }
    // The largest index first (a vectorized pass); the offender is looked for only on error.
    let largest = triangles.iter().flatten().copied().max();
    if largest.is_none_or(|m| (m as usize) < vertices) {
        return Ok(());
    }
    let bad = triangles.iter().enumerate().find_map(|(t, tri)| {
        tri.iter()
            .find(|&&i| i as usize >= vertices)
            .map(|&i| (t, i))
    });
    match bad {
        Some((triangle, index)) => Err(RasterError::VertexIndex {
            triangle,
            index,
            vertices,
        }),
        None => Ok(()),
    }
}

/// Dot product (f64: the rasterizer's camera-space arithmetic).
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product (f64).
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Triangles per parallel task.
const CHUNK: usize = 8192;

/// Traces the 26 [`EYE_TEST_DIRECTIONS`] from `eye` against every triangle and returns the
/// shared rule's verdict: the eye is inside an object when at least 22 of them meet a back
/// side first, a back side being one whose interpolated vertex normal points away from the eye
/// (as in the baker). `normals` are per vertex (unnormalized is fine), `triangle_material` per
/// triangle; the material count is the largest index plus one.
///
/// The ray-triangle test is the tracer's (f32 Moller-Trumbore, hits at `t > 0`); of equally
/// near hits, the lowest triangle index counts.
pub(crate) fn eye_verdict(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    triangles: &[[u32; 3]],
    triangle_material: &[u32],
    eye: [f32; 3],
) -> Result<EyeVerdict, RasterError> {
    if normals.len() != positions.len() {
        return Err(RasterError::Length {
            what: "vertex normals",
            got: normals.len(),
            expected: positions.len(),
        });
    }
    if triangle_material.len() != triangles.len() {
        return Err(RasterError::Length {
            what: "triangle materials",
            got: triangle_material.len(),
            expected: triangles.len(),
        });
    }
    if !eye.iter().all(|c| c.is_finite()) {
        return Err(RasterError::Eye { eye });
    }
    check_indices(positions.len(), triangles)?;

    let nearest = nearest_hits(positions, triangles, eye);
    let material_count = triangle_material
        .iter()
        .max()
        .map_or(0, |&m| m as usize + 1);
    Ok(judge_eye(material_count, |dir| {
        let k = EYE_TEST_DIRECTIONS.iter().position(|d| *d == dir)?;
        let h = nearest[k];
        if h.triangle == u32::MAX {
            return None;
        }
        let [na, nb, nc] = triangles[h.triangle as usize].map(|v| normals[v as usize]);
        let w = 1.0 - h.u - h.v;
        let n: [f32; 3] = std::array::from_fn(|i| na[i] * w + nb[i] * h.u + nc[i] * h.v);
        let facing_away = n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2] > 0.0;
        Some((triangle_material[h.triangle as usize] as usize, facing_away))
    }))
}

/// Triangles per culling block: a block's bounding box is tested against the rays that could
/// still find a nearer hit, and only its triangles for the rays that pass.
const BLOCK: usize = 32;

/// The nearest hit along each of the 26 rays from `eye`: the same as testing every triangle
/// against every ray (`nearest_hits_brute`, kept for the test), but a block of [`BLOCK`]
/// consecutive triangles (meshes store nearby triangles together) is skipped for the rays
/// that miss its box or already have a hit nearer than the box. A camera move re-runs this,
/// so its cost is part of a view change.
fn nearest_hits(positions: &[[f32; 3]], triangles: &[[u32; 3]], eye: [f32; 3]) -> [Hit; 26] {
    let dirs = EYE_TEST_DIRECTIONS.map(|d| d.map(f64::from));
    let e = eye.map(f64::from);
    triangles
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(c, tris)| {
            let mut best = [Hit::NONE; 26];
            for (b, block) in tris.chunks(BLOCK).enumerate() {
                let (lo, hi) = padded_box(positions, block);
                let mut mask = 0u32;
                for (k, d) in dirs.iter().enumerate() {
                    if let Some(t_near) = ray_box(e, *d, lo, hi) {
                        // Strictly beyond the best hit: nothing in the box can come first or
                        // tie (ties go to the lower triangle index, compared in `before`).
                        if t_near <= f64::from(best[k].t) {
                            mask |= 1 << k;
                        }
                    }
                }
                if mask == 0 {
                    continue;
                }
                for (i, tri) in block.iter().enumerate() {
                    let t = (c * CHUNK + b * BLOCK + i) as u32;
                    hit_some(tri.map(|v| positions[v as usize]), eye, t, mask, &mut best);
                }
            }
            best
        })
        // The nearest of two hits, ties to the lower triangle: the same in any grouping.
        .reduce(
            || [Hit::NONE; 26],
            |a, b| std::array::from_fn(|k| if b[k].before(&a[k]) { b[k] } else { a[k] }),
        )
}

/// The bounding box of `block`'s vertices (f64), grown so that every hit the f32 test can
/// report lies inside: Moller-Trumbore's barycentrics and `t` carry f32 rounding, so a hit
/// may fall a few ulps outside the triangle; the margin is many times that.
fn padded_box(positions: &[[f32; 3]], block: &[[u32; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for tri in block {
        for &v in tri {
            let p = positions[v as usize];
            for i in 0..3 {
                lo[i] = lo[i].min(f64::from(p[i]));
                hi[i] = hi[i].max(f64::from(p[i]));
            }
        }
    }
    let scale = (0..3).fold(0.0f64, |m, i| {
        m.max(lo[i].abs()).max(hi[i].abs()).max(hi[i] - lo[i])
    });
    let pad = 1e-4 * scale + 1e-12;
    (lo.map(|x| x - pad), hi.map(|x| x + pad))
}

/// Where the ray `eye + t d` (t >= 0) enters the box, or None when it misses it. A zero
/// direction component keeps the ray in that slab only when the eye lies within it.
fn ray_box(eye: [f64; 3], d: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> Option<f64> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for i in 0..3 {
        if d[i] == 0.0 {
            if eye[i] < lo[i] || eye[i] > hi[i] {
                return None;
            }
            continue;
        }
        let (a, b) = ((lo[i] - eye[i]) / d[i], (hi[i] - eye[i]) / d[i]);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    // A small relative allowance, as for the box: the entry point is only a bound.
    (t0 <= t1 * (1.0 + 1e-9) + 1e-12).then_some(t0 * (1.0 - 1e-6))
}

/// Every triangle against every ray: what [`nearest_hits`] must equal.
#[cfg(test)]
fn nearest_hits_brute(positions: &[[f32; 3]], triangles: &[[u32; 3]], eye: [f32; 3]) -> [Hit; 26] {
    let mut best = [Hit::NONE; 26];
    for (t, tri) in triangles.iter().enumerate() {
        hit_some(
            tri.map(|v| positions[v as usize]),
            eye,
            t as u32,
            u32::MAX,
            &mut best,
        );
    }
    best
}

/// The nearest hit so far along one of the 26 rays.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Hit {
    t: f32,
    triangle: u32,
    u: f32,
    v: f32,
}

impl Hit {
    const NONE: Hit = Hit {
        t: f32::INFINITY,
        triangle: u32::MAX,
        u: 0.0,
        v: 0.0,
    };

    fn before(&self, other: &Hit) -> bool {
        self.t < other.t || (self.t == other.t && self.triangle < other.triangle)
    }
}

// f32 vector helpers: the eye check reproduces the tracer's f32 intersection test.
fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot32(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross32(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Moller-Trumbore of one triangle against the rays from `eye` whose bit is set in `rays` (of
/// the 26), keeping the nearest hit of each. What depends only on the triangle and the eye is
/// computed once.
fn hit_some(p: [[f32; 3]; 3], eye: [f32; 3], triangle: u32, rays: u32, best: &mut [Hit; 26]) {
    let e1 = sub(p[1], p[0]);
    let e2 = sub(p[2], p[0]);
    let s = sub(eye, p[0]);
    let q = cross32(s, e1);
    let t_num = dot32(e2, q);
    for (k, dir) in EYE_TEST_DIRECTIONS.iter().enumerate() {
        if rays & (1 << k) == 0 {
            continue;
        }
        let pv = cross32(*dir, e2);
        let det = dot32(e1, pv);
        if det == 0.0 || !det.is_finite() {
            continue;
        }
        let inv_det = 1.0 / det;
        let u = dot32(s, pv) * inv_det;
        if !(0.0..=1.0).contains(&u) {
            continue;
        }
        let v = dot32(*dir, q) * inv_det;
        if v < 0.0 || u + v > 1.0 {
            continue;
        }
        let t = t_num * inv_det;
        let hit = Hit { t, triangle, u, v };
        if t > 0.0 && hit.before(&best[k]) {
            best[k] = hit;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift) for the test geometry.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// A grid of `n x n` quads in the plane y = `y` over [-1, 1]^2, jittered in height, and
    /// `soup` random small triangles scattered through [-1, 1]^3.
    fn scene(n: usize, y: f32, soup: usize, rng: &mut Rng) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        let mut t = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                p.push([2.0 * u - 1.0, y + 0.01 * rng.next(), 2.0 * v - 1.0]);
            }
        }
        for j in 0..n {
            for i in 0..n {
                let a = (j * (n + 1) + i) as u32;
                let (b, c, d) = (a + 1, a + n as u32 + 2, a + n as u32 + 1);
                t.push([a, b, c]);
                t.push([a, c, d]);
            }
        }
        for _ in 0..soup {
            let c = [0.0; 3].map(|_: f32| 2.0 * rng.next() - 1.0);
            let base = p.len() as u32;
            for _ in 0..3 {
                p.push(std::array::from_fn(|i| c[i] + 0.2 * (rng.next() - 0.5)));
            }
            t.push([base, base + 1, base + 2]);
        }
        (p, t)
    }

    #[test]
    fn culled_nearest_hits_equal_testing_every_triangle() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let (p, t) = scene(40, 0.0, 12000, &mut rng);
        let mut eyes: Vec<[f32; 3]> = (0..300)
            .map(|_| [0.0; 3].map(|_: f32| 2.4 * rng.next() - 1.2))
            .collect();
        // Eyes on grid vertices and edges (rays along the plane), at a soup vertex, and on the
        // plane of a box face.
        eyes.extend([
            [0.0, 0.0, 0.0],
            [0.5, 0.0, -0.25],
            p[t[5000][0] as usize],
            [1.0, 0.3, 0.2],
        ]);
        for eye in eyes {
            let fast = nearest_hits(&p, &t, eye);
            let slow = nearest_hits_brute(&p, &t, eye);
            for k in 0..26 {
                assert_eq!(
                    (fast[k].triangle, fast[k].t.to_bits()),
                    (slow[k].triangle, slow[k].t.to_bits()),
                    "eye {eye:?}, ray {k}"
                );
            }
        }
    }
}
