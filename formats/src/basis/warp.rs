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

/// Linear interpolation weights over the parameter samples: `(1 - t) row[j0] + t row[j1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamWeights {
    /// Lower sample.
    pub j0: usize,
    /// Upper sample (`j0` when there is one sample).
    pub j1: usize,
    /// Fraction of the way from `j0` to `j1` in the warped parameter, in `[0, 1]`.
    pub t: f32,
}

impl ParamWarp {
    /// The interpolation weights of parameter `p` over the increasing, non-empty `samples`,
    /// linear in the warped parameter (the one rule of both persisted bases); the flag is true
    /// when `p` was outside the sampled range (or NaN) and was clamped to it.
    #[inline]
    pub fn weights(self, samples: &[f32], p: f32) -> (ParamWeights, bool) {
        let (lo, hi) = (samples[0], samples[samples.len() - 1]);
        let clamped = !(p >= lo && p <= hi);
        let p = if p.is_nan() { lo } else { p.clamp(lo, hi) };
        if samples.len() == 1 {
            return (
                ParamWeights {
                    j0: 0,
                    j1: 0,
                    t: 0.0,
                },
                clamped,
            );
        }
        // samples[j0] <= p < samples[j0 + 1], the last interval for p = hi
        let j0 = samples
            .partition_point(|&x| x <= p)
            .saturating_sub(1)
            .min(samples.len() - 2);
        let u0 = self.apply_f32(samples[j0]);
        let u1 = self.apply_f32(samples[j0 + 1]);
        let u = self.apply_f32(p);
        let t = if u1 > u0 {
            ((u - u0) / (u1 - u0)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (ParamWeights { j0, j1: j0 + 1, t }, clamped)
    }
}
