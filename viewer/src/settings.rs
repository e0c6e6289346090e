//! What one browser tab shows (its [`Settings`]: materials, tone, and for a per-vertex bake the
//! environment, camera and image size), the requests that change it, and their checks.
//!
//! A request names one control and its new value. It is checked against what the bake allows
//! ([`BakeInfo`]: the runtime's own material list and ranges, the environments offered) before
//! anything changes, and refused with a message naming the problem; an accepted request
//! changes exactly the setting it names. What only the relighter can judge (an eye inside an
//! object) is refused when the frame is rendered (`render.rs`).

use prt_formats::view::CameraSpec;
use prt_formats::ToneCurve;
use prt_runtime::{MaterialInfo, OverrideValue, Param};
use serde_json::{json, Value};

/// The largest image side a per-vertex view may ask for (the runtime takes up to 16384; a
/// browser canvas and one frame's 4 bytes per pixel make more than this pointless).
pub const MAX_SIDE: u32 = 4096;

/// The largest exposure multiplier accepted.
pub const MAX_EXPOSURE: f32 = 1e6;

/// The name of the environment a per-vertex bake was baked with, in the environment picker.
pub const BAKED_ENVIRONMENT: &str = "baked";

/// What the bake offers, found once at start: its materials with their ranges, its kind and
/// size, the environments a per-vertex view may pick.
#[derive(Clone, Debug)]
pub struct BakeInfo {
    /// The bake file as given on the command line.
    pub bake: String,
    /// The runtime's material list at open (baked values, ranges, editable or not).
    pub materials: Vec<MaterialInfo>,
    /// Per-vertex: the environments offered ([`BAKED_ENVIRONMENT`] first, then the folder's
    /// maps by file name); `None` for a per-pixel bake.
    pub environments: Option<Vec<String>>,
    /// The image size at open (per-pixel: fixed).
    pub size: (u32, u32),
    /// Why the reference toggle is off (no config given), or `None` when it works.
    pub reference_unavailable: Option<String>,
}

/// A per-vertex view: environment, camera, image size.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewSettings {
    /// [`BAKED_ENVIRONMENT`] or a map's file name in the environment folder.
    pub environment: String,
    /// Rotation about +Y, degrees (absolute).
    pub rotation: f32,
    /// Multiplier of the environment's radiance.
    pub intensity: f32,
    /// The camera (+Y up, as `relight --camera` takes it).
    pub camera: CameraSpec,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// A material's current values, one per parameter its family has, in [`Param::ALL`] order.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialValues {
    /// The material's name.
    pub name: String,
    /// Its parameters' values.
    pub values: Vec<OverrideValue>,
}

/// Everything a tab's frame depends on.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// Every material of the bake, in its order.
    pub materials: Vec<MaterialValues>,
    /// Linear multiplier before the tone curve.
    pub exposure: f32,
    /// The tone curve.
    pub tone: ToneCurve,
    /// Per-vertex: the view; `None` for a per-pixel bake.
    pub view: Option<ViewSettings>,
}

impl Settings {
    /// The settings a bake opens with: its materials at their baked values, exposure 1, the
    /// clamp curve, and per vertex `view` (the relighter's environment, camera and size).
    pub fn initial(info: &BakeInfo, view: Option<ViewSettings>) -> Settings {
        Settings {
            materials: info
                .materials
                .iter()
                .map(|m| MaterialValues {
                    name: m.name.clone(),
                    values: m.params.iter().map(|p| p.value).collect(),
                })
                .collect(),
            exposure: 1.0,
            tone: ToneCurve::Clamp,
            view,
        }
    }

    /// Whether a frame of `self` has the same pixels before tone mapping as one of `other`
    /// (only the exposure or the curve differ).
    pub fn same_render(&self, other: &Settings) -> bool {
        self.materials == other.materials && self.view == other.view
    }

    /// The settings as the page reads them.
    pub fn to_json(&self) -> Value {
        let materials: serde_json::Map<String, Value> = self
            .materials
            .iter()
            .map(|m| {
                let params: serde_json::Map<String, Value> = m
                    .values
                    .iter()
                    .map(|v| (v.param().name().to_string(), value_json(v)))
                    .collect();
                (m.name.clone(), Value::Object(params))
            })
            .collect();
        let view = self.view.as_ref().map(|v| {
            json!({
                "environment": v.environment,
                "rotation": v.rotation,
                "intensity": v.intensity,
                "camera": {
                    "eye": v.camera.eye,
                    "target": v.camera.target,
                    "fov": v.camera.fov_deg,
                },
                "width": v.width,
                "height": v.height,
            })
        });
        json!({
            "materials": materials,
            "exposure": self.exposure,
            "tone": self.tone.name(),
            "view": view,
        })
    }
}

/// A parameter's value as JSON (a colour as `[r, g, b]`).
pub fn value_json(v: &OverrideValue) -> Value {
    match *v {
        OverrideValue::Kd(c) | OverrideValue::Ks(c) => json!(c),
        OverrideValue::Shininess(x) | OverrideValue::Alpha(x) => json!(x),
        // A parameter the syntax knows but this viewer does not show.
        _ => Value::Null,
    }
}

/// A request of the page: one control and its new value, or the reference toggle.
#[derive(Clone, Debug, PartialEq)]
pub enum Request {
    /// Sets one parameter of one material.
    Material {
        /// The material.
        name: String,
        /// The parameter and its value.
        value: OverrideValue,
    },
    /// Sets the exposure.
    Exposure(f32),
    /// Sets the tone curve.
    Tone(ToneCurve),
    /// Per-vertex: picks an environment by name.
    Environment(String),
    /// Per-vertex: the environment's rotation, degrees.
    Rotation(f32),
    /// Per-vertex: the environment's intensity.
    Intensity(f32),
    /// Per-vertex: the camera.
    Camera(CameraSpec),
    /// Per-vertex: the image size.
    Size(u32, u32),
    /// Starts or stops the reference tracer beside the relit image.
    Reference(bool),
    /// How frames are sent: raw RGBA pixels or PNG.
    Encoding(Encoding),
}

/// How a frame's pixels travel to the page.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Encoding {
    /// 8-bit RGBA, 4 bytes per pixel, as a canvas takes them (the default: fastest on one
    /// machine, docs/viewer.md "Protocol").
    #[default]
    Raw,
    /// A PNG of the same bytes.
    Png,
}

impl Encoding {
    /// The encoding's name in the protocol.
    pub fn name(self) -> &'static str {
        match self {
            Encoding::Raw => "raw",
            Encoding::Png => "png",
        }
    }
}

/// A parsed message of the page: its sequence number (echoed in the frame or error that
/// answers it) and the request.
#[derive(Clone, Debug, PartialEq)]
pub struct Message {
    /// The page's number for the request (0 when it gave none).
    pub seq: u64,
    /// What it asks.
    pub request: Request,
}

/// Why a message was refused (shown to the user as it is).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Refusal(pub String);

fn refuse<T>(text: impl Into<String>) -> Result<T, Refusal> {
    Err(Refusal(text.into()))
}

/// A finite number field of `obj`, as f32 (refused when missing, not a number, or outside
/// what f32 holds).
fn number(obj: &serde_json::Map<String, Value>, key: &str, what: &str) -> Result<f32, Refusal> {
    let Some(v) = obj.get(key) else {
        return refuse(format!("{what}: missing field '{key}'"));
    };
    let Some(x) = v.as_f64() else {
        return refuse(format!("{what}: '{key}' must be a number, got {v}"));
    };
    let x32 = x as f32;
    if !x32.is_finite() {
        return refuse(format!(
            "{what}: '{key}' = {x} is not a finite 32-bit number"
        ));
    }
    Ok(x32)
}

fn vec3(obj: &serde_json::Map<String, Value>, key: &str, what: &str) -> Result<[f32; 3], Refusal> {
    let bad = || {
        Refusal(format!(
            "{what}: '{key}' must be three finite numbers [x, y, z]"
        ))
    };
    let arr = obj.get(key).and_then(Value::as_array).ok_or_else(bad)?;
    if arr.len() != 3 {
        return Err(bad());
    }
    let mut out = [0.0f32; 3];
    for (o, v) in out.iter_mut().zip(arr) {
        *o = v
            .as_f64()
            .map(|x| x as f32)
            .filter(|x| x.is_finite())
            .ok_or_else(bad)?;
    }
    Ok(out)
}

fn text<'a>(
    obj: &'a serde_json::Map<String, Value>,
    key: &str,
    what: &str,
) -> Result<&'a str, Refusal> {
    match obj.get(key) {
        Some(Value::String(s)) => Ok(s),
        Some(v) => refuse(format!("{what}: '{key}' must be a string, got {v}")),
        None => refuse(format!("{what}: missing field '{key}'")),
    }
}

fn side(obj: &serde_json::Map<String, Value>, key: &str) -> Result<u32, Refusal> {
    let v = obj.get(key);
    match v.and_then(Value::as_u64) {
        Some(n) if (1..=u64::from(MAX_SIDE)).contains(&n) => Ok(n as u32),
        _ => refuse(format!(
            "size: {key} must be a whole number of pixels in 1..={MAX_SIDE}, got {}",
            v.map_or("nothing".to_string(), Value::to_string)
        )),
    }
}

/// The fields each request type takes (besides `type` and `seq`); others are refused, so a
/// misspelt field is not silently ignored.
fn fields(kind: &str) -> Option<&'static [&'static str]> {
    Some(match kind {
        "material" => &["name", "param", "value"],
        "exposure" | "tone" | "rotation" | "intensity" | "encoding" => &["value"],
        "environment" => &["name"],
        "camera" => &["eye", "target", "fov"],
        "size" => &["width", "height"],
        "reference" => &["on"],
        _ => return None,
    })
}

/// Parses one message of the page (JSON text) and checks it against what the bake allows.
/// Nothing is changed: [`Settings::apply`] does that.
pub fn parse(text_in: &str, info: &BakeInfo) -> Result<Message, Refusal> {
    let value: Value =
        serde_json::from_str(text_in).map_err(|e| Refusal(format!("not a JSON message: {e}")))?;
    let Value::Object(obj) = value else {
        return refuse("a message must be a JSON object with a \"type\"");
    };
    let seq = match obj.get("seq") {
        None => 0,
        Some(v) => v
            .as_u64()
            .ok_or_else(|| Refusal(format!("'seq' must be a whole number, got {v}")))?,
    };
    let kind = text(&obj, "type", "message")?;
    let Some(allowed) = fields(kind) else {
        return refuse(format!(
            "unknown request type '{kind}' (known: material, exposure, tone, environment, \
             rotation, intensity, camera, size, reference, encoding)"
        ));
    };
    if let Some(extra) = obj
        .keys()
        .find(|k| *k != "type" && *k != "seq" && !allowed.contains(&k.as_str()))
    {
        return refuse(format!(
            "{kind}: unknown field '{extra}' (it takes {})",
            allowed.join(", ")
        ));
    }
    let vertex_only = |what: &str| -> Result<(), Refusal> {
        match info.environments {
            Some(_) => Ok(()),
            None => refuse(format!(
                "{what}: this is a per-pixel bake, its light and view are frozen into the file \
                 (only materials, exposure and tone can change)"
            )),
        }
    };
    let request = match kind {
        "material" => material(&obj, info)?,
        "exposure" => {
            let x = number(&obj, "value", "exposure")?;
            if !(0.0..=MAX_EXPOSURE).contains(&x) {
                return refuse(format!("exposure {x} is outside [0, {MAX_EXPOSURE}]"));
            }
            Request::Exposure(x)
        }
        "tone" => Request::Tone(
            text(&obj, "value", "tone")?
                .parse()
                .map_err(|e: String| Refusal(format!("tone: {e}")))?,
        ),
        "environment" => {
            vertex_only("environment")?;
            let name = text(&obj, "name", "environment")?;
            let known = info.environments.as_deref().unwrap_or_default();
            if !known.iter().any(|n| n == name) {
                return refuse(format!(
                    "unknown environment '{name}' (offered: {})",
                    known.join(", ")
                ));
            }
            Request::Environment(name.to_string())
        }
        "rotation" => {
            vertex_only("rotation")?;
            let x = number(&obj, "value", "rotation")?;
            if !(-360.0..=360.0).contains(&x) {
                return refuse(format!("rotation {x} is outside [-360, 360] degrees"));
            }
            Request::Rotation(x)
        }
        "intensity" => {
            vertex_only("intensity")?;
            let x = number(&obj, "value", "intensity")?;
            if !(0.0..=MAX_EXPOSURE).contains(&x) {
                return refuse(format!("intensity {x} is outside [0, {MAX_EXPOSURE}]"));
            }
            Request::Intensity(x)
        }
        "camera" => {
            vertex_only("camera")?;
            let spec = CameraSpec {
                eye: vec3(&obj, "eye", "camera")?,
                target: vec3(&obj, "target", "camera")?,
                fov_deg: number(&obj, "fov", "camera")?,
            };
            spec.frame().map_err(|e| Refusal(e.to_string()))?;
            Request::Camera(spec)
        }
        "size" => {
            vertex_only("size")?;
            Request::Size(side(&obj, "width")?, side(&obj, "height")?)
        }
        "reference" => match obj.get("on") {
            Some(Value::Bool(on)) => {
                if *on {
                    if let Some(why) = &info.reference_unavailable {
                        return refuse(format!("reference: {why}"));
                    }
                }
                Request::Reference(*on)
            }
            other => {
                return refuse(format!(
                    "reference: 'on' must be true or false, got {}",
                    other.map_or("nothing".to_string(), Value::to_string)
                ))
            }
        },
        _ => match text(&obj, "value", "encoding")? {
            "raw" => Request::Encoding(Encoding::Raw),
            "png" => Request::Encoding(Encoding::Png),
            other => return refuse(format!("unknown encoding '{other}' (use raw or png)")),
        },
    };
    Ok(Message { seq, request })
}

/// A material request: the material exists and is editable, its family has the parameter,
/// the value has the parameter's shape and lies in its range (the runtime's rules, read from
/// its material list).
fn material(obj: &serde_json::Map<String, Value>, info: &BakeInfo) -> Result<Request, Refusal> {
    let name = text(obj, "name", "material")?;
    let Some(m) = info.materials.iter().find(|m| m.name == name) else {
        let names: Vec<&str> = info.materials.iter().map(|m| m.name.as_str()).collect();
        return refuse(format!(
            "unknown material '{name}'; the bake has: {}",
            names.join(", ")
        ));
    };
    if !m.editable {
        let editable: Vec<&str> = info
            .materials
            .iter()
            .filter(|m| m.editable)
            .map(|m| m.name.as_str())
            .collect();
        return refuse(format!(
            "material '{name}' is not editable in this bake (editable: {})",
            editable.join(", ")
        ));
    }
    let param_name = text(obj, "param", "material")?;
    let param = Param::ALL.iter().copied().find(|p| p.name() == param_name);
    let Some(info_p) = param.and_then(|p| m.params.iter().find(|q| q.param() == p)) else {
        return refuse(format!(
            "material '{name}' is {}: it has no parameter '{param_name}' (it has {})",
            m.family,
            m.family.param_names().join(", ")
        ));
    };
    let range = info_p.range;
    let outside = |shown: String| {
        Refusal(format!(
            "material '{name}': {param_name} = {shown} is outside its valid range {range}"
        ))
    };
    let value = match info_p.value {
        OverrideValue::Kd(_) | OverrideValue::Ks(_) => {
            let c = vec3(obj, "value", &format!("material '{name}' {param_name}"))?;
            if !c.iter().all(|&v| range.contains(v)) {
                return Err(outside(format!("{c:?}")));
            }
            match info_p.value {
                OverrideValue::Kd(_) => OverrideValue::Kd(c),
                _ => OverrideValue::Ks(c),
            }
        }
        OverrideValue::Shininess(_) | OverrideValue::Alpha(_) => {
            let x = number(obj, "value", &format!("material '{name}' {param_name}"))?;
            if !range.contains(x) {
                return Err(outside(x.to_string()));
            }
            match info_p.value {
                OverrideValue::Shininess(_) => OverrideValue::Shininess(x),
                _ => OverrideValue::Alpha(x),
            }
        }
        _ => {
            return refuse(format!(
                "material '{name}': the viewer cannot set {param_name}"
            ))
        }
    };
    Ok(Request::Material {
        name: name.to_string(),
        value,
    })
}

impl Settings {
    /// Applies a checked request ([`parse`]): exactly the setting it names changes. The
    /// reference toggle and the encoding are not settings of the image and change nothing
    /// here.
    pub fn apply(&mut self, request: &Request) {
        match request {
            Request::Material { name, value } => {
                if let Some(m) = self.materials.iter_mut().find(|m| &m.name == name) {
                    for v in m.values.iter_mut().filter(|v| v.param() == value.param()) {
                        *v = *value;
                    }
                }
            }
            Request::Exposure(x) => self.exposure = *x,
            Request::Tone(c) => self.tone = *c,
            Request::Reference(_) | Request::Encoding(_) => {}
            view_request => {
                if let Some(v) = &mut self.view {
                    match view_request {
                        Request::Environment(n) => v.environment = n.clone(),
                        Request::Rotation(x) => v.rotation = *x,
                        Request::Intensity(x) => v.intensity = *x,
                        Request::Camera(c) => v.camera = *c,
                        Request::Size(w, h) => (v.width, v.height) = (*w, *h),
                        _ => {}
                    }
                }
            }
        }
    }
}

impl BakeInfo {
    /// What the page builds its controls from.
    pub fn to_json(&self) -> Value {
        let finite = |x: f32| if x.is_finite() { json!(x) } else { Value::Null };
        let materials: Vec<Value> = self
            .materials
            .iter()
            .map(|m| {
                let params: Vec<Value> = m
                    .params
                    .iter()
                    .map(|p| {
                        json!({
                            "param": p.param().name(),
                            "value": value_json(&p.value),
                            "min": finite(p.range.min),
                            "max": finite(p.range.max),
                            "sampled": p.sampled.map(|s| [s.min, s.max]),
                        })
                    })
                    .collect();
                json!({
                    "name": m.name,
                    "family": m.family.to_string(),
                    "editable": m.editable,
                    "textured": m.textured,
                    "params": params,
                })
            })
            .collect();
        json!({
            "bake": self.bake,
            "kind": if self.environments.is_some() { "vertex" } else { "pixel" },
            "materials": materials,
            "size": [self.size.0, self.size.1],
            "max_side": MAX_SIDE,
            "environments": self.environments,
            "tones": ToneCurve::ALL.map(|c| c.name()),
            "reference": {
                "available": self.reference_unavailable.is_none(),
                "reason": self.reference_unavailable,
            },
        })
    }
}

/// The `seq` of a message, when it has one (to answer even a message that is refused).
pub fn seq_of(text: &str) -> u64 {
    serde_json::from_str::<Value>(text)
        .ok()
        .and_then(|v| v.get("seq").and_then(Value::as_u64))
        .unwrap_or(0)
}
