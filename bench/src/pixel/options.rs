//! What the per-pixel report runs (scenes, settings, sizes) and where it writes.

use std::path::PathBuf;

use prt_formats::basis::AngularGrid;

/// The command that regenerates `docs/report-pixel.md` (run from the repository root).
pub const REGENERATE: &str = "cargo run --release -p prt-bench -- pixel";

/// Default scenes: the first is the main one (bake and relight timings, pictures).
pub const DEFAULT_CONFIGS: [&str; 2] = ["scenes/cornell/bake.toml", "scenes/ring/bake.toml"];

/// Material settings the report evaluates besides the starting values. A setting is used for
/// a scene only when every edit applies to it (material exists, is editable, has the
/// parameter).
pub const DEFAULT_SETTINGS: [(&str, &[&str]); 4] = [
    (
        "bunny red, s=150",
        &["bunny.kd=0.8,0.2,0.2", "bunny.shininess=150"],
    ),
    (
        "tall_box alpha=0.05, ks=0.8",
        &["tall_box.alpha=0.05", "tall_box.ks=0.8"],
    ),
    ("ring s=50", &["ring.shininess=50"]),
    (
        "ring copper, s=120",
        &["ring.ks=0.95,0.64,0.54", "ring.shininess=120"],
    ),
];

/// What to run and where to write.
#[derive(Clone, Debug)]
pub struct ReportOptions {
    /// Bake configs; the first is the main scene.
    pub configs: Vec<PathBuf>,
    /// The markdown report.
    pub out: PathBuf,
    /// Folder of the plots (SVG) and pictures (PNG), prefix `pixel-`.
    pub img_dir: PathBuf,
    /// Scratch folder for bake files (deleted after use).
    pub work_dir: PathBuf,
    /// Tiny sizes everywhere: a smoke run of every step in seconds.
    pub quick: bool,
    /// The command line of this run, recorded in the report.
    pub command: String,
    /// Progress lines on stderr.
    pub verbose: bool,
}

/// What the run wrote.
#[derive(Clone, Debug)]
pub struct ReportSummary {
    pub markdown: PathBuf,
    pub images: Vec<PathBuf>,
    pub seconds: f64,
}

/// Sizes and sample counts of every step.
#[derive(Clone, Debug)]
pub(crate) struct Plan {
    /// (width, height, spp) of the "default config" bake; None = the config's own.
    pub(crate) default_size: Option<(u32, u32, u32)>,
    /// Side and spp of the large bake (relight timings).
    pub(crate) big: u32,
    pub(crate) big_spp: Option<u32>,
    /// Also render a reference at the large size for the bake/render ratio.
    pub(crate) big_reference: bool,
    /// Side of the error images and of the N_b sweep; spp of the N_b and ratio sweeps.
    pub(crate) small: u32,
    pub(crate) small_spp: u32,
    pub(crate) ratio_nb: Vec<usize>,
    pub(crate) timing_repeats: usize,
    pub(crate) frames: usize,
    pub(crate) ranks: Vec<usize>,
    pub(crate) bw_bytes: usize,
    pub(crate) bw_runs: usize,
    /// Each reference is the mean of two renders of this many spp (different seeds).
    pub(crate) ref_half_spp: u32,
    pub(crate) bake_spps: Vec<u32>,
    pub(crate) nb_sweep: Vec<usize>,
    pub(crate) main_nb: usize,
    pub(crate) table_rank: usize,
    /// Basis grid and parameter samples; None = the builder's defaults (what `bake` uses).
    pub(crate) grid: Option<AngularGrid>,
    pub(crate) param_samples: Option<usize>,
}

impl Plan {
    pub(crate) fn full() -> Plan {
        Plan {
            default_size: None,
            big: 512,
            big_spp: None,
            big_reference: true,
            small: 128,
            small_spp: 64,
            ratio_nb: vec![2, 4, 6, 8],
            timing_repeats: 3,
            frames: 101,
            ranks: vec![1, 2, 4, 8, 16, 32, 64],
            bw_bytes: 512 << 20,
            bw_runs: 20,
            ref_half_spp: 512,
            bake_spps: vec![4, 16, 64, 256],
            nb_sweep: (2..=10).collect(),
            main_nb: 6,
            table_rank: 8,
            grid: None,
            param_samples: None,
        }
    }

    pub(crate) fn quick() -> Plan {
        Plan {
            default_size: Some((24, 24, 4)),
            big: 32,
            big_spp: Some(4),
            big_reference: true,
            small: 16,
            small_spp: 4,
            ratio_nb: vec![2, 4],
            timing_repeats: 1,
            frames: 3,
            ranks: vec![1, 2, 4],
            bw_bytes: 16 << 20,
            bw_runs: 3,
            ref_half_spp: 8,
            bake_spps: vec![2, 4],
            nb_sweep: vec![2, 4],
            main_nb: 4,
            table_rank: 2,
            grid: Some(AngularGrid {
                n_theta_i: 8,
                n_theta_o: 8,
                n_phi: 16,
            }),
            param_samples: Some(32),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The run
