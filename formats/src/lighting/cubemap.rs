//! The cube map: 6 faces of N x N RGB texels, the direction of every texel, the exact solid
//! angle of every texel, resampling of lat-long environments (with a rotation about the up
//! axis), exact 2x downsampling and lookups. `docs/lighting.md` draws the layout.
//!
//! # Convention
//!
//! Faces are stored in the OpenGL order +X, -X, +Y, -Y, +Z, -Z ([`Face`]). Each face is an
//! image of N x N texels, row-major with the top row first: the layout of the texel array is
//! `[face][row t][column s]`. Within a face `s` grows to the right and `t` downwards, both in
//! `[0, 1]`; texel `(i, j)` (column i, row j) covers `[i/N, (i+1)/N] x [j/N, (j+1)/N]` and has
//! its centre at `((i + 0.5)/N, (j + 0.5)/N)`. With `a = 2s - 1` and `b = 2t - 1` the point
//! `(s, t)` of a face looks along (before normalization) the OpenGL cube-map directions:
//!
//! ```text
//! +X: ( 1, -b, -a)    -X: (-1, -b,  a)
//! +Y: ( a,  1,  b)    -Y: ( a, -1, -b)
//! +Z: ( a, -b,  1)    -Z: (-a, -b, -1)
//! ```
//!
//! The world is the lat-long map's: right-handed, +Y up (see [`crate::latlong`]).

use super::error::LightingError;
use crate::latlong;

/// The largest cube-map side accepted (6 x 4096^2 texels is 1.2 GB of RGB f32, and sparse
/// Haar indices must fit a u32).
pub const MAX_CUBE_SIZE: usize = 4096;

/// At most this many sub-samples per source texel when resampling a lat-long map (bounds the
/// work for maps of extreme aspect ratio; ordinary maps need far fewer).
const MAX_SUBSAMPLES_PER_SOURCE_TEXEL: usize = 16;

/// A face of the cube, in storage order (OpenGL's).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Face {
    /// The face centred on +X.
    PosX = 0,
    /// The face centred on -X.
    NegX = 1,
    /// The face centred on +Y (up).
    PosY = 2,
    /// The face centred on -Y (down).
    NegY = 3,
    /// The face centred on +Z.
    PosZ = 4,
    /// The face centred on -Z.
    NegZ = 5,
}

impl Face {
    /// All faces in storage order.
    pub const ALL: [Face; 6] = [
        Face::PosX,
        Face::NegX,
        Face::PosY,
        Face::NegY,
        Face::PosZ,
        Face::NegZ,
    ];

    /// The face's position in storage order (0..6).
    #[inline]
    pub fn index(self) -> usize {
        self as usize
    }

    /// The face at position `i` of the storage order, `None` for `i >= 6`.
    pub fn from_index(i: usize) -> Option<Face> {
        Face::ALL.get(i).copied()
    }

    /// The face's name, `"+X"` ... `"-Z"`.
    pub fn name(self) -> &'static str {
        ["+X", "-X", "+Y", "-Y", "+Z", "-Z"][self.index()]
    }
}

/// The unnormalized direction of face coordinates `(a, b) = (2s - 1, 2t - 1)` (the inverse of
/// [`direction_to_face_st`] on the face; beyond `[-1, 1]` the face's plane continued).
#[inline]
pub fn face_ab_to_vector(face: Face, a: f64, b: f64) -> [f64; 3] {
    match face {
        Face::PosX => [1.0, -b, -a],
        Face::NegX => [-1.0, -b, a],
        Face::PosY => [a, 1.0, b],
        Face::NegY => [a, -1.0, -b],
        Face::PosZ => [a, -b, 1.0],
        Face::NegZ => [-a, -b, -1.0],
    }
}

#[inline]
fn normalize(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / n, v[1] / n, v[2] / n]
}

/// The unit direction of the point `(s, t)` of a face (see the module documentation).
#[inline]
pub fn face_st_to_direction(face: Face, s: f64, t: f64) -> [f64; 3] {
    normalize(face_ab_to_vector(face, 2.0 * s - 1.0, 2.0 * t - 1.0))
}

/// The face and face coordinates `(s, t)` in `[0, 1]^2` of a direction (any length): the face
/// of the largest absolute component, the inverse of [`face_st_to_direction`].
///
/// Directions on a face edge (two or three components of equal magnitude) go to the face of
/// the first such axis in the order X, Y, Z, so the result is deterministic. A zero or
/// non-finite vector gives the centre of +X, `(Face::PosX, 0.5, 0.5)`.
#[inline]
pub fn direction_to_face_st(d: [f64; 3]) -> (Face, f64, f64) {
    let [x, y, z] = d;
    let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
    if !(ax.is_finite() && ay.is_finite() && az.is_finite())
        || (ax == 0.0 && ay == 0.0 && az == 0.0)
    {
        return (Face::PosX, 0.5, 0.5);
    }
    // Solve the table of the module documentation for (a, b), the major axis scaled to 1.
    let (face, a, b, major) = if ax >= ay && ax >= az {
        if x > 0.0 {
            (Face::PosX, -z, -y, ax)
        } else {
            (Face::NegX, z, -y, ax)
        }
    } else if ay >= az {
        if y > 0.0 {
            (Face::PosY, x, z, ay)
        } else {
            (Face::NegY, x, -z, ay)
        }
    } else if z > 0.0 {
        (Face::PosZ, x, -y, az)
    } else {
        (Face::NegZ, -x, -y, az)
    };
    let s = (0.5 * (a / major + 1.0)).clamp(0.0, 1.0);
    let t = (0.5 * (b / major + 1.0)).clamp(0.0, 1.0);
    (face, s, t)
}

/// The position of texel `(i, j)` (column i, row j) of `face` in a cube map of side `size`:
/// `(face * size + j) * size + i`. Indices are not checked.
#[inline]
pub fn texel_index(size: usize, face: Face, i: usize, j: usize) -> usize {
    (face.index() * size + j) * size + i
}

/// The face, column and row of the texel at storage position `index` of a cube map of side
/// `size` (`None` past the end or for size 0).
pub fn texel_at(size: usize, index: usize) -> Option<(Face, usize, usize)> {
    let per_face = size.checked_mul(size)?;
    if per_face == 0 {
        return None;
    }
    let face = Face::from_index(index / per_face)?;
    let r = index % per_face;
    Some((face, r % size, r / size))
}

/// The texel `(face, column i, row j)` of a cube map of side `size` whose square holds the
/// direction `d` (nearest lookup). Points on a texel edge go to the texel to their right or
/// below; `s = 1` or `t = 1` fall in the last column or row. A size of 0 is treated as 1.
#[inline]
pub fn direction_to_texel(size: usize, d: [f64; 3]) -> (Face, usize, usize) {
    let (face, s, t) = direction_to_face_st(d);
    face_st_to_texel(size, face, s, t)
}

/// [`direction_to_texel`] of the direction whose [`direction_to_face_st`] is `(face, s, t)`.
#[inline]
pub fn face_st_to_texel(size: usize, face: Face, s: f64, t: f64) -> (Face, usize, usize) {
    let n = size.max(1);
    let i = ((s * n as f64) as usize).min(n - 1);
    let j = ((t * n as f64) as usize).min(n - 1);
    (face, i, j)
}

/// The unit direction of the centre of texel `(i, j)` of `face` in a cube map of side `size`.
#[inline]
pub fn texel_centre_direction(size: usize, face: Face, i: usize, j: usize) -> [f64; 3] {
    let n = size.max(1) as f64;
    face_st_to_direction(face, (i as f64 + 0.5) / n, (j as f64 + 0.5) / n)
}

/// The signed solid angle, seen from the cube's centre, of the face rectangle between the face
/// centre `(0, 0)` and the point `(a, b)`: `atan(a b / sqrt(1 + a^2 + b^2))`, the integral of
/// `(1 + a^2 + b^2)^(-3/2)` (the solid angle per unit face area). Differences of it give any
/// rectangle's solid angle exactly.
#[inline]
fn corner_solid_angle(a: f64, b: f64) -> f64 {
    (a * b).atan2((1.0 + a * a + b * b).sqrt())
}

/// The exact solid angle (sr) of the rectangle `[a0, a1] x [b0, b1]` of a cube face in
/// coordinates `a = 2s - 1`, `b = 2t - 1` (each in `[-1, 1]`), seen from the cube's centre.
#[inline]
pub fn face_rect_solid_angle(a0: f64, a1: f64, b0: f64, b1: f64) -> f64 {
    corner_solid_angle(a1, b1) - corner_solid_angle(a0, b1) - corner_solid_angle(a1, b0)
        + corner_solid_angle(a0, b0)
}

/// The exact solid angle (sr) of texel `(i, j)` of a face of a cube map of side `size` (the
/// same on every face). The solid angles of all `6 size^2` texels sum to 4 pi. A size of 0 is
/// treated as 1.
pub fn texel_solid_angle(size: usize, i: usize, j: usize) -> f64 {
    let n = size.max(1) as f64;
    let edge = |k: usize| 2.0 * k as f64 / n - 1.0;
    face_rect_solid_angle(edge(i), edge(i + 1), edge(j), edge(j + 1))
}

/// The solid angles of the texels of one face of a cube map of side `size`, `[row j][column
/// i]` (every face has the same table). Computed from the `(size + 1)^2` corner values, so
/// neighbouring texels share their edges exactly. A size of 0 is treated as 1.
pub fn face_solid_angles(size: usize) -> Vec<f64> {
    sub_grid_solid_angles(size.max(1))
}

/// The solid angles of an `m x m` uniform grid of one face, `[row][column]`.
pub(crate) fn sub_grid_solid_angles(m: usize) -> Vec<f64> {
    let edge = |k: usize| 2.0 * k as f64 / m as f64 - 1.0;
    let mut out = Vec::with_capacity(m * m);
    let mut upper: Vec<f64> = (0..=m).map(|k| corner_solid_angle(edge(k), -1.0)).collect();
    for j in 0..m {
        let b1 = edge(j + 1);
        let lower: Vec<f64> = (0..=m).map(|k| corner_solid_angle(edge(k), b1)).collect();
        for i in 0..m {
            out.push(lower[i + 1] - upper[i + 1] - lower[i] + upper[i]);
        }
        upper = lower;
    }
    out
}

/// The rotation matrix (row-major, acting on column vectors) of `angle_deg` degrees about +Y
/// by the right-hand rule: counterclockwise seen from above, taking +Z towards +X and +X
/// towards -Z.
pub fn rotation_y(angle_deg: f64) -> [[f64; 3]; 3] {
    let (s, c) = angle_deg.to_radians().sin_cos();
    [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
}

/// `m v` for a row-major 3x3 matrix.
#[inline]
pub(crate) fn mat_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

/// Checks a cube-map side: at least 1 and at most [`MAX_CUBE_SIZE`].
pub(crate) fn check_size(size: usize) -> Result<(), LightingError> {
    if size == 0 {
        return Err(LightingError::ZeroSize {
            what: "cube-map side",
        });
    }
    if size > MAX_CUBE_SIZE {
        return Err(LightingError::TooLarge {
            what: "cube-map side",
            value: size,
            max: MAX_CUBE_SIZE,
        });
    }
    Ok(())
}

/// Checks that every channel of every texel is finite.
fn check_finite_rgb(what: &'static str, texels: &[[f32; 3]]) -> Result<(), LightingError> {
    for (index, t) in texels.iter().enumerate() {
        if let Some(&v) = t.iter().find(|v| !v.is_finite()) {
            return Err(LightingError::NonFinite {
                what,
                index,
                value: v as f64,
            });
        }
    }
    Ok(())
}

/// A cube map of RGB radiance (or any RGB quantity): `6 x size x size` texels, layout
/// `[face][row t][column s]` (see the module documentation). Every texel is finite.
#[derive(Clone, Debug, PartialEq)]
pub struct CubeMap {
    size: usize,
    texels: Vec<[f32; 3]>,
}

impl CubeMap {
    /// A cube map of side `size` from its texels in storage order (`6 size^2` of them, all
    /// finite).
    pub fn new(size: usize, texels: Vec<[f32; 3]>) -> Result<Self, LightingError> {
        check_size(size)?;
        let expected = 6 * size * size;
        if texels.len() != expected {
            return Err(LightingError::LengthMismatch {
                what: "cube-map texels",
                expected,
                got: texels.len(),
            });
        }
        check_finite_rgb("cube-map texels", &texels)?;
        Ok(CubeMap { size, texels })
    }

    /// A cube map of side `size` with every texel `value`.
    pub fn constant(size: usize, value: [f32; 3]) -> Result<Self, LightingError> {
        check_size(size)?;
        CubeMap::new(size, vec![value; 6 * size * size])
    }

    /// A cube map of side `size` holding `f` at each texel's centre direction (a point sample,
    /// not the texel average: for averages resample a lat-long map with
    /// [`CubeMap::from_latlong`]). Fails if `f` gives a non-finite value.
    pub fn from_fn(
        size: usize,
        mut f: impl FnMut([f64; 3]) -> [f64; 3],
    ) -> Result<Self, LightingError> {
        check_size(size)?;
        let mut texels = Vec::with_capacity(6 * size * size);
        for face in Face::ALL {
            for j in 0..size {
                for i in 0..size {
                    let v = f(texel_centre_direction(size, face, i, j));
                    texels.push([v[0] as f32, v[1] as f32, v[2] as f32]);
                }
            }
        }
        CubeMap::new(size, texels)
    }

    /// A cube map of side `size` from three single-channel planes in storage order.
    pub fn from_channels(
        size: usize,
        r: &[f32],
        g: &[f32],
        b: &[f32],
    ) -> Result<Self, LightingError> {
        check_size(size)?;
        let expected = 6 * size * size;
        for (what, c) in [
            ("red channel", r),
            ("green channel", g),
            ("blue channel", b),
        ] {
            if c.len() != expected {
                return Err(LightingError::LengthMismatch {
                    what,
                    expected,
                    got: c.len(),
                });
            }
        }
        let texels = (0..expected).map(|k| [r[k], g[k], b[k]]).collect();
        CubeMap::new(size, texels)
    }

    /// The side N of each face.
    #[inline]
    pub fn size(&self) -> usize {
        self.size
    }

    /// The texels in storage order, `[face][row t][column s]`.
    #[inline]
    pub fn texels(&self) -> &[[f32; 3]] {
        &self.texels
    }

    /// The texels in storage order, consuming the map.
    pub fn into_texels(self) -> Vec<[f32; 3]> {
        self.texels
    }

    /// Texel `(i, j)` (column, row) of `face`, `None` outside the face.
    pub fn get(&self, face: Face, i: usize, j: usize) -> Option<[f32; 3]> {
        if i >= self.size || j >= self.size {
            return None;
        }
        Some(self.texels[texel_index(self.size, face, i, j)])
    }

    /// One channel (0 red, 1 green, 2 blue) as a plane in storage order, the input of the Haar
    /// transform; `None` for a channel past 2.
    pub fn channel(&self, c: usize) -> Option<Vec<f32>> {
        if c >= 3 {
            return None;
        }
        Some(self.texels.iter().map(|t| t[c]).collect())
    }

    /// The integral over the sphere of the piecewise-constant function the map holds:
    /// `sum_t value_t * solid_angle_t` per channel (radiance * sr for a radiance map).
    pub fn integral(&self) -> [f64; 3] {
        let omega = face_solid_angles(self.size);
        let per_face = self.size * self.size;
        let mut sum = [0.0f64; 3];
        for (k, t) in self.texels.iter().enumerate() {
            let w = omega[k % per_face];
            for c in 0..3 {
                sum[c] += w * t[c] as f64;
            }
        }
        sum
    }

    /// Resamples an RGB lat-long map (`width x height`, row-major, row 0 the top, in the
    /// convention of [`crate::latlong`]) into a cube map of side `size`, rotating the
    /// environment by `rotation_deg` degrees about +Y.
    ///
    /// Each cube texel is the solid-angle-weighted average of [`latlong::lookup_bilinear`]
    /// over an `m x m` grid of sub-samples (sub-sample centres, weighted by their exact solid
    /// angles). `m` is the smallest count making the sub-sample pitch at a face centre
    /// (`2 / (size m)` radians, the coarsest on the face) no coarser than the source texel
    /// pitch at the equator (`min(pi / height, 2 pi / width)`), but at most 16 sub-samples
    /// per source texel overall. So a 512x256 map goes into 6x64x64 with 3x3 sub-samples and
    /// into 6x8x8 with 21x21.
    ///
    /// **Rotation sign.** Rotating by `+angle` turns the environment counterclockwise seen
    /// from above (the right-hand rule about +Y, [`rotation_y`]): what was seen in direction
    /// `d0` is afterwards seen in direction `R_y(angle) d0`. Equivalently, the radiance
    /// arriving from direction `d` is what arrived from `R_y(-angle) d` before. A source
    /// bright only towards -Z, rotated by +90 degrees, is bright towards -X.
    pub fn from_latlong(
        texels: &[[f32; 3]],
        width: usize,
        height: usize,
        size: usize,
        rotation_deg: f64,
    ) -> Result<Self, LightingError> {
        let resample = LatLongToCube::new(texels, width, height, size, rotation_deg)?;
        let mut out = Vec::with_capacity(6 * size * size);
        for face in Face::ALL {
            out.extend(resample.face(face));
        }
        CubeMap::new(size, out)
    }

    /// The cube map of half the side whose every texel is the solid-angle-weighted average of
    /// its 2x2 children, so the integral over the sphere ([`CubeMap::integral`]) is kept (to
    /// rounding). 6x64x64 halves to 6x32x32, and so on down to 6x1x1. Fails for an odd side.
    pub fn downsample(&self) -> Result<CubeMap, LightingError> {
        let n = self.size;
        if !n.is_multiple_of(2) {
            return Err(LightingError::OddSize { size: n });
        }
        let h = n / 2;
        let omega = face_solid_angles(n);
        let mut out = Vec::with_capacity(6 * h * h);
        for face in Face::ALL {
            for j in 0..h {
                for i in 0..h {
                    let mut acc = [0.0f64; 4];
                    for (di, dj) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (ci, cj) = (2 * i + di, 2 * j + dj);
                        let w = omega[cj * n + ci];
                        let v = self.texels[texel_index(n, face, ci, cj)];
                        acc[0] += w * v[0] as f64;
                        acc[1] += w * v[1] as f64;
                        acc[2] += w * v[2] as f64;
                        acc[3] += w;
                    }
                    out.push([
                        (acc[0] / acc[3]) as f32,
                        (acc[1] / acc[3]) as f32,
                        (acc[2] / acc[3]) as f32,
                    ]);
                }
            }
        }
        CubeMap::new(h, out)
    }

    /// The value of the texel holding direction `d` ([`direction_to_texel`]).
    pub fn lookup_nearest(&self, d: [f64; 3]) -> [f32; 3] {
        let (face, i, j) = direction_to_texel(self.size, d);
        self.texels[texel_index(self.size, face, i, j)]
    }

    /// The value in direction `d`, interpolated bilinearly between texel centres.
    ///
    /// The interpolation runs in the face coordinates of the face holding `d`. Within half a
    /// texel of a face edge the texels beyond the edge are taken from the neighbouring face:
    /// the face's texel grid is continued onto the plane beyond the edge and each missing
    /// texel is the one holding the direction of its continued centre. So the lookup is
    /// continuous across face edges (on an edge both faces blend the same two texels half
    /// and half). At a cube corner, where three faces meet, the missing fourth texel is one
    /// of the corner's texels (chosen by [`direction_to_texel`]).
    pub fn lookup_bilinear(&self, d: [f64; 3]) -> [f32; 3] {
        let (face, s, t) = direction_to_face_st(d);
        self.lookup_bilinear_face_st(face, s, t)
    }

    /// [`CubeMap::lookup_bilinear`] at the direction whose [`direction_to_face_st`] is
    /// `(face, s, t)`: for callers that look one direction up in several maps (or find its
    /// texel too) and convert it once.
    #[inline(always)]
    pub fn lookup_bilinear_face_st(&self, face: Face, s: f64, t: f64) -> [f32; 3] {
        let mut out = [0.0f64; 3];
        for (k, w) in bilinear_taps(self.size, face, s, t) {
            if w == 0.0 {
                continue;
            }
            let v = self.texels[k];
            for c in 0..3 {
                out[c] += w * v[c] as f64;
            }
        }
        out.map(|v| v as f32)
    }
}

/// The four texels (indices per [`texel_index`]) and weights of the bilinear interpolation
/// between texel centres of a cube of side `size` at `(face, s, t)` (from
/// [`direction_to_face_st`]), continued across face edges as [`CubeMap::lookup_bilinear`]
/// describes. The weights sum to 1. For any per-texel data laid out like a cube map (the
/// per-vertex visibility cubes, for one).
#[inline(always)]
pub fn bilinear_taps(size: usize, face: Face, s: f64, t: f64) -> [(usize, f64); 4] {
    let n = size;
    let nf = n as f64;
    // Texel centres sit at integers of fx, fy; both lie in [-0.5, n - 0.5].
    let (fx, fy) = (s * nf - 0.5, t * nf - 0.5);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - x0, fy - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let inside = |k: i64| k >= 0 && k < n as i64;
    [
        (0, 0, (1.0 - tx) * (1.0 - ty)),
        (1, 0, tx * (1.0 - ty)),
        (0, 1, (1.0 - tx) * ty),
        (1, 1, tx * ty),
    ]
    .map(|(di, dj, w)| {
        let (i, j) = (x0 + di, y0 + dj);
        let k = if inside(i) && inside(j) {
            texel_index(n, face, i as usize, j as usize)
        } else {
            let a = 2.0 * (i as f64 + 0.5) / nf - 1.0;
            let b = 2.0 * (j as f64 + 0.5) / nf - 1.0;
            let (f2, i2, j2) = direction_to_texel(n, face_ab_to_vector(face, a, b));
            texel_index(n, f2, i2, j2)
        };
        (k, w)
    })
}

/// The sub-sample count per side of a cube texel when resampling a `width x height` lat-long
/// map into side `size` (see [`CubeMap::from_latlong`]).
pub fn subsamples_per_texel(size: usize, width: usize, height: usize) -> usize {
    let (n, w, h) = (
        size.max(1) as f64,
        width.max(1) as f64,
        height.max(1) as f64,
    );
    let source_pitch = (std::f64::consts::PI / h).min(2.0 * std::f64::consts::PI / w);
    let needed = ((2.0 / n) / source_pitch).ceil().max(1.0);
    // Never more than MAX_SUBSAMPLES_PER_SOURCE_TEXEL sub-samples per source texel in all.
    let cap = (MAX_SUBSAMPLES_PER_SOURCE_TEXEL as f64 * w * h / (6.0 * n * n))
        .sqrt()
        .floor()
        .max(1.0);
    needed.min(cap) as usize
}

/// The resampling of [`CubeMap::from_latlong`], one face at a time, for callers that compute
/// the six faces in parallel: the same values bit for bit.
pub struct LatLongToCube<'a> {
    texels: &'a [[f32; 3]],
    width: usize,
    height: usize,
    size: usize,
    /// Sub-samples per texel side, and per face side.
    m: usize,
    ns: usize,
    /// The sub-sample grid's exact solid angles (the same on every face).
    weights: Vec<f64>,
    /// `R_y(-rotation)`: radiance arriving from d is the source's from `back d`.
    back: [[f64; 3]; 3],
}

impl<'a> LatLongToCube<'a> {
    /// The resampling of a `width x height` lat-long map to cube faces of side `size`, turned
    /// `rotation_deg` about +Y; refused as [`CubeMap::from_latlong`] refuses.
    pub fn new(
        texels: &'a [[f32; 3]],
        width: usize,
        height: usize,
        size: usize,
        rotation_deg: f64,
    ) -> Result<LatLongToCube<'a>, LightingError> {
        check_size(size)?;
        if width == 0 {
            return Err(LightingError::ZeroSize {
                what: "lat-long width",
            });
        }
        if height == 0 {
            return Err(LightingError::ZeroSize {
                what: "lat-long height",
            });
        }
        let expected = width.checked_mul(height).ok_or(LightingError::TooLarge {
            what: "lat-long width x height",
            value: width,
            max: usize::MAX / height,
        })?;
        if texels.len() != expected {
            return Err(LightingError::LengthMismatch {
                what: "lat-long texels",
                expected,
                got: texels.len(),
            });
        }
        check_finite_rgb("lat-long texels", texels)?;
        if !rotation_deg.is_finite() {
            return Err(LightingError::InvalidParameter {
                what: "rotation angle",
                expected: "finite",
                value: rotation_deg,
            });
        }

        let m = subsamples_per_texel(size, width, height);
        let ns = size * m;
        Ok(LatLongToCube {
            texels,
            width,
            height,
            size,
            m,
            ns,
            weights: sub_grid_solid_angles(ns),
            back: rotation_y(-rotation_deg),
        })
    }

    /// One face's `size x size` texels, row-major.
    pub fn face(&self, face: Face) -> Vec<[f32; 3]> {
        let (m, ns, size) = (self.m, self.ns, self.size);
        let centre = |k: usize| 2.0 * (k as f64 + 0.5) / ns as f64 - 1.0;
        let mut acc = vec![[0.0f64; 4]; size * size];
        for l in 0..ns {
            let b = centre(l);
            let row = (l / m) * size;
            for k in 0..ns {
                let d = mat_vec(&self.back, normalize(face_ab_to_vector(face, centre(k), b)));
                let v = latlong::lookup_bilinear(
                    self.texels,
                    self.width,
                    self.height,
                    [d[0] as f32, d[1] as f32, d[2] as f32],
                );
                let w = self.weights[l * ns + k];
                let a = &mut acc[row + k / m];
                a[0] += w * v[0] as f64;
                a[1] += w * v[1] as f64;
                a[2] += w * v[2] as f64;
                a[3] += w;
            }
        }
        acc.iter()
            .map(|a| {
                [
                    (a[0] / a[3]) as f32,
                    (a[1] / a[3]) as f32,
                    (a[2] / a[3]) as f32,
                ]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn close3(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
    }

    #[test]
    fn face_centres_and_axes() {
        let centres = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        for (face, c) in Face::ALL.into_iter().zip(centres) {
            assert!(close3(face_st_to_direction(face, 0.5, 0.5), c, 1e-15));
            assert_eq!(Face::from_index(face.index()), Some(face));
        }
        assert_eq!(Face::from_index(6), None);
    }

    #[test]
    fn inverse_mapping_round_trips_inside_faces() {
        for face in Face::ALL {
            for (s, t) in [(0.1, 0.2), (0.5, 0.5), (0.9, 0.3), (0.25, 0.99)] {
                let d = face_st_to_direction(face, s, t);
                let (f2, s2, t2) = direction_to_face_st(d);
                assert_eq!(f2, face);
                assert!((s - s2).abs() < 1e-12 && (t - t2).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn degenerate_directions_do_not_panic() {
        assert_eq!(direction_to_face_st([0.0; 3]), (Face::PosX, 0.5, 0.5));
        assert_eq!(
            direction_to_face_st([f64::NAN, 1.0, 0.0]),
            (Face::PosX, 0.5, 0.5)
        );
        assert_eq!(direction_to_texel(0, [0.0, 0.0, 1.0]), (Face::PosZ, 0, 0));
        // A corner shared by +X, +Y and +Z goes to +X (X before Y before Z).
        assert_eq!(direction_to_face_st([1.0, 1.0, 1.0]).0, Face::PosX);
        assert_eq!(direction_to_face_st([0.0, -1.0, -1.0]).0, Face::NegY);
    }

    #[test]
    fn solid_angles_sum_to_a_face() {
        for n in [1, 2, 3, 8, 64] {
            let total: f64 = face_solid_angles(n).iter().sum();
            assert!((total - 4.0 * PI / 6.0).abs() < 1e-13, "{n}: {total}");
            let one = texel_solid_angle(n, n / 2, 0);
            assert!((one - face_solid_angles(n)[n / 2]).abs() < 1e-15);
        }
    }

    #[test]
    fn odd_sides_cannot_halve_and_bad_input_is_refused() {
        let c = CubeMap::constant(3, [1.0; 3]).unwrap();
        assert_eq!(c.downsample(), Err(LightingError::OddSize { size: 3 }));
        assert!(matches!(
            CubeMap::new(2, vec![[0.0; 3]; 23]),
            Err(LightingError::LengthMismatch { .. })
        ));
        assert!(matches!(
            CubeMap::constant(0, [0.0; 3]),
            Err(LightingError::ZeroSize { .. })
        ));
        assert!(matches!(
            CubeMap::constant(1, [0.0, f32::NAN, 0.0]),
            Err(LightingError::NonFinite { index: 0, .. })
        ));
    }

    #[test]
    fn subsample_counts() {
        assert_eq!(subsamples_per_texel(64, 512, 256), 3);
        assert_eq!(subsamples_per_texel(8, 512, 256), 21);
        assert_eq!(subsamples_per_texel(64, 4, 2), 1);
        // Extreme aspect ratios stay bounded by the source size.
        let m = subsamples_per_texel(8, 1, 1_000_000);
        assert!(6 * (8 * m) * (8 * m) <= 16 * 1_000_000);
    }
}
