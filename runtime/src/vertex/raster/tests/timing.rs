//! The rasterizer's frame time (ignored: run with `--ignored --nocapture`; not asserted).

use super::*;

/// Time this thread has spent on a CPU (Linux: /proc/thread-self/schedstat, nanoseconds), so
/// that a measurement on a busy machine counts only the rasterizer's own work.
fn thread_cpu_ns() -> Option<u64> {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// Frame time on ~100K triangles at 640x480 (run with `--ignored --nocapture`; not asserted).
/// On one thread, the on-CPU time is reported too (wall time on a shared machine includes
/// waiting for a core).
#[test]
#[ignore]
fn frame_time_on_100k_triangles() {
    let mut rng = Lcg::new(1);
    let mut mesh = floor(-1.2, 30.0, 60, &mut rng); // 7 200
    mesh.add(&torus([0.0, 0.0, 0.0], 1.2, 0.45, 256, 160)); // 81 920
    mesh.add(&sphere([1.8, -0.4, 1.0], 0.8, 64, 96, 0.05)); // 12 096
    let cam = camera("eye=0.5,1.6,4 target=0,0,0 fov=50");
    let mut r = Rasterizer::new();
    let mut vb = rasterize(&mesh.positions, &mesh.triangles, &cam, 640, 480).expect("raster");
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        let frames = 40;
        let mut wall = Vec::new();
        let mut cpu_ns = Some(0u64);
        for _ in 0..frames {
            // A kept rasterizer and buffer, as a renderer would hold them.
            let t0 = std::time::Instant::now();
            let c = pool.install(|| {
                let c0 = thread_cpu_ns();
                r.render(&mesh.positions, &mesh.triangles, &cam, 640, 480, &mut vb)
                    .expect("raster");
                Some(thread_cpu_ns()? - c0?)
            });
            wall.push(t0.elapsed().as_secs_f64() * 1e3);
            cpu_ns = cpu_ns.zip(c).map(|(a, b)| a + b);
        }
        wall.sort_by(f64::total_cmp);
        let covered = vb.fragments.iter().filter(|f| !f.is_empty()).count();
        let cpu = match (threads, cpu_ns) {
            (1, Some(ns)) => format!("; on-CPU mean {:.2} ms", ns as f64 * 1e-6 / frames as f64),
            _ => String::new(),
        };
        eprintln!(
            "{} triangles, 640x480, {threads} thread(s): wall median {:.2} ms, min {:.2} ms{cpu} \
             ({covered} pixels covered)",
            mesh.triangles.len(),
            wall[wall.len() / 2],
            wall[0],
        );
    }
}
