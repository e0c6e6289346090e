//! The viewer's error type.

use prt_formats::view::CameraSpecError;
use prt_runtime::RuntimeError;

/// Why the viewer could not start, or a frame, a save or a reference could not be made.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    /// The bake could not be opened, or the relighter refused a setting (the runtime's
    /// message: an eye inside an object, an unreadable environment map, ...).
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
    /// The camera makes no view.
    #[error(transparent)]
    Camera(CameraSpecError),
    /// The environment folder cannot be listed.
    #[error("environment folder {path}: {source}")]
    EnvFolder {
        /// The folder, as given.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The address cannot be listened on.
    #[error("cannot listen on {address}: {source}")]
    Bind {
        /// The address.
        address: String,
        /// Why.
        source: std::io::Error,
    },
    /// A thread or the async runtime could not be started.
    #[error("cannot start the server's threads: {0}")]
    Thread(std::io::Error),
    /// The server's thread ended abnormally.
    #[error("the server stopped")]
    Stopped,
    /// A frame could not be encoded for the page or a download.
    #[error("encoding the image: {0}")]
    Encode(String),
    /// The GPU backend could not start or render (`view --gpu`).
    #[error("GPU: {0}")]
    Gpu(String),
    /// The reference tracer cannot run.
    #[error("reference ({config}): {reason}")]
    Reference {
        /// The config given.
        config: String,
        /// Why.
        reason: String,
    },
}
