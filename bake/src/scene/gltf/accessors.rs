//! Low-level glTF input: parsing the container, resolving buffers and images (external files,
//! data URIs, the GLB `BIN` chunk) and reading accessors.
//!
//! We read accessors ourselves instead of through `gltf::mesh::Reader` because the crate's
//! reader trusts the file: a zero `count` underflows, a wrong accessor type trips a
//! `debug_assert`, a short sparse block `unwrap`s. Here every offset, stride and count is
//! checked with overflow-checked arithmetic against the bytes actually present, so malformed
//! input becomes an error message and never a panic or a huge allocation.

use std::path::{Path, PathBuf};

use gltf::accessor::{sparse::IndexType, DataType, Dimensions};
use gltf::Accessor;

/// Accessors without a buffer view are all zeros; above this many elements we refuse rather
/// than allocate gigabytes because of one number in a small JSON file.
const MAX_VIRTUAL_ELEMENTS: usize = 1 << 26;

/// Parses a `.gltf` (JSON) or `.glb` byte string and validates it against the glTF schema.
pub(super) fn parse(bytes: &[u8]) -> Result<gltf::Gltf, String> {
    if bytes.is_empty() {
        return Err("the file is empty".to_owned());
    }
    if bytes.starts_with(b"glTF") {
        // gltf 1.4 computes `header.length - 12` unchecked; a length below 20 (header plus one
        // chunk header) would underflow, so reject it here.
        if bytes.len() < 20 {
            return Err(format!(
                "truncated GLB: {} bytes, a GLB needs at least a 12-byte header and a chunk",
                bytes.len()
            ));
        }
        let declared = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize;
        if declared < 20 {
            return Err(format!(
                "corrupt GLB header: declared length {declared} < 20"
            ));
        }
        if declared > bytes.len() {
            return Err(format!(
                "truncated GLB: the header declares {declared} bytes but the file has {}",
                bytes.len()
            ));
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
        Ok(Err(e)) => Err(describe_gltf_error(&e)),
        Err(_) => Err("the glTF parser failed on this input (malformed file)".to_owned()),
    }
}

/// The crate's schema validation, minus one rule: POSITION accessors must declare `min` and
/// `max`. Those are bounds hints we never read (bounds come from the data), and hand-written
/// or lightly exported files often omit them, so refusing such files would help nobody.
fn validate(root: &gltf::json::Root) -> Vec<(gltf::json::Path, gltf::json::validation::Error)> {
    use gltf::json::validation::{Error, Validate};
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| {
        let p = path();
        let s = p.as_str();
        let bounds_hint = s.ends_with("[\"POSITION\"].min") || s.ends_with("[\"POSITION\"].max");
        if !(bounds_hint && matches!(error, Error::Missing)) {
            errors.push((p, error));
        }
    });
    errors
}

fn describe_gltf_error(e: &gltf::Error) -> String {
    match e {
        gltf::Error::Validation(list) => {
            let items: Vec<String> = list
                .iter()
                .take(8)
                .map(|(path, err)| format!("{path}: {err}"))
                .collect();
            let more = if list.len() > 8 {
                format!(" (and {} more)", list.len() - 8)
            } else {
                String::new()
            };
            format!("invalid glTF: {}{more}", items.join("; "))
        }
        gltf::Error::Deserialize(err) => format!("malformed glTF JSON: {err}"),
        other => format!("{other}"),
    }
}

/// Where a buffer's or image's bytes come from, resolved.
pub(super) enum UriTarget {
    /// Bytes embedded in a `data:` URI, already decoded.
    Data(Vec<u8>),
    /// A file, relative URIs resolved against the glTF's folder.
    File(PathBuf),
}

/// Resolves a glTF URI: `data:...;base64,...`, a (percent-encoded) relative path, or
/// `file://` path. Other schemes (http, ...) are refused: a bake must not reach the network.
pub(super) fn resolve_uri(uri: &str, gltf_folder: &Path) -> Result<UriTarget, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (header, payload) = rest
            .split_once(',')
            .ok_or_else(|| "malformed data URI (no ',')".to_owned())?;
        if !header.ends_with(";base64") {
            return Err("only base64 data URIs are supported".to_owned());
        }
        return base64_decode(payload).map(UriTarget::Data);
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
            return Err(format!(
                "URI scheme \"{scheme}:\" is not supported (only relative paths, file:// and data:)"
            ));
        }
    }
    let decoded = percent_decode(uri)?;
    Ok(UriTarget::File(gltf_folder.join(decoded)))
}

fn percent_decode(s: &str) -> Result<String, String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = b
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("bad percent-encoding in URI \"{s}\""))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| format!("URI \"{s}\" is not UTF-8 after decoding"))
}

/// Standard base64 (RFC 4648, with or without `=` padding; whitespace ignored).
pub(super) fn base64_decode(s: &str) -> Result<Vec<u8>, String> {
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
            return Err(format!(
                "invalid base64: data after '=' padding at byte {pos}"
            ));
        }
        let v = val(c)
            .ok_or_else(|| format!("invalid base64 character {:?} at byte {pos}", c as char))?;
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    if bits >= 6 {
        return Err("invalid base64: truncated data".to_owned());
    }
    Ok(out)
}

/// A human-readable name for a buffer or image source in messages.
pub(super) fn uri_label(uri: &str) -> String {
    if uri.starts_with("data:") {
        "embedded data URI".to_owned()
    } else {
        format!("\"{uri}\"")
    }
}

/// The bytes of a buffer view, checked against its buffer.
pub(super) fn view_bytes<'b>(
    view: &gltf::buffer::View,
    buffers: &'b [Vec<u8>],
) -> Result<&'b [u8], String> {
    let bi = view.buffer().index();
    let data = buffers
        .get(bi)
        .ok_or_else(|| format!("buffer view {} refers to missing buffer {bi}", view.index()))?;
    let start = view.offset();
    let end = start
        .checked_add(view.length())
        .ok_or_else(|| format!("buffer view {}: offset + length overflows", view.index()))?;
    data.get(start..end).ok_or_else(|| {
        format!(
            "buffer view {} (bytes {start}..{end}) runs past the end of buffer {bi} ({} bytes)",
            view.index(),
            data.len()
        )
    })
}

fn component_size(t: DataType) -> usize {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

fn type_name(d: Dimensions) -> &'static str {
    match d {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

/// Decodes one component to f32, applying glTF's normalized-integer rules.
fn decode_f32(b: &[u8], t: DataType, normalized: bool) -> f32 {
    match t {
        DataType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        DataType::U8 if normalized => b[0] as f32 / 255.0,
        DataType::U16 if normalized => u16::from_le_bytes([b[0], b[1]]) as f32 / 65535.0,
        DataType::I8 if normalized => (b[0] as i8 as f32 / 127.0).max(-1.0),
        DataType::I16 if normalized => {
            (i16::from_le_bytes([b[0], b[1]]) as f32 / 32767.0).max(-1.0)
        }
        DataType::U8 => b[0] as f32,
        DataType::I8 => b[0] as i8 as f32,
        DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f32,
        DataType::I16 => i16::from_le_bytes([b[0], b[1]]) as f32,
        DataType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
    }
}

fn decode_u32(b: &[u8], t: DataType) -> u32 {
    match t {
        DataType::U8 | DataType::I8 => b[0] as u32,
        DataType::U16 | DataType::I16 => u16::from_le_bytes([b[0], b[1]]) as u32,
        DataType::U32 | DataType::F32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    }
}

/// `count` elements of `elem_size` bytes, `stride` apart, starting at `offset` in `bytes`:
/// checks they fit and returns the element start offsets' base slice.
fn check_strided(
    bytes: &[u8],
    offset: usize,
    stride: usize,
    elem_size: usize,
    count: usize,
    what: &str,
) -> Result<(), String> {
    if count == 0 {
        return Ok(());
    }
    let needed = (count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(elem_size))
        .and_then(|x| x.checked_add(offset))
        .ok_or_else(|| format!("{what}: size overflows"))?;
    if needed > bytes.len() {
        return Err(format!(
            "{what}: {count} elements need {needed} bytes but its buffer view has {}",
            bytes.len()
        ));
    }
    Ok(())
}

/// Reads an accessor as `count` elements of `comps` f32 components (flattened), applying
/// sparse substitution. `allowed` lists the component types accepted for this attribute as
/// `(type, must_be_normalized)`.
pub(super) fn read_f32(
    acc: &Accessor,
    buffers: &[Vec<u8>],
    what: &str,
    comps: usize,
    allowed: &[(DataType, bool)],
) -> Result<Vec<f32>, String> {
    let dims = acc.dimensions();
    if dims.multiplicity() != comps {
        return Err(format!(
            "{what} accessor {} has type {}, expected {} components",
            acc.index(),
            type_name(dims),
            comps
        ));
    }
    let t = acc.data_type();
    let ok = allowed
        .iter()
        .any(|&(at, norm)| at == t && (!norm || acc.normalized()));
    if !ok {
        return Err(format!(
            "{what} accessor {} has component type {t:?}{}, which is not supported here",
            acc.index(),
            if acc.normalized() {
                " (normalized)"
            } else {
                ""
            }
        ));
    }
    let norm = acc.normalized();
    read_generic(acc, buffers, what, comps, |b| decode_f32(b, t, norm), 0.0)
}

/// Reads a scalar unsigned-integer accessor (triangle indices).
pub(super) fn read_indices(acc: &Accessor, buffers: &[Vec<u8>]) -> Result<Vec<u32>, String> {
    if acc.dimensions() != Dimensions::Scalar {
        return Err(format!(
            "index accessor {} has type {}, expected SCALAR",
            acc.index(),
            type_name(acc.dimensions())
        ));
    }
    let t = acc.data_type();
    if !matches!(t, DataType::U8 | DataType::U16 | DataType::U32) {
        return Err(format!(
            "index accessor {} has component type {t:?}; indices must be unsigned bytes, shorts or ints",
            acc.index()
        ));
    }
    read_generic(acc, buffers, "indices", 1, |b| decode_u32(b, t), 0)
}

fn read_generic<T: Copy>(
    acc: &Accessor,
    buffers: &[Vec<u8>],
    what: &str,
    comps: usize,
    decode: impl Fn(&[u8]) -> T,
    zero: T,
) -> Result<Vec<T>, String> {
    let count = acc.count();
    let csize = component_size(acc.data_type());
    let elem_size = comps * csize;
    let label = format!("{what} accessor {}", acc.index());

    let mut out: Vec<T> = match acc.view() {
        Some(view) => {
            let bytes = view_bytes(&view, buffers).map_err(|e| format!("{label}: {e}"))?;
            let stride = view.stride().unwrap_or(elem_size);
            if stride < elem_size {
                return Err(format!(
                    "{label}: byteStride {stride} is smaller than the element size {elem_size}"
                ));
            }
            check_strided(bytes, acc.offset(), stride, elem_size, count, &label)?;
            let mut v = Vec::with_capacity(count * comps);
            for i in 0..count {
                let base = acc.offset() + i * stride;
                for c in 0..comps {
                    let at = base + c * csize;
                    v.push(decode(&bytes[at..at + csize]));
                }
            }
            v
        }
        None => {
            if count > MAX_VIRTUAL_ELEMENTS {
                return Err(format!(
                    "{label}: {count} elements without a buffer view is implausibly large"
                ));
            }
            vec![zero; count * comps]
        }
    };

    if let Some(sparse) = acc.sparse() {
        let n = sparse.count();
        let idx = sparse.indices();
        let idx_type = match idx.index_type() {
            IndexType::U8 => DataType::U8,
            IndexType::U16 => DataType::U16,
            IndexType::U32 => DataType::U32,
        };
        let isize_ = component_size(idx_type);
        let ibytes =
            view_bytes(&idx.view(), buffers).map_err(|e| format!("{label} sparse indices: {e}"))?;
        check_strided(
            ibytes,
            idx.offset(),
            isize_,
            isize_,
            n,
            &format!("{label} sparse indices"),
        )?;
        let vals = sparse.values();
        let vbytes =
            view_bytes(&vals.view(), buffers).map_err(|e| format!("{label} sparse values: {e}"))?;
        check_strided(
            vbytes,
            vals.offset(),
            elem_size,
            elem_size,
            n,
            &format!("{label} sparse values"),
        )?;
        for k in 0..n {
            let ia = idx.offset() + k * isize_;
            let target = decode_u32(&ibytes[ia..ia + isize_], idx_type) as usize;
            if target >= count {
                return Err(format!(
                    "{label}: sparse index {target} is out of range (count {count})"
                ));
            }
            for c in 0..comps {
                let at = vals.offset() + k * elem_size + c * csize;
                out[target * comps + c] = decode(&vbytes[at..at + csize]);
            }
        }
    }
    Ok(out)
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
        assert!(base64_decode("Zm9v!").is_err());
        assert!(base64_decode("Z").is_err());
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
        assert!(resolve_uri("http://example.com/x.bin", f).is_err());
    }

    #[test]
    fn truncated_glb_headers_are_errors() {
        assert!(parse(b"glTF").is_err());
        let mut h = b"glTF".to_vec();
        h.extend_from_slice(&2u32.to_le_bytes());
        h.extend_from_slice(&3u32.to_le_bytes());
        h.extend_from_slice(&[0; 8]);
        assert!(parse(&h).is_err());
    }
}
