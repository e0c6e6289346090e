//! What the run measured, as the markdown and the plots read it.

use prt_bake::metrics::{relative_l2, rmse};
use prt_formats::basis::AngularGrid;
use std::path::PathBuf;

use super::measure::RelightTiming;
use super::options::{Plan, ReportOptions};
use super::stream::Bandwidth;

pub(crate) struct BakeRow {
    pub(crate) what: String,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) spp: u32,
    pub(crate) nb: usize,
    pub(crate) slots: usize,
    pub(crate) basis_s: f64,
    pub(crate) bake_s: f64,
    pub(crate) rays: u64,
    pub(crate) file_bytes: u64,
    pub(crate) ref_s: Option<f64>,
    pub(crate) ref_rays: Option<u64>,
}

/// Errors of one relit image against the reference.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Err2 {
    pub(crate) rel: f64,
    pub(crate) rmse: f64,
}

pub(crate) fn err2(a: &[[f32; 3]], b: &[[f32; 3]]) -> Err2 {
    Err2 {
        rel: relative_l2(a, b),
        rmse: rmse(a, b),
    }
}

pub(crate) struct SettingErrors {
    pub(crate) label: String,
    pub(crate) describe: String,
    pub(crate) ref_noise: f64,
    pub(crate) ref_rmse_noise: f64,
    pub(crate) ref_seconds: f64,
    /// Per bake spp (N_b = main).
    pub(crate) by_spp: Vec<(u32, Err2)>,
    /// Per N_b (spp = small): error vs reference and difference to the largest N_b.
    pub(crate) by_nb: Vec<(usize, Err2, f64)>,
    /// Per rank (bake at the largest spp): added (vs uncompressed) and total error.
    pub(crate) by_rank: Vec<(usize, f64, Err2)>,
}

pub(crate) struct SceneErrors {
    pub(crate) name: String,
    pub(crate) triangles: usize,
    pub(crate) settings: Vec<SettingErrors>,
}

pub(crate) struct Report {
    pub(crate) plan: Plan,
    pub(crate) opts: ReportOptions,
    pub(crate) started: String,
    pub(crate) load_start: String,
    pub(crate) load_end: String,
    pub(crate) total_s: f64,
    pub(crate) main_name: String,
    pub(crate) main_reflections: u32,
    pub(crate) basis_grid: Option<(AngularGrid, usize)>,
    pub(crate) bandwidth: Bandwidth,
    pub(crate) bake_rows: Vec<BakeRow>,
    pub(crate) ratio_rows: Vec<BakeRow>,
    pub(crate) ratio_repeats: usize,
    pub(crate) pca_seconds: f64,
    pub(crate) big_settings: usize,
    pub(crate) relight: Vec<RelightTiming>,
    pub(crate) errors: Vec<SceneErrors>,
    pub(crate) pictures: Vec<(String, String, PathBuf)>,
    pub(crate) plots: Vec<(String, PathBuf)>,
    pub(crate) exposure: f32,
}

/// Least-squares fit of err^2 - noise_ref^2 = a / spp + floor^2 over the spp sweep: the bake
/// noise at `spp` (sqrt(a / spp)) and the floor (0 when the fit gives none).
pub(crate) fn noise_fit(e: &SettingErrors, spp: u32) -> (f64, f64) {
    let pts: Vec<(f64, f64)> = e
        .by_spp
        .iter()
        .map(|(n, x)| (1.0 / *n as f64, x.rel * x.rel - e.ref_noise * e.ref_noise))
        .collect();
    if pts.len() < 2 {
        return (f64::NAN, f64::NAN);
    }
    // Weighted by 1 / err^4: relative residuals, so the low-error (high-spp) points count.
    let w: Vec<f64> = e
        .by_spp
        .iter()
        .map(|(_, x)| 1.0 / (x.rel * x.rel).max(1e-30).powi(2))
        .collect();
    let sw: f64 = w.iter().sum();
    let mx = pts.iter().zip(&w).map(|(p, w)| w * p.0).sum::<f64>() / sw;
    let my = pts.iter().zip(&w).map(|(p, w)| w * p.1).sum::<f64>() / sw;
    let sxy: f64 = pts
        .iter()
        .zip(&w)
        .map(|(p, w)| w * (p.0 - mx) * (p.1 - my))
        .sum();
    let sxx: f64 = pts
        .iter()
        .zip(&w)
        .map(|(p, w)| w * (p.0 - mx).powi(2))
        .sum();
    let a = (sxy / sxx.max(1e-300)).max(0.0);
    let b = my - a * mx;
    ((a / spp.max(1) as f64).sqrt(), b.max(0.0).sqrt())
}

/// Slope of log(error) against log(spp) by least squares.
pub(crate) fn slope(points: &[(u32, Err2)]) -> f64 {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|(_, e)| e.rel > 0.0)
        .map(|(n, e)| ((*n as f64).ln(), e.rel.ln()))
        .collect();
    let n = pts.len() as f64;
    if n < 2.0 {
        return f64::NAN;
    }
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx.max(1e-300)
}
