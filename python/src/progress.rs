//! Long library calls (a bake, a reference render) run from Python: the work runs on its own
//! thread without the interpreter's lock, while the calling thread delivers its progress to
//! the Python callback and watches for Ctrl-C. So the callback always runs on the thread that
//! called (where a notebook's widgets and `tqdm` expect it), an exception it raises surfaces
//! there, and Ctrl-C, which Python only delivers to the main thread, is seen within
//! [`POLL`].
//!
//! Stopping: the callback returning `False`, raising, or Ctrl-C sets a flag; the next time the
//! work reports a stage or a step ([`Reporter::start`], [`Reporter::advance`]) the report
//! unwinds the work thread with a [`Stopped`] payload (rayon carries it out of its pool), so
//! the work ends before it writes its file (files are written atomically, at the end; a
//! per-vertex bake's checkpoint, saved as it goes, stays). The exception raised is the
//! callback's own (or `KeyboardInterrupt`), else `prt.Cancelled`.
//!
//! Why an unwind and not a question the libraries ask: the baker's `Progress` has no way yet
//! to ask whether to stop. Once it has one (`Progress::cancelled`, and an error that says it
//! was the answer), `Reporter` answers it from the same flag and the unwind goes.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::sync::Mutex;
use std::time::Duration;

use pyo3::prelude::*;

use crate::errors::{message, Kind};

/// How often the calling thread looks for Ctrl-C while the work runs.
const POLL: Duration = Duration::from_millis(50);

/// One thing a long call reports, as the progress callback receives it.
#[pyclass(module = "prt", frozen, get_all)]
#[derive(Clone, Debug)]
pub struct ProgressEvent {
    /// `"start"` (a stage of `total` steps begins), `"advance"` (`steps` more are done),
    /// `"restored"` (`steps` were done by an earlier, interrupted run: count them, but not in
    /// a rate), `"finish"` (the stage is over), `"note"` or `"warning"` (`text`).
    pub kind: &'static str,
    /// The current stage ("tracing", "rendering", ...); `None` outside one.
    pub stage: Option<String>,
    /// Steps of the current stage (0 outside one).
    pub total: u64,
    /// Steps of the current stage done so far, this event's included.
    pub done: u64,
    /// Steps this event adds (`"advance"`, `"restored"`).
    pub steps: u64,
    /// The note's or warning's text.
    pub text: Option<String>,
}

#[pymethods]
impl ProgressEvent {
    fn __repr__(&self) -> String {
        match (&self.text, &self.stage) {
            (Some(t), _) => format!("ProgressEvent({}: {t:?})", self.kind),
            (None, Some(s)) => format!(
                "ProgressEvent({} {s:?}: {}/{})",
                self.kind, self.done, self.total
            ),
            (None, None) => format!("ProgressEvent({})", self.kind),
        }
    }
}

/// What the work thread sends the calling thread.
enum Message {
    Start(String, u64),
    Advance(u64, bool),
    Finish,
    Note(String),
    Warn(String),
}

/// The libraries' [`prt_bake::progress::Progress`], forwarding to the calling thread.
pub struct Reporter {
    /// `None` once the work is over.
    sender: Mutex<Option<Sender<Message>>>,
    cancel: AtomicBool,
}

impl Reporter {
    fn send(&self, m: Message) {
        // A poisoned lock only means another thread panicked while sending; the receiver
        // gone means the call is over. Either way there is no one left to report to.
        if let Ok(Some(s)) = self.sender.lock().as_deref() {
            let _ = s.send(m);
        }
    }

    /// Whether the caller asked to stop (the callback, or Ctrl-C).
    pub fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// Unwinds the work thread if the caller asked to stop. `resume_unwind`, not `panic!`:
    /// no panic hook runs, so nothing is printed.
    fn stop_if_cancelled(&self) {
        if self.cancelled() {
            std::panic::resume_unwind(Box::new(Stopped));
        }
    }

    pub fn start(&self, stage: &str, total: u64) {
        self.stop_if_cancelled();
        self.send(Message::Start(stage.to_string(), total));
    }

    pub fn advance(&self, steps: u64) {
        self.send(Message::Advance(steps, false));
        self.stop_if_cancelled();
    }

    pub fn restored(&self, steps: u64) {
        self.send(Message::Advance(steps, true));
        self.stop_if_cancelled();
    }

    /// Never unwinds: it runs as a stage's guard is dropped, also while unwinding.
    pub fn finish(&self) {
        self.send(Message::Finish);
    }

    pub fn note(&self, text: &str) {
        self.send(Message::Note(text.to_string()));
    }

    pub fn warn(&self, text: &str) {
        self.send(Message::Warn(text.to_string()));
    }
}

/// The payload of the unwind that stops the work when the caller asked to.
struct Stopped;

/// The calling thread's side: the stage, and what stopped the work.
struct Delivery<'py> {
    callback: Option<Bound<'py, PyAny>>,
    stage: Option<(String, u64, u64)>,
    /// The exception that ends the call: the callback's, or Ctrl-C's.
    raised: Option<PyErr>,
    /// The callback returned `False`.
    declined: bool,
}

impl<'py> Delivery<'py> {
    fn deliver(&mut self, py: Python<'py>, m: Message) {
        let event = match m {
            Message::Start(stage, total) => {
                self.stage = Some((stage.clone(), total, 0));
                self.event("start", 0, None)
            }
            Message::Advance(steps, restored) => {
                if let Some((_, total, done)) = &mut self.stage {
                    *done = (*done + steps).min(*total);
                }
                self.event(if restored { "restored" } else { "advance" }, steps, None)
            }
            Message::Finish => {
                let e = self.event("finish", 0, None);
                self.stage = None;
                e
            }
            Message::Note(text) => self.event("note", 0, Some(text)),
            Message::Warn(text) => self.event("warning", 0, Some(text)),
        };
        if self.raised.is_some() || self.declined {
            return;
        }
        let Some(callback) = &self.callback else {
            // Without a callback a warning still reaches the user, as a Python warning.
            if let (Some(text), "warning") = (&event.text, event.kind) {
                if let Err(e) = warn(py, text) {
                    self.raised = Some(e);
                }
            }
            return;
        };
        match callback.call1((event,)) {
            Ok(r) if r.is(pyo3::types::PyBool::new(py, false)) => self.declined = true,
            Ok(_) => {}
            Err(e) => self.raised = Some(e),
        }
    }

    fn event(&self, kind: &'static str, steps: u64, text: Option<String>) -> ProgressEvent {
        let (stage, total, done) = match &self.stage {
            Some((s, t, d)) => (Some(s.clone()), *t, *d),
            None => (None, 0, 0),
        };
        ProgressEvent {
            kind,
            stage,
            total,
            done,
            steps,
            text,
        }
    }
}

/// `warnings.warn(text, prt.PrtWarning)`.
fn warn(py: Python<'_>, text: &str) -> PyResult<()> {
    let category = py.import("prt._errors")?.getattr("PrtWarning")?;
    py.import("warnings")?
        .getattr("warn")?
        .call1((text, category, 2))?;
    Ok(())
}

/// Runs `work` on its own thread with the interpreter's lock released, delivering its progress
/// to `callback` (a callable taking a [`ProgressEvent`]; `None`: warnings become Python
/// warnings, the rest is dropped) on this thread. Returns the work's result, or the exception
/// that stopped it: the callback's, `KeyboardInterrupt`, or [`Kind::Cancelled`] when the
/// callback returned `False` (also when the work finished before it saw the request: the
/// caller asked to stop). A panic in the work is raised as an error naming it.
pub fn run<T: Send>(
    py: Python<'_>,
    callback: Option<Bound<'_, PyAny>>,
    work: impl FnOnce(&Reporter) -> T + Send,
) -> PyResult<T> {
    let (sender, receiver) = channel();
    // Behind a lock only to be shared with the unlocked waits (a receiver is not `Sync`).
    let receiver = Mutex::new(receiver);
    let reporter = Reporter {
        sender: Mutex::new(Some(sender)),
        cancel: AtomicBool::new(false),
    };
    let mut delivery = Delivery {
        callback,
        stage: None,
        raised: None,
        declined: false,
    };
    let finished = std::thread::scope(|scope| {
        let reporter = &reporter;
        let handle = scope.spawn(move || {
            let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(reporter)));
            // Hang up, so the calling thread stops waiting once every message is delivered.
            if let Ok(mut s) = reporter.sender.lock() {
                *s = None;
            }
            out
        });
        loop {
            let received = py.detach(|| match receiver.lock() {
                Ok(r) => r.recv_timeout(POLL),
                Err(_) => Err(RecvTimeoutError::Disconnected),
            });
            match received {
                Ok(m) => delivery.deliver(py, m),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            if delivery.raised.is_none() {
                if let Err(e) = py.check_signals() {
                    delivery.raised = Some(e);
                }
            }
            if delivery.raised.is_some() || delivery.declined {
                reporter.cancel.store(true, Ordering::Relaxed);
            }
        }
        py.detach(|| handle.join())
    });
    let result = match finished {
        Ok(Ok(r)) => Some(r),
        Ok(Err(payload)) | Err(payload) if payload.is::<Stopped>() => None,
        Ok(Err(panic)) | Err(panic) => return Err(crate::errors::panic(panic.as_ref())),
    };
    if let Some(e) = delivery.raised {
        return Err(e);
    }
    match result {
        Some(r) if !delivery.declined => Ok(r),
        _ => Err(message(
            Kind::Cancelled,
            "cancelled: the progress callback returned False".into(),
        )),
    }
}
