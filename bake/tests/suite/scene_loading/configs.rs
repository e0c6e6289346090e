//! Configs: unknown keys and bad values name the key, the documented example parses, and
//! `bake INPUT` accepts a config, a scene folder or a bare glTF (`config::input`), configs
//! written back as TOML.

use super::*;

// ---------------------------------------------------------------------------------------------
// Configs.

fn config_err(text: &str) -> String {
    match BakeConfig::parse(text, "/somewhere/bake.toml") {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => {
            let s = e.to_string();
            assert!(s.contains("/somewhere/bake.toml"), "{s}");
            s
        }
    }
}

#[test]
fn config_unknown_keys_are_errors() {
    let e = config_err("scene = \"a.gltf\"\nsamples = 3\n");
    assert!(e.contains("unknown field `samples`"), "{e}");
    let e = config_err("scene = \"a.gltf\"\n[materials.m]\neditible = true\n");
    assert!(e.contains("editible"), "{e}");
    let e = config_err("scene = \"a.gltf\"\n[environment]\ncolour = 1\n");
    assert!(e.contains("colour"), "{e}");
    let e = config_err("scene = \"a.gltf\"\n[basis]\ncont = 3\n");
    assert!(e.contains("cont"), "{e}");
    let e = config_err("scene = \"a.gltf\"\n[bake]\nx = 3\n");
    assert!(e.contains("bake"), "{e}");
    let e = config_err("width = 3\n");
    assert!(e.contains("scene"), "{e}");
    let e = config_err("scene = \"a.gltf\"\nwidth = \n");
    assert!(e.contains("line 2"), "{e}");
}

#[test]
fn config_bad_values_name_the_key() {
    let cases: &[(&str, &str)] = &[
        ("width = 0", "`width`"),
        ("height = 20000", "`height`"),
        ("width = -3", "width"),
        ("spp = 0", "`spp`"),
        ("spp = 100000000", "`spp`"),
        ("reflections = 0", "`reflections`"),
        // One limit for the config and the integrator: more would be silently clamped.
        ("reflections = 5", "`reflections`"),
        ("mode = \"voxel\"", "voxel"),
        ("seed = -1", "seed"),
        ("[environment]\ncolor = [1, -1, 0]", "`environment.color`"),
        ("[environment]\ncolor = [1, nan, 0]", "`environment.color`"),
        ("[environment]\ncolor = [1, 1]", "color"),
        ("[environment]\ncolor = \"white\"", "color"),
        ("[environment]\nmap = \"sky.png\"", "`environment.map`"),
        (
            "[environment]\nmap = \"sky.exr\"\nintensity = -2",
            "`environment.intensity`",
        ),
        ("[environment]\nintensity = 2", "`environment`"),
        ("[materials.m]\nkd = [0.5, -0.1, 0]", "`materials.m.kd`"),
        ("[materials.m]\nks = inf", "`materials.m.ks`"),
        (
            "[materials.m]\nfamily = \"cook-torrance\"",
            "`materials.m.family`",
        ),
        (
            "[materials.m]\nfamily = \"blinn-phong\"\nshininess = -1",
            "`materials.m.shininess`",
        ),
        (
            "[materials.m]\nfamily = \"blinn-phong\"\nshininess = 2e6",
            "`materials.m.shininess`",
        ),
        (
            "[materials.m]\nfamily = \"ggx\"\nalpha = 0",
            "`materials.m.alpha`",
        ),
        (
            "[materials.m]\nfamily = \"ggx\"\nalpha = 1.5",
            "`materials.m.alpha`",
        ),
        (
            "[materials.m]\nfamily = \"diffuse\"\nks = 0.5",
            "`materials.m.ks`",
        ),
        ("[materials.m]\nshininess = 10", "`materials.m.shininess`"),
        ("[materials.m]\neditable = \"yes\"", "editable"),
        ("[basis]\ncount = 0", "`basis.count`"),
        ("[basis]\nerror_target = -0.1", "`basis.error_target`"),
        ("output = \"\"", "`output`"),
    ];
    for (body, key) in cases {
        let e = config_err(&format!("scene = \"a.gltf\"\n{body}\n"));
        assert!(e.contains(key), "{body:?}: expected {key:?} in: {e}");
    }
}

#[test]
fn config_full_example_parses() {
    let c = BakeConfig::parse(
        r#"
scene = "models/room.glb"
output = "/tmp/room.prtbake"
mode = "vertex"
width = 320
height = 200
spp = 16
reflections = 3
seed = 42

[environment]
map = "sky.hdr"
intensity = 0.5

[materials.floor]
kd = [0.2, 0.3, 0.4]

[materials.vase]
editable = true
family = "ggx"
ks = 0.04
alpha = 0.3

[basis]
count = 6
error_target = 0.01
"#,
        "/project/bake.toml",
    )
    .unwrap();
    assert_eq!(c.scene_path, PathBuf::from("/project/models/room.glb"));
    assert_eq!(c.output, PathBuf::from("/tmp/room.prtbake"));
    assert_eq!(c.mode, Mode::Vertex);
    assert_eq!(
        (c.width, c.height, c.spp, c.reflections, c.seed),
        (320, 200, 16, 3, 42)
    );
    assert_eq!(
        c.environment,
        EnvironmentConfig::Map {
            path: PathBuf::from("/project/sky.hdr"),
            intensity: 0.5,
            rotation: 0.0,
        }
    );
    assert_eq!(c.materials.len(), 2);
    let vase = c.material("vase").unwrap();
    assert!(vase.editable && vase.family == Some(Family::Ggx) && vase.alpha == Some(0.3));
    let basis = c.basis.as_ref().unwrap();
    assert_eq!((basis.count, basis.error_target), (Some(6), Some(0.01)));
    assert_eq!(c.folder(), Path::new("/project"));
}

#[test]
fn config_default_output_and_missing_file() {
    let c = BakeConfig::from_file(scenes_dir().join("ring/bake.toml")).unwrap();
    assert_eq!(c.output, scenes_dir().join("ring/out/ring.prtbake"));
    match BakeConfig::from_file(scenes_dir().join("nope/bake.toml")) {
        Err(ConfigError::Io { path, .. }) => assert!(path.ends_with("nope/bake.toml")),
        other => panic!("{other:?}"),
    }
    let c = BakeConfig::with_defaults("/x/y/scene.glb");
    assert_eq!(c.output, PathBuf::from("/x/y/out/y.prtbake"));
    assert_eq!(c.scene_path, PathBuf::from("/x/y/scene.glb"));
}

#[test]
fn missing_scene_file_is_an_io_error() {
    let c = BakeConfig::with_defaults("/definitely/not/here.gltf");
    match load_with_warnings(&c) {
        Err(e @ SceneError::Io { .. }) => assert!(e.to_string().contains("here.gltf")),
        other => panic!("{:?}", other.map(|_| ())),
    }
}

#[test]
fn interleaved_and_sparse_accessors() {
    let dir = TempDir::new("interleaved");
    let mut doc = Doc::new();
    // Positions and normals interleaved in one view (stride 24), and a sparse accessor that
    // moves vertex 2 of the positions from (0, 1, 0) to (0, 2, 0).
    let mut inter = Vec::new();
    for k in 0..3 {
        for v in [TRI[3 * k], TRI[3 * k + 1], TRI[3 * k + 2], 0.0, 0.0, 1.0] {
            inter.extend_from_slice(&f32::to_le_bytes(v));
        }
    }
    let view = doc.view(&inter);
    doc.json["bufferViews"][view]["byteStride"] = json!(24);
    let sparse_idx = doc.view(&[2u8]);
    let sparse_val = doc.view(&[0.0f32, 2.0, 0.0].map(f32::to_le_bytes).concat());
    let pos = doc.push(
        "accessors",
        json!({"bufferView": view, "componentType": 5126, "count": 3, "type": "VEC3",
               "sparse": {"count": 1,
                          "indices": {"bufferView": sparse_idx, "componentType": 5121},
                          "values": {"bufferView": sparse_val}}}),
    );
    let nor = doc.push(
        "accessors",
        json!({"bufferView": view, "byteOffset": 12, "componentType": 5126, "count": 3,
               "type": "VEC3"}),
    );
    let mesh = doc.push(
        "meshes",
        json!({"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nor}}]}),
    );
    let node = doc.push("nodes", json!({"mesh": mesh}));
    doc.json["scenes"][0]["nodes"] = json!([0, node]);
    doc.write_embedded(&dir);
    let (scene, warnings) = load_with_warnings(&dir.config("")).unwrap_or_else(|e| panic!("{e}"));
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(
        scene.positions,
        [Vec3::ZERO, Vec3::X, Vec3::new(0.0, 2.0, 0.0)]
    );
    assert!(scene.normals.iter().all(|n| *n == Vec3::Z));
}

/// The example in docs/config.md must stay a valid config.
#[test]
fn documented_example_config_parses() {
    let doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/config.md"))
            .unwrap();
    let start = doc.find("```toml\n").expect("a toml block") + "```toml\n".len();
    let end = start + doc[start..].find("```").unwrap();
    let c = BakeConfig::parse(&doc[start..end], scenes_dir().join("cornell/bake.toml"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(c.materials.len(), 2);
    // And it fits the scene it claims to be for.
    load_with_warnings(&c).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn shared_child_nodes_are_an_error() {
    // Node 2 is a child of both node 1 and node 3: a DAG, not a tree.
    let dir = TempDir::new("dag");
    let mut doc = Doc::new();
    let m = doc.mesh(&TRI, None, None);
    let a = doc.push("nodes", json!({"children": [m]}));
    let b = doc.push("nodes", json!({"children": [m]}));
    doc.json["scenes"][0]["nodes"] = json!([0, a, b]);
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(e.contains("two parents"), "{e}");
}

#[test]
fn glb_embedded_image_via_buffer_view() {
    let dir = TempDir::new("glb-image");
    let mut png = Vec::new();
    image::RgbImage::from_raw(1, 1, vec![0, 255, 0])
        .unwrap()
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let mut doc = Doc::new();
    let m = doc.material(json!({"name": "glowing",
        "emissiveFactor": [1.0, 1.0, 1.0], "emissiveTexture": {"index": 0}}));
    doc.mesh(&TRI, None, Some(m));
    let view = doc.view(&png);
    doc.json["textures"] = json!([{"source": 0}]);
    doc.json["images"] = json!([{"bufferView": view, "mimeType": "image/png"}]);
    dir.write("scene.glb", doc.glb());
    let p = dir.write("bake.toml", "scene = \"scene.glb\"");
    let (scene, _) =
        load_with_warnings(&BakeConfig::from_file(p).unwrap()).unwrap_or_else(|e| panic!("{e}"));
    let t = scene.materials[0].emissive_texture.unwrap();
    assert_eq!(scene.textures[t].texels, [Vec3::Y]);
    assert!(scene.materials[0].is_emissive());
}

// ---------------------------------------------------------------------------------------------
// What `bake INPUT` accepts (config::input) and configs written back as TOML.

/// The config's TOML parses back (from the same config path) to the same config, and writing
/// that again gives the same text.
fn assert_roundtrip(c: &BakeConfig) {
    let text = c.to_toml();
    let back = BakeConfig::parse(&text, &c.config_path).unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert_eq!(&back, c, "{text}");
    assert_eq!(back.to_toml(), text);
}

/// Found by fuzzing (`prt-fuzz config`): a path naming the config's own folder was written
/// back as `""`, which the parser refuses.
#[test]
fn roundtrip_keeps_a_path_naming_the_config_folder() {
    let c = BakeConfig::parse("scene = \".\"\noutput = \"./\"", "/scenes/x/bake.toml").unwrap();
    assert_eq!(c.scene_path, PathBuf::from("/scenes/x"));
    assert_roundtrip(&c);
}

#[test]
fn input_folder_means_its_bake_toml() {
    let r = input::resolve(&scenes_dir().join("cornell")).unwrap();
    assert_eq!(r.kind, InputKind::SceneFolder);
    let direct = BakeConfig::from_file(scenes_dir().join("cornell/bake.toml")).unwrap();
    assert_eq!(r.config, direct);
    let r = input::resolve(&scenes_dir().join("cornell/bake.toml")).unwrap();
    assert_eq!(r.kind, InputKind::Config);
    assert_eq!(r.config, direct);
    // The example configs survive a round trip through TOML too.
    for name in ["cornell", "ring", "furnace"] {
        assert_roundtrip(&load_example(name).0);
    }
}

#[test]
fn input_glb_bakes_with_defaults() {
    let path = scenes_dir().join("furnace/furnace.glb");
    let r = input::resolve(&path).unwrap();
    assert_eq!(r.kind, InputKind::Gltf);
    let c = &r.config;
    assert_eq!(c.scene_path, path);
    assert_eq!(c.mode, Mode::Pixel);
    assert_eq!((c.width, c.height, c.spp, c.reflections), (256, 256, 64, 2));
    assert_eq!(c.output, scenes_dir().join("furnace/out/furnace.prtbake"));
    // Under the neutral studio map shipped with the project (a bare glTF rarely brings lights).
    assert_eq!(
        c.environment,
        EnvironmentConfig::Map {
            path: prt_bake::config::default_environment_map(),
            intensity: 1.0,
            rotation: 0.0
        }
    );
    assert!(prt_bake::config::default_environment_map().is_file());
    // The GLB has a camera, so the config names none and the glTF's is used.
    assert!(c.camera.is_none());
    let editable_diffuse = MaterialConfig {
        editable: true,
        family: Some(Family::Diffuse),
        ..MaterialConfig::default()
    };
    assert_eq!(c.materials, vec![("sphere".to_owned(), editable_diffuse)]);
    let scene = prt_bake::run::load_scene(c, &prt_bake::progress::Silent).unwrap();
    let (_, example, _) = load_example("furnace");
    assert_eq!(scene.camera, example.camera);
    assert!(scene.materials[0].editable);
    assert_roundtrip(c);
}

#[test]
fn input_gltf_leaves_emissive_materials_alone() {
    let r = input::resolve(&scenes_dir().join("cornell/cornell.gltf")).unwrap();
    let names: Vec<&str> = r.config.materials.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["white", "red", "green", "bunny", "tall_box"]);
    let family = |n: &str| r.config.material(n).unwrap().family;
    // The bunny is glossy in the glTF (ggx); the walls and the tall box are fully rough.
    assert_eq!(family("bunny"), Some(Family::Ggx));
    assert_eq!(family("white"), Some(Family::Diffuse));
    assert_eq!(family("tall_box"), Some(Family::Diffuse));
    assert!(r.config.materials.iter().all(|(_, m)| m.editable));
    let scene = prt_bake::run::load_scene(&r.config, &prt_bake::progress::Silent).unwrap();
    assert!(!scene.materials[scene.material_index("light").unwrap()].editable);
    assert_roundtrip(&r.config);
}

#[test]
fn input_gltf_without_camera_gets_a_framing_camera() {
    let dir = TempDir::new("frame");
    let mut doc = Doc::new();
    doc.mesh(
        &[
            2.0, 1.0, -3.0, 4.0, 1.0, -3.0, 2.0, 3.0, -4.0, 5.0, -1.0, -6.0, 6.0, 0.0, -6.0, 5.0,
            0.5, -5.0,
        ],
        None,
        None,
    );
    doc.json["nodes"][0] = json!({"name": "empty"});
    doc.json.as_object_mut().unwrap().remove("cameras");
    let path = doc.write_embedded(&dir);
    // Loading it with a plain config is still an error: only the defaults frame the scene.
    assert!(load_err(&BakeConfig::with_defaults(&path)).contains("no camera"));

    let r = input::resolve(&path).unwrap();
    assert_eq!(r.kind, InputKind::Gltf);
    let framing = r.config.camera.expect("a framing camera");
    assert!(framing.position.is_finite() && framing.target.is_finite());
    let scene = prt_bake::run::load_scene(&r.config, &prt_bake::progress::Silent).unwrap();
    let cam = scene.camera;
    assert!(cam.position.is_finite() && cam.forward.is_finite() && cam.up.is_finite());
    let tan = (0.5 * cam.yfov).tan();
    let aspect = r.config.width as f32 / r.config.height as f32;
    for p in &scene.positions {
        let d = *p - cam.position;
        let z = d.dot(cam.forward);
        assert!(z > 0.0, "{p} is behind the camera");
        assert!(
            d.dot(cam.up).abs() / z < tan,
            "{p} is above or below the view"
        );
        assert!(
            d.dot(cam.right).abs() / z < tan * aspect,
            "{p} is left or right of the view"
        );
    }
    // Primitives without a material share `default`: editable diffuse.
    assert_eq!(r.config.materials.len(), 1);
    assert_eq!(r.config.materials[0].0, "default");
    assert_eq!(r.config.materials[0].1.family, Some(Family::Diffuse));
    assert_roundtrip(&r.config);

    // The printed config, saved beside the glTF, gives the same config and the same scene.
    dir.write("bake.toml", r.config.to_toml());
    let again = input::resolve(&dir.0).unwrap();
    assert_eq!(again.kind, InputKind::SceneFolder);
    assert_eq!(again.config, r.config);
    let scene2 = prt_bake::run::load_scene(&again.config, &prt_bake::progress::Silent).unwrap();
    assert_eq!(scene2.camera, scene.camera);
    assert_eq!(scene2.positions, scene.positions);
}

#[test]
fn input_of_the_wrong_form_says_what_was_expected() {
    const EXPECTED: &str = "expected a bake config (.toml), a scene folder holding bake.toml, \
                            or a glTF scene (.gltf/.glb)";
    let dir = TempDir::new("forms");
    dir.write("notes.txt", "hello");
    for (path, reason) in [
        (dir.0.join("missing"), "no such file or folder"),
        (dir.0.join("missing.glb"), "no such file or folder"),
        (dir.0.clone(), "the folder holds no bake.toml"),
        (dir.0.join("notes.txt"), "unknown file type"),
    ] {
        let e = input::resolve(&path).unwrap_err();
        assert!(matches!(e, InputError::WrongForm { .. }), "{e:?}");
        let e = e.to_string();
        assert!(e.starts_with(&path.display().to_string()), "{e}");
        assert!(e.contains(reason) && e.contains(EXPECTED), "{e}");
    }
    // The right form with bad content: the config's or the scene's own error, naming the file.
    dir.write("bad.toml", "scene = ");
    let e = input::resolve(&dir.0.join("bad.toml")).unwrap_err();
    assert!(matches!(e, InputError::Config(_)), "{e:?}");
    assert!(e.to_string().contains("bad.toml"), "{e}");
    let e = input::resolve(&dir.0.join("absent.toml")).unwrap_err();
    assert!(
        matches!(e, InputError::Config(ConfigError::Io { .. })),
        "{e:?}"
    );
    dir.write("bad.glb", "not a glb");
    let e = input::resolve(&dir.0.join("bad.glb")).unwrap_err();
    assert!(
        matches!(e, InputError::Scene(SceneError::Parse { .. })),
        "{e:?}"
    );
    assert!(e.to_string().contains("bad.glb"), "{e}");
}

#[test]
fn config_camera_table() {
    let c = BakeConfig::parse(
        "scene = \"x.gltf\"\n[camera]\nposition = [0, 1, 5]\ntarget = [0, 1, 0]\n",
        "/somewhere/bake.toml",
    )
    .unwrap();
    let cam = c.camera.unwrap();
    assert_eq!(cam.position, Vec3::new(0.0, 1.0, 5.0));
    assert_eq!(cam.fov, prt_bake::config::DEFAULT_FOV);
    assert_roundtrip(&c);
    for (body, key) in [
        ("position = [0, 0, 0]\ntarget = [0, 0, 0]", "camera.target"),
        ("position = [0, 0, 0]\ntarget = [0, 5, 0]", "camera.target"),
        (
            "position = [0, 0, 1]\ntarget = [0, 0, 0]\nyfov = 4",
            "camera.yfov",
        ),
        ("position = [0, 0, 1]", "target"),
        (
            "position = [0, 0, 1]\ntarget = [0, 0, 0]\nfov = 180",
            "camera.fov",
        ),
        (
            "position = [0, 0, 1]\ntarget = [0, 0, 0]\nfov = 0",
            "camera.fov",
        ),
        (
            "position = [0, 0, 1]\ntarget = [0, 0, 0]\nfov = 40\nyfov = 0.7",
            "camera.yfov",
        ),
        (
            "position = [0, 0, 1]\ntarget = [0, 0, 0]\nfovy = 40",
            "fovy",
        ),
    ] {
        let e = config_err(&format!("scene = \"x.gltf\"\n[camera]\n{body}\n"));
        assert!(e.contains(key), "{body:?}: {e}");
    }
}
