//! The canonical header digest whose CRC-32 is stored as `header_crc32` (see
//! `docs/format.md`, "Header checksum").

use super::{keys, Dtype};

/// Domain separator of the header digest; changing the digest definition means changing this.
const HEADER_DIGEST_TAG: &[u8] = b"prt-bake header digest v1\0";

/// CRC-32 of the canonical header digest (see `docs/format.md`, "Header checksum"): every
/// `__metadata__` entry except `header_crc32` in key order, then every tensor (padding included)
/// in name order. Strings are length-prefixed and numbers are u64 LE, so the encoding is
/// unambiguous.
pub(super) fn header_digest<'s>(
    meta: impl Iterator<Item = (&'s str, &'s str)>,
    tensors: impl Iterator<Item = (&'s str, Dtype, &'s [usize], usize, usize)>,
) -> u32 {
    fn put_u64(h: &mut crc32fast::Hasher, v: u64) {
        h.update(&v.to_le_bytes());
    }
    fn put_str(h: &mut crc32fast::Hasher, s: &str) {
        put_u64(h, s.len() as u64);
        h.update(s.as_bytes());
    }
    let mut h = crc32fast::Hasher::new();
    h.update(HEADER_DIGEST_TAG);
    let mut meta: Vec<_> = meta.filter(|(k, _)| *k != keys::HEADER_CRC32).collect();
    meta.sort_unstable();
    put_u64(&mut h, meta.len() as u64);
    for (k, v) in meta {
        put_str(&mut h, k);
        put_str(&mut h, v);
    }
    let mut tensors: Vec<_> = tensors.collect();
    tensors.sort_unstable_by(|a, b| a.0.cmp(b.0));
    put_u64(&mut h, tensors.len() as u64);
    for (name, dtype, shape, begin, end) in tensors {
        put_str(&mut h, name);
        put_str(&mut h, dtype.name());
        put_u64(&mut h, shape.len() as u64);
        for &d in shape {
            put_u64(&mut h, d as u64);
        }
        put_u64(&mut h, begin as u64);
        put_u64(&mut h, end as u64);
    }
    h.finalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::container::Dtype;

    #[test]
    fn header_digest_depends_on_every_field() {
        let base = || {
            header_digest(
                [("format", "prt-bake"), ("metadata", "{}")].into_iter(),
                [("a", Dtype::F32, &[2usize][..], 0usize, 8usize)].into_iter(),
            )
        };
        let d0 = base();
        assert_eq!(d0, base());
        let d1 = header_digest(
            [("format", "prt-bake"), ("metadata", "{ }")].into_iter(),
            [("a", Dtype::F32, &[2usize][..], 0usize, 8usize)].into_iter(),
        );
        let d2 = header_digest(
            [("format", "prt-bake"), ("metadata", "{}")].into_iter(),
            [("a", Dtype::U32, &[2usize][..], 0usize, 8usize)].into_iter(),
        );
        // header_crc32 itself is excluded.
        let d3 = header_digest(
            [
                ("format", "prt-bake"),
                ("metadata", "{}"),
                ("header_crc32", "x"),
            ]
            .into_iter(),
            [("a", Dtype::F32, &[2usize][..], 0usize, 8usize)].into_iter(),
        );
        assert_ne!(d0, d1);
        assert_ne!(d0, d2);
        assert_eq!(d0, d3);
    }
}
