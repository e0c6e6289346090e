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
//!
//! This file holds the bakes, the server and the tab (a WebSocket client); the tests are in
//! `controls.rs`, `refusals.rs` (bad and random requests) and `sessions.rs` (coalescing, tabs,
//! save, the reference toggle).

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

mod controls;
mod refusals;
mod sessions;
