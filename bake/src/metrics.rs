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

#[cfg(test)]
mod tests {
    use super::{relative_l2, rmse};

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
}
