//! The viewer's protocol, driven as the page drives it (one WebSocket per tab), against bakes
//! of the example scenes made here (cornell at 32x32 per pixel, vitrine per vertex, one
//! sample each: what they look like does not matter, that the server answers right does).
//!
//! - Every control's request changes exactly the setting it names, and the frame is the
//!   runtime's own render of the settings, tone-mapped as `relight` writes PNGs.
//! - Bad requests are refused with a message naming the problem, and change nothing.
//! - Random requests (a fuzz loop) never take the server down.
//! - Requests sent while a frame renders are coalesced; tabs keep their own settings; save
//!   gives the shown frame; the reference toggle streams converging passes.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

use prt_bake::progress::Silent;
use prt_bake::run::{load, run_pixel, run_vertex, PixelRunSettings, VertexRunSettings};
use prt_formats::image_io::tonemap_srgb8_with;
use prt_formats::view::CameraSpec;
use prt_formats::ToneCurve;
use prt_runtime::{OverrideValue, Param, Relighter};
use prt_viewer::{Server, ServerOptions};
use serde_json::{json, Value};
use tungstenite::{Message, WebSocket};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The bakes, made once per test run.
struct Bakes {
    pixel: PathBuf,
    vertex: PathBuf,
}

fn bakes() -> &'static Bakes {
    static BAKES: OnceLock<Bakes> = OnceLock::new();
    BAKES.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("prt-viewer-api-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let pixel = dir.join("cornell.prtbake");
        let (config, scene) = load(&root().join("scenes/cornell"), &Silent).expect("cornell");
        let settings = PixelRunSettings {
            spp: Some(1),
            width: Some(32),
            height: Some(32),
            output: Some(pixel.clone()),
            ..Default::default()
        };
        run_pixel(&config, &scene, &settings, &Silent).expect("cornell bake");
        let vertex = dir.join("vitrine.prtbake");
        let (config, scene) = load(&root().join("scenes/vitrine"), &Silent).expect("vitrine");
        let settings = VertexRunSettings {
            spp: Some(1),
            output: Some(vertex.clone()),
            ..Default::default()
        };
        run_vertex(&config, &scene, &settings, &Silent).expect("vitrine bake");
        Bakes { pixel, vertex }
    })
}

fn serve(bake: &Path, config: Option<&str>) -> SocketAddr {
    let server = Server::start(ServerOptions {
        bake: bake.to_path_buf(),
        env_folder: Some(root().join("scenes/envmaps")),
        config: config.map(|c| root().join(c)),
        address: "127.0.0.1:0".parse().expect("address"),
        gpu: false,
    })
    .expect("server starts");
    let address = server.address();
    // Serves until the test process ends.
    std::mem::forget(server);
    address
}

/// What the server answered.
#[derive(Debug)]
enum Reply {
    Frame(Value, Vec<u8>),
    Error(Value),
}

/// One tab.
struct Tab {
    ws: WebSocket<TcpStream>,
    seq: u64,
    hello: Value,
    /// The last frame's description and pixels.
    frame: (Value, Vec<u8>),
}

impl Tab {
    fn open(address: SocketAddr) -> Tab {
        let stream = TcpStream::connect(address).expect("connect");
        stream
            .set_read_timeout(Some(Duration::from_secs(120)))
            .expect("timeout");
        let (ws, _) = tungstenite::client(format!("ws://{address}/ws"), stream).expect("websocket");
        let mut tab = Tab {
            ws,
            seq: 0,
            hello: Value::Null,
            frame: (Value::Null, Vec::new()),
        };
        tab.hello = tab.text();
        assert_eq!(tab.hello["type"], "hello");
        match tab.reply() {
            Reply::Frame(meta, pixels) => tab.frame = (meta, pixels),
            other => panic!("first frame: {other:?}"),
        }
        tab
    }

    fn text(&mut self) -> Value {
        loop {
            match self.ws.read().expect("the server answers") {
                Message::Text(t) => return serde_json::from_str(&t).expect("JSON"),
                Message::Binary(b) => panic!("binary message of {} bytes out of turn", b.len()),
                _ => {}
            }
        }
    }

    fn binary(&mut self) -> Vec<u8> {
        loop {
            match self.ws.read().expect("the server answers") {
                Message::Binary(b) => return b.to_vec(),
                Message::Text(t) => panic!("text out of turn: {t}"),
                _ => {}
            }
        }
    }

    /// The next frame or error (reference messages are skipped).
    fn reply(&mut self) -> Reply {
        loop {
            let m = self.text();
            match m["type"].as_str() {
                Some("frame") => {
                    let pixels = self.binary();
                    return Reply::Frame(m, pixels);
                }
                Some("error") => return Reply::Error(m),
                Some("reference") => {
                    self.binary();
                    self.binary();
                }
                _ => {}
            }
        }
    }

    fn send_raw(&mut self, text: &str) {
        self.ws.send(Message::text(text)).expect("send");
    }

    /// Sends a request (numbered) and returns its frame or error.
    fn request(&mut self, mut request: Value) -> Reply {
        self.seq += 1;
        request["seq"] = json!(self.seq);
        self.send_raw(&request.to_string());
        let reply = self.reply();
        if let Reply::Frame(meta, pixels) = &reply {
            self.frame = (meta.clone(), pixels.clone());
        }
        reply
    }

    fn frame_of(&mut self, request: Value) -> (Value, Vec<u8>) {
        match self.request(request.clone()) {
            Reply::Frame(meta, pixels) => (meta, pixels),
            Reply::Error(e) => panic!("{request} refused: {}", e["message"]),
        }
    }

    fn settings(&self) -> Value {
        self.frame.0["settings"].clone()
    }
}

fn f32s(v: &Value) -> Vec<f32> {
    match v {
        Value::Array(a) => a
            .iter()
            .map(|x| x.as_f64().expect("number") as f32)
            .collect(),
        x => vec![x.as_f64().expect("number") as f32],
    }
}

/// The frame the runtime itself renders for `settings` (the page's JSON), tone-mapped as
/// `relight` writes a PNG, as RGBA: what the canvas must show.
fn expected_rgba(bake: &Path, settings: &Value) -> Vec<u8> {
    let mut r = prt_runtime::open(bake).expect("open");
    for m in r.materials() {
        let params = &settings["materials"][&m.name];
        let values: Vec<OverrideValue> = m
            .params
            .iter()
            .map(|p| {
                let v = f32s(&params[p.param().name()]);
                match p.param() {
                    Param::Kd => OverrideValue::Kd([v[0], v[1], v[2]]),
                    Param::Ks => OverrideValue::Ks([v[0], v[1], v[2]]),
                    Param::Shininess => OverrideValue::Shininess(v[0]),
                    _ => OverrideValue::Alpha(v[0]),
                }
            })
            .collect();
        if m.editable {
            r.set_params(&m.name, &values).expect("set");
        }
    }
    if let Relighter::Vertex(v) = &mut r {
        let view = &settings["view"];
        let env = view["environment"].as_str().expect("env");
        if env != "baked" {
            v.load_environment(root().join("scenes/envmaps").join(env))
                .expect("env");
        }
        v.set_environment_rotation(f32s(&view["rotation"])[0])
            .expect("rotation");
        v.set_environment_intensity(f32s(&view["intensity"])[0])
            .expect("intensity");
        let w = view["width"].as_u64().expect("w") as u32;
        let h = view["height"].as_u64().expect("h") as u32;
        v.set_size(w, h).expect("size");
        let cam = &view["camera"];
        let e = f32s(&cam["eye"]);
        let t = f32s(&cam["target"]);
        let spec = CameraSpec {
            eye: [e[0], e[1], e[2]],
            target: [t[0], t[1], t[2]],
            fov_deg: f32s(&cam["fov"])[0],
        };
        v.set_camera(spec.frame().expect("frame")).expect("camera");
    }
    let image = r.render().expect("render");
    let exposure = f32s(&settings["exposure"])[0];
    let tone: ToneCurve = settings["tone"]
        .as_str()
        .expect("tone")
        .parse()
        .expect("curve");
    image
        .pixels
        .iter()
        .flat_map(|p| {
            let [r, g, b] = p.map(|c| tonemap_srgb8_with(c, exposure, tone));
            [r, g, b, 255]
        })
        .collect()
}

/// `after` equals `before` with exactly the field at `path` (a JSON pointer) changed.
fn changed_exactly(before: &Value, after: &Value, path: &str) {
    assert_ne!(
        before.pointer(path),
        after.pointer(path),
        "{path} did not change"
    );
    let mut patched = before.clone();
    *patched.pointer_mut(path).expect("path exists") = after.pointer(path).expect("path").clone();
    assert_eq!(
        &patched, after,
        "a request for {path} changed something else"
    );
}

fn check_controls(bake: &Path, controls: &[(Value, &str)]) {
    let address = serve(bake, None);
    let mut tab = Tab::open(address);
    assert_eq!(
        tab.frame.1,
        expected_rgba(bake, &tab.settings()),
        "first frame"
    );
    for (request, path) in controls {
        let before = tab.settings();
        let mut request = request.clone();
        // "same": the current value (a camera request changing one field of three).
        for key in ["target", "eye"] {
            if request[key] == "same" {
                request[key] = before["view"]["camera"][key].clone();
            }
        }
        let (meta, pixels) = tab.frame_of(request.clone());
        assert_eq!(meta["seq"], json!(tab.seq));
        changed_exactly(&before, &meta["settings"], path);
        assert_eq!(
            pixels,
            expected_rgba(bake, &meta["settings"]),
            "{request}: the frame is not the runtime's render of the settings"
        );
        let (w, h) = (
            meta["width"].as_u64().unwrap(),
            meta["height"].as_u64().unwrap(),
        );
        assert_eq!(pixels.len() as u64, 4 * w * h);
    }
}

#[test]
fn every_control_changes_exactly_what_it_names_per_pixel() {
    let b = bakes();
    check_controls(
        &b.pixel,
        &[
            (
                json!({"type": "material", "name": "bunny", "param": "kd", "value": [0.8, 0.1, 0.1]}),
                "/materials/bunny/kd",
            ),
            (
                json!({"type": "material", "name": "bunny", "param": "ks", "value": [0.05, 0.5, 0.05]}),
                "/materials/bunny/ks",
            ),
            (
                json!({"type": "material", "name": "bunny", "param": "shininess", "value": 300}),
                "/materials/bunny/shininess",
            ),
            (
                json!({"type": "material", "name": "tall_box", "param": "alpha", "value": 0.5}),
                "/materials/tall_box/alpha",
            ),
            (json!({"type": "exposure", "value": 2.5}), "/exposure"),
            (json!({"type": "tone", "value": "aces"}), "/tone"),
        ],
    );
}

#[test]
fn every_control_changes_exactly_what_it_names_per_vertex() {
    let b = bakes();
    check_controls(
        &b.vertex,
        &[
            (
                json!({"type": "size", "width": 96, "height": 512}),
                "/view/width",
            ),
            (
                json!({"type": "size", "width": 96, "height": 80}),
                "/view/height",
            ),
            (
                json!({"type": "material", "name": "sphere", "param": "alpha", "value": 0.4}),
                "/materials/sphere/alpha",
            ),
            (
                json!({"type": "material", "name": "bunny", "param": "kd", "value": [0.2, 0.3, 0.9]}),
                "/materials/bunny/kd",
            ),
            (
                json!({"type": "environment", "name": "studio.exr"}),
                "/view/environment",
            ),
            (json!({"type": "rotation", "value": 75}), "/view/rotation"),
            (
                json!({"type": "intensity", "value": 0.6}),
                "/view/intensity",
            ),
            (
                json!({"type": "camera", "eye": [0.5, 0.4, 0.7], "target": "same", "fov": 40}),
                "/view/camera/eye",
            ),
            (
                json!({"type": "camera", "eye": "same", "target": [0, 0.1, 0], "fov": 40}),
                "/view/camera/target",
            ),
            (
                json!({"type": "camera", "eye": "same", "target": "same", "fov": 55}),
                "/view/camera/fov",
            ),
            (json!({"type": "exposure", "value": 0.5}), "/exposure"),
            (json!({"type": "tone", "value": "reinhard"}), "/tone"),
            (
                json!({"type": "environment", "name": "baked"}),
                "/view/environment",
            ),
        ],
    );
}

/// Sends `bad`, expects a refusal whose message contains each of `words`, and that the
/// settings did not change.
fn refused(tab: &mut Tab, bad: &str, words: &[&str]) {
    let before = tab.settings();
    tab.send_raw(bad);
    let Reply::Error(e) = tab.reply() else {
        panic!("{bad} was not refused");
    };
    let message = e["message"].as_str().expect("a message");
    for w in words {
        assert!(
            message.contains(w),
            "{bad}: message {message:?} lacks {w:?}"
        );
    }
    assert_eq!(e["settings"], before, "{bad}: settings changed");
}

#[test]
fn bad_requests_are_refused_with_a_message_and_change_nothing() {
    let b = bakes();
    let mut tab = Tab::open(serve(&b.vertex, None));
    let cases: &[(&str, &[&str])] = &[
        ("not json", &["not a JSON message"]),
        ("[1, 2]", &["JSON object"]),
        (r#"{"value": 1}"#, &["missing field 'type'"]),
        (
            r#"{"type": "teleport"}"#,
            &["unknown request type 'teleport'"],
        ),
        (
            r#"{"type": "exposure", "value": 1, "colour": 2}"#,
            &["unknown field 'colour'"],
        ),
        (
            r#"{"type": "exposure", "value": "bright"}"#,
            &["must be a number"],
        ),
        (
            r#"{"type": "exposure", "value": -1}"#,
            &["exposure -1 is outside"],
        ),
        (
            r#"{"type": "exposure", "value": 1e300}"#,
            &["not a finite 32-bit number"],
        ),
        (
            r#"{"type": "tone", "value": "filmic"}"#,
            &["unknown tone curve 'filmic'"],
        ),
        (
            r#"{"type": "material", "name": "teapot", "param": "kd", "value": [1, 1, 1]}"#,
            &["unknown material 'teapot'", "sphere"],
        ),
        (
            r#"{"type": "material", "name": "floor", "param": "kd", "value": [1, 1, 1]}"#,
            &["'floor' is not editable", "sphere, bunny"],
        ),
        (
            r#"{"type": "material", "name": "bunny", "param": "alpha", "value": 0.3}"#,
            &["'bunny' is diffuse", "no parameter 'alpha'"],
        ),
        (
            r#"{"type": "material", "name": "sphere", "param": "shininess", "value": 30}"#,
            &["'sphere' is ggx", "kd, ks, alpha"],
        ),
        (
            r#"{"type": "material", "name": "sphere", "param": "alpha", "value": 1.5}"#,
            &["alpha = 1.5 is outside its valid range"],
        ),
        (
            r#"{"type": "material", "name": "sphere", "param": "kd", "value": [1, -0.5, 1]}"#,
            &["kd = [1.0, -0.5, 1.0] is outside"],
        ),
        (
            r#"{"type": "material", "name": "sphere", "param": "kd", "value": [1, 1]}"#,
            &["three finite numbers"],
        ),
        (
            r#"{"type": "environment", "name": "../secret.exr"}"#,
            &["unknown environment '../secret.exr'", "studio.exr"],
        ),
        (
            r#"{"type": "rotation", "value": 1000}"#,
            &["rotation 1000 is outside"],
        ),
        (
            r#"{"type": "intensity", "value": -2}"#,
            &["intensity -2 is outside"],
        ),
        (
            r#"{"type": "camera", "eye": [0, 1, 0], "target": [0, 0, 0], "fov": 40}"#,
            &["vertical"],
        ),
        (
            r#"{"type": "camera", "eye": [0, 1, 3], "target": [0, 1, 3], "fov": 40}"#,
            &["eye and target must differ"],
        ),
        (
            r#"{"type": "camera", "eye": [0, 1, 3], "target": [0, 0, 0], "fov": 180}"#,
            &["fov 180 must be in (0, 180)"],
        ),
        (
            r#"{"type": "size", "width": 0, "height": 64}"#,
            &["width must be a whole number of pixels in 1..=4096"],
        ),
        (
            r#"{"type": "size", "width": 64, "height": 100000}"#,
            &["height must be", "100000"],
        ),
        (
            r#"{"type": "size", "width": 64.5, "height": 64}"#,
            &["width must be"],
        ),
        (r#"{"type": "reference", "on": true}"#, &["--config"]),
        (
            r#"{"type": "reference", "on": "yes"}"#,
            &["'on' must be true or false"],
        ),
        (
            r#"{"type": "encoding", "value": "jpeg"}"#,
            &["unknown encoding 'jpeg'"],
        ),
    ];
    for (bad, words) in cases {
        refused(&mut tab, bad, words);
        // Still serving.
        tab.frame_of(json!({"type": "exposure", "value": 1.25}));
    }
    // Refused when the frame renders: the eye inside the sphere (the runtime's rule); the
    // settings go back to the last rendered ones.
    let before = tab.settings();
    let Reply::Error(e) = tab.request(
        json!({"type": "camera", "eye": [-0.17, 0.119, 0.0], "target": [0.3, 0.1, 0.2], "fov": 40}),
    ) else {
        panic!("an eye inside the sphere was rendered");
    };
    assert!(e["message"].as_str().unwrap().contains("is inside"), "{e}");
    assert_eq!(e["settings"], before);
    let (meta, _) = tab.frame_of(json!({"type": "rotation", "value": 10}));
    assert_eq!(meta["settings"]["view"]["camera"], before["view"]["camera"]);
    // A per-pixel bake has no view.
    let mut pixel = Tab::open(serve(&b.pixel, None));
    refused(
        &mut pixel,
        r#"{"type": "rotation", "value": 10}"#,
        &["per-pixel bake", "frozen"],
    );
    refused(
        &mut pixel,
        r#"{"type": "size", "width": 64, "height": 64}"#,
        &["per-pixel bake"],
    );
}

/// A small generator of random requests (no randomness crate: a fixed 64-bit LCG, so a
/// failure repeats).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 >> 33
    }

    fn pick<'a, T>(&mut self, xs: &'a [T]) -> &'a T {
        &xs[self.next() as usize % xs.len()]
    }

    fn value(&mut self, depth: u32) -> Value {
        match self.next() % 10 {
            0 => json!(null),
            1 => json!(self.next().is_multiple_of(2)),
            2 => json!(*self.pick(&[0.0, -1.0, 1e39, -1e-45, 0.5, 3.0, 1e6, 4096.0, 16.0, 65.0])),
            3 => json!(self.next() as i64 - (1 << 30)),
            4 => json!(*self.pick(&[
                "",
                "kd",
                "baked",
                "studio.exr",
                "aces",
                "NaN",
                "inf",
                "sphere",
                "\u{0}"
            ])),
            5 if depth < 2 => Value::Array(
                (0..self.next() % 5)
                    .map(|_| self.value(depth + 1))
                    .collect(),
            ),
            6 => json!([0.2, 0.3, 0.4]),
            7 => json!(*self.pick(&[0.3, 90.0, 40.0, 128.0, 2.0])),
            8 if depth < 2 => json!({"x": self.value(depth + 1)}),
            _ => json!(self.next() % 300),
        }
    }
}

#[test]
fn random_requests_never_take_the_server_down() {
    let b = bakes();
    let address = serve(&b.vertex, None);
    let mut tab = Tab::open(address);
    let mut rng = Lcg(0x5eed);
    let types = [
        "material",
        "exposure",
        "tone",
        "environment",
        "rotation",
        "intensity",
        "camera",
        "size",
        "reference",
        "encoding",
        "bogus",
    ];
    let keys = [
        "name", "param", "value", "eye", "target", "fov", "width", "height", "on", "seq", "extra",
    ];
    let (mut frames, mut errors) = (0, 0);
    for i in 0..400u64 {
        let text = match rng.next() % 8 {
            0 => {
                // Bytes that may not even be JSON.
                let n = rng.next() % 40;
                (0..n)
                    .map(|_| *rng.pick(&['{', '}', '"', ':', ',', '[', 'a', '1', ' ', 'é']))
                    .collect()
            }
            1..=4 => {
                // A well-formed request with a value that may or may not be valid, sometimes
                // with a field dropped or one added.
                let pick_value = |rng: &mut Lcg| rng.value(0);
                let mut obj = match rng.next() % 9 {
                    0 => json!({"type": "material",
                        "name": rng.pick(&["sphere", "bunny", "floor", "nope"]),
                        "param": rng.pick(&["kd", "ks", "alpha", "shininess"]),
                        "value": rng.pick(&[json!([0.2, 0.5, 0.9]), json!(0.3), json!(2.0), json!([1, -1, 0])]).clone()}),
                    1 => {
                        json!({"type": "exposure", "value": rng.pick(&[0.5, 2.0, -1.0, 1e7, 0.0])})
                    }
                    2 => {
                        json!({"type": "tone", "value": rng.pick(&["clamp", "aces", "reinhard", "gamma"])})
                    }
                    3 => {
                        json!({"type": "environment", "name": rng.pick(&["baked", "sky.exr", "sunset.exr", "x.exr"])})
                    }
                    4 => {
                        json!({"type": "rotation", "value": rng.pick(&[30.0, -200.0, 359.0, 720.0])})
                    }
                    5 => json!({"type": "intensity", "value": rng.pick(&[0.5, 3.0, -1.0])}),
                    6 => {
                        json!({"type": "camera", "eye": rng.pick(&[[0.4, 0.3, 0.8], [0.0, 1.0, 0.0], [-0.17, 0.119, 0.0]]),
                        "target": [0.0, 0.1, 0.0], "fov": rng.pick(&[40.0, 0.0, 90.0])})
                    }
                    7 => {
                        let sides = [
                            json!(16),
                            json!(48),
                            json!(0),
                            json!(99999),
                            json!(16.5),
                            json!("32"),
                            json!(-4),
                        ];
                        json!({"type": "size", "width": rng.pick(&sides), "height": rng.pick(&sides)})
                    }
                    _ => {
                        json!({"type": rng.pick(&["reference", "encoding"]), "on": false, "value": "png"})
                    }
                };
                match rng.next() % 6 {
                    0 => {
                        let k = rng.pick(&keys).to_string();
                        obj[k] = pick_value(&mut rng);
                    }
                    1 => {
                        let k = *rng.pick(&keys);
                        obj.as_object_mut().map(|o| o.remove(k));
                    }
                    _ => {}
                }
                obj["seq"] = json!(1000 + i);
                obj.to_string()
            }
            _ => {
                let mut obj = serde_json::Map::new();
                obj.insert("type".into(), json!(rng.pick(&types)));
                for _ in 0..rng.next() % 5 {
                    let k = rng.pick(&keys).to_string();
                    let v = rng.value(0);
                    obj.insert(k, v);
                }
                // Sizes stay small when valid, so the loop stays quick.
                if obj["type"] == "size" {
                    obj.insert("width".into(), json!(*rng.pick(&[16, 48, 0, 99999])));
                }
                obj.insert("seq".into(), json!(1000 + i));
                Value::Object(obj).to_string()
            }
        };
        tab.send_raw(&text);
        // Every message gets an answer: a frame or an error (a frame may answer several).
        match tab.reply() {
            Reply::Frame(meta, pixels) => {
                frames += 1;
                let (w, h) = (
                    meta["width"].as_u64().unwrap(),
                    meta["height"].as_u64().unwrap(),
                );
                if meta["encoding"] == "raw" {
                    assert_eq!(pixels.len() as u64, 4 * w * h);
                } else {
                    assert!(pixels.starts_with(b"\x89PNG"));
                }
                tab.frame = (meta, pixels);
            }
            Reply::Error(e) => {
                errors += 1;
                assert!(!e["message"].as_str().unwrap_or("").is_empty(), "{e}");
            }
        }
        if i % 50 == 0 {
            tab.ws.send(Message::binary(vec![0u8, 1, 2])).expect("send");
            assert!(matches!(tab.reply(), Reply::Error(_)));
        }
    }
    assert!(
        frames > 10 && errors > 100,
        "{frames} frames, {errors} errors"
    );
    // The server still serves this tab, a new tab and plain HTTP.
    tab.frame_of(json!({"type": "size", "width": 32, "height": 32}));
    let mut other = Tab::open(address);
    other.frame_of(json!({"type": "exposure", "value": 2}));
    let (status, body) = http_get(address, "/api/info");
    assert_eq!(status, 200);
    assert!(body.starts_with(b"{"));
}

#[test]
fn requests_arriving_while_a_frame_renders_are_coalesced() {
    let b = bakes();
    let mut tab = Tab::open(serve(&b.vertex, None));
    tab.frame_of(json!({"type": "size", "width": 128, "height": 128}));
    // A material edit re-runs the material stage: far slower than sending 30 messages.
    let first = tab.seq + 1;
    for k in 0..30 {
        tab.seq += 1;
        let request = json!({"type": "material", "name": "sphere", "param": "alpha",
            "value": 0.05 + 0.02 * k as f64, "seq": tab.seq});
        tab.send_raw(&request.to_string());
    }
    let mut frames = Vec::new();
    loop {
        let Reply::Frame(meta, _) = tab.reply() else {
            panic!("refused")
        };
        let seq = meta["seq"].as_u64().unwrap();
        frames.push(seq);
        if seq == tab.seq {
            let last = (0.05 + 0.02 * 29.0) as f32;
            assert_eq!(
                meta["settings"]["materials"]["sphere"]["alpha"],
                json!(last)
            );
            break;
        }
    }
    assert!(frames.iter().all(|&s| s >= first));
    assert!(
        frames.len() <= 4,
        "30 quick requests gave {} frames ({frames:?}): not coalesced",
        frames.len()
    );
}

#[test]
fn tabs_keep_their_own_settings() {
    let b = bakes();
    let address = serve(&b.vertex, None);
    let mut a = Tab::open(address);
    let mut c = Tab::open(address);
    let (meta_a, pixels_a) = a.frame_of(
        json!({"type": "material", "name": "bunny", "param": "kd", "value": [0.1, 0.9, 0.1]}),
    );
    let (meta_c, pixels_c) = c.frame_of(json!({"type": "rotation", "value": 45}));
    assert_eq!(
        meta_c["settings"]["materials"],
        c.hello["settings"]["materials"]
    );
    assert_eq!(pixels_c, expected_rgba(&b.vertex, &meta_c["settings"]));
    // Back to tab a: its own edit, and not c's rotation.
    let (meta_a2, pixels_a2) = a.frame_of(json!({"type": "exposure", "value": 1.0}));
    assert_eq!(meta_a2["settings"]["view"], meta_a["settings"]["view"]);
    assert_eq!(pixels_a2, pixels_a);
    assert_eq!(pixels_a2, expected_rgba(&b.vertex, &meta_a2["settings"]));
}

/// A plain HTTP GET (a test helper; the server side is axum).
fn http_get(address: SocketAddr, path: &str) -> (u32, Vec<u8>) {
    let mut s = TcpStream::connect(address).expect("connect");
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n"
    )
    .expect("write");
    let mut buf = Vec::new();
    s.read_to_end(&mut buf).expect("read");
    let split = buf
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("headers");
    let head = String::from_utf8_lossy(&buf[..split]).to_string();
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .expect("status");
    let body = buf[split + 4..].to_vec();
    // Small bodies only come back unchunked; a chunked one is decoded here.
    if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        let mut out = Vec::new();
        let mut rest = &body[..];
        loop {
            let end = rest
                .windows(2)
                .position(|w| w == b"\r\n")
                .expect("chunk size");
            let n = usize::from_str_radix(std::str::from_utf8(&rest[..end]).expect("hex"), 16)
                .expect("size");
            if n == 0 {
                break;
            }
            out.extend_from_slice(&rest[end + 2..end + 2 + n]);
            rest = &rest[end + 4 + n..];
        }
        return (status, out);
    }
    (status, body)
}

#[test]
fn save_gives_the_shown_frame_as_exr_and_png() {
    let b = bakes();
    let address = serve(&b.pixel, None);
    let mut tab = Tab::open(address);
    let (meta, pixels) = tab.frame_of(json!({"type": "exposure", "value": 3.0}));
    let id = tab.hello["session"].as_u64().unwrap();
    let (status, png) = http_get(address, &format!("/api/session/{id}/image.png"));
    assert_eq!(status, 200);
    let decoded = image::load_from_memory(&png).expect("a PNG").to_rgba8();
    assert_eq!(
        decoded.as_raw(),
        &pixels,
        "the PNG is not what the canvas shows"
    );
    let (status, exr) = http_get(address, &format!("/api/session/{id}/image.exr"));
    assert_eq!(status, 200);
    let path = std::env::temp_dir().join(format!("prt-viewer-save-{}.exr", std::process::id()));
    std::fs::write(&path, exr).expect("write");
    let (w, h, linear) = prt_formats::read_exr_rgb(&path).expect("an EXR");
    std::fs::remove_file(&path).ok();
    assert_eq!(
        (w as u64, h as u64),
        (
            meta["width"].as_u64().unwrap(),
            meta["height"].as_u64().unwrap()
        )
    );
    let mut r = prt_runtime::open(&b.pixel).expect("open");
    assert_eq!(
        linear,
        r.render().expect("render").pixels,
        "the EXR is not the linear frame"
    );
    for (path, code) in [
        (format!("/api/session/{id}/image.jpg"), 404),
        ("/api/session/999/image.png".to_string(), 404),
        ("/api/session/x/image.png".to_string(), 400),
        ("/nothing".to_string(), 404),
    ] {
        let (status, body) = http_get(address, &path);
        assert_eq!(status, code, "{path}");
        assert!(!body.is_empty(), "{path}: no message");
    }
}

#[test]
fn the_reference_toggle_streams_converging_passes() {
    let b = bakes();
    let mut tab = Tab::open(serve(&b.pixel, Some("scenes/cornell")));
    assert_eq!(tab.hello["info"]["reference"]["available"], json!(true));
    tab.seq += 1;
    tab.send_raw(&json!({"type": "reference", "on": true, "seq": tab.seq}).to_string());
    let mut seen = Vec::new();
    while seen.len() < 3 {
        let m = tab.text();
        if m["type"] == "reference" {
            let reference = tab.binary();
            let difference = tab.binary();
            assert_eq!(reference.len(), 4 * 32 * 32);
            assert_eq!(difference.len(), reference.len());
            assert!(
                reference
                    .chunks(4)
                    .filter(|p| p[0] > 10 || p[1] > 10)
                    .count()
                    > 200
            );
            let l2 = m["rel_l2"].as_f64().expect("compared with the relit frame");
            seen.push((m["spp"].as_u64().unwrap(), l2));
        } else if m["type"] == "frame" {
            tab.binary();
        } else {
            panic!("{m}");
        }
    }
    assert!(seen.windows(2).all(|w| w[1].0 > w[0].0), "{seen:?}");
    // A 1-spp bake against a reference of a few samples: the same image, noisy.
    assert!(seen.iter().all(|&(_, l2)| l2 > 0.0 && l2 < 2.0), "{seen:?}");
    // Off: the passes stop (a frame answers; no reference message follows it for a while).
    let _ = tab.request(json!({"type": "reference", "on": false}));
    let _ = tab.request(json!({"type": "exposure", "value": 1.5}));
}
