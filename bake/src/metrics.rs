//! Image error measures shared by the CLI, the tests and the reports.

/// Relative L2 error `||a - b|| / ||b||` over all pixels and channels. NaN when the images
/// differ in size or are empty (a truncated image must not score as a small error).
pub fn relative_l2(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    if a.len() != b.len() || a.is_empty() {
        return f64::NAN;
    }
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(b) {
        for c in 0..3 {
            let d = (x[c] - y[c]) as f64;
            num += d * d;
            den += (y[c] as f64).powi(2);
        }
    }
    (num / den.max(1e-300)).sqrt()
}

/// Root-mean-square difference over all pixels and channels (radiance units). NaN when the
/// images differ in size or are empty.
pub fn rmse(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    if a.len() != b.len() || a.is_empty() {
        return f64::NAN;
    }
    let n = (a.len() * 3) as f64;
    let s: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (0..3).map(|c| ((x[c] - y[c]) as f64).powi(2)).sum::<f64>())
        .sum();
    (s / n).sqrt()
}

/// The mean of `a - b` over the pixels and its standard error, per channel and for the
/// pixels' channel averages (the last entry): how far apart two images are on average, in
/// units of the noise their pixel-to-pixel spread shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanDifference {
    /// Mean of `a - b` per channel (R, G, B) and of the channel average.
    pub mean: [f64; 4],
    /// Standard error of each mean: the sample standard deviation of the per-pixel
    /// differences over the square root of the pixel count.
    pub standard_error: [f64; 4],
}

impl MeanDifference {
    /// Each mean in standard errors (`mean / standard_error`; 0 when both are 0, infinite when
    /// only the error is).
    pub fn z(&self) -> [f64; 4] {
        std::array::from_fn(|c| match (self.mean[c], self.standard_error[c]) {
            (0.0, _) => 0.0,
            (m, se) => m / se,
        })
    }
}

/// The mean difference of `a` and `b` and its standard error. The pixels' differences are
/// taken as independent samples, which they are for Monte Carlo renders whose pixels own their
/// random streams (a relit bake and the reference tracer); a difference with structure (an
/// edge moved, a bias in one material) spreads them too and so shows as fewer standard errors
/// than a uniform bias of the same mean. NaN when the images differ in size or have fewer
/// than two pixels.
pub fn mean_difference(a: &[[f32; 3]], b: &[[f32; 3]]) -> MeanDifference {
    if a.len() != b.len() || a.len() < 2 {
        return MeanDifference {
            mean: [f64::NAN; 4],
            standard_error: [f64::NAN; 4],
        };
    }
    let n = a.len() as f64;
    let diff = |x: &[f32; 3], y: &[f32; 3]| -> [f64; 4] {
        let d: [f64; 3] = std::array::from_fn(|c| f64::from(x[c]) - f64::from(y[c]));
        [d[0], d[1], d[2], (d[0] + d[1] + d[2]) / 3.0]
    };
    let mut mean = [0.0f64; 4];
    for (x, y) in a.iter().zip(b) {
        for (m, d) in mean.iter_mut().zip(diff(x, y)) {
            *m += d;
        }
    }
    mean = mean.map(|m| m / n);
    // Two passes: the spread around the mean, not sum(d^2) - n mean^2, which cancels.
    let mut squares = [0.0f64; 4];
    for (x, y) in a.iter().zip(b) {
        for ((s, d), m) in squares.iter_mut().zip(diff(x, y)).zip(mean) {
            *s += (d - m) * (d - m);
        }
    }
    MeanDifference {
        mean,
        standard_error: squares.map(|s| (s / (n - 1.0) / n).sqrt()),
    }
}

/// An error over part of an image (a region: [`crate::view::first_hit_materials`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionError {
    /// Pixels in the region.
    pub pixels: usize,
    /// `||a - b|| / ||b||` over the region's pixels and channels.
    pub relative_l2: f64,
    /// The region's mean of `a` over its mean of `b` (channels added): a bias shows as a
    /// ratio away from 1 however the error is spread.
    pub mean_ratio: f64,
    /// The region's `||a - b||^2` over the whole image's `||b||^2`: the regions' shares add
    /// up to the whole image's squared relative L2.
    pub squared_share: f64,
}

/// The error of `a` against `b` over the pixels where `inside` is true. NaN figures when the
/// images or the mask differ in size, or the region is empty.
pub fn region_error(a: &[[f32; 3]], b: &[[f32; 3]], inside: &[bool]) -> RegionError {
    let nan = RegionError {
        pixels: 0,
        relative_l2: f64::NAN,
        mean_ratio: f64::NAN,
        squared_share: f64::NAN,
    };
    if a.len() != b.len() || a.len() != inside.len() {
        return nan;
    }
    let (mut num, mut den, mut sa, mut sb, mut all, mut n) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0);
    for ((x, y), &m) in a.iter().zip(b).zip(inside) {
        for c in 0..3 {
            let (x, y) = (f64::from(x[c]), f64::from(y[c]));
            all += y * y;
            if m {
                num += (x - y) * (x - y);
                den += y * y;
                sa += x;
                sb += y;
            }
        }
        n += usize::from(m);
    }
    if n == 0 {
        return nan;
    }
    RegionError {
        pixels: n,
        relative_l2: (num / den.max(1e-300)).sqrt(),
        mean_ratio: sa / sb,
        squared_share: num / all.max(1e-300),
    }
}

#[cfg(test)]
mod tests {
    use super::{mean_difference, region_error, relative_l2, rmse};

    #[test]
    fn error_measures() {
        let b = [[1.0f32, 2.0, 2.0], [0.0, 0.0, 0.0]];
        let a = [[1.0f32, 2.0, 3.0], [0.0, 0.0, 0.0]];
        assert!((relative_l2(&a, &b) - 1.0 / 3.0).abs() < 1e-12);
        assert!((rmse(&a, &b) - (1.0f64 / 6.0).sqrt()).abs() < 1e-12);
        assert_eq!(relative_l2(&b, &b), 0.0);
        // A truncated or empty image is no small error.
        assert!(relative_l2(&a[..1], &b).is_nan() && rmse(&a[..1], &b).is_nan());
        assert!(relative_l2(&[], &[]).is_nan() && rmse(&[], &[]).is_nan());
    }

    #[test]
    fn mean_difference_in_standard_errors() {
        // Differences 1, 3 (R), 0, 0 (G), -2, -2 (B): means 2, 0, -2; channel averages -1/3
        // and 1/3, mean 0.
        let b = [[1.0f32, 1.0, 3.0], [1.0, 1.0, 3.0]];
        let a = [[2.0f32, 1.0, 1.0], [4.0, 1.0, 1.0]];
        let m = mean_difference(&a, &b);
        assert_eq!(m.mean[..3], [2.0, 0.0, -2.0]);
        assert!(m.mean[3].abs() < 1e-15);
        // Sample standard deviation of (1, 3) is sqrt(2); over sqrt(2) pixels: 1.
        assert!((m.standard_error[0] - 1.0).abs() < 1e-12);
        assert_eq!(m.standard_error[1..3], [0.0, 0.0]);
        assert!((m.standard_error[3] - 1.0 / 3.0).abs() < 1e-12);
        let z = m.z();
        assert!((z[0] - 2.0).abs() < 1e-12);
        assert_eq!(z[1], 0.0);
        assert_eq!(z[2], f64::NEG_INFINITY);
        // A truncated or single-pixel image is no measurement.
        assert!(mean_difference(&a[..1], &b).mean[0].is_nan());
        assert!(mean_difference(&a[..1], &b[..1]).standard_error[0].is_nan());
    }

    #[test]
    fn region_errors_add_up_to_the_image() {
        let b = [[1.0f32, 1.0, 1.0], [2.0, 2.0, 2.0], [0.5, 0.5, 0.5]];
        let a = [[1.1f32, 1.1, 1.1], [1.0, 1.0, 1.0], [0.5, 0.5, 0.5]];
        let m = [true, false, true];
        let inside = region_error(&a, &b, &m);
        let outside = region_error(&a, &b, &m.map(|x| !x));
        assert_eq!((inside.pixels, outside.pixels), (2, 1));
        assert!((outside.mean_ratio - 0.5).abs() < 1e-12);
        assert!((inside.mean_ratio - 1.6 / 1.5).abs() < 1e-6);
        let whole = relative_l2(&a, &b);
        assert!((inside.squared_share + outside.squared_share - whole * whole).abs() < 1e-9);
        assert!((outside.relative_l2 - 0.5).abs() < 1e-12);
        assert!(region_error(&a, &b, &[true]).relative_l2.is_nan());
        assert!(region_error(&a, &b, &[false; 3]).mean_ratio.is_nan());
    }
}
