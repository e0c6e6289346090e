//! The per-pixel bake in pieces (docs/shards.md): a unit is an image row; its piece holds the
//! row's emission and its pixels' dense transfer rows ([`row_piece`]), and the rows of every
//! shard, read back in order ([`row_from_piece`]), finish into the same bake as an unsharded
//! run ([`super::finish_rows`]). [`pixel_fingerprints`]: what a row depends on.

use prt_formats::pixel::PIXEL_SCHEMA_VERSION;

use crate::scene::Scene;
use crate::shard::{scene_entries, Fingerprint, Piece, PieceOut, ShardError, StoreFingerprints};

use super::bake::{PixelBakeOptions, RowOut};
use super::layout::SlotLayout;

/// Row `y`'s piece. Sections: `emission` (f32, `[width, 3]`), `pixels` and `materials` (u32,
/// one per entry), `lengths` (u32, each entry's row length) and `values` (f32, the rows one
/// after another); summary: the unit and its rays.
pub fn row_piece(y: u32, row: &RowOut) -> PieceOut {
    let mut p = PieceOut::new(serde_json::json!({ "unit": y, "rays": row.rays }));
    p.add("emission", &row.emission);
    let pixels: Vec<u32> = row.entries.iter().map(|e| e.0).collect();
    let materials: Vec<u32> = row.entries.iter().map(|e| e.1).collect();
    let lengths: Vec<u32> = row.entries.iter().map(|e| e.2.len() as u32).collect();
    let values: Vec<f32> = row
        .entries
        .iter()
        .flat_map(|e| e.2.iter().copied())
        .collect();
    p.add("pixels", &pixels);
    p.add("materials", &materials);
    p.add("lengths", &lengths);
    p.add("values", &values);
    p
}

/// The row [`row_piece`] stored, checked for consistency.
pub fn row_from_piece(piece: &Piece) -> Result<RowOut, ShardError> {
    let rays: u64 = piece.field("rays")?;
    let pixels = piece.values::<u32>("pixels")?;
    let materials = piece.values::<u32>("materials")?;
    let lengths = piece.values::<u32>("lengths")?;
    let values = piece.values::<f32>("values")?;
    if pixels.len() != materials.len() || pixels.len() != lengths.len() {
        return Err(piece.bad("its entry lists differ in length".into()));
    }
    let total: usize = lengths.iter().map(|&l| l as usize).sum();
    if total != values.len() {
        return Err(piece.bad(format!(
            "its rows hold {} values, their lengths say {total}",
            values.len()
        )));
    }
    let mut at = 0;
    let entries = pixels
        .iter()
        .zip(materials.iter())
        .zip(lengths.iter())
        .map(|((&p, &m), &l)| {
            let row = values[at..at + l as usize].to_vec();
            at += l as usize;
            (p, m, row)
        })
        .collect();
    Ok(RowOut {
        emission: piece.values::<f32>("emission")?.into_owned(),
        entries,
        rays,
    })
}

/// What a per-pixel bake's rows depend on: the program and pixel schema, the options, the slot
/// layout, the scene as loaded. The compression rank is applied when the rows are finished,
/// but it is part of the bake a merge must reproduce, so it is in the fingerprint too.
pub fn pixel_fingerprints(
    scene: &Scene,
    layout: &SlotLayout,
    opts: &PixelBakeOptions,
) -> StoreFingerprints {
    let mut fp = Fingerprint::new();
    fp.literal(
        "program",
        format!(
            "prt-bake {} (pixel schema {PIXEL_SCHEMA_VERSION})",
            env!("CARGO_PKG_VERSION")
        ),
    );
    fp.literal("width", opts.width);
    fp.literal("height", opts.height);
    fp.literal("spp", opts.spp);
    fp.literal("emission_oversampling", opts.emission_oversampling);
    fp.literal("reflections", opts.reflections);
    fp.literal("seed", opts.seed);
    fp.literal("precision", opts.precision.name());
    fp.literal(
        "compress_rank",
        opts.compress_rank
            .map_or("none".to_string(), |k| k.to_string()),
    );
    scene_entries(
        &mut fp,
        scene,
        &scene.normals,
        &format!("{:?} {:?}", layout.materials, layout.bases),
    );
    StoreFingerprints {
        mode: "pixel".into(),
        pieces: fp.clone(),
        traced: fp,
    }
}
