//! A per-vertex bake's working memory does not grow with the vertex count (docs/vertex.md,
//! "Bounded memory"): the scene is traced and compressed a few units of vertices at a time and
//! each unit is written out as it finishes, so the peak of the heap above what the caller held
//! before the bake is bounded by the units in flight, not by the scene's tensors.
//!
//! Measured with the allocator's own counter (a global allocator that tracks the live bytes
//! and their peak), not with time or the resident set: its own test binary, one test, so no
//! other test's allocations are counted.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::Vec3;
use prt_bake::basis::shading::default_shading_basis;
use prt_bake::brdf::{BrdfParams, Family};
use prt_bake::scene::{Environment, Scene};
use prt_bake::testing::SceneBuilder;
use prt_bake::vertex::{bake_vertex, default_compression, VertexBakeOptions};
use prt_formats::pixel::Precision;
use prt_tests::{small_basis, temp_path};

/// Live heap bytes and their peak since the last reset.
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

struct Tracking;

fn grew(bytes: usize) {
    let now = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

// SAFETY: every call is forwarded to the system allocator unchanged; the counters only
// observe sizes.
unsafe impl GlobalAlloc for Tracking {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc_zeroed(layout);
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout);
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = System.realloc(ptr, layout, new_size);
        if !p.is_null() {
            if new_size >= layout.size() {
                grew(new_size - layout.size());
            } else {
                LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

#[global_allocator]
static GLOBAL: Tracking = Tracking;

/// A rolling terrain of `n` x `n` quads with smooth normals (nothing to weld: every grid
/// point is a vertex) and an editable GGX sphere on it, under a constant sky.
fn terrain(n: u32) -> Scene {
    let mut b = SceneBuilder::new();
    let ground = b.material(
        "ground",
        BrdfParams::diffuse(Vec3::splat(0.5)),
        Vec3::ZERO,
        true,
    );
    let ball = b.material(
        "ball",
        BrdfParams {
            family: Family::Ggx,
            kd: Vec3::splat(0.2),
            ks: Vec3::splat(0.5),
            param: 0.3,
        },
        Vec3::ZERO,
        true,
    );
    let h = |x: f32, z: f32| 0.05 * (3.0 * x).sin() * (2.0 * z).cos();
    let side = 4.0;
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let x = side * (i as f32 / n as f32 - 0.5);
            let z = side * (j as f32 / n as f32 - 0.5);
            positions.push(Vec3::new(x, h(x, z), z));
            let (dx, dz) = (
                0.15 * (3.0 * x).cos() * (2.0 * z).cos(),
                -0.1 * (3.0 * x).sin() * (2.0 * z).sin(),
            );
            normals.push(Vec3::new(-dx, 1.0, -dz).normalize());
        }
    }
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            triangles.push([a, a + n + 1, a + 1]);
            triangles.push([a + 1, a + n + 1, a + n + 2]);
        }
    }
    b.mesh(&positions, &normals, &triangles, ground);
    b.sphere(Vec3::new(0.0, 0.5, 0.0), 0.4, 3, ball);
    b.environment(Environment::Constant(Vec3::new(0.8, 0.9, 1.0)));
    b.build()
}

/// The heap's peak above its level at the start, over a compressed bake of `scene`; and the
/// vertex count.
fn bake_peak(scene: &Scene, name: &str) -> (usize, usize) {
    let bases = vec![small_basis(Family::Ggx, 4)];
    let shading = vec![default_shading_basis(Family::Ggx).expect("GGX shading basis")];
    let opts = VertexBakeOptions {
        samples: 8,
        secondary: 1,
        reflections: 2,
        precision: Precision::F16,
        compression: Some(default_compression()),
        ..Default::default()
    };
    let path = temp_path(name);
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let result = bake_vertex(scene, &bases, &shading, &opts, &path, None).expect("bake");
    let peak = PEAK.load(Ordering::Relaxed) - base;
    let _ = std::fs::remove_file(&path);
    (peak, result.meta.vertices as usize)
}

#[test]
fn working_memory_stays_flat_when_the_vertex_count_grows_8x() {
    // Two threads on any machine: the units in flight (and so the peak) do not depend on it.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("thread pool");
    let small = terrain(44);
    let large = terrain(143);
    let (small_peak, small_vertices) = pool.install(|| bake_peak(&small, "memory-small"));
    let (large_peak, large_vertices) = pool.install(|| bake_peak(&large, "memory-large"));
    let growth = large_vertices as f64 / small_vertices as f64;
    let ratio = large_peak as f64 / small_peak as f64;
    eprintln!(
        "{small_vertices} vertices: peak {:.1} MB; {large_vertices} vertices: peak {:.1} MB \
         ({growth:.2}x the vertices, {ratio:.3}x the memory)",
        small_peak as f64 / 1e6,
        large_peak as f64 / 1e6
    );
    assert!(
        growth >= 7.9,
        "the large scene has {growth:.2}x the vertices"
    );
    assert!(
        ratio <= 1.25,
        "the working memory grew {ratio:.3}x for {growth:.2}x the vertices"
    );
}
