//! `bench pixel`: the per-pixel speed-vs-error report (`docs/report-pixel.md`, plots and
//! pictures under `docs/img/pixel-*`; the method is in docs/pixel.md).
//!
//! Everything in the report is measured by this module in one run:
//! 1. bake time, rays/s and file size (default config, 512x512), and the ratio of the bake time
//!    to a reference render of the same size, spp and reflections, for several basis sizes;
//! 2. relight time per frame at 512x512 through the runtime ([`prt_runtime::Relighter`]),
//!    uncompressed and compressed at several ranks, against a measured streaming bandwidth;
//! 3. relative L2 error and RMSE of relit images against a high-spp true-BRDF reference, as a
//!    function of bake spp, basis size N_b and compression rank, for several material settings;
//! 4. side-by-side pictures relit | reference | |difference| x 10.
//!
//! Bake files go under a work folder (default `target/report/`) and are deleted after use. The
//! report's text is `bench/templates/report-pixel*.md`.

mod discussion;
mod markdown;
mod measure;
mod options;
mod plots;
mod results;
mod scenes;
pub mod stream;

use options::Plan;
pub use options::{ReportOptions, ReportSummary, DEFAULT_CONFIGS, DEFAULT_SETTINGS, REGENERATE};

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use prt_bake::metrics::{relative_l2, rmse};
use prt_bake::pixel::{self, Precision};

use prt_runtime::Variant;

use crate::util::{load_average, median, pct, utc_now};
use measure::{
    bake_once, err_norm, err_norm_diff, reference, relight_all, remove, time_variants, write_bake,
    Pca, VariantRun,
};
use results::{err2, BakeRow, Report, SceneErrors, SettingErrors};
use scenes::{BasisCache, SceneCtx};
use stream::StreamBench;

/// Runs every measurement and writes the markdown report, its plots and pictures.
pub fn run(opts: &ReportOptions) -> Result<ReportSummary> {
    let t0 = Instant::now();
    let plan = if opts.quick {
        Plan::quick()
    } else {
        Plan::full()
    };
    if opts.configs.is_empty() {
        bail!("give at least one bake config (--config)");
    }
    let say = |msg: String| {
        if opts.verbose {
            eprintln!("[{:6.1} s] {msg}", t0.elapsed().as_secs_f64());
        }
    };
    let started = utc_now();
    let load_start = load_average();
    let scenes = opts
        .configs
        .iter()
        .map(|p| SceneCtx::new(p, opts.verbose))
        .collect::<Result<Vec<_>>>()?;
    for d in [&opts.img_dir, &opts.work_dir] {
        std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
    }
    if let Some(p) = opts.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(p).with_context(|| format!("creating {}", p.display()))?;
    }
    let main = &scenes[0];
    let mut cache = BasisCache::new(plan.grid, plan.param_samples);

    // 1. Bakes of the main scene: default config and the large size, each against a render.
    let fam = main.families();
    let mut bake_rows = Vec::new();
    let (dw, dh, dspp) =
        plan.default_size
            .unwrap_or((main.config.width, main.config.height, main.config.spp));
    let nb = plan.main_nb;
    let (bases, basis_s) = cache.get(&fam, nb)?;
    say(format!(
        "{}: bases N_b={nb} in {basis_s:.2} s; baking {dw}x{dh} at {dspp} spp",
        main.name
    ));
    let b = bake_once(main, &bases, dw, dh, dspp)?;
    let path = opts.work_dir.join(format!("{}-default.prtbake", main.name));
    let file_bytes = write_bake(&b.bake, &path)?;
    remove(&path);
    say(format!("{}: reference {dw}x{dh} at {dspp} spp", main.name));
    let r = reference(&main.scene, &main.config, dw, dh, dspp, main.config.seed);
    bake_rows.push(BakeRow {
        what: "config's size and spp".into(),
        width: dw,
        height: dh,
        spp: dspp,
        nb,
        slots: b.slots,
        basis_s,
        bake_s: b.seconds,
        rays: b.rays,
        file_bytes,
        ref_s: Some(r.seconds),
        ref_rays: Some(r.rays),
    });
    drop(b);

    let big_spp = plan.big_spp.unwrap_or(main.config.spp);
    say(format!(
        "{}: baking {}x{} at {big_spp} spp",
        main.name, plan.big, plan.big
    ));
    let mut big = bake_once(main, &bases, plan.big, plan.big, big_spp)?;
    let big_ref = plan.big_reference.then(|| {
        say(format!(
            "{}: reference {}x{} at {big_spp} spp",
            main.name, plan.big, plan.big
        ));
        reference(
            &main.scene,
            &main.config,
            plan.big,
            plan.big,
            big_spp,
            main.config.seed,
        )
    });

    // 2. Relight timings at the large size: f16 and f32 files, and every rank.
    let mut runs = Vec::new();
    for (label, precision) in [
        ("uncompressed, f16", Precision::F16),
        ("uncompressed, f32", Precision::F32),
    ] {
        let p = opts
            .work_dir
            .join(format!("{}-big-{}.prtbake", main.name, precision.name()));
        let size = pixel::write_bake_file(&big.bake, &p, precision)
            .map_err(anyhow::Error::msg)
            .with_context(|| format!("writing {}", p.display()))?;
        runs.push(VariantRun {
            label: label.into(),
            rank: None,
            variant: Variant::Full,
            path: p,
            file_bytes: size,
        });
    }
    bake_rows.push(BakeRow {
        what: "large".into(),
        width: plan.big,
        height: plan.big,
        spp: big_spp,
        nb,
        slots: big.slots,
        basis_s,
        bake_s: big.seconds,
        rays: big.rays,
        file_bytes: runs[0].file_bytes,
        ref_s: big_ref.as_ref().map(|r| r.seconds),
        ref_rays: big_ref.as_ref().map(|r| r.rays),
    });
    drop(big_ref);
    let max_rank = plan.ranks.iter().copied().max().unwrap_or(1);
    let pca = Pca::new(&big.bake, max_rank);
    say(format!(
        "PCA of the large bake to rank {max_rank} in {:.2} s",
        pca.seconds
    ));
    for &k in &plan.ranks {
        pca.apply(&mut big.bake, k);
        let p = opts
            .work_dir
            .join(format!("{}-big-r{k}.prtbake", main.name));
        let size = write_bake(&big.bake, &p)?;
        runs.push(VariantRun {
            label: "compressed (f16 file)".into(),
            rank: Some(k),
            variant: Variant::Compressed,
            path: p,
            file_bytes: size,
        });
    }
    let pca_seconds = pca.seconds;
    drop((big, pca));
    say(format!(
        "relighting {}x{}: {} variants x {} frames, interleaved",
        plan.big,
        plan.big,
        runs.len(),
        plan.frames
    ));
    // The bandwidth passes are interleaved with the relight rounds, so that both see the same
    // load on the shared machine.
    let mut stream = StreamBench::new(plan.bw_bytes);
    let every = (plan.frames / plan.bw_runs.max(1)).max(1);
    let timed = time_variants(&runs, &main.settings, plan.frames, &mut stream, every);
    for v in &runs {
        remove(&v.path);
    }
    let (relight_rows, rates, write_rates) = timed?;
    let bandwidth = stream.figures(rates, write_rates);
    drop(stream);
    say(format!(
        "bandwidth {:.2} GB/s (median of {})",
        bandwidth.median / 1e9,
        bandwidth.runs
    ));
    for t in &relight_rows {
        say(format!(
            "{} {}: {:.3} ms/frame, added error {}",
            t.label,
            t.rank.map_or(String::new(), |k| format!("rank {k}")),
            t.median_s * 1e3,
            t.added_error.map_or("-".into(), pct)
        ));
    }

    // 1b. Bake against render as N_b grows, interleaved over repeats.
    let n = plan.small;
    let mut ratio_rows = Vec::new();
    {
        let mut per_nb = Vec::new();
        let ratio_nb = if fam.is_empty() {
            vec![plan.main_nb]
        } else {
            plan.ratio_nb.clone()
        };
        for &nb in &ratio_nb {
            let (bases, basis_s) = cache.get(&fam, nb)?;
            per_nb.push((nb, bases, basis_s, Vec::new(), None));
        }
        let mut ref_times = Vec::new();
        let mut ref_rays = 0;
        for rep in 0..plan.timing_repeats.max(1) {
            say(format!(
                "{}: bake/render ratio {n}x{n} at {} spp, round {}",
                main.name,
                plan.small_spp,
                rep + 1
            ));
            let r = reference(
                &main.scene,
                &main.config,
                n,
                n,
                plan.small_spp,
                main.config.seed,
            );
            ref_times.push(r.seconds);
            ref_rays = r.rays;
            for (_, bases, _, times, info) in &mut per_nb {
                let b = bake_once(main, bases, n, n, plan.small_spp)?;
                times.push(b.seconds);
                if info.is_none() {
                    let p = opts.work_dir.join(format!("{}-ratio.prtbake", main.name));
                    let size = write_bake(&b.bake, &p)?;
                    remove(&p);
                    *info = Some((b.slots, b.rays, size));
                }
            }
        }
        let ref_s = median(&ref_times);
        for (nb, _, basis_s, times, info) in per_nb {
            let (slots, rays, file_bytes) = info.unwrap_or((0, 0, 0));
            ratio_rows.push(BakeRow {
                what: if fam.is_empty() {
                    "no basis (diffuse editable only)".into()
                } else {
                    format!("N_b = {nb}")
                },
                width: n,
                height: n,
                spp: plan.small_spp,
                nb,
                slots,
                basis_s,
                bake_s: median(&times),
                rays,
                file_bytes,
                ref_s: Some(ref_s),
                ref_rays: Some(ref_rays),
            });
        }
    }

    // 3. Errors per scene.
    let mut errors = Vec::new();
    let mut pictures = Vec::new();
    let mut exposure = 1.0f32;
    for (si, ctx) in scenes.iter().enumerate() {
        let fam = ctx.families();
        // References: two seeds, averaged; their difference estimates the mean's noise.
        let mut refs = Vec::new();
        for s in &ctx.settings {
            say(format!(
                "{}: reference '{}' {n}x{n} at 2 x {} spp",
                ctx.name, s.label, plan.ref_half_spp
            ));
            let sc = ctx.scene_with(s)?;
            let a = reference(&sc, &ctx.config, n, n, plan.ref_half_spp, 1_000_003);
            let b = reference(&sc, &ctx.config, n, n, plan.ref_half_spp, 2_000_003);
            let mean: Vec<[f32; 3]> = a
                .pixels
                .iter()
                .zip(&b.pixels)
                .map(|(x, y)| {
                    [
                        0.5 * (x[0] + y[0]),
                        0.5 * (x[1] + y[1]),
                        0.5 * (x[2] + y[2]),
                    ]
                })
                .collect();
            let noise = 0.5 * err_norm_diff(&a.pixels, &b.pixels) / err_norm(&mean).max(1e-300);
            let noise_rmse = 0.5 * rmse(&a.pixels, &b.pixels);
            refs.push((mean, noise, noise_rmse, a.seconds + b.seconds));
        }
        let mut per: Vec<SettingErrors> = ctx
            .settings
            .iter()
            .zip(&refs)
            .map(|(s, r)| SettingErrors {
                label: s.label.clone(),
                describe: s.describe(),
                ref_noise: r.1,
                ref_rmse_noise: r.2,
                ref_seconds: r.3,
                by_spp: Vec::new(),
                by_nb: Vec::new(),
                by_rank: Vec::new(),
            })
            .collect();

        // Bake spp sweep (N_b = main); the largest spp bake also feeds the rank sweep.
        let (bases, _) = cache.get(&fam, plan.main_nb)?;
        let top_spp = plan.bake_spps.iter().copied().max().unwrap_or(1);
        for &spp in &plan.bake_spps {
            say(format!(
                "{}: bake {n}x{n} at {spp} spp, N_b={}",
                ctx.name, plan.main_nb
            ));
            let mut b = bake_once(ctx, &bases, n, n, spp)?;
            let p = opts.work_dir.join(format!("{}-spp{spp}.prtbake", ctx.name));
            write_bake(&b.bake, &p)?;
            let imgs = relight_all(&p, &ctx.settings, Variant::Full);
            remove(&p);
            let imgs = imgs?;
            for ((e, img), r) in per.iter_mut().zip(&imgs).zip(&refs) {
                e.by_spp.push((spp, err2(img, &r.0)));
            }
            if spp == top_spp {
                let pca = Pca::new(&b.bake, max_rank);
                for &k in &plan.ranks {
                    pca.apply(&mut b.bake, k);
                    let pk = opts
                        .work_dir
                        .join(format!("{}-spp{spp}-r{k}.prtbake", ctx.name));
                    write_bake(&b.bake, &pk)?;
                    let comp = relight_all(&pk, &ctx.settings, Variant::Compressed);
                    remove(&pk);
                    for (((e, img), r), c) in per.iter_mut().zip(&imgs).zip(&refs).zip(comp?) {
                        e.by_rank.push((k, relative_l2(&c, img), err2(&c, &r.0)));
                    }
                }
                if si == 0 {
                    // 4. Side-by-side pictures of the main scene.
                    exposure = crate::pictures::auto_exposure(&refs[0].0);
                    for ((s, img), r) in ctx.settings.iter().zip(&imgs).zip(&refs).take(3) {
                        let file =
                            opts.img_dir
                                .join(format!("pixel-side-{}-{}.png", ctx.name, s.slug()));
                        crate::pictures::side_by_side(img, &r.0, n, n, exposure, &file)?;
                        pictures.push((s.label.clone(), s.describe(), file));
                    }
                }
            }
        }

        // N_b sweep (spp = small).
        let mut nb_imgs: Vec<(usize, Vec<Vec<[f32; 3]>>)> = Vec::new();
        let sweep: Vec<usize> = if fam.is_empty() {
            vec![plan.main_nb]
        } else {
            plan.nb_sweep.clone()
        };
        for &nb in &sweep {
            let (bases, _) = cache.get(&fam, nb)?;
            say(format!(
                "{}: bake {n}x{n} at {} spp, N_b={nb}",
                ctx.name, plan.small_spp
            ));
            let b = bake_once(ctx, &bases, n, n, plan.small_spp)?;
            let p = opts.work_dir.join(format!("{}-nb{nb}.prtbake", ctx.name));
            write_bake(&b.bake, &p)?;
            let imgs = relight_all(&p, &ctx.settings, Variant::Full);
            remove(&p);
            nb_imgs.push((nb, imgs?));
        }
        if let Some((_, last)) = nb_imgs.last() {
            for (nb, imgs) in &nb_imgs {
                for (((e, img), r), top) in per.iter_mut().zip(imgs).zip(&refs).zip(last) {
                    e.by_nb.push((*nb, err2(img, &r.0), relative_l2(img, top)));
                }
            }
        }
        errors.push(SceneErrors {
            name: ctx.name.clone(),
            triangles: ctx.scene.triangles.len(),
            settings: per,
        });
    }

    let mut report = Report {
        plan,
        opts: opts.clone(),
        started,
        load_start,
        load_end: load_average(),
        total_s: 0.0,
        main_name: main.name.clone(),
        main_reflections: main.config.reflections,
        basis_grid: cache.used,
        bandwidth,
        bake_rows,
        ratio_rows,
        ratio_repeats: 0,
        pca_seconds,
        big_settings: main.settings.len(),
        relight: relight_rows,
        errors,
        pictures,
        plots: Vec::new(),
        exposure,
    };
    report.ratio_repeats = report.plan.timing_repeats;
    report.plots = plots::write_plots(&report)?;
    report.total_s = t0.elapsed().as_secs_f64();
    let md = markdown::markdown(&report)?;
    std::fs::write(&opts.out, md).with_context(|| format!("writing {}", opts.out.display()))?;
    say(format!("wrote {}", opts.out.display()));
    let mut images: Vec<PathBuf> = report.plots.iter().map(|(_, p)| p.clone()).collect();
    images.extend(report.pictures.iter().map(|(_, _, p)| p.clone()));
    Ok(ReportSummary {
        markdown: opts.out.clone(),
        images,
        seconds: report.total_s,
    })
}
