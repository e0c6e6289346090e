//! Analytic checks of the reference path tracer: cases with a closed-form answer.

use glam::{DVec3, Vec3};
use prt_bake::accel::Accel;
use prt_bake::brdf::{BrdfParams, Family};
use prt_bake::integrator::Integrator;
use prt_bake::lights::LightSet;
use prt_bake::scene::{Environment, Scene};
use prt_bake::testing::{
    albedo, camera_samples, closed_sphere_radiance, convex_furnace_scene, furnace_scene,
    inside_sphere_scene, look_at, CameraSample, SceneBuilder, SPLIT_GEOMETRY,
};

fn render_scene(
    scene: &Scene,
    reflections: usize,
    w: u32,
    h: u32,
    spp: u32,
) -> prt_bake::reference::Render {
    prt_bake::reference::render_true(
        scene,
        reflections,
        w,
        h,
        spp,
        prt_bake::film_emission::DEFAULT_EMISSION_OVERSAMPLING,
        7,
        None,
    )
}

/// Mean of `values` and the standard error of that mean, per channel, with the sample
/// variance measured from the values themselves (camera samples are independent: each owns
/// its random stream).
fn mean_and_se(values: impl Iterator<Item = DVec3>) -> (DVec3, DVec3, usize) {
    let (mut n, mut sum, mut sum2) = (0usize, DVec3::ZERO, DVec3::ZERO);
    for v in values {
        n += 1;
        sum += v;
        sum2 += v * v;
    }
    let nf = n.max(2) as f64;
    let mean = sum / nf;
    let var = ((sum2 - sum * mean) / (nf - 1.0)).max(DVec3::ZERO);
    (mean, (var / nf).map(f64::sqrt), n)
}

/// Largest angle between a vertex normal and its triangle's facet normal, squared.
fn max_normal_tilt_squared(scene: &Scene) -> f64 {
    let mut worst = 0.0f64;
    for t in &scene.triangles {
        let [a, b, c] = t.map(|v| scene.positions[v as usize]);
        let ng = (b - a).cross(c - a).normalize();
        for v in t {
            let cos = scene.normals[*v as usize]
                .normalize()
                .dot(ng)
                .clamp(-1.0, 1.0);
            worst = worst.max((cos as f64).acos().powi(2));
        }
    }
    worst
}

/// White furnace: a convex Lambert object under a constant environment of radiance 1 reflects
/// exactly its albedo, whatever the number of reflections (no interreflection on a convex
/// object).
///
/// The estimator has no variance here, so the check is per camera sample, to float rounding.
/// The constant environment is sampled by the cosine, as the Lambert BRDF is, so both MIS
/// strategies have the same density, their weights sum to 1 and each contributes
/// `w (a/pi) cos / (cos/pi) = w a`: a sample's estimate is `a`. The two densities are computed
/// along different code paths (local frame vs world frame), so they agree only to rounding:
/// measured at most 49 ulps (3e-6 relative) off; `SAMPLE_TOL` allows 1e-5. The exceptions
/// are geometric, with smooth shading normals only: a direction above the shading horizon but
/// below the facet is refused by the integrator, so a strategy that draws into that wedge
/// loses its half of the estimate (per draw with probability about tilt^2 / 4, tilt being the
/// angle between shading and facet normal, at most 0.02 rad here); and a camera ray that
/// meets a facet from below its shading normal, at the silhouette, gives a black sample
/// (about tilt^2 / 2 of the samples). So a handful among the 8 600 samples at most (none at
/// this seed). The flat-shaded sphere has neither.
#[test]
fn furnace_sphere_radiance_equals_albedo() {
    const SAMPLE_TOL: f32 = 1e-5;
    let albedo = Vec3::new(0.5, 0.3, 0.8);
    let smooth = furnace_scene(albedo, Vec3::ONE);
    let flat = convex_furnace_scene(BrdfParams::diffuse(albedo), false, Vec3::ONE);
    for (name, scene) in [("smooth", &smooth), ("flat", &flat)] {
        let tilt2 = max_normal_tilt_squared(scene);
        for reflections in [1, 3] {
            let samples = camera_samples(scene, reflections, (32, 32), 16, 7, true);
            let (mut n, mut lost, mut sum) = (0usize, 0usize, DVec3::ZERO);
            for s in &samples {
                let Some(hit) = s.hit else {
                    // The background is the environment itself, exactly.
                    assert_eq!(s.radiance, Vec3::ONE, "{name}: background sample {s:?}");
                    continue;
                };
                n += 1;
                sum += s.radiance.as_dvec3();
                let ratio = s.radiance / albedo;
                let near = |k: f32| (ratio - Vec3::splat(k)).abs().max_element() <= SAMPLE_TOL;
                if near(1.0) {
                    continue;
                }
                assert!(
                    tilt2 > 0.0 && (near(0.5) || near(0.0)),
                    "{name}, {reflections} reflections: pixel {} sample {}: radiance {} is not \
                     the albedo {albedo} (ratio {ratio}); the facet normal is {}",
                    s.pixel,
                    s.sample,
                    s.radiance,
                    hit.ng
                );
                lost += 1;
            }
            assert!(n > 8000, "{name}: the sphere covers {n} samples");
            // Two draws per sample into the wedge, and the silhouette.
            let expected_lost = n as f64 * tilt2;
            assert!(
                (lost as f64) <= 5.0 + 3.0 * expected_lost,
                "{name}: {lost} samples lost light to the shading normals, expected at most \
                 {expected_lost:.2}"
            );
            let mean = sum / n as f64;
            let rel = ((mean - albedo.as_dvec3()) / albedo.as_dvec3())
                .abs()
                .max_element();
            eprintln!(
                "furnace {name}, {reflections} reflections: {n} samples, mean {mean:.8}, \
                 relative error {rel:.1e}, {lost} samples lost light (expected <= \
                 {expected_lost:.2})"
            );
            // Rounding averages out; each loss removes at most a whole sample.
            assert!(
                rel <= 1e-6 + lost as f64 / n as f64,
                "{name}, {reflections} reflections: sphere mean {mean} vs albedo {albedo} \
                 (relative {rel:.2e})"
            );
        }
    }
}

/// Inside a closed Lambert sphere that emits `Le` everywhere, radiance is `Le (1 + a + ... +
/// a^N)` at every point for N reflections (albedo a per channel), and with two halves of
/// albedos a1, a2 the integrating-sphere form (see [`closed_sphere_radiance`]). Every
/// reflection count 1..4 is checked, so a dropped or doubled bounce, or a bounce that uses
/// the wrong vertex's albedo, shows. Bounded by the measured standard error (the estimator
/// has little variance: next-event and BRDF sampling of a sphere's interior both have the
/// cosine density, up to the facets).
#[test]
fn closed_sphere_interreflection_is_a_geometric_series() {
    let le = Vec3::new(1.0, 0.8, 0.6);
    let cases = [
        (Vec3::new(0.2, 0.5, 0.9), Vec3::new(0.2, 0.5, 0.9)),
        (Vec3::splat(0.2), Vec3::splat(0.9)),
    ];
    for (upper, lower) in cases {
        let scene = inside_sphere_scene(upper, lower, le, false);
        let m = 0.5 * (upper + lower);
        let split = upper != lower;
        for n in 1..=4usize {
            let samples = camera_samples(&scene, n, (24, 24), 16, 3, true);
            for (material, a) in [(0u32, upper), (1, lower)] {
                let (mean, se, count) = mean_and_se(
                    samples
                        .iter()
                        .filter(|s| s.hit.map(|h| h.material) == Some(material))
                        .map(|s| s.radiance.as_dvec3()),
                );
                assert!(count > 3000, "material {material} covers {count} samples");
                let expect = closed_sphere_radiance(le, a, m, n);
                let geometry = if split { SPLIT_GEOMETRY } else { 0.0 };
                for c in 0..3 {
                    let d = mean[c] - expect[c];
                    let allowed =
                        4.5 * se[c] + 1e-6 * expect[c] + geometry * (expect[c] - le[c] as f64);
                    eprintln!(
                        "closed sphere {upper}/{lower}, N = {n}, material {material}, channel \
                         {c}: {:.6} vs {:.6} ({:+.1e} relative, {:+.2} standard errors)",
                        mean[c],
                        expect[c],
                        d / expect[c],
                        d / se[c]
                    );
                    assert!(
                        d.abs() <= allowed,
                        "closed sphere {upper}/{lower}, {n} reflections, material {material}, \
                         channel {c}: mean radiance {} vs closed form {} ({:.1} standard \
                         errors of {:.1e}; allowed {allowed:.1e})",
                        mean[c],
                        expect[c],
                        d / se[c],
                        se[c]
                    );
                }
            }
        }
    }
}

/// Glossy furnace: a convex sphere under a constant white environment has, at every camera
/// sample, radiance `Kd + Ks a(wo)` with `a` the lobe's directional albedo for the view
/// direction in the facet's frame, here from the independent quadrature of
/// `prt_bake::testing::albedo`. Two reflections (a convex object never sees itself, so the
/// second adds nothing). The residuals (sample minus closed form) are binned by `cos(theta_o)`
/// and each bin's mean must be within 4.5 standard errors of zero (measured per bin), so an
/// error in the sampled density, the MIS weights or the lobe shows where it is.
#[test]
fn glossy_furnace_reference_equals_directional_albedo() {
    let spec = |family, kd: f32, ks: f32, param| BrdfParams {
        family,
        kd: Vec3::splat(kd),
        ks: Vec3::splat(ks),
        param,
    };
    let cases = [
        spec(Family::Ggx, 0.0, 1.0, 0.1),
        spec(Family::Ggx, 0.0, 1.0, 0.3),
        spec(Family::Ggx, 0.0, 1.0, 0.6),
        spec(Family::Ggx, 0.3, 0.5, 0.2),
        spec(Family::BlinnPhong, 0.0, 1.0, 5.0),
        spec(Family::BlinnPhong, 0.0, 1.0, 60.0),
    ];
    for brdf in cases {
        let p = brdf.param as f64;
        let table = albedo::Table::new(121, |c| match brdf.family {
            Family::Ggx => albedo::ggx(p, c, 192),
            _ => albedo::blinn_phong(p, c, 192),
        });
        let scene = convex_furnace_scene(brdf, false, Vec3::ONE);
        let samples = camera_samples(&scene, 2, (48, 48), 16, 5, true);
        let closed = |s: &CameraSample| {
            let hit = s.hit.expect("hit");
            let cos_o = hit.ns.dot(-s.dir) as f64;
            brdf.kd.x as f64 + brdf.ks.x as f64 * table.at(cos_o)
        };
        check_binned_residuals(&format!("{brdf:?}"), &samples, closed);
    }
}

/// Bins the samples that hit something by `cos^2(theta_o)` (quarters of [0, 1]: equal shares
/// of a sphere's projected area, the first one theta_o > 60 degrees) and asserts that each
/// bin's mean residual (first channel minus `closed`) is within 4.5 of its standard errors,
/// plus 2e-4 of the closed form for the quadrature and the table's interpolation.
fn check_binned_residuals(
    name: &str,
    samples: &[CameraSample],
    closed: impl Fn(&CameraSample) -> f64,
) {
    let mut bins: Vec<Vec<(f64, f64)>> = vec![Vec::new(); 4];
    for s in samples {
        let Some(hit) = s.hit else { continue };
        let cos_o = hit.ns.dot(-s.dir).clamp(0.0, 1.0);
        let b = ((cos_o * cos_o * 4.0) as usize).min(3);
        let e = closed(s);
        bins[b].push((s.radiance.x as f64 - e, e));
    }
    for (b, bin) in bins.iter().enumerate() {
        let (mean, se, n) = mean_and_se(bin.iter().map(|&(r, _)| DVec3::splat(r)));
        assert!(n > 200, "{name}: bin {b} has {n} samples");
        let level = bin.iter().map(|&(_, e)| e).sum::<f64>() / n as f64;
        let allowed = 4.5 * se.x + 2e-4 * level;
        eprintln!(
            "{name}: cos^2(theta_o) in [{:.2}, {:.2}): {n} samples, closed form {level:.4}, \
             mean residual {:+.2e} ({:+.2} standard errors)",
            b as f64 / 4.0,
            (b + 1) as f64 / 4.0,
            mean.x,
            mean.x / se.x
        );
        assert!(
            mean.x.abs() <= allowed,
            "{name}: cos^2(theta_o) in [{}, {}): mean radiance is {:+.2e} off the closed form \
             {level:.4} \
             ({:.1} standard errors of {:.1e}; allowed {allowed:.1e})",
            b as f64 / 4.0,
            (b + 1) as f64 / 4.0,
            mean.x,
            mean.x / se.x,
            se.x
        );
    }
}

/// Irradiance at `p` (normal `n`) from a polygon of uniform radiance `le` (Lambert's formula).
fn polygon_irradiance(p: Vec3, n: Vec3, poly: &[Vec3], le: f32) -> f32 {
    let mut sum = 0.0f64;
    for i in 0..poly.len() {
        let a = (poly[i] - p).normalize().as_dvec3();
        let b = (poly[(i + 1) % poly.len()] - p).normalize().as_dvec3();
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        let g = a.cross(b).normalize();
        sum += theta * n.as_dvec3().dot(g);
    }
    (0.5 * sum.abs() * le as f64) as f32
}

/// A diffuse plane lit by a square area light: the rendered radiance is Kd/pi times the
/// closed-form irradiance, averaged over each pixel's footprint.
#[test]
fn diffuse_plane_under_polygonal_light_matches_closed_form() {
    let kd = 0.8;
    let le = 5.0;
    let mut b = SceneBuilder::new();
    let floor = b.material(
        "floor",
        BrdfParams::diffuse(Vec3::splat(kd)),
        Vec3::ZERO,
        false,
    );
    let light = b.material(
        "light",
        BrdfParams::diffuse(Vec3::ZERO),
        Vec3::splat(le),
        false,
    );
    b.quad(
        [
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(-2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0),
        ],
        floor,
    );
    // Light at y = 1, offset in x so the irradiance varies across the view; faces down.
    let poly = [
        Vec3::new(0.0, 1.0, -0.3),
        Vec3::new(0.6, 1.0, -0.3),
        Vec3::new(0.6, 1.0, 0.3),
        Vec3::new(0.0, 1.0, 0.3),
    ];
    b.quad(poly, light);
    b.camera(look_at(
        Vec3::new(0.0, 0.6, 0.0),
        Vec3::ZERO,
        Vec3::Z,
        60f32.to_radians(),
    ));
    let scene = b.build();
    let (w, h) = (8u32, 8u32);
    let r = render_scene(&scene, 1, w, h, 4096);

    let accel = Accel::build(&scene);
    let lights = LightSet::new(&scene);
    let integ = Integrator::new(&scene, &accel, &lights, 1, w, h);
    let mut worst = 0.0f32;
    let mut total_err = 0.0f32;
    for y in 0..h {
        for x in 0..w {
            // Average the closed form over a sub-pixel grid (the renderer box-filters).
            let mut expected = 0.0;
            let grid = 8;
            for sy in 0..grid {
                for sx in 0..grid {
                    let fx = x as f32 + (sx as f32 + 0.5) / grid as f32;
                    let fy = y as f32 + (sy as f32 + 0.5) / grid as f32;
                    let (o, d) = integ.camera_ray(fx, fy);
                    let t = -o.y / d.y;
                    let p = o + d * t;
                    expected +=
                        kd / std::f32::consts::PI * polygon_irradiance(p, Vec3::Y, &poly, le);
                }
            }
            expected /= (grid * grid) as f32;
            let got = r.pixels[(y * w + x) as usize];
            let rel = (got - Vec3::splat(expected)).abs().max_element() / expected;
            worst = worst.max(rel);
            total_err += rel;
        }
    }
    let mean_err = total_err / (w * h) as f32;
    eprintln!("polygon light: mean rel err {mean_err}, worst {worst}");
    assert!(mean_err < 0.01, "mean relative error {mean_err}");
    assert!(worst < 0.03, "worst pixel relative error {worst}");
}

/// The same render on 1 and on 3 threads is bit-identical.
#[test]
fn render_is_identical_on_any_thread_count() {
    let scene = furnace_scene(Vec3::splat(0.5), Vec3::new(1.0, 0.5, 0.25));
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| render_scene(&scene, 2, 24, 16, 4).pixels)
    };
    let a = run(1);
    let b = run(3);
    assert_eq!(a.len(), b.len());
    for (p, q) in a.iter().zip(&b) {
        assert_eq!(
            p.to_array().map(f32::to_bits),
            q.to_array().map(f32::to_bits)
        );
    }
}

/// A lat-long environment map of constant value must give the furnace result too: this checks
/// the map's importance-sampling density (normalisation, sin(theta) Jacobian) through MIS.
/// The map's sampling is not the cosine, so the estimator has variance: the bound is 4.5
/// measured standard errors.
#[test]
fn latlong_environment_sampling_is_normalised() {
    let albedo = Vec3::splat(0.6);
    let (w, h) = (64u32, 32u32);
    let radiance = Vec3::new(0.5, 1.0, 2.0);
    let mut scene = furnace_scene(albedo, Vec3::ONE);
    scene.environment = Environment::LatLong {
        width: w,
        height: h,
        texels: vec![radiance; (w * h) as usize],
    };
    let samples = camera_samples(&scene, 1, (24, 24), 16, 7, true);
    let (mean, se, n) = mean_and_se(
        samples
            .iter()
            .filter(|s| s.hit.is_some())
            .map(|s| s.radiance.as_dvec3()),
    );
    assert!(n > 3000);
    let expect = (albedo * radiance).as_dvec3();
    let z = (mean - expect) / se;
    eprintln!(
        "constant lat-long map: mean {mean:.6} vs {expect}, standard error {se:.7}, z {z:.2}"
    );
    assert!(
        z.abs().max_element() <= 4.5,
        "sphere mean {mean} vs {expect}: {z} standard errors ({se})"
    );
}

/// A lat-long map in the docs' convention (docs/conventions.md), written here independently of
/// `prt_formats::latlong`: direction of image coordinate (u, v).
fn latlong_direction(u: f64, v: f64) -> DVec3 {
    let (theta, phi) = (
        std::f64::consts::PI * v,
        2.0 * std::f64::consts::PI * (u - 0.5),
    );
    DVec3::new(
        theta.sin() * phi.sin(),
        theta.cos(),
        -theta.sin() * phi.cos(),
    )
}

/// `∫ max(0, n.w) k(w) dw` for the bilinear "tent" `k` that a block of texels
/// `x0..=x1` by `y0..=y1` of value 1 (0 elsewhere) makes on a `w` x `h` lat-long map: the
/// lookup interpolates linearly between texel centres (docs/conventions.md), so the block's
/// weight is 1 between its first and last centres and falls to 0 one texel further out.
/// A midpoint rule of 16 x 16 cells per texel over that footprint, each cell with its exact
/// solid angle `dphi (cos theta0 - cos theta1)`. (The block stays away from the poles and
/// the seam.)
fn block_irradiance(n: DVec3, (x0, x1): (u32, u32), (y0, y1): (u32, u32), w: u32, h: u32) -> f64 {
    let sub = 16;
    // Weight along one axis at texel coordinate t (centres at i + 0.5).
    let tent = |t: f64, lo: u32, hi: u32| -> f64 {
        let (first, last) = (lo as f64 + 0.5, hi as f64 + 0.5);
        if t < first {
            (1.0 - (first - t)).max(0.0)
        } else if t > last {
            (1.0 - (t - last)).max(0.0)
        } else {
            1.0
        }
    };
    let mut e = 0.0;
    for yt in (y0 - 1)..=(y1 + 1) {
        for i in 0..sub {
            let v0 = (yt as f64 + i as f64 / sub as f64) / h as f64;
            let v1 = (yt as f64 + (i + 1) as f64 / sub as f64) / h as f64;
            let wy = tent(0.5 * (v0 + v1) * h as f64, y0, y1);
            let solid = 2.0 * std::f64::consts::PI / (w * sub) as f64
                * ((std::f64::consts::PI * v0).cos() - (std::f64::consts::PI * v1).cos());
            for xt in (x0 - 1)..=(x1 + 1) {
                for j in 0..sub {
                    let u = (xt as f64 + (j as f64 + 0.5) / sub as f64) / w as f64;
                    let wx = tent(u * w as f64, x0, x1);
                    let dir = latlong_direction(u, 0.5 * (v0 + v1));
                    e += n.dot(dir).max(0.0) * wx * wy * solid;
                }
            }
        }
    }
    e
}

/// A genuinely non-uniform lat-long map: a dim sky with a small sun (2 x 2 texels, about 1000
/// times brighter, three quarters of the sampling mass) low on the +X side, so the camera
/// (on +Z) sees the sphere's lit and shadowed halves.
/// Every camera sample on the (flat-shaded, convex) Lambert sphere has radiance
/// `a/pi E(n)`, E the irradiance of the map over the facet's hemisphere: `pi B` from the
/// constant sky plus the sun's bilinearly interpolated footprint integrated by an independent
/// quadrature. Residuals are
/// binned into shadow, terminator and lit (by the facet's cosine to the sun) and each bin's
/// mean must be within 4.5 measured standard errors: a density that disagrees with where the
/// samples go (a half-texel shift, a wrong Jacobian, row and column mixed up) biases the lit
/// side by many standard errors, which a constant map cannot show.
#[test]
fn latlong_environment_with_a_sun_matches_its_irradiance() {
    let (w, h) = (64u32, 32u32);
    let sky = Vec3::new(0.2, 0.3, 0.4);
    let sun = Vec3::new(400.0, 300.0, 200.0);
    let sun_texels = [(47u32, 12u32), (48, 12), (47, 13), (48, 13)];
    let mut texels = vec![sky; (w * h) as usize];
    for &(x, y) in &sun_texels {
        texels[(y * w + x) as usize] = sun;
    }
    let albedo = Vec3::new(0.6, 0.5, 0.4);
    let mut scene = convex_furnace_scene(BrdfParams::diffuse(albedo), false, Vec3::ONE);
    scene.environment = Environment::LatLong {
        width: w,
        height: h,
        texels,
    };
    let sun_dir = latlong_direction(48.0 / w as f64, 13.0 / h as f64);
    let samples = camera_samples(&scene, 1, (24, 24), 32, 9, true);
    let mut bins: Vec<Vec<(DVec3, DVec3)>> = vec![Vec::new(); 3];
    for s in &samples {
        let Some(hit) = s.hit else { continue };
        let n = hit.ng.as_dvec3();
        let sun_e = block_irradiance(n, (47, 48), (12, 13), w, h);
        let e = std::f64::consts::PI * sky.as_dvec3() + (sun - sky).as_dvec3() * sun_e;
        let expect = albedo.as_dvec3() * e / std::f64::consts::PI;
        let c = n.dot(sun_dir);
        let b = if c < -0.15 {
            0
        } else if c <= 0.15 {
            1
        } else {
            2
        };
        bins[b].push((s.radiance.as_dvec3() - expect, expect));
    }
    for (b, name) in ["shadow", "terminator", "lit"].iter().enumerate() {
        let (mean, se, n) = mean_and_se(bins[b].iter().map(|&(r, _)| r));
        let level = bins[b].iter().map(|&(_, e)| e).sum::<DVec3>() / n as f64;
        assert!(n > 400, "{name}: {n} samples");
        for c in 0..3 {
            let allowed = 4.5 * se[c] + 1e-4 * level[c];
            eprintln!(
                "sun map, {name}, channel {c}: {n} samples, closed form {:.4}, mean residual \
                 {:+.2e} ({:+.2} standard errors)",
                level[c],
                mean[c],
                mean[c] / se[c]
            );
            assert!(
                mean[c].abs() <= allowed,
                "sun map, {name} side, channel {c}: mean radiance {:+.3e} off the closed form \
                 {:.4} ({:.1} standard errors of {:.1e}; allowed {allowed:.1e})",
                mean[c],
                level[c],
                mean[c] / se[c],
                se[c]
            );
        }
    }
}

/// A diffuse plane under a point light and under a directional light: radiance
/// Kd/pi * I cos(theta) / d^2 and Kd/pi * E cos(theta), exactly (no sampling of the light).
#[test]
fn punctual_lights_match_closed_form() {
    use prt_bake::scene::PunctualLight;
    let kd = 0.5;
    for light in [
        PunctualLight::Point {
            position: Vec3::new(0.3, 1.5, -0.2),
            intensity: Vec3::new(2.0, 3.0, 4.0),
        },
        PunctualLight::Directional {
            direction: Vec3::new(0.3, -1.0, 0.2).normalize(),
            irradiance: Vec3::new(1.0, 2.0, 0.5),
        },
    ] {
        let mut b = SceneBuilder::new();
        let floor = b.material(
            "floor",
            BrdfParams::diffuse(Vec3::splat(kd)),
            Vec3::ZERO,
            false,
        );
        b.quad(
            [
                Vec3::new(-2.0, 0.0, -2.0),
                Vec3::new(-2.0, 0.0, 2.0),
                Vec3::new(2.0, 0.0, 2.0),
                Vec3::new(2.0, 0.0, -2.0),
            ],
            floor,
        );
        b.light(light);
        b.camera(look_at(
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::ZERO,
            Vec3::Z,
            50f32.to_radians(),
        ));
        let scene = b.build();
        let (w, h) = (6u32, 6u32);
        let accel = Accel::build(&scene);
        let lights = LightSet::new(&scene);
        let integ = Integrator::new(&scene, &accel, &lights, 1, w, h);
        // One sample per pixel at a known position is not available (jitter), so compare the
        // pixel mean with the closed form averaged over the same footprint.
        let r = render_scene(&scene, 1, w, h, 256);
        for y in 0..h {
            for x in 0..w {
                let grid = 16;
                let mut expected = Vec3::ZERO;
                for sy in 0..grid {
                    for sx in 0..grid {
                        let (o, d) = integ.camera_ray(
                            x as f32 + (sx as f32 + 0.5) / grid as f32,
                            y as f32 + (sy as f32 + 0.5) / grid as f32,
                        );
                        let p = o + d * (-o.y / d.y);
                        expected += match light {
                            PunctualLight::Point {
                                position,
                                intensity,
                            } => {
                                let to = position - p;
                                intensity * (to.normalize().y / to.length_squared())
                            }
                            PunctualLight::Directional {
                                direction,
                                irradiance,
                            } => irradiance * (-direction.y),
                            _ => Vec3::ZERO,
                        } * (kd / std::f32::consts::PI);
                    }
                }
                expected /= (grid * grid) as f32;
                let got = r.pixels[(y * w + x) as usize];
                let rel = ((got - expected) / expected).abs().max_element();
                // Only the footprint average differs (256 jittered samples vs a 16x16 grid).
                assert!(rel < 0.01, "{light:?} pixel ({x},{y}): {got} vs {expected}");
            }
        }
    }
}

/// Turning a lat-long environment by +90 degrees about +Y (`Scene::environment_rotation`, the
/// right-hand rule) is the same light as the map with its columns shifted a quarter turn:
/// what the unturned map shows at u + 1/4 now arrives from u (docs/conventions.md: +90 takes
/// -Z, u = 1/2, to -X, u = 1/4). Radiance and sampling density agree direction by direction,
/// and sampled directions are distributed alike (their mean direction). A sign error in the
/// rotation (the map turned the other way) moves the sun by half a turn and fails.
#[test]
fn environment_rotation_is_a_shift_of_the_map() {
    let (w, h) = (32u32, 16u32);
    let texel = |x: u32, y: u32| {
        if (x, y) == (20, 5) || (x, y) == (21, 5) {
            Vec3::new(50.0, 40.0, 30.0)
        } else {
            Vec3::new(0.1 + 0.01 * x as f32, 0.2, 0.05 * y as f32)
        }
    };
    let map: Vec<Vec3> = (0..h)
        .flat_map(|y| (0..w).map(move |x| texel(x, y)))
        .collect();
    let shifted: Vec<Vec3> = (0..h)
        .flat_map(|y| (0..w).map(move |x| texel((x + w / 4) % w, y)))
        .collect();
    let mut turned = furnace_scene(Vec3::splat(0.5), Vec3::ONE);
    turned.environment = Environment::LatLong {
        width: w,
        height: h,
        texels: map,
    };
    turned.environment_rotation = 90.0;
    let mut reference = turned.clone();
    reference.environment = Environment::LatLong {
        width: w,
        height: h,
        texels: shifted,
    };
    reference.environment_rotation = 0.0;
    let (a, b) = (LightSet::new(&turned), LightSet::new(&reference));
    let n = Vec3::Y;
    for i in 0..400 {
        let (u, v) = (
            (i % 20) as f64 / 20.0 + 0.013,
            (i / 20) as f64 / 20.0 + 0.021,
        );
        let d = latlong_direction(u, v).as_vec3();
        let (ra, rb) = (a.environment_radiance(d), b.environment_radiance(d));
        assert!(
            (ra - rb).abs().max_element() <= 1e-4 * rb.max_element().max(1.0),
            "{d}: turned {ra}, shifted {rb}"
        );
        let (pa, pb) = (a.environment_pdf(n, d), b.environment_pdf(n, d));
        assert!((pa - pb).abs() <= 1e-3 * pb, "{d}: density {pa} vs {pb}");
    }
    let mean_dir = |lights: &LightSet| {
        let mut sum = DVec3::ZERO;
        for i in 0..4096u32 {
            let u = glam::Vec2::new(
                (i % 64) as f32 / 64.0 + 0.007,
                (i / 64) as f32 / 64.0 + 0.003,
            );
            if let Some(s) = lights.sample_environment(n, u) {
                sum += s.wi.as_dvec3();
            }
        }
        sum / 4096.0
    };
    let (ma, mb) = (mean_dir(&a), mean_dir(&b));
    assert!(
        (ma - mb).length() < 0.02,
        "mean sampled direction {ma} vs {mb}"
    );
    assert!(mb.length() > 0.3, "the sun dominates the sampling: {mb}");
}
