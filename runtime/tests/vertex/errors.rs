//! What the per-vertex runtime refuses, and how it says so: a bake of the other kind (both
//! ways), one corruption at a time (each error names the tensor or field), bad cameras, bad
//! environments and bad edits; nothing is written to the output on error.

use prt_formats::pixel::Precision;
use prt_formats::Family;
use prt_runtime::{OverrideValue, PixelRelighter, RuntimeError, VertexRelighter};

use crate::common::*;
use crate::pixel_synthetic;

const UP: [f32; 3] = [0.0, 1.0, 0.0];

/// Two materials on one quad each (the glossy one with a shading basis), reflections 3,
/// one T2 slot.
fn two_quads() -> Bake {
    let basis = constant_basis(0.05, [0.1, 0.05, 0.03, 0.02], false);
    let mut mesh = Mesh::quad(UP, 0);
    let other = Mesh::quad(UP, 1);
    for (p, n) in other.positions.iter().zip(&other.normals) {
        mesh.positions.push([p[0] + 3.0, p[1], p[2]]);
        mesh.normals.push(*n);
    }
    mesh.uvs.extend(&other.uvs);
    for t in &other.triangles {
        mesh.triangles.push(t.map(|v| v + 4));
    }
    mesh.triangle_material.extend(&other.triangle_material);
    let diffuse_rows: Vec<_> = (0..4).map(|_| t0_rows(UP, None)).collect();
    let glossy_rows: Vec<_> = (0..4).map(|_| t0_rows(UP, Some(&basis))).collect();
    let g0 = Group::new(vec![0, 1, 2, 3], &diffuse_rows, 2, 1, 1);
    let g1 = Group::new(vec![4, 5, 6, 7], &glossy_rows, 2, 1, 1);
    let mut fixed = material("stone", Family::Diffuse, [0.4; 3], [0.0; 3], 0.0);
    fixed.editable = false;
    let materials = vec![
        material("floor", Family::Diffuse, [0.5; 3], [0.0; 3], 0.0),
        material("metal", Family::Ggx, [0.1; 3], [0.8; 3], 0.3),
        fixed,
    ];
    let mut bake = Bake::new(
        mesh,
        materials,
        vec![(0, g0, None), (1, g1, Some(0))],
        vec![basis],
        [1.0; 3],
    );
    bake.meta.reflections = 3;
    bake
}

fn open_err(bake: &Bake) -> String {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("bad.prtbake");
    bake.write(&path);
    match VertexRelighter::open(&path) {
        Ok(_) => panic!("a corrupt bake was opened"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn the_reference_bake_opens() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("good.prtbake");
    two_quads().write(&path);
    let mut r = VertexRelighter::open(&path).expect("open");
    let img = render(&mut r, &camera([1.5, 2.0, 3.0], 50.0), 16, 16);
    assert!(img.iter().all(|v| v.is_finite()));
}

/// Schema 3 gives each group its own count of T0 terms (at most the bake's); older files have
/// none and use the bake's. A group cut to fewer terms relights exactly like the same terms
/// padded to the bake's count, and older schemas still open.
#[test]
fn group_t0_terms_are_read_and_older_schemas_still_open() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cam = camera([1.5, 2.0, 3.0], 50.0);
    let relit = |b: &Bake, name: &str| {
        let path = dir.path().join(name);
        b.write(&path);
        render(
            &mut VertexRelighter::open(&path).expect("open"),
            &cam,
            16,
            16,
        )
    };
    let keep = 300;
    let mut padded = two_quads();
    padded.cut_t0(1, keep, false);
    let mut own = two_quads();
    own.cut_t0(1, keep, true);
    assert_eq!(own.meta.groups[1].t0_terms, Some(keep as u32));
    assert!(own.meta.t0_terms as usize > keep);
    let reference = relit(&padded, "padded.prtbake");
    assert!(relit(&own, "own.prtbake") == reference, "own count");
    for version in [1, 2, 3] {
        let mut old = padded.clone();
        old.meta.vertex_schema_version = version;
        let img = relit(&old, &format!("schema{version}.prtbake"));
        assert!(img == reference, "schema {version}");
    }
}

#[test]
fn a_bake_of_the_other_kind_is_refused_with_what_to_use() {
    let dir = tempfile::tempdir().expect("temp dir");
    let pixel = dir.path().join("pixel.prtbake");
    pixel_synthetic::Synthetic::new(1, None, 3).write(&pixel, Precision::F32);
    let vertex = dir.path().join("vertex.prtbake");
    two_quads().write(&vertex);
    match VertexRelighter::open(&pixel) {
        Err(e @ RuntimeError::WrongKind { .. }) => {
            let msg = e.to_string();
            assert!(
                msg.contains("per-pixel bake, not a per-vertex") && msg.contains("PixelRelighter"),
                "{msg}"
            );
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("a per-pixel bake opened as per-vertex"),
    }
    match PixelRelighter::open(&vertex) {
        Err(e @ RuntimeError::WrongKind { .. }) => {
            let msg = e.to_string();
            assert!(
                msg.contains("per-vertex bake, not a per-pixel") && msg.contains("VertexRelighter"),
                "{msg}"
            );
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("a per-vertex bake opened as per-pixel"),
    }
    // Each still opens with its own runtime.
    PixelRelighter::open(&pixel).expect("pixel bake");
    VertexRelighter::open(&vertex).expect("vertex bake");
}

#[test]
fn each_corruption_is_refused_naming_the_tensor() {
    type Corrupt = fn(&mut Bake);
    let cases: Vec<(&str, Corrupt, &[&str])> = vec![
        (
            "an extra active slot",
            |b| b.meta.groups[0].active.push(2),
            &["v0.t1", "shape"],
        ),
        (
            "fewer T0 terms",
            |b| b.meta.t0_terms -= 1,
            &["v0.t0.index", "shape"],
        ),
        (
            "an extra T2 slot",
            |b| b.meta.t2_slots.push(3),
            &["v0.t2", "shape"],
        ),
        (
            "a Haar index out of range",
            |b| b.groups[1].t0_index[5] = 30000,
            &["v1.t0.index", "30000"],
        ),
        (
            "T1 stored as f16",
            |b| b.t1_stored_as = Some(Precision::F16),
            &["v0.t1", "stored as F16, expected F32"],
        ),
        (
            "a triangle index out of range",
            |b| b.mesh.triangles[3][1] = 8,
            &["mesh.triangles", "triangle 3", "vertex 8"],
        ),
        (
            "a triangle material out of range",
            |b| b.mesh.triangle_material[1] = 7,
            &["mesh.triangle_material", "triangle 1"],
        ),
        (
            "a group vertex out of range",
            |b| b.groups[1].vertices[3] = 9,
            &["v1.vertices", "vertex 9"],
        ),
        (
            "a vertex in two groups",
            |b| b.groups[1].vertices[0] = 3,
            &["v1.vertices", "vertex 3", "group 0"],
        ),
        (
            "a triangle using another group's vertex",
            |b| b.mesh.triangles[2][0] = 1,
            &["triangle 2", "v1.vertices"],
        ),
        (
            "a non-finite position",
            |b| b.mesh.positions[6][1] = f32::NAN,
            &["mesh.positions", "vertex 6"],
        ),
        (
            "a zero normal",
            |b| b.mesh.normals[2] = [0.0; 3],
            &["mesh.normals", "normal 2"],
        ),
        (
            "a short shading table",
            |b| {
                b.shading[0].u_i.pop();
            },
            &["shading basis 0", "u_i"],
        ),
        (
            "a non-finite environment",
            |b| {
                let mut map = asymmetric_map(8, 4);
                map[7] = f32::INFINITY;
                b.set_latlong(8, 4, map, 0.0);
            },
            &["environment", "NaN or infinite"],
        ),
        (
            "a group storing 0 T0 terms",
            |b| b.groups_meta_t0_terms(0, 0),
            &["group 0", "t0_terms = 0", "1 ..= the bake's t0_terms"],
        ),
        (
            "a group storing more T0 terms than the bake kept",
            |b| {
                let above = b.meta.t0_terms + 1;
                b.groups_meta_t0_terms(1, above);
            },
            &["group 1", "t0_terms =", "1 ..= the bake's t0_terms"],
        ),
        (
            "a group's T0 terms that do not match its tensors",
            |b| {
                let fewer = b.meta.t0_terms - 1;
                b.groups_meta_t0_terms(1, fewer);
            },
            &["v1.t0.index", "shape"],
        ),
        (
            "an open-sky flag that is neither 0 nor 1",
            |b| b.groups[1].t0_open[2] = 2,
            &["v1.t0.open", "flag 2", "vertex 2"],
        ),
        (
            "another schema version",
            |b| b.meta.vertex_schema_version = 99,
            &["vertex schema version 99"],
        ),
        (
            "a normal map that is not among the textures",
            |b| b.meta.material_normal_maps = vec![Some(7); b.meta.materials.len()],
            &["material normal map 7 out of range"],
        ),
        (
            "normal maps not one per material",
            |b| b.meta.material_normal_maps = vec![None; b.meta.materials.len() + 1],
            &["material_normal_maps", "one entry per material"],
        ),
    ];
    for (what, corrupt, words) in cases {
        let mut b = two_quads();
        corrupt(&mut b);
        let msg = open_err(&b);
        for w in words {
            assert!(msg.contains(w), "{what}: {msg:?} does not say {w:?}");
        }
    }
}

#[test]
fn bad_cameras_and_outputs_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("good.prtbake");
    two_quads().write(&path);
    let mut r = VertexRelighter::open(&path).expect("open");
    let good = camera([1.5, 2.0, 3.0], 50.0);
    let mut out = vec![-7.0f32; 3 * 8 * 8];
    let mut zero_fov = good;
    zero_fov.yfov = 0.0;
    let mut nan_eye = good;
    nan_eye.position[0] = f32::NAN;
    r.set_size(8, 8).expect("size");
    r.set_camera(good).expect("camera");
    for (cam, words) in [(zero_fov, "field of view"), (nan_eye, "not finite")] {
        let e = r.set_camera(cam).expect_err("bad camera");
        assert!(e.to_string().contains(words), "{e}");
        assert_eq!(r.camera(), good, "a refused camera was kept");
    }
    let e = r.set_size(0, 8).expect_err("empty image");
    assert!(e.to_string().contains("0x8"), "{e}");
    assert_eq!(r.size(), (8, 8), "a refused size was kept");
    let e = r.set_size(8, 16385).expect_err("huge image");
    assert!(e.to_string().contains("8x16385"), "{e}");
    r.set_size(8, 9).expect("size");
    let e = r.render_into(&mut out).expect_err("wrong output size");
    assert!(matches!(e, RuntimeError::BufferSize { .. }), "{e}");
    assert!(out.iter().all(|&v| v == -7.0), "written on error");

    // An eye inside a closed box.
    let mesh = Mesh::closed_box(0);
    let nv = mesh.positions.len();
    let rows: Vec<_> = (0..nv).map(|_| vec![vec![0.0f32; 4]]).collect();
    let g = Group::new((0..nv as u32).collect(), &rows, 0, 0, 1);
    let m = material("crate", Family::Diffuse, [0.5; 3], [0.0; 3], 0.0);
    let boxed = Bake::new(mesh, vec![m], vec![(0, g, None)], Vec::new(), [1.0; 3]);
    let path = dir.path().join("box.prtbake");
    boxed.write(&path);
    let mut r = VertexRelighter::open(&path).expect("open");
    let inside = prt_formats::view::CameraSpec {
        eye: [0.1, 0.2, 0.0],
        target: [0.0, 0.0, -1.0],
        fov_deg: 60.0,
    }
    .frame()
    .expect("camera");
    let e = r.set_camera(inside).expect_err("eye inside");
    assert!(matches!(e, RuntimeError::EyeInside { .. }), "{e}");
    assert!(e.to_string().contains("inside 'crate'"), "{e}");
    assert_eq!(r.camera(), r.default_camera(), "a refused camera was kept");
    // Outside, the box renders.
    render(&mut r, &camera([3.0, 2.0, 4.0], 50.0), 8, 8);
}

#[test]
fn bad_environments_and_edits_are_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("good.prtbake");
    two_quads().write(&path);
    let mut r = VertexRelighter::open(&path).expect("open");
    let e = r
        .set_environment_texels(2, 1, &[1.0, 1.0, 1.0, f32::NAN, 0.0, 0.0])
        .expect_err("NaN texel");
    assert!(e.to_string().contains("NaN or infinite"), "{e}");
    let e = r
        .set_environment_texels(2, 2, &[1.0; 9])
        .expect_err("texel count");
    assert!(
        e.to_string()
            .contains("environment's texels holds 9 floats; a 2x2 RGB image needs 12"),
        "{e}"
    );
    let e = r
        .set_environment_rotation(f32::INFINITY)
        .expect_err("rotation");
    assert!(e.to_string().contains("rotation"), "{e}");
    for bad in [-1.0, f32::NAN, f32::INFINITY] {
        let e = r.set_environment_intensity(bad).expect_err("bad intensity");
        assert!(e.to_string().contains("intensity"), "{e}");
        assert_eq!(
            r.environment_intensity(),
            1.0,
            "a refused intensity was kept"
        );
    }
    let report = r
        .set_environment_texels(2, 1, &[1.0, 1.0, 1.0, -1.0, 0.5, 0.5])
        .expect("negative channels are clamped");
    assert_eq!(report.clamped_texels, 1);

    assert!(matches!(
        set(&mut r, "stone.kd=0.1,0.1,0.1"),
        Err(RuntimeError::NotEditable { .. })
    ));
    assert!(matches!(
        set(&mut r, "floor.alpha=0.2"),
        Err(RuntimeError::WrongParam { .. })
    ));
    assert!(matches!(
        set(&mut r, "nothing.kd=1"),
        Err(RuntimeError::UnknownMaterial { .. })
    ));
    let e = r
        .set_params("metal", &[OverrideValue::Ks([-1.0, 0.0, 0.0])])
        .expect_err("negative ks");
    assert!(matches!(e, RuntimeError::OutOfRange { .. }), "{e}");
    assert!(e.to_string().contains("ks"), "{e}");
    r.set_params(
        "metal",
        &[OverrideValue::Ks([0.5; 3]), OverrideValue::Alpha(0.6)],
    )
    .expect("good params");
    assert_eq!(r.params("metal").expect("params").param, 0.6);
}

#[test]
fn corrupt_compressed_groups_are_refused_naming_the_tensor() {
    let mut good = two_quads();
    good.compress_as_identity = true;
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("good.prtbake");
    good.write(&path);
    VertexRelighter::open(&path).expect("the identity-compressed bake opens");
    let cases: [(Tamper, &str); 2] = [
        // Vertex 3 moves to cluster 0: cluster 1 keeps its rank 2 with 1 vertex left.
        (
            |c| c[3] = 0,
            "cluster 1 has vertex rank 2, more than its 1 vertices",
        ),
        (
            |c| c[0] = 9,
            "v0.clusters: vertex 0 is in cluster 9, but there are 2",
        ),
    ];
    for (tamper, want) in cases {
        let mut bad = two_quads();
        bad.compress_as_identity = true;
        bad.tamper_clusters = Some(tamper);
        let e = open_err(&bad);
        assert!(e.contains(want), "expected {want:?} in: {e}");
    }
}
