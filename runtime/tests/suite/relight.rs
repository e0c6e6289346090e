//! Relit frames against an independent f64 sum over the stored values, for every storage the
//! runtime reads (f32, f16 with a scale, low rank), gray and RGB, both kernels, any thread
//! count.

use prt_formats::pixel::Precision;
use prt_runtime::hooks::Kernel;
use prt_runtime::{Image, OverrideValue, PixelRelighter, RenderStats, RuntimeError, Variant};

use crate::synthetic::{Synthetic, H, W};

/// The frame of variant `v`, rendered into an owned image, and its stats.
pub fn frame(r: &mut PixelRelighter, v: Variant) -> (Image, RenderStats) {
    r.set_variant(v).expect("variant");
    let (width, height) = r.size();
    let mut image = Image::new(width, height);
    let stats = r
        .render_into(image.pixels.as_flattened_mut())
        .expect("render");
    (image, stats)
}

/// Largest per-pixel error relative to the image's largest value (a scale-aware bound for f32
/// sums of ~100 terms).
fn max_rel_err(frame: &[[f32; 3]], expect: &[[f64; 3]]) -> f64 {
    assert_eq!(frame.len(), expect.len(), "frame size");
    let scale = expect
        .iter()
        .flat_map(|p| p.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    frame
        .iter()
        .zip(expect)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] as f64 - b[c]).abs()))
        .fold(0.0, f64::max)
        / scale
}

/// Both kernels' full frames against the plain f64 sum of the stored f32 values.
fn full_frames_equal_the_plain_sum(s: &Synthetic, r: &mut PixelRelighter) {
    let expect = s.relight(&s.params(), false, None);
    for kernel in [Kernel::Auto, Kernel::Scalar] {
        r.set_kernel(kernel);
        let (f, _) = frame(r, Variant::Full);
        let err = max_rel_err(&f.pixels, &expect);
        assert!(err < 2e-6, "{kernel:?}: max error {err:e}");
    }
}

fn open(s: &Synthetic, precision: Precision) -> (tempfile::TempDir, PixelRelighter) {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("synthetic.prtbake");
    s.write(&path, precision);
    let r = PixelRelighter::open(&path).expect("open synthetic bake");
    (dir, r)
}

#[test]
fn full_frames_equal_the_plain_sum_for_f32_and_f16_gray_and_rgb() {
    for channels in [1, 3] {
        let s = Synthetic::new(channels, None, 11 + channels as u64);
        for precision in [Precision::F32, Precision::F16] {
            let (_dir, mut r) = open(&s, precision);
            assert_eq!(r.size(), (W, H));
            let values = match precision {
                Precision::F32 => None,
                Precision::F16 => Some(s.f16_values()),
            };
            let expect = s.relight(&s.params(), false, values.as_deref());
            for kernel in [Kernel::Auto, Kernel::Scalar] {
                r.set_kernel(kernel);
                let (f, _) = frame(&mut r, Variant::Full);
                assert_eq!((f.width, f.height), (W, H));
                let err = max_rel_err(&f.pixels, &expect);
                assert!(
                    err < 2e-6,
                    "channels {channels}, {precision:?}, {kernel:?}: max error {err:e}"
                );
            }
        }
    }
}

#[test]
fn compressed_frames_equal_the_plain_low_rank_sum() {
    for channels in [1, 3] {
        let s = Synthetic::new(channels, Some(3), 5);
        let (_dir, mut r) = open(&s, Precision::F32);
        assert!(r.has_compressed());
        let (f, _) = frame(&mut r, Variant::Compressed);
        let err = max_rel_err(&f.pixels, &s.relight(&s.params(), true, None));
        assert!(err < 2e-6, "channels {channels}: max error {err:e}");
        // The full variant is still the stored rows, not the low-rank ones.
        let (full, _) = frame(&mut r, Variant::Full);
        let err = max_rel_err(&full.pixels, &s.relight(&s.params(), false, None));
        assert!(err < 2e-6, "channels {channels}, full: max error {err:e}");
    }
}

#[test]
fn frames_report_the_bytes_they_read() {
    let s = Synthetic::new(3, Some(2), 3);
    let (_dir, mut r) = open(&s, Precision::F32);
    let emission = (W * H * 3 * 4) as u64;
    // The pixel lists are not read per frame: their runs are found when the file is opened.
    let full: u64 = s.groups.iter().map(|g| g.transfer.len() as u64 * 4).sum();
    let low: u64 = s
        .groups
        .iter()
        .map(|g| {
            let (m, c, z) = g.compressed.as_ref().expect("compressed");
            (m.len() + c.len() + z.len()) as u64 * 4
        })
        .sum();
    let (_, f) = frame(&mut r, Variant::Full);
    assert_eq!(f.bytes_read, Some(emission + full));
    assert!(f.seconds >= 0.0 && f.seconds.is_finite());
    let (_, c) = frame(&mut r, Variant::Compressed);
    assert_eq!(c.bytes_read, Some(emission + low));
    let (_dir16, mut r16) = open(&s, Precision::F16);
    let (_, h) = frame(&mut r16, Variant::Full);
    assert_eq!(h.bytes_read, Some(emission + full / 2));
}

#[test]
fn frames_are_identical_on_any_thread_count() {
    let s = Synthetic::new(3, Some(2), 9);
    let (_dir, mut r) = open(&s, Precision::F16);
    for v in [Variant::Full, Variant::Compressed] {
        r.set_variant(v).expect("variant");
        let render = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool")
                .install(|| r.render().expect("render").pixels)
        };
        let one = render(1);
        for t in [2, 5] {
            assert!(one == render(t), "{v:?}: 1 and {t} threads differ");
        }
    }
}

#[test]
fn groups_smaller_than_a_tile_relight_exactly() {
    // The contraction works in tiles of 8 pixels with a scalar tail; a group with fewer pixels
    // than a tile is all tail.
    let mut s = Synthetic::new(1, None, 13);
    for (g, keep) in s.groups.iter_mut().zip([5usize, 1, 9]) {
        let p = g.pixels.len();
        let len = g.transfer.len() / p;
        g.transfer = (0..len)
            .flat_map(|e| g.transfer[e * p..e * p + keep].to_vec())
            .collect();
        g.pixels.truncate(keep);
        g.meta.pixels = keep as u32;
    }
    let (_dir, mut r) = open(&s, Precision::F32);
    full_frames_equal_the_plain_sum(&s, &mut r);
}

#[test]
fn runs_across_blocks_and_bands_relight_exactly() {
    // 160 wide: a band of 8 rows holds 1280 pixels, so the wall's runs of 140 cross the
    // contraction blocks of 1024, and the paint's run through rows 14-16 crosses a band's edge.
    let s = Synthetic::spans(160, 20, 21);
    let (_dir, mut r) = open(&s, Precision::F32);
    full_frames_equal_the_plain_sum(&s, &mut r);
}

#[test]
fn render_into_overwrites_whatever_the_buffer_held() {
    // A caller's buffer is overwritten, never read: stale or poisoned floats must not leak
    // into the frame, which equals the owned render bit for bit, for both variants.
    let s = Synthetic::new(3, Some(2), 22);
    let (_dir, mut r) = open(&s, Precision::F32);
    for v in [Variant::Full, Variant::Compressed] {
        r.set_variant(v).expect("variant");
        let owned = r.render().expect("render");
        for poison in [f32::NAN, 7.0, -0.0] {
            let mut out = vec![poison; 3 * (W * H) as usize];
            r.render_into(&mut out).expect("render into");
            assert!(
                out.iter().map(|v| v.to_bits()).eq(owned
                    .pixels
                    .as_flattened()
                    .iter()
                    .map(|v| v.to_bits())),
                "{v:?}: render_into over {poison} differs from render"
            );
        }
    }
}

#[test]
fn columns_of_zero_weight_are_neither_read_nor_counted() {
    // paint.kd = 0 zeroes every element of the paint group and the other groups' terms that
    // pass through paint's slot: those columns are skipped, and the byte count says so.
    let s = Synthetic::new(3, None, 4);
    let (_dir, mut r) = open(&s, Precision::F32);
    r.set_params("paint", &[OverrideValue::Kd([0.0; 3])])
        .expect("edit");
    let mut p = s.params();
    p[1].kd = [0.0; 3];
    let coeff = s.coefficients(&p);
    let read: u64 = s
        .groups
        .iter()
        .map(|g| {
            let w = s.weights(g, &coeff);
            let len = g.meta.row_len as usize;
            let nonzero = (0..len)
                .filter(|&e| (0..3).any(|c| w[c * len + e] != 0.0))
                .count();
            (nonzero * g.pixels.len() * 4) as u64
        })
        .sum();
    let all: u64 = s.groups.iter().map(|g| g.transfer.len() as u64 * 4).sum();
    assert!(
        read < all,
        "the edit should zero some columns ({read} of {all} bytes)"
    );
    let (f, stats) = frame(&mut r, Variant::Full);
    assert_eq!(stats.bytes_read, Some((W * H * 3 * 4) as u64 + read));
    let err = max_rel_err(&f.pixels, &s.relight(&p, false, None));
    assert!(err < 2e-6, "max error {err:e}");
}

#[test]
fn time_reads_reads_what_a_frame_reads_and_changes_nothing() {
    let s = Synthetic::new(3, Some(2), 23);
    let (_dir, mut r) = open(&s, Precision::F16);
    let mut scratch = Vec::new();
    for v in [Variant::Full, Variant::Compressed] {
        let (before, stats) = frame(&mut r, v);
        let pass = r.time_reads(&mut scratch).expect("reads");
        assert_eq!(Some(pass.bytes_read), stats.bytes_read, "{v:?}");
        assert!(pass.seconds >= 0.0 && pass.seconds.is_finite());
        assert_eq!(
            scratch.len(),
            3 * before.pixels.len(),
            "{v:?}: scratch reused"
        );
        // The reads-only pass sums unweighted values into the first channel only: not the
        // frame, and (uncompressed, where pixels start from nothing but their emission) the
        // other two channels keep the emission, on the vector path and the portable tail.
        assert!(
            scratch != before.pixels.as_flattened(),
            "{v:?}: the pass made the frame"
        );
        if v == Variant::Full {
            for (p, e) in scratch.chunks_exact(3).zip(s.emission.chunks_exact(3)) {
                assert_eq!([p[1], p[2]], [e[1], e[2]], "weights were applied");
            }
        }
        let (after, _) = frame(&mut r, v);
        assert!(
            after.pixels == before.pixels,
            "{v:?}: the pass changed a frame"
        );
    }
    let (_dir, mut plain) = open(&Synthetic::new(1, None, 3), Precision::F32);
    assert!(matches!(
        plain.set_variant(Variant::Compressed),
        Err(RuntimeError::NoCompressed)
    ));
}

#[test]
fn only_emitting_pixels_are_read_and_negative_zero_is_kept() {
    // Pixels whose stored emission is +0 in every channel start from zero instead of being
    // read. Pixel 14 is in no group, so its frame value is its emission exactly: -0 must stay
    // -0 (a test by value instead of by bits would make it +0).
    let mut s = Synthetic::new(1, None, 31);
    let dark = 100..400;
    for p in dark.clone() {
        s.emission[3 * p..3 * p + 3].fill(0.0);
    }
    s.emission[3 * 14..3 * 14 + 3].fill(-0.0);
    assert!(s.groups.iter().all(|g| !g.pixels.contains(&14)));
    let (_dir, mut r) = open(&s, Precision::F32);
    let full: u64 = s.groups.iter().map(|g| g.transfer.len() as u64 * 4).sum();
    let emitting = (W * H) as u64 - dark.len() as u64;
    let expect = s.relight(&s.params(), false, None);
    for kernel in [Kernel::Auto, Kernel::Scalar] {
        r.set_kernel(kernel);
        let (f, stats) = frame(&mut r, Variant::Full);
        assert_eq!(stats.bytes_read, Some(emitting * 12 + full), "{kernel:?}");
        let err = max_rel_err(&f.pixels, &expect);
        assert!(err < 2e-6, "{kernel:?}: max error {err:e}");
        assert_eq!(f.pixels[14].map(f32::to_bits), [(-0.0f32).to_bits(); 3]);
    }
}
