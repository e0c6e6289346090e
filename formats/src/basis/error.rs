//! [`BasisError`]: why a deserialized basis was refused.

/// Errors found when validating a deserialized basis.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BasisError {
    /// The basis has a schema version other than [`super::BASIS_SCHEMA_VERSION`].
    #[error("unsupported BRDF basis schema version {found} (this build reads {expected})")]
    Version {
        /// The version stored in the basis.
        found: u32,
        /// The version this build reads.
        expected: u32,
    },
    /// A table has the wrong number of values for the grid, basis count or parameter samples.
    #[error("BRDF basis field `{field}` has {found} values, expected {expected}")]
    Shape {
        /// Name of the field (`tables` or `coefficients`).
        field: &'static str,
        /// Number of values it has.
        found: usize,
        /// Number of values the other fields imply.
        expected: usize,
    },
    /// Any other broken invariant (grid too small, unordered samples, non-finite values, ...),
    /// described in words.
    #[error("BRDF basis is invalid: {0}")]
    Invalid(String),
}
