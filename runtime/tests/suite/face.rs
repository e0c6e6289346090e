//! The face both kinds share (`prt_runtime::open`, `Relighter`), on a per-pixel bake: the
//! kind is read from the file, a file that is not a bake is refused naming what it is, and a
//! render into a caller's buffer is the owned render's bits or refused. The per-vertex side is
//! in the `vertex` test binary (`face.rs`).

use prt_formats::pixel::Precision;
use prt_formats::BakeWriter;
use prt_runtime::{BakeKind, FormatError, Relighter, RuntimeError};

use crate::synthetic::{Synthetic, H, W};

#[test]
fn open_reads_a_per_pixel_bake_as_one() {
    let s = Synthetic::new(3, Some(2), 41);
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("pixel.prtbake");
    s.write(&path, Precision::F16);
    let r = prt_runtime::open(&path).expect("open");
    assert_eq!(r.kind(), BakeKind::Pixel);
    assert!(matches!(r, Relighter::Pixel(_)));
    assert_eq!(r.size(), (W, H));
    let names: Vec<String> = r.materials().into_iter().map(|m| m.name).collect();
    assert_eq!(names, ["wall", "paint", "metal"]);
    // The face's own calls reach the kind's: the same parameters, the same frame.
    let mut via_kind = prt_runtime::PixelRelighter::open(&path).expect("open as per-pixel");
    assert_eq!(r.params("metal").ok(), via_kind.params("metal").ok());
    let mut r = r;
    let edit = [prt_runtime::OverrideValue::Alpha(0.4)];
    r.set_params("metal", &edit).expect("edit");
    via_kind.set_params("metal", &edit).expect("edit");
    assert_eq!(
        r.render().expect("render").pixels,
        via_kind.render().expect("render").pixels
    );
}

#[test]
fn a_buffer_rendered_through_the_face_is_the_owned_render_or_refused() {
    let s = Synthetic::new(1, None, 42);
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("pixel.prtbake");
    s.write(&path, Precision::F32);
    let mut r = prt_runtime::open(&path).expect("open");
    let owned = r.render().expect("render");
    assert_eq!((owned.width, owned.height), (W, H));
    let mut out = vec![f32::NAN; 3 * (W * H) as usize];
    let stats = r.render_into(&mut out).expect("render into");
    assert!(stats.bytes_read.is_some() && stats.light_s.is_none());
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&out), bits(owned.pixels.as_flattened()));
    let mut short = vec![0.0f32; 3 * (W * H) as usize - 3];
    match r.render_into(&mut short) {
        Err(e @ RuntimeError::BufferSize { .. }) => {
            let m = e.to_string();
            assert!(m.contains(&format!("{}", short.len())), "{m}");
            assert!(m.contains(&format!("{W}x{H}")), "{m}");
        }
        other => panic!("a short buffer: {other:?}"),
    }
}

#[test]
fn files_that_are_not_bakes_are_refused_naming_what_they_are() {
    let dir = tempfile::tempdir().expect("tempdir");
    let message = |path: &std::path::Path| match prt_runtime::open(path) {
        Ok(_) => panic!("{} opened as a bake", path.display()),
        Err(e) => (e.to_string(), e),
    };
    // No such file.
    let missing = dir.path().join("missing.prtbake");
    let (m, e) = message(&missing);
    assert!(
        matches!(e, RuntimeError::Format(FormatError::Open { .. })),
        "{e:?}"
    );
    assert!(m.contains("missing.prtbake"), "{m}");
    // A plain safetensors file: a container, but not ours.
    let header = br#"{"__metadata__":{"note":"plain"}}"#;
    let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
    bytes.extend_from_slice(header);
    let plain = dir.path().join("plain.safetensors");
    std::fs::write(&plain, bytes).expect("write");
    let (m, e) = message(&plain);
    assert!(
        matches!(e, RuntimeError::Format(FormatError::WrongFormat { .. })),
        "{e:?}"
    );
    assert!(
        m.contains("plain.safetensors") && m.contains("not a PRT bake file"),
        "{m}"
    );
    // A PRT container whose metadata names neither kind of bake.
    let mut w = BakeWriter::new();
    w.set_metadata(serde_json::json!({"note": "no kind"}));
    let kindless = dir.path().join("kindless.prtbake");
    w.write_atomic(&kindless).expect("write");
    let (m, e) = message(&kindless);
    assert!(matches!(e, RuntimeError::UnknownKind { .. }), "{e:?}");
    assert!(
        m.contains("kindless.prtbake") && m.contains("not a bake of a known kind"),
        "{m}"
    );
    // A text file (a glTF scene) is refused by the container's reader, naming the file.
    let text = dir.path().join("scene.gltf");
    std::fs::write(&text, r#"{"asset": {"version": "2.0"}, "scenes": []}"#).expect("write");
    let (m, e) = message(&text);
    assert!(matches!(e, RuntimeError::Format(_)), "{e:?}");
    assert!(m.contains("scene.gltf"), "{m}");
}
