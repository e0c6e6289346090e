//! The interactive viewer (docs/viewer.md): a local web server over one bake file whose page
//! shows the relit image and the bake's controls (materials; per vertex the environment,
//! camera and image size; exposure and tone curve), relit by `prt-runtime` on the server as
//! the controls move, with the reference tracer beside it on request.
//!
//! It sits above the runtime and the baker (whose reference tracer it runs) and holds the
//! project's only HTTP server, so it is a crate of its own: `cargo run --bin bake` never
//! builds it.
//!
//! - `settings.rs`: what a tab shows, the requests that change it and their checks.
//! - `render.rs`: the relighter brought to a tab's settings.
//! - `encode.rs`: tone mapping for the canvas, PNG and EXR for save.
//! - `command.rs`: the `relight` command line of what is shown.
//! - `reference.rs`: the reference tracer's passes for a tab's settings.
//! - `hub.rs`: what the server's threads share (the tabs, the reference wanted).
//! - `pipeline.rs`: the render and reference threads.
//! - `server.rs`: HTTP, WebSocket, the page (`assets/`).

#![warn(missing_docs)]

pub mod command;
pub mod encode;
mod error;
mod hub;
mod pipeline;
pub mod reference;
pub mod render;
mod server;
pub mod settings;

pub use error::ViewerError;
pub use server::{Server, ServerOptions};
