//! `bench rays`: closest-hit and occlusion ray throughput, coherent and incoherent, on one
//! thread and on all threads.

use std::time::Instant;

use glam::Vec3;
use prt_bake::accel::Accel;
use prt_bake::brdf::BrdfParams;
use prt_bake::sampling::{uniform_sphere, Rng};
use prt_bake::scene::Scene;
use prt_bake::testing::{look_at, SceneBuilder};
use rayon::prelude::*;

/// About 100K triangles: five subdivided spheres on a floor, seen by a camera.
pub fn hundred_k_scene() -> Scene {
    let mut b = SceneBuilder::new();
    let m = b.material(
        "grey",
        BrdfParams::diffuse(Vec3::splat(0.5)),
        Vec3::ZERO,
        false,
    );
    for i in 0..5 {
        let x = (i as f32 - 2.0) * 1.1;
        b.sphere(
            Vec3::new(x, 0.5 + 0.1 * i as f32, -(i % 2) as f32 * 0.7),
            0.5,
            5,
            m,
        );
    }
    b.quad(
        [
            Vec3::new(-4.0, 0.0, -4.0),
            Vec3::new(-4.0, 0.0, 4.0),
            Vec3::new(4.0, 0.0, 4.0),
            Vec3::new(4.0, 0.0, -4.0),
        ],
        m,
    );
    b.camera(look_at(
        Vec3::new(0.0, 1.5, 4.5),
        Vec3::new(0.0, 0.4, 0.0),
        Vec3::Y,
        45f32.to_radians(),
    ));
    b.build()
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct RayFigures {
    pub kind: &'static str,
    pub threads: usize,
    pub rays: u64,
    pub seconds: f64,
    pub rays_per_second: f64,
    pub hits: u64,
}

/// Ray batches: coherent = the camera's primary rays in scanline order; incoherent = random
/// origins inside the scene bounds with uniformly random directions.
fn ray_batch(scene: &Scene, coherent: bool, n: usize) -> Vec<(Vec3, Vec3)> {
    let (lo, hi) = scene.positions.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(a, b), p| (a.min(*p), b.max(*p)),
    );
    let side = (n as f64).sqrt().ceil() as u32;
    let cam = &scene.camera;
    let t = (cam.yfov * 0.5).tan();
    let mut rng = Rng::for_sample(99, 0, 0);
    (0..n)
        .map(|i| {
            if coherent {
                let (x, y) = (
                    (i as u32 % side) as f32 + 0.5,
                    (i as u32 / side) as f32 + 0.5,
                );
                let sx = (2.0 * x / side as f32 - 1.0) * t;
                let sy = (1.0 - 2.0 * y / side as f32) * t;
                (
                    cam.position,
                    (cam.forward + cam.right * sx + cam.up * sy).normalize(),
                )
            } else {
                let o = lo + (hi - lo) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                (o, uniform_sphere(rng.next_vec2()))
            }
        })
        .collect()
}

/// Measures closest-hit and occlusion throughput, coherent and incoherent, on one thread and
/// on all threads.
pub fn ray_throughput(scene: &Scene, rays: usize) -> Vec<RayFigures> {
    let accel = Accel::build(scene);
    let mut out = Vec::new();
    let all = rayon::current_num_threads();
    for (kind, coherent, shadow) in [
        ("coherent closest-hit", true, false),
        ("incoherent closest-hit", false, false),
        ("incoherent occlusion", false, true),
    ] {
        let batch = ray_batch(scene, coherent, rays);
        for threads in [1, all] {
            let pool = match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
                Ok(p) => p,
                Err(_) => continue,
            };
            let start = Instant::now();
            let hits: u64 = pool.install(|| {
                batch
                    .par_chunks(4096)
                    .map(|c| {
                        c.iter()
                            .filter(|(o, d)| {
                                if shadow {
                                    accel.occluded(*o, *d, 0.0, 1.0)
                                } else {
                                    accel.intersect(*o, *d, 0.0, f32::INFINITY).is_some()
                                }
                            })
                            .count() as u64
                    })
                    .sum()
            });
            let seconds = start.elapsed().as_secs_f64();
            out.push(RayFigures {
                kind,
                threads,
                rays: rays as u64,
                seconds,
                rays_per_second: rays as f64 / seconds.max(1e-12),
                hits,
            });
        }
    }
    out
}

/// Prints the figures as a table.
pub fn print(scene: &Scene, rays: usize, figures: &[RayFigures]) {
    println!(
        "ray throughput, {} triangles, {} rays per measurement",
        scene.triangles.len(),
        rays
    );
    println!("{:<24} {:>8} {:>14}", "kind", "threads", "Mrays/s");
    for f in figures {
        println!(
            "{:<24} {:>8} {:>14.2}",
            f.kind,
            f.threads,
            f.rays_per_second / 1e6
        );
    }
}
