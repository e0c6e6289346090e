//! [`ParamWarp`]: the warp of the lobe parameter in which coefficients are interpolated.

use serde::{Deserialize, Serialize};

/// How the lobe parameter is warped before coefficients are interpolated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum ParamWarp {
    /// `u = p`
    Linear,
    /// `u = ln(p + offset)`
    Log {
        /// Added to the parameter before the logarithm; `p + offset` must stay positive over
        /// the sampled range.
        offset: f32,
    },
}

impl ParamWarp {
    /// The warped parameter `u = warp(p)` (f64, the baker's precision).
    #[inline]
    pub fn apply(self, p: f64) -> f64 {
        match self {
            ParamWarp::Linear => p,
            ParamWarp::Log { offset } => (p + offset as f64).max(1e-300).ln(),
        }
    }

    /// [`ParamWarp::apply`] in f32 (the runtime's interpolation).
    #[inline]
    pub fn apply_f32(self, p: f32) -> f32 {
        match self {
            ParamWarp::Linear => p,
            ParamWarp::Log { offset } => (p + offset).max(f32::MIN_POSITIVE).ln(),
        }
    }

    /// The parameter `p` whose warp is `u` (the inverse of [`ParamWarp::apply`]).
    #[inline]
    pub fn invert(self, u: f64) -> f64 {
        match self {
            ParamWarp::Linear => u,
            ParamWarp::Log { offset } => u.exp() - offset as f64,
        }
    }
}
