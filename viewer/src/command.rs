//! "Copy command": the `relight` command line that writes the image a tab shows.
//!
//! Every number is printed as Rust prints an `f32` (the shortest text that parses back to the
//! same bits), so `relight` sets the very values the viewer set and renders the same floats;
//! its PNG is the canvas' bytes (the same tone mapping). Materials appear only where they
//! differ from the bake's values; a per-vertex view is always spelt out in full.

use prt_formats::MaterialOverride;

use crate::settings::{BakeInfo, Settings, BAKED_ENVIRONMENT};

/// Quotes a shell word when it needs it (POSIX single quotes).
pub fn shell_word(word: &str) -> String {
    let plain = !word.is_empty()
        && word
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=,:+@%".contains(c));
    if plain {
        word.to_string()
    } else {
        format!("'{}'", word.replace('\'', r"'\''"))
    }
}

/// The output file the command writes: `<bake name>-view.png` in the working folder.
pub fn output_name(info: &BakeInfo) -> String {
    let stem = std::path::Path::new(&info.bake)
        .file_stem()
        .map_or("bake".into(), |s| s.to_string_lossy().into_owned());
    format!("{stem}-view.png")
}

/// The `relight` command line reproducing `settings` (environment maps named relative to
/// `env_folder` as given on the viewer's command line).
pub fn relight_command(info: &BakeInfo, settings: &Settings, env_folder: Option<&str>) -> String {
    let mut words: Vec<String> = vec!["relight".into(), shell_word(&info.bake)];
    for (m, baked) in settings.materials.iter().zip(&info.materials) {
        for (v, b) in m.values.iter().zip(&baked.params) {
            if *v != b.value {
                let o = MaterialOverride {
                    material: m.name.clone(),
                    value: *v,
                };
                words.push("--set".into());
                words.push(shell_word(&o.to_string()));
            }
        }
    }
    if let Some(view) = &settings.view {
        if view.environment != BAKED_ENVIRONMENT {
            let path = std::path::Path::new(env_folder.unwrap_or(".")).join(&view.environment);
            words.push("--env".into());
            words.push(shell_word(&path.display().to_string()));
        }
        words.push(format!("--env-rotate={}", view.rotation));
        words.push(format!("--env-intensity={}", view.intensity));
        words.push("--camera".into());
        words.push(shell_word(&view.camera.to_string()));
        words.push(format!("--width={}", view.width));
        words.push(format!("--height={}", view.height));
    }
    words.push(format!("--exposure={}", settings.exposure));
    words.push(format!("--tone={}", settings.tone.name()));
    words.push("--out".into());
    words.push(shell_word(&output_name(info)));
    words.join(" ")
}
