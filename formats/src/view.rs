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

impl CameraFrame {
    /// This camera turned `deg` degrees about the world's +Y axis through the origin (the
    /// right-hand rule, as environment rotations: `lighting::cubemap::rotation_y`): an orbit
    /// step, a view-only change.
    pub fn orbited(&self, deg: f32) -> CameraFrame {
        let m = crate::lighting::cubemap::rotation_y(f64::from(deg));
        let turn = |v: [f32; 3]| -> [f32; 3] {
            let v = v.map(f64::from);
            std::array::from_fn(|i| (m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2]) as f32)
        };
        CameraFrame {
            position: turn(self.position),
            forward: turn(self.forward),
            right: turn(self.right),
            up: turn(self.up),
            yfov: self.yfov,
        }
    }
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

/// The directions the eye-inside-geometry rule traces from the eye: the 26 neighbours of a cube's
/// centre (its 6 faces, 12 edges and 8 corners), normalized, in the order of `dx`, `dy`, `dz`
/// in {-1, 0, 1} (`dx` slowest, (0, 0, 0) skipped). Each component is exactly what `f32`
/// normalization (`v * (1 / |v|)`) gives, so a tracer that builds them itself traces the same
/// rays.
pub const EYE_TEST_DIRECTIONS: [[f32; 3]; 26] = eye_test_directions();

/// At least this many of the 26 [`EYE_TEST_DIRECTIONS`] must meet the back of a surface first
/// for the eye to count as inside an object ([`judge_eye`]).
pub const EYE_INSIDE_MIN_BACK: usize = 22;

/// `1 / sqrt(3)` rounded to `f32`, which is also `1.0f32 / 3.0f32.sqrt()` (a unit test checks).
const FRAC_1_SQRT_3: f32 = 0.577_350_26;

const fn eye_test_directions() -> [[f32; 3]; 26] {
    let mut out = [[0.0f32; 3]; 26];
    let (mut k, mut i) = (0i32, 0usize);
    while k < 27 {
        let d = [k / 9 - 1, k / 3 % 3 - 1, k % 3 - 1];
        let nonzero = (d[0] != 0) as usize + (d[1] != 0) as usize + (d[2] != 0) as usize;
        if nonzero > 0 {
            let s = [1.0, std::f32::consts::FRAC_1_SQRT_2, FRAC_1_SQRT_3][nonzero - 1];
            out[i] = [d[0] as f32 * s, d[1] as f32 * s, d[2] as f32 * s];
            i += 1;
        }
        k += 1;
    }
    out
}

/// What the [`EYE_TEST_DIRECTIONS`] traced from an eye met ([`judge_eye`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EyeVerdict {
    /// True when at least [`EYE_INSIDE_MIN_BACK`] of the directions met a back side first: the
    /// eye is inside an object and the view should be refused.
    pub inside: bool,
    /// Directions whose first hit was a back side (of a material below the material count).
    pub back: usize,
    /// Directions traced (26).
    pub total: usize,
    /// The material most often seen from behind (ties to the lowest index), `None` when no
    /// direction met a back side.
    pub material: Option<usize>,
    /// Back-side hits per material index.
    pub back_by_material: Vec<usize>,
}

/// The eye-inside-geometry rule, shared by the baker (BVH) and the runtime (brute force) so
/// both refuse the same views. From inside a closed object every direction meets a surface from
/// behind (its interpolated normal points away from the eye); an eye in the open, or in a room
/// whose walls face inwards, sees front sides, and a thin sheet or an open mesh behind the eye
/// cannot fool a majority of directions.
///
/// `first_hit(direction)` traces one of the [`EYE_TEST_DIRECTIONS`] from the eye and returns
/// the material index of the first surface met and whether it was seen from behind, or `None`
/// when the ray escapes. Back hits on a material index `>= material_count` are not counted.
pub fn judge_eye(
    material_count: usize,
    mut first_hit: impl FnMut([f32; 3]) -> Option<(usize, bool)>,
) -> EyeVerdict {
    let mut back_by_material = vec![0usize; material_count];
    for dir in EYE_TEST_DIRECTIONS {
        if let Some((material, true)) = first_hit(dir) {
            if let Some(count) = back_by_material.get_mut(material) {
                *count += 1;
            }
        }
    }
    let back: usize = back_by_material.iter().sum();
    let total = EYE_TEST_DIRECTIONS.len();
    let material = (0..material_count)
        .filter(|&m| back_by_material[m] > 0)
        .max_by_key(|&m| (back_by_material[m], std::cmp::Reverse(m)));
    EyeVerdict {
        inside: back >= EYE_INSIDE_MIN_BACK,
        back,
        total,
        material,
        back_by_material,
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
    fn an_orbit_turns_the_whole_frame_about_y() {
        let f = "eye=0,1,5 target=0,1,0 fov=30"
            .parse::<CameraSpec>()
            .expect("parse")
            .frame()
            .expect("frame");
        // Right-hand rule about +Y: +Z goes to +X.
        let g = f.orbited(90.0);
        let near = |a: [f32; 3], b: [f32; 3]| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-6);
        assert!(near(g.position, [5.0, 1.0, 0.0]), "{:?}", g.position);
        assert!(near(g.forward, [-1.0, 0.0, 0.0]), "{:?}", g.forward);
        assert!(near(g.up, f.up) && g.yfov == f.yfov);
        let h = f.orbited(30.0).orbited(60.0);
        for (a, b) in [(h.position, g.position), (h.right, g.right)] {
            assert!(near(a, b), "{a:?} {b:?}");
        }
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

    #[test]
    fn eye_test_directions_are_the_normalized_cube_neighbours() {
        let mut i = 0;
        for dx in -1i32..=1 {
            for dy in -1i32..=1 {
                for dz in -1i32..=1 {
                    if (dx, dy, dz) == (0, 0, 0) {
                        continue;
                    }
                    let v = [dx as f32, dy as f32, dz as f32];
                    // What f32 normalization computes: v * (1 / sqrt(v . v)).
                    let inv = 1.0 / dot(v, v).sqrt();
                    let want = v.map(|c| c * inv);
                    assert_eq!(EYE_TEST_DIRECTIONS[i], want, "direction {i}");
                    i += 1;
                }
            }
        }
        assert_eq!(i, 26);
    }

    #[test]
    fn the_eye_rule_counts_back_sides_per_material() {
        // 22 back hits: inside; material 2 is seen from behind 12 times, 1 and 3 five times.
        let mut n = 0;
        let v = judge_eye(4, |_| {
            n += 1;
            match n {
                1..=12 => Some((2, true)),
                13..=17 => Some((3, true)),
                18..=22 => Some((1, true)),
                23 => Some((0, false)),
                24 => Some((7, true)), // no such material: not counted
                _ => None,
            }
        });
        assert_eq!(n, 26);
        assert!(v.inside);
        assert_eq!((v.back, v.total, v.material), (22, 26, Some(2)));
        assert_eq!(v.back_by_material, vec![0, 5, 12, 5]);
        // 21 back hits (11 of material 1, 10 of material 2): outside.
        let mut n = 0;
        let v = judge_eye(3, |_| {
            n += 1;
            (n <= 21).then_some((2 - n % 2, true))
        });
        assert!(!v.inside);
        assert_eq!((v.back, v.material), (21, Some(1)));
        // 22 back hits, 11 each of materials 1 and 2: inside, the tie goes to the lowest index.
        let mut n = 0;
        let v = judge_eye(3, |_| {
            n += 1;
            (n <= 22).then_some((2 - n % 2, true))
        });
        assert!(v.inside);
        assert_eq!((v.back, v.material), (22, Some(1)));
        // Nothing behind: no material.
        let v = judge_eye(3, |_| Some((0, false)));
        assert!(!v.inside);
        assert_eq!((v.back, v.material), (0, None));
    }
}
