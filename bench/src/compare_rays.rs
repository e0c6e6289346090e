//! `bench compare-rays`: the ray side of the comparison with Embree (bench/compare/compare.py,
//! docs/compare.md).
//!
//! `dump` writes a scene's triangles and a deterministic set of incoherent rays (cosine-
//! distributed bounce rays leaving the surface points a camera sees) as raw little-endian
//! arrays that numpy reads with `np.fromfile`, plus our own closest hits and occlusion
//! answers for them, so another ray tracer can be given exactly the same queries and checked
//! ray by ray. `time` loads a dump, builds our `Accel` over its triangles and times closest-hit
//! and occlusion queries on exactly those rays, on one thread and on all threads.
//!
//! Files of scene `NAME` in the dump folder (n = triangles, m = rays):
//!
//! ```text
//! NAME.json           manifest: counts, file names, seed, eps, tmin/tmax, checksums
//! NAME-triangles.f32  n x 3 x 3 float32: vertex 0, 1, 2 of each triangle, x y z each
//! NAME-rays.f32       m x 6 float32: origin x y z, unit direction x y z
//! NAME-hit-t.f32      m float32: our closest-hit distance, +inf where the ray misses
//! NAME-hit-tri.i32    m int32: index of the triangle hit (into NAME-triangles), -1 on a miss
//! NAME-occluded.u8    m uint8: 1 where our occlusion query over (0, inf) says blocked
//! ```
//!
//! Every ray is a query over t in (0, +inf): the origins are already offset off the surface
//! (by 1e-4 of the scene's extent along the geometric normal, as the baker offsets its rays),
//! so both tracers start at t = 0.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use glam::Vec3;
use prt_bake::accel::{Accel, Ray};
use prt_bake::brdf::{cosine_hemisphere, BrdfParams};
use prt_bake::sampling::Rng;
use prt_bake::scene::Scene;
use prt_bake::testing::{look_at, SceneBuilder};
use rayon::prelude::*;

/// Version of the dump layout; a manifest with another version is rewritten.
const FORMAT: u32 = 1;
/// Camera rays tried per bounce ray before giving up on a scene the camera hardly sees.
const CAMERA_TRIES: u32 = 64;
/// Rays per parallel work item in the timed loops.
const CHUNK: usize = 4096;

#[derive(clap::Args, Debug)]
pub struct CompareRaysArgs {
    #[command(subcommand)]
    pub action: Action,
}

#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Write triangles, rays and our hits of each scene as raw arrays (skipped where the
    /// folder already holds the same dump).
    Dump {
        /// Output folder.
        #[arg(long, default_value = "target/compare/rays")]
        dir: PathBuf,
        /// Scenes: `cornell` (scenes/cornell, ~6K triangles), `100k` (`bench rays`' spheres),
        /// `1m` (~1M triangles of spheres), or a bake config / scene folder (named after its
        /// file or folder).
        #[arg(long = "scene", default_values = ["cornell", "100k", "1m"])]
        scenes: Vec<String>,
        /// Rays per scene.
        #[arg(long, default_value_t = 2_000_000)]
        rays: usize,
        /// Seed of the ray generator.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Rewrite even where an identical dump exists.
        #[arg(long)]
        force: bool,
    },
    /// Time our ray core on a dump: closest hit and occlusion, one thread and all threads;
    /// prints one JSON object (medians over --rounds), or with --serve one JSON line per line
    /// read on stdin (for the interleaved run of bench/compare/compare.py).
    Time {
        #[arg(long, default_value = "target/compare/rays")]
        dir: PathBuf,
        /// Scene name of the dump (NAME.json in --dir).
        #[arg(long)]
        scene: String,
        #[arg(long, default_value_t = 3)]
        rounds: usize,
        /// Run one round per line read on stdin, printing its figures as one JSON line; stop
        /// at the end of input.
        #[arg(long)]
        serve: bool,
    },
}

pub fn run(args: &CompareRaysArgs) -> Result<()> {
    match &args.action {
        Action::Dump {
            dir,
            scenes,
            rays,
            seed,
            force,
        } => {
            if *rays == 0 {
                bail!("--rays must be at least 1");
            }
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
            let mut manifests = Vec::new();
            for spec in scenes {
                manifests.push(dump(dir, spec, *rays, *seed, *force)?);
            }
            println!("{}", serde_json::to_string(&manifests)?);
            Ok(())
        }
        Action::Time {
            dir,
            scene,
            rounds,
            serve,
        } => time(dir, scene, (*rounds).max(1), *serve),
    }
}

// ------------------------------------------------------------------------------------------
// Scenes

/// About a million triangles: twelve spheres of 81 920 triangles each (icosphere level 6) in a
/// 4 x 3 grid on a floor, seen by a camera from the front and above.
pub fn million_scene() -> Scene {
    let mut b = SceneBuilder::new();
    let m = b.material(
        "grey",
        BrdfParams::diffuse(Vec3::splat(0.5)),
        Vec3::ZERO,
        false,
    );
    for row in 0..3 {
        for col in 0..4 {
            let x = (col as f32 - 1.5) * 1.1;
            let z = -(row as f32) * 1.1;
            b.sphere(Vec3::new(x, 0.45 + 0.05 * col as f32, z), 0.45, 6, m);
        }
    }
    b.quad(
        [
            Vec3::new(-4.0, 0.0, -5.0),
            Vec3::new(-4.0, 0.0, 3.0),
            Vec3::new(4.0, 0.0, 3.0),
            Vec3::new(4.0, 0.0, -5.0),
        ],
        m,
    );
    b.camera(look_at(
        Vec3::new(0.0, 2.0, 4.0),
        Vec3::new(0.0, 0.3, -1.1),
        Vec3::Y,
        45f32.to_radians(),
    ));
    b.build()
}

/// A scene by name, with its name in the dump and the camera's aspect ratio (width / height).
fn scene_by_spec(spec: &str) -> Result<(String, Scene, f32)> {
    let named = match spec {
        "cornell" => Some(PathBuf::from("scenes/cornell/bake.toml")),
        "100k" => return Ok(("100k".into(), prt_bench::rays::hundred_k_scene(), 1.0)),
        "1m" => return Ok(("1m".into(), million_scene(), 1.0)),
        _ => None,
    };
    let mut path = named.clone().unwrap_or_else(|| PathBuf::from(spec));
    if path.is_dir() {
        path = path.join("bake.toml");
    }
    if !path.is_file() {
        bail!(
            "--scene {spec}: not cornell, 100k, 1m, a bake config or a scene folder{}",
            if named.is_some() {
                " (run from the repository root)"
            } else {
                ""
            }
        );
    }
    let (config, scene) = prt_bake::run::load(&path, &prt_bake::progress::Silent)
        .with_context(|| format!("--scene {spec}"))?;
    let name = if named.is_some() {
        spec.to_string()
    } else {
        let stem = if path.file_name().is_some_and(|f| f == "bake.toml") {
            path.parent().and_then(|p| p.file_name())
        } else {
            path.file_stem()
        };
        stem.map_or("scene".into(), |s| s.to_string_lossy().into_owned())
    };
    if !name
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.')
    {
        bail!("--scene {spec}: name {name:?} has characters unfit for a file name");
    }
    let aspect = config.width as f32 / config.height.max(1) as f32;
    Ok((name, scene, aspect))
}

// ------------------------------------------------------------------------------------------
// Rays

/// An orthonormal frame around unit `n` (Duff et al. 2017): tangent, bitangent.
fn frame(n: Vec3) -> (Vec3, Vec3) {
    let s = 1f32.copysign(n.z);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x),
        Vec3::new(b, s + n.y * n.y * a, -n.y),
    )
}

/// The ray-origin offset the baker uses: 1e-4 of the scene's extent.
fn origin_offset(scene: &Scene) -> f32 {
    let extent = scene
        .positions
        .iter()
        .fold(0.0f32, |m, p| m.max(p.abs().max_element()));
    1e-4 * extent.max(1e-3)
}

/// `n` bounce rays: ray i traces a camera ray through a uniformly random film point (retrying
/// where it misses), takes the surface point hit, and leaves it along a cosine-distributed
/// direction about the geometric normal on the side the camera ray came from, starting `eps`
/// off the surface. Ray i depends on (seed, i) only, so the set is the same on any number of
/// threads.
pub fn bounce_rays(
    scene: &Scene,
    accel: &Accel,
    n: usize,
    seed: u64,
    aspect: f32,
) -> Result<Vec<[f32; 6]>> {
    let eps = origin_offset(scene);
    let cam = &scene.camera;
    let tan = (cam.yfov * 0.5).tan();
    let rays: Vec<Option<[f32; 6]>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let mut rng = Rng::for_sample(seed, i as u64, 0);
            for _ in 0..CAMERA_TRIES {
                let film = rng.next_vec2();
                let sx = (2.0 * film.x - 1.0) * tan * aspect;
                let sy = (1.0 - 2.0 * film.y) * tan;
                let dir = (cam.forward + cam.right * sx + cam.up * sy).normalize();
                let u = rng.next_vec2();
                let Some(hit) = accel.intersect(cam.position, dir, 0.0, f32::INFINITY) else {
                    continue;
                };
                let [a, b, c] =
                    scene.triangles[hit.triangle as usize].map(|v| scene.positions[v as usize]);
                let p = a + (b - a) * hit.bary.x + (c - a) * hit.bary.y;
                let mut ng = (b - a).cross(c - a).normalize();
                if ng.dot(dir) > 0.0 {
                    ng = -ng;
                }
                let (t, bt) = frame(ng);
                let local = cosine_hemisphere(u);
                let d = (t * local.x + bt * local.y + ng * local.z).normalize();
                let o = p + ng * eps;
                return Some([o.x, o.y, o.z, d.x, d.y, d.z]);
            }
            None
        })
        .collect();
    let missed = rays.iter().filter(|r| r.is_none()).count();
    if missed > 0 {
        bail!(
            "the camera sees too little of the scene: {missed} of {n} rays found no surface in \
             {CAMERA_TRIES} camera rays"
        );
    }
    Ok(rays.into_iter().flatten().collect())
}

/// Our closest hits (distance, triangle or -1) and occlusion answers over (0, inf).
fn our_hits(accel: &Accel, rays: &[[f32; 6]]) -> (Vec<f32>, Vec<i32>, Vec<u8>) {
    let closest: Vec<(f32, i32)> = rays
        .par_iter()
        .map(|r| {
            let (o, d) = split(r);
            accel
                .intersect(o, d, 0.0, f32::INFINITY)
                .map_or((f32::INFINITY, -1), |h| (h.t, h.triangle as i32))
        })
        .collect();
    let occluded: Vec<u8> = rays
        .par_iter()
        .map(|r| {
            let (o, d) = split(r);
            accel.occluded(o, d, 0.0, f32::INFINITY) as u8
        })
        .collect();
    let (t, tri) = closest.into_iter().unzip();
    (t, tri, occluded)
}

#[inline]
fn split(r: &[f32; 6]) -> (Vec3, Vec3) {
    (Vec3::new(r[0], r[1], r[2]), Vec3::new(r[3], r[4], r[5]))
}

// ------------------------------------------------------------------------------------------
// Dump files

fn write_f32(path: &Path, values: impl Iterator<Item = f32>) -> Result<()> {
    let bytes: Vec<u8> = values.flat_map(f32::to_le_bytes).collect();
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}

fn read_f32(path: &Path) -> Result<Vec<f32>> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    if bytes.len() % 4 != 0 {
        bail!("{}: length not a multiple of 4", path.display());
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// FNV-1a over the triangles' bytes: tells whether an existing dump is of the same geometry.
fn geometry_hash(tris: &[f32]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for v in tris {
        for b in v.to_le_bytes() {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
    format!("{h:016x}")
}

/// Hit counts and the sum of hit triangle indices: what both tracers can compute cheaply from
/// their answers, so a timed run can be checked against the dumped hits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Checksum {
    pub hits: u64,
    pub triangle_sum: u64,
}

fn files(name: &str) -> serde_json::Value {
    serde_json::json!({
        "triangles": format!("{name}-triangles.f32"),
        "rays": format!("{name}-rays.f32"),
        "hit_t": format!("{name}-hit-t.f32"),
        "hit_triangle": format!("{name}-hit-tri.i32"),
        "occluded": format!("{name}-occluded.u8"),
    })
}

fn dump(dir: &Path, spec: &str, n: usize, seed: u64, force: bool) -> Result<serde_json::Value> {
    let (name, scene, aspect) = scene_by_spec(spec)?;
    let tris: Vec<f32> = scene
        .triangles
        .iter()
        .flat_map(|t| t.map(|v| scene.positions[v as usize].to_array()))
        .flatten()
        .collect();
    let hash = geometry_hash(&tris);
    let manifest_path = dir.join(format!("{name}.json"));
    if !force {
        if let Ok(text) = std::fs::read_to_string(&manifest_path) {
            if let Ok(old) = serde_json::from_str::<serde_json::Value>(&text) {
                let same = old["format"] == FORMAT
                    && old["rays"] == n as u64
                    && old["seed"] == seed
                    && old["geometry_hash"] == hash.as_str()
                    && old["aspect"] == aspect as f64;
                let present = old["files"].as_object().is_some_and(|f| {
                    f.values()
                        .all(|v| v.as_str().is_some_and(|s| dir.join(s).is_file()))
                });
                if same && present {
                    eprintln!("{name}: dump in {} is current", dir.display());
                    return Ok(old);
                }
            }
        }
    }
    eprintln!(
        "{name}: {} triangles, building and tracing {n} rays",
        scene.triangles.len()
    );
    let accel = Accel::build(&scene);
    let rays = bounce_rays(&scene, &accel, n, seed, aspect)?;
    let (hit_t, hit_tri, occluded) = our_hits(&accel, &rays);
    let checksum = Checksum {
        hits: hit_tri.iter().filter(|&&t| t >= 0).count() as u64,
        triangle_sum: hit_tri.iter().filter(|&&t| t >= 0).map(|&t| t as u64).sum(),
    };
    let occluded_count = occluded.iter().filter(|&&o| o != 0).count() as u64;
    let f = files(&name);
    let path = |key: &str| dir.join(f[key].as_str().unwrap_or_default());
    write_f32(&path("triangles"), tris.iter().copied())?;
    write_f32(&path("rays"), rays.iter().flatten().copied())?;
    write_f32(&path("hit_t"), hit_t.iter().copied())?;
    let tri_bytes: Vec<u8> = hit_tri.iter().flat_map(|t| t.to_le_bytes()).collect();
    std::fs::write(path("hit_triangle"), tri_bytes)
        .with_context(|| format!("writing {}", path("hit_triangle").display()))?;
    std::fs::write(path("occluded"), &occluded)
        .with_context(|| format!("writing {}", path("occluded").display()))?;
    let manifest = serde_json::json!({
        "format": FORMAT,
        "name": name,
        "source": spec,
        "triangles": scene.triangles.len(),
        "rays": n,
        "seed": seed,
        "aspect": aspect as f64,
        "eps": origin_offset(&scene),
        "tmin": 0.0,
        "tmax": "inf",
        "geometry_hash": hash,
        "generator": "cosine-distributed bounce rays about the geometric normal, leaving the \
                      first hits of camera rays through uniform random film points, origins \
                      offset by eps along the normal",
        "files": f,
        "closest": checksum,
        "occluded": occluded_count,
    });
    std::fs::write(&manifest_path, serde_json::to_string_pretty(&manifest)?)
        .with_context(|| format!("writing {}", manifest_path.display()))?;
    Ok(manifest)
}

/// A dump read back: the manifest, an `Accel` over its triangles, and its rays.
struct Loaded {
    manifest: serde_json::Value,
    accel: Accel,
    triangles: usize,
    rays: Vec<[f32; 6]>,
}

fn load(dir: &Path, name: &str) -> Result<Loaded> {
    let manifest_path = dir.join(format!("{name}.json"));
    let text = std::fs::read_to_string(&manifest_path).with_context(|| {
        format!(
            "reading {} (write it with `bench compare-rays dump --scene {name}`)",
            manifest_path.display()
        )
    })?;
    let manifest: serde_json::Value =
        serde_json::from_str(&text).with_context(|| manifest_path.display().to_string())?;
    if manifest["format"] != FORMAT {
        bail!(
            "{}: dump format {} (this bench reads {FORMAT}); dump again",
            manifest_path.display(),
            manifest["format"]
        );
    }
    let file = |key: &str| -> Result<PathBuf> {
        manifest["files"][key]
            .as_str()
            .map(|s| dir.join(s))
            .with_context(|| format!("{}: no files.{key}", manifest_path.display()))
    };
    let tris = read_f32(&file("triangles")?)?;
    let flat = read_f32(&file("rays")?)?;
    if tris.len() % 9 != 0 || flat.len() % 6 != 0 {
        bail!("{}: truncated arrays", dir.display());
    }
    if tris.iter().chain(&flat).any(|v| !v.is_finite()) {
        bail!("{}: non-finite triangle or ray values", dir.display());
    }
    let positions: Vec<Vec3> = tris
        .chunks_exact(3)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect();
    let indices: Vec<[u32; 3]> = (0..positions.len() as u32 / 3)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    let mut b = SceneBuilder::new();
    let m = b.material("any", BrdfParams::diffuse(Vec3::ONE), Vec3::ZERO, false);
    b.mesh(&positions, &vec![Vec3::Y; positions.len()], &indices, m);
    let scene = b.build();
    let accel = Accel::build(&scene);
    let rays = flat
        .chunks_exact(6)
        .map(|c| [c[0], c[1], c[2], c[3], c[4], c[5]])
        .collect();
    Ok(Loaded {
        manifest,
        accel,
        triangles: indices.len(),
        rays,
    })
}

// ------------------------------------------------------------------------------------------
// Timing

#[derive(Clone, Debug, serde::Serialize)]
pub struct Timed {
    pub query: &'static str,
    pub threads: usize,
    pub seconds: f64,
    pub mrays_per_second: f64,
    pub checksum: Checksum,
}

/// The timed queries: one ray at a time (`Accel::intersect`, `Accel::occluded`, what Embree's
/// `rtcIntersect1` / `rtcOccluded1` answer) and as streams (`Accel::intersect_stream`,
/// `Accel::occluded_stream`: the same answers, several rays in flight).
const QUERIES: [&str; 4] = ["closest", "occlusion", "closest-stream", "occlusion-stream"];

/// One timed pass of `query` (one of `QUERIES`) over all rays in `pool`.
fn timed_pass(
    pool: &rayon::ThreadPool,
    accel: &Accel,
    rays: &[[f32; 6]],
    query: &'static str,
) -> Timed {
    let closest = query.starts_with("closest");
    let stream = query.ends_with("-stream");
    let start = Instant::now();
    let checksum = pool.install(|| {
        rays.par_chunks(CHUNK)
            .map(|chunk| {
                let mut c = Checksum {
                    hits: 0,
                    triangle_sum: 0,
                };
                if stream {
                    let rays: Vec<Ray> = chunk
                        .iter()
                        .map(|r| {
                            let (o, d) = split(r);
                            Ray::new(o, d)
                        })
                        .collect();
                    if closest {
                        let mut hits = vec![None; rays.len()];
                        accel.intersect_stream(&rays, &mut hits);
                        for h in hits.iter().flatten() {
                            c.hits += 1;
                            c.triangle_sum += h.triangle as u64;
                        }
                    } else {
                        let mut blocked = vec![false; rays.len()];
                        accel.occluded_stream(&rays, &mut blocked);
                        c.hits += blocked.iter().filter(|&&b| b).count() as u64;
                    }
                    return c;
                }
                for r in chunk {
                    let (o, d) = split(r);
                    if closest {
                        if let Some(h) = accel.intersect(o, d, 0.0, f32::INFINITY) {
                            c.hits += 1;
                            c.triangle_sum += h.triangle as u64;
                        }
                    } else if accel.occluded(o, d, 0.0, f32::INFINITY) {
                        c.hits += 1;
                    }
                }
                c
            })
            .reduce(
                || Checksum {
                    hits: 0,
                    triangle_sum: 0,
                },
                |a, b| Checksum {
                    hits: a.hits + b.hits,
                    triangle_sum: a.triangle_sum + b.triangle_sum,
                },
            )
    });
    let seconds = start.elapsed().as_secs_f64();
    Timed {
        query,
        threads: pool.current_num_threads(),
        seconds,
        mrays_per_second: rays.len() as f64 / seconds.max(1e-12) / 1e6,
        checksum,
    }
}

fn time(dir: &Path, name: &str, rounds: usize, serve: bool) -> Result<()> {
    let loaded = load(dir, name)?;
    let all = rayon::current_num_threads();
    let mut pools = Vec::new();
    for threads in if all > 1 { vec![1, all] } else { vec![1] } {
        pools.push(
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .context("thread pool")?,
        );
    }
    let round = || -> Vec<Timed> {
        let mut out = Vec::new();
        for query in QUERIES {
            for pool in &pools {
                out.push(timed_pass(pool, &loaded.accel, &loaded.rays, query));
            }
        }
        out
    };
    let head = serde_json::json!({
        "scene": name,
        "triangles": loaded.triangles,
        "rays": loaded.rays.len(),
        "dump_closest": loaded.manifest["closest"],
        "dump_occluded": loaded.manifest["occluded"],
    });
    if serve {
        // One round per input line, one JSON line out: the caller interleaves other tracers
        // between our rounds while this process (and its built BVH) waits.
        println!("{}", serde_json::json!({"ready": head}));
        std::io::stdout().flush()?;
        for line in std::io::stdin().lock().lines() {
            line?;
            println!("{}", serde_json::json!({"round": round()}));
            std::io::stdout().flush()?;
        }
        return Ok(());
    }
    let runs: Vec<Vec<Timed>> = (0..rounds).map(|_| round()).collect();
    let medians: Vec<serde_json::Value> = (0..runs[0].len())
        .map(|k| {
            let mut s: Vec<f64> = runs.iter().map(|r| r[k].seconds).collect();
            s.sort_by(f64::total_cmp);
            let median = s[s.len() / 2];
            let f = &runs[0][k];
            serde_json::json!({
                "query": f.query,
                "threads": f.threads,
                "seconds_median": median,
                "mrays_per_second": loaded.rays.len() as f64 / median.max(1e-12) / 1e6,
                "checksum": f.checksum,
            })
        })
        .collect();
    println!(
        "{}",
        serde_json::json!({"scene": head, "rounds": rounds, "results": medians})
    );
    Ok(())
}
