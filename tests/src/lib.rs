//! Shared fixtures of the cross-crate regression tests (`tests/tests/*.rs`): small scenes,
//! small bases, and the bake -> file -> relight round trip.

use std::path::PathBuf;

use glam::Vec3;
use prt_bake::basis::{BasisBuilder, BasisConfig};
use prt_bake::brdf::{BrdfParams, Family};
use prt_bake::pixel::{self, PixelBakeOptions, Precision, SlotLayout};
use prt_bake::scene::{Environment, PunctualLight, Scene};
use prt_bake::testing::{look_at, SceneBuilder};
use prt_formats::basis::{AngularGrid, BrdfBasis};

/// A small basis (coarse grid, few parameter samples) so tests build it in milliseconds: the
/// default half/difference grid kind at 24 theta_h x 16 theta_d x 4 phi_d nodes.
pub fn small_basis(family: Family, count: usize) -> BrdfBasis {
    let mut cfg = BasisConfig::new(family, count).expect("basis config");
    cfg.grid = AngularGrid {
        n_theta_i: 24,
        n_theta_o: 16,
        n_phi: 4,
    };
    cfg.param_samples = 24;
    BasisBuilder::new(cfg)
        .and_then(|b| b.build(count))
        .expect("basis build")
        .to_persisted()
}

/// A box-like scene: a coloured floor and back wall (fixed glossy GGX), an editable
/// Blinn-Phong sphere, an editable GGX sphere, an editable diffuse block, an area light and a
/// point light. `light` is the colour of both lights; `env` the environment.
pub fn test_scene(light: Vec3, env: Vec3) -> Scene {
    let mut b = SceneBuilder::new();
    let floor = b.material(
        "floor",
        BrdfParams::diffuse(Vec3::new(0.7, 0.6, 0.5)),
        Vec3::ZERO,
        false,
    );
    let wall = b.material(
        "wall",
        BrdfParams {
            family: Family::Ggx,
            kd: Vec3::new(0.2, 0.4, 0.6),
            ks: Vec3::splat(0.2),
            param: 0.3,
        },
        Vec3::ZERO,
        false,
    );
    let bp = b.material(
        "shiny",
        BrdfParams {
            family: Family::BlinnPhong,
            kd: Vec3::new(0.5, 0.2, 0.2),
            ks: Vec3::splat(0.4),
            param: 40.0,
        },
        Vec3::ZERO,
        true,
    );
    let gg = b.material(
        "metal",
        BrdfParams {
            family: Family::Ggx,
            kd: Vec3::splat(0.1),
            ks: Vec3::new(0.8, 0.7, 0.3),
            param: 0.2,
        },
        Vec3::ZERO,
        true,
    );
    let block = b.material(
        "block",
        BrdfParams::diffuse(Vec3::splat(0.6)),
        Vec3::ZERO,
        true,
    );
    let lamp = b.material("lamp", BrdfParams::diffuse(Vec3::ZERO), light * 8.0, false);
    b.quad(
        [
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(-2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0),
        ],
        floor,
    );
    b.quad(
        [
            Vec3::new(-2.0, 0.0, -1.5),
            Vec3::new(2.0, 0.0, -1.5),
            Vec3::new(2.0, 2.5, -1.5),
            Vec3::new(-2.0, 2.5, -1.5),
        ],
        wall,
    );
    b.sphere(Vec3::new(-0.6, 0.5, -0.4), 0.5, 2, bp);
    b.sphere(Vec3::new(0.6, 0.4, 0.0), 0.4, 2, gg);
    b.quad(
        [
            Vec3::new(0.9, 0.0, -1.2),
            Vec3::new(1.6, 0.0, -1.2),
            Vec3::new(1.6, 1.2, -1.2),
            Vec3::new(0.9, 1.2, -1.2),
        ],
        block,
    );
    b.quad(
        [
            Vec3::new(-0.4, 2.2, -0.6),
            Vec3::new(0.4, 2.2, -0.6),
            Vec3::new(0.4, 2.2, 0.2),
            Vec3::new(-0.4, 2.2, 0.2),
        ],
        lamp,
    );
    b.light(PunctualLight::Point {
        position: Vec3::new(1.2, 1.8, 1.0),
        intensity: light * 2.0,
    });
    b.environment(Environment::Constant(env));
    b.camera(look_at(
        Vec3::new(0.0, 1.2, 3.2),
        Vec3::new(0.0, 0.6, -0.5),
        Vec3::Y,
        50f32.to_radians(),
    ));
    b.build()
}

/// Bases for the families `scene`'s editable materials use.
pub fn bases_for(scene: &Scene, count: usize) -> Vec<BrdfBasis> {
    let mut fams: Vec<Family> = Vec::new();
    for m in &scene.materials {
        if m.editable && m.brdf.family != Family::Diffuse && !fams.contains(&m.brdf.family) {
            fams.push(m.brdf.family);
        }
    }
    fams.into_iter().map(|f| small_basis(f, count)).collect()
}

/// Options of a small bake.
pub fn small_options(
    w: u32,
    h: u32,
    spp: u32,
    reflections: u32,
    precision: Precision,
) -> PixelBakeOptions {
    PixelBakeOptions {
        width: w,
        height: h,
        spp,
        emission_oversampling: prt_bake::film_emission::DEFAULT_EMISSION_OVERSAMPLING,
        reflections,
        seed: 11,
        precision,
        max_memory: None,
        compress_rank: None,
    }
}

/// A unique temporary path for a test artefact.
pub fn temp_path(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("prt-tests-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    dir.join(name)
}

/// Bakes and writes a bake file; returns the layout used and the path.
pub fn bake_to_file(
    scene: &Scene,
    bases: &[BrdfBasis],
    opts: &PixelBakeOptions,
    name: &str,
) -> (SlotLayout, PathBuf) {
    let layout = SlotLayout::new(scene, bases).expect("layout");
    let bake = pixel::bake(scene, &layout, opts, None).expect("bake");
    let path = temp_path(name);
    pixel::write_bake_file(&bake, &path, opts.precision).expect("write bake file");
    (layout, path)
}

/// Panics unless `a` and `b` are images of the same, nonzero number of pixels: an error
/// measure that zips a truncated or empty image against a full one would otherwise score the
/// missing pixels as zero error.
#[track_caller]
pub fn assert_same_size(a: &[[f32; 3]], b: &[[f32; 3]]) {
    assert!(
        a.len() == b.len(),
        "images differ in size: {} vs {} pixels (truncated image?)",
        a.len(),
        b.len()
    );
    assert!(!a.is_empty(), "empty images: nothing to compare");
}

/// Relative L2 error ||a - b|| / ||b|| over all pixels and channels (the report's
/// definition, `prt_bake::metrics`); panics when the images differ in size or are empty.
#[track_caller]
pub fn relative_l2(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    assert_same_size(a, b);
    prt_bake::metrics::relative_l2(a, b)
}

/// One view of a scene for the per-vertex mode's comparisons: an environment map (file and
/// intensity) turned about +Y, a camera, material edits, an image size.
#[derive(Clone, Debug)]
pub struct ViewSetting {
    /// A name for messages.
    pub name: &'static str,
    /// Lat-long map (path relative to the workspace root) and its intensity.
    pub env: (&'static str, f32),
    /// Rotation about +Y, degrees.
    pub rotation_deg: f32,
    /// `--camera` syntax.
    pub camera: &'static str,
    /// `--set` edits.
    pub edits: Vec<&'static str>,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
}

/// The workspace root (the tests crate's parent folder).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests crate has a parent")
        .to_path_buf()
}

/// `scene` as `setting` changes it for the reference tracer: its environment, rotation, camera
/// and true BRDFs.
pub fn scene_for_setting(scene: &Scene, setting: &ViewSetting) -> Scene {
    let mut scene = scene.clone();
    let (file, intensity) = setting.env;
    let (env, _) = prt_bake::scene::envmap::load_latlong(&workspace_root().join(file), intensity)
        .expect("environment map");
    scene.environment = env;
    scene.environment_rotation = setting.rotation_deg;
    let frame = setting
        .camera
        .parse::<prt_formats::view::CameraSpec>()
        .expect("camera spec")
        .frame()
        .expect("camera frame");
    scene.camera = prt_bake::view::camera_from_frame(&frame);
    for e in &setting.edits {
        let o = prt_formats::parse_override(e).expect("edit syntax");
        prt_bake::run::apply_override(&mut scene, &o).expect("edit applies");
    }
    scene
}

/// The reference tracer's image of `setting` (true BRDFs, `reflections` reflections).
pub fn reference_image(
    scene: &Scene,
    setting: &ViewSetting,
    reflections: usize,
    spp: u32,
    seed: u64,
) -> Vec<[f32; 3]> {
    let scene = scene_for_setting(scene, setting);
    prt_bake::reference::render_true(
        &scene,
        reflections,
        setting.width,
        setting.height,
        spp,
        prt_bake::film_emission::DEFAULT_EMISSION_OVERSAMPLING,
        seed,
        None,
    )
    .pixels
    .into_iter()
    .map(|p| p.to_array())
    .collect()
}

/// Applies one `--set MATERIAL.PARAM=VALUE` edit to a per-pixel bake, as `relight` does.
pub fn edit_pixel(
    r: &mut prt_runtime::PixelRelighter,
    edit: &str,
) -> Result<(), prt_runtime::RuntimeError> {
    let o = prt_formats::parse_override(edit).expect("valid --set syntax");
    r.set_params(&o.material, &[o.value])
}

/// Applies one `--set MATERIAL.PARAM=VALUE` edit to a per-vertex bake, as `relight` does.
pub fn edit_vertex(
    r: &mut prt_runtime::VertexRelighter,
    edit: &str,
) -> Result<(), prt_runtime::RuntimeError> {
    let o = prt_formats::parse_override(edit).expect("valid --set syntax");
    r.set_params(&o.material, &[o.value])
}

#[cfg(test)]
mod tests {
    use super::relative_l2;

    #[test]
    fn relative_l2_scores_equal_images_zero_and_a_black_image_one() {
        let b = vec![[1.0, 2.0, 3.0], [0.5, 0.0, 4.0]];
        assert_eq!(relative_l2(&b, &b), 0.0);
        assert!((relative_l2(&[[0.0; 3]; 2], &b) - 1.0).abs() < 1e-12);
    }

    #[test]
    #[should_panic(expected = "images differ in size: 1 vs 2 pixels")]
    fn relative_l2_rejects_a_truncated_image() {
        let b = vec![[1.0, 2.0, 3.0], [0.5, 0.0, 4.0]];
        relative_l2(&b[..1], &b);
    }

    #[test]
    #[should_panic(expected = "empty images")]
    fn relative_l2_rejects_empty_images() {
        relative_l2(&[], &[]);
    }
}
