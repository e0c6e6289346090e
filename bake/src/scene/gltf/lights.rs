//! glTF punctual lights (`KHR_lights_punctual`), placed by their node and read
//! radiometrically (docs/conventions.md, "Lights").

use glam::{Mat4, Vec3};
use gltf::khr_lights_punctual::Kind as LightKind;

use super::Loader;
use crate::scene::{PunctualLight, SceneError};

impl Loader<'_> {
    pub(super) fn light(
        &mut self,
        light: &gltf::khr_lights_punctual::Light,
        node: &gltf::Node,
        world: Mat4,
    ) -> Result<PunctualLight, SceneError> {
        let name = light.name().unwrap_or("unnamed");
        let path = self.path;
        let err = |m: String| SceneError::Invalid {
            path: path.to_path_buf(),
            message: format!("light {} ({name}): {m}", light.index()),
        };
        let color = Vec3::from_array(light.color());
        let intensity = light.intensity();
        if !color.is_finite() || color.min_element() < 0.0 {
            return Err(err(format!("color {color:?} must be finite and >= 0")));
        }
        if !intensity.is_finite() || intensity < 0.0 {
            return Err(err(format!(
                "intensity {intensity} must be finite and >= 0"
            )));
        }
        if light.range().is_some() {
            // Physically based transport has no cut-off; say so rather than silently differ.
            self.warnings.push(format!(
                "{}: light {} ({name}): `range` is ignored; intensity falls off as 1/d^2 \
                 without cut-off",
                self.path.display(),
                light.index()
            ));
        }
        let power = color * intensity;
        let position = world.transform_point3(Vec3::ZERO);
        let direction = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
        let need_direction = || {
            if direction == Vec3::ZERO || !direction.is_finite() {
                Err(err(format!(
                    "node {} has a degenerate transform, so the light has no direction",
                    node.index()
                )))
            } else {
                Ok(direction)
            }
        };
        Ok(match light.kind() {
            LightKind::Point => PunctualLight::Point {
                position,
                intensity: power,
            },
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let half_pi = std::f32::consts::FRAC_PI_2;
                if !(inner_cone_angle.is_finite()
                    && outer_cone_angle.is_finite()
                    && 0.0 <= inner_cone_angle
                    && inner_cone_angle <= outer_cone_angle
                    && outer_cone_angle <= half_pi + 1e-6)
                {
                    return Err(err(format!(
                        "spot cone angles inner {inner_cone_angle}, outer {outer_cone_angle} \
                         must satisfy 0 <= inner <= outer <= pi/2"
                    )));
                }
                PunctualLight::Spot {
                    position,
                    direction: need_direction()?,
                    intensity: power,
                    inner_cone: inner_cone_angle,
                    outer_cone: outer_cone_angle.min(half_pi),
                }
            }
            LightKind::Directional => PunctualLight::Directional {
                direction: need_direction()?,
                irradiance: power,
            },
        })
    }
}
