//! EXR/PNG output: round trips, tone mapping, extension dispatch, atomicity.

use std::fs;
use std::path::PathBuf;

use prt_formats::image_io::{
    read_exr_rgb, srgb_oetf, tonemap_srgb8, tonemap_srgb8_with, write_exr, write_exr_with,
    write_image, write_image_with, write_png, ExrPrecision, Srgb8Table, ToneCurve,
};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("prt-image-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// A non-square test image with a wide dynamic range, negative values and exact zeros.
fn test_image(w: usize, h: usize) -> Vec<[f32; 3]> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            [
                x / w as f32,
                (y * 0.37 + 1e-3).powi(3),
                if i % 7 == 0 { -0.25 } else { 1e4 * (x + y) },
            ]
        })
        .collect()
}

fn no_temp_files(dir: &PathBuf) {
    for e in fs::read_dir(dir).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.ends_with(".tmp"), "temporary file left: {name}");
    }
}

#[test]
fn exr_f32_round_trip_is_exact() {
    let dir = scratch("exr32");
    let (w, h) = (37, 21);
    let img = test_image(w, h);
    let path = dir.join("nested/out.exr");
    write_exr(&path, w, h, &img).unwrap();
    let (rw, rh, back) = read_exr_rgb(&path).unwrap();
    assert_eq!((rw, rh), (w, h));
    assert_eq!(back, img);
    no_temp_files(&dir.join("nested"));
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exr_f16_round_trip_within_half_precision_and_saturates() {
    let dir = scratch("exr16");
    let (w, h) = (16, 9);
    let mut img = test_image(w, h);
    img[0] = [1e6, -1e6, f32::NAN];
    img[1] = [f32::INFINITY, 1e-9, 65504.0];
    let path = dir.join("out.exr");
    write_exr_with(&path, w, h, &img, ExrPrecision::F16).unwrap();
    let (_, _, back) = read_exr_rgb(&path).unwrap();
    // Past the f16 range: finite values saturate, non-finite ones stay non-finite.
    assert_eq!(back[0][0], 65504.0);
    assert_eq!(back[0][1], -65504.0);
    assert!(back[0][2].is_nan());
    assert_eq!(back[1][0], f32::INFINITY);
    assert_eq!(back[1][2], 65504.0);
    for (i, (a, b)) in img.iter().zip(&back).enumerate().skip(2) {
        for c in 0..3 {
            // Values past the half range saturate (checked above); compare the rest.
            let (a, b) = (a[c].clamp(-65504.0, 65504.0), b[c]);
            // Half has an 11-bit significand: relative error <= 2^-11 for normal values,
            // absolute error <= 2^-25 in the subnormal range.
            let tol = (a.abs() * 4.9e-4).max(6e-8);
            assert!(
                (a - b).abs() <= tol,
                "pixel {i} channel {c}: wrote {a}, read {b}"
            );
        }
    }
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn png_is_tone_mapped_srgb() {
    let dir = scratch("png");
    let img = vec![
        [0.0, 0.5, 1.0],
        [2.0, -1.0, f32::NAN],
        [0.002, 0.2, f32::INFINITY],
        [0.25, 0.25, 0.25],
    ];
    let path = dir.join("out.png");
    write_png(&path, 2, 2, &img, 1.0).unwrap();
    let back = image::open(&path).unwrap().to_rgb8();
    assert_eq!(back.dimensions(), (2, 2));
    let px: Vec<[u8; 3]> = back.pixels().map(|p| p.0).collect();
    assert_eq!(px[0], [0, 188, 255]); // sRGB(0.5) = 0.7354 -> 188
    assert_eq!(px[1], [255, 0, 0]); // clamp above, negative and NaN -> 0
    assert_eq!(px[2][0], (0.002f32 * 12.92 * 255.0 + 0.5) as u8); // linear toe
    assert_eq!(px[2][2], 255);
    // Exposure is a linear scale applied before the clamp.
    write_png(&path, 2, 2, &img, 2.0).unwrap();
    let back = image::open(&path).unwrap().to_rgb8();
    assert_eq!(back.get_pixel(1, 1).0, [188; 3]);
    assert_eq!(tonemap_srgb8(0.25, 2.0), 188);
    assert!((srgb_oetf(1.0) - 1.0).abs() < 1e-6);
    assert!(write_png(&path, 2, 2, &img, f32::NAN).is_err());
    assert!(write_png(&path, 2, 2, &img, -1.0).is_err());
    no_temp_files(&dir);
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn tone_curves_have_their_closed_forms_and_show_every_radiance() {
    // The closed forms at points where each is easy to state.
    assert_eq!(ToneCurve::Reinhard.apply(1.0), 0.5);
    assert_eq!(ToneCurve::Reinhard.apply(3.0), 0.75);
    let aces = |x: f64| x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14);
    for x in [0.01f32, 0.18, 0.5, 0.8] {
        assert!((f64::from(ToneCurve::Aces.apply(x)) - aces(f64::from(x))).abs() < 1e-6);
    }
    assert_eq!(ToneCurve::Aces.apply(100.0), 1.0);
    for curve in ToneCurve::ALL {
        // Names round-trip (relight --tone, the viewer's picker).
        assert_eq!(curve.name().parse::<ToneCurve>(), Ok(curve));
        // Monotone, 0 at 0, and white for huge and infinite radiance; black for NaN and
        // negatives.
        let mut last = 0u8;
        for i in 0..=4000 {
            let v = i as f32 * 0.005;
            let c = tonemap_srgb8_with(v, 1.0, curve);
            assert!(c >= last, "{curve}: not monotone at {v}");
            last = c;
        }
        assert_eq!(tonemap_srgb8_with(0.0, 1.0, curve), 0);
        assert_eq!(
            tonemap_srgb8_with(f32::INFINITY, 1.0, curve),
            255,
            "{curve}"
        );
        assert_eq!(tonemap_srgb8_with(f32::MAX, 1.0, curve), 255, "{curve}");
        assert_eq!(tonemap_srgb8_with(f32::NAN, 1.0, curve), 0);
        assert_eq!(tonemap_srgb8_with(-2.0, 1.0, curve), 0);
    }
    // Clamp is the default and what tonemap_srgb8 always was.
    assert_eq!(ToneCurve::default(), ToneCurve::Clamp);
    for v in [0.001f32, 0.25, 0.7, 1.0, 3.0] {
        assert_eq!(
            tonemap_srgb8_with(v, 1.5, ToneCurve::Clamp),
            tonemap_srgb8(v, 1.5)
        );
    }
    assert!("filmic"
        .parse::<ToneCurve>()
        .unwrap_err()
        .contains("clamp, reinhard, aces"));
    // A PNG through a curve holds the curve's bytes.
    let dir = scratch("tone");
    let img = vec![[0.5, 2.0, 8.0]];
    write_image_with(dir.join("t.png"), 1, 1, &img, 1.0, ToneCurve::Reinhard).unwrap();
    let back = image::open(dir.join("t.png")).unwrap().to_rgb8();
    let want = img[0].map(|c| tonemap_srgb8_with(c, 1.0, ToneCurve::Reinhard));
    assert_eq!(back.get_pixel(0, 0).0, want);
    assert_eq!(want[1], (srgb_oetf(2.0 / 3.0) * 255.0 + 0.5) as u8);
    fs::remove_dir_all(&dir).unwrap();
}

/// The table gives the direct formula's byte for every shown value near a level's edge (every
/// bit pattern within 1024 of each place the level changes) and on a sweep of every 61st
/// `f32` in [0, 1]; and through exposure and each curve, for radiances from 1e-6 to 1e6 and
/// the special values.
#[test]
fn the_srgb8_table_gives_the_direct_formulas_bytes() {
    let table = Srgb8Table::new();
    // For y in [0, 1], tonemap_srgb8_with(y, 1, clamp) is the sRGB level of y itself.
    let direct = |bits: u32| tonemap_srgb8_with(f32::from_bits(bits), 1.0, ToneCurve::Clamp);
    let check = |bits: u32| {
        let y = f32::from_bits(bits);
        assert_eq!(table.level(y), direct(bits), "y = {y:e} (bits {bits:#x})");
    };
    let one = 1.0f32.to_bits();
    let (mut last_bits, mut last_level, mut changes) = (0u32, direct(0), 0);
    let mut bits = 0u32;
    while bits <= one {
        check(bits);
        let level = direct(bits);
        if level != last_level {
            changes += 1;
            let lo = last_bits.saturating_sub(1024);
            for b in lo..=(bits + 1024).min(one) {
                check(b);
            }
        }
        (last_bits, last_level) = (bits, level);
        bits += 61;
    }
    check(one);
    assert_eq!(
        changes, 255,
        "every level from 0 to 255 is reached once, in order"
    );
    for curve in ToneCurve::ALL {
        for exposure in [0.0f32, 0.37, 1.0, 2.828427, 1e6] {
            let specials = [
                0.0,
                -0.0,
                -2.0,
                f32::NAN,
                f32::INFINITY,
                f32::MAX,
                f32::MIN_POSITIVE,
            ];
            let sweep = (0..=120_000).map(|i| 1e-6f32 * 10f32.powf(i as f32 * 1e-4));
            let values: Vec<f32> = specials.into_iter().chain(sweep).collect();
            for &v in &values {
                assert_eq!(
                    table.tonemap(v, exposure, curve),
                    tonemap_srgb8_with(v, exposure, curve),
                    "{curve}, exposure {exposure}, radiance {v:e}"
                );
            }
            // The whole-frame loop: the same bytes, each channel in its place, alpha 255.
            let rgb: Vec<f32> = values.chunks_exact(3).flatten().copied().collect();
            let mut rgba = vec![0u8; rgb.len() / 3 * 4];
            table.tonemap_rgba8(&rgb, exposure, curve, &mut rgba);
            for (p, (o, l)) in rgba.chunks_exact(4).zip(rgb.chunks_exact(3)).enumerate() {
                let want = l.iter().map(|&v| tonemap_srgb8_with(v, exposure, curve));
                assert!(
                    o[..3].iter().copied().eq(want) && o[3] == 255,
                    "{curve}, exposure {exposure}, pixel {p} {l:?}: {o:?}"
                );
            }
        }
    }
}

#[test]
fn write_image_dispatches_on_extension() {
    let dir = scratch("dispatch");
    let img = test_image(4, 3);
    write_image(dir.join("a.EXR"), 4, 3, &img, 8.0).unwrap();
    // EXR ignores the exposure: it stores scene-linear values.
    assert_eq!(read_exr_rgb(dir.join("a.EXR")).unwrap().2, img);
    write_image(dir.join("a.png"), 4, 3, &img, 1.0).unwrap();
    assert_eq!(image::open(dir.join("a.png")).unwrap().width(), 4);

    for name in ["a.jpg", "noext"] {
        let e = write_image(dir.join(name), 4, 3, &img, 1.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(name) && e.contains(".exr") && e.contains(".png"),
            "{e}"
        );
        assert!(!dir.join(name).exists());
    }
    let e = write_image(dir.join("b.exr"), 5, 3, &img, 1.0)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("5x3") && e.contains("15") && e.contains("12"),
        "{e}"
    );
    assert!(write_image(dir.join("b.png"), 0, 0, &[], 1.0).is_err());
    assert!(!dir.join("b.exr").exists() && !dir.join("b.png").exists());
    no_temp_files(&dir);
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn failed_image_write_keeps_the_old_image() {
    let dir = scratch("keep");
    let path = dir.join("a.exr");
    let img = test_image(4, 3);
    write_exr(&path, 4, 3, &img).unwrap();
    let before = fs::read(&path).unwrap();
    assert!(write_exr(&path, 4, 4, &img).is_err()); // wrong pixel count
    assert_eq!(fs::read(&path).unwrap(), before);
    // Writing over a folder fails at the rename; nothing is left behind.
    fs::create_dir_all(dir.join("d.exr/x")).unwrap();
    let e = write_exr(dir.join("d.exr"), 4, 3, &img)
        .unwrap_err()
        .to_string();
    assert!(e.contains("d.exr"), "{e}");
    no_temp_files(&dir);
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn reading_bad_exr_is_an_error() {
    let dir = scratch("badexr");
    let e = read_exr_rgb(dir.join("missing.exr"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("missing.exr") && e.contains("no such file"),
        "{e}"
    );
    fs::write(dir.join("junk.exr"), b"not an exr at all").unwrap();
    let e = read_exr_rgb(dir.join("junk.exr")).unwrap_err().to_string();
    assert!(e.contains("junk.exr"), "{e}");
    // Truncated EXR.
    let img = test_image(8, 8);
    write_exr(dir.join("t.exr"), 8, 8, &img).unwrap();
    let bytes = fs::read(dir.join("t.exr")).unwrap();
    for cut in [10, bytes.len() / 2, bytes.len() - 1] {
        fs::write(dir.join("t2.exr"), &bytes[..cut]).unwrap();
        assert!(read_exr_rgb(dir.join("t2.exr")).is_err(), "cut at {cut}");
    }
    fs::remove_dir_all(&dir).unwrap();
}
