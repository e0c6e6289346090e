//! The glTF container and where its bytes come from: parsing `.gltf` (JSON) and `.glb` files
//! defensively, and resolving buffer and image URIs (external files, `data:` URIs).

use crate::scene::error::{Base64Error, GltfParseError, UriError};
use std::path::{Path, PathBuf};

/// Parses a `.gltf` (JSON) or `.glb` byte string and validates it against the glTF schema.
pub(crate) fn parse(bytes: &[u8]) -> Result<gltf::Gltf, GltfParseError> {
    if bytes.is_empty() {
        return Err(GltfParseError::Empty);
    }
    if bytes.starts_with(b"glTF") {
        // gltf 1.4 computes `header.length - 12` unchecked; a length below 20 (header plus one
        // chunk header) would underflow, so reject it here.
        if bytes.len() < 20 {
            return Err(GltfParseError::TooShort { len: bytes.len() });
        }
        let declared = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize;
        if declared < 20 {
            return Err(GltfParseError::BadLength { declared });
        }
        if declared > bytes.len() {
            return Err(GltfParseError::Truncated {
                declared,
                len: bytes.len(),
            });
        }
    }
    // The crate is third-party code parsing untrusted input; if it ever panics on some input
    // we did not foresee, turn that into an error too rather than abort the bake.
    let parsed = std::panic::catch_unwind(|| {
        let g = gltf::Gltf::from_slice_without_validation(bytes)?;
        let errors = validate(g.document.as_json());
        if errors.is_empty() {
            Ok(g)
        } else {
            Err(gltf::Error::Validation(errors))
        }
    });
    match parsed {
        Ok(Ok(g)) => Ok(g),
        Ok(Err(gltf::Error::Validation(list))) => Err(GltfParseError::Invalid {
            problems: list
                .iter()
                .take(8)
                .map(|(path, err)| format!("{path}: {err}"))
                .collect(),
            more: list.len().saturating_sub(8),
        }),
        Ok(Err(gltf::Error::Deserialize(err))) => Err(GltfParseError::Json(err)),
        Ok(Err(other)) => Err(GltfParseError::Other(other)),
        Err(_) => Err(GltfParseError::ParserPanicked),
    }
}

/// The crate's schema validation, minus one rule: POSITION accessors must declare `min` and
/// `max`. Those are bounds hints we never read (bounds come from the data), and hand-written
/// or lightly exported files often omit them, so refusing such files would help nobody.
fn validate(root: &gltf::json::Root) -> Vec<(gltf::json::Path, gltf::json::validation::Error)> {
    use gltf::json::camera::Type;
    use gltf::json::validation::{Checked, Error, Validate};
    use gltf::json::Path;
    let mut errors = Vec::new();
    root.validate(root, Path::new, &mut |path, error| {
        let p = path();
        let s = p.as_str();
        let bounds_hint = s.ends_with("[\"POSITION\"].min") || s.ends_with("[\"POSITION\"].max");
        if !(bounds_hint && matches!(error, Error::Missing)) {
            errors.push((p, error));
        }
    });
    // Rules of the glTF spec the crate does not check, although its accessors unwrap them
    // (found by fuzzing): a camera has the projection its `type` names; an image has a URI
    // or a buffer view, and a MIME type with the buffer view.
    for (i, camera) in root.cameras.iter().enumerate() {
        let missing = match camera.type_ {
            Checked::Valid(Type::Perspective) if camera.perspective.is_none() => "perspective",
            Checked::Valid(Type::Orthographic) if camera.orthographic.is_none() => "orthographic",
            _ => continue,
        };
        errors.push((
            Path::new().field("cameras").index(i).field(missing),
            Error::Missing,
        ));
    }
    for (i, image) in root.images.iter().enumerate() {
        let missing = match (&image.uri, &image.buffer_view, &image.mime_type) {
            (None, None, _) => "uri",
            (None, Some(_), None) => "mimeType",
            _ => continue,
        };
        errors.push((
            Path::new().field("images").index(i).field(missing),
            Error::Missing,
        ));
    }
    errors
}

/// Where a buffer's or image's bytes come from, resolved.
pub(crate) enum UriTarget {
    /// Bytes embedded in a `data:` URI, already decoded.
    Data(Vec<u8>),
    /// A file, relative URIs resolved against the glTF's folder.
    File(PathBuf),
}

/// Resolves a glTF URI: `data:...;base64,...`, a (percent-encoded) relative path, or
/// `file://` path. Other schemes (http, ...) are refused: a bake must not reach the network.
pub(crate) fn resolve_uri(uri: &str, gltf_folder: &Path) -> Result<UriTarget, UriError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (header, payload) = rest.split_once(',').ok_or(UriError::MalformedData)?;
        if !header.ends_with(";base64") {
            return Err(UriError::NotBase64);
        }
        return Ok(UriTarget::Data(base64_decode(payload)?));
    }
    if let Some(rest) = uri.strip_prefix("file://") {
        return Ok(UriTarget::File(PathBuf::from(percent_decode(rest)?)));
    }
    if let Some(colon) = uri.find(':') {
        let scheme = &uri[..colon];
        // A one-letter "scheme" is a Windows drive letter, not a URI scheme.
        if scheme.len() > 1
            && scheme
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
        {
            return Err(UriError::UnsupportedScheme(scheme.to_owned()));
        }
    }
    let decoded = percent_decode(uri)?;
    Ok(UriTarget::File(gltf_folder.join(decoded)))
}

fn percent_decode(s: &str) -> Result<String, UriError> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = b
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| UriError::BadPercent(s.to_owned()))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| UriError::NotUtf8(s.to_owned()))
}

/// Standard base64 (RFC 4648, with or without `=` padding; whitespace ignored; the URL-safe
/// alphabet's `-` and `_` are accepted too).
pub(crate) fn base64_decode(s: &str) -> Result<Vec<u8>, Base64Error> {
    fn val(c: u8) -> Option<u32> {
        match c {
            b'A'..=b'Z' => Some((c - b'A') as u32),
            b'a'..=b'z' => Some((c - b'a') as u32 + 26),
            b'0'..=b'9' => Some((c - b'0') as u32 + 52),
            b'+' | b'-' => Some(62),
            b'/' | b'_' => Some(63),
            _ => None,
        }
    }
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    let mut acc = 0u32;
    let mut bits = 0u32;
    let mut padding = false;
    for (pos, &c) in s.as_bytes().iter().enumerate() {
        if c.is_ascii_whitespace() {
            continue;
        }
        if c == b'=' {
            padding = true;
            continue;
        }
        if padding {
            return Err(Base64Error::AfterPadding(pos));
        }
        let v = val(c).ok_or(Base64Error::BadCharacter { ch: c as char, pos })?;
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    if bits >= 6 {
        return Err(Base64Error::Truncated);
    }
    Ok(out)
}

/// A human-readable name for a buffer or image source in messages.
pub(crate) fn uri_label(uri: &str) -> String {
    if uri.starts_with("data:") {
        "embedded data URI".to_owned()
    } else {
        format!("\"{uri}\"")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_roundtrip_known_values() {
        assert_eq!(base64_decode("").unwrap(), b"");
        assert_eq!(base64_decode("Zg==").unwrap(), b"f");
        assert_eq!(base64_decode("Zm8=").unwrap(), b"fo");
        assert_eq!(base64_decode("Zm9v").unwrap(), b"foo");
        assert_eq!(base64_decode("Zm9vYmFy").unwrap(), b"foobar");
        assert_eq!(
            base64_decode("Zm9v!").unwrap_err(),
            Base64Error::BadCharacter { ch: '!', pos: 4 }
        );
        assert_eq!(base64_decode("Z").unwrap_err(), Base64Error::Truncated);
        assert_eq!(
            base64_decode("Zg==Zg").unwrap_err(),
            Base64Error::AfterPadding(4)
        );
    }

    #[test]
    fn uris() {
        let f = Path::new("/a");
        match resolve_uri("my%20mesh.bin", f).unwrap() {
            UriTarget::File(p) => assert_eq!(p, PathBuf::from("/a/my mesh.bin")),
            UriTarget::Data(_) => panic!(),
        }
        match resolve_uri("data:application/octet-stream;base64,Zm9v", f).unwrap() {
            UriTarget::Data(d) => assert_eq!(d, b"foo"),
            UriTarget::File(_) => panic!(),
        }
        assert!(matches!(
            resolve_uri("http://example.com/x.bin", f),
            Err(UriError::UnsupportedScheme(s)) if s == "http"
        ));
        assert!(matches!(
            resolve_uri("bad%zz.bin", f),
            Err(UriError::BadPercent(_))
        ));
    }

    #[test]
    fn truncated_glb_headers_are_errors() {
        assert!(matches!(
            parse(b"glTF"),
            Err(GltfParseError::TooShort { len: 4 })
        ));
        let mut h = b"glTF".to_vec();
        h.extend_from_slice(&2u32.to_le_bytes());
        h.extend_from_slice(&3u32.to_le_bytes());
        h.extend_from_slice(&[0; 8]);
        assert!(matches!(
            parse(&h),
            Err(GltfParseError::BadLength { declared: 3 })
        ));
        assert!(matches!(parse(b""), Err(GltfParseError::Empty)));
    }
}
