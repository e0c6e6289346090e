//! The Gaussian prefilter of the specular-lobe split: an environment convolved with
//! `G_sigma(a) = exp(-a^2 / (2 sigma^2))`, `a` the angle to the lookup direction, on the cube
//! map and, in closed form per band, on spherical harmonics.
//!
//! # Definition
//!
//! `E(r) = integral G_sigma(angle(w, r)) L(w) dw`, **unnormalized**: its units are radiance *
//! sr, and a constant environment `L` gives `L * K(sigma)` with `K(sigma) =
//! integral G_sigma dw` ([`kernel_integral`]); divide by it for a weighted average. Width 0
//! means no filtering: `E = L`, the normalized limit `E / K` as sigma -> 0. For consistency
//! [`kernel_integral`] gives 1 and [`sh_factors`] gives 1 for every band at width 0, so
//! `E / K` and the SH relation below hold at every width.
//!
//! On spherical harmonics (Funk–Hecke) `E = sum_lm lambda_l c_lm Y_lm` with
//! `lambda_l = 2 pi integral_{-1}^{1} G_sigma(acos t) P_l(t) dt` ([`sh_factors`];
//! `lambda_0 = K`).
//!
//! # How the cube map is filtered, and how accurately
//!
//! The input cube map is a piecewise-constant function (each texel constant over its solid
//! angle), and `E` is its exact convolution. The output is a cube map of side `ceil(4 /
//! sigma)` by default ([`output_size`]: its texels are at most sigma / 2 across; 33, 17 and
//! 11 for 7, 14 and 21 degrees) holding `E` at each output texel's centre.
//!
//! * **Quadrature.** Every input texel is used at the input's resolution (never averaged
//!   into a coarser map first: that would move a point-like light by up to half a coarse
//!   texel, an error of first order). Texels wider than sigma / 4 (at a face centre) are split
//!   into `m x m` sub-samples with exact solid angles, so the points are at most sigma / 4
//!   apart. The width must be at least `1 / N` radians for an input of side N (half its
//!   texel pitch `2 / N`), so `m <= 8`; narrower lobes are refused
//!   ([`super::LightingError::WidthTooNarrow`]).
//! * **Kernel.** Truncated at [`CUTOFF_SIGMAS`] = 4 sigma (the dropped tail is `exp(-8)` =
//!   3.4e-4 of a narrow kernel's mass) and scaled by the ratio of the full to the truncated
//!   integral, so a constant environment loses nothing; tabulated in `u = 1 - cos(angle)`
//!   with linear interpolation (error < 1e-6 of the peak). Kernels reaching the antipode
//!   (widths above 45 degrees) are evaluated exactly.
//! * **Speed.** Points are grouped in tiles that are skipped as a whole when out of reach;
//!   the inner loop runs in f32 over lanes of 8 points. A 6x64x64 input takes about 0.2 s
//!   for 7 degrees and 0.05 s each for 14 and 21 degrees on one core of a shared machine
//!   (single-threaded; the result does not depend on any thread count).
//!
//! Measured on 6x64x64 inputs (the tests in `formats/tests/suite/lighting/prefilter.rs`
//! check these bounds with a margin), errors relative to the largest value:
//!
//! | case | 7 deg | 14 deg | 21 deg |
//! |---|---|---|---|
//! | constant environment vs `L K` | 1.2e-4 | 1.7e-4 | 0.9e-4 |
//! | SH band-limited environment vs `lambda_l` | 1.1e-4 | 2.8e-4 | 1.9e-4 |
//! | smooth sky vs exact `E` (16 sub-samples per texel, no truncation) | 0.7e-4 | 1.8e-4 | 1.5e-4 |
//! | one bright texel ("sun") vs exact `E` | 9.5e-4 | 9.1e-4 | 3.7e-4 |
//! | bilinear lookup between output centres, sun | 3.3e-2 | 1.3e-2 | 1.7e-2 |
//! | bilinear lookup between output centres, smooth sky | 0.7e-3 | 2.5e-3 | 7.2e-3 |
//!
//! The quadrature's error is that of the midpoint rule on the cube's texel grid (second
//! order in the point spacing). The lookup rows are the interpolation between output
//! centres sigma / 2 apart (`(sigma/2)^2 / (8 sigma^2)`, 3 % at a Gaussian peak); a caller
//! that needs less asks for a larger output with [`prefilter_to_size`].

use super::cubemap::{
    check_size, face_st_to_direction, sub_grid_solid_angles, texel_centre_direction, texel_index,
    CubeMap, Face,
};
use super::error::LightingError;
use super::quadrature::gauss_legendre;
use super::sh::SH_BANDS;
use std::f64::consts::PI;

/// The kernel is truncated at this many widths from the lookup direction.
pub const CUTOFF_SIGMAS: f64 = 4.0;

/// The widest quadrature spacing, in widths.
const QUADRATURE_PITCH_SIGMAS: f64 = 0.25;

/// The default output texel size, in widths.
const OUTPUT_PITCH_SIGMAS: f64 = 0.5;

/// Intervals of the kernel table in `cos(angle)`.
const TABLE_INTERVALS: usize = 4096;

/// The most quadrature points the filter keeps in memory (24 bytes each: 100 MB).
const MAX_POINTS: usize = 1 << 22;

/// Points processed together in the convolution's inner loop.
const LANES: usize = 8;

/// Tiles per face side for culling (each tile is skipped as a whole when it is out of reach).
const TILES_PER_SIDE: usize = 16;

/// The kernel `exp(-a^2 / (2 sigma^2))` at angle `a` (radians). At width 0 it is 1 at angle 0
/// and 0 elsewhere.
pub fn kernel(sigma: f64, angle: f64) -> f64 {
    if sigma == 0.0 {
        return if angle == 0.0 { 1.0 } else { 0.0 };
    }
    (-angle * angle / (2.0 * sigma * sigma)).exp()
}

fn check_sigma(sigma: f64) -> Result<(), LightingError> {
    if !sigma.is_finite() || sigma < 0.0 {
        return Err(LightingError::InvalidParameter {
            what: "Gaussian width (radians)",
            expected: "finite and >= 0",
            value: sigma,
        });
    }
    Ok(())
}

/// The narrowest width (radians) accepted for an input cube map of side `size`: `1 / size`,
/// half its texel pitch at a face centre (1.79 degrees / 2 = 0.9 degrees for side 64).
pub fn min_width(size: usize) -> f64 {
    1.0 / size.max(1) as f64
}

/// `lambda_l` for l = 0..3: `2 pi integral_0^pi G_sigma(a) P_l(cos a) sin a da`, by
/// composite Gauss–Legendre in the angle over `[0, min(pi, 12 sigma)]` (the kernel is below
/// 1e-31 beyond), f64, accurate to ~1e-14 relative. Width 0 gives 1 for every band (the
/// normalized limit, see the module documentation).
pub fn sh_factors(sigma: f64) -> Result<[f64; SH_BANDS], LightingError> {
    check_sigma(sigma)?;
    if sigma == 0.0 {
        return Ok([1.0; SH_BANDS]);
    }
    Ok(factors_up_to(sigma, (12.0 * sigma).min(PI)))
}

/// `2 pi integral_0^end G_sigma(a) P_l(cos a) sin a da` for l = 0..3 (sigma > 0): 64 panels
/// of 16-point Gauss–Legendre, each panel at most sigma / 5 wide for `end <= 12 sigma`.
fn factors_up_to(sigma: f64, end: f64) -> [f64; SH_BANDS] {
    let (x, w) = gauss_legendre(16);
    let panels = 64;
    let h = end / panels as f64;
    let mut out = [0.0; SH_BANDS];
    for p in 0..panels {
        let mid = (p as f64 + 0.5) * h;
        for (xi, wi) in x.iter().zip(&w) {
            let a = mid + 0.5 * h * xi;
            let t = a.cos();
            let f = 2.0 * PI * kernel(sigma, a) * a.sin() * 0.5 * h * wi;
            let legendre = [
                1.0,
                t,
                0.5 * (3.0 * t * t - 1.0),
                0.5 * (5.0 * t * t * t - 3.0 * t),
            ];
            for (o, pl) in out.iter_mut().zip(legendre) {
                *o += f * pl;
            }
        }
    }
    out
}

/// `K(sigma) = integral G_sigma dw` (sr), the value [`prefilter`] gives a constant
/// environment of 1 (`lambda_0` of [`sh_factors`]); 1 at width 0 (normalized limit).
pub fn kernel_integral(sigma: f64) -> Result<f64, LightingError> {
    Ok(sh_factors(sigma)?[0])
}

/// The default output side for width `sigma` > 0: `ceil(4 / sigma)`, the smallest side whose
/// texels are at most sigma / 2 across at a face centre. 33, 17 and 11 for 7, 14 and 21
/// degrees.
pub fn output_size(sigma: f64) -> Result<usize, LightingError> {
    check_sigma(sigma)?;
    if sigma == 0.0 {
        return Err(LightingError::InvalidParameter {
            what: "Gaussian width (radians) for an output size",
            expected: "> 0 (width 0 keeps the input's side)",
            value: sigma,
        });
    }
    let n = (2.0 / (OUTPUT_PITCH_SIGMAS * sigma)).ceil().max(1.0);
    let n = if n > super::cubemap::MAX_CUBE_SIZE as f64 {
        super::cubemap::MAX_CUBE_SIZE + 1
    } else {
        n as usize
    };
    check_size(n)?;
    Ok(n)
}

/// `E` for width `sigma` (radians) at the texel centres of a cube map of side
/// [`output_size`]`(sigma)`; width 0 returns the input itself. See the module documentation
/// for the definition (unnormalized) and the accuracy.
pub fn prefilter(cube: &CubeMap, sigma: f64) -> Result<CubeMap, LightingError> {
    check_sigma(sigma)?;
    if sigma == 0.0 {
        return Ok(cube.clone());
    }
    prefilter_to_size(cube, sigma, output_size(sigma)?)
}

/// [`prefilter`] with the output side chosen by the caller. At width 0 the output is the
/// input's bilinear lookup ([`CubeMap::lookup_bilinear`]) at each output texel centre, which
/// is the input itself when the sides agree.
pub fn prefilter_to_size(
    cube: &CubeMap,
    sigma: f64,
    size: usize,
) -> Result<CubeMap, LightingError> {
    check_sigma(sigma)?;
    check_size(size)?;
    if sigma == 0.0 {
        if size == cube.size() {
            return Ok(cube.clone());
        }
        return CubeMap::from_fn(size, |d| cube.lookup_bilinear(d).map(|v| v as f64));
    }
    let min = min_width(cube.size());
    if sigma < min {
        return Err(LightingError::WidthTooNarrow {
            sigma,
            size: cube.size(),
            pitch: 2.0 / cube.size() as f64,
            min,
        });
    }
    let p = Prefilter::new(cube, sigma, size)?;
    let mut texels = Vec::with_capacity(6 * size * size);
    for face in Face::ALL {
        texels.extend(p.face(face));
    }
    CubeMap::new(size, texels)
}

/// [`prefilter_to_size`] for widths > 0 one face at a time, so that a caller with threads can
/// compute the faces in parallel: `CubeMap::new(size, faces in Face::ALL order, concatenated)`
/// equals [`prefilter_to_size`]'s result bit for bit.
pub struct Prefilter {
    points: QuadraturePoints,
    table: KernelTable,
    size: usize,
}

impl Prefilter {
    /// The quadrature of `cube` for width `sigma` (radians, at least [`min_width`] of the
    /// cube's side) and an output side `size`.
    pub fn new(cube: &CubeMap, sigma: f64, size: usize) -> Result<Prefilter, LightingError> {
        check_sigma(sigma)?;
        check_size(size)?;
        let min = min_width(cube.size());
        if sigma == 0.0 || sigma < min {
            return Err(LightingError::WidthTooNarrow {
                sigma,
                size: cube.size(),
                pitch: 2.0 / cube.size() as f64,
                min,
            });
        }
        Ok(Prefilter {
            points: QuadraturePoints::new(cube, sigma)?,
            table: KernelTable::new(sigma),
            size,
        })
    }

    /// The output side.
    pub fn size(&self) -> usize {
        self.size
    }

    /// The prefiltered texels of one face, row after row.
    pub fn face(&self, face: Face) -> Vec<[f32; 3]> {
        let size = self.size;
        let mut texels = Vec::with_capacity(size * size);
        for j in 0..size {
            for i in 0..size {
                let r = texel_centre_direction(size, face, i, j);
                let e = self.points.convolve(&self.table, r);
                texels.push([e[0] as f32, e[1] as f32, e[2] as f32]);
            }
        }
        texels
    }
}

/// The kernel as a function of `u = 1 - cos(angle)` on `[0, 1 - cos(cutoff)]`, tabulated.
/// `u` is computed as half the squared chord `|r - w|^2 / 2`, which keeps its relative
/// precision in f32 near the lobe's centre (a cosine in f32 cannot resolve a narrow lobe:
/// 1 - 6e-8 is the closest value to 1). The kernel is a smooth function of u (`acos(1 -
/// u)^2` is analytic at u = 0), so linear interpolation is accurate: over the table `G`
/// falls by about `e^-8`, each interval spans about 1/500 of an e-folding, an interpolation
/// error below 1e-6 relative.
///
/// A kernel reaching the antipode (cutoff >= pi, widths above 45 degrees) is not tabulated
/// but evaluated exactly: `acos(1 - u)` has a square-root corner at u = 2 that linear
/// interpolation would blur (such wide kernels need few outputs and points anyway).
struct KernelTable {
    /// `Some(sigma)` when the kernel is evaluated exactly.
    exact: Option<f64>,
    u_cut: f32,
    inv_step: f32,
    /// `TABLE_INTERVALS + 1` samples and one more copy of the last, so that a clamped index
    /// can always read two neighbours (a fixed-size array: no bounds checks in the loop).
    values: Box<[f32; TABLE_INTERVALS + 2]>,
}

impl KernelTable {
    fn new(sigma: f64) -> Self {
        let cut = (CUTOFF_SIGMAS * sigma).min(PI);
        let u_cut = 2.0 * (0.5 * cut).sin().powi(2);
        let step = u_cut / TABLE_INTERVALS as f64;
        // The truncated kernel is scaled up to the full kernel's integral, so that a constant
        // (and any slowly varying) environment loses nothing to the truncation.
        let scale = if cut >= PI {
            1.0
        } else {
            factors_up_to(sigma, (12.0 * sigma).min(PI))[0] / factors_up_to(sigma, cut)[0]
        };
        let mut values = Box::new([0.0f32; TABLE_INTERVALS + 2]);
        for (k, v) in values.iter_mut().enumerate() {
            let u = k.min(TABLE_INTERVALS) as f64 * step;
            // acos(1 - u) = 2 asin(sqrt(u / 2)), exact for small u.
            let a = 2.0 * (0.5 * u).sqrt().min(1.0).asin();
            *v = (scale * kernel(sigma, a)) as f32;
        }
        KernelTable {
            exact: (cut >= PI).then_some(sigma),
            u_cut: u_cut as f32,
            inv_step: (1.0 / step) as f32,
            values,
        }
    }

    /// The tabulated G at `u = 1 - cos(angle)` (>= 0), 0 beyond the cutoff. Written without a
    /// branch (the index is clamped and the cutoff is a select) for the inner loop.
    #[inline(always)]
    fn at(&self, u: f32) -> f32 {
        let x = (u * self.inv_step).min(TABLE_INTERVALS as f32);
        // k = floor(x) for x in [0, TABLE_INTERVALS], by the 1.5 * 2^23 trick: the sum lies in
        // [2^23, 2^24), where f32 steps are 1, so its low mantissa bits hold 2^22 + round(x -
        // 0.5) (a saturating float-to-int cast costs more in this loop). At integers the tie
        // may round down, giving k = x - 1 and f = 1: the same value.
        let k = ((((x - 0.5 + 12_582_912.0).to_bits() & 0x007f_ffff) - 0x0040_0000) as usize)
            .min(TABLE_INTERVALS);
        let f = x - k as f32;
        let (v0, v1) = (self.values[k], self.values[k + 1]);
        let g = v0 + f * (v1 - v0);
        if u <= self.u_cut {
            g
        } else {
            0.0
        }
    }

    /// The exact G at `u = 1 - cos(angle)`, 0 beyond the cutoff.
    fn at_exact(&self, sigma: f64, u: f32) -> f32 {
        if u > self.u_cut {
            return 0.0;
        }
        let a = 2.0 * (0.5 * u.max(0.0) as f64).sqrt().min(1.0).asin();
        kernel(sigma, a) as f32
    }

    /// G at `u`, exact or tabulated.
    #[cfg(test)]
    fn eval(&self, u: f32) -> f32 {
        match self.exact {
            Some(sigma) => self.at_exact(sigma, u),
            None => self.at(u),
        }
    }
}

/// The quadrature points, structure of arrays (directions, and radiance times solid angle).
#[derive(Default)]
struct Points {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    r: Vec<f32>,
    g: Vec<f32>,
    b: Vec<f32>,
}

impl Points {
    fn len(&self) -> usize {
        self.x.len()
    }

    fn push(&mut self, d: [f64; 3], v: [f64; 3]) {
        self.x.push(d[0] as f32);
        self.y.push(d[1] as f32);
        self.z.push(d[2] as f32);
        self.r.push(v[0] as f32);
        self.g.push(v[1] as f32);
        self.b.push(v[2] as f32);
    }
}

/// A block of points on one face that is culled as a whole.
struct Tile {
    centre: [f64; 3],
    /// `cos` of (cutoff + the tile's angular radius); the tile is out of reach of a lookup
    /// direction whose cosine with the centre is below it.
    cos_reach: f64,
    start: usize,
    end: usize,
}

struct QuadraturePoints {
    points: Points,
    tiles: Vec<Tile>,
}

impl QuadraturePoints {
    fn new(cube: &CubeMap, sigma: f64) -> Result<Self, LightingError> {
        let pitch = QUADRATURE_PITCH_SIGMAS * sigma;
        // The input is used at its own resolution, never halved first: a coarser map would
        // move a point-like light (a sun) by up to half a coarse texel, an error of first order
        // in that offset (several percent of the peak for a halving at the quadrature pitch).
        let src = cube;
        let n = src.size();
        // Sub-samples per texel side so that their pitch is within the quadrature pitch; at
        // most 8 because sigma >= 1 / N. Sub-samples share their texel's value: the integral
        // is that of the piecewise-constant input.
        let m = ((2.0 / n as f64) / pitch).ceil().max(1.0) as usize;
        let ns = n * m;
        let total = 6 * ns * ns;
        if total > MAX_POINTS {
            return Err(LightingError::TooLarge {
                what: "prefilter quadrature point count",
                value: total,
                max: MAX_POINTS,
            });
        }
        let weights = sub_grid_solid_angles(ns);
        let tile = ns.div_ceil(TILES_PER_SIDE);
        let tiles_per_side = ns.div_ceil(tile);
        let cut = (CUTOFF_SIGMAS * sigma).min(PI);
        let texels = src.texels();
        let mut points = Points::default();
        let mut tiles = Vec::with_capacity(6 * tiles_per_side * tiles_per_side);
        let at = |face, k: f64, l: f64| face_st_to_direction(face, k / ns as f64, l / ns as f64);
        for face in Face::ALL {
            for ty in 0..tiles_per_side {
                for tx in 0..tiles_per_side {
                    let (k0, k1) = (tx * tile, ((tx + 1) * tile).min(ns));
                    let (l0, l1) = (ty * tile, ((ty + 1) * tile).min(ns));
                    let start = points.len();
                    for l in l0..l1 {
                        for k in k0..k1 {
                            let v = texels[texel_index(n, face, k / m, l / m)];
                            // Black texels add nothing (a sun-only sky is mostly black).
                            if v == [0.0; 3] {
                                continue;
                            }
                            let w = weights[l * ns + k];
                            let d = at(face, k as f64 + 0.5, l as f64 + 0.5);
                            points.push(d, v.map(|c| c as f64 * w));
                        }
                    }
                    if points.len() == start {
                        continue;
                    }
                    // Pad to whole lanes with points that add nothing.
                    while points.len() % LANES != 0 {
                        points.push([1.0, 0.0, 0.0], [0.0; 3]);
                    }
                    let centre = at(face, 0.5 * (k0 + k1) as f64, 0.5 * (l0 + l1) as f64);
                    // The tile is a spherical quadrilateral (its edges are great-circle arcs),
                    // so the cap about its centre through its farthest corner holds it all.
                    let radius = [(k0, l0), (k1, l0), (k0, l1), (k1, l1)]
                        .iter()
                        .map(|&(k, l)| angle_between(centre, at(face, k as f64, l as f64)))
                        .fold(0.0, f64::max);
                    // A small margin covers the f32 rounding of the points' directions.
                    let reach = cut + radius + 1e-5;
                    tiles.push(Tile {
                        centre,
                        cos_reach: if reach >= PI { -2.0 } else { reach.cos() },
                        start,
                        end: points.len(),
                    });
                }
            }
        }
        Ok(QuadraturePoints { points, tiles })
    }

    /// `sum_points G(angle(r, point)) value` per channel.
    fn convolve(&self, table: &KernelTable, r: [f64; 3]) -> [f64; 3] {
        let (rx, ry, rz) = (r[0] as f32, r[1] as f32, r[2] as f32);
        let p = &self.points;
        let mut acc = [0.0f64; 3];
        for tile in &self.tiles {
            let c = r[0] * tile.centre[0] + r[1] * tile.centre[1] + r[2] * tile.centre[2];
            if c < tile.cos_reach {
                continue;
            }
            let range = tile.start..tile.end;
            // Lanes of LANES points (tiles are padded with zero-valued points to whole lanes),
            // written as fixed-size array loops that the compiler turns into packed arithmetic;
            // only the table reads stay scalar.
            let chunks = p.x[range.clone()]
                .chunks_exact(LANES)
                .zip(p.y[range.clone()].chunks_exact(LANES))
                .zip(p.z[range.clone()].chunks_exact(LANES))
                .zip(p.r[range.clone()].chunks_exact(LANES))
                .zip(p.g[range.clone()].chunks_exact(LANES))
                .zip(p.b[range].chunks_exact(LANES));
            // Per tile in f32 (a tile holds at most a few hundred points), then in f64.
            let (mut sr, mut sg, mut sb) = ([0.0f32; LANES], [0.0f32; LANES], [0.0f32; LANES]);
            for (((((x, y), z), vr), vg), vb) in chunks {
                let mut u = [0.0f32; LANES];
                for l in 0..LANES {
                    // u = 1 - cos(angle), as half the squared chord (precise near the centre).
                    let (dx, dy, dz) = (rx - x[l], ry - y[l], rz - z[l]);
                    u[l] = 0.5 * (dx * dx + dy * dy + dz * dz);
                }
                let mut g = [0.0f32; LANES];
                match table.exact {
                    None => {
                        for l in 0..LANES {
                            g[l] = table.at(u[l]);
                        }
                    }
                    Some(sigma) => {
                        for l in 0..LANES {
                            g[l] = table.at_exact(sigma, u[l]);
                        }
                    }
                }
                for l in 0..LANES {
                    sr[l] += g[l] * vr[l];
                    sg[l] += g[l] * vg[l];
                    sb[l] += g[l] * vb[l];
                }
            }
            let part = [sr, sg, sb].map(|s| s.iter().sum::<f32>());
            for k in 0..3 {
                acc[k] += part[k] as f64;
            }
        }
        acc
    }
}

/// The angle between two unit vectors, accurate for small angles too.
fn angle_between(a: [f64; 3], b: [f64; 3]) -> f64 {
    let cross = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let sin = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
    let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    sin.atan2(cos)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_matches_the_kernel() {
        for deg in [1.0f64, 7.0, 14.0, 21.0, 60.0] {
            let sigma = deg.to_radians();
            let t = KernelTable::new(sigma);
            for k in 0..=1000 {
                let a = (CUTOFF_SIGMAS * sigma).min(PI) * k as f64 / 1000.0;
                let exact = kernel(sigma, a);
                let got = t.eval((2.0 * (0.5 * a).sin().powi(2)) as f32) as f64;
                // The table holds the kernel scaled by full / truncated integral (~1 + 3.4e-4).
                let cut = (CUTOFF_SIGMAS * sigma).min(PI);
                let scale = kernel_integral(sigma).unwrap() / factors_up_to(sigma, cut)[0];
                assert!((1.0..1.0 + 4e-4).contains(&scale), "{scale}");
                let exact = exact * scale;
                assert!((got - exact).abs() < 2e-6, "{deg} {a}: {got} vs {exact}");
            }
            let beyond = (CUTOFF_SIGMAS * sigma).min(PI - 0.01) + 0.01;
            if beyond < PI {
                assert_eq!(t.eval((1.0 - beyond.cos()) as f32), 0.0);
            }
        }
    }

    #[test]
    fn small_width_integral_is_planar() {
        // For a narrow kernel the sphere is locally a plane: K ~ 2 pi sigma^2 (1 - sigma^2/3).
        let sigma = 0.01;
        let k = kernel_integral(sigma).unwrap();
        let planar = 2.0 * PI * sigma * sigma * (1.0 - sigma * sigma / 3.0);
        assert!((k / planar - 1.0).abs() < 1e-6, "{k} vs {planar}");
        assert_eq!(sh_factors(0.0).unwrap(), [1.0; 4]);
        assert!(sh_factors(-1.0).is_err() && sh_factors(f64::NAN).is_err());
    }

    #[test]
    fn factors_match_an_independent_simpson_rule() {
        // lambda_l from composite Simpson (200 000 intervals in the angle, Python), 7 digits.
        let table = [
            (7.0f64, [9.331919e-2, 9.194005e-2, 8.924261e-2, 8.534411e-2]),
            (14.0, [3.677602e-1, 3.466532e-1, 3.080036e-1, 2.579561e-1]),
            (21.0, [8.072601e-1, 7.079473e-1, 5.444596e-1, 3.671875e-1]),
        ];
        for (deg, want) in table {
            let got = sh_factors(deg.to_radians()).unwrap();
            for l in 0..4 {
                assert!(
                    (got[l] / want[l] - 1.0).abs() < 2e-6,
                    "{deg} {l}: {}",
                    got[l]
                );
            }
        }
    }

    #[test]
    fn sizes_and_refusals() {
        assert_eq!(output_size(7f64.to_radians()).unwrap(), 33);
        assert_eq!(output_size(14f64.to_radians()).unwrap(), 17);
        assert_eq!(output_size(21f64.to_radians()).unwrap(), 11);
        assert!(output_size(0.0).is_err());
        assert!(output_size(1e-9).is_err());
        let c = CubeMap::constant(8, [1.0; 3]).unwrap();
        assert!(matches!(
            prefilter(&c, 0.1),
            Err(LightingError::WidthTooNarrow { size: 8, .. })
        ));
        assert!(prefilter(&c, 1.0 / 8.0).is_ok());
        assert_eq!(prefilter(&c, 0.0).unwrap(), c);
    }
}
