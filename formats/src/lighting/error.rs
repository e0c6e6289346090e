//! The one error type of the lighting bases: every refusal names what was wrong and the value.

/// Why a lighting-basis operation refused its input. The lighting functions validate what a
/// caller controls (sizes, lengths, finiteness, parameters) and return this instead of
/// panicking.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LightingError {
    /// A size that must be at least 1 (a cube-map side, a map's width or height) was 0.
    #[error("{what} must be at least 1, got 0")]
    ZeroSize {
        /// What the size is of.
        what: &'static str,
    },
    /// A size beyond what the module accepts (its product would overflow or exhaust memory).
    #[error("{what} {value} is too large (at most {max})")]
    TooLarge {
        /// What the size is of.
        what: &'static str,
        /// The size given.
        value: usize,
        /// The largest accepted.
        max: usize,
    },
    /// A size that must be a power of two (the Haar transform halves each face down to 1).
    #[error("{what} must be a power of two, got {value}")]
    NotPowerOfTwo {
        /// What the size is of.
        what: &'static str,
        /// The size given.
        value: usize,
    },
    /// A cube map with an odd side cannot be downsampled by 2.
    #[error("cannot halve a cube map of odd side {size}")]
    OddSize {
        /// The side of the cube map.
        size: usize,
    },
    /// A slice of the wrong length.
    #[error("{what}: expected {expected} values, got {got}")]
    LengthMismatch {
        /// What the slice holds.
        what: &'static str,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        got: usize,
    },
    /// A value that must be finite was NaN or infinite.
    #[error("{what}: value {index} is not finite ({value})")]
    NonFinite {
        /// What the slice holds.
        what: &'static str,
        /// Where in the slice (for a texel: the texel index; channels are not counted).
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// A scalar parameter outside its domain.
    #[error("{what} must be {expected}, got {value}")]
    InvalidParameter {
        /// The parameter.
        what: &'static str,
        /// The accepted domain, in words.
        expected: &'static str,
        /// The value given.
        value: f64,
    },
    /// A prefilter width too narrow for the map's texels to resolve.
    #[error(
        "Gaussian width {sigma} rad is too narrow for a cube map of side {size} \
         (its texels are {pitch} rad apart; the width must be at least {min} rad, or 0 for no \
         filtering)"
    )]
    WidthTooNarrow {
        /// The width given (radians).
        sigma: f64,
        /// The input cube map's side.
        size: usize,
        /// The input's texel pitch at a face centre, `2 / size` radians.
        pitch: f64,
        /// The narrowest accepted width (radians).
        min: f64,
    },
    /// A 3x3 matrix that is not a rotation (not orthonormal within tolerance, or a reflection).
    #[error("not a rotation matrix: {reason} (deviation {deviation:e})")]
    NotARotation {
        /// Which property failed.
        reason: &'static str,
        /// How far from it the matrix is.
        deviation: f64,
    },
    /// A sparse vector whose indices are not strictly increasing or reach past its length.
    #[error("sparse vector of length {len}: index {index} at position {position} is {problem}")]
    BadSparseIndex {
        /// The dense length of the vector.
        len: usize,
        /// The position in the index list.
        position: usize,
        /// The index found there.
        index: u32,
        /// What is wrong with it.
        problem: &'static str,
    },
    /// Two vectors of different dense lengths in a dot product.
    #[error("dot product of vectors of different lengths ({left} and {right})")]
    DimensionMismatch {
        /// The dense length of the left operand.
        left: usize,
        /// The dense length of the right operand.
        right: usize,
    },
}
