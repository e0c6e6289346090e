//! Bad requests are refused with a message naming the problem and change nothing; random
//! requests (a fuzz loop) never take the server down.

use super::*;

/// Sends `bad`, expects a refusal whose message contains each of `words`, and that the
/// settings did not change.
fn refused(tab: &mut Tab, bad: &str, words: &[&str]) {
    let before = tab.settings();
    tab.send_raw(bad);
    let Reply::Error(e) = tab.reply() else {
        panic!("{bad} was not refused");
    };
    let message = e["message"].as_str().expect("a message");
    for w in words {
        assert!(
            message.contains(w),
            "{bad}: message {message:?} lacks {w:?}"
        );
    }
    assert_eq!(e["settings"], before, "{bad}: settings changed");
}

#[test]
fn bad_requests_are_refused_with_a_message_and_change_nothing() {
    let b = bakes();
    let mut tab = Tab::open(serve(&b.vertex, None));
    let cases: &[(&str, &[&str])] = &[
        ("not json", &["not a JSON message"]),
        ("[1, 2]", &["JSON object"]),
        (r#"{"value": 1}"#, &["missing field 'type'"]),
        (
            r#"{"type": "teleport"}"#,
            &["unknown request type 'teleport'"],
        ),
        (
            r#"{"type": "exposure", "value": 1, "colour": 2}"#,
            &["unknown field 'colour'"],
        ),
        (
            r#"{"type": "exposure", "value": "bright"}"#,
            &["must be a number"],
        ),
        (
            r#"{"type": "exposure", "value": -1}"#,
            &["exposure -1 is outside"],
        ),
        (
            r#"{"type": "exposure", "value": 1e300}"#,
            &["not a finite 32-bit number"],
        ),
        (
            r#"{"type": "tone", "value": "filmic"}"#,
            &["unknown tone curve 'filmic'"],
        ),
        (
            r#"{"type": "material", "name": "teapot", "param": "kd", "value": [1, 1, 1]}"#,
            &["unknown material 'teapot'", "sphere"],
        ),
        (
            r#"{"type": "material", "name": "floor", "param": "kd", "value": [1, 1, 1]}"#,
            &["'floor' is not editable", "sphere, bunny"],
        ),
        (
            r#"{"type": "material", "name": "bunny", "param": "alpha", "value": 0.3}"#,
            &["'bunny' is diffuse", "no parameter 'alpha'"],
        ),
        (
            r#"{"type": "material", "name": "sphere", "param": "shininess", "value": 30}"#,
            &["'sphere' is ggx", "kd, ks, alpha"],
        ),
        (
            r#"{"type": "material", "name": "sphere", "param": "alpha", "value": 1.5}"#,
            &["alpha = 1.5 is outside its valid range"],
        ),
        (
            r#"{"type": "material", "name": "sphere", "param": "kd", "value": [1, -0.5, 1]}"#,
            &["kd = [1.0, -0.5, 1.0] is outside"],
        ),
        (
            r#"{"type": "material", "name": "sphere", "param": "kd", "value": [1, 1]}"#,
            &["three finite numbers"],
        ),
        (
            r#"{"type": "environment", "name": "../secret.exr"}"#,
            &["unknown environment '../secret.exr'", "studio.exr"],
        ),
        (
            r#"{"type": "rotation", "value": 1000}"#,
            &["rotation 1000 is outside"],
        ),
        (
            r#"{"type": "intensity", "value": -2}"#,
            &["intensity -2 is outside"],
        ),
        (
            r#"{"type": "camera", "eye": [0, 1, 0], "target": [0, 0, 0], "fov": 40}"#,
            &["vertical"],
        ),
        (
            r#"{"type": "camera", "eye": [0, 1, 3], "target": [0, 1, 3], "fov": 40}"#,
            &["eye and target must differ"],
        ),
        (
            r#"{"type": "camera", "eye": [0, 1, 3], "target": [0, 0, 0], "fov": 180}"#,
            &["fov 180 must be in (0, 180)"],
        ),
        (
            r#"{"type": "size", "width": 0, "height": 64}"#,
            &["width must be a whole number of pixels in 1..=4096"],
        ),
        (
            r#"{"type": "size", "width": 64, "height": 100000}"#,
            &["height must be", "100000"],
        ),
        (
            r#"{"type": "size", "width": 64.5, "height": 64}"#,
            &["width must be"],
        ),
        (r#"{"type": "reference", "on": true}"#, &["--config"]),
        (
            r#"{"type": "reference", "on": "yes"}"#,
            &["'on' must be true or false"],
        ),
        (
            r#"{"type": "encoding", "value": "jpeg"}"#,
            &["unknown encoding 'jpeg'"],
        ),
    ];
    for (bad, words) in cases {
        refused(&mut tab, bad, words);
        // Still serving.
        tab.frame_of(json!({"type": "exposure", "value": 1.25}));
    }
    // Refused when the frame renders: the eye inside the sphere (the runtime's rule); the
    // settings go back to the last rendered ones.
    let before = tab.settings();
    let Reply::Error(e) = tab.request(
        json!({"type": "camera", "eye": [-0.17, 0.119, 0.0], "target": [0.3, 0.1, 0.2], "fov": 40}),
    ) else {
        panic!("an eye inside the sphere was rendered");
    };
    assert!(e["message"].as_str().unwrap().contains("is inside"), "{e}");
    assert_eq!(e["settings"], before);
    let (meta, _) = tab.frame_of(json!({"type": "rotation", "value": 10}));
    assert_eq!(meta["settings"]["view"]["camera"], before["view"]["camera"]);
    // A per-pixel bake has no view.
    let mut pixel = Tab::open(serve(&b.pixel, None));
    refused(
        &mut pixel,
        r#"{"type": "rotation", "value": 10}"#,
        &["per-pixel bake", "frozen"],
    );
    refused(
        &mut pixel,
        r#"{"type": "size", "width": 64, "height": 64}"#,
        &["per-pixel bake"],
    );
}

/// A small generator of random requests (no randomness crate: a fixed 64-bit LCG, so a
/// failure repeats).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 >> 33
    }

    fn pick<'a, T>(&mut self, xs: &'a [T]) -> &'a T {
        &xs[self.next() as usize % xs.len()]
    }

    fn value(&mut self, depth: u32) -> Value {
        match self.next() % 10 {
            0 => json!(null),
            1 => json!(self.next().is_multiple_of(2)),
            2 => json!(*self.pick(&[0.0, -1.0, 1e39, -1e-45, 0.5, 3.0, 1e6, 4096.0, 16.0, 65.0])),
            3 => json!(self.next() as i64 - (1 << 30)),
            4 => json!(*self.pick(&[
                "",
                "kd",
                "baked",
                "studio.exr",
                "aces",
                "NaN",
                "inf",
                "sphere",
                "\u{0}"
            ])),
            5 if depth < 2 => Value::Array(
                (0..self.next() % 5)
                    .map(|_| self.value(depth + 1))
                    .collect(),
            ),
            6 => json!([0.2, 0.3, 0.4]),
            7 => json!(*self.pick(&[0.3, 90.0, 40.0, 128.0, 2.0])),
            8 if depth < 2 => json!({"x": self.value(depth + 1)}),
            _ => json!(self.next() % 300),
        }
    }
}

#[test]
fn random_requests_never_take_the_server_down() {
    let b = bakes();
    let address = serve(&b.vertex, None);
    let mut tab = Tab::open(address);
    let mut rng = Lcg(0x5eed);
    let types = [
        "material",
        "exposure",
        "tone",
        "environment",
        "rotation",
        "intensity",
        "camera",
        "size",
        "reference",
        "encoding",
        "bogus",
    ];
    let keys = [
        "name", "param", "value", "eye", "target", "fov", "width", "height", "on", "seq", "extra",
    ];
    let (mut frames, mut errors) = (0, 0);
    for i in 0..400u64 {
        let text = match rng.next() % 8 {
            0 => {
                // Bytes that may not even be JSON.
                let n = rng.next() % 40;
                (0..n)
                    .map(|_| *rng.pick(&['{', '}', '"', ':', ',', '[', 'a', '1', ' ', 'é']))
                    .collect()
            }
            1..=4 => {
                // A well-formed request with a value that may or may not be valid, sometimes
                // with a field dropped or one added.
                let pick_value = |rng: &mut Lcg| rng.value(0);
                let mut obj = match rng.next() % 9 {
                    0 => json!({"type": "material",
                        "name": rng.pick(&["sphere", "bunny", "floor", "nope"]),
                        "param": rng.pick(&["kd", "ks", "alpha", "shininess"]),
                        "value": rng.pick(&[json!([0.2, 0.5, 0.9]), json!(0.3), json!(2.0), json!([1, -1, 0])]).clone()}),
                    1 => {
                        json!({"type": "exposure", "value": rng.pick(&[0.5, 2.0, -1.0, 1e7, 0.0])})
                    }
                    2 => {
                        json!({"type": "tone", "value": rng.pick(&["clamp", "aces", "reinhard", "gamma"])})
                    }
                    3 => {
                        json!({"type": "environment", "name": rng.pick(&["baked", "sky.exr", "sunset.exr", "x.exr"])})
                    }
                    4 => {
                        json!({"type": "rotation", "value": rng.pick(&[30.0, -200.0, 359.0, 720.0])})
                    }
                    5 => json!({"type": "intensity", "value": rng.pick(&[0.5, 3.0, -1.0])}),
                    6 => {
                        json!({"type": "camera", "eye": rng.pick(&[[0.4, 0.3, 0.8], [0.0, 1.0, 0.0], [-0.17, 0.119, 0.0]]),
                        "target": [0.0, 0.1, 0.0], "fov": rng.pick(&[40.0, 0.0, 90.0])})
                    }
                    7 => {
                        let sides = [
                            json!(16),
                            json!(48),
                            json!(0),
                            json!(99999),
                            json!(16.5),
                            json!("32"),
                            json!(-4),
                        ];
                        json!({"type": "size", "width": rng.pick(&sides), "height": rng.pick(&sides)})
                    }
                    _ => {
                        json!({"type": rng.pick(&["reference", "encoding"]), "on": false, "value": "png"})
                    }
                };
                match rng.next() % 6 {
                    0 => {
                        let k = rng.pick(&keys).to_string();
                        obj[k] = pick_value(&mut rng);
                    }
                    1 => {
                        let k = *rng.pick(&keys);
                        obj.as_object_mut().map(|o| o.remove(k));
                    }
                    _ => {}
                }
                obj["seq"] = json!(1000 + i);
                obj.to_string()
            }
            _ => {
                let mut obj = serde_json::Map::new();
                obj.insert("type".into(), json!(rng.pick(&types)));
                for _ in 0..rng.next() % 5 {
                    let k = rng.pick(&keys).to_string();
                    let v = rng.value(0);
                    obj.insert(k, v);
                }
                // Sizes stay small when valid, so the loop stays quick.
                if obj["type"] == "size" {
                    obj.insert("width".into(), json!(*rng.pick(&[16, 48, 0, 99999])));
                }
                obj.insert("seq".into(), json!(1000 + i));
                Value::Object(obj).to_string()
            }
        };
        tab.send_raw(&text);
        // Every message gets an answer: a frame or an error (a frame may answer several).
        match tab.reply() {
            Reply::Frame(meta, pixels) => {
                frames += 1;
                let (w, h) = (
                    meta["width"].as_u64().unwrap(),
                    meta["height"].as_u64().unwrap(),
                );
                if meta["encoding"] == "raw" {
                    assert_eq!(pixels.len() as u64, 4 * w * h);
                } else {
                    assert!(pixels.starts_with(b"\x89PNG"));
                }
                tab.frame = (meta, pixels);
            }
            Reply::Error(e) => {
                errors += 1;
                assert!(!e["message"].as_str().unwrap_or("").is_empty(), "{e}");
            }
        }
        if i % 50 == 0 {
            tab.ws.send(Message::binary(vec![0u8, 1, 2])).expect("send");
            assert!(matches!(tab.reply(), Reply::Error(_)));
        }
    }
    assert!(
        frames > 10 && errors > 100,
        "{frames} frames, {errors} errors"
    );
    // The server still serves this tab, a new tab and plain HTTP.
    tab.frame_of(json!({"type": "size", "width": 32, "height": 32}));
    let mut other = Tab::open(address);
    other.frame_of(json!({"type": "exposure", "value": 2}));
    let (status, body) = http_get(address, "/api/info");
    assert_eq!(status, 200);
    assert!(body.starts_with(b"{"));
}
