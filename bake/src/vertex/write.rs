//! Storage precision of the per-vertex bake's values: f16 with a per-group, per-tensor scale
//! (the per-pixel writer's rule: the largest magnitude maps to 2^14), or f32. The file itself
//! is written from the units' pieces by `assemble.rs`.

use prt_formats::pixel::Precision;

/// Bytes of one stored T0 value, T1 or T2 value.
pub(crate) fn value_bytes(p: Precision) -> usize {
    match p {
        Precision::F32 => 4,
        Precision::F16 => 2,
    }
}
