//! The stages' caching and determinism, and the environment's rotation: a view-only,
//! material-only or light change gives the image a fresh relighter gives, bit for bit; the
//! image is the same on any number of threads; a rotation turns the light on surfaces and in
//! the background by the documented convention, and 360 degrees restores the image.

use prt_formats::envmap::LatLongMap;
use prt_formats::pixel::Precision;
use prt_formats::Family;
use prt_runtime::hooks::{Kernel, LightCoefficients};
use prt_runtime::VertexRelighter;

use crate::common::*;

const UP: [f32; 3] = [0.0, 1.0, 0.0];
const FRONT: [f32; 3] = [0.0, 0.0, 1.0];
const W: u32 = 40;
const H: u32 = 36;

/// A deterministic generator for test data.
struct Lcg(u64);

impl Lcg {
    fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((self.0 >> 40) as f32 / (1u64 << 24) as f32)
    }
}

/// A 12 x 12 glossy grid with random T1 and T2 (f16), a visibility pattern, under an
/// asymmetric lat-long environment.
fn busy_bake(path: &std::path::Path) {
    let basis = constant_basis(0.06, [0.2, 0.1, 0.05, 0.05], true);
    let mesh = Mesh::grid(12, UP, 0);
    let nv = mesh.positions.len();
    let row = t0_rows(UP, Some(&basis));
    let rows: Vec<_> = (0..nv).map(|_| row.clone()).collect();
    let mut g = Group::new((0..nv as u32).collect(), &rows, 3, 2, 1);
    let mut rng = Lcg(7);
    for x in g.t1.iter_mut().chain(g.t2.iter_mut()) {
        *x = rng.uniform(-0.01, 0.05);
    }
    for (k, v) in g.visibility.iter_mut().enumerate() {
        *v = ((k * 7 + k / 1536) % 256) as u8;
    }
    let materials = vec![
        material("metal", Family::Ggx, [0.3, 0.4, 0.2], [0.8, 0.6, 0.4], 0.3),
        material("wall", Family::Diffuse, [0.6, 0.2, 0.2], [0.0; 3], 0.0),
    ];
    let mut bake = Bake::new(
        mesh,
        materials,
        vec![(0, g, Some(0))],
        vec![basis],
        [1.0; 3],
    );
    bake.meta.precision = Precision::F16;
    bake.meta.reflections = 3;
    bake.set_latlong(64, 32, asymmetric_map(64, 32), 10.0);
    bake.write(path);
}

fn same_bits(a: &[f32], b: &[f32], what: &str) {
    assert_eq!(a.len(), b.len());
    let diff = a
        .iter()
        .zip(b)
        .position(|(x, y)| x.to_bits() != y.to_bits());
    assert!(diff.is_none(), "{what}: first difference at {diff:?}");
}

#[test]
fn cached_stages_give_the_image_of_a_fresh_relighter_bit_for_bit() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("busy.prtbake");
    busy_bake(&path);
    let cam1 = camera([0.4, 1.8, 2.2], 50.0);
    let cam2 = camera([-1.0, 1.2, 1.9], 60.0);
    let edit = "metal.kd=0.9,0.1,0.5";
    let mut a = VertexRelighter::open(&path).expect("open");
    let mut out = vec![0.0f32; (3 * W * H) as usize];
    let s = frame(&mut a, &cam1, W, H, &mut out).expect("render");
    assert!(s.light_s.is_some() && s.material_s.is_some());
    // View only.
    let s = frame(&mut a, &cam2, W, H, &mut out).expect("render");
    assert!(s.light_s.is_none() && s.material_s.is_none(), "{s:?}");
    let fresh = |setup: &dyn Fn(&mut VertexRelighter)| {
        let mut b = VertexRelighter::open(&path).expect("open");
        setup(&mut b);
        render(&mut b, &cam2, W, H)
    };
    same_bits(&out, &fresh(&|_| {}), "view change");
    // Materials only.
    set(&mut a, edit).expect("edit");
    let s = a.render_into(&mut out).expect("render");
    assert!(s.light_s.is_none() && s.material_s.is_some(), "{s:?}");
    same_bits(
        &out,
        &fresh(&|b| set(b, edit).expect("edit")),
        "material change",
    );
    // Light: a rotation.
    a.set_environment_rotation(40.0).expect("rotation");
    let s = a.render_into(&mut out).expect("render");
    assert!(s.light_s.is_some() && s.material_s.is_some(), "{s:?}");
    let both = |b: &mut VertexRelighter| {
        set(b, edit).expect("edit");
        b.set_environment_rotation(40.0).expect("rotation");
    };
    same_bits(&out, &fresh(&both), "light change");
    // An unchanged rotation keeps the light.
    a.set_environment_rotation(40.0).expect("rotation");
    let s = a.render_into(&mut out).expect("render");
    assert!(s.light_s.is_none() && s.material_s.is_none(), "{s:?}");
    // The image is not trivial: the surface shows and varies.
    let distinct: std::collections::BTreeSet<u32> = out.iter().map(|v| v.to_bits()).collect();
    assert!(distinct.len() > 500, "{}", distinct.len());
}

#[test]
fn the_avx2_and_portable_view_stages_give_the_same_bits() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("busy.prtbake");
    busy_bake(&path);
    let mut r = VertexRelighter::open(&path).expect("open");
    // Glossy and diffuse pixels, the background, and a grazing view near the horizon.
    for (eye, fov) in [([0.4, 1.5, 2.0], 60.0), ([-2.5, 0.15, 0.3], 70.0)] {
        let cam = camera(eye, fov);
        r.set_kernel(Kernel::Auto);
        let auto = render(&mut r, &cam, W, H);
        r.set_kernel(Kernel::Scalar);
        let scalar = render(&mut r, &cam, W, H);
        let lit = scalar.iter().filter(|&&v| v > 0.0).count();
        assert!(lit > scalar.len() / 2, "{eye:?}: mostly black ({lit} lit)");
        same_bits(&auto, &scalar, &format!("eye {eye:?}"));
    }
}

#[test]
fn the_image_is_the_same_on_any_number_of_threads() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("busy.prtbake");
    busy_bake(&path);
    let cam = camera([0.4, 1.8, 2.2], 50.0);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let mut r = VertexRelighter::open(&path).expect("open");
            let mut img = render(&mut r, &cam, W, H);
            set(&mut r, "metal.alpha=0.7").expect("edit");
            img.extend(render(&mut r, &cam, W, H));
            let inc = r.vertex_incident(77).expect("stages").expect("vertex");
            img.extend(inc.one_bounce_sh.iter().flatten());
            img
        })
    };
    let one = run(1);
    for threads in [2, 3, 5] {
        same_bits(&one, &run(threads), &format!("{threads} threads"));
    }
}

#[test]
fn a_rotation_turns_the_light_and_360_degrees_restores_the_image() {
    let (mw, mh) = (64, 32);
    let map = asymmetric_map(mw, mh);
    let kd = [0.7f32, 0.5, 0.6];
    let mesh = Mesh::quad(FRONT, 0);
    let rows: Vec<_> = (0..4).map(|_| t0_rows(FRONT, None)).collect();
    let g = Group::new(vec![0, 1, 2, 3], &rows, 0, 0, 1);
    let m = material("panel", Family::Diffuse, kd, [0.0; 3], 0.0);
    let mut bake = Bake::new(mesh, vec![m], vec![(0, g, None)], Vec::new(), [1.0; 3]);
    bake.set_latlong(mw, mh, map.clone(), 0.0);
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("panel.prtbake");
    bake.write(&path);
    let mut r = VertexRelighter::open(&path).expect("open");
    let cam = camera([0.5, 0.8, 3.0], 50.0);
    let texels: Vec<[f32; 3]> = map.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let ll = LatLongMap::new(mw, mh, texels, 1.0).expect("map").0;
    let mut images = Vec::new();
    for rotation in [0.0f32, 90.0, 360.0] {
        r.set_environment_rotation(rotation).expect("rotation");
        let img = render(&mut r, &cam, W, H);
        // On the panel: Kd / pi times the irradiance of the turned light (the cube's midpoint
        // rule, which the stored T0 rows integrate exactly).
        let light = LightCoefficients::from_latlong(&ll, rotation as f64, &[]).expect("light");
        let e: Vec<f64> = (0..3)
            .map(|ch| {
                direct_texels()
                    .iter()
                    .zip(light.cube.texels())
                    .map(|((d, w), l)| d[2].max(0.0) * w * l[ch] as f64)
                    .sum()
            })
            .collect();
        let mut inside = 0;
        for y in 0..H {
            for x in 0..W {
                let Some(p) = hit_plane(&cam, W, H, x, y, FRONT) else {
                    continue;
                };
                if p[0].abs() > 0.97 || p[1].abs() > 0.97 {
                    continue;
                }
                inside += 1;
                for ch in 0..3 {
                    let want = kd[ch] as f64 * e[ch] / std::f64::consts::PI;
                    let got = img[(3 * (y * W + x)) as usize + ch] as f64;
                    assert!(
                        (got - want).abs() <= 1e-4 * want,
                        "rotation {rotation}: ({x}, {y}) channel {ch}: {got} vs {want}"
                    );
                }
            }
        }
        assert!(inside > 300, "{inside}");
        images.push(img);
    }
    // 90 degrees changes the panel's light (the warm patch moves from -Z to -X).
    let changed = images[0]
        .iter()
        .zip(&images[1])
        .filter(|(a, b)| (*a - *b).abs() > 0.01 * a.abs().max(0.01))
        .count();
    assert!(changed > 300, "{changed}");
    for (a, b) in images[0].iter().zip(&images[2]) {
        assert!((a - b).abs() <= 1e-5 * a.abs().max(1.0), "{a} vs {b}");
    }
    // The background by the convention: bright towards -Z unrotated; turned +90 degrees about
    // +Y, bright towards -X.
    let towards_minus_x = prt_formats::view::CameraSpec {
        eye: [0.0, 0.5, 3.0],
        target: [-10.0, 5.0, 3.0],
        fov_deg: 20.0,
    }
    .frame()
    .expect("camera");
    let centre = |r: &mut VertexRelighter| {
        let img = render(r, &towards_minus_x, 9, 9);
        img[3 * (4 * 9 + 4)]
    };
    r.set_environment_rotation(0.0).expect("rotation");
    let dim = centre(&mut r);
    r.set_environment_rotation(90.0).expect("rotation");
    let warm = centre(&mut r);
    assert!(
        (dim - 0.2).abs() < 1e-3 && (warm - 6.0).abs() < 1e-3,
        "{dim} {warm}"
    );
}
