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
