//! BRDF family properties (docs/brdf.md): non-negativity, reciprocity, directional albedo,
//! sampling densities (normalization and histogram of sampled directions).

use glam::Vec3;
use prt_bake::brdf::{BrdfParams, Family};
use prt_bake::sampling::Rng;
use prt_bake::testing::albedo;
use std::f64::consts::PI;

/// The project's one random generator (PCG), one stream per test.
fn rng(seed: u64) -> Rng {
    Rng::for_sample(seed, 0, 0)
}

/// Uniform direction on the upper hemisphere.
fn hemi(rng: &mut Rng) -> Vec3 {
    let z = rng.next_f32().max(1e-4);
    let r = (1.0 - z * z).max(0.0).sqrt();
    let p = 2.0 * std::f32::consts::PI * rng.next_f32();
    Vec3::new(r * p.cos(), r * p.sin(), z)
}

fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

fn spec(family: Family, kd: f32, ks: f32, param: f32) -> BrdfParams {
    BrdfParams {
        family,
        kd: Vec3::splat(kd),
        ks: Vec3::splat(ks),
        param,
    }
}

fn all_params() -> Vec<BrdfParams> {
    let mut v = vec![BrdfParams::diffuse(Vec3::new(0.2, 0.5, 0.8))];
    for s in [0.0, 1.0, 10.0, 200.0, 2000.0] {
        v.push(spec(Family::BlinnPhong, 0.3, 0.7, s));
    }
    for a in [0.01, 0.05, 0.2, 0.5, 1.0] {
        v.push(spec(Family::Ggx, 0.3, 0.7, a));
    }
    v
}

#[test]
fn non_negative_and_finite() {
    let mut rng = rng(1);
    for b in all_params() {
        for _ in 0..20_000 {
            let (wo, wi) = (hemi(&mut rng), hemi(&mut rng));
            let f = b.eval(wo, wi);
            assert!(
                f.is_finite() && f.min_element() >= 0.0,
                "{b:?} {wo} {wi} -> {f}"
            );
        }
        // grazing and mirror configurations
        for t in [0.0f32, 45.0, 89.0, 89.99, 90.0] {
            let wo = dir(t, 0.0);
            let wi = dir(t, 180.0);
            let f = b.eval(wo, wi);
            assert!(
                f.is_finite() && f.min_element() >= 0.0,
                "{b:?} theta {t} -> {f}"
            );
        }
        // below the horizon: zero
        assert_eq!(
            b.eval(dir(30.0, 0.0), Vec3::new(0.0, 0.0, -1.0)),
            Vec3::ZERO
        );
    }
}

#[test]
fn reciprocity() {
    let mut rng = rng(2);
    for b in all_params() {
        for _ in 0..20_000 {
            let (wo, wi) = (hemi(&mut rng), hemi(&mut rng));
            let (f1, f2) = (b.eval(wo, wi), b.eval(wi, wo));
            let d = (f1 - f2).abs().max_element();
            assert!(
                d <= 1e-5 * f1.max_element().max(1e-6),
                "{b:?}: {f1} vs {f2}"
            );
        }
    }
}

/// Nodes per axis of the independent albedo quadrature (`prt_bake::testing::albedo`):
/// converged to about 1e-5 for the lobes and angles below (`albedo_quadrature_is_exact`).
const QUAD: usize = 512;

/// Directional albedo of the Blinn-Phong lobe (Ks = 1, Kd = 0) by the independent quadrature.
fn bp_albedo(s: f64, theta_o: f64) -> f64 {
    albedo::blinn_phong(s, theta_o.cos(), QUAD)
}

/// Largest Blinn-Phong lobe albedo over outgoing directions (docs/brdf.md), on a coarser
/// rule (it only sizes Ks; about 1e-4 off).
fn bp_max_albedo(s: f64) -> f64 {
    (0..=18)
        .map(|k| albedo::blinn_phong(s, (k as f64 * 5.0).min(89.0).to_radians().cos(), 128))
        .fold(0.0, f64::max)
}

/// Monte Carlo albedo with the BRDF's own sampler, E[f cos / pdf] (first channel), and the
/// standard error of that mean from the samples' variance (a sample the sampler refuses
/// counts as 0).
fn mc_albedo(b: &BrdfParams, wo: Vec3, n: usize, rng: &mut Rng) -> (f64, f64) {
    let (mut sum, mut sum2) = (0.0, 0.0);
    for _ in 0..n {
        let u = rng.next_vec2();
        if let Some(smp) = b.sample(wo, u) {
            let f = b.eval(wo, smp.wi).x as f64;
            let x = f * smp.wi.z as f64 / smp.pdf as f64;
            sum += x;
            sum2 += x * x;
        }
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(0.0) * n as f64 / (n - 1) as f64;
    (mean, (var / n as f64).sqrt())
}

/// The code's BRDF evaluation (first channel) integrated on the quadrature's own nodes: it
/// differs from the independent formula's integral only by f32 rounding.
fn eval_albedo(b: &BrdfParams, width: f64, cos_o: f64) -> f64 {
    albedo::hemisphere(width, cos_o, QUAD, |wo, wi| {
        b.eval(wo.as_vec3(), wi.as_vec3()).x as f64
    })
}

#[test]
fn albedo_diffuse_is_kd() {
    let mut rng = rng(3);
    let b = BrdfParams::diffuse(Vec3::splat(0.8));
    for t in [0.0, 45.0, 85.0] {
        // Cosine sampling of a Lambert lobe: every sample's estimate is Kd.
        let (a, se) = mc_albedo(&b, dir(t, 10.0), 20_000, &mut rng);
        assert!((a - 0.8).abs() < 1e-6 && se < 1e-6, "theta {t}: {a} ± {se}");
    }
}

/// The independent quadrature against closed forms: GGX at alpha = 1 (D = 1/pi and
/// G1(c) = 2c/(1+c), so f = 1/(pi (1 + cos_i)(1 + cos_o)) and a(cos_o) =
/// 2 (1 - ln 2) / (1 + cos_o)), and Blinn-Phong at normal incidence (A(s) of docs/brdf.md).
/// Also that halving the nodes changes little where the tests below use it.
#[test]
fn albedo_quadrature_is_exact() {
    for deg in [0.0f64, 30.0, 60.0, 75.0, 85.0] {
        let c = deg.to_radians().cos();
        let q = albedo::ggx(1.0, c, QUAD);
        let exact = 2.0 * (1.0 - 2f64.ln()) / (1.0 + c);
        assert!(
            (q - exact).abs() < 5e-6,
            "alpha 1, theta {deg}: {q} vs {exact}"
        );
    }
    let c = std::f64::consts::FRAC_1_SQRT_2;
    for s in [0.0f64, 1.0, 10.0, 100.0, 1000.0] {
        let a0 = 4.0
            * (s + 2.0)
            * (2.0 / (s + 4.0) * (1.0 - c.powf(s + 4.0)) - (1.0 - c.powf(s + 2.0)) / (s + 2.0));
        let q = bp_albedo(s, 0.0);
        assert!((q - a0).abs() < 1e-5 * a0, "s {s}: {q} vs {a0}");
    }
    for alpha in [0.05, 0.2, 0.5] {
        for deg in [0.0f64, 60.0, 85.0] {
            let c = deg.to_radians().cos();
            let (a, b) = (albedo::ggx(alpha, c, QUAD), albedo::ggx(alpha, c, QUAD / 2));
            assert!(
                (a - b).abs() < 2e-4,
                "alpha {alpha} theta {deg}: {a} vs {b} on half the nodes"
            );
        }
    }
}

/// GGX directional albedo (Ks = 1, Kd = 0) against the independent quadrature, for alpha from
/// 0.05 to 1 and theta_o up to 85 degrees: (a) the code's `eval` integrated on the same nodes
/// agrees to f32 rounding (relative 2e-5), so the lobe's formula is the documented one; (b)
/// the Monte Carlo estimate with the code's sampler and density agrees within 5 standard
/// errors (measured from the samples), so sampling and pdf are consistent with it; (c) the
/// albedo is at most 1 (docs/brdf.md: F = 1 with separable Smith cannot create energy).
#[test]
fn albedo_ggx_matches_independent_quadrature() {
    let mut rng = rng(4);
    for alpha in [0.05f32, 0.2, 0.5, 1.0] {
        for t in [0.0f32, 30.0, 60.0, 75.0, 85.0] {
            let b = spec(Family::Ggx, 0.0, 1.0, alpha);
            let c = (t as f64).to_radians().cos();
            let q = albedo::ggx(alpha as f64, c, QUAD);
            let e = eval_albedo(&b, alpha as f64, c);
            let (m, se) = mc_albedo(&b, dir(t, 0.0), 100_000, &mut rng);
            eprintln!(
                "ggx alpha {alpha} theta {t}: quadrature {q:.6}, eval {e:.6}, Monte Carlo \
                 {m:.6} ± {se:.1e} ({:+.2} standard errors)",
                (m - q) / se
            );
            assert!(
                q <= 1.0 + 1e-5 && q > 0.0,
                "alpha {alpha} theta {t}: albedo {q}"
            );
            assert!(
                (e - q).abs() <= 2e-5 * q,
                "alpha {alpha} theta {t}: eval integrates to {e}, the formula to {q}"
            );
            assert!(
                (m - q).abs() <= 5.0 * se + 1e-5,
                "alpha {alpha} theta {t}: Monte Carlo {m} vs quadrature {q} ({:.1} standard \
                 errors of {se:.1e})",
                (m - q) / se
            );
        }
    }
}

#[test]
fn albedo_blinn_phong_bound() {
    // Quadrature facts (docs/brdf.md): s = 0 is Lambert (albedo 1), and the half-angle
    // normalization exceeds 1 for s > 0, approaching 4 at normal incidence for large s.
    assert!((bp_albedo(0.0, 0.3) - 1.0).abs() < 1e-5);
    let a200 = bp_max_albedo(200.0);
    assert!(a200 > 3.5 && a200 < 4.0, "{a200}");
    let mut rng = rng(5);
    for s in [1.0f32, 10.0, 100.0, 1000.0] {
        let m = bp_max_albedo(s as f64);
        // Kd + Ks max_albedo(s) = 1: energy conserving for every direction
        let ks = 0.6 / m as f32;
        let kd = 1.0 - ks * m as f32;
        let b = spec(Family::BlinnPhong, kd, ks, s);
        let width = (2.0 / (s as f64 + 2.0)).sqrt();
        for t in [0.0f32, 40.0, 75.0, 85.0] {
            let c = (t as f64).to_radians().cos();
            let q = kd as f64 + ks as f64 * bp_albedo(s as f64, c.acos());
            assert!(q <= 1.0 + 1e-5, "s {s} theta {t}: albedo {q}");
            // The code's eval of the lobe alone integrated on the quadrature's nodes (the
            // nodes crowd in the lobe, and would integrate a Lambert term less well).
            let lobe = spec(Family::BlinnPhong, 0.0, 1.0, s);
            let e = eval_albedo(&lobe, width, c);
            let l = bp_albedo(s as f64, c.acos());
            let (a, se) = mc_albedo(&b, dir(t, 0.0), 100_000, &mut rng);
            eprintln!(
                "blinn-phong s {s} theta {t}: lobe quadrature {l:.6}, eval {e:.6}; material \
                 {q:.6}, Monte Carlo {a:.6} ± {se:.1e} ({:+.2} standard errors)",
                (a - q) / se
            );
            assert!(
                (e - l).abs() <= 2e-5 * l,
                "s {s} theta {t}: eval integrates to {e}, the formula to {l}"
            );
            // the sampler's estimate agrees with the quadrature
            assert!(
                (a - q).abs() <= 5.0 * se + 1e-5,
                "s {s} theta {t}: Monte Carlo {a} vs quadrature {q} ({:.1} standard errors of \
                 {se:.1e})",
                (a - q) / se
            );
        }
    }
}

/// ∫ pdf(wo, wi) dwi over the upper hemisphere, by midpoint quadrature in (cos theta, phi)
/// refined towards the specular peak by splitting cells.
fn pdf_integral(b: &BrdfParams, wo: Vec3, nz: usize, np: usize) -> f64 {
    let mut sum = 0.0;
    for a in 0..nz {
        let z = (a as f64 + 0.5) / nz as f64;
        let r = (1.0 - z * z).sqrt();
        for c in 0..np {
            let p = 2.0 * PI * (c as f64 + 0.5) / np as f64;
            let wi = Vec3::new((r * p.cos()) as f32, (r * p.sin()) as f32, z as f32);
            sum += b.pdf(wo, wi) as f64;
        }
    }
    sum * 2.0 * PI / (nz * np) as f64
}

#[test]
fn pdf_normalization() {
    let mut rng = rng(6);
    for b in [
        BrdfParams::diffuse(Vec3::ONE),
        spec(Family::BlinnPhong, 0.5, 0.5, 1.0),
        spec(Family::BlinnPhong, 0.2, 0.8, 30.0),
        spec(Family::BlinnPhong, 0.0, 1.0, 200.0),
        spec(Family::Ggx, 0.5, 0.5, 0.5),
        spec(Family::Ggx, 0.0, 1.0, 0.15),
    ] {
        for t in [0.0f32, 50.0, 80.0] {
            let wo = dir(t, 20.0);
            let integral = pdf_integral(&b, wo, 1500, 1500);
            // mass the sampler sends below the horizon (it returns None for those)
            let n = 200_000;
            let lost = (0..n)
                .filter(|_| b.sample(wo, rng.next_vec2()).is_none())
                .count() as f64
                / n as f64;
            assert!(
                (integral + lost - 1.0).abs() < 0.01,
                "{b:?} theta {t}: ∫pdf = {integral}, lost = {lost}"
            );
            if t == 0.0 && b.family == Family::Diffuse {
                assert!((integral - 1.0).abs() < 1e-3);
            }
        }
    }
}

/// Expected count of bin (a, c) of an `nz` x `np` histogram in (cos theta, phi) of `n`
/// sampled directions: `n ∫_bin pdf` by a `sub` x `sub` midpoint rule inside the bin.
fn expected_count(
    b: &BrdfParams,
    wo: Vec3,
    (a, c): (usize, usize),
    (nz, np): (usize, usize),
    n: usize,
    sub: usize,
) -> f64 {
    let mut e = 0.0;
    for i in 0..sub {
        let z = (a as f64 + (i as f64 + 0.5) / sub as f64) / nz as f64;
        let r = (1.0 - z * z).sqrt();
        for j in 0..sub {
            let p = 2.0 * PI * (c as f64 + (j as f64 + 0.5) / sub as f64) / np as f64;
            let wi = Vec3::new((r * p.cos()) as f32, (r * p.sin()) as f32, z as f32);
            e += b.pdf(wo, wi) as f64;
        }
    }
    e * 2.0 * PI / (nz * np * sub * sub) as f64 * n as f64
}

/// 200 000 sampled directions, binned 8 x 16 in (cos theta, phi), against the counts the
/// density predicts. Each bin's count is binomial, so it must be within 5 of its standard
/// deviations `sqrt(e (1 - e/n))` of the expected `e` (plus the quadrature's error for `e`,
/// bounded by the change from a 12 x 12 to a 24 x 24 rule, a few counts at most), and the
/// chi-square statistic over the bins must stay below its mean + 5 standard deviations
/// (`dof + 5 sqrt(2 dof)`, a false alarm rate of about 1e-5 under the hypothesis): a
/// per-bin test catches a local error, the chi-square a small one spread over many bins.
#[test]
fn sampled_histogram_matches_pdf() {
    let mut rng = rng(7);
    let (nz, np) = (8usize, 16usize);
    for b in [
        spec(Family::BlinnPhong, 0.3, 0.7, 20.0),
        spec(Family::Ggx, 0.3, 0.7, 0.3),
        spec(Family::Ggx, 0.0, 1.0, 0.1),
        BrdfParams::diffuse(Vec3::ONE),
    ] {
        let wo = dir(40.0, 0.0);
        let n = 200_000usize;
        let mut hist = vec![0.0f64; nz * np];
        for _ in 0..n {
            if let Some(s) = b.sample(wo, rng.next_vec2()) {
                let z = s.wi.z.clamp(0.0, 0.999_999) as f64;
                let p = (s.wi.y as f64).atan2(s.wi.x as f64).rem_euclid(2.0 * PI);
                let (a, c) = (
                    (z * nz as f64) as usize,
                    ((p / (2.0 * PI)) * np as f64) as usize,
                );
                hist[a.min(nz - 1) * np + c.min(np - 1)] += 1.0;
            }
        }
        let (mut chi2, mut dof, mut worst) = (0.0, 0usize, 0.0f64);
        for a in 0..nz {
            for c in 0..np {
                let e = expected_count(&b, wo, (a, c), (nz, np), n, 24);
                let quad = (e - expected_count(&b, wo, (a, c), (nz, np), n, 12)).abs();
                let o = hist[a * np + c];
                let sd = (e * (1.0 - e / n as f64)).max(0.0).sqrt();
                worst = worst.max((o - e).abs() / sd.max(1.0));
                assert!(
                    (o - e).abs() <= 5.0 * sd + quad + 1.0,
                    "{b:?} bin ({a},{c}): observed {o}, expected {e:.1} (standard deviation \
                     {sd:.1}, quadrature error <= {quad:.2}): {:.1} standard deviations",
                    (o - e) / sd
                );
                // Bins with few expected counts are not chi-square distributed.
                if e >= 5.0 {
                    chi2 += (o - e) * (o - e) / e;
                    dof += 1;
                }
            }
        }
        let dof = dof - 1;
        let limit = dof as f64 + 5.0 * (2.0 * dof as f64).sqrt();
        eprintln!(
            "{:?}: chi-square {chi2:.1} on {dof} degrees of freedom (limit {limit:.1}), worst \
             bin {worst:.2} standard deviations",
            b.family
        );
        assert!(
            chi2 <= limit,
            "{b:?}: chi-square {chi2:.1} on {dof} degrees of freedom exceeds {limit:.1}"
        );
    }
}

/// Prints the Blinn-Phong albedo table of docs/brdf.md:
/// `cargo test -p prt-bake --test suite -- --ignored --nocapture print_blinn_phong_albedo`.
#[test]
#[ignore]
fn print_blinn_phong_albedo() {
    println!(
        "| s | albedo at theta_o = 0 | 45 deg | 80 deg | max over theta_o | Ks max with Kd = 0 |"
    );
    for s in [
        0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0,
    ] {
        let m = bp_max_albedo(s);
        println!(
            "| {s} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} |",
            bp_albedo(s, 0.0),
            bp_albedo(s, 45f64.to_radians()),
            bp_albedo(s, 80f64.to_radians()),
            m,
            1.0 / m
        );
    }
}
