//! BRDF family properties (docs/brdf.md): non-negativity, reciprocity, directional albedo,
//! sampling densities (normalization and histogram of sampled directions).

use glam::Vec3;
use prt_bake::brdf::{BrdfParams, Family};
use prt_bake::sampling::Rng;
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

/// Directional albedo of the Blinn-Phong lobe (Ks = 1, Kd = 0) by quadrature over the half
/// vector, with the substitution t = cos^(s+1)(theta_h) that makes the integrand smooth:
/// a(wo) = (s+2)/(2 pi (s+1)) ∫∫ 4 (wo.h) cos(theta_i) [wi above] dt dphi_h.
fn bp_albedo(s: f64, theta_o: f64) -> f64 {
    let wo = [theta_o.sin(), 0.0, theta_o.cos()];
    let (nt, np) = (400, 256);
    let mut sum = 0.0;
    for a in 0..nt {
        let t = (a as f64 + 0.5) / nt as f64;
        let mu = t.powf(1.0 / (s + 1.0));
        let st = (1.0 - mu * mu).max(0.0).sqrt();
        for b in 0..np {
            let ph = 2.0 * PI * (b as f64 + 0.5) / np as f64;
            let h = [st * ph.cos(), st * ph.sin(), mu];
            let oh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
            if oh <= 0.0 {
                continue;
            }
            let wiz = 2.0 * oh * h[2] - wo[2];
            if wiz <= 0.0 {
                continue;
            }
            sum += 4.0 * oh * wiz;
        }
    }
    (s + 2.0) / (2.0 * PI * (s + 1.0)) * sum * 2.0 * PI / (nt * np) as f64
}

/// Largest Blinn-Phong lobe albedo over outgoing directions (docs/brdf.md).
fn bp_max_albedo(s: f64) -> f64 {
    (0..=18)
        .map(|k| bp_albedo(s, (k as f64 * 5.0).min(89.0).to_radians()))
        .fold(0.0, f64::max)
}

/// Monte Carlo albedo with the BRDF's own sampler: E[f cos / pdf] (first channel).
fn mc_albedo(b: &BrdfParams, wo: Vec3, n: usize, rng: &mut Rng) -> f64 {
    let mut sum = 0.0;
    for _ in 0..n {
        let u = rng.next_vec2();
        let ul = rng.next_f32();
        if let Some(smp) = b.sample(wo, u, ul) {
            let f = b.eval(wo, smp.wi).x as f64;
            sum += f * smp.wi.z as f64 / smp.pdf as f64;
        }
    }
    sum / n as f64
}

#[test]
fn albedo_diffuse_is_kd() {
    let mut rng = rng(3);
    let b = BrdfParams::diffuse(Vec3::splat(0.8));
    for t in [0.0, 45.0, 85.0] {
        let a = mc_albedo(&b, dir(t, 10.0), 20_000, &mut rng);
        assert!((a - 0.8).abs() < 1e-4, "theta {t}: {a}");
    }
}

#[test]
fn albedo_ggx_at_most_one() {
    // F = 1 with separable Smith: a(wo) <= 1 for every alpha and direction.
    let mut rng = rng(4);
    for alpha in [0.02, 0.1, 0.3, 0.6, 1.0] {
        for t in [0.0, 30.0, 60.0, 80.0, 88.0] {
            let b = spec(Family::Ggx, 0.0, 1.0, alpha);
            let a = mc_albedo(&b, dir(t, 0.0), 40_000, &mut rng);
            assert!(a <= 1.0 + 0.01, "alpha {alpha} theta {t}: albedo {a}");
            assert!(a > 0.0);
        }
    }
}

#[test]
fn albedo_blinn_phong_bound() {
    // Quadrature facts (docs/brdf.md): s = 0 is Lambert (albedo 1), and the half-angle
    // normalization exceeds 1 for s > 0, approaching 4 at normal incidence for large s.
    assert!((bp_albedo(0.0, 0.3) - 1.0).abs() < 1e-3);
    let a200 = bp_max_albedo(200.0);
    assert!(a200 > 3.5 && a200 < 4.0, "{a200}");
    let mut rng = rng(5);
    for s in [1.0f32, 10.0, 100.0, 1000.0] {
        let m = bp_max_albedo(s as f64);
        // normal incidence, closed form: 4 (s+2) [2/(s+4) (1 - c^(s+4)) - 1/(s+2) (1 - c^(s+2))]
        let c = std::f64::consts::FRAC_1_SQRT_2;
        let sd = s as f64;
        let a0 = 4.0
            * (sd + 2.0)
            * (2.0 / (sd + 4.0) * (1.0 - c.powf(sd + 4.0)) - (1.0 - c.powf(sd + 2.0)) / (sd + 2.0));
        assert!(
            (bp_albedo(sd, 0.0) - a0).abs() < 2e-3 * a0,
            "s {s}: {} vs {a0}",
            bp_albedo(sd, 0.0)
        );
        // Kd + Ks max_albedo(s) = 1: energy conserving for every direction
        let ks = 0.6 / m as f32;
        let kd = 1.0 - ks * m as f32;
        for t in [0.0, 40.0, 75.0, 87.0] {
            let b = spec(Family::BlinnPhong, kd, ks, s);
            let a = mc_albedo(&b, dir(t, 0.0), 40_000, &mut rng);
            assert!(a <= 1.0 + 0.01, "s {s} theta {t}: albedo {a}");
            // the sampler's estimate agrees with the quadrature
            let q = kd as f64 + ks as f64 * bp_albedo(sd, (t as f64).to_radians());
            assert!(
                (a - q).abs() < 0.02 * q.max(0.1),
                "s {s} theta {t}: MC {a} vs quadrature {q}"
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
                .filter(|_| b.sample(wo, rng.next_vec2(), rng.next_f32()).is_none())
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

#[test]
fn sampled_histogram_matches_pdf() {
    let mut rng = rng(7);
    let (nz, np) = (8usize, 16usize);
    for b in [
        spec(Family::BlinnPhong, 0.3, 0.7, 20.0),
        spec(Family::Ggx, 0.3, 0.7, 0.3),
        BrdfParams::diffuse(Vec3::ONE),
    ] {
        let wo = dir(40.0, 0.0);
        let n = 200_000usize;
        let mut hist = vec![0.0f64; nz * np];
        for _ in 0..n {
            if let Some(s) = b.sample(wo, rng.next_vec2(), rng.next_f32()) {
                let z = s.wi.z.clamp(0.0, 0.999_999) as f64;
                let p = (s.wi.y as f64).atan2(s.wi.x as f64).rem_euclid(2.0 * PI);
                let (a, c) = (
                    (z * nz as f64) as usize,
                    ((p / (2.0 * PI)) * np as f64) as usize,
                );
                hist[a.min(nz - 1) * np + c.min(np - 1)] += 1.0;
            }
        }
        // expected counts: n ∫_bin pdf, by a 24x24 midpoint rule inside each bin
        let sub = 24;
        for a in 0..nz {
            for c in 0..np {
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
                e *= 2.0 * PI / (nz * np * sub * sub) as f64 * n as f64;
                let o = hist[a * np + c];
                assert!(
                    (o - e).abs() <= 5.0 * e.sqrt() + 0.002 * n as f64,
                    "{:?} bin ({a},{c}): observed {o}, expected {e:.1}",
                    b.family
                );
            }
        }
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
