//! A view asked for on the command line (`--camera eye=.. target=.. fov=..`,
//! [`prt_formats::view`]): the scene camera it gives, and the check that the eye is not inside
//! an object, where every pixel would see the inside of one surface and the image would be
//! black or meaningless without any error.

use glam::Vec3;
use prt_formats::view::{judge_eye, CameraFrame};

use crate::accel::Accel;
use crate::scene::{Camera, Scene};

/// The scene camera of a validated `--camera` frame (the same frame the config's `[camera]`
/// table gives, so `reference` and `relight` render the same view).
pub fn camera_from_frame(frame: &CameraFrame) -> Camera {
    Camera {
        position: Vec3::from_array(frame.position),
        forward: Vec3::from_array(frame.forward),
        up: Vec3::from_array(frame.up),
        right: Vec3::from_array(frame.right),
        yfov: frame.yfov,
    }
}

/// Why a view cannot be rendered.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ViewError {
    /// The eye is enclosed by a surface (seen from behind in most directions).
    #[error(
        "the camera at ({:.4}, {:.4}, {:.4}) is inside `{material}`: {back} of {total} \
         directions from the eye meet the back of a surface first; move the eye out of the \
         object",
        eye.x,
        eye.y,
        eye.z
    )]
    InsideGeometry {
        /// The eye.
        eye: Vec3,
        /// The material most often seen from behind.
        material: String,
        /// Directions that met a back side first.
        back: usize,
        /// Directions tried.
        total: usize,
    },
}

/// Refuses an eye enclosed by geometry, by the rule baker and runtime share
/// ([`judge_eye`]): the 26 [`EYE_TEST_DIRECTIONS`](prt_formats::view::EYE_TEST_DIRECTIONS) are
/// traced from the eye, and the eye is inside when at least 22 of them meet a back side first
/// (the interpolated normal points away from the eye). An eye in the open, or in a room whose
/// walls face inwards, sees front sides; a thin sheet or an open mesh behind the eye cannot
/// fool a majority of directions.
pub fn check_eye_outside(scene: &Scene, accel: &Accel, eye: Vec3) -> Result<(), ViewError> {
    let verdict = judge_eye(scene.materials.len(), |d| {
        let dir = Vec3::from_array(d);
        let hit = accel.intersect(eye, dir, 0.0, f32::INFINITY)?;
        let tri = scene.triangles[hit.triangle as usize];
        let [na, nb, nc] = tri.map(|v| scene.normals[v as usize]);
        let n = na * (1.0 - hit.bary.x - hit.bary.y) + nb * hit.bary.x + nc * hit.bary.y;
        let material = scene.triangle_material[hit.triangle as usize] as usize;
        Some((material, n.dot(dir) > 0.0))
    });
    if verdict.inside {
        return Err(ViewError::InsideGeometry {
            eye,
            material: verdict
                .material
                .and_then(|m| scene.materials.get(m))
                .map_or_else(|| "?".to_string(), |m| m.name.clone()),
            back: verdict.back,
            total: verdict.total,
        });
    }
    Ok(())
}

/// What the centre of each pixel of a `width x height` image from the scene's camera sees
/// first: the material index of the nearest surface, or `None` where the ray escapes to the
/// environment. Row-major with y down, the pixel order of the reference's and relight's
/// images; the regions an error is split into (`bench budget`, the convergence tests).
pub fn first_hit_materials(scene: &Scene, width: u32, height: u32) -> Vec<Option<u32>> {
    let accel = Accel::build(scene);
    let lights = crate::lights::LightSet::new(scene);
    let integ = crate::integrator::Integrator::new(scene, &accel, &lights, 1, width, height);
    (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (o, d) = integ.camera_ray(x as f32 + 0.5, y as f32 + 0.5);
            accel
                .intersect(o, d, 0.0, f32::INFINITY)
                .map(|h| scene.triangle_material[h.triangle as usize])
        })
        .collect()
}
