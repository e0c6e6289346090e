//! Smoke test of the per-pixel report (`bench pixel --quick`): every step runs on a tiny scene
//! and the report has its tables. Speed is measured by the report, never asserted here.

use std::path::PathBuf;

use prt_bench::pixel::{run, ReportOptions};

fn scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(name)
        .join("bake.toml")
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("prt-report-pixel-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn quick_report_has_every_table() {
    let dir = scratch("quick");
    // The furnace (a diffuse editable sphere, no basis) and the Cornell box (two glossy
    // editable families), both at the quick mode's tiny sizes.
    let opts = ReportOptions {
        configs: vec![scene("furnace"), scene("cornell")],
        out: dir.join("report-pixel.md"),
        img_dir: dir.join("img"),
        work_dir: dir.join("work"),
        quick: true,
        command: "test".into(),
        verbose: false,
    };
    let summary = run(&opts).expect("quick report");
    let md = std::fs::read_to_string(&summary.markdown).expect("report written");
    for header in [
        "## Summary",
        "| goal | measured | met |",
        "## 1. Bake",
        "| bake | size | spp | N_b | slots | basis build (s) | bake (s) | Mrays/s | file (f16) | render (s) |",
        "## 2. Relight at",
        "| variant | rank | file size | bytes read / frame | ms / frame (median) |",
        "## 3. Errors against the true-BRDF reference",
        "| scene | setting | reference noise (rel. L2 / RMSE) |",
        "| N_b |",
        "| rank |",
        "## 4. Pictures",
        "## 5. Discussion",
    ] {
        assert!(md.contains(header), "report lacks '{header}':\n{md}");
    }
    assert!(
        md.contains("| cornell | bunny red, s=150"),
        "cornell settings missing:\n{md}"
    );
    assert!(
        md.contains("| furnace | sphere red"),
        "fallback setting missing:\n{md}"
    );
    assert!(!md.contains("NaN"), "report has NaN figures:\n{md}");
    // Plots (SVG) and up to three pictures (PNG) on disk; the scratch bake files are gone.
    assert!(summary.images.len() >= 5, "{:?}", summary.images);
    for p in &summary.images {
        let bytes = std::fs::read(p).expect("image written");
        let svg = p.extension().is_some_and(|e| e == "svg");
        assert!(
            if svg {
                String::from_utf8_lossy(&bytes).contains("<svg")
            } else {
                bytes.starts_with(b"\x89PNG")
            },
            "{} is not a valid image",
            p.display()
        );
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        assert!(name.starts_with("pixel-"), "{name}");
        assert!(md.contains(&format!("img/{name}")), "{name} not linked");
    }
    let leftovers = std::fs::read_dir(dir.join("work"))
        .map(|d| d.count())
        .unwrap_or(0);
    assert_eq!(leftovers, 0, "bake files left in the work folder");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn missing_config_is_a_clear_error() {
    let dir = scratch("missing");
    let opts = ReportOptions {
        configs: vec![dir.join("nope.toml")],
        out: dir.join("r.md"),
        img_dir: dir.join("img"),
        work_dir: dir.join("work"),
        quick: true,
        command: "test".into(),
        verbose: false,
    };
    let e = run(&opts).expect_err("missing config");
    assert!(format!("{e:#}").contains("nope.toml"), "{e:#}");
    let _ = std::fs::remove_dir_all(&dir);
}
