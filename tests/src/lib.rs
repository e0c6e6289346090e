//! Cross-crate regression tests live in `tests/tests/`.
