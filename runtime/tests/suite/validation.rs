//! `prt_runtime::open` refuses a file that is a valid container but not a consistent per-pixel
//! bake, one corruption at a time, with a reason naming it; the uncorrupted file and the
//! boundary values (last pixel, last slot) open.

use prt_formats::pixel::Precision;
use prt_runtime::{PixelRelighter, RuntimeError};

use crate::synthetic::{Synthetic, H, W};

/// Writes `s` and opens it; returns the error's message (panics if it opens).
fn refused(s: &Synthetic, precision: Precision) -> (String, RuntimeError) {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bad.prtbake");
    s.write(&path, precision);
    match prt_runtime::open(&path) {
        Ok(_) => panic!("a corrupt bake opened"),
        Err(e) => (e.to_string(), e),
    }
}

fn good() -> Synthetic {
    Synthetic::new(1, Some(2), 17)
}

#[test]
fn the_uncorrupted_bake_and_its_boundary_values_open() {
    let s = good();
    // The boundary values are present: a group holds the last pixel, a group the last slot.
    assert!(s.groups.iter().any(|g| g.pixels.contains(&(W * H - 1))));
    assert!(s.groups.iter().any(|g| g.meta.active.contains(&4)));
    let dir = tempfile::tempdir().expect("tempdir");
    for precision in [Precision::F32, Precision::F16] {
        let path = dir.path().join("good.prtbake");
        s.write(&path, precision);
        let r = PixelRelighter::open(&path).expect("the uncorrupted bake opens");
        assert_eq!(r.meta().groups.len(), 3);
        assert_eq!(r.meta().precision, precision);
    }
}

#[test]
fn each_inconsistency_is_refused_with_its_reason() {
    type Corrupt = fn(&mut Synthetic);
    let cases: [(&str, Corrupt, &str); 11] = [
        (
            "newer schema",
            |s| s.meta.pixel_schema_version += 1,
            "per-pixel schema version",
        ),
        (
            "short coefficient table",
            |s| {
                s.meta.bases[0].basis.coefficients.pop();
            },
            "inconsistent coefficient table",
        ),
        (
            "no parameter samples",
            |s| {
                let b = &mut s.meta.bases[0].basis;
                b.param_samples.clear();
                b.coefficients.clear();
            },
            "inconsistent coefficient table",
        ),
        (
            "group of a missing material",
            |s| s.groups[1].meta.material = 3,
            "names material 3 which does not exist",
        ),
        (
            "material with a missing basis",
            |s| s.meta.materials[2].basis = Some(1),
            "names a missing basis",
        ),
        (
            "active slot past the last",
            |s| s.groups[2].meta.active[2] = 5,
            "beyond the 5 slots",
        ),
        (
            "row length off by one",
            |s| s.groups[0].meta.row_len += 1,
            "row length",
        ),
        (
            "pixel past the image",
            |s| {
                let last = s.groups[1].pixels.len() - 1;
                s.groups[1].pixels[last] = W * H;
            },
            "pixel index outside the image",
        ),
        (
            "f32 tensors said to be f16",
            |s| s.stated_precision = Some(Precision::F16),
            "transfer tensor is f32 but the metadata says f16",
        ),
        (
            "image size not the emission's",
            |s| s.meta.width += 1,
            "emission",
        ),
        (
            "fewer low-rank components than the rank",
            |s| {
                let g = &mut s.groups[0];
                g.meta.compressed_rank = Some(3);
            },
            "g0.",
        ),
    ];
    for (what, corrupt, reason) in cases {
        let mut s = good();
        corrupt(&mut s);
        let (msg, _) = refused(&s, Precision::F32);
        assert!(
            msg.to_lowercase().contains(&reason.to_lowercase()),
            "{what}: the error should say '{reason}', got: {msg}"
        );
    }
    // Pixel counts that disagree with the pixel tensor are refused by shape.
    let mut s = good();
    s.groups[2].meta.pixels += 1;
    let (msg, e) = refused(&s, Precision::F32);
    assert!(matches!(e, RuntimeError::Format(_)), "{msg}");
    // f16 tensors said to be f32 are refused too.
    let mut s = good();
    s.stated_precision = Some(Precision::F32);
    let (msg, _) = refused(&s, Precision::F16);
    assert!(
        msg.to_lowercase()
            .contains("transfer tensor is f16 but the metadata says f32"),
        "{msg}"
    );
}
