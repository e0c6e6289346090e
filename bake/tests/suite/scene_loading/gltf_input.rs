//! Malformed glTF and GLB input, hand-made: an error naming the problem (or a counted
//! warning), never a panic; the loader's transforms, cameras, lights and environment maps.

use super::*;

#[test]
fn minimal_scene_embedded_external_and_glb() {
    for variant in 0..3 {
        let dir = TempDir::new("minimal");
        let mut doc = Doc::new();
        doc.mesh(&TRI, Some(&[0, 1, 2]), None);
        let config = match variant {
            0 => {
                doc.write_embedded(&dir);
                dir.config("")
            }
            1 => {
                doc.write_external(&dir);
                dir.config("")
            }
            _ => {
                dir.write("scene.glb", doc.glb());
                let p = dir.write("bake.toml", "scene = \"scene.glb\"");
                BakeConfig::from_file(p).unwrap()
            }
        };
        let (scene, warnings) = load_with_warnings(&config).unwrap_or_else(|e| panic!("{e}"));
        assert!(warnings.is_empty(), "{warnings:?}");
        check_invariants(&scene);
        assert_eq!(scene.triangles.len(), 1);
        // No material: the white diffuse `default`.
        assert_eq!(scene.materials.len(), 1);
        assert_eq!(scene.materials[0].name, "default");
        assert_eq!(scene.materials[0].brdf.kd, Vec3::ONE);
        // No normals: flat, counter-clockwise front (+Z); no UVs: zero.
        assert!(scene.normals.iter().all(|n| *n == Vec3::Z));
        assert!(scene.uvs.iter().all(|t| *t == Vec2::ZERO));
        assert!(scene
            .camera
            .position
            .abs_diff_eq(Vec3::new(0.0, 0.0, 3.0), 1e-6));
        assert!(scene.camera.forward.abs_diff_eq(Vec3::NEG_Z, 1e-6));
    }
}

#[test]
fn truncated_glb_is_an_error() {
    let glb = std::fs::read(scenes_dir().join("furnace/furnace.glb")).unwrap();
    let dir = TempDir::new("trunc-glb");
    let p = dir.write("bake.toml", "scene = \"scene.glb\"");
    let config = BakeConfig::from_file(p).unwrap();
    let mut lengths: Vec<usize> = vec![
        0,
        3,
        4,
        11,
        12,
        19,
        20,
        27,
        100,
        glb.len() / 2,
        glb.len() - 1,
    ];
    lengths.extend((0..40).map(|k| k * glb.len() / 40));
    for len in lengths {
        dir.write("scene.glb", &glb[..len]);
        let e = load_err(&config);
        assert!(e.contains("scene.glb"), "{e}");
    }
    // A plausible-looking header whose length field is too small must not underflow.
    let mut bad = glb.clone();
    bad[8..12].copy_from_slice(&5u32.to_le_bytes());
    dir.write("scene.glb", &bad);
    assert!(load_err(&config).contains("GLB"));
}

#[test]
fn truncated_gltf_json_is_an_error() {
    let text = std::fs::read_to_string(scenes_dir().join("cornell/cornell.gltf")).unwrap();
    let bin = std::fs::read(scenes_dir().join("cornell/cornell.bin")).unwrap();
    let dir = TempDir::new("trunc-json");
    dir.write("cornell.bin", &bin);
    let p = dir.write("bake.toml", "scene = \"cornell.gltf\"");
    let config = BakeConfig::from_file(p).unwrap();
    for k in 0..30 {
        let cut = k * text.len() / 30;
        dir.write("cornell.gltf", &text[..cut]);
        let e = load_err(&config);
        assert!(e.contains("cornell.gltf"), "{e}");
    }
    dir.write("cornell.gltf", &text[..text.len() / 2]);
    assert!(load_err(&config).contains("malformed glTF JSON"));
}

/// Truncated buffers and flipped bytes anywhere in a GLB: always Ok or Err, never a panic.
#[test]
fn corrupted_bytes_never_panic() {
    let mut doc = Doc::new();
    doc.mesh(&TRI, Some(&[0, 1, 2]), None);
    let glb = doc.glb();
    let dir = TempDir::new("corrupt");
    let p = dir.write("bake.toml", "scene = \"scene.glb\"");
    let config = BakeConfig::from_file(p).unwrap();
    let mut state = 0x9E3779B97F4A7C15u64;
    for _ in 0..300 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let pos = (state >> 33) as usize % glb.len();
        let mut bytes = glb.clone();
        bytes[pos] ^= 1 << ((state >> 20) % 8);
        dir.write("scene.glb", &bytes);
        let _ = load_with_warnings(&config);
    }
}

#[test]
fn missing_bin_is_an_error_naming_the_file() {
    let dir = TempDir::new("missing-bin");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.write_external(&dir);
    std::fs::remove_file(dir.0.join("scene.bin")).unwrap();
    let e = load_err(&dir.config(""));
    assert!(e.contains("scene.bin") && e.contains("buffer 0"), "{e}");
}

#[test]
fn short_bin_is_an_error() {
    let dir = TempDir::new("short-bin");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.write_external(&dir);
    dir.write("scene.bin", [0u8; 20]);
    let e = load_err(&dir.config(""));
    assert!(e.contains("byteLength"), "{e}");
}

#[test]
fn accessor_past_the_end_of_its_view_is_an_error() {
    let dir = TempDir::new("accessor-range");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["accessors"][0]["count"] = json!(1000);
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(
        e.contains("mesh \"thing\"") && e.contains("POSITION"),
        "{e}"
    );
    // A zero-element accessor is merely empty.
    let dir = TempDir::new("accessor-zero");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["accessors"][0]["count"] = json!(0);
    doc.write_embedded(&dir);
    let (scene, _) = load_with_warnings(&dir.config("")).unwrap();
    assert!(scene.triangles.is_empty());
}

#[test]
fn wrong_accessor_type_is_an_error() {
    let dir = TempDir::new("accessor-type");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["accessors"][0]["type"] = json!("VEC2");
    doc.json["accessors"][0]["count"] = json!(4);
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(e.contains("VEC2"), "{e}");
}

#[test]
fn out_of_range_indices_are_an_error_naming_the_mesh() {
    let dir = TempDir::new("bad-indices");
    let mut doc = Doc::new();
    doc.mesh(&TRI, Some(&[0, 1, 7]), None);
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(
        e.contains("mesh \"thing\"") && e.contains("index 7") && e.contains("out of range"),
        "{e}"
    );
    let dir = TempDir::new("bad-index-count");
    let mut doc = Doc::new();
    doc.mesh(&TRI, Some(&[0, 1]), None);
    doc.write_embedded(&dir);
    assert!(load_err(&dir.config("")).contains("multiple of 3"));
}

#[test]
fn nan_and_degenerate_triangles_are_skipped_and_counted() {
    let dir = TempDir::new("nan");
    let mut doc = Doc::new();
    let nan = f32::NAN;
    #[rustfmt::skip]
    let pos = [
        0.0, 0.0, 0.0,  1.0, 0.0, 0.0,  0.0, 1.0, 0.0,   // good
        nan, 0.0, 0.0,  1.0, 0.0, 0.0,  0.0, 1.0, 0.0,   // NaN vertex
        0.0, 0.0, 0.0,  1.0, 0.0, 0.0,  2.0, 0.0, 0.0,   // collinear: zero area
    ];
    doc.mesh(&pos, Some(&[0, 1, 2, 3, 4, 5, 6, 7, 8, 0, 0, 1]), None);
    doc.write_embedded(&dir);
    let (scene, warnings) = load_with_warnings(&dir.config("")).unwrap();
    check_invariants(&scene);
    assert_eq!(scene.triangles.len(), 1);
    assert_eq!(scene.skipped_triangles, 3);
    // The NaN vertex is not kept.
    assert_eq!(scene.positions.len(), 3);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("skipped 3"), "{warnings:?}");
}

/// Found by fuzzing (`prt-fuzz gltf`): one finite vertex near f32::MAX among a thousand
/// triangles made the BVH builder (obvhs) panic. The loader drops such triangles like
/// non-finite ones, so every scene it returns can be traced.
#[test]
fn triangles_beyond_the_coordinate_limit_are_skipped() {
    let dir = TempDir::new("huge");
    let mut doc = Doc::new();
    let mut pos = Vec::new();
    for i in 0..1000 {
        let (x, y) = ((i % 32) as f32 * 0.1, (i / 32) as f32 * 0.1);
        pos.extend([x, y, 0.0, x + 0.1, y, 0.0, x, y + 0.1, 0.0]);
    }
    pos[4] = 2e38;
    pos[12] = 1.1e15;
    doc.mesh(&pos, None, None);
    doc.write_embedded(&dir);
    let (scene, warnings) = load_with_warnings(&dir.config("")).unwrap();
    check_invariants(&scene);
    assert_eq!(scene.skipped_triangles, 2);
    assert_eq!(scene.triangles.len(), 998);
    assert!(warnings[0].contains("skipped 2"), "{warnings:?}");
    let accel = prt_bake::accel::Accel::build(&scene);
    assert_eq!(accel.triangle_count(), 998);
}

/// Found by fuzzing (`prt-fuzz gltf`): a buffer URI naming a device was read until memory ran
/// out. URIs must name regular files.
#[test]
fn uris_naming_devices_or_folders_are_errors() {
    for uri in ["file:///dev/zero", "."] {
        let dir = TempDir::new("device");
        let mut doc = Doc::new();
        doc.mesh(&TRI, None, None);
        doc.json["buffers"] = json!([{"byteLength": 36, "uri": uri}]);
        dir.write("scene.gltf", doc.json.to_string());
        let e = load_err(&dir.config(""));
        assert!(e.contains("is not a regular file"), "{uri}: {e}");
    }
}

/// Found by fuzzing (`prt-fuzz gltf`): the glTF crate's validation does not check that a
/// camera has the projection its `type` names, or that an image has a source (and a MIME
/// type with a buffer view), and its accessors then panic. The loader refuses such files.
#[test]
fn cameras_and_images_must_have_what_their_accessors_unwrap() {
    let cases = [
        (
            "camera",
            json!({"cameras": [{"type": "orthographic", "perspective": {"yfov": 0.8, "znear": 0.1}}]}),
            "cameras[0].orthographic",
        ),
        (
            "image-view",
            json!({"images": [{"bufferView": 0}], "textures": [{"source": 0}]}),
            "images[0].mimeType",
        ),
        (
            "image-none",
            json!({"images": [{"name": "nothing"}], "textures": [{"source": 0}]}),
            "images[0].uri",
        ),
    ];
    for (tag, patch, expected) in cases {
        let dir = TempDir::new(tag);
        let mut doc = Doc::new();
        let m = doc.material(json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}));
        doc.mesh(&TRI, None, Some(m));
        for (k, v) in patch.as_object().unwrap() {
            doc.json[k] = v.clone();
        }
        doc.write_embedded(&dir);
        let e = load_err(&dir.config(""));
        assert!(e.contains(expected), "{tag}: {e}");
    }
}

#[test]
fn supplied_normals_are_transformed_and_bad_ones_repaired() {
    let dir = TempDir::new("normals");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    // Normals: +Z, zero, NaN; the node scales x by 2 and mirrors z (determinant < 0).
    let nor = doc.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0], "VEC3");
    doc.json["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(nor);
    doc.json["nodes"][1]["scale"] = json!([2.0, 1.0, -1.0]);
    doc.write_embedded(&dir);
    let (scene, warnings) = load_with_warnings(&dir.config("")).unwrap();
    check_invariants(&scene);
    assert!(
        warnings.iter().any(|w| w.contains("2 zero or non-finite")),
        "{warnings:?}"
    );
    // The mirrored triangle faces -Z; all its normals (transformed or repaired) agree, and
    // the winding was flipped so the geometric normal does too.
    assert!(scene
        .normals
        .iter()
        .all(|n| n.abs_diff_eq(Vec3::NEG_Z, 1e-6)));
    assert_eq!(winding_agreement(&scene), 1.0);
}

#[test]
fn node_hierarchy_transforms_compose() {
    let dir = TempDir::new("hierarchy");
    let mut doc = Doc::new();
    let child = doc.mesh(&TRI, None, None);
    // Move the mesh node under a parent: parent translates by +10 x, child by +1 y.
    doc.json["scenes"][0]["nodes"] = json!([0, child + 1]);
    doc.json["nodes"][child]["translation"] = json!([0.0, 1.0, 0.0]);
    doc.push(
        "nodes",
        json!({"name": "parent", "children": [child], "translation": [10.0, 0.0, 0.0]}),
    );
    doc.write_embedded(&dir);
    let (scene, _) = load_with_warnings(&dir.config("")).unwrap();
    let min = scene
        .positions
        .iter()
        .fold(Vec3::INFINITY, |a, &b| a.min(b));
    assert_eq!(min, Vec3::new(10.0, 1.0, 0.0));
}

#[test]
fn cyclic_nodes_are_an_error() {
    let dir = TempDir::new("cycle");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["nodes"][1]["children"] = json!([2]);
    doc.push("nodes", json!({"children": [1]}));
    doc.write_embedded(&dir);
    // Either the glTF validator or the loader must refuse it.
    let e = load_err(&dir.config(""));
    assert!(e.contains("scene.gltf"), "{e}");
}

#[test]
fn cameras_perspective_required() {
    let dir = TempDir::new("ortho");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["cameras"] = json!([{"type": "orthographic",
        "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.01, "zfar": 10.0}}]);
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(e.contains("orthographic"), "{e}");

    let dir = TempDir::new("nocam");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.json["nodes"][0] = json!({"name": "empty"});
    doc.json.as_object_mut().unwrap().remove("cameras");
    doc.write_embedded(&dir);
    let e = load_err(&dir.config(""));
    assert!(e.contains("no camera"), "{e}");

    // A rotated camera: 90 degrees about +Y turns -Z into -X.
    let dir = TempDir::new("camrot");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    let h = std::f32::consts::FRAC_PI_4;
    doc.json["nodes"][0]["rotation"] = json!([0.0, h.sin(), 0.0, h.cos()]);
    doc.write_embedded(&dir);
    let (scene, _) = load_with_warnings(&dir.config("")).unwrap();
    assert!(scene.camera.forward.abs_diff_eq(Vec3::NEG_X, 1e-6));
    assert!(scene.camera.right.abs_diff_eq(Vec3::NEG_Z, 1e-6));
    assert!(scene.camera.up.abs_diff_eq(Vec3::Y, 1e-6));
}

#[test]
fn punctual_lights_and_emission() {
    let dir = TempDir::new("lights");
    let mut doc = Doc::new();
    let m = doc.material(json!({
        "name": "glow",
        "emissiveFactor": [1.0, 0.5, 0.25],
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}
    }));
    doc.mesh(&TRI, None, Some(m));
    doc.json["extensionsUsed"] = json!(["KHR_lights_punctual", "KHR_materials_emissive_strength"]);
    doc.json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "point", "color": [1.0, 0.5, 0.5], "intensity": 10.0},
        {"type": "spot", "intensity": 2.0,
         "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}},
        {"type": "directional", "color": [0.5, 0.5, 1.0], "intensity": 3.0}
    ]}});
    let h = std::f32::consts::FRAC_PI_4;
    for (k, rot) in [
        [0.0, 0.0, 0.0, 1.0],
        [h.sin(), 0.0, 0.0, h.cos()],
        [0.0, 0.0, 0.0, 1.0],
    ]
    .iter()
    .enumerate()
    {
        let n = doc.push(
            "nodes",
            json!({"translation": [1.0, 2.0, 3.0], "rotation": rot,
                   "extensions": {"KHR_lights_punctual": {"light": k}}}),
        );
        doc.json["scenes"][0]["nodes"]
            .as_array_mut()
            .unwrap()
            .push(json!(n));
    }
    doc.write_embedded(&dir);
    let (scene, _) = load_with_warnings(&dir.config("")).unwrap();
    assert!(scene.materials[0]
        .emission
        .abs_diff_eq(Vec3::new(4.0, 2.0, 1.0), 1e-6));
    assert_eq!(scene.lights.len(), 3);
    assert_eq!(
        scene.lights[0],
        PunctualLight::Point {
            position: Vec3::new(1.0, 2.0, 3.0),
            intensity: Vec3::new(10.0, 5.0, 5.0)
        }
    );
    match scene.lights[1] {
        PunctualLight::Spot {
            position,
            direction,
            intensity,
            inner_cone,
            outer_cone,
        } => {
            assert_eq!(position, Vec3::new(1.0, 2.0, 3.0));
            // 90 degrees about +X turns -Z into +Y.
            assert!(direction.abs_diff_eq(Vec3::Y, 1e-6), "{direction}");
            assert_eq!(intensity, Vec3::splat(2.0));
            assert_eq!((inner_cone, outer_cone), (0.2, 0.5));
        }
        ref other => panic!("{other:?}"),
    }
    assert_eq!(
        scene.lights[2],
        PunctualLight::Directional {
            direction: Vec3::NEG_Z,
            irradiance: Vec3::new(1.5, 1.5, 3.0)
        }
    );
}

#[test]
fn config_material_names_must_exist() {
    let dir = TempDir::new("unknown-material");
    let mut doc = Doc::new();
    let m = doc.material(json!({"name": "paint"}));
    doc.mesh(&TRI, None, Some(m));
    doc.material(json!({}));
    doc.write_embedded(&dir);
    let e = load_err(&dir.config("[materials.pain]\neditable = true\n"));
    assert!(
        e.contains("pain") && e.contains("\"paint\"") && e.contains("\"material1\""),
        "{e}"
    );
    assert!(e.contains("bake.toml"), "{e}");
    // And a correct one applies.
    let (scene, _) =
        load_with_warnings(&dir.config("[materials.paint]\neditable = true\nkd = 0.25\n")).unwrap();
    assert!(scene.materials[0].editable);
    assert_eq!(scene.materials[0].brdf.kd, Vec3::splat(0.25));
    assert_eq!(scene.materials[1].name, "material1");
}

#[test]
fn editable_specular_family_without_parameters_is_an_error() {
    let dir = TempDir::new("family-params");
    let mut doc = Doc::new();
    let m = doc.material(json!({"name": "matte"}));
    doc.mesh(&TRI, None, Some(m));
    doc.write_embedded(&dir);
    // The default glTF material (metallic 1, roughness 1) is specular: it supplies Ks/alpha.
    // Make it a fully rough dielectric, which maps to diffuse and supplies nothing.
    let dir2 = TempDir::new("family-params2");
    let mut doc = Doc::new();
    let m = doc.material(json!({"name": "matte",
        "pbrMetallicRoughness": {"metallicFactor": 0.0}}));
    doc.mesh(&TRI, None, Some(m));
    doc.write_embedded(&dir2);
    let e =
        load_err(&dir2.config("[materials.matte]\neditable = true\nfamily = \"blinn-phong\"\n"));
    assert!(
        e.contains("matte") && e.contains("`ks`") && e.contains("`shininess`"),
        "{e}"
    );
    let (scene, _) = load_with_warnings(&dir2.config(
        "[materials.matte]\neditable = true\nfamily = \"blinn-phong\"\nks = 0.1\nshininess = 20\n",
    ))
    .unwrap();
    assert_eq!(scene.materials[0].brdf.family, Family::BlinnPhong);
    let e = load_err(&dir2.config("[materials.matte]\nalpha = 0.5\n"));
    assert!(e.contains("`alpha`") && e.contains("diffuse"), "{e}");
    drop(dir);
}

#[test]
fn environment_maps_exr_and_hdr() {
    let dir = TempDir::new("envmap");
    let mut doc = Doc::new();
    doc.mesh(&TRI, None, None);
    doc.write_embedded(&dir);
    // 4x2 maps whose texel (x, y) holds (x, y, 1).
    let (w, h) = (4usize, 2usize);
    exr::prelude::write_rgb_file(dir.0.join("sky.exr"), w, h, |x, y| {
        (x as f32, y as f32, 1.0f32)
    })
    .unwrap();
    let pixels: Vec<image::Rgb<f32>> = (0..h)
        .flat_map(|y| (0..w).map(move |x| image::Rgb([x as f32, y as f32, 1.0])))
        .collect();
    let mut hdr = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut hdr)
        .encode(&pixels, w, h)
        .unwrap();
    dir.write("sky.hdr", &hdr);
    for file in ["sky.exr", "sky.hdr"] {
        let config = dir.config(&format!(
            "[environment]\nmap = \"{file}\"\nintensity = 2.0\n"
        ));
        let (scene, _) = load_with_warnings(&config).unwrap_or_else(|e| panic!("{e}"));
        match &scene.environment {
            Environment::LatLong {
                width,
                height,
                texels,
            } => {
                assert_eq!((*width, *height), (4, 2));
                // Row 0 first (the top, +Y), intensity applied.
                assert!(
                    texels[1].abs_diff_eq(Vec3::new(2.0, 0.0, 2.0), 0.05),
                    "{file} {texels:?}"
                );
                assert!(
                    texels[4 + 3].abs_diff_eq(Vec3::new(6.0, 2.0, 2.0), 0.05),
                    "{file}"
                );
            }
            other => panic!("{other:?}"),
        }
    }
    let e = load_err(&dir.config("[environment]\nmap = \"nothere.exr\"\n"));
    assert!(e.contains("nothere.exr"), "{e}");
    dir.write("broken.hdr", b"#?RADIANCE\ngarbage");
    let e = load_err(&dir.config("[environment]\nmap = \"broken.hdr\"\n"));
    assert!(e.contains("broken.hdr"), "{e}");
    // A NaN or infinite texel is refused, naming the file and the texel; negative channels
    // (lossy compression's ringing) are clamped to 0 with a warning.
    exr::prelude::write_rgb_file(dir.0.join("nan.exr"), w, h, |x, y| {
        let r = if (x, y) == (2, 1) { f32::NAN } else { 1.0 };
        (r, 1.0f32, 1.0f32)
    })
    .unwrap();
    let e = load_err(&dir.config("[environment]\nmap = \"nan.exr\"\n"));
    assert!(
        e.contains("nan.exr") && e.contains("NaN or infinite") && e.contains("column 2, row 1"),
        "{e}"
    );
    exr::prelude::write_rgb_file(dir.0.join("negative.exr"), w, h, |x, y| {
        let g = if (x, y) == (1, 0) { -0.25 } else { 0.5 };
        (1.0f32, g, 1.0f32)
    })
    .unwrap();
    let (scene, warnings) =
        load_with_warnings(&dir.config("[environment]\nmap = \"negative.exr\"\n"))
            .unwrap_or_else(|e| panic!("{e}"));
    let Environment::LatLong { texels, .. } = &scene.environment else {
        panic!("{:?}", scene.environment)
    };
    assert_eq!(texels[1], Vec3::new(1.0, 0.0, 1.0));
    assert_eq!(texels[0], Vec3::new(1.0, 0.5, 1.0));
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("negative.exr") && w.contains("1 texel(s)")),
        "{warnings:?}"
    );
}
