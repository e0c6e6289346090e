//! Reading glTF accessors (and buffer views) into flat arrays.
//!
//! We read accessors ourselves instead of through `gltf::mesh::Reader` because the crate's
//! reader trusts the file: a zero `count` underflows, a wrong accessor type trips a
//! `debug_assert`, a short sparse block `unwrap`s. Here every offset, stride and count is
//! checked with overflow-checked arithmetic against the bytes actually present, so malformed
//! input becomes an error and never a panic or a huge allocation.

use crate::scene::error::AccessorError;
use gltf::accessor::{sparse::IndexType, DataType, Dimensions};
use gltf::Accessor;

/// Accessors without a buffer view are all zeros; above this many elements we refuse rather
/// than allocate gigabytes because of one number in a small JSON file.
const MAX_VIRTUAL_ELEMENTS: usize = 1 << 26;

impl AccessorError {
    fn context(self, context: &str) -> AccessorError {
        AccessorError::In {
            context: context.to_owned(),
            source: Box::new(self),
        }
    }
}

/// The bytes of a buffer view, checked against its buffer.
pub(crate) fn view_bytes<'b>(
    view: &gltf::buffer::View,
    buffers: &'b [Vec<u8>],
) -> Result<&'b [u8], AccessorError> {
    let bi = view.buffer().index();
    let data = buffers.get(bi).ok_or(AccessorError::MissingBuffer {
        view: view.index(),
        buffer: bi,
    })?;
    let start = view.offset();
    let end = start
        .checked_add(view.length())
        .ok_or(AccessorError::ViewOverflow { view: view.index() })?;
    data.get(start..end).ok_or(AccessorError::ViewPastEnd {
        view: view.index(),
        start,
        end,
        buffer: bi,
        len: data.len(),
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
/// checks that they fit.
fn check_strided(
    bytes: &[u8],
    offset: usize,
    stride: usize,
    elem_size: usize,
    count: usize,
) -> Result<(), AccessorError> {
    if count == 0 {
        return Ok(());
    }
    let needed = (count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(elem_size))
        .and_then(|x| x.checked_add(offset))
        .ok_or(AccessorError::SizeOverflow)?;
    if needed > bytes.len() {
        return Err(AccessorError::TooShort {
            count,
            needed,
            len: bytes.len(),
        });
    }
    Ok(())
}

/// Reads an accessor as `count` elements of `comps` f32 components (flattened), applying
/// sparse substitution. `allowed` lists the component types accepted for this attribute as
/// `(type, must_be_normalized)`; `what` names the attribute in errors.
pub(crate) fn read_f32(
    acc: &Accessor,
    buffers: &[Vec<u8>],
    what: &'static str,
    comps: usize,
    allowed: &[(DataType, bool)],
) -> Result<Vec<f32>, AccessorError> {
    let dims = acc.dimensions();
    if dims.multiplicity() != comps {
        return Err(AccessorError::WrongType {
            what,
            accessor: acc.index(),
            found: type_name(dims),
            expected: format!("{comps} components"),
        });
    }
    let t = acc.data_type();
    let ok = allowed
        .iter()
        .any(|&(at, norm)| at == t && (!norm || acc.normalized()));
    if !ok {
        return Err(AccessorError::UnsupportedComponent {
            what,
            accessor: acc.index(),
            component: t,
            normalized: acc.normalized(),
        });
    }
    let norm = acc.normalized();
    read_generic(acc, buffers, what, comps, |b| decode_f32(b, t, norm), 0.0)
}

/// Reads a scalar unsigned-integer accessor (triangle indices).
pub(crate) fn read_indices(acc: &Accessor, buffers: &[Vec<u8>]) -> Result<Vec<u32>, AccessorError> {
    if acc.dimensions() != Dimensions::Scalar {
        return Err(AccessorError::WrongType {
            what: "index",
            accessor: acc.index(),
            found: type_name(acc.dimensions()),
            expected: "SCALAR".to_owned(),
        });
    }
    let t = acc.data_type();
    if !matches!(t, DataType::U8 | DataType::U16 | DataType::U32) {
        return Err(AccessorError::IndexComponent {
            accessor: acc.index(),
            component: t,
        });
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
) -> Result<Vec<T>, AccessorError> {
    let count = acc.count();
    let csize = component_size(acc.data_type());
    let elem_size = comps * csize;
    let label = format!("{what} accessor {}", acc.index());

    let mut out: Vec<T> = match acc.view() {
        Some(view) => {
            let bytes = view_bytes(&view, buffers).map_err(|e| e.context(&label))?;
            let stride = view.stride().unwrap_or(elem_size);
            if stride < elem_size {
                return Err(AccessorError::StrideTooSmall {
                    stride,
                    element: elem_size,
                }
                .context(&label));
            }
            check_strided(bytes, acc.offset(), stride, elem_size, count)
                .map_err(|e| e.context(&label))?;
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
                return Err(AccessorError::TooManyVirtual(count).context(&label));
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
        let idx_label = format!("{label} sparse indices");
        let ibytes = view_bytes(&idx.view(), buffers).map_err(|e| e.context(&idx_label))?;
        check_strided(ibytes, idx.offset(), isize_, isize_, n)
            .map_err(|e| e.context(&idx_label))?;
        let vals = sparse.values();
        let vals_label = format!("{label} sparse values");
        let vbytes = view_bytes(&vals.view(), buffers).map_err(|e| e.context(&vals_label))?;
        check_strided(vbytes, vals.offset(), elem_size, elem_size, n)
            .map_err(|e| e.context(&vals_label))?;
        for k in 0..n {
            let ia = idx.offset() + k * isize_;
            let target = decode_u32(&ibytes[ia..ia + isize_], idx_type) as usize;
            if target >= count {
                return Err(AccessorError::SparseIndexOutOfRange {
                    index: target,
                    count,
                }
                .context(&label));
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
    fn context_prefixes_the_message() {
        let e = AccessorError::StrideTooSmall {
            stride: 4,
            element: 12,
        }
        .context("POSITION accessor 2");
        assert_eq!(
            e.to_string(),
            "POSITION accessor 2: byteStride 4 is smaller than the element size 12"
        );
    }
}
