//! What the light stage keeps (docs/vertex.md, section 4): the light coefficients of the
//! current map and turn with the per-group results, or, when a GPU backend runs the stage
//! (feature `gpu-surface`), only the unturned map's prefiltered cubes; and how the
//! coefficients reuse those cubes across turns.

use prt_formats::envmap::LatLongMap;
use prt_formats::lighting::{CubeMap, LightingError};

use prt_formats::lighting::cubemap::rotation_y;
use prt_formats::lighting::HaarCube;
use prt_formats::vertex::DIRECT_CUBE;

use super::compact_lights::{self, Extraction};
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

/// The prefiltered cubes of the current map **unturned and at intensity 1**, made once per
/// map and kept: a turn or an intensity change of the map reuses them.
///
/// Why unturned: the prefilter is a convolution with a kernel that depends only on the angle
/// between directions, so it commutes with rotations: the prefiltered turned map at `d` is the
/// prefiltered map at `R_y(-rotation) d`. The view stage looks the cubes up there
/// (`shade::Environment::turned`), so a turn of the map, the common light edit, skips the
/// prefilter, which is most of the light stage's cost. The two differ only by where each
/// resamples (the cube texel grid is turned or the lookup is), within the bilinear lookup's
/// own error (`runtime` test `a_turned_lookup_matches_prefiltering_the_turned_map`); at
/// rotation 0 nothing changes.
///
/// Why at intensity 1: the prefilter is linear too, so the cubes of the map times `k` are the
/// cubes times `k` (an intensity slider moved in the viewer costs a multiply per texel, not a
/// prefilter of 0.3 to 0.7 s). Scaled by a power of two the result is the same bits.
#[derive(Default)]
pub(super) struct PrefilterCache {
    /// The cubes and whether they are of the map less its compact lights.
    cubes: Option<(bool, Vec<CubeMap>)>,
    /// The map (as set, before its intensity) split into its compact lights and the rest:
    /// found once per map, like the cubes.
    extraction: Option<Extraction>,
    /// How many times the prefilter ran (for the hooks' `prefilter_runs`).
    pub(super) runs: u64,
}

impl PrefilterCache {
    /// Forgets the cubes and the lights (the map changed).
    pub(super) fn clear(&mut self) {
        self.cubes = None;
        self.extraction = None;
    }

    /// `map` (as set, before its intensity) split into its compact lights and the rest,
    /// found when not kept yet.
    pub(super) fn extraction(&mut self, map: &LatLongMap) -> &Extraction {
        self.extraction
            .get_or_insert_with(|| compact_lights::extract(map))
    }

    /// The split found by [`PrefilterCache::extraction`], if kept.
    pub(super) fn kept_extraction(&self) -> Option<&Extraction> {
        self.extraction.as_ref()
    }

    /// The prefiltered cubes of `map` (as set, before its intensity; `compact`: less its
    /// compact lights) unturned for `widths` (degrees), times `intensity`; prefiltered only
    /// when not kept yet.
    pub(super) fn scaled(
        &mut self,
        map: &LatLongMap,
        widths: &[f64],
        intensity: f32,
        compact: bool,
    ) -> Result<Vec<CubeMap>, LightingError> {
        let cubes = match self.cubes.take() {
            Some((kept, cubes)) if kept == compact => cubes,
            _ => {
                self.runs += 1;
                let source = if compact {
                    &self.extraction(map).residual
                } else {
                    map
                };
                light::prefiltered(&light::environment_cube(source, 0.0)?, widths)?
            }
        };
        let out = if intensity == 1.0 {
            Ok(cubes.clone())
        } else {
            cubes
                .iter()
                .map(|c| {
                    let texels = c.texels().iter().map(|t| t.map(|v| v * intensity));
                    CubeMap::new(c.size(), texels.collect())
                })
                .collect()
        };
        self.cubes = Some((compact, cubes));
        out
    }
}

/// The light coefficients of `map` (the lighting map: the environment times its intensity)
/// turned `rotation_deg`, with `prefiltered`, the unturned cubes of the same light
/// ([`PrefilterCache::scaled`]); with `compact`, the environment's compact lights and the
/// rest (before the intensity, `intensity`): the lights turned into the world and the glossy
/// rows' Haar coefficients of the rest.
pub(super) fn light_coefficients(
    map: &LatLongMap,
    rotation_deg: f32,
    widths: &[f64],
    prefiltered: Vec<CubeMap>,
    compact: Option<(&Extraction, f32)>,
) -> Result<LightCoefficients, LightingError> {
    let mut base = LightCoefficients::from_latlong(map, f64::from(rotation_deg), &[])?;
    base.widths_deg = widths.to_vec();
    base.prefiltered = prefiltered;
    if let Some((extraction, intensity)) = compact.filter(|(e, _)| !e.lights.is_empty()) {
        let to_world = rotation_y(f64::from(rotation_deg));
        base.compact_lights = extraction
            .lights
            .iter()
            .map(|l| {
                let mut t = compact_lights::turned(l, &to_world);
                t.power = t.power.map(|p| p * intensity);
                t
            })
            .collect();
        // A copy only when the intensity scales it (a turn at intensity 1 resamples in place).
        let scaled;
        let rest = if intensity == 1.0 {
            &extraction.residual
        } else {
            let mut copy = extraction.residual.clone();
            copy.texels
                .iter_mut()
                .for_each(|t| *t = t.map(|v| v * intensity));
            scaled = copy;
            &scaled
        };
        let cube = light::environment_cube(rest, f64::from(rotation_deg))?;
        base.glossy_haar = Some(HaarCube::new(DIRECT_CUBE)?.forward_cube(&cube)?);
    }
    Ok(base)
}
