//! Every control's request changes exactly the setting it names, and the frame is the
//! runtime's own render of the settings, tone-mapped as `relight` writes PNGs.

use super::*;

/// `after` equals `before` with exactly the field at `path` (a JSON pointer) changed.
fn changed_exactly(before: &Value, after: &Value, path: &str) {
    assert_ne!(
        before.pointer(path),
        after.pointer(path),
        "{path} did not change"
    );
    let mut patched = before.clone();
    *patched.pointer_mut(path).expect("path exists") = after.pointer(path).expect("path").clone();
    assert_eq!(
        &patched, after,
        "a request for {path} changed something else"
    );
}

fn check_controls(bake: &Path, controls: &[(Value, &str)]) {
    let address = serve(bake, None);
    let mut tab = Tab::open(address);
    assert_eq!(
        tab.frame.1,
        expected_rgba(bake, &tab.settings()),
        "first frame"
    );
    for (request, path) in controls {
        let before = tab.settings();
        let mut request = request.clone();
        // "same": the current value (a camera request changing one field of three).
        for key in ["target", "eye"] {
            if request[key] == "same" {
                request[key] = before["view"]["camera"][key].clone();
            }
        }
        let (meta, pixels) = tab.frame_of(request.clone());
        assert_eq!(meta["seq"], json!(tab.seq));
        changed_exactly(&before, &meta["settings"], path);
        assert_eq!(
            pixels,
            expected_rgba(bake, &meta["settings"]),
            "{request}: the frame is not the runtime's render of the settings"
        );
        let (w, h) = (
            meta["width"].as_u64().unwrap(),
            meta["height"].as_u64().unwrap(),
        );
        assert_eq!(pixels.len() as u64, 4 * w * h);
    }
}

#[test]
fn every_control_changes_exactly_what_it_names_per_pixel() {
    let b = bakes();
    check_controls(
        &b.pixel,
        &[
            (
                json!({"type": "material", "name": "bunny", "param": "kd", "value": [0.8, 0.1, 0.1]}),
                "/materials/bunny/kd",
            ),
            (
                json!({"type": "material", "name": "bunny", "param": "ks", "value": [0.05, 0.5, 0.05]}),
                "/materials/bunny/ks",
            ),
            (
                json!({"type": "material", "name": "bunny", "param": "shininess", "value": 300}),
                "/materials/bunny/shininess",
            ),
            (
                json!({"type": "material", "name": "tall_box", "param": "alpha", "value": 0.5}),
                "/materials/tall_box/alpha",
            ),
            (json!({"type": "exposure", "value": 2.5}), "/exposure"),
            (json!({"type": "tone", "value": "aces"}), "/tone"),
        ],
    );
}

#[test]
fn every_control_changes_exactly_what_it_names_per_vertex() {
    let b = bakes();
    check_controls(
        &b.vertex,
        &[
            (
                json!({"type": "size", "width": 96, "height": 512}),
                "/view/width",
            ),
            (
                json!({"type": "size", "width": 96, "height": 80}),
                "/view/height",
            ),
            (
                json!({"type": "material", "name": "sphere", "param": "alpha", "value": 0.4}),
                "/materials/sphere/alpha",
            ),
            (
                json!({"type": "material", "name": "bunny", "param": "kd", "value": [0.2, 0.3, 0.9]}),
                "/materials/bunny/kd",
            ),
            (
                json!({"type": "environment", "name": "studio.exr"}),
                "/view/environment",
            ),
            (json!({"type": "rotation", "value": 75}), "/view/rotation"),
            (
                json!({"type": "intensity", "value": 0.6}),
                "/view/intensity",
            ),
            (
                json!({"type": "camera", "eye": [0.5, 0.4, 0.7], "target": "same", "fov": 40}),
                "/view/camera/eye",
            ),
            (
                json!({"type": "camera", "eye": "same", "target": [0, 0.1, 0], "fov": 40}),
                "/view/camera/target",
            ),
            (
                json!({"type": "camera", "eye": "same", "target": "same", "fov": 55}),
                "/view/camera/fov",
            ),
            (json!({"type": "exposure", "value": 0.5}), "/exposure"),
            (json!({"type": "tone", "value": "reinhard"}), "/tone"),
            (
                json!({"type": "environment", "name": "baked"}),
                "/view/environment",
            ),
        ],
    );
}
