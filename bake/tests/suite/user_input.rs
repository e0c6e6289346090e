//! What a user types and what the baker tells back: angles in degrees in the config as on the
//! command line (the deprecated radian key converted, with a warning naming the new key and its
//! value), a warning for a scene nothing lights, a warning for a material that reflects more
//! light than it receives, and a printed per-pixel config that becomes a per-vertex one by
//! changing `mode` alone.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use prt_bake::config::input;
use prt_bake::config::{BakeConfig, Mode};
use prt_bake::progress::Progress;
use prt_bake::run::load_scene;
use prt_bake::view::camera_from_frame;
use prt_formats::view::CameraSpec;

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

/// Keeps the warnings a library call reports.
#[derive(Default)]
struct Warnings(Mutex<Vec<String>>);

impl Progress for Warnings {
    fn warn(&self, text: &str) {
        self.0.lock().expect("lock").push(text.to_string());
    }
}

impl Warnings {
    fn taken(&self) -> Vec<String> {
        std::mem::take(&mut self.0.lock().expect("lock"))
    }
}

/// A config beside the furnace's GLB (it need not exist: it anchors the relative scene path).
fn furnace_config(body: &str) -> (BakeConfig, Vec<String>) {
    let text = format!("scene = \"furnace.glb\"\n{body}");
    BakeConfig::parse_with_warnings(&text, scenes_dir().join("furnace/user.toml"))
        .unwrap_or_else(|e| panic!("{e}\n{text}"))
}

fn camera_table(fov_line: &str) -> String {
    format!("[camera]\nposition = [0.3, 0.4, 2.0]\ntarget = [0.0, 0.05, 0.0]\n{fov_line}\n")
}

/// `[camera] fov = 40` in a config and `--camera "... fov=40"` on the command line are the
/// same camera, bit for bit; the old radian key gives it too, with a warning that names `fov`
/// and the value to write; the old key given degrees is refused, saying what to write.
#[test]
fn degrees_in_the_config_and_on_the_command_line_give_the_same_camera() {
    let spec: CameraSpec = "eye=0.3,0.4,2 target=0,0.05,0 fov=40"
        .parse()
        .expect("a camera");
    let want = camera_from_frame(&spec.frame().expect("a frame"));
    assert_eq!(want.yfov, 40f32.to_radians());

    let (config, warnings) = furnace_config(&camera_table("fov = 40"));
    assert!(warnings.is_empty(), "{warnings:?}");
    let scene = load_scene(&config, &Warnings::default()).expect("furnace loads");
    assert_eq!(scene.camera, want);

    let radians = 40f32.to_radians();
    let (old, warnings) = furnace_config(&camera_table(&format!("yfov = {radians}")));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let w = &warnings[0];
    assert!(
        w.contains("`camera.yfov`") && w.contains("deprecated") && w.contains("`fov = 40`"),
        "{w}"
    );
    assert!(w.contains("user.toml"), "names the config: {w}");
    let old_scene = load_scene(&old, &Warnings::default()).expect("furnace loads");
    assert_eq!(old_scene.camera, want);
    // The printed config writes the new key.
    assert!(old.to_toml().contains("fov = 40.0\n"), "{}", old.to_toml());

    // 40 under the radian key (degrees meant): refused, saying what to write.
    let text = format!("scene = \"furnace.glb\"\n{}", camera_table("yfov = 40"));
    let e = BakeConfig::parse(&text, scenes_dir().join("furnace/user.toml"))
        .expect_err("40 radians")
        .to_string();
    assert!(
        e.contains("`camera.yfov`") && e.contains("`fov = 40`"),
        "{e}"
    );
}

/// A scene with no emitter, no light and a black environment warns when it is loaded for a
/// bake (its images would be black), naming the scene, the config and the fix; a per-vertex
/// bake's warning also names `relight --env`. Scenes lit by an environment, an emissive
/// material or a point light do not warn, nor does a bare glTF (it gets the neutral map).
#[test]
fn a_scene_nothing_lights_warns_when_it_is_loaded() {
    let unlit = |text: &str| {
        let (config, _) = furnace_config(text);
        let w = Warnings::default();
        load_scene(&config, &w).expect("furnace loads");
        w.taken()
    };
    let warnings = unlit("");
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let w = &warnings[0];
    assert!(
        w.contains("nothing lights the scene")
            && w.contains("furnace.glb")
            && w.contains("user.toml")
            && w.contains("[environment]")
            && w.contains("neutral.hdr"),
        "{w}"
    );
    assert!(!w.contains("relight --env"), "{w}");
    let w = unlit("mode = \"vertex\"\n");
    assert!(
        w.len() == 1 && w[0].contains("relight --env"),
        "per vertex: {w:?}"
    );
    assert_eq!(unlit("[environment]\ncolor = 0\n").len(), 1);
    assert_eq!(
        unlit("[environment]\ncolor = 1\nintensity = 0\n").len(),
        1,
        "a zero intensity is black"
    );
    assert!(unlit("[environment]\ncolor = 0.2\n").is_empty());

    for lit in ["furnace", "cornell", "ring", "vitrine"] {
        let config = BakeConfig::from_file(scenes_dir().join(lit).join("bake.toml"))
            .unwrap_or_else(|e| panic!("{e}"));
        let w = Warnings::default();
        load_scene(&config, &w).unwrap_or_else(|e| panic!("{lit}: {e}"));
        assert!(
            !w.taken().iter().any(|w| w.contains("nothing lights")),
            "{lit}"
        );
    }
    // The bare glTF's default environment is the shipped map, and lights it.
    let bare = input::resolve(&scenes_dir().join("furnace/furnace.glb")).expect("defaults");
    let w = Warnings::default();
    let scene = load_scene(&bare.config, &w).expect("loads");
    assert!(w.taken().is_empty());
    assert!(scene.has_light());
}

/// A config's `kd` (or `kd + ks`) above 1 in a channel is baked, with a warning naming the
/// material, the values and the range.
#[test]
fn a_material_that_reflects_more_than_it_receives_warns() {
    let load = |body: &str| {
        let (config, _) = furnace_config(&format!("[environment]\ncolor = 1\n{body}"));
        let w = Warnings::default();
        load_scene(&config, &w).expect("furnace loads");
        w.taken()
    };
    let w = load("[materials.sphere]\nkd = [1.5, 0.5, 0.5]\n");
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("materials.sphere")
            && w[0].contains("kd = 1.5")
            && w[0].contains("[0, 1]")
            && w[0].contains("user.toml"),
        "{}",
        w[0]
    );
    let w = load("[materials.sphere]\nfamily = \"ggx\"\nkd = 0.5\nks = 0.6\nalpha = 0.3\n");
    assert!(
        w.len() == 1 && w[0].contains("0.5 + 0.6"),
        "kd + ks = 1.1: {w:?}"
    );
    assert!(load("[materials.sphere]\nkd = 0.9\n").is_empty());
    assert!(
        load("[materials.sphere]\nfamily = \"ggx\"\nkd = 0.5\nks = 0.5\nalpha = 0.3\n").is_empty()
    );
}

/// `bake model.glb --print-config` output, with `mode = "vertex"` written in place of
/// `"pixel"`, is a valid per-vertex config (the per-pixel-only key is not printed at its
/// default); a per-vertex config that sets it is told to remove it.
#[test]
fn a_printed_config_switches_to_per_vertex_by_its_mode_alone() {
    let path = scenes_dir().join("furnace/furnace.glb");
    let printed = input::resolve(&path).expect("defaults").config.to_toml();
    assert!(printed.contains("mode = \"pixel\"\n"), "{printed}");
    let vertex = printed.replace("mode = \"pixel\"", "mode = \"vertex\"");
    let config = BakeConfig::parse(&vertex, scenes_dir().join("furnace/printed.toml"))
        .unwrap_or_else(|e| panic!("{e}\n{vertex}"));
    assert_eq!(config.mode, Mode::Vertex);

    let e = BakeConfig::parse(
        "scene = \"x.gltf\"\nmode = \"vertex\"\nemission_oversampling = 8\n",
        "/s/bake.toml",
    )
    .expect_err("per-pixel key")
    .to_string();
    assert!(
        e.contains("`emission_oversampling`") && e.contains("remove this key"),
        "{e}"
    );
    // A non-default oversampling is still printed (and read back) in pixel mode.
    let c = BakeConfig::parse(
        "scene = \"x.gltf\"\nemission_oversampling = 3\n",
        "/s/bake.toml",
    )
    .expect("valid");
    assert!(c.to_toml().contains("emission_oversampling = 3\n"));
}
