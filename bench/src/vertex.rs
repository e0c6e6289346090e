//! The per-vertex report (`docs/report-vertex.md`): one scene baked dense and with several
//! compression settings (the knobs of docs/vertex.md section 7), each relit under the baked
//! light and a turned studio map and compared with the dense relight and with the reference
//! tracer, and the three runtime paths timed in interleaved rounds: view only (the view stage
//! runs every frame), view + BRDF (a material edit), view + BRDF + light (a rotation of the
//! environment as well).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result};
use prt_bake::config::{EnvironmentConfig, VertexConfig};
use prt_bake::progress::Silent;
use prt_bake::run::{load, run_vertex, VertexRunSettings};
use prt_formats::pixel::Precision;
use prt_runtime::vertex::VertexRelighter;

use crate::util::{median, ms, pct};

/// The report's prose; `{{name}}` fields are filled in by [`run`].
const TEMPLATE: &str = include_str!("../templates/report-vertex.md");

/// Arguments of `bench vertex`.
#[derive(clap::Args, Debug)]
pub struct VertexArgs {
    /// The per-vertex bake config.
    #[arg(long, default_value = "scenes/vitrine/bake.toml")]
    pub config: PathBuf,
    /// The markdown report.
    #[arg(long, default_value = "docs/report-vertex.md")]
    pub out: PathBuf,
    /// Scratch folder for the bake files (deleted after use).
    #[arg(long, default_value = "target/report/vertex")]
    pub work_dir: PathBuf,
    /// Interleaved timing rounds (medians are reported).
    #[arg(long, default_value_t = 5)]
    pub rounds: usize,
    /// Samples per pixel of the reference images.
    #[arg(long, default_value_t = 1024)]
    pub reference_spp: u32,
    /// Image side (square images).
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Two settings, tiny images, few samples: a smoke run of every step.
    #[arg(long)]
    pub quick: bool,
}

/// One bake of the sweep: a name and the `[vertex]` compression keys it sets.
struct Setting {
    name: &'static str,
    compress: bool,
    cluster_vertices: Option<u32>,
    compress_error: Option<f32>,
    vertex_rank: Option<u32>,
    light_rank: Option<u32>,
}

/// The sweep: each knob of docs/vertex.md section 7 moved once from its default
/// (name, compress, cluster_vertices, compress_error, vertex_rank, light_rank).
type Knobs = (
    &'static str,
    bool,
    Option<u32>,
    Option<f32>,
    Option<u32>,
    Option<u32>,
);
const SWEEP: [Knobs; 8] = [
    ("dense", false, None, None, None, None),
    ("defaults", true, None, None, None, None),
    (
        "256 vertices per cluster",
        true,
        Some(256),
        None,
        None,
        None,
    ),
    ("64 vertices per cluster", true, Some(64), None, None, None),
    ("error target 5 %", true, None, Some(0.05), None, None),
    ("error target 20 %", true, None, Some(0.2), None, None),
    ("vertex rank 16", true, None, None, Some(16), None),
    ("light rank 32", true, None, None, None, Some(32)),
];

fn settings(quick: bool) -> Vec<Setting> {
    let n = if quick { 2 } else { SWEEP.len() };
    SWEEP[..n]
        .iter()
        .map(
            |&(name, compress, cluster_vertices, compress_error, vertex_rank, light_rank)| {
                Setting {
                    name,
                    compress,
                    cluster_vertices,
                    compress_error,
                    vertex_rank,
                    light_rank,
                }
            },
        )
        .collect()
}

/// A light of the comparison: None is the baked environment.
struct Light {
    name: &'static str,
    map: Option<(&'static str, f32)>,
}

const LIGHTS: [Light; 2] = [
    Light {
        name: "baked light",
        map: None,
    },
    Light {
        name: "studio turned 120",
        map: Some(("scenes/envmaps/studio.exr", 120.0)),
    },
];

type Image = Vec<[f32; 3]>;

fn to_rgb(flat: &[f32]) -> Image {
    flat.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect()
}

/// The relighter of `path` lit by `light` (at the config's intensity).
fn lit(path: &Path, light: &Light, intensity: f32) -> Result<VertexRelighter> {
    let mut r = VertexRelighter::open(path)?;
    if let Some((map, rotation)) = light.map {
        let (env, _) = prt_formats::envmap::load_latlong(Path::new(map), intensity)
            .with_context(|| format!("loading {map}"))?;
        r.set_environment(env, rotation)?;
    }
    Ok(r)
}

fn render(r: &mut VertexRelighter, size: u32) -> Result<(Image, prt_runtime::vertex::RenderStats)> {
    let camera = r.default_camera();
    let mut out = vec![0.0f32; 3 * (size * size) as usize];
    let stats = r.render(&camera, size, size, &mut out)?;
    Ok((to_rgb(&out), stats))
}

/// Runs the sweep and writes the report.
pub fn run(args: &VertexArgs) -> Result<()> {
    let (size, rounds, spp) = if args.quick {
        (48, 2, 16)
    } else {
        (args.size, args.rounds.max(1), args.reference_spp)
    };
    let (config, scene) = load(&args.config, &Silent)?;
    // The turned studio map is lit at the config's own map intensity.
    let intensity = match &config.environment {
        EnvironmentConfig::Map { intensity, .. } => *intensity,
        EnvironmentConfig::Color(_) => 1.0,
    };
    std::fs::create_dir_all(&args.work_dir)?;
    let settings = settings(args.quick);

    // Bakes.
    let mut baked = Vec::new();
    for s in &settings {
        let mut c = config.clone();
        let v = c.vertex.get_or_insert_with(VertexConfig::default);
        v.compress = Some(s.compress);
        v.cluster_vertices = s.cluster_vertices.or(v.cluster_vertices);
        v.compress_error = s.compress_error.or(v.compress_error);
        v.vertex_rank = s.vertex_rank.or(v.vertex_rank);
        v.light_rank = s.light_rank.or(v.light_rank);
        let path = args.work_dir.join(format!("{}.prtbake", baked.len()));
        let run = VertexRunSettings {
            output: Some(path.clone()),
            precision: Some(Precision::F16),
            spp: args.quick.then_some(8),
            ..Default::default()
        };
        eprintln!("baking: {}", s.name);
        let t = Instant::now();
        let summary = run_vertex(&c, &scene, &run, &Silent)?;
        baked.push((path, summary.file_bytes, t.elapsed().as_secs_f64()));
    }

    // References, one per light.
    let mut references = Vec::new();
    for light in &LIGHTS {
        eprintln!("reference: {} at {spp} spp", light.name);
        let mut sc = scene.clone();
        if let Some((map, rotation)) = light.map {
            sc.environment = prt_bake::scene::envmap::load_latlong(Path::new(map), intensity)?.0;
            sc.environment_rotation = rotation;
        }
        let r = prt_bake::reference::render_true(
            &sc,
            config.reflections as usize,
            size,
            size,
            spp,
            config.seed,
            None,
        );
        references.push(r.pixels.iter().map(|p| p.to_array()).collect::<Image>());
    }

    // Errors: against the dense relight (setting 0) and against the reference.
    let mut errors = vec![Vec::new(); settings.len()];
    for (li, light) in LIGHTS.iter().enumerate() {
        let mut images = Vec::new();
        for (path, _, _) in &baked {
            images.push(render(&mut lit(path, light, intensity)?, size)?.0);
        }
        for (i, img) in images.iter().enumerate() {
            errors[i].push((
                prt_bake::metrics::relative_l2(img, &images[0]),
                prt_bake::metrics::relative_l2(img, &references[li]),
            ));
        }
    }

    // Timings, interleaved: per round, every setting's three paths.
    let mut times = vec![[Vec::new(), Vec::new(), Vec::new()]; settings.len()];
    let mut relighters = baked
        .iter()
        .map(|(p, _, _)| lit(p, &LIGHTS[0], intensity))
        .collect::<Result<Vec<_>>>()?;
    for r in relighters.iter_mut() {
        render(r, size)?;
    }
    let edit = |k: usize| {
        let m = config_material(&config);
        prt_formats::parse_override(&format!("{m}.kd={},0.3,0.2", 0.3 + 0.1 * (k % 5) as f32))
    };
    for round in 0..rounds {
        eprintln!("timing round {} of {rounds}", round + 1);
        for (i, r) in relighters.iter_mut().enumerate() {
            let (_, s) = render(r, size)?;
            times[i][0].push(s.view_s);
            r.apply(&edit(round)?)?;
            let (_, s) = render(r, size)?;
            times[i][1].push(s.material_s.unwrap_or(0.0) + s.view_s);
            r.set_environment_rotation(10.0 * (round + 1) as f32)?;
            r.apply(&edit(round + 1)?)?;
            let (_, s) = render(r, size)?;
            times[i][2].push(s.light_s.unwrap_or(0.0) + s.material_s.unwrap_or(0.0) + s.view_s);
        }
    }
    drop(relighters);

    let mut rows = String::new();
    for (i, s) in settings.iter().enumerate() {
        let (bytes, seconds) = (baked[i].1, baked[i].2);
        let t: Vec<f64> = times[i].iter().map(|v| median(v)).collect();
        rows.push_str(&format!(
            "| {} | {:.1} MB | {:.1} s | {} / {} | {} / {} | {} | {} | {} |\n",
            s.name,
            bytes as f64 / 1e6,
            seconds,
            pct(errors[i][0].0),
            pct(errors[i][0].1),
            pct(errors[i][1].0),
            pct(errors[i][1].1),
            ms(t[0]),
            ms(t[1]),
            ms(t[2]),
        ));
    }
    let values = [
        ("host", crate::util::cpu_model()),
        ("threads", rayon::current_num_threads().to_string()),
        ("load", crate::util::load_average()),
        (
            "commit",
            crate::util::git_head().unwrap_or_else(|| "unknown".into()),
        ),
        ("date", crate::util::utc_now()),
        ("config", args.config.display().to_string()),
        ("vertices", scene.positions.len().to_string()),
        ("size", size.to_string()),
        ("spp", spp.to_string()),
        ("rounds", rounds.to_string()),
        ("rows", rows.trim_end().to_string()),
    ];
    let report = crate::template::render(TEMPLATE, &values)?;
    let out = if args.quick {
        args.work_dir.join("report-vertex.md")
    } else {
        args.out.clone()
    };
    std::fs::write(&out, report).with_context(|| format!("writing {}", out.display()))?;
    for (p, _, _) in &baked {
        let _ = std::fs::remove_file(p);
    }
    eprintln!("wrote {}", out.display());
    Ok(())
}

/// The first editable material of the config's scene (the one the timing edits).
fn config_material(config: &prt_bake::config::BakeConfig) -> String {
    config
        .materials
        .iter()
        .find(|(_, m)| m.editable)
        .map(|(n, _)| n.clone())
        .unwrap_or_default()
}
