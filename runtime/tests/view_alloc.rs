//! A view-only frame of the per-vertex runtime allocates nothing once its buffers have
//! settled (docs/vertex.md, section 4): every allocation made by any thread is counted while
//! frames are rendered for views already seen from the same eye. A binary of its own, so that no other test
//! allocates while it counts.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use prt_runtime::VertexRelighter;

#[allow(dead_code)]
#[path = "vertex/common/mod.rs"]
mod common;
use common::*;

/// The system allocator, counting allocations while `COUNTING` is set.
struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is passed on to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        System.alloc(layout)
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn a_view_only_frame_allocates_nothing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("view.prtbake");
    glossy_grid().write(&path);
    let mut r = VertexRelighter::open(&path).expect("open");
    // One eye looking two ways: a new eye also runs the eye-inside-geometry check, whose
    // verdict (`prt_formats::view::judge_eye`, shared with the baker) holds a per-material
    // tally, so a moving eye allocates that one small vector per frame.
    let eye = [0.4, 1.5, 2.0];
    let look = |target: [f32; 3], fov_deg: f32| {
        prt_formats::view::CameraSpec {
            eye,
            target,
            fov_deg,
        }
        .frame()
        .expect("camera")
    };
    let cams = [look([0.0; 3], 60.0), look([-0.8, 0.3, -0.5], 75.0)];
    let (w, h) = (48u32, 40u32);
    let mut out = vec![0.0f32; 3 * (w * h) as usize];
    // The first frames run the light and material stages and size the buffers.
    for cam in &cams {
        frame(&mut r, cam, w, h, &mut out).expect("render");
    }
    let lit = out.iter().filter(|&&v| v > 0.0).count();
    assert!(lit > out.len() / 2, "the frame is mostly black: {lit} lit");
    COUNTING.store(true, Ordering::SeqCst);
    for _ in 0..3 {
        for cam in &cams {
            frame(&mut r, cam, w, h, &mut out).expect("render");
        }
    }
    COUNTING.store(false, Ordering::SeqCst);
    let n = ALLOCATIONS.load(Ordering::SeqCst);
    println!("allocations in 6 view-only frames: {n}");
    assert_eq!(n, 0, "view-only frames allocated {n} times");
}
