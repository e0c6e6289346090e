//! Unit tests of the per-vertex relighter's own paths against the slow way: a background
//! pixel's average over the map, a turned map read through the unturned prefiltered cubes.

use super::view::MAX_BACKGROUND_SAMPLES;
use super::*;
use prt_formats::lighting::cubemap::direction_to_face_st;

/// A sky with a warm horizon band and a small bright spot off every axis of symmetry.
fn asymmetric_map() -> LatLongMap {
    let (w, h) = (128usize, 64usize);
    let texels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let spot = (20..24).contains(&x) && (18..21).contains(&y);
            let band = (30..36).contains(&y);
            let v = if spot {
                80.0
            } else if band {
                2.0
            } else {
                0.3
            };
            [v, 0.8 * v, 0.5 * v + 0.01 * x as f32]
        })
        .collect();
    LatLongMap::new(w, h, texels, 1.0).expect("map").0
}

/// A background pixel shows the map's average over the pixel, as a path tracer's jittered
/// camera rays do, not the lookup at its centre: under a lamp one texel wide, with pixels
/// from a sixth of a texel to two texels across (sub-samples half a texel apart, capped),
/// each pixel within 3 % of the lamp's peak of a 48x48-sample average and the lamp's total
/// over the image within 2 % (the centre lookup: 5.5 and 8.3 % of the peak).
#[test]
fn a_background_pixel_averages_the_map_over_the_pixel() {
    let (w, h) = (128usize, 64usize);
    let (lx, ly) = (37usize, 21usize);
    let texels = (0..w * h)
        .map(|i| {
            if i == ly * w + lx {
                [1000.0, 800.0, 500.0]
            } else {
                [0.1; 3]
            }
        })
        .collect();
    let map = LatLongMap::new(w, h, texels, 1.0).expect("map").0;
    let env = shade::Environment {
        map: &map,
        back: rotation_y(0.0),
        turned: false,
    };
    // Looking at the lamp, a little off so that it falls between pixel centres.
    let (u, v) = prt_formats::latlong::texel_centre(lx, ly, w, h);
    let forward = prt_formats::latlong::uv_to_direction(u + 0.0013, v - 0.0021);
    let cross = |a: [f32; 3], b: [f32; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let unit = |a: [f32; 3]| {
        let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|c| c / l)
    };
    let right = unit(cross(forward, [0.0, 1.0, 0.0]));
    let up = cross(right, forward);
    for (side, fov_deg) in [(48u32, 20.0f32), (24, 40.0), (12, 60.0), (6, 90.0)] {
        let camera = CameraFrame {
            position: [0.0; 3],
            forward,
            right,
            up,
            yfov: fov_deg.to_radians(),
        };
        let rays = ViewRays::new(&camera, side, side).expect("rays");
        let k = rays.background_samples(w, h);
        let (mut lamp_got, mut lamp_want) = (0.0f64, 0.0f64);
        let (mut worst, mut centre_worst) = (0.0f64, 0.0f64);
        for py in 0..side {
            for px in 0..side {
                let want: f64 = {
                    let n = 48;
                    let mut sum = 0.0;
                    for j in 0..n {
                        for i in 0..n {
                            let x = f64::from(px) + (f64::from(i) + 0.5) / f64::from(n);
                            let y = f64::from(py) + (f64::from(j) + 0.5) / f64::from(n);
                            let d = rays.direction(x, y).map(|c| c as f32);
                            sum += f64::from(env.radiance(d)[0]);
                        }
                    }
                    sum / f64::from(n * n)
                };
                let got = f64::from(env.pixel_average(&rays, px, py, k)[0]);
                let centre = f64::from(env.radiance(rays.pixel_direction(px, py))[0]);
                lamp_got += got;
                lamp_want += want;
                worst = worst.max((got - want).abs());
                centre_worst = centre_worst.max((centre - want).abs());
            }
        }
        let total = (lamp_got - lamp_want).abs() / lamp_want;
        // The lamp's peak over a pixel is at most 1000: errors relative to it.
        eprintln!(
            "{side}x{side} at {fov_deg} degrees: k = {k}, worst pixel {:.2e}, total {total:.2e} \
             (centre lookup: worst pixel {:.2e})",
            worst / 1000.0,
            centre_worst / 1000.0
        );
        if side == 6 {
            // Pixels four texels across: the sub-samples are capped a texel apart, and no
            // bound is claimed.
            assert_eq!(k, MAX_BACKGROUND_SAMPLES);
            continue;
        }
        assert!(
            worst <= 0.03 * 1000.0 && total <= 0.02,
            "{side}x{side} at {fov_deg} degrees, k = {k}: a pixel off by {worst}, the \
             image's total by {total}"
        );
    }
}

#[test]
fn a_turned_lookup_matches_prefiltering_the_turned_map() {
    let map = asymmetric_map();
    let widths = [4.0, 12.0, 30.0];
    let rotation = 70.0f32;
    let turned = light::environment_cube(&map, f64::from(rotation)).expect("turned cube");
    let direct = light::prefiltered(&turned, &widths).expect("prefiltered turned map");
    let mut cache = PrefilterCache::default();
    let unturned = cache
        .scaled(&map, &widths, 1.0, false)
        .expect("prefiltered");
    let reused = light_coefficients(&map, rotation, &widths, unturned, None)
        .expect("coefficients")
        .prefiltered;
    cache
        .scaled(&map, &widths, 2.0, false)
        .expect("prefiltered");
    assert_eq!(cache.runs, 1, "the unturned cubes were not kept");
    let env = shade::Environment {
        map: &map,
        back: rotation_y(-f64::from(rotation)),
        turned: true,
    };
    // Directions spread over the sphere (a Fibonacci lattice).
    let n = 2000;
    for (w, (a, b)) in widths.iter().zip(direct.iter().zip(&reused)) {
        let (mut worst, mut peak) = (0.0f32, 0.0f32);
        for k in 0..n {
            let z = 1.0 - (2 * k + 1) as f64 / n as f64;
            let phi = k as f64 * 2.399_963_229_728_653;
            let r = (1.0 - z * z).sqrt();
            let d = [r * phi.cos(), z, r * phi.sin()];
            let at = direction_to_face_st(d);
            let want = a.lookup_bilinear_face_st(at.0, at.1, at.2);
            let (f, s, t) = env.prefiltered_at(d.map(|x| x as f32), at);
            let got = b.lookup_bilinear_face_st(f, s, t);
            for c in 0..3 {
                worst = worst.max((want[c] - got[c]).abs());
                peak = peak.max(want[c]);
            }
        }
        // Both resample the same continuous prefiltered sky (one turns the texel grid, the
        // other the lookup); the narrowest width, a few texels wide, differs most.
        assert!(
            worst <= 0.03 * peak,
            "width {w}: turned lookup off by {worst} (peak {peak})"
        );
    }
}
