//! A counting global allocator with a limit on live heap bytes.
//!
//! Readers must refuse absurd sizes before they allocate; an input that makes a library ask for
//! more than the limit (2 GiB by default) is a finding, not a crash of the machine. An
//! allocation cannot fail gracefully on stable Rust (a null return aborts, an allocator must
//! not unwind), so the first allocation past the limit calls the handler set with
//! [`set_over_limit_handler`], which reports, saves the input and exits. Allocations made
//! while it reports pass through unlimited.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::OnceLock;

/// Called with (requested bytes, live bytes before the request, limit); must not return.
pub type OverLimitHandler = fn(usize, usize, usize);

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static LIMIT: AtomicUsize = AtomicUsize::new(usize::MAX);
static TRIPPED: AtomicBool = AtomicBool::new(false);
static HANDLER: OnceLock<OverLimitHandler> = OnceLock::new();

/// The fuzz binary's global allocator: [`System`] plus accounting.
pub struct Counting;

/// Sets the live-heap limit in bytes.
pub fn set_limit(bytes: usize) {
    LIMIT.store(bytes, Ordering::Relaxed);
}

/// Sets what happens when an allocation would pass the limit.
pub fn set_over_limit_handler(f: OverLimitHandler) {
    let _ = HANDLER.set(f);
}

/// Highest live heap seen so far, in bytes.
pub fn peak() -> usize {
    PEAK.load(Ordering::Relaxed)
}

/// Accounts for `size` more bytes, calling the handler first if that passes the limit.
fn grow(size: usize) {
    let before = LIVE.fetch_add(size, Ordering::Relaxed);
    let now = before.saturating_add(size);
    PEAK.fetch_max(now, Ordering::Relaxed);
    let limit = LIMIT.load(Ordering::Relaxed);
    if now > limit && !TRIPPED.swap(true, Ordering::SeqCst) {
        if let Some(h) = HANDLER.get() {
            h(size, before, limit);
        }
    }
}

fn shrink(size: usize) {
    LIVE.fetch_sub(size, Ordering::Relaxed);
}

// SAFETY: every method forwards to `System` with the caller's arguments unchanged; the
// accounting only reads and writes atomics (the handler, called at most once, may allocate:
// those calls re-enter here and pass through because TRIPPED is set).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grow(layout.size());
        // SAFETY: forwarded unchanged (see the impl's comment).
        let p = unsafe { System.alloc(layout) };
        if p.is_null() {
            shrink(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        grow(layout.size());
        // SAFETY: forwarded unchanged.
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() {
            shrink(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged.
        unsafe { System.dealloc(ptr, layout) };
        shrink(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > layout.size() {
            grow(new_size - layout.size());
        }
        // SAFETY: forwarded unchanged.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if p.is_null() {
            if new_size > layout.size() {
                shrink(new_size - layout.size());
            }
        } else if new_size < layout.size() {
            shrink(layout.size() - new_size);
        }
        p
    }
}
