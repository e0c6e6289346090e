//! Exact quadratures for the spherical-harmonic mathematics: Gauss–Legendre nodes on [-1, 1]
//! and the product rule on the sphere (Gauss–Legendre in `z = cos theta` times uniform
//! azimuths), exact for polynomials in `(x, y, z)` up to a chosen degree.

use std::f64::consts::PI;

/// The nodes and weights of the `n`-point Gauss–Legendre rule on `[-1, 1]`, exact for
/// polynomials of degree `2n - 1`; nodes ascending. `n = 0` gives empty lists.
///
/// Newton's iteration on the Legendre polynomial from Chebyshev starting points, in f64; the
/// nodes are accurate to a few ulps for the sizes used here (n up to a few hundred).
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    let nf = n as f64;
    // Roots come in +- pairs: find the positive half and mirror it.
    for i in 0..n.div_ceil(2) {
        let mut x = (PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (p, d) = legendre_and_derivative(n, x);
            dp = d;
            let dx = p / d;
            x -= dx;
            if dx.abs() <= 1e-16 * x.abs().max(1.0) {
                break;
            }
        }
        // Re-evaluate the derivative at the converged root for the weight.
        let (_, d) = legendre_and_derivative(n, x);
        if d.is_finite() && d != 0.0 {
            dp = d;
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        nodes[i] = -x;
        nodes[n - 1 - i] = x;
        weights[i] = w;
        weights[n - 1 - i] = w;
    }
    if n % 2 == 1 {
        nodes[n / 2] = 0.0;
    }
    (nodes, weights)
}

/// `P_n(x)` and `P_n'(x)` by the three-term recurrence.
fn legendre_and_derivative(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    if n == 0 {
        return (1.0, 0.0);
    }
    for k in 2..=n {
        let kf = k as f64;
        let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
        p0 = p1;
        p1 = p2;
    }
    let d = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, d)
}

/// A quadrature on the unit sphere that integrates every polynomial in `(x, y, z)` of total
/// degree at most `degree` exactly (to rounding): `degree / 2 + 1` Gauss–Legendre nodes in
/// `z` times `degree + 1` uniform azimuths. Returns `(direction, weight)` pairs; the weights
/// sum to 4 pi.
///
/// Why it is exact: a monomial `x^a y^b z^c` is `sin^(a+b) theta cos^a phi sin^b phi z^c`. The
/// uniform azimuth rule with `M > a + b` points integrates its trigonometric polynomial in
/// phi exactly; when `a + b` is odd that integral is 0, and when it is even
/// `sin^(a+b) theta = (1 - z^2)^((a+b)/2)` is a polynomial in z of degree at most `degree`,
/// which Gauss–Legendre integrates exactly.
pub fn sphere_rule(degree: usize) -> Vec<([f64; 3], f64)> {
    let (zs, wz) = gauss_legendre(degree / 2 + 1);
    let m = degree + 1;
    let mut out = Vec::with_capacity(zs.len() * m);
    for (&z, &w) in zs.iter().zip(&wz) {
        let r = (1.0 - z * z).max(0.0).sqrt();
        for k in 0..m {
            // Offset by half a step so that no node sits on the seam (any offset is exact).
            let phi = 2.0 * PI * (k as f64 + 0.5) / m as f64;
            out.push(([r * phi.cos(), r * phi.sin(), z], w * 2.0 * PI / m as f64));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_monomials_exactly() {
        for n in 1..=12 {
            let (x, w) = gauss_legendre(n);
            for p in 0..2 * n {
                let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(p as i32)).sum();
                let exact = if p % 2 == 1 {
                    0.0
                } else {
                    2.0 / (p as f64 + 1.0)
                };
                assert!((q - exact).abs() < 1e-14, "n {n} p {p}: {q} vs {exact}");
            }
            // ... and not one degree beyond (the error of x^(2n) is 2^(2n+1) (n!)^4 /
            // ((2n+1) ((2n)!)^2), 1.8e-7 for n = 12), so the test above has teeth.
            let p = 2 * n;
            let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(p as i32)).sum();
            assert!((q - 2.0 / (p as f64 + 1.0)).abs() > 1e-10, "n {n}");
        }
        assert_eq!(gauss_legendre(0), (vec![], vec![]));
    }

    #[test]
    fn sphere_rule_integrates_monomials_exactly() {
        // The integral of x^a y^b z^c over the sphere: 0 unless all even, else
        // 2 G(a') G(b') G(c') / G(a' + b' + c') with a' = (a + 1) / 2 and G the gamma function,
        // written with double factorials: 4 pi (a-1)!! (b-1)!! (c-1)!! / (a+b+c+1)!!.
        fn dfact(k: i64) -> f64 {
            if k <= 0 {
                1.0
            } else {
                (k as f64) * dfact(k - 2)
            }
        }
        let rule = sphere_rule(6);
        for a in 0..=6i64 {
            for b in 0..=6 - a {
                for c in 0..=6 - a - b {
                    let q: f64 = rule
                        .iter()
                        .map(|(d, w)| {
                            w * d[0].powi(a as i32) * d[1].powi(b as i32) * d[2].powi(c as i32)
                        })
                        .sum();
                    let exact = if a % 2 == 1 || b % 2 == 1 || c % 2 == 1 {
                        0.0
                    } else {
                        4.0 * PI * dfact(a - 1) * dfact(b - 1) * dfact(c - 1) / dfact(a + b + c + 1)
                    };
                    assert!((q - exact).abs() < 1e-13, "{a} {b} {c}: {q} vs {exact}");
                }
            }
        }
    }
}
