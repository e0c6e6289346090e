//! Material edits: what they change in the frame, and the edits refused with the names a
//! user needs.

use prt_formats::parse_override;
use prt_formats::pixel::{MaterialParams, Precision};
use prt_runtime::{OverrideValue, Param, ParamRange, PixelRelighter, RuntimeError, Variant};

use crate::relight::frame;
use crate::synthetic::Synthetic;

fn open(s: &Synthetic) -> (tempfile::TempDir, PixelRelighter) {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("synthetic.prtbake");
    s.write(&path, Precision::F32);
    (dir, PixelRelighter::open(&path).expect("open"))
}

/// A `--set` edit, as `relight` makes it.
fn set(r: &mut PixelRelighter, edit: &str) -> Result<(), RuntimeError> {
    let o = parse_override(edit).expect("valid --set syntax");
    r.set_params(&o.material, &[o.value])
}

#[test]
fn edits_change_the_frame_as_the_plain_sum_says() {
    let s = Synthetic::new(3, None, 21);
    let (_dir, mut r) = open(&s);
    set(&mut r, "paint.kd=0.9,0.1,0.05").expect("kd");
    set(&mut r, "metal.alpha=0.55").expect("alpha");
    set(&mut r, "metal.ks=0.2,0.6,0.1").expect("ks");
    set(&mut r, "metal.kd=0.05,0.1,0.2").expect("kd");
    let mut p = s.params();
    p[1].kd = [0.9, 0.1, 0.05];
    p[2] = MaterialParams {
        kd: [0.05, 0.1, 0.2],
        ks: [0.2, 0.6, 0.1],
        param: 0.55,
    };
    for (i, name) in ["wall", "paint", "metal"].iter().enumerate() {
        assert_eq!(r.params(name).expect("params"), p[i], "{name}");
    }
    let (coeff, clamped) = r.coefficients();
    assert!(!clamped);
    let want = s.coefficients(&p);
    assert_eq!(coeff.len(), want.len());
    for (a, b) in coeff.iter().zip(&want) {
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() < 1e-6, "{coeff:?} vs {want:?}");
        }
    }
    let (f, _) = frame(&mut r, Variant::Full);
    let expect = s.relight(&p, false, None);
    let scale = expect
        .iter()
        .flat_map(|x| x.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    for (a, b) in f.pixels.iter().zip(&expect) {
        for c in 0..3 {
            assert!(
                ((a[c] as f64) - b[c]).abs() < 2e-6 * scale,
                "{a:?} vs {b:?}"
            );
        }
    }
    // An edit changes the frame (the test above is not satisfied by a frozen image).
    let before = f.pixels;
    set(&mut r, "paint.kd=0.1,0.1,0.1").expect("kd");
    assert!(frame(&mut r, Variant::Full).0.pixels != before);
}

#[test]
fn a_parameter_outside_the_basis_range_is_clamped_and_reported() {
    let s = Synthetic::new(1, None, 2);
    let (_dir, mut r) = open(&s);
    set(&mut r, "metal.alpha=0.8").expect("alpha at the range's end");
    let (at_end, clamped) = r.coefficients();
    assert!(!clamped, "the range's end is inside it");
    set(&mut r, "metal.alpha=0.95").expect("alpha past the range");
    let (past, clamped) = r.coefficients();
    assert!(clamped, "0.95 lies outside the basis' [0.05, 0.8]");
    assert_eq!(at_end, past, "clamped to the range's end");
    // What a caller is shown: the sampled range, and that the value lies outside it.
    let metal = r
        .materials()
        .into_iter()
        .find(|m| m.name == "metal")
        .expect("metal");
    let alpha = metal
        .params
        .iter()
        .find(|p| p.param() == Param::Alpha)
        .expect("alpha");
    assert_eq!(alpha.value, OverrideValue::Alpha(0.95));
    assert_eq!(
        alpha.sampled,
        Some(ParamRange {
            min: 0.05,
            max: 0.8
        })
    );
    assert!(alpha.clamped());
    set(&mut r, "metal.alpha=0.8").expect("alpha at the range's end");
    let at_end_shown = r.materials().into_iter().find(|m| m.name == "metal");
    assert!(at_end_shown
        .expect("metal")
        .params
        .iter()
        .all(|p| !p.clamped()));
}

#[test]
fn edits_the_bake_cannot_honour_are_refused_with_names() {
    let s = Synthetic::new(1, None, 4);
    let (_dir, mut r) = open(&s);
    match set(&mut r, "chair.kd=0.5") {
        Err(RuntimeError::UnknownMaterial { name, available }) => {
            assert_eq!(name, "chair");
            assert_eq!(available, "wall, paint, metal");
        }
        other => panic!("unknown material: {other:?}"),
    }
    match r.params("chair") {
        Err(RuntimeError::UnknownMaterial { .. }) => {}
        other => panic!("params of an unknown material: {other:?}"),
    }
    match set(&mut r, "wall.kd=0.5") {
        Err(RuntimeError::NotEditable { name, editable }) => {
            assert_eq!(name, "wall");
            assert_eq!(editable, "paint, metal");
        }
        other => panic!("fixed material: {other:?}"),
    }
    for (edit, param) in [
        ("paint.alpha=0.3", "alpha"),
        ("metal.shininess=20", "shininess"),
    ] {
        match set(&mut r, edit) {
            Err(RuntimeError::WrongParam {
                name,
                family,
                param: p,
                ..
            }) => {
                assert_eq!(p, param, "{edit}");
                assert!(["paint", "metal"].contains(&name.as_str()));
                assert!(["diffuse", "ggx"].contains(&family.as_str()), "{family}");
            }
            other => panic!("{edit}: {other:?}"),
        }
    }
    // Refused edits change nothing.
    assert_eq!(r.params("paint").expect("params"), s.params()[1]);
    assert_eq!(r.params("metal").expect("params"), s.params()[2]);
    assert!(matches!(
        r.set_variant(Variant::Compressed),
        Err(RuntimeError::NoCompressed)
    ));
    assert!(!r.has_compressed());
}

#[test]
fn materials_list_every_parameter_with_its_value_and_range() {
    let s = Synthetic::new(1, None, 6);
    let (_dir, r) = open(&s);
    let materials = r.materials();
    let names: Vec<&str> = materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["wall", "paint", "metal"]);
    for (m, baked) in materials.iter().zip(s.params()) {
        let params: Vec<Param> = m.params.iter().map(|p| p.param()).collect();
        let want: Vec<Param> = match m.family {
            prt_runtime::Family::Diffuse => vec![Param::Kd],
            prt_runtime::Family::Ggx => vec![Param::Kd, Param::Ks, Param::Alpha],
            prt_runtime::Family::BlinnPhong => vec![Param::Kd, Param::Ks, Param::Shininess],
        };
        assert_eq!(params, want, "{}", m.name);
        for p in &m.params {
            match p.value {
                OverrideValue::Kd(c) => assert_eq!(c, baked.kd),
                OverrideValue::Ks(c) => assert_eq!(c, baked.ks),
                OverrideValue::Alpha(v) => {
                    assert_eq!(v, baked.param);
                    assert_eq!(
                        p.range,
                        ParamRange {
                            min: 1e-4,
                            max: 1.0
                        }
                    );
                }
                other => panic!("{}: {other:?}", m.name),
            }
            if matches!(p.value, OverrideValue::Kd(_) | OverrideValue::Ks(_)) {
                assert_eq!(p.range, ParamRange::COLOUR);
                assert_eq!(p.sampled, None);
            }
        }
    }
    assert_eq!(
        materials.iter().map(|m| m.editable).collect::<Vec<_>>(),
        [false, true, true]
    );
}

#[test]
fn set_params_refuses_a_value_outside_its_range_naming_it_and_changes_nothing() {
    let s = Synthetic::new(1, None, 8);
    let (_dir, mut r) = open(&s);
    let cases = [
        (
            "metal",
            OverrideValue::Alpha(1.5),
            Param::Alpha,
            "1.5",
            "[0.0001, 1]",
        ),
        (
            "metal",
            OverrideValue::Alpha(0.0),
            Param::Alpha,
            "0",
            "[0.0001, 1]",
        ),
        (
            "metal",
            OverrideValue::Alpha(f32::NAN),
            Param::Alpha,
            "NaN",
            "[0.0001, 1]",
        ),
        (
            "paint",
            OverrideValue::Kd([0.5, -0.1, 0.2]),
            Param::Kd,
            "[0.5, -0.1, 0.2]",
            "[0, inf]",
        ),
        (
            "metal",
            OverrideValue::Ks([f32::INFINITY, 0.0, 0.0]),
            Param::Ks,
            "[inf, 0.0, 0.0]",
            "[0, inf]",
        ),
    ];
    for (material, value, param, shown, range) in cases {
        // The bad value comes after a good one: nothing of the call is applied.
        let values = [OverrideValue::Kd([0.3, 0.3, 0.3]), value];
        let e = r.set_params(material, &values).expect_err("out of range");
        match &e {
            RuntimeError::OutOfRange {
                name,
                param: p,
                value: v,
                ..
            } => assert_eq!((name.as_str(), *p, v.as_str()), (material, param, shown)),
            other => panic!("{value:?}: {other:?}"),
        }
        let message = e.to_string();
        for part in [material, param.name(), shown, range] {
            assert!(message.contains(part), "'{message}' does not name {part}");
        }
    }
    assert_eq!(r.params("paint").expect("params"), s.params()[1]);
    assert_eq!(r.params("metal").expect("params"), s.params()[2]);
    // The range's ends are inside it.
    r.set_params(
        "metal",
        &[OverrideValue::Alpha(1e-4), OverrideValue::Ks([0.0; 3])],
    )
    .expect("ends of the ranges");
    r.set_params("metal", &[OverrideValue::Alpha(1.0)])
        .expect("alpha 1");
}

#[test]
fn set_params_errors_name_the_material_and_the_parameter() {
    let s = Synthetic::new(1, None, 9);
    let (_dir, mut r) = open(&s);
    let mut message = |material: &str, value: OverrideValue| {
        r.set_params(material, &[value])
            .expect_err("refused")
            .to_string()
    };
    let unknown = message("chair", OverrideValue::Kd([0.5; 3]));
    assert!(
        unknown.contains("'chair'") && unknown.contains("wall, paint, metal"),
        "{unknown}"
    );
    let lacking = message("paint", OverrideValue::Shininess(20.0));
    for part in ["'paint'", "diffuse", "'shininess'", "kd"] {
        assert!(lacking.contains(part), "'{lacking}' does not name {part}");
    }
    let fixed = message("wall", OverrideValue::Kd([0.5; 3]));
    assert!(
        fixed.contains("'wall'") && fixed.contains("paint, metal"),
        "{fixed}"
    );
}
