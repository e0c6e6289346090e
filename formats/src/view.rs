//! The command-line camera syntax shared by the `reference` tool (baker) and the `relight`
//! tool (runtime), and the camera frame both derive from it, so a view asked of either tool is
//! the same view:
//!
//! ```text
//! --camera "eye=0,1.2,3.5 target=0,0.4,0 fov=40"
//! ```
//!
//! `eye` and `target` are world positions (metres, +Y up), `fov` the **vertical** field of
//! view in degrees, in (0, 180). Fields are separated by spaces or `;`, in any order, each once.
//! The camera is a pinhole at `eye` looking at `target` with +Y up (re-orthogonalized), the
//! frame the config's `[camera]` table gives (docs/conventions.md, "Camera"); a view straight
//! up or down has no such frame and is refused.

use std::fmt;
use std::str::FromStr;

/// A parsed and validated `--camera` argument.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraSpec {
    /// Position of the pinhole, world space.
    pub eye: [f32; 3],
    /// The point looked at, world space.
    pub target: [f32; 3],
    /// Vertical field of view, degrees, in (0, 180).
    pub fov_deg: f32,
}

/// The orthonormal frame of a [`CameraSpec`]: the camera looks along `forward`, `right` and
/// `up` span the image plane (image x grows along `right`, image y downward along `-up`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraFrame {
    /// Position of the pinhole.
    pub position: [f32; 3],
    /// Unit viewing direction.
    pub forward: [f32; 3],
    /// Unit vector to the image's right.
    pub right: [f32; 3],
    /// Unit vector to the image's top.
    pub up: [f32; 3],
    /// Vertical field of view, radians.
    pub yfov: f32,
}

/// Why a `--camera` argument was refused; the message quotes the argument.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CameraSpecError {
    /// A field is not `name=value`, or its name is unknown, or it is given twice.
    #[error("camera {spec:?}: {reason} (expected e.g. \"eye=0,1,3 target=0,0,0 fov=40\")")]
    Syntax {
        /// The whole argument.
        spec: String,
        /// What is wrong.
        reason: String,
    },
    /// A value does not parse or is not finite.
    #[error("camera {spec:?}: {field} = {value:?} is not {expected}")]
    Value {
        /// The whole argument.
        spec: String,
        /// The field (`eye`, `target`, `fov`).
        field: &'static str,
        /// Its text.
        value: String,
        /// What was expected.
        expected: &'static str,
    },
    /// The values parse but make no camera.
    #[error("camera {spec:?}: {reason}")]
    Invalid {
        /// The whole argument.
        spec: String,
        /// What is wrong.
        reason: String,
    },
}

fn parse_vec3(text: &str) -> Option<[f32; 3]> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return None;
    }
    let mut v = [0.0f32; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        *slot = p.parse::<f32>().ok().filter(|x| x.is_finite())?;
    }
    Some(v)
}

impl FromStr for CameraSpec {
    type Err = CameraSpecError;

    fn from_str(spec: &str) -> Result<Self, Self::Err> {
        let syntax = |reason: String| CameraSpecError::Syntax {
            spec: spec.to_string(),
            reason,
        };
        let (mut eye, mut target, mut fov) = (None, None, None);
        for field in spec
            .split(|c: char| c.is_whitespace() || c == ';')
            .filter(|f| !f.is_empty())
        {
            let Some((name, value)) = field.split_once('=') else {
                return Err(syntax(format!("{field:?} is not name=value")));
            };
            let value_err = |field: &'static str, expected: &'static str| CameraSpecError::Value {
                spec: spec.to_string(),
                field,
                value: value.to_string(),
                expected,
            };
            let slot_taken = match name.trim() {
                "eye" => eye
                    .replace(parse_vec3(value).ok_or_else(|| value_err("eye", "x,y,z"))?)
                    .is_some(),
                "target" => target
                    .replace(parse_vec3(value).ok_or_else(|| value_err("target", "x,y,z"))?)
                    .is_some(),
                "fov" => fov
                    .replace(
                        value
                            .trim()
                            .parse::<f32>()
                            .ok()
                            .filter(|x| x.is_finite())
                            .ok_or_else(|| value_err("fov", "a number of degrees"))?,
                    )
                    .is_some(),
                other => return Err(syntax(format!("unknown field {other:?}"))),
            };
            if slot_taken {
                return Err(syntax(format!("{} is given twice", name.trim())));
            }
        }
        let missing = |what: &str| syntax(format!("{what} is missing"));
        let camera = CameraSpec {
            eye: eye.ok_or_else(|| missing("eye"))?,
            target: target.ok_or_else(|| missing("target"))?,
            fov_deg: fov.ok_or_else(|| missing("fov"))?,
        };
        camera.frame().map(|_| camera)
    }
}

impl CameraSpec {
    /// The camera's frame, or why there is none: a field of view outside (0, 180) degrees,
    /// `eye == target`, or a view within about 0.1 degree of straight up or down (+Y is up, so
    /// the image's right would be undefined).
    pub fn frame(&self) -> Result<CameraFrame, CameraSpecError> {
        let invalid = |reason: String| CameraSpecError::Invalid {
            spec: self.to_string(),
            reason,
        };
        if !(self.fov_deg > 0.0 && self.fov_deg < 180.0) {
            return Err(invalid(format!(
                "fov {} must be in (0, 180) degrees",
                self.fov_deg
            )));
        }
        let d = [
            self.target[0] - self.eye[0],
            self.target[1] - self.eye[1],
            self.target[2] - self.eye[2],
        ];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if !(len > 0.0 && len.is_finite()) {
            return Err(invalid("eye and target must differ".into()));
        }
        let forward = [d[0] / len, d[1] / len, d[2] / len];
        // right = forward x +Y, then up = right x forward (as the config's camera).
        let r = [-forward[2], 0.0, forward[0]];
        let r_len = (r[0] * r[0] + r[2] * r[2]).sqrt();
        if r_len < 2e-3 {
            return Err(invalid(
                "the view is vertical (straight up or down): +Y is up, so give a target \
                 that is not directly above or below the eye"
                    .into(),
            ));
        }
        let right = [r[0] / r_len, 0.0, r[2] / r_len];
        let up = [
            right[1] * forward[2] - right[2] * forward[1],
            right[2] * forward[0] - right[0] * forward[2],
            right[0] * forward[1] - right[1] * forward[0],
        ];
        Ok(CameraFrame {
            position: self.eye,
            forward,
            right,
            up,
            yfov: self.fov_deg.to_radians(),
        })
    }
}

impl fmt::Display for CameraSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [a, b, c] = self.eye;
        let [x, y, z] = self.target;
        write!(f, "eye={a},{b},{c} target={x},{y},{z} fov={}", self.fov_deg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    #[test]
    fn parses_fields_in_any_order_and_separators() {
        let a: CameraSpec = "eye=0,1,3 target=0,0,0 fov=40".parse().expect("parse");
        let b: CameraSpec = " fov=40;target=0,0,0 ; eye=0,1,3 ".parse().expect("parse");
        assert_eq!(a, b);
        assert_eq!(a.eye, [0.0, 1.0, 3.0]);
        assert_eq!(a.fov_deg, 40.0);
        // Display round-trips.
        assert_eq!(a.to_string().parse::<CameraSpec>(), Ok(a));
    }

    #[test]
    fn frame_is_orthonormal_and_looks_at_the_target() {
        let c: CameraSpec = "eye=1,2,3 target=-0.5,0.2,0.1 fov=35"
            .parse()
            .expect("parse");
        let f = c.frame().expect("frame");
        for v in [f.forward, f.right, f.up] {
            assert!((dot(v, v) - 1.0).abs() < 1e-6);
        }
        assert!(dot(f.forward, f.right).abs() < 1e-6);
        assert!(dot(f.forward, f.up).abs() < 1e-6);
        assert!(dot(f.right, f.up).abs() < 1e-6);
        // Up is on +Y's side; right is horizontal; forward points at the target.
        assert!(f.up[1] > 0.0 && f.right[1] == 0.0);
        let d = [-1.5f32, -1.8, -2.9];
        let n = dot(d, d).sqrt();
        assert!((dot(f.forward, d) / n - 1.0).abs() < 1e-6);
        // Looking down -Z from +Z: right is +X (a right-handed image frame).
        let g = "eye=0,0,5 target=0,0,0 fov=30"
            .parse::<CameraSpec>()
            .expect("parse")
            .frame()
            .expect("frame");
        assert!((g.right[0] - 1.0).abs() < 1e-6 && (g.up[1] - 1.0).abs() < 1e-6);
        assert!((g.yfov - 30f32.to_radians()).abs() < 1e-7);
    }

    #[test]
    fn bad_cameras_are_refused_with_the_reason() {
        let cases = [
            ("eye=0,1,3 target=0,0,0", "fov is missing"),
            ("target=0,0,0 fov=40", "eye is missing"),
            ("eye=0,1,3 fov=40", "target is missing"),
            ("eye=0,1,3 target=0,0,0 fov=40 fov=30", "given twice"),
            ("eye=0,1 target=0,0,0 fov=40", "x,y,z"),
            ("eye=0,1,nan target=0,0,0 fov=40", "x,y,z"),
            ("eye=0,1,3 target=0,0,0 fov=abc", "degrees"),
            ("eye=0,1,3 target=0,0,0 fov=0", "(0, 180)"),
            ("eye=0,1,3 target=0,0,0 fov=180", "(0, 180)"),
            ("eye=0,1,3 target=0,0,0 fov=-5", "(0, 180)"),
            ("eye=0,1,3 target=0,1,3 fov=40", "must differ"),
            ("eye=0,5,0 target=0,0,0 fov=40", "vertical"),
            ("eye=0,1,3 target=0,0,0 zoom=2", "unknown field"),
            ("eye 0,1,3", "not name=value"),
            ("", "eye is missing"),
        ];
        for (text, want) in cases {
            let e = text
                .parse::<CameraSpec>()
                .expect_err(&format!("{text:?} must be refused"));
            let msg = e.to_string();
            assert!(msg.contains(want), "{text:?}: {msg}");
            assert!(
                msg.contains(text.trim()),
                "{text:?}: the message quotes it: {msg}"
            );
        }
    }
}
