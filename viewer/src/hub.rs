//! What the server's threads share: the open tabs (each one's latest settings not yet
//! rendered, whether a frame is on its way, its socket's queue, the frame it shows) and the
//! reference job wanted. The HTTP side (`server.rs`) writes requests in; the render and
//! reference threads (`pipeline.rs`) take them out.

use std::collections::HashMap;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};

use tokio::sync::mpsc;

use crate::render::LinearFrame;
use crate::settings::{BakeInfo, Encoding, Settings};

/// The reference job now wanted.
#[derive(Default)]
pub(crate) struct RefState {
    pub job: Option<RefJob>,
    /// Bumped whenever the job changes or stops: a running job whose generation is no longer
    /// this stops after its pass.
    pub generation: u64,
}

/// The reference for a tab's settings.
pub(crate) struct RefJob {
    pub session: u64,
    pub generation: u64,
    pub settings: Settings,
}

/// A message for one tab's socket.
pub(crate) enum Outgoing {
    /// A frame: its description, then its pixels; the render thread sends the tab no other
    /// frame until this one is written ([`Shared::frame_sent`]).
    Frame { meta: String, pixels: Vec<u8> },
    /// A refused frame: the settings go back to the last ones rendered.
    Refused {
        seq: u64,
        message: String,
        good: Box<Settings>,
    },
    /// A reference pass: its description, the reference and the difference images.
    Reference {
        meta: String,
        reference: Vec<u8>,
        difference: Vec<u8>,
    },
    /// A plain message.
    Text(String),
}

/// What the render thread should render for a tab.
pub(crate) struct Job {
    pub seq: u64,
    pub settings: Settings,
    pub encoding: Encoding,
}

/// One tab.
pub(crate) struct Slot {
    /// The latest settings asked for and not yet rendered (a newer request replaces it).
    pub pending: Option<Job>,
    /// A frame is on its way to the socket.
    pub in_flight: bool,
    pub out: mpsc::UnboundedSender<Outgoing>,
    /// The frame shown now (for save and the reference's difference).
    pub shown: Option<Arc<LinearFrame>>,
    /// The settings of the last frame rendered.
    pub good: Settings,
    /// Whether the reference toggle is on.
    pub reference: bool,
}

/// The tabs and what the threads share.
pub(crate) struct Hub {
    pub sessions: HashMap<u64, Slot>,
    pub next_id: u64,
    pub stop: bool,
}

/// What the server's threads share.
pub(crate) struct Shared {
    pub info: BakeInfo,
    pub info_json: String,
    pub initial: Settings,
    /// The environment folder as given on the command line (for the command).
    pub env_folder: Option<String>,
    pub hub: Mutex<Hub>,
    pub wake: Condvar,
    pub reference: Mutex<RefState>,
    pub reference_wake: Condvar,
}

impl Shared {
    /// The hub, even if a thread panicked holding it (the sessions stay usable).
    pub(crate) fn hub(&self) -> MutexGuard<'_, Hub> {
        self.hub.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub(crate) fn references(&self) -> MutexGuard<'_, RefState> {
        self.reference.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub(crate) fn register(&self, out: mpsc::UnboundedSender<Outgoing>) -> u64 {
        let mut hub = self.hub();
        hub.next_id += 1;
        let id = hub.next_id;
        hub.sessions.insert(
            id,
            Slot {
                pending: None,
                in_flight: false,
                out,
                shown: None,
                good: self.initial.clone(),
                reference: false,
            },
        );
        id
    }

    pub(crate) fn unregister(&self, id: u64) {
        self.hub().sessions.remove(&id);
        self.set_reference(id, false);
    }

    /// Asks for a frame of `job` for tab `id`, replacing any not yet rendered.
    pub(crate) fn submit(&self, id: u64, job: Job) {
        if let Some(slot) = self.hub().sessions.get_mut(&id) {
            slot.pending = Some(job);
        }
        self.wake.notify_all();
    }

    /// The tab's frame has been written to its socket: it may get the next.
    pub(crate) fn frame_sent(&self, id: u64) {
        if let Some(slot) = self.hub().sessions.get_mut(&id) {
            slot.in_flight = false;
        }
        self.wake.notify_all();
    }

    pub(crate) fn set_reference(&self, id: u64, on: bool) {
        if let Some(slot) = self.hub().sessions.get_mut(&id) {
            slot.reference = on;
        }
        if !on {
            let mut r = self.references();
            if r.job.as_ref().is_some_and(|j| j.session == id) {
                r.job = None;
                r.generation += 1;
            }
        }
        self.reference_wake.notify_all();
    }
}
