//! The per-pixel metadata's JSON and a stored basis' coefficient checks: what the runtime
//! relies on when it opens a file.

use prt_formats::basis::{BrdfBasis, GridSpec, ParamWarp, BASIS_SCHEMA_VERSION};
use prt_formats::pixel::{
    BakeStats, BasisMeta, CameraMeta, GroupMeta, MaterialMeta, PixelBakeMeta, Precision, SlotKind,
    PIXEL_SCHEMA_VERSION,
};
use prt_formats::Family;

fn basis(samples: Vec<f32>, warp: ParamWarp) -> BrdfBasis {
    let grid = GridSpec::DEFAULT;
    BrdfBasis {
        version: BASIS_SCHEMA_VERSION,
        family: Family::BlinnPhong,
        method: "test".into(),
        param_range: [samples[0], samples[samples.len() - 1]],
        param_warp: warp,
        coefficients: (0..samples.len() * 2).map(|i| i as f32 * 0.1).collect(),
        param_samples: samples,
        grid: grid.dims,
        grid_kind: grid.kind,
        num_bases: 2,
        tables: Vec::new(),
    }
}

#[test]
fn the_metadata_json_round_trips() {
    let meta = PixelBakeMeta {
        pixel_schema_version: PIXEL_SCHEMA_VERSION,
        width: 7,
        height: 5,
        spp: 16,
        emission_oversampling: Some(4),
        reflections: 3,
        seed: 99,
        channels: 3,
        tint: [1.0, 0.5, 0.25],
        precision: Precision::F16,
        materials: vec![MaterialMeta {
            name: "glossy".into(),
            editable: true,
            family: Family::BlinnPhong,
            kd: [0.1, 0.2, 0.3],
            ks: [0.4, 0.5, 0.6],
            param: 42.0,
            textured: false,
            slots: vec![SlotKind::Basis(0), SlotKind::Basis(1)],
            slot_offset: 0,
            basis: Some(0),
        }],
        bases: vec![BasisMeta {
            basis: basis(vec![1.0, 10.0, 100.0], ParamWarp::Log { offset: 1.0 }),
        }],
        groups: vec![GroupMeta {
            material: 0,
            pixels: 12,
            slots: 2,
            active: vec![0, 1],
            row_len: 18,
            compressed_rank: Some(2),
            scale: 0.5,
        }],
        camera: CameraMeta {
            position: [1.0, 2.0, 3.0],
            forward: [0.0, 0.0, -1.0],
            up: [0.0, 1.0, 0.0],
            yfov: 0.5,
        },
        stats: BakeStats {
            rays: 1234,
            dense_values: 56,
            stored_values: 34,
            allocation: vec!["glossy: editable".into()],
            triangles: 8,
        },
    };
    let json = meta.to_json();
    assert_eq!(json["width"], 7);
    assert_eq!(json["precision"], "f16");
    let back: PixelBakeMeta = serde_json::from_value(json).expect("metadata JSON parses back");
    assert_eq!(
        serde_json::to_string(&back).expect("json"),
        serde_json::to_string(&meta).expect("json")
    );
    assert_eq!(back.emission_oversampling(), 4);
    // Files from before `emission_oversampling` was recorded sampled emission with the paths.
    let mut old = meta.to_json();
    old.as_object_mut()
        .expect("an object")
        .remove("emission_oversampling");
    let old: PixelBakeMeta =
        serde_json::from_value(old).expect("metadata without emission_oversampling");
    assert_eq!(
        (old.emission_oversampling, old.emission_oversampling()),
        (None, 1)
    );
}

#[test]
fn coefficient_checks_accept_a_valid_basis_and_refuse_each_defect() {
    let ok = basis(vec![1.0, 2.0, 4.0], ParamWarp::Linear);
    ok.validate_coefficients().expect("valid");
    // A log warp whose offset is negative but keeps param + offset > 0 is valid.
    basis(vec![2.0, 3.0], ParamWarp::Log { offset: -1.0 })
        .validate_coefficients()
        .expect("param + offset = 1 > 0");
    let cases: Vec<(&str, BrdfBasis)> = vec![
        ("no bases", {
            let mut b = ok.clone();
            b.num_bases = 0;
            b
        }),
        ("no samples", {
            let mut b = ok.clone();
            b.param_samples.clear();
            b
        }),
        ("short table", {
            let mut b = ok.clone();
            b.coefficients.pop();
            b
        }),
        ("non-finite sample", {
            let mut b = ok.clone();
            b.param_samples[1] = f32::NAN;
            b
        }),
        ("non-finite coefficient", {
            let mut b = ok.clone();
            b.coefficients[3] = f32::INFINITY;
            b
        }),
        (
            "repeated sample",
            basis(vec![1.0, 2.0, 2.0], ParamWarp::Linear),
        ),
        (
            "decreasing samples",
            basis(vec![3.0, 2.0, 4.0], ParamWarp::Linear),
        ),
        (
            "log of a non-positive value",
            basis(vec![0.5, 3.0], ParamWarp::Log { offset: -1.0 }),
        ),
        (
            "NaN log offset",
            basis(vec![1.0, 3.0], ParamWarp::Log { offset: f32::NAN }),
        ),
    ];
    for (what, b) in cases {
        assert!(b.validate_coefficients().is_err(), "{what}: accepted");
    }
}

#[test]
fn coefficients_interpolate_linearly_in_the_warped_parameter_and_clamp() {
    // Five samples, so the last interval's index (len - 2 = 3) differs from len / 2.
    for warp in [ParamWarp::Linear, ParamWarp::Log { offset: 0.5 }] {
        let b = basis(vec![1.0, 2.0, 4.0, 8.0, 16.0], warp);
        let nb = b.num_bases;
        for j in 0..4 {
            let (lo, hi) = (b.param_samples[j], b.param_samples[j + 1]);
            for t in [0.0f32, 0.25, 0.5, 0.9] {
                // The parameter whose warped value lies a fraction t along the interval.
                let (u0, u1) = (warp.apply_f32(lo), warp.apply_f32(hi));
                let u = u0 + t * (u1 - u0);
                let p = match warp {
                    ParamWarp::Linear => u,
                    ParamWarp::Log { offset } => u.exp() - offset,
                };
                let (c, clamped) = b.coefficients(p);
                assert!(!clamped, "{p} lies inside the range");
                assert_eq!(c.len(), nb);
                for (k, ck) in c.iter().enumerate() {
                    let a0 = b.coefficients[j * nb + k];
                    let a1 = b.coefficients[(j + 1) * nb + k];
                    let want = a0 + t * (a1 - a0);
                    assert!(
                        (ck - want).abs() < 1e-5,
                        "{warp:?}, interval {j}, t {t}: basis {k} is {ck} not {want}"
                    );
                }
            }
        }
        let last = &b.coefficients[4 * nb..];
        for p in [16.0, 20.0, f32::INFINITY] {
            let (c, clamped) = b.coefficients(p);
            assert_eq!(&c[..], last, "{p} clamps to the last sample");
            assert_eq!(clamped, p > 16.0, "{p}");
        }
        for p in [0.5, f32::NAN] {
            let (c, clamped) = b.coefficients(p);
            assert_eq!(
                &c[..],
                &b.coefficients[..nb],
                "{p} clamps to the first sample"
            );
            assert!(clamped, "{p}");
        }
    }
}

#[test]
fn material_coefficients_fold_kd_into_the_first_basis() {
    let b = basis(vec![1.0, 2.0, 4.0], ParamWarp::Linear);
    let (kd, ks) = ([0.5, 0.25, 0.125], [0.2, 0.4, 0.8]);
    let (a, _) = b.coefficients(3.0);
    let (c, clamped) = b.material_coefficients(kd, ks, 3.0);
    assert!(!clamped);
    assert_eq!(c.len(), b.num_bases);
    for (k, ck) in c.iter().enumerate() {
        for ch in 0..3 {
            let d = if k == 0 { kd[ch] } else { 0.0 };
            assert_eq!(ck[ch], d + ks[ch] * a[k], "basis {k}, channel {ch}");
        }
    }
}
