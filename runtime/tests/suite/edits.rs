//! Material edits: what they change in the frame, and the edits refused with the names a
//! user needs.

use prt_formats::parse_override;
use prt_formats::pixel::{MaterialParams, Precision};
use prt_runtime::{Relighter, RuntimeError, Variant};

use crate::synthetic::Synthetic;

fn open(s: &Synthetic) -> (tempfile::TempDir, Relighter) {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("synthetic.prtbake");
    s.write(&path, Precision::F32);
    (dir, Relighter::open(&path).expect("open"))
}

fn set(r: &mut Relighter, edit: &str) -> Result<(), RuntimeError> {
    r.apply(&parse_override(edit).expect("valid --set syntax"))
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
    let f = r.render(Variant::Full).expect("render");
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
    assert!(r.render(Variant::Full).expect("render").pixels != before);
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
        r.render(Variant::Compressed),
        Err(RuntimeError::NoCompressed)
    ));
    assert!(!r.has_compressed());
}
