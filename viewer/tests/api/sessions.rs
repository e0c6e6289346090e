//! Requests sent while a frame renders are coalesced; tabs keep their own settings; save
//! gives the shown frame; the reference toggle streams converging passes.

use super::*;

#[test]
fn requests_arriving_while_a_frame_renders_are_coalesced() {
    let b = bakes();
    let mut tab = Tab::open(serve(&b.vertex, None));
    tab.frame_of(json!({"type": "size", "width": 128, "height": 128}));
    // A material edit re-runs the material stage: far slower than sending 30 messages.
    let first = tab.seq + 1;
    for k in 0..30 {
        tab.seq += 1;
        let request = json!({"type": "material", "name": "sphere", "param": "alpha",
            "value": 0.05 + 0.02 * k as f64, "seq": tab.seq});
        tab.send_raw(&request.to_string());
    }
    let mut frames = Vec::new();
    loop {
        let Reply::Frame(meta, _) = tab.reply() else {
            panic!("refused")
        };
        let seq = meta["seq"].as_u64().unwrap();
        frames.push(seq);
        if seq == tab.seq {
            let last = (0.05 + 0.02 * 29.0) as f32;
            assert_eq!(
                meta["settings"]["materials"]["sphere"]["alpha"],
                json!(last)
            );
            break;
        }
    }
    assert!(frames.iter().all(|&s| s >= first));
    assert!(
        frames.len() <= 4,
        "30 quick requests gave {} frames ({frames:?}): not coalesced",
        frames.len()
    );
}

#[test]
fn tabs_keep_their_own_settings() {
    let b = bakes();
    let address = serve(&b.vertex, None);
    let mut a = Tab::open(address);
    let mut c = Tab::open(address);
    let (meta_a, pixels_a) = a.frame_of(
        json!({"type": "material", "name": "bunny", "param": "kd", "value": [0.1, 0.9, 0.1]}),
    );
    let (meta_c, pixels_c) = c.frame_of(json!({"type": "rotation", "value": 45}));
    assert_eq!(
        meta_c["settings"]["materials"],
        c.hello["settings"]["materials"]
    );
    assert_eq!(pixels_c, expected_rgba(&b.vertex, &meta_c["settings"]));
    // Back to tab a: its own edit, and not c's rotation.
    let (meta_a2, pixels_a2) = a.frame_of(json!({"type": "exposure", "value": 1.0}));
    assert_eq!(meta_a2["settings"]["view"], meta_a["settings"]["view"]);
    assert_eq!(pixels_a2, pixels_a);
    assert_eq!(pixels_a2, expected_rgba(&b.vertex, &meta_a2["settings"]));
}

#[test]
fn save_gives_the_shown_frame_as_exr_and_png() {
    let b = bakes();
    let address = serve(&b.pixel, None);
    let mut tab = Tab::open(address);
    let (meta, pixels) = tab.frame_of(json!({"type": "exposure", "value": 3.0}));
    let id = tab.hello["session"].as_u64().unwrap();
    let (status, png) = http_get(address, &format!("/api/session/{id}/image.png"));
    assert_eq!(status, 200);
    let decoded = image::load_from_memory(&png).expect("a PNG").to_rgba8();
    assert_eq!(
        decoded.as_raw(),
        &pixels,
        "the PNG is not what the canvas shows"
    );
    let (status, exr) = http_get(address, &format!("/api/session/{id}/image.exr"));
    assert_eq!(status, 200);
    let path = std::env::temp_dir().join(format!("prt-viewer-save-{}.exr", std::process::id()));
    std::fs::write(&path, exr).expect("write");
    let (w, h, linear) = prt_formats::read_exr_rgb(&path).expect("an EXR");
    std::fs::remove_file(&path).ok();
    assert_eq!(
        (w as u64, h as u64),
        (
            meta["width"].as_u64().unwrap(),
            meta["height"].as_u64().unwrap()
        )
    );
    let mut r = prt_runtime::open(&b.pixel).expect("open");
    assert_eq!(
        linear,
        r.render().expect("render").pixels,
        "the EXR is not the linear frame"
    );
    for (path, code) in [
        (format!("/api/session/{id}/image.jpg"), 404),
        ("/api/session/999/image.png".to_string(), 404),
        ("/api/session/x/image.png".to_string(), 400),
        ("/nothing".to_string(), 404),
    ] {
        let (status, body) = http_get(address, &path);
        assert_eq!(status, code, "{path}");
        assert!(!body.is_empty(), "{path}: no message");
    }
}

#[test]
fn the_reference_toggle_streams_converging_passes() {
    let b = bakes();
    let mut tab = Tab::open(serve(&b.pixel, Some("scenes/cornell")));
    assert_eq!(tab.hello["info"]["reference"]["available"], json!(true));
    tab.seq += 1;
    tab.send_raw(&json!({"type": "reference", "on": true, "seq": tab.seq}).to_string());
    let mut seen = Vec::new();
    while seen.len() < 3 {
        let m = tab.text();
        if m["type"] == "reference" {
            let reference = tab.binary();
            let difference = tab.binary();
            assert_eq!(reference.len(), 4 * 32 * 32);
            assert_eq!(difference.len(), reference.len());
            assert!(
                reference
                    .chunks(4)
                    .filter(|p| p[0] > 10 || p[1] > 10)
                    .count()
                    > 200
            );
            let l2 = m["rel_l2"].as_f64().expect("compared with the relit frame");
            seen.push((m["spp"].as_u64().unwrap(), l2));
        } else if m["type"] == "frame" {
            tab.binary();
        } else {
            panic!("{m}");
        }
    }
    assert!(seen.windows(2).all(|w| w[1].0 > w[0].0), "{seen:?}");
    // A 1-spp bake against a reference of a few samples: the same image, noisy.
    assert!(seen.iter().all(|&(_, l2)| l2 > 0.0 && l2 < 2.0), "{seen:?}");
    // Off: the passes stop (a frame answers; no reference message follows it for a while).
    let _ = tab.request(json!({"type": "reference", "on": false}));
    let _ = tab.request(json!({"type": "exposure", "value": 1.5}));
}
