//! "Model only what a scene needs" (docs/pixel.md section 2, issue 4 item 2): slots per material by
//! need, gray tensors when colour can live in coefficients, no storage for slots that never
//! carry light, and a clear refusal past the memory limit.

use glam::Vec3;
use prt_bake::brdf::BrdfParams;
use prt_bake::config::BakeConfig;
use prt_bake::pixel::{self, Precision, SlotLayout};
use prt_bake::run::{run_pixel, PixelRunSettings};
use prt_bake::testing::{look_at, SceneBuilder};
use prt_formats::pixel::SlotKind;
use prt_tests::{bases_for, small_options, temp_path, test_scene};

#[test]
fn slots_follow_what_each_material_needs() {
    let scene = test_scene(Vec3::new(1.0, 0.8, 0.6), Vec3::ZERO);
    let bases = bases_for(&scene, 5);
    let layout = SlotLayout::new(&scene, &bases).expect("layout");
    let slots = |name: &str| {
        let i = scene.material_index(name).expect("material");
        layout.materials[i].slots.clone()
    };
    assert_eq!(
        slots("floor"),
        vec![SlotKind::Kd],
        "fixed diffuse: one slot"
    );
    assert_eq!(
        slots("wall"),
        vec![SlotKind::Kd, SlotKind::Lobe],
        "fixed glossy: Kd + lobe"
    );
    assert_eq!(
        slots("shiny"),
        (0..5).map(SlotKind::Basis).collect::<Vec<_>>(),
        "editable: its basis"
    );
    assert_eq!(slots("metal").len(), 5);
    assert_eq!(
        slots("block"),
        vec![SlotKind::Kd],
        "editable diffuse: one slot"
    );
    assert!(slots("lamp").is_empty(), "black emitter: no slot");
    assert_eq!(layout.total_slots, 1 + 2 + 5 + 5 + 1);
    // One light colour: gray tensors with the colour factored out.
    assert_eq!(layout.channels, 1);
    assert!((layout.tint - Vec3::new(1.0, 0.8, 0.6)).abs().max_element() < 1e-6);
    // A second, differently coloured light makes them RGB.
    let rgb =
        SlotLayout::new(&test_scene(Vec3::ONE, Vec3::new(0.1, 0.2, 0.3)), &bases).expect("layout");
    assert_eq!(rgb.channels, 3);
}

#[test]
fn slots_that_never_carry_light_are_not_stored() {
    // A glossy editable sphere sealed inside a closed box: no path ever reaches it.
    let mut b = SceneBuilder::new();
    let floor = b.material(
        "floor",
        BrdfParams::diffuse(Vec3::splat(0.5)),
        Vec3::ZERO,
        false,
    );
    let boxm = b.material(
        "box",
        BrdfParams::diffuse(Vec3::splat(0.5)),
        Vec3::ZERO,
        false,
    );
    let hidden = b.material(
        "hidden",
        BrdfParams {
            family: prt_bake::brdf::Family::BlinnPhong,
            kd: Vec3::splat(0.3),
            ks: Vec3::splat(0.5),
            param: 30.0,
        },
        Vec3::ZERO,
        true,
    );
    let lamp = b.material(
        "lamp",
        BrdfParams::diffuse(Vec3::ZERO),
        Vec3::splat(5.0),
        false,
    );
    b.quad(
        [
            Vec3::new(-3.0, 0.0, -3.0),
            Vec3::new(-3.0, 0.0, 3.0),
            Vec3::new(3.0, 0.0, 3.0),
            Vec3::new(3.0, 0.0, -3.0),
        ],
        floor,
    );
    let (lo, hi) = (Vec3::new(-0.5, 0.01, -0.5), Vec3::new(0.5, 1.0, 0.5));
    let c =
        |x: usize, y: usize, z: usize| Vec3::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z]);
    for face in [
        [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)],
        [c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)],
        [c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)],
        [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)],
        [c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)],
        [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)],
    ] {
        b.quad(face, boxm);
    }
    b.sphere(Vec3::new(0.0, 0.5, 0.0), 0.3, 2, hidden);
    b.quad(
        [
            Vec3::new(-1.0, 3.0, -1.0),
            Vec3::new(1.0, 3.0, -1.0),
            Vec3::new(1.0, 3.0, 1.0),
            Vec3::new(-1.0, 3.0, 1.0),
        ],
        lamp,
    );
    b.camera(look_at(
        Vec3::new(0.0, 2.0, 4.0),
        Vec3::new(0.0, 0.5, 0.0),
        Vec3::Y,
        50f32.to_radians(),
    ));
    let scene = b.build();
    let bases = bases_for(&scene, 4);
    let layout = SlotLayout::new(&scene, &bases).expect("layout");
    let bake = pixel::bake(
        &scene,
        &layout,
        &small_options(24, 16, 8, 3, Precision::F32),
        None,
    )
    .expect("bake");
    let hidden_i = scene.material_index("hidden").expect("hidden") as u32;
    let hidden_slots: Vec<u32> = {
        let m = &layout.materials[hidden_i as usize];
        (m.slot_offset..m.slot_offset + m.slots.len() as u32).collect()
    };
    assert!(
        bake.meta.groups.iter().all(|g| g.material != hidden_i),
        "hidden sphere got a group"
    );
    for g in &bake.meta.groups {
        assert!(
            g.active.iter().all(|j| !hidden_slots.contains(j)),
            "group of material {} stores slots of the hidden sphere",
            g.material
        );
    }
    // Both visible materials exchange light, so each stores the other's slot.
    assert!(
        bake.meta.groups.iter().all(|g| g.active.len() == 2),
        "{:?}",
        bake.meta.groups
    );
}

/// Records the notes a bake reports, to see how far it got.
#[derive(Default)]
struct Notes(std::sync::Mutex<Vec<String>>);

impl prt_bake::progress::Progress for Notes {
    fn note(&self, text: &str) {
        self.0.lock().expect("notes").push(text.to_string());
    }
}

#[test]
fn a_bake_past_max_memory_is_refused_before_it_starts() {
    let config_path =
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/bake.toml");
    let config = BakeConfig::from_file(&config_path).expect("config");
    let scene = prt_bake::scene::load(&config).expect("scene");
    let out = temp_path("refused.prtbake");
    let settings = PixelRunSettings {
        width: Some(64),
        height: Some(64),
        spp: Some(1),
        output: Some(out.clone()),
        max_memory: Some(10_000),
        basis_count: Some(2),
        ..Default::default()
    };
    let notes = Notes::default();
    let err = run_pixel(&config, &scene, &settings, &notes)
        .expect_err("must refuse")
        .to_string();
    assert!(err.contains("--max-memory"), "{err}");
    assert!(
        !out.exists(),
        "nothing may be written when the bake is refused"
    );
    // Refused before the expensive work: the estimate was reported, no basis was built.
    let notes = notes.0.into_inner().expect("notes");
    assert!(
        notes.iter().any(|n| n.contains("memory estimate")),
        "the estimate is reported before refusing: {notes:?}"
    );
    assert!(
        !notes.iter().any(|n| n.starts_with("basis ")),
        "a basis was built before the memory check: {notes:?}"
    );
}
