//! Textures: colour textures decoded from sRGB to linear, normal maps decoded to
//! tangent-space vectors with their scale, each image once per encoding.

use glam::{Vec2, Vec3};
use prt_bake::scene::load_with_warnings;
use serde_json::json;

use super::{load_err, Doc, TempDir, TRI};

/// A PNG of `width x height` RGB8 texels.
fn png(width: u32, height: u32, texels: Vec<u8>) -> Vec<u8> {
    let mut out = Vec::new();
    image::RgbImage::from_raw(width, height, texels)
        .expect("texel count")
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .expect("png");
    out
}

#[test]
fn textures_are_decoded_to_linear() {
    let dir = TempDir::new("texture");
    // A 2x1 PNG: sRGB 255 and 128.
    dir.write("albedo.png", png(2, 1, vec![255, 255, 255, 128, 128, 128]));
    let mut doc = Doc::new();
    let m = doc.material(json!({"name": "textured",
        "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}));
    doc.mesh(&TRI, None, Some(m));
    let uv = doc.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC2");
    doc.json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(uv);
    doc.json["textures"] = json!([{"source": 0}]);
    doc.json["images"] = json!([{"uri": "albedo.png"}]);
    let gltf = doc.write_embedded(&dir);
    let config = dir.config("");
    let (scene, warnings) = load_with_warnings(&config).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    let t = scene.materials[0].base_color_texture.unwrap();
    let tex = &scene.textures[t];
    assert_eq!((tex.width, tex.height), (2, 1));
    assert!(tex.texels[0].abs_diff_eq(Vec3::ONE, 1e-6));
    assert!(
        (tex.texels[1].x - 0.2158605).abs() < 1e-4,
        "{}",
        tex.texels[1]
    );
    assert_eq!(scene.uvs[1], Vec2::new(1.0, 0.0));

    // The same image missing: an error naming the image file.
    std::fs::remove_file(dir.0.join("albedo.png")).unwrap();
    let e = load_err(&config);
    assert!(e.contains("albedo.png") && e.contains("image 0"), "{e}");
    // Not an image at all.
    dir.write("albedo.png", b"not a png");
    let e = load_err(&config);
    assert!(e.contains("cannot decode"), "{e}");
    drop(gltf);
}

/// A normal map is read linearly (128 is the middle, not sRGB's 0.216) and stored decoded,
/// `(2c - 1) (scale, scale, 1)`; the same image also used as a base colour is a second,
/// sRGB-decoded texture; a primitive without TEXCOORD_0 is warned about.
#[test]
fn normal_maps_are_decoded_linearly_with_their_scale() {
    let dir = TempDir::new("normal-map");
    dir.write("bumps.png", png(2, 1, vec![255, 128, 255, 128, 0, 128]));
    // Material 0 carries the map, material 1 the same image as its colour.
    let write = |with_uv: bool| {
        let mut doc = Doc::new();
        let bumpy = doc.material(json!({"name": "bumpy",
            "normalTexture": {"index": 0, "scale": 0.5}}));
        let painted = doc.material(json!({"name": "painted",
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}));
        doc.mesh(&TRI, None, Some(bumpy));
        if with_uv {
            let uv = doc.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC2");
            doc.json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(uv);
        }
        doc.mesh(&TRI, None, Some(painted));
        doc.json["textures"] = json!([{"source": 0}]);
        doc.json["images"] = json!([{"uri": "bumps.png"}]);
        doc.write_embedded(&dir)
    };
    write(true);
    let config = dir.config("");
    let (scene, warnings) = load_with_warnings(&config).unwrap();
    let n = scene.materials[0].normal_texture.expect("a normal map");
    let map = &scene.textures[n];
    let mid = 2.0 * 128.0 / 255.0 - 1.0;
    assert!(
        map.texels[0].abs_diff_eq(Vec3::new(0.5, 0.5 * mid, 1.0), 1e-6),
        "{}",
        map.texels[0]
    );
    assert!(
        map.texels[1].abs_diff_eq(Vec3::new(0.5 * mid, -0.5, mid), 1e-6),
        "{}",
        map.texels[1]
    );
    let c = scene.materials[1]
        .base_color_texture
        .expect("a colour texture");
    assert_ne!(c, n, "one image, two encodings: two textures");
    assert!((scene.textures[c].texels[0].y - 0.2158605).abs() < 1e-4);
    assert_eq!(scene.materials[1].normal_texture, None);
    assert!(
        !warnings.iter().any(|w| w.contains("normalTexture")),
        "the mapped primitive has texture coordinates: {warnings:?}"
    );
    assert_eq!(scene.uvs[1], Vec2::new(1.0, 0.0));

    // Without texture coordinates the map cannot be oriented: said, naming the mesh.
    write(false);
    let (_, warnings) = load_with_warnings(&config).unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("normalTexture") && w.contains("no TEXCOORD_0")),
        "{warnings:?}"
    );
}

/// A metallicRoughnessTexture is read linearly and varies the BRDF of a fixed material the
/// config leaves alone; one BRDF for the whole material (an editable one's starting values,
/// the per-vertex last reflection) maps from the factors times the texture's mean; the
/// variation is dropped, saying why, for an editable material and for one whose BRDF the
/// config sets; a per-vertex bake says what its last reflection uses.
#[test]
fn metallic_roughness_textures_vary_fixed_materials_and_say_where_they_cannot() {
    let dir = TempDir::new("metallic-roughness");
    dir.write("mr.png", png(1, 1, vec![0, 128, 255]));
    let mut doc = Doc::new();
    let m = doc.material(json!({"name": "metal",
        "pbrMetallicRoughness": {"metallicRoughnessTexture": {"index": 0},
                                 "metallicFactor": 1.0, "roughnessFactor": 0.8}}));
    doc.mesh(&TRI, None, Some(m));
    let uv = doc.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC2");
    doc.json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(uv);
    doc.json["textures"] = json!([{"source": 0}]);
    doc.json["images"] = json!([{"uri": "mr.png"}]);
    let gltf = doc.write_embedded(&dir);

    let (scene, warnings) = load_with_warnings(&dir.config("")).unwrap();
    assert!(
        !warnings.iter().any(|w| w.contains("metallicRoughness")),
        "{warnings:?}"
    );
    let map = scene.materials[0]
        .metallic_roughness
        .expect("a fixed material keeps its map");
    assert_eq!((map.pbr.metallic, map.pbr.roughness), (1.0, 0.8));
    let texel = scene.textures[map.texture].texels[0];
    assert!(
        texel.abs_diff_eq(Vec3::new(0.0, 128.0 / 255.0, 1.0), 1e-6),
        "linear, not sRGB: {texel}"
    );

    // One BRDF for the whole material maps from the factors times the texture's mean:
    // metallic 1 x 1, roughness 0.8 x 128/255 (GGX alpha = roughness^2), not the factors'
    // roughness 0.8.
    let mean_alpha = (0.8f32 * 128.0 / 255.0).powi(2);
    assert!((scene.materials[0].brdf.param - mean_alpha).abs() < 1e-5);
    let ignored = |extra: &str, why: &str| {
        let (scene, warnings) = load_with_warnings(&dir.config(extra)).unwrap();
        assert!(scene.materials[0].metallic_roughness.is_none(), "{extra}");
        if extra.contains("editable") {
            assert!(
                (scene.materials[0].brdf.param - mean_alpha).abs() < 1e-5,
                "{extra}: the texture's mean"
            );
        }
        assert!(
            warnings.iter().any(|w| w.contains("\"metal\"")
                && w.contains("metallicRoughnessTexture's variation is not baked")
                && w.contains(why)),
            "{extra}: {warnings:?}"
        );
    };
    ignored("[materials.metal]\neditable = true\n", "the ones you edit");
    ignored("[materials.metal]\nalpha = 0.3\n", "the config sets");
    ignored(
        "[materials.metal]\nfamily = \"blinn-phong\"\n",
        "the config sets",
    );
    // Made fixed as the warning says, with the family `--print-config` writes: honoured.
    let fixed = "[materials.metal]\neditable = false\nfamily = \"ggx\"\n";
    let (scene, _) = load_with_warnings(&dir.config(fixed)).unwrap();
    assert!(scene.materials[0].metallic_roughness.is_some());

    let (scene, warnings) = load_with_warnings(&dir.config("mode = \"vertex\"\n")).unwrap();
    assert!(scene.materials[0].metallic_roughness.is_some());
    assert!(
        warnings.iter().any(|w| w.contains("\"metal\"")
            && w.contains("the texture's mean (metallic 1.00, roughness 0.40)")),
        "{warnings:?}"
    );
    drop(gltf);
}
