//! Behaviour of bake -> relight beyond exactness (issue 4 tests (c), (d), (e)): edits are
//! local, hard settings stay finite, bad input gets clear errors.

use glam::Vec3;
use prt_bake::brdf::BrdfParams;
use prt_bake::pixel::Precision;
use prt_bake::testing::SceneBuilder;
use prt_formats::overrides::parse_override;
use prt_formats::pixel::PixelBakeMeta;
use prt_runtime::{PixelRelighter, RuntimeError, Variant};
use prt_tests::{
    assert_same_size, bake_to_file, bases_for, relative_l2, small_options, temp_path, test_scene,
};

fn set(r: &mut PixelRelighter, edits: &[&str]) {
    for e in edits {
        prt_tests::edit_pixel(r, e).expect("apply");
    }
}

/// With direct light only, editing a material changes exactly the pixels where it is
/// visible (antialiased edges included) and leaves every other pixel bit-identical.
#[test]
fn direct_only_edit_changes_exactly_the_objects_pixels() {
    let scene = test_scene(Vec3::ONE, Vec3::ZERO);
    let bases = bases_for(&scene, 4);
    let (_, path) = bake_to_file(
        &scene,
        &bases,
        &small_options(32, 24, 4, 1, Precision::F32),
        "local1.prtbake",
    );
    let mut r = PixelRelighter::open(&path).expect("open");
    let before = r.render().expect("render").pixels;
    set(&mut r, &["shiny.kd=0.9,0.9,0.1", "shiny.shininess=5"]);
    let after = r.render().expect("render").pixels;
    let meta = r.meta();
    let shiny = meta
        .materials
        .iter()
        .position(|m| m.name == "shiny")
        .expect("shiny") as u32;
    let g = meta
        .groups
        .iter()
        .position(|g| g.material == shiny)
        .expect("shiny visible");
    let file = prt_formats::BakeFile::open(&path).expect("file");
    let pixels: Vec<u32> = file
        .tensor(&format!("g{g}.pixels"))
        .expect("pixels")
        .as_u32()
        .expect("u32")
        .to_vec();
    let (mut changed, mut same) = (0, 0);
    assert_same_size(&before, &after);
    for (i, (a, b)) in before.iter().zip(&after).enumerate() {
        if pixels.contains(&(i as u32)) {
            changed += usize::from(a != b);
        } else {
            assert_eq!(a, b, "pixel {i} does not see 'shiny' but changed");
            same += 1;
        }
    }
    assert!(
        changed > 20 && same > 100,
        "changed {changed}, unchanged {same}"
    );
    let _ = std::fs::remove_file(&path);
}

/// With bounces, a pixel whose stored transfer never involves the edited material's slots is
/// bit-identical after the edit; pixels that do involve it change.
#[test]
fn indirect_edit_leaves_pixels_without_its_light_unchanged() {
    // A partition hides the editable block from the left half of the floor.
    let mut b = SceneBuilder::new();
    let floor = b.material(
        "floor",
        BrdfParams::diffuse(Vec3::splat(0.6)),
        Vec3::ZERO,
        false,
    );
    let block = b.material(
        "block",
        BrdfParams::diffuse(Vec3::splat(0.5)),
        Vec3::ZERO,
        true,
    );
    let lamp = b.material(
        "lamp",
        BrdfParams::diffuse(Vec3::ZERO),
        Vec3::splat(10.0),
        false,
    );
    b.quad(
        [
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(-2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0),
        ],
        floor,
    );
    // Partition at x = 0, taller than everything.
    b.quad(
        [
            Vec3::new(0.0, 0.0, -2.0),
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(0.0, 3.0, 2.0),
            Vec3::new(0.0, 3.0, -2.0),
        ],
        floor,
    );
    b.quad(
        [
            Vec3::new(0.3, 0.0, -0.8),
            Vec3::new(1.8, 0.0, -0.8),
            Vec3::new(1.8, 1.5, -0.8),
            Vec3::new(0.3, 1.5, -0.8),
        ],
        block,
    );
    b.quad(
        [
            Vec3::new(-1.5, 2.5, -0.5),
            Vec3::new(-0.5, 2.5, -0.5),
            Vec3::new(-0.5, 2.5, 0.5),
            Vec3::new(-1.5, 2.5, 0.5),
        ],
        lamp,
    );
    b.quad(
        [
            Vec3::new(0.5, 2.5, -0.5),
            Vec3::new(1.5, 2.5, -0.5),
            Vec3::new(1.5, 2.5, 0.5),
            Vec3::new(0.5, 2.5, 0.5),
        ],
        lamp,
    );
    b.camera(prt_bake::testing::look_at(
        Vec3::new(0.0, 5.0, 3.0),
        Vec3::ZERO,
        Vec3::Y,
        50f32.to_radians(),
    ));
    let scene = b.build();
    let (layout, path) = bake_to_file(
        &scene,
        &[],
        &small_options(32, 24, 32, 2, Precision::F32),
        "local2.prtbake",
    );
    let mut r = PixelRelighter::open(&path).expect("open");
    let before = r.render().expect("render").pixels;
    set(&mut r, &["block.kd=0.1,0.9,0.2"]);
    let after = r.render().expect("render").pixels;

    // Which pixels' rows involve the block (seen directly or through a bounce)?
    let meta: &PixelBakeMeta = r.meta();
    let block_idx = scene.material_index("block").expect("block") as u32;
    let block_slot = layout.materials[block_idx as usize].slot_offset;
    let file = prt_formats::BakeFile::open(&path).expect("file");
    let mut involved = vec![false; before.len()];
    for (g, gm) in meta.groups.iter().enumerate() {
        let pix = file
            .tensor(&format!("g{g}.pixels"))
            .expect("pixels")
            .as_u32()
            .expect("u32")
            .to_vec();
        let t = file
            .tensor(&format!("g{g}.t"))
            .expect("t")
            .as_f32()
            .expect("f32")
            .to_vec();
        let len = gm.row_len as usize;
        let jn = gm.active.len();
        let Some(ja) = gm.active.iter().position(|&j| j == block_slot) else {
            if gm.material == block_idx {
                pix.iter().for_each(|&p| involved[p as usize] = true);
            }
            continue;
        };
        // Stored element-major: value e of pixel k at e * pixels + k.
        let np = pix.len();
        assert_eq!(t.len(), len * np);
        for (k, &p) in pix.iter().enumerate() {
            let uses = (0..gm.slots as usize).any(|b0| {
                t[prt_formats::pixel::element_index(gm.slots as usize, jn, 1, b0, &[ja], 0) * np
                    + k]
                    != 0.0
            });
            if uses || gm.material == block_idx {
                involved[p as usize] = true;
            }
        }
    }
    let (mut changed, mut same) = (0, 0);
    assert_same_size(&before, &after);
    for (i, (a, b)) in before.iter().zip(&after).enumerate() {
        if involved[i] {
            changed += usize::from(a != b);
        } else {
            assert_eq!(a, b, "pixel {i} receives no light via 'block' but changed");
            same += 1;
        }
    }
    let n_involved = involved.iter().filter(|&&x| x).count();
    // Every involved pixel changes unless its block terms happen to cancel exactly.
    assert!(
        changed * 10 >= n_involved * 9 && changed > 50,
        "{changed} of {n_involved} involved pixels changed"
    );
    assert!(
        same > 50,
        "only {same} pixels are free of the block's light: the partition should hide it"
    );
    let _ = std::fs::remove_file(&path);
}

/// Hard settings stay finite: shininess at and beyond the top of the range, coefficients far
/// outside the sampled range, large Ks (negative basis lobes weigh in), and a tiny sun-like
/// light whose transfer exceeds f16's range (stored with a per-group scale).
#[test]
fn hard_settings_give_finite_images() {
    let scene = test_scene(Vec3::new(1.0, 0.9, 0.8), Vec3::ZERO);
    let mut sun = scene.clone();
    // Make the lamp tiny and 1e6 times brighter: radiance far past f16's 65504.
    for m in &mut sun.materials {
        if m.name == "lamp" {
            m.emission *= 1.0e6;
        }
    }
    let bases = bases_for(&scene, 6);
    for (name, sc) in [("normal", &scene), ("sun", &sun)] {
        let (_, p16) = bake_to_file(
            sc,
            &bases,
            &small_options(24, 16, 4, 2, Precision::F16),
            &format!("hard16-{name}.prtbake"),
        );
        let (_, p32) = bake_to_file(
            sc,
            &bases,
            &small_options(24, 16, 4, 2, Precision::F32),
            &format!("hard32-{name}.prtbake"),
        );
        // (edits, bound on the f16-vs-f32 relative L2 error; None = only finiteness). f16 keeps
        // ~2^-11 relative precision per stored value, but sharp lobes are sums of large basis
        // terms of both signs, so the relit value's error is that times the cancellation
        // factor: small for in-range settings, large for absurd ones (measured in docs/pixel.md).
        let cases: [(&[&str], Option<f64>); 3] = [
            (&["shiny.shininess=200", "metal.alpha=0.02"], Some(1.5e-2)),
            (
                &[
                    "shiny.shininess=100000",
                    "metal.alpha=0.0001",
                    "shiny.ks=50",
                ],
                None,
            ),
            (
                &[
                    "shiny.shininess=0",
                    "metal.alpha=1",
                    "metal.ks=0,0,0",
                    "block.kd=0,0,0",
                ],
                Some(5e-4),
            ),
        ];
        for (edits, bound) in cases {
            let mut a = PixelRelighter::open(&p16).expect("open f16");
            let mut b = PixelRelighter::open(&p32).expect("open f32");
            set(&mut a, edits);
            set(&mut b, edits);
            let fa = a.render().expect("render f16").pixels;
            let fb = b.render().expect("render f32").pixels;
            assert!(
                fa.iter().flatten().all(|v| v.is_finite()),
                "{name} {edits:?}: non-finite f16 relight"
            );
            assert!(
                fb.iter().flatten().all(|v| v.is_finite()),
                "{name} {edits:?}: non-finite f32 relight"
            );
            let err = relative_l2(&fa, &fb);
            eprintln!("{name} {edits:?}: f16 vs f32 relative L2 {err:.2e}");
            if let Some(bound) = bound {
                assert!(
                    err < bound,
                    "{name} {edits:?}: f16 vs f32 relative L2 {err}"
                );
            }
        }
        let _ = std::fs::remove_file(&p16);
        let _ = std::fs::remove_file(&p32);
    }
}

/// Bad input to the runtime gets clear errors naming the problem.
#[test]
fn relight_rejects_bad_input_with_clear_errors() {
    let scene = test_scene(Vec3::ONE, Vec3::ZERO);
    let bases = bases_for(&scene, 3);
    let (_, path) = bake_to_file(
        &scene,
        &bases,
        &small_options(12, 8, 2, 2, Precision::F16),
        "bad.prtbake",
    );
    let mut r = PixelRelighter::open(&path).expect("open");
    let err = |e: RuntimeError| e.to_string();
    let e = err(prt_tests::edit_pixel(&mut r, "nosuch.kd=1").expect_err("unknown material"));
    assert!(
        e.contains("unknown material 'nosuch'") && e.contains("shiny"),
        "{e}"
    );
    let e = err(prt_tests::edit_pixel(&mut r, "floor.kd=1").expect_err("not editable"));
    assert!(e.contains("not editable") && e.contains("floor"), "{e}");
    let e = err(prt_tests::edit_pixel(&mut r, "shiny.alpha=0.3").expect_err("wrong param"));
    assert!(e.contains("blinn-phong") && e.contains("alpha"), "{e}");
    let e = err(prt_tests::edit_pixel(&mut r, "block.ks=0.3").expect_err("diffuse has no ks"));
    assert!(e.contains("ks"), "{e}");
    assert!(parse_override("shiny.kd=abc").is_err());
    assert!(parse_override("shiny.shininess=-1").is_err());
    assert!(matches!(
        r.set_variant(Variant::Compressed),
        Err(RuntimeError::NoCompressed)
    ));

    let bytes = std::fs::read(&path).expect("read");
    // Truncated at several places.
    for cut in [0, 7, 100, bytes.len() / 2, bytes.len() - 1] {
        let p = temp_path(&format!("cut{cut}.prtbake"));
        std::fs::write(&p, &bytes[..cut]).expect("write");
        let e = PixelRelighter::open(&p)
            .err()
            .map(|e| e.to_string())
            .expect("truncated file must fail");
        assert!(
            e.contains(&p.display().to_string()),
            "error does not name the file: {e}"
        );
        let _ = std::fs::remove_file(&p);
    }
    // A flipped byte in the tensor data fails the checksum.
    let mut bad = bytes.clone();
    let n = bad.len();
    bad[n - 5] ^= 0x40;
    let p = temp_path("flipped.prtbake");
    std::fs::write(&p, &bad).expect("write");
    let e = PixelRelighter::open(&p)
        .err()
        .map(|e| e.to_string())
        .expect("corrupt file must fail");
    assert!(
        e.to_lowercase().contains("checksum") || e.contains("crc"),
        "{e}"
    );
    let _ = std::fs::remove_file(&p);
    // A valid container that is not a per-pixel bake.
    let mut w = prt_formats::BakeWriter::new();
    w.set_metadata(serde_json::json!({"something": "else"}));
    let p = temp_path("foreign.prtbake");
    w.write_atomic(&p).expect("write");
    let e = PixelRelighter::open(&p)
        .err()
        .map(|e| e.to_string())
        .expect("foreign file must fail");
    assert!(e.contains("per-pixel"), "{e}");
    let _ = std::fs::remove_file(&p);
    let _ = std::fs::remove_file(&path);
}
