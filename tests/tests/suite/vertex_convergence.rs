//! The per-vertex mode against the reference tracer (docs/vertex.md, section 6): `vitrine` is
//! baked per vertex once, then relit for several (environment, rotation, camera, material)
//! settings and compared with the reference tracer's render of the same setting (true BRDFs,
//! the same number of reflections). A second bake, `vitrine` with its sphere Blinn-Phong at
//! s = 200 (a modified copy of its config in a temporary folder), covers the other
//! near-mirror lobe (GGX alpha = 0.05 is a material edit of the first bake).
//!
//! The per-vertex mode is an approximation (transfer stored at vertices and interpolated,
//! T1 projected on order-4 SH, the BRDF in a Tucker basis, Haar terms dropped), so the
//! comparison bounds a relative L2 error measured on this scene with some margin, not noise.
//! Each bound is checked to be tight: a black image, a 2x image and the same relight with the
//! environment turned 90 degrees too far must each exceed it. `PRT_VERTEX_DUMP=DIR` writes each
//! setting's relit image, reference and 4x difference side by side as PNG.

use std::sync::OnceLock;

use prt_bake::progress::Silent;
use prt_bake::run::{load, run_vertex, VertexRunSettings};
use prt_formats::pixel::Precision;
use prt_runtime::VertexRelighter;
use prt_tests::{reference_image, relative_l2, temp_path, workspace_root, ViewSetting};

/// Reflections of the bake and of the reference.
const REFLECTIONS: usize = 2;
/// Reference samples per pixel: its own noise must stay well below the bounds.
const REFERENCE_SPP: u32 = 1024;

struct Baked {
    scene: prt_bake::scene::Scene,
    path: std::path::PathBuf,
}

/// Bakes the config at `config_path` per vertex (f16) to `output`.
fn bake(config_path: &std::path::Path, output: std::path::PathBuf) -> Baked {
    let (config, scene) = load(config_path, &Silent).expect("vitrine loads");
    assert_eq!(config.reflections as usize, REFLECTIONS);
    let settings = VertexRunSettings {
        output: Some(output.clone()),
        precision: Some(Precision::F16),
        ..Default::default()
    };
    run_vertex(&config, &scene, &settings, &Silent).expect("vertex bake");
    Baked {
        scene,
        path: output,
    }
}

/// `scenes/vitrine` baked per vertex once for all tests of this file.
fn baked() -> &'static Baked {
    static BAKED: OnceLock<Baked> = OnceLock::new();
    BAKED.get_or_init(|| {
        bake(
            &workspace_root().join("scenes/vitrine/bake.toml"),
            temp_path("vitrine-vertex.prt"),
        )
    })
}

/// Blinn-Phong shininess of the near-mirror sphere (the top of the family's default basis
/// range, [1, 200]: docs/brdf-basis.md).
const SHININESS: f32 = 200.0;

/// `scenes/vitrine` with its sphere Blinn-Phong at s = [`SHININESS`], baked per vertex once: a
/// copy of its `bake.toml` in a temporary folder, pointing at the original glTF and map by
/// absolute path, with the sphere's material section replaced.
fn baked_blinn_phong() -> &'static Baked {
    static BAKED: OnceLock<Baked> = OnceLock::new();
    BAKED.get_or_init(|| {
        let root = workspace_root();
        let original = std::fs::read_to_string(root.join("scenes/vitrine/bake.toml"))
            .expect("read scenes/vitrine/bake.toml");
        let abs = |p: &str| {
            let path = root.join(p);
            // TOML basic strings: a Windows path's backslashes would need escaping.
            path.display().to_string().replace('\\', "/")
        };
        let replace = |text: String, from: &str, to: &str| {
            assert!(
                text.contains(from),
                "scenes/vitrine/bake.toml no longer holds `{from}`: update this test's copy"
            );
            text.replace(from, to)
        };
        let mut text = replace(
            original,
            "scene = \"vitrine.gltf\"",
            &format!("scene = \"{}\"", abs("scenes/vitrine/vitrine.gltf")),
        );
        text = replace(
            text,
            "map = \"../envmaps/sky.exr\"",
            &format!("map = \"{}\"", abs("scenes/envmaps/sky.exr")),
        );
        text = replace(
            text,
            "family = \"ggx\"\nkd = [0.1, 0.1, 0.1]\nks = 0.6\nalpha = 0.1\n",
            &format!(
                "family = \"blinn-phong\"\nkd = [0.03, 0.03, 0.03]\nks = 0.8\nshininess = {SHININESS}\n"
            ),
        );
        let dir = temp_path("vitrine-blinn-phong");
        std::fs::create_dir_all(&dir).expect("temporary folder");
        let config_path = dir.join("bake.toml");
        std::fs::write(&config_path, text).expect("write the modified bake.toml");
        bake(&config_path, dir.join("vitrine-blinn-phong.prt"))
    })
}

/// The runtime's image of `setting`, with the environment turned `extra_deg` further.
fn relight(b: &Baked, setting: &ViewSetting, extra_deg: f32) -> Vec<[f32; 3]> {
    let mut r = VertexRelighter::open(&b.path).expect("open vertex bake");
    let (file, intensity) = setting.env;
    r.load_environment(workspace_root().join(file))
        .expect("environment map");
    r.set_environment_intensity(intensity).expect("intensity");
    r.set_environment_rotation(setting.rotation_deg + extra_deg)
        .expect("rotation");
    for e in &setting.edits {
        prt_tests::edit_vertex(&mut r, e).expect("edit applies");
    }
    let frame = setting
        .camera
        .parse::<prt_formats::view::CameraSpec>()
        .expect("camera spec")
        .frame()
        .expect("camera frame");
    r.set_size(setting.width, setting.height).expect("size");
    r.set_camera(frame).expect("camera");
    r.render().expect("render").pixels
}

/// Relights `setting`, compares with the reference, and checks that the bound separates the
/// image from a black one, a 2x one and a 90-degree rotation error.
fn check(setting: ViewSetting, bound: f64) {
    check_bake(baked(), setting, bound, &[])
}

/// [`check`] on the bake `b`; each of `wrong_edits` (a name and an edit applied after the
/// setting's own) must also give an image the bound catches.
fn check_bake(b: &Baked, setting: ViewSetting, bound: f64, wrong_edits: &[(&str, &'static str)]) {
    let reference = reference_image(&b.scene, &setting, REFLECTIONS, REFERENCE_SPP, 7);
    let image = relight(b, &setting, 0.0);
    let nonfinite = image.iter().flatten().filter(|v| !v.is_finite()).count();
    let negative = image.iter().flatten().filter(|v| **v < 0.0).count();
    let min = image.iter().flatten().fold(f32::INFINITY, |m, v| m.min(*v));
    assert!(
        nonfinite == 0 && negative == 0,
        "{}: {nonfinite} non-finite and {negative} negative values (min {min})",
        setting.name
    );
    if let Some(dir) = std::env::var_os("PRT_VERTEX_DUMP") {
        // Side by side for a person: relit | reference | 4x |difference|.
        let (w, h) = (setting.width as usize, setting.height as usize);
        let mut side = vec![[0.0f32; 3]; 3 * w * h];
        for y in 0..h {
            for x in 0..w {
                let (a, r) = (image[y * w + x], reference[y * w + x]);
                side[y * 3 * w + x] = a;
                side[y * 3 * w + w + x] = r;
                side[y * 3 * w + 2 * w + x] = std::array::from_fn(|c| 4.0 * (a[c] - r[c]).abs());
            }
        }
        let name: String = setting
            .name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        let path = std::path::Path::new(&dir).join(format!("{name}.png"));
        prt_formats::write_png(&path, 3 * w, h, &side, 1.0).expect("write the side-by-side");
    }
    let err = relative_l2(&image, &reference);
    let black = relative_l2(&vec![[0.0; 3]; image.len()], &reference);
    let doubled: Vec<[f32; 3]> = image.iter().map(|p| p.map(|v| 2.0 * v)).collect();
    let err_double = relative_l2(&doubled, &reference);
    let turned = relight(b, &setting, 90.0);
    let err_turned = relative_l2(&turned, &reference);
    let mut wrong = vec![
        ("black", black),
        ("2x", err_double),
        ("turned 90", err_turned),
    ];
    for &(what, edit) in wrong_edits {
        let mut edited = setting.clone();
        edited.edits.push(edit);
        wrong.push((what, relative_l2(&relight(b, &edited, 0.0), &reference)));
    }
    let wrong_text: Vec<String> = wrong
        .iter()
        .map(|(what, e)| format!("{what} {e:.3}"))
        .collect();
    eprintln!(
        "{}: rel. L2 {err:.4} (bound {bound}); {}",
        setting.name,
        wrong_text.join(", ")
    );
    assert!(err <= bound, "{}: rel. L2 {err:.4} > {bound}", setting.name);
    check_region_means(b, &setting, &image, &reference);
    for (what, e) in wrong {
        assert!(
            e > bound,
            "{}: the bound {bound} does not catch a {what} image (rel. L2 {e:.4})",
            setting.name
        );
    }
}

/// How far a region's mean may lie from the reference's, for every material that covers at
/// least [`REGION_PIXELS`] of the image (what each pixel's camera ray meets first): a bias
/// shows here however its error is spread. Diffuse regions: measured at most 3.9 % (the
/// edited bunny under the studio map turned 120; floors at most 1.8 %); with T0's irradiance
/// row kept only as the visible part (before the open-sky table) the floor was 7.2 % too dark
/// under the studio map turned 90 and 4.9 % too bright turned 120, and this bound fails
/// them. Glossy regions: the GGX sphere at alpha 0.25 under the studio map turned 120 is
/// 7.7 % too dark (10.9 % before the centroid lookup and the compact lights), a defect of the
/// last reflection's shading at that width left open (docs/report-vertex.md, "Error budget");
/// the bound keeps it from growing.
const DIFFUSE_MEAN_BOUND: f64 = 0.045;
const GLOSSY_MEAN_BOUND: f64 = 0.12;
/// Pixels a region needs for its mean to be checked.
const REGION_PIXELS: usize = 400;

fn check_region_means(
    b: &Baked,
    setting: &ViewSetting,
    image: &[[f32; 3]],
    reference: &[[f32; 3]],
) {
    let scene = prt_tests::scene_for_setting(&b.scene, setting);
    let first = prt_bake::view::first_hit_materials(&scene, setting.width, setting.height);
    let mut text = Vec::new();
    let mut failures = Vec::new();
    for (m, mat) in scene.materials.iter().enumerate() {
        let mask: Vec<bool> = first.iter().map(|f| *f == Some(m as u32)).collect();
        let e = prt_bake::metrics::region_error(image, reference, &mask);
        if e.pixels < REGION_PIXELS {
            continue;
        }
        text.push(format!(
            "{} {:.4} ({} px)",
            mat.name, e.mean_ratio, e.pixels
        ));
        let bound = if mat.brdf.family == prt_bake::brdf::Family::Diffuse {
            DIFFUSE_MEAN_BOUND
        } else {
            GLOSSY_MEAN_BOUND
        };
        let off = (e.mean_ratio - 1.0).abs();
        if off > bound {
            failures.push(format!(
                "{}'s mean is {:.1} % off the reference's (bound {:.1} %)",
                mat.name,
                100.0 * off,
                100.0 * bound
            ));
        }
    }
    eprintln!(
        "{}: region means over the reference's: {}",
        setting.name,
        text.join(", ")
    );
    assert!(
        failures.is_empty(),
        "{}: {}",
        setting.name,
        failures.join("; ")
    );
}

#[test]
fn sky_default_view_matches_the_reference() {
    check(
        ViewSetting {
            name: "sky, default view",
            env: ("scenes/envmaps/sky.exr", 0.25),
            rotation_deg: 0.0,
            camera: "eye=0,0.35,0.85 target=0,0.1,0 fov=40",
            edits: vec![],
            width: 96,
            height: 96,
        },
        // Measured 0.088 (0.207 before the sun was a compact light, reflected through the
        // true lobe: docs/vertex.md, "Compact lights"): the sun's sharp shadows are what a
        // per-vertex representation on this coarse bunny and sphere blurs most.
        0.13,
    );
}

#[test]
fn studio_turned_new_view_and_edits_match_the_reference() {
    check(
        ViewSetting {
            name: "studio turned 120, side view, edited",
            env: ("scenes/envmaps/studio.exr", 0.25),
            rotation_deg: 120.0,
            camera: "eye=0.7,0.3,0.45 target=0,0.08,0 fov=45",
            edits: vec![
                "sphere.alpha=0.25",
                "sphere.kd=0.3,0.05,0.05",
                "bunny.kd=0.2,0.5,0.7",
            ],
            width: 96,
            height: 96,
        },
        // Measured 0.031.
        0.06,
    );
}

#[test]
fn sunset_grazing_view_near_mirror_matches_the_reference() {
    check(
        ViewSetting {
            name: "sunset turned -60, grazing view, near-mirror sphere",
            env: ("scenes/envmaps/sunset.exr", 0.25),
            rotation_deg: -60.0,
            camera: "eye=-0.1,0.05,0.8 target=0,0.06,0 fov=35",
            edits: vec![
                "sphere.alpha=0.05",
                "sphere.ks=0.8",
                "sphere.kd=0.02,0.02,0.02",
            ],
            width: 96,
            height: 96,
        },
        // Measured 0.104 (the sunset's hazy sun is no compact light).
        0.16,
    );
}

#[test]
fn studio_blinn_phong_near_mirror_sphere_matches_the_reference() {
    // The sphere (Blinn-Phong s = 200, Ks 0.8, Kd 0.03) fills most of the frame and mirrors
    // the studio's lamp and the floor; nearly all of the image is its specular lobe (with
    // `sphere.ks=0` the rel. L2 is 0.97). The lobe's width is checked too: the same relight
    // at s = 100 must fail the bound.
    check_bake(
        baked_blinn_phong(),
        ViewSetting {
            name: "studio turned 90, front view, Blinn-Phong s = 200 sphere",
            env: ("scenes/envmaps/studio.exr", 0.25),
            rotation_deg: 90.0,
            camera: "eye=-0.17,0.2,0.6 target=-0.17,0.1,0 fov=35",
            edits: vec![],
            width: 96,
            height: 96,
        },
        // Measured 0.026 (s = 100: 0.376; 0.073 before the lamp was a compact light,
        // reflected through the true lobe): the floor's reflection, as one-reflection light
        // (6x8x8 bins, order-4 SH), and the per-vertex shadows are what is left.
        0.05,
        &[("s = 100 lobe", "sphere.shininess=100")],
    );
}
