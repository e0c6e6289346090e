//! The irradiance of an environment at every normal,
//! `E(n) = integral L(w) max(0, w . n) dw`, tabulated on a small cube map of normals and read
//! back bilinearly ([`CubeMap::lookup_bilinear`]).
//!
//! Why (docs/vertex.md, "T0: the open sky exactly"): a per-vertex bake stores the light
//! arriving directly at a vertex as a few Haar terms of `(w . n) V(w)`. Kept to 96 of 24 576
//! terms, that sum loses the fine detail of the cosine, and under a map whose light comes
//! from a few small lamps the loss is a bias (the gallery's open floor came out 6.4 % too
//! dark). Splitting the row as `(w . n)+ - (w . n)+ (1 - V)` leaves the Haar terms only the
//! occluded part, which is zero where nothing blocks the sky, and takes the open-sky part
//! from this table, which is exact up to its quadrature and interpolation.
//!
//! # Accuracy
//!
//! Each output texel holds `E` at its centre normal, summed over the source cube's texels
//! (each texel's radiance times its exact solid angle times the clamped cosine at its
//! centre: the midpoint rule on the source grid). The irradiance is the environment
//! convolved with a clamped cosine, so it is smooth in the normal: its curvature is at most
//! that of `cos`, and bilinear interpolation between output centres `2 / size` radians apart
//! errs by about `(2 / size)^2 / 8` of the value (0.05 % at size 32) away from the
//! terminator; across it (the kink of the clamped cosine) the error is first order, 0.4 % of
//! the largest irradiance under a one-texel sun. The tests bound both against the exact sum
//! over a 6 x 64 x 64 source.

use super::cubemap::{face_solid_angles, texel_centre_direction, texel_index, CubeMap, Face};
use super::error::LightingError;

/// The output side the per-vertex runtime uses (6 x 32 x 32 normals).
pub const IRRADIANCE_CUBE: usize = 32;
/// The source side the per-vertex runtime sums over: the light's 6 x 64 x 64 cube halved
/// (each texel the exact mean of its four), a quarter of the work for 0.06 % of the peak
/// more error under a one-texel sun (the tests).
pub const IRRADIANCE_SOURCE: usize = 32;

/// The source texels premultiplied for the sum: directions and `L dOmega` as separate lanes.
pub struct IrradianceSource {
    dirs: [Vec<f32>; 3],
    weighted: [Vec<f32>; 3],
}

impl IrradianceSource {
    /// The texels of `cube` (any side), each with its centre direction and radiance times
    /// solid angle.
    pub fn new(cube: &CubeMap) -> IrradianceSource {
        let n = cube.size();
        let omega = face_solid_angles(n);
        let len = 6 * n * n;
        let mut dirs = [vec![0.0f32; len], vec![0.0f32; len], vec![0.0f32; len]];
        let mut weighted = [vec![0.0f32; len], vec![0.0f32; len], vec![0.0f32; len]];
        for face in Face::ALL {
            for j in 0..n {
                for i in 0..n {
                    let k = texel_index(n, face, i, j);
                    let d = texel_centre_direction(n, face, i, j);
                    let l = cube.texels()[k];
                    let w = omega[j * n + i];
                    for c in 0..3 {
                        dirs[c][k] = d[c] as f32;
                        weighted[c][k] = (f64::from(l[c]) * w) as f32;
                    }
                }
            }
        }
        IrradianceSource { dirs, weighted }
    }

    /// `E(n)` for a unit normal `n`: the midpoint-rule sum over the source texels.
    // Lanes and channels index several arrays in lockstep: plain index loops are the form the
    // compiler vectorizes and the clearest to read.
    #[allow(clippy::needless_range_loop)]
    pub fn irradiance(&self, n: [f32; 3]) -> [f32; 3] {
        // Eight partial sums per channel, so the loop vectorizes and rounding stays small.
        const LANES: usize = 8;
        let mut acc = [[0.0f32; LANES]; 3];
        let len = self.dirs[0].len();
        let whole = len - len % LANES;
        let cosine = |k: usize| {
            (self.dirs[0][k] * n[0] + self.dirs[1][k] * n[1] + self.dirs[2][k] * n[2]).max(0.0)
        };
        for base in (0..whole).step_by(LANES) {
            for lane in 0..LANES {
                let k = base + lane;
                let c = cosine(k);
                for ch in 0..3 {
                    acc[ch][lane] += c * self.weighted[ch][k];
                }
            }
        }
        let mut out = acc.map(|a| a.iter().sum::<f32>());
        for k in whole..len {
            let c = cosine(k);
            for ch in 0..3 {
                out[ch] += c * self.weighted[ch][k];
            }
        }
        out
    }

    /// One face of the irradiance cube of side `size` (row-major, [`texel_index`] order
    /// within the face): `E` at each output texel's centre normal.
    pub fn face(&self, size: usize, face: Face) -> Vec<[f32; 3]> {
        let mut out = Vec::with_capacity(size * size);
        for j in 0..size {
            for i in 0..size {
                let d = texel_centre_direction(size, face, i, j).map(|x| x as f32);
                out.push(self.irradiance(d));
            }
        }
        out
    }
}

/// The irradiance cube of side `size` of the environment `cube` (see the module
/// documentation); faces in storage order, computed one after another.
pub fn irradiance_cube(cube: &CubeMap, size: usize) -> Result<CubeMap, LightingError> {
    let source = IrradianceSource::new(cube);
    let mut texels = Vec::with_capacity(6 * size * size);
    for face in Face::ALL {
        texels.extend(source.face(size, face));
    }
    CubeMap::new(size, texels)
}

/// The per-vertex runtime's irradiance table of a light cube (side 64 or any even side at
/// least [`IRRADIANCE_SOURCE`]): the cube halved down to [`IRRADIANCE_SOURCE`], then
/// [`irradiance_cube`] of side [`IRRADIANCE_CUBE`].
pub fn irradiance_table(cube: &CubeMap) -> Result<CubeMap, LightingError> {
    let mut source = cube.clone();
    while source.size() > IRRADIANCE_SOURCE {
        source = source.downsample()?;
    }
    irradiance_cube(&source, IRRADIANCE_CUBE)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exact midpoint sum over `cube`'s texels in f64, the reference of the tests.
    fn exact(cube: &CubeMap, n: [f64; 3]) -> [f64; 3] {
        let s = cube.size();
        let omega = face_solid_angles(s);
        let mut e = [0.0f64; 3];
        for face in Face::ALL {
            for j in 0..s {
                for i in 0..s {
                    let d = texel_centre_direction(s, face, i, j);
                    let c = (d[0] * n[0] + d[1] * n[1] + d[2] * n[2]).max(0.0);
                    let l = cube.texels()[texel_index(s, face, i, j)];
                    for ch in 0..3 {
                        e[ch] += c * omega[j * s + i] * f64::from(l[ch]);
                    }
                }
            }
        }
        e
    }

    fn normals() -> Vec<[f64; 3]> {
        // A spiral over the sphere (no axis-aligned special cases) plus the axes.
        let mut v: Vec<[f64; 3]> = (0..200)
            .map(|k| {
                let z = 1.0 - 2.0 * (k as f64 + 0.5) / 200.0;
                let phi = k as f64 * 2.399_963;
                let r = (1.0 - z * z).sqrt();
                [r * phi.cos(), z, r * phi.sin()]
            })
            .collect();
        v.extend([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]);
        v
    }

    #[test]
    fn a_constant_sky_gives_pi_times_its_radiance_at_every_normal() {
        let cube = CubeMap::constant(64, [1.0, 2.0, 0.5]).unwrap();
        let irr = irradiance_cube(&cube, IRRADIANCE_CUBE).unwrap();
        for n in normals() {
            let e = irr.lookup_bilinear(n);
            for (ch, l) in [1.0f64, 2.0, 0.5].iter().enumerate() {
                let rel = (f64::from(e[ch]) - std::f64::consts::PI * l).abs()
                    / (std::f64::consts::PI * l);
                // The midpoint rule on a 64 grid against the true integral.
                assert!(rel < 2e-3, "normal {n:?} channel {ch}: {rel}");
            }
        }
    }

    #[test]
    fn lookups_match_the_exact_sum_under_a_sun() {
        // A dim sky, a warm horizon band and a one-texel sun off every axis: the hardest
        // case for the interpolation (the irradiance is a clamped cosine of the sun).
        let cube = CubeMap::from_fn(64, |d| {
            let sun = [0.3f64, 0.8, -0.52];
            let len = (sun[0] * sun[0] + sun[1] * sun[1] + sun[2] * sun[2]).sqrt();
            let c = (d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2]) / len;
            let band = if d[1].abs() < 0.1 { 2.0 } else { 0.2 };
            let v = if c > 0.9995 { 5000.0 } else { band };
            [v, 0.8 * v, 0.6 * v]
        })
        .unwrap();
        let irr = irradiance_cube(&cube, IRRADIANCE_CUBE).unwrap();
        let table = irradiance_table(&cube).unwrap();
        let source = IrradianceSource::new(&cube);
        let peak = normals()
            .iter()
            .map(|&n| exact(&cube, n)[0])
            .fold(0.0f64, f64::max);
        let mut worst = (0.0f64, 0.0f64);
        let mut table_worst = 0.0f64;
        for n in normals() {
            let e = exact(&cube, n);
            let direct = source.irradiance(n.map(|x| x as f32));
            let looked = irr.lookup_bilinear(n);
            for ch in 0..3 {
                let d = (f64::from(direct[ch]) - e[ch]).abs() / e[ch].max(1e-9);
                let l = (f64::from(looked[ch]) - e[ch]).abs() / peak;
                worst = (worst.0.max(d), worst.1.max(l));
                let t = (f64::from(table.lookup_bilinear(n)[ch]) - e[ch]).abs() / peak;
                table_worst = table_worst.max(t);
            }
        }
        // The f32 sum: rounding only. The lookup: the interpolation bound of the module
        // documentation, relative to the largest irradiance.
        assert!(worst.0 < 1e-4, "f32 sum vs exact: {}", worst.0);
        // Measured: 3.3e-3 from the 64 source, 3.9e-3 from the 32 one (the table's): the
        // interpolation across the terminator, where the clamped cosine has its kink.
        assert!(worst.1 < 4e-3, "lookup vs exact: {}", worst.1);
        assert!(table_worst < 5e-3, "table lookup vs exact: {table_worst}");
    }
}
