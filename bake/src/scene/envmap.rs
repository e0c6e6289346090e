//! The scene's lat-long environment map: loaded by [`prt_formats::envmap`] (shared with the
//! runtime, so both accept and refuse the same maps) and turned into
//! [`Environment::LatLong`].

use std::path::Path;

use glam::Vec3;
pub use prt_formats::envmap::{EnvMapError, EnvMapReport, MAX_ENV_SIDE};

use super::Environment;

/// Loads `path` (.exr or .hdr, by extension) as an [`Environment::LatLong`] scaled by
/// `intensity`. Errors do not repeat the file name; the caller adds it.
pub fn load_latlong(
    path: &Path,
    intensity: f32,
) -> Result<(Environment, EnvMapReport), EnvMapError> {
    let (map, report) = prt_formats::envmap::load_latlong(path, intensity)?;
    Ok((
        Environment::LatLong {
            width: map.width as u32,
            height: map.height as u32,
            texels: map.texels.into_iter().map(Vec3::from_array).collect(),
        },
        report,
    ))
}
