//! The per-vertex report (`docs/report-vertex.md`): the main scene (by default
//! `scenes/gallery`, 46 483 vertices) traced once and compressed with each setting of the
//! compression knobs (clusters, eigenvectors, light dimension, error target; from the kept
//! checkpoint), plus its dense bake; a detail scene (`scenes/vitrine`) baked whole for the
//! knobs that change the trace (kept Haar terms, samples); optionally a larger scene at its
//! defaults. Each bake is relit under the baked light and a turned studio map and compared with
//! the reference tracer (and the dense relight), the three runtime paths are timed in
//! interleaved rounds (view only; view + BRDF: a material edit; view + BRDF + light: a turn of
//! the environment as well), and the goals of the per-vertex mode are checked.

pub mod budget;
mod measure;
mod report;
pub mod scale;
mod sweep;

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};
use prt_bake::progress::Silent;
use prt_bake::run::load;

use measure::{editable_material, errors, map_intensity, references, time_paths};
use measure::{Errors, PathTimes, Pixels};
use sweep::{Baked, Setting};

/// Arguments of `bench vertex`.
/// Where the report's sections that other commands write begin; regenerating the report
/// keeps the existing file's text from here on.
const KEPT_FROM: &str = "\n## Error budget";

/// The regenerated report `new` followed by the old report's text from [`KEPT_FROM`] on (when
/// it has that section).
fn keep_tail(new: String, old: &str) -> String {
    match old.find(KEPT_FROM) {
        Some(at) => format!("{}\n{}", new.trim_end(), &old[at..]),
        None => new,
    }
}

#[derive(clap::Args, Debug)]
pub struct VertexArgs {
    /// The main scene: traced once, compressed with every compression setting.
    #[arg(long, default_value = "scenes/gallery/bake.toml")]
    pub config: PathBuf,
    /// The detail scene: baked once per kept-Haar-terms and samples setting.
    #[arg(long, default_value = "scenes/vitrine/bake.toml")]
    pub detail_config: PathBuf,
    /// A larger scene, baked at its defaults (skipped when not given).
    #[arg(long)]
    pub large_config: Option<PathBuf>,
    /// The markdown report.
    #[arg(long, default_value = "docs/report-vertex.md")]
    pub out: PathBuf,
    /// Where the plots and pictures go.
    #[arg(long, default_value = "docs/img/vertex")]
    pub img_dir: PathBuf,
    /// Scratch folder for the bake files and the checkpoint (emptied after use).
    #[arg(long, default_value = "target/report/vertex")]
    pub work_dir: PathBuf,
    /// Interleaved timing rounds (medians are reported).
    #[arg(long, default_value_t = 5)]
    pub rounds: usize,
    /// Samples per pixel of the reference images.
    #[arg(long, default_value_t = 1024)]
    pub reference_spp: u32,
    /// Image side of the main and large scenes (square images).
    #[arg(long, default_value_t = 512)]
    pub size: u32,
    /// Image side of the detail scene.
    #[arg(long, default_value_t = 256)]
    pub detail_size: u32,
    /// The detail scene as the main one, two settings, tiny images, few samples: a smoke run
    /// of every step (written under the work folder).
    #[arg(long)]
    pub quick: bool,
}

/// One scene's bakes and what was measured of them.
pub(crate) struct SceneRun {
    pub config: PathBuf,
    pub vertices: usize,
    pub size: u32,
    pub settings: Vec<Setting>,
    pub baked: Vec<Baked>,
    pub errors: Vec<Errors>,
    /// Per bake (only the timed ones).
    pub times: Vec<PathTimes>,
    pub references: Vec<Pixels>,
}

/// How a scene is baked and measured.
struct Plan<'a> {
    config: &'a Path,
    stem: &'a str,
    settings: Vec<Setting>,
    /// Trace once and compress from the checkpoint (every setting must differ only in
    /// compression keys).
    one_trace: bool,
    size: u32,
    time: bool,
    /// Also bake the dense bake with another seed (not timed).
    noise_floor: bool,
}

fn run_scene(args: &VertexArgs, plan: Plan, spp: u32, rounds: usize) -> Result<SceneRun> {
    let (config, scene) = load(plan.config, &Silent)?;
    let dir = &args.work_dir;
    let mut settings = plan.settings;
    let mut baked = if plan.one_trace {
        sweep::bake_from_one_trace(&config, &scene, &settings, dir, plan.stem, args.quick)?
    } else {
        sweep::bake_each(&config, &scene, &settings, dir, plan.stem, args.quick)?
    };
    let timed = baked.len();
    if plan.noise_floor {
        let noise = Setting::noise_floor();
        let stem = format!("{}-noise", plan.stem);
        let one = std::slice::from_ref(&noise);
        baked.extend(sweep::bake_each(
            &config, &scene, one, dir, &stem, args.quick,
        )?);
        settings.push(noise);
    }
    let references = references(&config, &scene, plan.size, spp)?;
    let paths: Vec<&Path> = baked.iter().map(|b| b.path.as_path()).collect();
    let dense = settings.iter().position(|s| !s.compress);
    let intensity = map_intensity(&config);
    let errors = errors(&paths, dense, &references, intensity, plan.size)?;
    let times = if plan.time {
        time_paths(
            &paths[..timed],
            &editable_material(&config),
            intensity,
            plan.size,
            rounds,
        )?
    } else {
        Vec::new()
    };
    for b in &baked {
        let _ = std::fs::remove_file(&b.path);
    }
    Ok(SceneRun {
        config: plan.config.to_path_buf(),
        vertices: scene.positions.len(),
        size: plan.size,
        settings,
        baked,
        errors,
        times,
        references,
    })
}

/// Runs the sweeps and writes the report, its plots and pictures.
pub fn run(args: &VertexArgs) -> Result<()> {
    let q = args.quick;
    let (size, detail_size, rounds, spp) = if q {
        (48, 32, 2, 16)
    } else {
        (
            args.size,
            args.detail_size,
            args.rounds.max(1),
            args.reference_spp,
        )
    };
    let main_config = if q { &args.detail_config } else { &args.config };
    let img_dir = if q {
        args.work_dir.join("img")
    } else {
        args.img_dir.clone()
    };
    std::fs::create_dir_all(&args.work_dir)?;
    std::fs::create_dir_all(&img_dir).with_context(|| format!("creating {}", img_dir.display()))?;

    let main = run_scene(
        args,
        Plan {
            config: main_config,
            stem: "main",
            settings: sweep::compression_settings(q),
            one_trace: true,
            size,
            time: true,
            noise_floor: true,
        },
        spp,
        rounds,
    )?;
    let detail = run_scene(
        args,
        Plan {
            config: &args.detail_config,
            stem: "detail",
            settings: sweep::trace_settings(q),
            one_trace: false,
            size: detail_size,
            time: false,
            noise_floor: false,
        },
        spp,
        rounds,
    )?;
    let large = match &args.large_config {
        Some(c) => Some(run_scene(
            args,
            Plan {
                config: c,
                stem: "large",
                settings: vec![sweep::compression_settings(true).remove(0)],
                one_trace: false,
                size,
                time: true,
                noise_floor: false,
            },
            spp,
            rounds,
        )?),
        None => None,
    };

    let out = if q {
        args.work_dir.join("report-vertex.md")
    } else {
        args.out.clone()
    };
    let text = report::write(&report::Inputs {
        main: &main,
        detail: &detail,
        large: large.as_ref(),
        img_dir: &img_dir,
        out: &out,
        spp,
        rounds,
    })?;
    // The sections from "## Error budget" on are written by `bench budget` and `bench scale`
    // (and the budget's discussion by hand): kept as they are.
    let text = match std::fs::read_to_string(&out) {
        Ok(old) => keep_tail(text, &old),
        Err(_) => text,
    };
    std::fs::write(&out, text).with_context(|| format!("writing {}", out.display()))?;
    eprintln!("wrote {}", out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::keep_tail;

    /// Regenerating the report keeps the budget's and the scale's sections, and only them.
    #[test]
    fn the_sections_other_commands_write_are_kept() {
        let old = "# R\n\nold goals\n\n## Error budget\n\nprose\n<!-- b -->\n## Scale\n\nx\n";
        let new = "# R\n\nnew goals\n".to_string();
        assert_eq!(
            keep_tail(new.clone(), old),
            "# R\n\nnew goals\n\n## Error budget\n\nprose\n<!-- b -->\n## Scale\n\nx\n"
        );
        assert_eq!(keep_tail(new.clone(), "# R\n\nold goals\n"), new);
    }
}
