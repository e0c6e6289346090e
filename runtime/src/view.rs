//! What a camera sees from where it stands, before any triangle is drawn: the ray through each
//! pixel (the film formula, written once for the rasterizer's coverage and a shader's view
//! directions), the checks of a mesh's indices, and whether the eye is inside an object, by
//! the rule the baker applies to a `--camera` view ([`prt_formats::view::judge_eye`]), here
//! with the 26 rays traced by brute force over all triangles (the runtime has no BVH; 26 rays
//! against ~100K triangles take milliseconds).

use prt_formats::view::{judge_eye, CameraFrame, EyeVerdict, EYE_TEST_DIRECTIONS};
use rayon::prelude::*;

use super::{MAX_IMAGE_SIDE, NO_TRIANGLE};

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
pub struct ViewRays {
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
    pub fn new(camera: &CameraFrame, width: u32, height: u32) -> Result<ViewRays, RasterError> {
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
    pub fn film(&self, x: f64, y: f64) -> (f64, f64) {
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
    pub fn direction(&self, x: f64, y: f64) -> [f64; 3] {
        let (sx, sy) = self.film(x, y);
        let d = self.world(sx, sy);
        let len = dot(d, d).sqrt();
        d.map(|c| c / len)
    }

    /// The unit view direction through the centre of pixel `(px, py)` (row 0 at the top).
    pub fn pixel_direction(&self, px: u32, py: u32) -> [f32; 3] {
        self.direction(f64::from(px) + 0.5, f64::from(py) + 0.5)
            .map(|c| c as f32)
    }

    /// The eye position.
    pub fn eye(&self) -> [f64; 3] {
        self.position
    }
}

/// Refuses vertex indices out of range and more triangles than a `u32` can name.
pub(super) fn check_indices(vertices: usize, triangles: &[[u32; 3]]) -> Result<(), RasterError> {
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
pub(super) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product (f64).
pub(super) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
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
pub fn eye_verdict(
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

    let nearest = triangles
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(c, tris)| {
            let mut best = [Hit::NONE; 26];
            for (i, tri) in tris.iter().enumerate() {
                let t = (c * CHUNK + i) as u32;
                hit_all(tri.map(|v| positions[v as usize]), eye, t, &mut best);
            }
            best
        })
        // The nearest of two hits, ties to the lower triangle: the same in any grouping.
        .reduce(
            || [Hit::NONE; 26],
            |a, b| std::array::from_fn(|k| if b[k].before(&a[k]) { b[k] } else { a[k] }),
        );
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

/// The nearest hit so far along one of the 26 rays.
#[derive(Clone, Copy)]
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

/// Moller-Trumbore of one triangle against the 26 rays from `eye`, keeping the nearest hit of
/// each. What depends only on the triangle and the eye is computed once.
fn hit_all(p: [[f32; 3]; 3], eye: [f32; 3], triangle: u32, best: &mut [Hit; 26]) {
    let e1 = sub(p[1], p[0]);
    let e2 = sub(p[2], p[0]);
    let s = sub(eye, p[0]);
    let q = cross32(s, e1);
    let t_num = dot32(e2, q);
    for (k, dir) in EYE_TEST_DIRECTIONS.iter().enumerate() {
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
