//! What the light stage keeps (docs/vertex.md, section 4): the light coefficients of the
//! current map and turn with the per-group results, or, when a GPU backend runs the stage
//! (feature `gpu-surface`), only the unturned map's prefiltered cubes; and how the
//! coefficients reuse those cubes across turns.

use prt_formats::envmap::LatLongMap;
use prt_formats::lighting::{CubeMap, LightingError};

use super::incident::GroupLight;
use super::light::{self, LightCoefficients};

/// The light stage's results.
pub(super) enum LightState {
    /// The whole light stage ran here.
    Host {
        coefficients: Box<LightCoefficients>,
        groups: Vec<GroupLight>,
    },
    /// A device runs the light stage (`prepare_device_stages`): here only what is made once
    /// per map, the unturned map's prefiltered cubes.
    // Made and read only through the feature `gpu-surface`.
    #[cfg_attr(not(feature = "gpu-surface"), allow(dead_code))]
    Device {
        widths_deg: Vec<f64>,
        prefiltered: Vec<CubeMap>,
    },
}

impl LightState {
    /// The prefiltered cubes' widths (degrees).
    pub(super) fn widths_deg(&self) -> &[f64] {
        match self {
            LightState::Host { coefficients, .. } => &coefficients.widths_deg,
            LightState::Device { widths_deg, .. } => widths_deg,
        }
    }

    /// The unturned map's prefiltered cubes, one per width.
    #[cfg_attr(not(feature = "gpu-surface"), allow(dead_code))]
    pub(super) fn prefiltered(&self) -> &[CubeMap] {
        match self {
            LightState::Host { coefficients, .. } => &coefficients.prefiltered,
            LightState::Device { prefiltered, .. } => prefiltered,
        }
    }

    /// The coefficients and per-group results when the stage ran here.
    pub(super) fn host(&self) -> Option<(&LightCoefficients, &[GroupLight])> {
        match self {
            LightState::Host {
                coefficients,
                groups,
            } => Some((coefficients, groups)),
            LightState::Device { .. } => None,
        }
    }
}

/// The light coefficients of `map` turned `rotation_deg`, with the prefiltered cubes of
/// `widths` (nonzero, degrees) of the map **unturned** (`light::prefiltered`), computed
/// when `unturned` does not hold them yet, and kept there.
///
/// Why unturned: the prefilter is a convolution with a kernel that depends only on the angle
/// between directions, so it commutes with rotations: the prefiltered turned map at `d` is the
/// prefiltered map at `R_y(-rotation) d`. The view stage looks the cubes up there
/// (`shade::Environment::turned`), so a turn of the map, the common light edit, skips the
/// prefilter, which is most of the light stage's cost. The two differ only by where each
/// resamples (the cube texel grid is turned or the lookup is), within the bilinear lookup's
/// own error (`runtime` test `a_turned_lookup_matches_prefiltering_the_turned_map`); at
/// rotation 0 nothing changes.
pub(super) fn light_coefficients(
    map: &LatLongMap,
    rotation_deg: f32,
    widths: &[f64],
    unturned: &mut Option<Vec<CubeMap>>,
) -> Result<LightCoefficients, LightingError> {
    let mut base = LightCoefficients::from_latlong(map, f64::from(rotation_deg), &[])?;
    let prefiltered = match unturned {
        Some(cubes) => cubes.clone(),
        None if rotation_deg == 0.0 => {
            let cubes = light::prefiltered(&base.cube, widths)?;
            *unturned = Some(cubes.clone());
            cubes
        }
        None => unturned_prefiltered(map, widths, unturned)?,
    };
    base.widths_deg = widths.to_vec();
    base.prefiltered = prefiltered;
    Ok(base)
}

/// The prefiltered cubes of `map` unturned for `widths` (degrees), from `cache` or made and
/// kept there.
pub(super) fn unturned_prefiltered(
    map: &LatLongMap,
    widths: &[f64],
    cache: &mut Option<Vec<CubeMap>>,
) -> Result<Vec<CubeMap>, LightingError> {
    if let Some(cubes) = cache {
        return Ok(cubes.clone());
    }
    let cubes = light::prefiltered(&light::environment_cube(map, 0.0)?, widths)?;
    *cache = Some(cubes.clone());
    Ok(cubes)
}
