//! Validation of a whole file image: header length, JSON header, format and version, tensor
//! table, exact tiling of the data section, checksums, and a cross-check with the reference
//! safetensors parser.

use std::collections::BTreeMap;
use std::path::Path;

use serde_json::Value;

use super::digest::header_digest;
use super::sniff;
use super::{
    keys, Dtype, FormatError, Result, FORMAT_NAME, MAX_HEADER_LEN, PAD_PREFIX, RESERVED_PREFIX,
    SCHEMA_VERSION, ST_METADATA,
};

/// One (non-padding) tensor of an open file, as validated by the parser.
#[derive(Debug)]
pub(super) struct TensorEntry {
    pub(super) name: String,
    pub(super) dtype: Dtype,
    pub(super) shape: Vec<usize>,
    /// Absolute byte range in the file.
    pub(super) start: usize,
    pub(super) end: usize,
    /// The stored CRC-32 of the bytes `start..end`.
    pub(super) crc: u32,
}

/// What [`parse`] found in a valid file.
pub(super) struct Parsed {
    pub(super) schema_version: u32,
    pub(super) metadata: Value,
    /// Tensors in file order, padding excluded.
    pub(super) tensors: Vec<TensorEntry>,
    /// Names and absolute byte ranges of the padding tensors.
    pub(super) pads: Vec<(String, usize, usize)>,
}

/// Validates a whole file image. Never panics: every index is checked, every number parsed
/// with overflow checks.
pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<Parsed> {
    let pathbuf = || path.to_path_buf();
    let invalid = |reason: String| FormatError::InvalidHeader {
        path: pathbuf(),
        reason,
    };
    let file_len = bytes.len() as u64;
    let Some(len_bytes) = bytes.first_chunk::<8>() else {
        return Err(FormatError::TooShort {
            path: pathbuf(),
            len: file_len,
        });
    };
    let header_len = u64::from_le_bytes(*len_bytes);
    let available = file_len - 8;
    if (header_len > available || header_len > MAX_HEADER_LEN as u64)
        && sniff::cannot_be_a_bake(bytes)
    {
        return Err(FormatError::NotABakeFile {
            path: pathbuf(),
            looks_like: sniff::looks_like(bytes),
        });
    }
    if header_len > available {
        return Err(FormatError::HeaderTruncated {
            path: pathbuf(),
            header_len,
            available,
            file_len,
        });
    }
    if header_len > MAX_HEADER_LEN as u64 {
        return Err(FormatError::HeaderTooLarge {
            path: pathbuf(),
            header_len,
        });
    }
    // header_len <= available <= bytes.len(), so these conversions and slices are in range.
    let data_start = 8 + header_len as usize;
    let header = &bytes[8..data_start];
    let data_len = bytes.len() - data_start;
    let header = std::str::from_utf8(header).map_err(|e| {
        invalid(format!(
            "not UTF-8 (at header byte {}); the header is damaged",
            e.valid_up_to()
        ))
    })?;
    let header: serde_json::Map<String, Value> =
        serde_json::from_str(header).map_err(|e| invalid(format!("bad JSON: {e}")))?;

    // __metadata__: format and version first, so that a file from another version gets the
    // version error rather than whatever structural difference it has.
    let st_meta = match header.get(ST_METADATA) {
        None => {
            return Err(FormatError::WrongFormat {
                path: pathbuf(),
                found: None,
            })
        }
        Some(Value::Object(m)) => m,
        Some(_) => return Err(invalid(format!("{ST_METADATA} is not a JSON object"))),
    };
    let mut meta: BTreeMap<&str, &str> = BTreeMap::new();
    for (k, v) in st_meta {
        match v {
            Value::String(s) => {
                meta.insert(k, s);
            }
            _ => {
                return Err(invalid(format!(
                    "{ST_METADATA}.{k} is not a string (safetensors metadata values are strings)"
                )))
            }
        }
    }
    match meta.get(keys::FORMAT) {
        Some(&FORMAT_NAME) => {}
        other => {
            return Err(FormatError::WrongFormat {
                path: pathbuf(),
                found: other.map(|s| s.to_string()),
            })
        }
    }
    let version_str = meta
        .get(keys::SCHEMA_VERSION)
        .ok_or_else(|| invalid(format!("{ST_METADATA}.{} is missing", keys::SCHEMA_VERSION)))?;
    let schema_version: u32 = version_str.parse().map_err(|_| {
        invalid(format!(
            "{ST_METADATA}.{} is '{version_str}', not a non-negative integer",
            keys::SCHEMA_VERSION
        ))
    })?;
    if schema_version != SCHEMA_VERSION {
        return Err(FormatError::WrongVersion {
            path: pathbuf(),
            found: schema_version,
            expected: SCHEMA_VERSION,
        });
    }

    // Tensor table.
    struct Raw<'h> {
        name: &'h str,
        dtype: Dtype,
        shape: Vec<usize>,
        begin: usize,
        end: usize,
    }
    let mut raw: Vec<Raw<'_>> = Vec::with_capacity(header.len());
    for (name, info) in &header {
        if name == ST_METADATA {
            continue;
        }
        let bad = |reason: String| FormatError::InvalidTensor {
            path: pathbuf(),
            tensor: name.clone(),
            reason,
        };
        let info = info
            .as_object()
            .ok_or_else(|| bad("entry is not a JSON object".into()))?;
        let dtype_str = info
            .get("dtype")
            .and_then(Value::as_str)
            .ok_or_else(|| bad("missing or non-string 'dtype'".into()))?;
        let dtype = Dtype::from_name(dtype_str).ok_or_else(|| {
            bad(format!(
                "dtype '{dtype_str}' is not used by PRT bake files (expected one of {})",
                Dtype::ALL.map(Dtype::name).join(", ")
            ))
        })?;
        let shape = info
            .get("shape")
            .and_then(Value::as_array)
            .ok_or_else(|| bad("missing or non-array 'shape'".into()))?
            .iter()
            .map(|d| d.as_u64().and_then(|d| usize::try_from(d).ok()))
            .collect::<Option<Vec<usize>>>()
            .ok_or_else(|| bad("'shape' must hold non-negative integers".into()))?;
        let offsets = info
            .get("data_offsets")
            .and_then(Value::as_array)
            .and_then(|a| match a.as_slice() {
                [b, e] => Some((b.as_u64()?, e.as_u64()?)),
                _ => None,
            })
            .ok_or_else(|| {
                bad("'data_offsets' must be [begin, end] (non-negative integers)".into())
            })?;
        let (begin, end) = offsets;
        if begin > end {
            return Err(bad(format!("data_offsets [{begin}, {end}] run backwards")));
        }
        if end > data_len as u64 {
            return Err(FormatError::TensorOutOfBounds {
                path: pathbuf(),
                tensor: name.clone(),
                begin,
                end,
                data_len: data_len as u64,
            });
        }
        // Both offsets are <= data_len, so they fit in usize.
        let (begin, end) = (begin as usize, end as usize);
        let needed = shape
            .iter()
            .try_fold(dtype.size() as u128, |acc, &d| acc.checked_mul(d as u128));
        if needed != Some((end - begin) as u128) {
            return Err(bad(format!(
                "shape {shape:?} of {dtype} needs {} bytes, but data_offsets span {}",
                needed.map_or("too many".to_string(), |n| n.to_string()),
                end - begin
            )));
        }
        if name.starts_with(RESERVED_PREFIX)
            && (!name.starts_with(PAD_PREFIX) || dtype != Dtype::U8)
        {
            return Err(bad(
                "names starting with '__' are reserved (only U8 '__pad' padding is allowed)".into(),
            ));
        }
        raw.push(Raw {
            name,
            dtype,
            shape,
            begin,
            end,
        });
    }

    // The data section must be tiled exactly: no gaps (the safetensors spec forbids holes, which
    // keeps the file from hiding data), no overlaps, nothing after the last tensor.
    raw.sort_unstable_by_key(|r| (r.begin, r.end));
    let layout_err = |reason: String| FormatError::Layout {
        path: pathbuf(),
        reason,
    };
    let mut pos = 0usize;
    for r in &raw {
        if r.begin != pos {
            return Err(layout_err(if r.begin > pos {
                format!(
                    "gap of {} bytes before tensor '{}' (data bytes {pos}..{})",
                    r.begin - pos,
                    r.name,
                    r.begin
                )
            } else {
                format!(
                    "tensor '{}' (data bytes {}..{}) overlaps the previous tensor, which ends at {pos}",
                    r.name, r.begin, r.end
                )
            }));
        }
        pos = r.end;
    }
    if pos != data_len {
        return Err(layout_err(format!(
            "{} bytes after the last tensor (tensors end at data byte {pos}, the file has {data_len})",
            data_len - pos
        )));
    }

    // Checksums.
    let crc_str = meta
        .get(keys::CRC32)
        .ok_or_else(|| invalid(format!("{ST_METADATA}.{} is missing", keys::CRC32)))?;
    let crc_map: BTreeMap<String, String> = serde_json::from_str(crc_str).map_err(|e| {
        invalid(format!(
            "{ST_METADATA}.{} is not a JSON object of strings: {e}",
            keys::CRC32
        ))
    })?;
    let parse_hex = |what: &str, s: &str| {
        // Exactly the canonical spelling (8 lowercase hex digits), so that the stored text
        // has one form and any change to it is detected.
        if s.len() == 8 && s.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f')) {
            u32::from_str_radix(s, 16).ok()
        } else {
            None
        }
        .ok_or_else(|| invalid(format!("{what} '{s}' is not 8 lowercase hex digits")))
    };
    let stored_header_crc = meta
        .get(keys::HEADER_CRC32)
        .ok_or_else(|| invalid(format!("{ST_METADATA}.{} is missing", keys::HEADER_CRC32)))?;
    let stored_header_crc = parse_hex("header checksum", stored_header_crc)?;
    let actual = header_digest(
        meta.iter().map(|(k, v)| (*k, *v)),
        raw.iter()
            .map(|r| (r.name, r.dtype, r.shape.as_slice(), r.begin, r.end)),
    );
    if actual != stored_header_crc {
        return Err(FormatError::HeaderChecksumMismatch {
            path: pathbuf(),
            expected: stored_header_crc,
            actual,
        });
    }

    let mut tensors = Vec::with_capacity(raw.len());
    let mut pads = Vec::new();
    for r in raw {
        let (start, end) = (data_start + r.begin, data_start + r.end);
        if r.name.starts_with(PAD_PREFIX) {
            pads.push((r.name.to_string(), start, end));
            continue;
        }
        let crc = match crc_map.get(r.name) {
            Some(s) => parse_hex(&format!("checksum of tensor '{}'", r.name), s)?,
            None => {
                return Err(FormatError::MissingChecksum {
                    path: pathbuf(),
                    tensor: r.name.to_string(),
                })
            }
        };
        tensors.push(TensorEntry {
            name: r.name.to_string(),
            dtype: r.dtype,
            shape: r.shape,
            start,
            end,
            crc,
        });
    }
    if let Some(extra) = crc_map
        .keys()
        .find(|k| !tensors.iter().any(|t| &t.name == *k))
    {
        return Err(invalid(format!(
            "{ST_METADATA}.{} lists a checksum for '{extra}', which is not a tensor in the file",
            keys::CRC32
        )));
    }

    let metadata_str = meta
        .get(keys::METADATA)
        .ok_or_else(|| FormatError::BadMetadata {
            path: pathbuf(),
            reason: format!("{ST_METADATA}.{} is missing", keys::METADATA),
        })?;
    let metadata: Value =
        serde_json::from_str(metadata_str).map_err(|e| FormatError::BadMetadata {
            path: pathbuf(),
            reason: format!("not valid JSON: {e}"),
        })?;

    // Independent check with the reference parser: whatever we accept, Python must accept too.
    // It only reads the header (no data is touched).
    if let Err(e) = safetensors::SafeTensors::read_metadata(bytes) {
        return Err(invalid(format!("rejected by the safetensors parser: {e}")));
    }

    Ok(Parsed {
        schema_version,
        metadata,
        tensors,
        pads,
    })
}
