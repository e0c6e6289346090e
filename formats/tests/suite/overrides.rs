//! `--set MATERIAL.PARAM=VALUE` parsing: accepted forms and precise rejections.

use prt_formats::overrides::{
    check_material, parse_override, MaterialOverride, OverrideError, OverrideValue, Param,
};

fn ok(s: &str) -> MaterialOverride {
    parse_override(s).unwrap_or_else(|e| panic!("{s}: {e}"))
}

fn err(s: &str) -> String {
    let e = parse_override(s).expect_err(s).to_string();
    assert!(
        e.contains(&format!("'{s}'")),
        "error does not quote the input: {e}"
    );
    e
}

#[test]
fn accepts_documented_forms() {
    assert_eq!(
        ok("bunny.kd=0.8,0.2,0.2"),
        MaterialOverride {
            material: "bunny".into(),
            value: OverrideValue::Kd([0.8, 0.2, 0.2])
        }
    );
    assert_eq!(ok("bunny.ks=0.5").value, OverrideValue::Ks([0.5; 3]));
    assert_eq!(ok("bunny.kd=1").value, OverrideValue::Kd([1.0; 3]));
    assert_eq!(
        ok("bunny.shininess=50").value,
        OverrideValue::Shininess(50.0)
    );
    assert_eq!(ok("wall.alpha=0.3").value, OverrideValue::Alpha(0.3));
    // Material names may contain dots: split at the last dot before '='.
    let o = ok("car.body.paint.ks=0.1,0.2,0.3");
    assert_eq!(o.material, "car.body.paint");
    assert_eq!(o.value, OverrideValue::Ks([0.1, 0.2, 0.3]));
    // Spaces around components and case-insensitive parameter names are tolerated.
    assert_eq!(
        ok("b.Kd= 0.1 , 0.2,0.3 ").value,
        OverrideValue::Kd([0.1, 0.2, 0.3])
    );
    assert_eq!(ok("b.kd=1e-1").value, OverrideValue::Kd([0.1; 3]));
    // Boundaries are inclusive.
    assert_eq!(ok("b.shininess=0").value, OverrideValue::Shininess(0.0));
    assert_eq!(ok("b.shininess=1e6").value, OverrideValue::Shininess(1e6));
    assert_eq!(ok("b.alpha=1e-4").value, OverrideValue::Alpha(1e-4));
    assert_eq!(ok("b.alpha=1").value, OverrideValue::Alpha(1.0));
    // FromStr and Display agree.
    let o: MaterialOverride = "x.y.alpha=0.25".parse().unwrap();
    assert_eq!(o.to_string(), "x.y.alpha=0.25");
    assert_eq!(o.value.param(), Param::Alpha);
}

#[test]
fn rejects_with_precise_messages() {
    assert!(err("bunny.kd").contains("missing '='"));
    assert!(err("bunnykd=1").contains("missing '.'"));
    assert!(err(".kd=1").contains("empty material"));
    let e = err("bunny.color=1");
    assert!(e.contains("unknown parameter 'color'"), "{e}");
    for p in Param::ALL {
        assert!(e.contains(p.name()), "valid list misses {p}: {e}");
    }
    assert!(err("bunny.=1").contains("unknown parameter ''"));
    let e = err("bunny.kd=0.1,0.2");
    assert!(
        e.contains("kd needs 1 number (gray) or 3") && e.contains("got 2"),
        "{e}"
    );
    assert!(err("bunny.kd=0.1,0.2,0.3,0.4").contains("got 4"));
    assert!(err("bunny.shininess=1,2").contains("exactly 1 number"));
    assert!(err("bunny.kd=red").contains("'red' is not a number"));
    assert!(err("bunny.kd=").contains("'' is not a number"));
    assert!(err("bunny.kd=0.1,,0.3").contains("'' is not a number"));
    let e = err("bunny.kd=0.1,nan,0.3");
    assert!(e.contains("finite") && e.contains("NaN"), "{e}");
    assert!(err("bunny.ks=inf").contains("finite"));
    assert!(err("bunny.ks=1e39").contains("finite"));
    let e = err("bunny.kd=0.5,-0.1,0.5");
    assert!(
        e.contains("must not be negative") && e.contains("-0.1"),
        "{e}"
    );
    let e = err("bunny.shininess=2e6");
    assert!(e.contains("shininess must be in [0, 1000000]"), "{e}");
    let e = err("wall.alpha=0");
    assert!(e.contains("alpha must be in [0.0001, 1]"), "{e}");
    assert!(err("wall.alpha=1.5").contains("alpha must be in"));
    assert!(err("wall.alpha=-1").contains("negative"));
}

#[test]
fn check_material_lists_the_scene() {
    let scene = ["bunny", "wall.left", "floor"];
    assert!(check_material("wall.left", &scene).is_ok());
    let e = check_material("Bunny", &scene).unwrap_err();
    assert_eq!(
        e.to_string(),
        "unknown material 'Bunny'; the scene has: bunny, wall.left, floor"
    );
    assert!(matches!(e, OverrideError::UnknownMaterial { .. }));
    assert!(check_material("x", &[])
        .unwrap_err()
        .to_string()
        .contains("no materials"));
}
