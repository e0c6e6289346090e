//! The camera the baker renders through: the glTF's first perspective camera, the config's
//! `[camera]`, or (for a bare glTF without a camera) one framing the scene's bounding box.
//! Conventions: docs/conventions.md, "Camera".

use glam::{Mat4, Vec3};

use super::Loader;
use crate::config::CameraConfig;
use crate::scene::{Camera, SceneError};

/// Vertical field of view of [`framing_camera`], degrees.
pub const FRAMING_FOV: f32 = 45.0;

/// The camera of a config `[camera]` table: a pinhole at `position` looking at `target`, +Y
/// up (re-orthogonalized): exactly the camera `--camera` gives for the same eye, target and
/// field of view (one frame, [`prt_formats::view::CameraSpec::frame`]). The config parser has
/// refused the tables this fails for (`position == target`, a vertical view, `fov` outside
/// (0, 180) degrees).
pub fn from_config(c: &CameraConfig) -> Result<Camera, prt_formats::view::CameraSpecError> {
    Ok(crate::view::camera_from_frame(&c.spec().frame()?))
}

/// A camera that sees all of `positions` (the scene's vertices) in an image of aspect ratio
/// `aspect` (width / height): it looks at the centre of their bounding box from the front (+Z)
/// and a little above, far enough back that the box's bounding sphere fits the narrower of the
/// two fields of view (with 5% margin), with [`FRAMING_FOV`]. No positions frame the unit
/// sphere about the origin.
pub fn framing_camera(positions: &[Vec3], aspect: f32) -> CameraConfig {
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let (centre, radius) = if lo.is_finite() && hi.is_finite() {
        let centre = (lo + hi) * 0.5;
        // Keep the camera distinguishable from its target even for a point-like scene far
        // from the origin.
        let floor = (centre.abs().max_element() * 1e-4).max(1e-3);
        (centre, ((hi - lo) * 0.5).length().max(floor))
    } else {
        (Vec3::ZERO, 1.0)
    };
    let aspect = if aspect.is_finite() && aspect > 0.0 {
        aspect
    } else {
        1.0
    };
    let half_vertical = 0.5 * FRAMING_FOV.to_radians();
    let half_horizontal = (half_vertical.tan() * aspect).atan();
    let half = half_vertical.min(half_horizontal);
    let distance = 1.05 * radius / half.sin();
    let from = Vec3::new(0.0, 0.35, 1.0).normalize();
    CameraConfig {
        position: centre + from * distance,
        target: centre,
        fov: FRAMING_FOV,
    }
}

impl Loader<'_> {
    pub(super) fn camera(
        &self,
        node: &gltf::Node,
        world: Mat4,
        yfov: f32,
    ) -> Result<Camera, SceneError> {
        let err = |m: &str| {
            self.invalid(format!(
                "camera on node {} ({}): {m}",
                node.index(),
                node.name().unwrap_or("unnamed")
            ))
        };
        if !(yfov.is_finite() && yfov > 0.0 && yfov < std::f32::consts::PI) {
            return Err(err(&format!("yfov {yfov} must be in (0, pi) radians")));
        }
        let position = world.transform_point3(Vec3::ZERO);
        let forward = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
        let up0 = world.transform_vector3(Vec3::Y);
        let right = forward.cross(up0).normalize_or_zero();
        if forward == Vec3::ZERO || right == Vec3::ZERO || !right.is_finite() {
            return Err(err("degenerate transform (zero scale or collapsed axes)"));
        }
        // Re-orthogonalize: node scales/shears must not skew the image plane.
        let up = right.cross(forward);
        Ok(Camera {
            position,
            forward,
            up,
            right,
            yfov,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_camera_sees_every_corner() {
        let pts = [Vec3::new(-1.0, 0.0, -2.0), Vec3::new(3.0, 2.0, 0.5)];
        for aspect in [0.5, 1.0, 2.0] {
            let cam = from_config(&framing_camera(&pts, aspect)).expect("a valid camera");
            assert!(cam.position.is_finite() && cam.forward.is_finite());
            let tan_v = (0.5 * cam.yfov).tan();
            for i in 0..8 {
                let corner = Vec3::new(
                    if i & 1 == 0 { -1.0 } else { 3.0 },
                    if i & 2 == 0 { 0.0 } else { 2.0 },
                    if i & 4 == 0 { -2.0 } else { 0.5 },
                );
                let d = corner - cam.position;
                let z = d.dot(cam.forward);
                assert!(z > 0.0);
                assert!(d.dot(cam.up).abs() / z < tan_v, "{aspect} {corner}");
                assert!(
                    d.dot(cam.right).abs() / z < tan_v * aspect,
                    "{aspect} {corner}"
                );
            }
        }
        let empty = framing_camera(&[], 1.0);
        assert!(empty.position.is_finite() && empty.position != empty.target);
    }
}
