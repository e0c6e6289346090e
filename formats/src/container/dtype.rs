//! Element types of tensors: [`Dtype`] (the safetensors spelling) and [`Element`] (the Rust
//! types that may be viewed zero-copy as tensor data).

use std::borrow::Cow;

/// Element types a bake file may hold (spelled as in safetensors).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Dtype {
    /// IEEE 754 binary32 (`f32`).
    F32,
    /// IEEE 754 binary16 (`half::f16`).
    F16,
    /// Unsigned 32-bit integer.
    U32,
    /// Unsigned 16-bit integer.
    U16,
    /// Unsigned byte (also the dtype of padding tensors).
    U8,
    /// Signed 32-bit integer (two's complement).
    I32,
}

impl Dtype {
    /// Every dtype a bake file may hold, in the order error messages list them.
    pub const ALL: [Dtype; 6] = [
        Dtype::F32,
        Dtype::F16,
        Dtype::U32,
        Dtype::U16,
        Dtype::U8,
        Dtype::I32,
    ];

    /// Size of one element in bytes.
    pub const fn size(self) -> usize {
        match self {
            Dtype::F32 | Dtype::U32 | Dtype::I32 => 4,
            Dtype::F16 | Dtype::U16 => 2,
            Dtype::U8 => 1,
        }
    }

    /// The safetensors spelling ("F32", ...).
    pub const fn name(self) -> &'static str {
        match self {
            Dtype::F32 => "F32",
            Dtype::F16 => "F16",
            Dtype::U32 => "U32",
            Dtype::U16 => "U16",
            Dtype::U8 => "U8",
            Dtype::I32 => "I32",
        }
    }

    /// Parses the safetensors spelling; `None` for dtypes bake files do not use.
    pub fn from_name(name: &str) -> Option<Dtype> {
        Dtype::ALL.into_iter().find(|d| d.name() == name)
    }
}

impl std::fmt::Display for Dtype {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

mod sealed {
    pub trait Sealed {}
}

/// Rust types that can be viewed zero-copy as tensor elements.
///
/// Sealed: the zero-copy casts of the container (`element_bytes` here and
/// [`TensorView::as_slice`](super::TensorView::as_slice)) are sound only because every
/// implementor is a plain number type (or `repr(transparent)` over one) with no padding and no
/// invalid bit patterns, whose size equals `DTYPE.size()`.
pub trait Element: sealed::Sealed + Copy + 'static {
    /// The dtype whose elements this type reads and writes.
    const DTYPE: Dtype;
    /// Appends the little-endian bytes of `values` (used on big-endian hosts only).
    fn extend_le_bytes(values: &[Self], out: &mut Vec<u8>);
}

macro_rules! impl_element {
    ($($t:ty => $d:ident),* $(,)?) => {$(
        impl sealed::Sealed for $t {}
        impl Element for $t {
            const DTYPE: Dtype = Dtype::$d;
            fn extend_le_bytes(values: &[Self], out: &mut Vec<u8>) {
                for v in values {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
    )*};
}

impl_element!(f32 => F32, half::f16 => F16, u32 => U32, u16 => U16, u8 => U8, i32 => I32);

/// Little-endian bytes of a typed slice: a borrowed reinterpretation on little-endian hosts
/// (no copy), a converted copy on big-endian ones.
pub fn element_bytes<T: Element>(data: &[T]) -> Cow<'_, [u8]> {
    if cfg!(target_endian = "little") {
        // SAFETY: `T` is a sealed plain number type without padding (see `Element`), so its
        // memory is `size_of_val(data)` initialized bytes; `u8` has alignment 1, and the
        // returned slice borrows `data`, so it cannot outlive it.
        let bytes = unsafe {
            std::slice::from_raw_parts(data.as_ptr().cast::<u8>(), std::mem::size_of_val(data))
        };
        Cow::Borrowed(bytes)
    } else {
        let mut out = Vec::with_capacity(std::mem::size_of_val(data));
        T::extend_le_bytes(data, &mut out);
        Cow::Owned(out)
    }
}
