//! The libraries' errors as Python exceptions. The classes are defined in Python
//! (`prt/_errors.py`), so that each can also derive from the built-in exception a Python
//! programmer expects (`OSError` for a file, `ValueError` for a value); the message is the
//! library's, with its causes (as the command-line tools print it).

use std::error::Error;

use prt_bake::config::input::InputError;
use prt_bake::config::ConfigError;
use prt_bake::error::BakeError;
use prt_bake::ground_truth::ReferenceError;
use prt_formats::describe_error;
use prt_runtime::RuntimeError;
use pyo3::PyErr;

/// The Python classes (their Rust names must be their Python names).
mod classes {
    pyo3::import_exception!(prt._errors, PrtError);
    pyo3::import_exception!(prt._errors, FileError);
    pyo3::import_exception!(prt._errors, ConfigError);
    pyo3::import_exception!(prt._errors, ParameterError);
    pyo3::import_exception!(prt._errors, Cancelled);
}

/// The exception class an error is raised as.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Anything else the libraries refuse ([`PrtError`]).
    Other,
    /// A file missing, unreadable, corrupt or of the wrong kind.
    File,
    /// A bake config or scene refused.
    Config,
    /// A parameter, camera, environment or array refused.
    Parameter,
    /// Work stopped by the caller.
    Cancelled,
}

/// Raises `e` (and its causes, in the message) as an exception of `kind`.
pub fn raise(kind: Kind, e: &(dyn Error + 'static)) -> PyErr {
    message(kind, describe_error(e))
}

/// An exception of `kind` with `text`.
pub fn message(kind: Kind, text: String) -> PyErr {
    match kind {
        Kind::Other => classes::PrtError::new_err(text),
        Kind::File => classes::FileError::new_err(text),
        Kind::Config => classes::ConfigError::new_err(text),
        Kind::Parameter => classes::ParameterError::new_err(text),
        Kind::Cancelled => classes::Cancelled::new_err(text),
    }
}

/// Whether an I/O error is among `e`'s causes: a file could not be read or written.
fn io_cause(e: &(dyn Error + 'static)) -> bool {
    let mut cause = Some(e);
    while let Some(c) = cause {
        if c.is::<std::io::Error>() {
            return true;
        }
        cause = c.source();
    }
    false
}

/// A runtime error as the exception it is raised as.
pub fn runtime(e: RuntimeError) -> PyErr {
    let kind = match &e {
        RuntimeError::Format(_)
        | RuntimeError::Schema { .. }
        | RuntimeError::VertexSchema { .. }
        | RuntimeError::WrongKind { .. }
        | RuntimeError::UnknownKind { .. }
        | RuntimeError::EnvironmentFile { .. } => Kind::File,
        RuntimeError::UnknownMaterial { .. }
        | RuntimeError::NotEditable { .. }
        | RuntimeError::WrongParam { .. }
        | RuntimeError::OutOfRange { .. }
        | RuntimeError::NoCompressed
        | RuntimeError::Raster(_)
        | RuntimeError::EyeInside { .. }
        | RuntimeError::Environment(_)
        | RuntimeError::Lighting(_)
        | RuntimeError::BufferSize { .. } => Kind::Parameter,
    };
    raise(kind, &e)
}

/// A baker error (a bake or a reference render) as the exception it is raised as.
pub fn bake(e: BakeError) -> PyErr {
    let kind = match &e {
        // The progress callback asked to stop (`Progress::cancelled`).
        e if e.is_cancelled() => Kind::Cancelled,
        // What the user named is not there (or not a config, scene folder or glTF).
        BakeError::Input(InputError::WrongForm { .. })
        | BakeError::Config(ConfigError::Io { .. })
        | BakeError::Input(InputError::Config(ConfigError::Io { .. })) => Kind::File,
        BakeError::Scene(_) | BakeError::Input(InputError::Scene(_)) if io_cause(&e) => Kind::File,
        BakeError::Config(_)
        | BakeError::Input(_)
        | BakeError::Scene(_)
        | BakeError::NoTriangles(_)
        | BakeError::WrongMode { .. }
        | BakeError::Basis { .. }
        | BakeError::BadErrorTarget(_)
        | BakeError::MemoryLimit { .. } => Kind::Config,
        BakeError::Override(_) | BakeError::WrongParam { .. } => Kind::Parameter,
        _ if io_cause(&e) => Kind::File,
        _ => Kind::Other,
    };
    raise(kind, &e)
}

/// A reference render's error as the exception it is raised as: the scene's or an edit's as
/// [`bake`] raises it, a refused setting as a parameter error.
pub fn reference(e: ReferenceError) -> PyErr {
    match e {
        ReferenceError::Bake(e) => bake(*e),
        e => raise(Kind::Parameter, &e),
    }
}

/// A panic's payload as an error (a panic never crosses into Python).
pub fn panic(payload: &(dyn std::any::Any + Send)) -> PyErr {
    let what = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "no message".into());
    message(
        Kind::Other,
        format!("internal error (please report it): a panic: {what}"),
    )
}
