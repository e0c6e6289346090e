//! What a file that is not a bake file looks like, so that opening a scene, a config or an
//! image by mistake (`relight scene.gltf`) says so instead of reporting a "truncated" bake with
//! an absurd header length read from the file's first eight bytes.
//!
//! A bake file's byte 8 is the `{` that opens its JSON header (the safetensors format requires
//! the header to begin with `{`, and our writer never writes whitespace before it). When the
//! header length field does not fit the file and byte 8 is anything else, the file is not a
//! bake file (truncated or not) and its first bytes tell what it is. (Text and the usual magic
//! numbers read as a little-endian u64 are far longer than any such file, so every file named
//! here gets this answer rather than a header error.)

/// How many leading bytes are looked at (enough for a glTF's `"asset"` key or a TOML table
/// header near the top).
const SNIFF_LEN: usize = 4096;

/// Whether `bytes` (a whole file, at least 9 bytes) cannot be a bake file, even a truncated one:
/// its byte 8, where the JSON header starts, is not `{`.
pub(super) fn cannot_be_a_bake(bytes: &[u8]) -> bool {
    bytes.get(8).is_some_and(|&b| b != b'{')
}

/// What a file that is not a bake file looks like, e.g. "a glTF JSON scene (.gltf)", from its
/// first bytes.
pub(super) fn looks_like(bytes: &[u8]) -> String {
    let head = &bytes[..bytes.len().min(SNIFF_LEN)];
    let magic: &[(&[u8], &str)] = &[
        (b"glTF", "a binary glTF scene (.glb)"),
        (b"\x89PNG\r\n\x1a\n", "a PNG image"),
        (b"\x76\x2f\x31\x01", "an OpenEXR image"),
        (b"#?RADIANCE", "a Radiance HDR image"),
        (b"#?RGBE", "a Radiance HDR image"),
        (b"\xff\xd8\xff", "a JPEG image"),
        (b"PK\x03\x04", "a zip archive"),
        (b"\x1f\x8b", "a gzip-compressed file"),
        (b"\x7fELF", "an executable (ELF)"),
    ];
    if let Some((_, what)) = magic.iter().find(|(m, _)| head.starts_with(m)) {
        return (*what).to_string();
    }
    if let Some(text) = as_text(head) {
        let trimmed = text.trim_start();
        if trimmed.starts_with('{') {
            return if text.contains("\"asset\"") {
                "a glTF JSON scene (.gltf)".to_string()
            } else {
                "a JSON text file".to_string()
            };
        }
        if looks_like_toml(text) {
            return "a TOML text file (a bake config?)".to_string();
        }
        return "a text file".to_string();
    }
    let first: Vec<String> = head.iter().take(8).map(|b| format!("{b:02x}")).collect();
    format!("unrecognised binary data (first bytes {})", first.join(" "))
}

/// `head` as text, when it is UTF-8 without control characters other than whitespace (a
/// multi-byte character cut by the end of `head` is allowed).
fn as_text(head: &[u8]) -> Option<&str> {
    let text = match std::str::from_utf8(head) {
        Ok(t) => t,
        // Cut inside a character at the very end: the part before it.
        Err(e) if e.error_len().is_none() => std::str::from_utf8(&head[..e.valid_up_to()]).ok()?,
        Err(_) => return None,
    };
    let control = |c: char| c.is_control() && !matches!(c, '\n' | '\r' | '\t');
    (!text.chars().any(control)).then_some(text)
}

/// Whether the first meaningful line of `text` is a TOML key/value pair (`name = ...`) or a
/// table header (`[name]`); comments and blank lines are skipped.
fn looks_like_toml(text: &str) -> bool {
    let Some(line) = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
    else {
        return false;
    };
    let bare_key = |k: &str| {
        !k.is_empty()
            && k.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '"'))
    };
    if let Some(inner) = line.strip_prefix('[') {
        return inner
            .trim_start_matches('[')
            .split(']')
            .next()
            .is_some_and(|k| bare_key(k.trim()));
    }
    line.split_once('=')
        .is_some_and(|(k, _)| bare_key(k.trim()))
}

#[cfg(test)]
mod tests {
    use super::{cannot_be_a_bake, looks_like};

    #[test]
    fn files_users_open_by_mistake_are_named() {
        let gltf = br#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}]}"#;
        assert_eq!(looks_like(gltf), "a glTF JSON scene (.gltf)");
        let mut glb = b"glTF\x02\x00\x00\x00".to_vec();
        glb.extend_from_slice(&[0x80, 0, 0, 0, b'J', b'S', b'O', b'N']);
        assert_eq!(looks_like(&glb), "a binary glTF scene (.glb)");
        let toml = b"# a config\nscene = \"x.gltf\"\nspp = 64\n";
        assert_eq!(looks_like(toml), "a TOML text file (a bake config?)");
        assert_eq!(
            looks_like(b"[materials.bunny]\neditable = true\n"),
            "a TOML text file (a bake config?)"
        );
        assert_eq!(looks_like(b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR"), "a PNG image");
        assert_eq!(
            looks_like(b"\x76\x2f\x31\x01\x02\0\0\0"),
            "an OpenEXR image"
        );
        assert_eq!(
            looks_like(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n"),
            "a Radiance HDR image"
        );
        assert_eq!(looks_like(b"hello, this is a note\n"), "a text file");
        assert_eq!(looks_like(b"[1, 2, 3] and more"), "a text file");
        assert_eq!(
            looks_like(&[0u8, 1, 2, 3, 4, 5, 6, 7, 8, 9]),
            "unrecognised binary data (first bytes 00 01 02 03 04 05 06 07)"
        );
        // A character cut by the end of the sniffed bytes is still text.
        let mut long = "scene = \"x\"\n".repeat(400).into_bytes();
        long.extend_from_slice("é".repeat(100).as_bytes());
        assert_eq!(
            looks_like(&long[..super::SNIFF_LEN]),
            "a TOML text file (a bake config?)"
        );
        // What may be a bake: byte 8 opens the JSON header.
        assert!(!cannot_be_a_bake(b"\x10\0\0\0\0\0\0\0{\"a\""));
        assert!(cannot_be_a_bake(gltf));
        assert!(!cannot_be_a_bake(b"12345678"));
    }
}
