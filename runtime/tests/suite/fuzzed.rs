//! Bake files that are valid containers but absurd per-pixel bakes, found by fuzzing
//! (`prt-fuzz bake-file`, docs/fuzzing.md): the runtime refuses them, or relights them at a
//! cost proportional to the file; it never panics, hangs or allocates without bound. Each
//! file here is self-contained (written from its metadata), like the fuzzer's inputs.

use std::path::PathBuf;
use std::time::Instant;

use prt_formats::basis::{AngularGrid, BrdfBasis, GridKind, ParamWarp, BASIS_SCHEMA_VERSION};
use prt_formats::pixel::{
    BakeStats, BasisMeta, CameraMeta, GroupMeta, MaterialMeta, PixelBakeMeta, Precision, SlotKind,
    PIXEL_SCHEMA_VERSION,
};
use prt_formats::{BakeWriter, Family};

use prt_runtime::RuntimeError;

/// A 1 x 1 gray bake of one diffuse material (Kd 0.5) seen by its one pixel, direct light only.
fn meta() -> PixelBakeMeta {
    PixelBakeMeta {
        pixel_schema_version: PIXEL_SCHEMA_VERSION,
        width: 1,
        height: 1,
        spp: 1,
        emission_oversampling: None,
        reflections: 1,
        seed: 0,
        channels: 1,
        tint: [1.0; 3],
        precision: Precision::F32,
        materials: vec![MaterialMeta {
            name: "m".into(),
            editable: true,
            family: Family::Diffuse,
            kd: [0.5; 3],
            ks: [0.0; 3],
            param: 0.0,
            textured: false,
            slots: vec![SlotKind::Kd],
            slot_offset: 0,
            basis: None,
        }],
        bases: vec![],
        groups: vec![GroupMeta {
            material: 0,
            pixels: 1,
            slots: 1,
            active: vec![],
            row_len: 1,
            compressed_rank: None,
            scale: 1.0,
        }],
        camera: CameraMeta {
            position: [0.0; 3],
            forward: [0.0, 0.0, -1.0],
            up: [0.0, 1.0, 0.0],
            yfov: 1.0,
        },
        stats: BakeStats::default(),
    }
}

/// Writes `meta` with a black emission and a transfer tensor of `row_len` ones per pixel
/// (`pixels` of them) into `dir`.
fn write(dir: &tempfile::TempDir, meta: &PixelBakeMeta, row_len: usize, pixels: &[u32]) -> PathBuf {
    let path = dir.path().join("fuzzed.prtbake");
    let t = vec![1.0f32; row_len * pixels.len()];
    let mut w = BakeWriter::new();
    w.set_metadata(meta.to_json());
    let (width, height) = (meta.width as usize, meta.height as usize);
    let emission = vec![0.0f32; width * height * 3];
    w.add_f32("emission", &[height, width, 3], &emission)
        .unwrap();
    w.add_u32("g0.pixels", &[pixels.len()], pixels).unwrap();
    w.add_f32("g0.t", &[row_len, pixels.len()], &t).unwrap();
    w.write_atomic(&path).unwrap();
    path
}

/// `reflections` = 2^31 - 1 with no active slots: the row is one value, and relighting it
/// used to loop 2^31 times.
#[test]
fn absurd_reflections_relight_at_the_cost_of_the_row() {
    let mut m = meta();
    m.reflections = i32::MAX as u32;
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, &m, 1, &[0]);
    let start = Instant::now();
    let frame = prt_runtime::open(&path)
        .and_then(|mut r| r.render())
        .unwrap();
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!(frame.pixels, [[0.5; 3]]);
    assert!(seconds < 1.0, "{seconds} s");
}

/// A group of no pixels holds no data whatever its row length (here 2^32 - 1: two active
/// slots, 32 reflections); rendering would allocate its weights, 48 GiB.
#[test]
fn groups_without_pixels_are_refused() {
    let mut m = meta();
    m.reflections = 32;
    m.groups[0].active = vec![0, 0];
    m.groups[0].row_len = u32::MAX;
    m.groups[0].pixels = 0;
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, &m, u32::MAX as usize, &[]);
    let err = prt_runtime::open(&path).err();
    match err {
        Some(RuntimeError::Schema { reason, .. }) => {
            assert!(reason.contains("no pixels"), "{reason}")
        }
        other => panic!("expected a schema error, got {other:?}"),
    }
}

/// Pixel indices out of order (here 8, 0 in a 1 x 9 image, two bands of rows): the render's
/// binary search put pixel 0 in the second band, whose first pixel is 8, and `0 - 8` indexed
/// the band out of bounds.
#[test]
fn unordered_pixel_indices_are_refused() {
    let mut m = meta();
    m.height = 9;
    m.groups[0].pixels = 2;
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, &m, 1, &[8, 0]);
    let err = prt_runtime::open(&path).err();
    match err {
        Some(RuntimeError::Schema { reason, .. }) => {
            assert!(reason.contains("strictly ascending"), "{reason}")
        }
        other => panic!("expected a schema error, got {other:?}"),
    }
}

/// A material outside every group names a basis the file does not have: the groups' checks
/// missed it, and computing the slot coefficients (every render) indexed the bases out of
/// bounds.
#[test]
fn materials_outside_the_groups_must_name_existing_bases() {
    let mut m = meta();
    let mut glossy = m.materials[0].clone();
    glossy.name = "unseen".into();
    glossy.family = Family::BlinnPhong;
    glossy.slots = vec![SlotKind::Basis(0)];
    glossy.slot_offset = 1;
    glossy.basis = Some(0);
    m.materials.push(glossy);
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, &m, 1, &[0]);
    let err = prt_runtime::open(&path).err();
    match err {
        Some(RuntimeError::Schema { reason, .. }) => {
            assert!(
                reason.contains("'unseen' names a missing basis"),
                "{reason}"
            )
        }
        other => panic!("expected a schema error, got {other:?}"),
    }
}

/// A basis whose parameter samples decrease (as stored: without its tables). Computing the
/// coefficients clamped the parameter to [5126, 200] and panicked.
#[test]
fn bases_with_unordered_samples_are_refused() {
    let mut m = meta();
    m.materials[0].family = Family::BlinnPhong;
    m.materials[0].slots = vec![SlotKind::Basis(0)];
    m.materials[0].basis = Some(0);
    m.bases = vec![BasisMeta {
        basis: BrdfBasis {
            version: BASIS_SCHEMA_VERSION,
            family: Family::BlinnPhong,
            method: "test".into(),
            param_range: [1.0, 200.0],
            param_warp: ParamWarp::Log { offset: 1.0 },
            param_samples: vec![5126.0, 200.0],
            grid: AngularGrid {
                n_theta_i: 2,
                n_theta_o: 2,
                n_phi: 2,
            },
            grid_kind: GridKind::HalfDiff,
            num_bases: 1,
            tables: vec![],
            coefficients: vec![1.0, 0.5],
        },
    }];
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, &m, 1, &[0]);
    let err = prt_runtime::open(&path).err();
    match err {
        Some(RuntimeError::Schema { reason, .. }) => {
            assert!(reason.contains("strictly increasing"), "{reason}")
        }
        other => panic!("expected a schema error, got {other:?}"),
    }
}

/// Not found by the fuzzer (it takes three matching changes: `channels`, the row length and
/// the tensor's size) but by reading the code while fixing its findings: `channels` = 2 made
/// `group_weights` write 3 values per element into a row sized for 2, out of bounds.
#[test]
fn channel_counts_other_than_1_or_3_are_refused() {
    for channels in [0, 2, 4] {
        let mut m = meta();
        m.channels = channels;
        m.groups[0].row_len = channels;
        let dir = tempfile::tempdir().unwrap();
        let path = write(&dir, &m, channels as usize, &[0]);
        match prt_runtime::open(&path).and_then(|mut r| r.render()) {
            Err(RuntimeError::Schema { reason, .. }) => {
                assert!(reason.contains("channels"), "{channels}: {reason}")
            }
            other => panic!("{channels} channels: expected a schema error, got {other:?}"),
        }
    }
}
