//! The web server: the page and its script, one WebSocket per tab, the save downloads.
//!
//! Why axum (on tokio): it is the most used and best kept Rust HTTP framework, and its
//! WebSocket support lets one task per tab wait on the socket and on its frames at once
//! (`tokio::select!`). tiny_http with tungstenite would build faster, but a blocking
//! WebSocket cannot be read and written from two threads, and a tab must send requests while
//! frames come back. The crate is heavy, which is why the viewer is a crate of its own and
//! `cargo run --bin bake` never builds it.
//!
//! Threads: tokio serves the sockets; one render thread owns the relighter (`render.rs`) and
//! takes the tabs' latest settings in turn; one reference thread runs the tracer on a pool of
//! its own, so a frame never waits behind a reference pass in rayon's queue.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

use axum::extract::ws::{Message as WsMessage, WebSocket, WebSocketUpgrade};
use axum::extract::{Path as UrlPath, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::serve::ListenerExt;
use axum::Router;
use serde_json::json;
use tokio::sync::mpsc;

use crate::hub::{Hub, Job, Outgoing, RefState, Shared};
use crate::pipeline::{reference_loop, render_loop};
use crate::render::Renderer;
use crate::settings::{self, Encoding, Request, Settings};
use crate::ViewerError;

/// The page, its script and style, built into the binary (no CDN, works offline).
const INDEX_HTML: &str = include_str!("../assets/index.html");
const VIEWER_JS: &str = include_str!("../assets/viewer.js");
const VIEWER_CSS: &str = include_str!("../assets/viewer.css");

/// The largest message a tab may send (a request is a few hundred bytes).
const MAX_REQUEST_BYTES: usize = 64 * 1024;

/// How to start the viewer.
#[derive(Clone, Debug)]
pub struct ServerOptions {
    /// The bake file.
    pub bake: PathBuf,
    /// Per-vertex bakes: a folder of `.exr` / `.hdr` environment maps for the picker.
    pub env_folder: Option<PathBuf>,
    /// The bake's config, for the reference toggle.
    pub config: Option<PathBuf>,
    /// Where to listen (127.0.0.1 unless the user asked otherwise).
    pub address: SocketAddr,
    /// Relight on the GPU (the crate's feature `gpu`; refused without it).
    pub gpu: bool,
}

/// A running viewer.
pub struct Server {
    address: SocketAddr,
    open_seconds: f64,
    thread: std::thread::JoinHandle<Result<(), ViewerError>>,
}

impl Server {
    /// Opens the bake, binds the address and starts serving (in threads of its own).
    pub fn start(options: ServerOptions) -> Result<Server, ViewerError> {
        let start = Instant::now();
        let reference_unavailable = match &options.config {
            Some(_) => None,
            None => Some(
                "start the viewer with --config <the bake's config> to run the reference tracer"
                    .to_string(),
            ),
        };
        let (renderer, info, initial) = Renderer::open(
            &options.bake,
            options.env_folder.as_deref(),
            reference_unavailable,
            options.gpu,
        )?;
        let tracing = renderer.tracing();
        let open_seconds = start.elapsed().as_secs_f64();
        let listener =
            std::net::TcpListener::bind(options.address).map_err(|source| ViewerError::Bind {
                address: options.address.to_string(),
                source,
            })?;
        let address = listener.local_addr().map_err(|source| ViewerError::Bind {
            address: options.address.to_string(),
            source,
        })?;
        listener
            .set_nonblocking(true)
            .map_err(|source| ViewerError::Bind {
                address: address.to_string(),
                source,
            })?;
        let shared = Arc::new(Shared {
            info_json: info.to_json().to_string(),
            info,
            initial,
            env_folder: options.env_folder.as_ref().map(|p| p.display().to_string()),
            hub: Mutex::new(Hub {
                sessions: HashMap::new(),
                next_id: 0,
                stop: false,
            }),
            wake: Condvar::new(),
            reference: Mutex::new(RefState::default()),
            reference_wake: Condvar::new(),
        });
        let render_shared = Arc::clone(&shared);
        std::thread::Builder::new()
            .name("render".into())
            .spawn(move || render_loop(&render_shared, renderer))
            .map_err(ViewerError::Thread)?;
        if let Some(config) = options.config.clone() {
            let ref_shared = Arc::clone(&shared);
            let env_folder = options.env_folder.clone();
            std::thread::Builder::new()
                .name("reference".into())
                .spawn(move || reference_loop(&ref_shared, &config, tracing, env_folder))
                .map_err(ViewerError::Thread)?;
        }
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
            .map_err(ViewerError::Thread)?;
        let app = Router::new()
            .route(
                "/",
                get(|| async { page(INDEX_HTML, "text/html; charset=utf-8") }),
            )
            .route(
                "/viewer.js",
                get(|| async { page(VIEWER_JS, "text/javascript; charset=utf-8") }),
            )
            .route(
                "/viewer.css",
                get(|| async { page(VIEWER_CSS, "text/css; charset=utf-8") }),
            )
            .route("/api/info", get(bake_info))
            .route("/api/session/{id}/{file}", get(save))
            .route("/ws", get(upgrade))
            .fallback(|| async { (StatusCode::NOT_FOUND, "no such page") })
            .with_state(shared);
        let thread = std::thread::Builder::new()
            .name("http".into())
            .spawn(move || {
                runtime.block_on(async move {
                    let listener =
                        tokio::net::TcpListener::from_std(listener).map_err(|source| {
                            ViewerError::Bind {
                                address: address.to_string(),
                                source,
                            }
                        })?;
                    // Every frame is a small text message and its pixels, written at once:
                    // without TCP_NODELAY, Nagle's algorithm may hold the last segment back
                    // until the page acknowledges the ones before.
                    let listener = listener.tap_io(|tcp| {
                        let _ = tcp.set_nodelay(true);
                    });
                    axum::serve(listener, app)
                        .await
                        .map_err(|source| ViewerError::Bind {
                            address: address.to_string(),
                            source,
                        })
                })
            })
            .map_err(ViewerError::Thread)?;
        Ok(Server {
            address,
            open_seconds,
            thread,
        })
    }

    /// The address it listens on.
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// Seconds it took to open and validate the bake.
    pub fn open_seconds(&self) -> f64 {
        self.open_seconds
    }

    /// Serves until the server fails.
    pub fn wait(self) -> Result<(), ViewerError> {
        self.thread.join().unwrap_or(Err(ViewerError::Stopped))
    }
}

fn page(body: &'static str, content_type: &'static str) -> Response {
    ([(header::CONTENT_TYPE, content_type)], body).into_response()
}

async fn bake_info(State(shared): State<Arc<Shared>>) -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        shared.info_json.clone(),
    )
        .into_response()
}

/// `GET /api/session/{id}/image.exr` or `.png`: the frame tab `id` shows, as `relight` would
/// write it.
async fn save(
    State(shared): State<Arc<Shared>>,
    UrlPath((id, file)): UrlPath<(String, String)>,
) -> Response {
    let bad = |code: StatusCode, text: String| (code, text).into_response();
    let extension = match file.as_str() {
        "image.exr" => "exr",
        "image.png" => "png",
        _ => {
            return bad(
                StatusCode::NOT_FOUND,
                format!("unknown file '{file}' (image.exr or image.png)"),
            )
        }
    };
    let Ok(id) = id.parse::<u64>() else {
        return bad(StatusCode::BAD_REQUEST, format!("'{id}' is not a session"));
    };
    let shown = shared.hub().sessions.get(&id).and_then(|s| s.shown.clone());
    let Some(frame) = shown else {
        return bad(
            StatusCode::NOT_FOUND,
            format!("session {id} is not open or has no frame yet"),
        );
    };
    let name = crate::command::output_name(&shared.info).replace(".png", &format!(".{extension}"));
    let encoded = tokio::task::spawn_blocking(move || {
        crate::encode::image_file(
            frame.width,
            frame.height,
            &frame.pixels,
            frame.settings.exposure,
            frame.settings.tone,
            extension,
        )
    })
    .await;
    match encoded {
        Ok(Ok(bytes)) => (
            [
                (
                    header::CONTENT_TYPE,
                    if extension == "exr" {
                        "image/x-exr".to_string()
                    } else {
                        "image/png".to_string()
                    },
                ),
                (
                    header::CONTENT_DISPOSITION,
                    format!("attachment; filename=\"{name}\""),
                ),
            ],
            bytes,
        )
            .into_response(),
        Ok(Err(e)) => bad(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()),
        Err(e) => bad(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()),
    }
}

async fn upgrade(ws: WebSocketUpgrade, State(shared): State<Arc<Shared>>) -> Response {
    ws.max_message_size(MAX_REQUEST_BYTES)
        .on_upgrade(move |socket| session(socket, shared))
}

/// One tab: its settings, its requests in, its frames out.
async fn session(mut socket: WebSocket, shared: Arc<Shared>) {
    let (tx, mut rx) = mpsc::unbounded_channel();
    let id = shared.register(tx);
    let mut settings = shared.initial.clone();
    let mut encoding = Encoding::default();
    let hello = json!({
        "type": "hello",
        "session": id,
        "info": serde_json::from_str::<serde_json::Value>(&shared.info_json).unwrap_or_default(),
        "settings": settings.to_json(),
    });
    if socket
        .send(WsMessage::Text(hello.to_string().into()))
        .await
        .is_err()
    {
        shared.unregister(id);
        return;
    }
    shared.submit(
        id,
        Job {
            seq: 0,
            settings: settings.clone(),
            encoding,
        },
    );
    loop {
        tokio::select! {
            incoming = socket.recv() => {
                let text = match incoming {
                    Some(Ok(WsMessage::Text(t))) => t.to_string(),
                    Some(Ok(WsMessage::Binary(_))) => {
                        let e = error_json(0, "binary messages are not requests; send JSON text", &settings);
                        if socket.send(WsMessage::Text(e.into())).await.is_err() { break; }
                        continue;
                    }
                    Some(Ok(WsMessage::Close(_))) | None | Some(Err(_)) => break,
                    Some(Ok(_)) => continue,
                };
                match settings::parse(&text, &shared.info) {
                    Ok(m) => {
                        match &m.request {
                            Request::Reference(on) => shared.set_reference(id, *on),
                            Request::Encoding(e) => encoding = *e,
                            r => settings.apply(r),
                        }
                        shared.submit(id, Job { seq: m.seq, settings: settings.clone(), encoding });
                    }
                    Err(refusal) => {
                        let e = error_json(settings::seq_of(&text), &refusal.0, &settings);
                        if socket.send(WsMessage::Text(e.into())).await.is_err() { break; }
                    }
                }
            }
            out = rx.recv() => {
                let sent = match out {
                    None => break,
                    Some(Outgoing::Frame { meta, pixels }) => {
                        let ok = socket.send(WsMessage::Text(meta.into())).await.is_ok()
                            && socket.send(WsMessage::Binary(pixels.into())).await.is_ok();
                        shared.frame_sent(id);
                        ok
                    }
                    Some(Outgoing::Refused { seq, message, good }) => {
                        settings = *good;
                        let e = error_json(seq, &message, &settings);
                        socket.send(WsMessage::Text(e.into())).await.is_ok()
                    }
                    Some(Outgoing::Reference { meta, reference, difference }) => {
                        socket.send(WsMessage::Text(meta.into())).await.is_ok()
                            && socket.send(WsMessage::Binary(reference.into())).await.is_ok()
                            && socket.send(WsMessage::Binary(difference.into())).await.is_ok()
                    }
                    Some(Outgoing::Text(t)) => socket.send(WsMessage::Text(t.into())).await.is_ok(),
                };
                if !sent { break; }
            }
        }
    }
    shared.unregister(id);
}

/// An error answer: the request's number, the message, and the settings now in force (the
/// page puts its controls back to them).
fn error_json(seq: u64, message: &str, settings: &Settings) -> String {
    json!({
        "type": "error",
        "seq": seq,
        "message": message,
        "settings": settings.to_json(),
    })
    .to_string()
}
