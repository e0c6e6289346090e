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
    /// A shading basis has a schema version other than [`super::SHADING_SCHEMA_VERSION`].
    #[error("unsupported shading basis schema version {found} (this build reads {expected})")]
    ShadingVersion {
        /// The version stored in the basis.
        found: u32,
        /// The version this build reads.
        expected: u32,
    },
    /// The family has no specular lobe (diffuse), so there is nothing to decompose.
    #[error("the {family} family has no specular lobe for a shading basis")]
    NoLobe {
        /// The family's name.
        family: &'static str,
    },
    /// A hemisphere grid outside the accepted sizes.
    #[error(
        "hemisphere grid {n_theta}x{n_phi} is invalid: it needs n_theta >= 2, n_phi >= 3 and at \
         most {max} directions",
        max = super::MAX_HEMI_DIRS
    )]
    HemiGrid {
        /// Rings.
        n_theta: usize,
        /// Azimuths per ring.
        n_phi: usize,
    },
    /// A Tucker rank of zero, above [`super::MAX_SHADING_RANK`] or above its mode's size.
    #[error("shading basis rank {rank} of mode {mode} is outside 1..={max}")]
    Rank {
        /// The mode (`h`, `o` or `i`).
        mode: &'static str,
        /// The rank asked for or stored.
        rank: usize,
        /// The largest rank allowed for that mode.
        max: usize,
    },
    /// A list that must not be empty is.
    #[error("shading basis field `{field}` is empty")]
    Empty {
        /// The field.
        field: &'static str,
    },
    /// A list longer than the format allows.
    #[error("shading basis field `{field}` has {found} entries, at most {max} are allowed")]
    TooMany {
        /// The field.
        field: &'static str,
        /// How many it has.
        found: usize,
        /// The most allowed.
        max: usize,
    },
    /// A NaN or infinite value.
    #[error("shading basis field `{field}` has a non-finite value at index {index}")]
    NonFinite {
        /// The field.
        field: &'static str,
        /// Index of the first bad value.
        index: usize,
    },
    /// A negative value where only nonnegative ones make sense (reflectances).
    #[error("shading basis field `{field}` has a negative value at index {index}")]
    Negative {
        /// The field.
        field: &'static str,
        /// Index of the first bad value.
        index: usize,
    },
    /// Values that must increase strictly do not.
    #[error("shading basis field `{field}` does not increase strictly at index {index}")]
    NotIncreasing {
        /// The field.
        field: &'static str,
        /// Index of the first value not above its predecessor.
        index: usize,
    },
    /// `param_range` is not `[first sample, last sample]`.
    #[error("parameter range [{range0}, {range1}] differs from the samples' [{first}, {last}]",
        range0 = range[0], range1 = range[1])]
    ParamRange {
        /// The stored range.
        range: [f32; 2],
        /// First parameter sample.
        first: f32,
        /// Last parameter sample.
        last: f32,
    },
    /// A logarithmic warp whose argument is not positive over the sampled range.
    #[error(
        "log warp with offset {offset} needs param + offset > 0, but the first sample is {first}"
    )]
    LogWarp {
        /// The warp's offset.
        offset: f32,
        /// The first parameter sample.
        first: f32,
    },
    /// A split width that is not finite, negative, not below 90 degrees or not above the
    /// previous one.
    #[error(
        "split width {value} degrees at index {index} is invalid (finite, in [0, 90), increasing)"
    )]
    SplitWidth {
        /// Index of the width.
        index: usize,
        /// Its value in degrees.
        value: f32,
    },
}
