//! The light coefficients of an environment for per-vertex relighting (docs/vertex.md,
//! sections 1 and 4): what the runtime computes once each time the light changes (a new map,
//! or a rotation of the current one), before touching any vertex.
//!
//! - the environment resampled (turned about +Y) into the cube map 6x64x64 that direct light
//!   is stored against, and its area-weighted Haar coefficients `C0` per channel, so that the
//!   direct light at a vertex is a sparse dot product with its stored terms;
//! - the exact 2x downsamplings to 6x8x8 (`C1`, one- reflection light) and 6x2x2 (`C2`,
//!   two reflections): the mean radiance over each coarse texel's solid angle, the
//!   coefficients of the environment's projection onto the coarse texels' box functions;
//! - the environment seen through the **normalized** Gaussians of the specular split, one cube
//!   per width (width 0: the 6x64x64 cube itself), read at mirror directions when shading.
//!
//! Everything here comes from `prt_formats::lighting`, the definitions the baker stores
//! transfer against.

use prt_formats::envmap::LatLongMap;
use prt_formats::lighting::cubemap::LatLongToCube;
use prt_formats::lighting::{prefilter, CubeMap, Face, HaarCube, LightingError};
use prt_formats::vertex::{DIRECT_CUBE, T1_LIGHT_CUBE, T2_LIGHT_CUBE};
use rayon::prelude::*;

use super::compact_lights::CompactLight;

/// The coefficients of one environment (see the module documentation).
#[derive(Debug, Clone)]
pub struct LightCoefficients {
    /// The environment as a 6 x [`DIRECT_CUBE`]^2 cube map (after its rotation).
    pub cube: CubeMap,
    /// `C0`: the area-weighted Haar coefficients of `cube`, `[red, green, blue]`.
    pub haar: [Vec<f32>; 3],
    /// `C1`: mean radiance per texel of the 6 x [`T1_LIGHT_CUBE`]^2 cube.
    pub one_bounce: CubeMap,
    /// `C2`: mean radiance per texel of the 6 x [`T2_LIGHT_CUBE`]^2 cube.
    pub two_bounce: CubeMap,
    /// The Gaussian widths (degrees) of `prefiltered`.
    pub widths_deg: Vec<f64>,
    /// Per width, the environment averaged over the normalized Gaussian about each
    /// direction: `integral G(angle(w, r)) L(w) dw / integral G dw`, on the prefilter's own
    /// cube size (width 0: `cube`).
    pub prefiltered: Vec<CubeMap>,
    /// The open sky's irradiance per normal (6 x 32 x 32, `open_sky`), when the bake needs
    /// it: vertices whose irradiance row is the occluded part, or a normal map (the view
    /// stage scales a pixel's irradiance by the open sky's at the bent normal over that at
    /// the interpolated one).
    pub open_sky: Option<CubeMap>,
    /// `C0` of the map less its compact lights (`compact_lights.rs`), which the glossy rows
    /// `U` read (the lights are shaded per pixel instead); `None`: they read `haar`.
    pub glossy_haar: Option<[Vec<f32>; 3]>,
    /// The compact lights taken out of `glossy_haar` and `prefiltered`, in the world's frame
    /// (after the rotation), their power times the intensity.
    pub compact_lights: Vec<CompactLight>,
}

impl LightCoefficients {
    /// The coefficients of `map` turned `rotation_deg` degrees about +Y (the right-hand rule;
    /// docs/conventions.md), with prefiltered cubes for the specular split's `widths_deg`.
    pub fn from_latlong(
        map: &LatLongMap,
        rotation_deg: f64,
        widths_deg: &[f64],
    ) -> Result<LightCoefficients, LightingError> {
        Self::from_cube(environment_cube(map, rotation_deg)?, widths_deg)
    }

    /// The coefficients of an environment already resampled to a 6 x [`DIRECT_CUBE`]^2 cube.
    pub fn from_cube(
        cube: CubeMap,
        widths_deg: &[f64],
    ) -> Result<LightCoefficients, LightingError> {
        if cube.size() != DIRECT_CUBE {
            return Err(LightingError::LengthMismatch {
                what: "cube-map side for per-vertex light (6 x 64 x 64)",
                expected: DIRECT_CUBE,
                got: cube.size(),
            });
        }
        let haar = HaarCube::new(DIRECT_CUBE)?.forward_cube(&cube)?;
        let mut one_bounce = cube.downsample()?;
        while one_bounce.size() > T1_LIGHT_CUBE {
            one_bounce = one_bounce.downsample()?;
        }
        let mut two_bounce = one_bounce.downsample()?;
        while two_bounce.size() > T2_LIGHT_CUBE {
            two_bounce = two_bounce.downsample()?;
        }
        let prefiltered = prefiltered(&cube, widths_deg)?;
        Ok(LightCoefficients {
            cube,
            haar,
            one_bounce,
            two_bounce,
            widths_deg: widths_deg.to_vec(),
            prefiltered,
            open_sky: None,
            glossy_haar: None,
            compact_lights: Vec::new(),
        })
    }
}

/// The environment `map` turned `rotation_deg` degrees about +Y as the 6 x [`DIRECT_CUBE`]^2
/// cube map direct light is stored against: `CubeMap::from_latlong`'s values bit for bit,
/// its six faces resampled in parallel (a light change's largest piece of work after the
/// prefilter).
pub(crate) fn environment_cube(
    map: &LatLongMap,
    rotation_deg: f64,
) -> Result<CubeMap, LightingError> {
    if !rotation_deg.is_finite() {
        return Err(LightingError::InvalidParameter {
            what: "environment rotation (degrees)",
            expected: "a finite number",
            value: rotation_deg,
        });
    }
    let resample = LatLongToCube::new(
        &map.texels,
        map.width,
        map.height,
        DIRECT_CUBE,
        rotation_deg,
    )?;
    let faces: Vec<Vec<[f32; 3]>> = Face::ALL
        .par_iter()
        .map(|&face| resample.face(face))
        .collect();
    CubeMap::new(DIRECT_CUBE, faces.concat())
}

/// The open sky's irradiance per normal of the light `cube` (6 x 64 x 64):
/// [`prt_formats::lighting::irradiance::irradiance_table`]'s values bit for bit, its six faces
/// computed in parallel.
pub(crate) fn open_sky(cube: &CubeMap) -> Result<CubeMap, LightingError> {
    use prt_formats::lighting::irradiance::{IrradianceSource, IRRADIANCE_CUBE, IRRADIANCE_SOURCE};
    let mut source = cube.clone();
    while source.size() > IRRADIANCE_SOURCE {
        source = source.downsample()?;
    }
    let source = IrradianceSource::new(&source);
    let faces: Vec<Vec<[f32; 3]>> = Face::ALL
        .par_iter()
        .map(|&face| source.face(IRRADIANCE_CUBE, face))
        .collect();
    CubeMap::new(IRRADIANCE_CUBE, faces.concat())
}

/// [`LightCoefficients::prefiltered`] of `cube` for `widths_deg` (width 0: `cube` itself):
/// every (width, face) computed on its own and in parallel, so the result does not depend on
/// the thread count.
pub(crate) fn prefiltered(
    cube: &CubeMap,
    widths_deg: &[f64],
) -> Result<Vec<CubeMap>, LightingError> {
    // The prefilter dominates a light change: its faces run in parallel (each face is
    // computed on its own, so the result does not depend on the thread count).
    let filters = widths_deg
        .iter()
        .map(|&w| {
            let sigma = w.to_radians();
            if sigma == 0.0 {
                return Ok(None);
            }
            // Never finer than the light's own cube: a width narrower than the cube's texels
            // (the split's spike, `ShadingBasis::spike_width_deg`) would otherwise be
            // prefiltered onto a finer cube that holds nothing the light does not.
            let size = prefilter::output_size(sigma)?.min(cube.size());
            Ok(Some(prefilter::Prefilter::new(cube, sigma, size)?))
        })
        .collect::<Result<Vec<_>, LightingError>>()?;
    let jobs: Vec<(usize, Face)> = filters
        .iter()
        .enumerate()
        .filter(|(_, f)| f.is_some())
        .flat_map(|(i, _)| Face::ALL.into_iter().map(move |face| (i, face)))
        .collect();
    let faces: Vec<Vec<[f32; 3]>> = jobs
        .par_iter()
        .map(|&(i, face)| filters[i].as_ref().map_or(Vec::new(), |f| f.face(face)))
        .collect();
    let mut faces = faces.into_iter();
    let mut out = Vec::with_capacity(widths_deg.len());
    for (&w, filter) in widths_deg.iter().zip(&filters) {
        let sigma = w.to_radians();
        let filtered = match filter {
            Some(f) => {
                let texels: Vec<[f32; 3]> = faces.by_ref().take(6).flatten().collect();
                CubeMap::new(f.size(), texels)?
            }
            None => cube.clone(),
        };
        let k = prefilter::kernel_integral(sigma)?;
        // Normalized: a constant environment stays that constant at every width.
        let scale = if sigma == 0.0 { 1.0 } else { 1.0 / k };
        let texels = filtered
            .texels()
            .iter()
            .map(|t| t.map(|c| (c as f64 * scale) as f32))
            .collect();
        out.push(CubeMap::new(filtered.size(), texels)?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn latlong(width: usize, height: usize, f: impl Fn(usize, usize) -> [f32; 3]) -> LatLongMap {
        let texels = (0..width * height)
            .map(|i| f(i % width, i / width))
            .collect();
        LatLongMap::new(width, height, texels, 1.0)
            .expect("valid map")
            .0
    }

    #[test]
    fn a_constant_environment_is_constant_in_every_coefficient() {
        let map = latlong(64, 32, |_, _| [0.5, 1.0, 2.0]);
        let c = LightCoefficients::from_latlong(&map, 37.0, &[0.0, 7.0, 14.0, 21.0])
            .expect("coefficients");
        for cube in [&c.cube, &c.one_bounce, &c.two_bounce]
            .into_iter()
            .chain(c.prefiltered.iter())
        {
            for t in cube.texels() {
                for (ch, want) in [0.5f32, 1.0, 2.0].into_iter().enumerate() {
                    assert!((t[ch] - want).abs() <= 2e-3 * want, "{t:?}");
                }
            }
        }
        assert_eq!(c.one_bounce.size(), T1_LIGHT_CUBE);
        assert_eq!(c.two_bounce.size(), T2_LIGHT_CUBE);
        // Parseval: the Haar coefficients carry the integral of L^2 over the sphere.
        for (ch, want) in [0.5f64, 1.0, 2.0].into_iter().enumerate() {
            let energy: f64 = c.haar[ch].iter().map(|&x| (x as f64) * (x as f64)).sum();
            let expect = want * want * 4.0 * std::f64::consts::PI;
            assert!(
                (energy - expect).abs() <= 1e-3 * expect,
                "{energy} vs {expect}"
            );
        }
    }

    #[test]
    fn coarse_light_keeps_the_integral_of_the_environment() {
        // A sky brighter above the horizon with a bright spot: the downsampled cubes hold
        // means over their texels, so the integral over the sphere is unchanged.
        let map = latlong(128, 64, |x, y| {
            let v = if y < 32 { 2.0 } else { 0.25 };
            let spot = if (40..44).contains(&x) && (10..13).contains(&y) {
                200.0
            } else {
                0.0
            };
            [v + spot, v, v + 0.5 * spot]
        });
        let c = LightCoefficients::from_latlong(&map, 0.0, &[]).expect("coefficients");
        let full = c.cube.integral();
        for coarse in [&c.one_bounce, &c.two_bounce] {
            let i = coarse.integral();
            for ch in 0..3 {
                assert!(
                    (i[ch] - full[ch]).abs() <= 1e-4 * full[ch],
                    "{i:?} vs {full:?}"
                );
            }
        }
    }

    #[test]
    fn the_rotation_turns_the_light() {
        // Bright only around -Z (the map's centre column); turned +90 degrees about +Y it
        // is bright around -X (docs/conventions.md).
        let map = latlong(64, 32, |x, y| {
            if (30..34).contains(&x) && (14..18).contains(&y) {
                [10.0; 3]
            } else {
                [0.0; 3]
            }
        });
        let c = LightCoefficients::from_latlong(&map, 90.0, &[]).expect("coefficients");
        let minus_x = c.cube.lookup_nearest([-1.0, 0.0, 0.0])[0];
        let minus_z = c.cube.lookup_nearest([0.0, 0.0, -1.0])[0];
        assert!(
            minus_x > 5.0 && minus_z < 1e-3,
            "-X {minus_x}, -Z {minus_z}"
        );
    }

    #[test]
    fn bad_input_is_refused() {
        let map = latlong(8, 4, |_, _| [1.0; 3]);
        assert!(LightCoefficients::from_latlong(&map, f64::NAN, &[]).is_err());
        assert!(LightCoefficients::from_latlong(&map, 0.0, &[-3.0]).is_err());
        let small = CubeMap::constant(8, [1.0; 3]).expect("cube");
        assert!(LightCoefficients::from_cube(small, &[]).is_err());
    }
}
