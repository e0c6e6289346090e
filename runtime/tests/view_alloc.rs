//! A view-only frame of the per-vertex runtime allocates nothing once its buffers have
//! settled (docs/vertex.md, section 4): every allocation made by any thread is counted while
//! frames are rendered for views already seen from the same eye. A binary of its own, so that no other test
//! allocates while it counts.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use prt_formats::pixel::Precision;
use prt_formats::Family;
use prt_runtime::VertexRelighter;

#[allow(dead_code)]
#[path = "vertex/common.rs"]
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

/// A 12 x 12 glossy, textured grid (f16) under an asymmetric lat-long environment: the view
/// stage's lobe, texture, visibility and background paths.
fn bake(path: &std::path::Path) {
    let up = [0.0, 1.0, 0.0];
    let basis = constant_basis(0.06, [0.2, 0.1, 0.05, 0.05], true);
    let mesh = Mesh::grid(12, up, 0);
    let nv = mesh.positions.len();
    let row = t0_rows(up, Some(&basis));
    let rows: Vec<_> = (0..nv).map(|_| row.clone()).collect();
    let mut g = Group::new((0..nv as u32).collect(), &rows, 3, 2, 1);
    for (k, x) in g.t1.iter_mut().chain(g.t2.iter_mut()).enumerate() {
        *x = 0.01 * (k % 5) as f32;
    }
    for (k, v) in g.visibility.iter_mut().enumerate() {
        *v = ((k * 7) % 256) as u8;
    }
    // The second material has no triangles; it gives the group the slot count of the
    // vertex tests' busy bake.
    let materials = vec![
        material("metal", Family::Ggx, [0.3, 0.4, 0.2], [0.8, 0.6, 0.4], 0.3),
        material("wall", Family::Diffuse, [0.6, 0.2, 0.2], [0.0; 3], 0.0),
    ];
    let mut bake = Bake::new(
        mesh,
        materials,
        vec![(0, g, Some(0))],
        vec![basis],
        [1.0; 3],
    );
    bake.meta.precision = Precision::F16;
    bake.meta.reflections = 3;
    bake.set_latlong(64, 32, asymmetric_map(64, 32), 10.0);
    let texels = (0..8 * 8 * 3).map(|k| 0.2 + 0.1 * (k % 7) as f32).collect();
    bake.set_texture(0, 8, 8, texels);
    bake.write(path);
}

#[test]
fn a_view_only_frame_allocates_nothing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("view.prtbake");
    bake(&path);
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
