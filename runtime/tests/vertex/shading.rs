//! The view stage against values computed here from the definitions: a quad facing +Y under a
//! constant environment, diffuse, glossy with hand-made shading bases, textured; the
//! background; the side without data.

use prt_formats::basis::cosine_centroid;
use prt_formats::lighting::cubemap::{
    direction_to_face_st, direction_to_texel, face_ab_to_vector, texel_index,
};
use prt_formats::lighting::Face;
use prt_formats::texture::sample_bilinear;
use prt_formats::vertex::{to_local, vertex_frame, VISIBILITY_CUBE};
use prt_formats::Family;
use prt_runtime::VertexRelighter;

use crate::common::*;

const UP: [f32; 3] = [0.0, 1.0, 0.0];
const L: [f32; 3] = [1.0, 2.0, 0.5];
const W: u32 = 48;
const H: u32 = 40;

/// Pixels of a `W x H` view of the quad: `(x, y, Some(hit point))` well inside the quad,
/// `(x, y, None)` well outside it (the background); pixels near the quad's edges are left out.
fn classify(cam: &prt_formats::view::CameraFrame) -> Vec<(u32, u32, Option<[f64; 3]>)> {
    let mut out = Vec::new();
    for y in 0..H {
        for x in 0..W {
            match hit_plane(cam, W, H, x, y, UP) {
                Some(p) if p[0].abs() < 0.97 && p[2].abs() < 0.97 => out.push((x, y, Some(p))),
                Some(p) if p[0].abs() < 1.03 && p[2].abs() < 1.03 => {}
                _ => out.push((x, y, None)),
            }
        }
    }
    let inside = out.iter().filter(|p| p.2.is_some()).count();
    assert!(
        inside > 200 && out.len() - inside > 100,
        "{inside} of {}",
        out.len()
    );
    out
}

fn open(bake: &Bake) -> (tempfile::TempDir, VertexRelighter) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("v.prtbake");
    bake.write(&path);
    let r = VertexRelighter::open(&path).expect("open");
    (dir, r)
}

fn close(got: &[f32], want: [f64; 3], rel: f64, what: &str) {
    for c in 0..3 {
        let tol = rel * want[c].abs().max(1e-3);
        assert!(
            (got[c] as f64 - want[c]).abs() <= tol,
            "{what}: channel {c}: {} vs {}",
            got[c],
            want[c]
        );
    }
}

fn diffuse_quad(kd: [f32; 3]) -> Bake {
    let mesh = Mesh::quad(UP, 0);
    let rows: Vec<_> = (0..4).map(|_| t0_rows(UP, None)).collect();
    let g = Group::new(vec![0, 1, 2, 3], &rows, 0, 0, 1);
    let m = material("floor", Family::Diffuse, kd, [0.0; 3], 0.0);
    Bake::new(mesh, vec![m], vec![(0, g, None)], Vec::new(), L)
}

#[test]
fn diffuse_under_a_constant_environment_is_kd_times_l() {
    let kd = [0.5, 0.3, 0.8];
    let (_dir, mut r) = open(&diffuse_quad(kd));
    let cam = camera([0.0, 2.0, 2.5], 45.0);
    let img = render(&mut r, &cam, W, H);
    for (x, y, hit) in classify(&cam) {
        let px = &img[3 * (y * W + x) as usize..][..3];
        let want: [f64; 3] = match hit {
            Some(_) => std::array::from_fn(|c| (kd[c] * L[c]) as f64),
            None => L.map(f64::from),
        };
        close(px, want, 1e-3, &format!("pixel ({x}, {y})"));
    }
    // From below, the quad shows its side without data: black, the sky still lit.
    let below = camera([0.0, -2.0, 2.5], 45.0);
    let img = render(&mut r, &below, W, H);
    for (x, y, hit) in classify(&below) {
        let px = &img[3 * (y * W + x) as usize..][..3];
        match hit {
            Some(_) => assert_eq!(px, [0.0; 3], "pixel ({x}, {y})"),
            None => close(px, L.map(f64::from), 1e-6, "background"),
        }
    }
}

/// Per-texel data of a cube of side `n` (`value(texel index)`) read bilinearly in direction
/// `d`, across face edges: the texel grid of `d`'s face continued onto the plane beyond each
/// edge, a missing texel being the one that holds its continued centre's direction. Written
/// out here from that definition (the runtime uses `cubemap::bilinear_taps`).
fn visibility_at(n: usize, d: [f64; 3], value: impl Fn(usize) -> f64) -> f64 {
    let (face, s, t) = direction_to_face_st(d);
    let nf = n as f64;
    let (fx, fy) = (s * nf - 0.5, t * nf - 0.5);
    let (i0, j0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - i0, fy - j0);
    let mut v = 0.0;
    for (di, dj, w) in [
        (0.0, 0.0, (1.0 - tx) * (1.0 - ty)),
        (1.0, 0.0, tx * (1.0 - ty)),
        (0.0, 1.0, (1.0 - tx) * ty),
        (1.0, 1.0, tx * ty),
    ] {
        // The texel's centre in the face's [-1, 1] coordinates, as a direction.
        let a = 2.0 * (i0 + di + 0.5) / nf - 1.0;
        let b = 2.0 * (j0 + dj + 0.5) / nf - 1.0;
        let (f, i, j) = direction_to_texel(n, face_ab_to_vector(face, a, b));
        v += w * value(texel_index(n, f, i, j));
    }
    v
}

fn glossy_quad(
    a: f32,
    refl: [f32; 4],
    view_dependent: bool,
    visibility: impl Fn(usize) -> u8,
) -> Bake {
    let basis = constant_basis(a, refl, view_dependent);
    let mesh = Mesh::quad(UP, 0);
    let rows: Vec<_> = (0..4).map(|_| t0_rows(UP, Some(&basis))).collect();
    let mut g = Group::new(vec![0, 1, 2, 3], &rows, 0, 0, 1);
    let per_vertex = 6 * VISIBILITY_CUBE * VISIBILITY_CUBE;
    for (k, v) in g.visibility.iter_mut().enumerate() {
        *v = visibility(k % per_vertex);
    }
    let m = material("metal", Family::Ggx, [0.2, 0.4, 0.1], [0.9, 0.6, 0.3], 0.3);
    Bake::new(mesh, vec![m], vec![(0, g, Some(0))], vec![basis], L)
}

#[test]
fn a_glossy_material_adds_ks_times_l_times_the_bases_albedo() {
    let (a, refl) = (0.05f32, [0.1f32, 0.05, 0.03, 0.02]);
    let cam = camera([0.5, 2.0, 2.5], 45.0);
    let (kd, ks) = ([0.2f32, 0.4, 0.1], [0.9f32, 0.6, 0.3]);
    let pi = std::f64::consts::PI;
    let e = cube_cosine_integral(UP);
    for (visible, split) in [(255u8, refl.iter().sum::<f32>() as f64), (0, 0.0)] {
        let (_dir, mut r) = open(&glossy_quad(a, refl, false, |_| visible));
        let img = render(&mut r, &cam, W, H);
        // B = Kd L E / pi + Ks L (a E + V sum_w R_w), E ~ pi the cube's cosine integral.
        for (x, y, hit) in classify(&cam) {
            let px = &img[3 * (y * W + x) as usize..][..3];
            let want: [f64; 3] = match hit {
                Some(_) => std::array::from_fn(|c| {
                    let l = L[c] as f64;
                    kd[c] as f64 * l * e / pi + ks[c] as f64 * l * (a as f64 * e + split)
                }),
                None => L.map(f64::from),
            };
            close(
                px,
                want,
                1e-3,
                &format!("visibility {visible}, pixel ({x}, {y})"),
            );
        }
    }
}

#[test]
fn glossy_shading_follows_the_view_and_the_mirror_directions_visibility() {
    // U^o = wo.z (view-dependent residual); the visibility cube is seen through its +Y face
    // fully, through -Z half, elsewhere not, so the split's direct part shows which face the
    // mirror direction (not the view direction, which leaves through +Z) goes through.
    let (a, refl) = (0.08f32, [0.2f32, 0.1, 0.05, 0.05]);
    let per_face = VISIBILITY_CUBE * VISIBILITY_CUBE;
    let face_visibility = |f: usize| [0u8, 0, 255, 0, 0, 128][f];
    let bake = glossy_quad(a, refl, true, |k| face_visibility(k / per_face));
    let basis = bake.shading[0].clone();
    let (_dir, mut r) = open(&bake);
    let cam = camera([0.0, 2.0, 2.5], 50.0);
    let img = render(&mut r, &cam, W, H);
    let (kd, ks, param) = ([0.2f32, 0.4, 0.1], [0.9f32, 0.6, 0.3], 0.3);
    let e = cube_cosine_integral(UP);
    let (t, b) = vertex_frame(UP);
    let (mut seen_visible, mut seen_hidden) = (0, 0);
    for (x, y, hit) in classify(&cam) {
        let Some(p) = hit else { continue };
        let eye = cam.position.map(f64::from);
        let d: [f64; 3] = std::array::from_fn(|i| eye[i] - p[i]);
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let wo = d.map(|c| (c / len) as f32);
        let wo_l = to_local(t, b, UP, wo);
        let mut uo = [0.0f32; 32];
        basis.u_o_row(wo_l, &mut uo);
        let mut rw = [0.0f32; 8];
        basis.reflectances_into(param, wo_l, &mut rw);
        // The mirror direction in the world: 2 (n . wo) n - wo.
        let r_w = [-wo[0], wo[1], -wo[2]].map(f64::from);
        let face = direction_to_texel(VISIBILITY_CUBE, r_w).0;
        match face {
            Face::PosY => seen_visible += 1,
            _ => seen_hidden += 1,
        }
        // Each width's visibility is read at its cosine-weighted centroid (the mirror
        // direction raised towards the normal), bilinear between texel centres: within half a
        // texel of a face edge the faces blend.
        let r_l = [-wo_l[0], -wo_l[1], wo_l[2]];
        let split: f64 = (0..4)
            .map(|k| {
                let sigma = basis.rendered_width_deg(k).expect("width").to_radians();
                let c = cosine_centroid(r_l, sigma);
                let c_w: [f64; 3] =
                    std::array::from_fn(|i| f64::from(t[i] * c[0] + b[i] * c[1] + UP[i] * c[2]));
                let v = visibility_at(VISIBILITY_CUBE, c_w, |t| {
                    face_visibility(t / per_face) as f64 / 255.0
                });
                rw[k] as f64 * v
            })
            .sum();
        let want: [f64; 3] = std::array::from_fn(|c| {
            let l = L[c] as f64;
            let spec = a as f64 * uo[0] as f64 * e * l + split * l;
            kd[c] as f64 * l * e / std::f64::consts::PI + ks[c] as f64 * spec
        });
        let px = &img[3 * (y * W + x) as usize..][..3];
        close(px, want, 1e-3, &format!("pixel ({x}, {y})"));
    }
    assert!(
        seen_visible > 50 && seen_hidden > 50,
        "{seen_visible} {seen_hidden}"
    );
}

#[test]
fn a_turning_camera_sees_a_smooth_reflection_of_nearby_geometry() {
    // A visibility that changes at every texel (0 or 255 at random): the reflection of nearby
    // objects at the scale of the 16-cube. The camera orbits in steps of 0.15 degrees, a
    // small fraction of a texel (5.6 degrees at a face's centre, 2.8 at its corners), so
    // between neighbouring frames no pixel's reflection may jump: read at the nearest texel
    // it jumped by the whole contrast where the mirror direction crossed a texel edge.
    let (a, refl) = (0.0f32, [0.2f32, 0.1, 0.05, 0.05]);
    let pattern = |k: usize| {
        if (k.wrapping_mul(2_654_435_761) >> 9) & 1 == 1 {
            255u8
        } else {
            0
        }
    };
    let (_d, mut lit) = open(&glossy_quad(a, refl, false, pattern));
    let (_d1, mut seen) = open(&glossy_quad(a, refl, false, |_| 255));
    let (_d0, mut hidden) = open(&glossy_quad(a, refl, false, |_| 0));
    let step = 0.15f32.to_radians();
    let eye = |k: usize| {
        let phi = 0.4 + k as f32 * step;
        [2.5 * phi.sin(), 2.0, 2.5 * phi.cos()]
    };
    let frames = 61;
    let sum = |p: &[f32]| p.iter().map(|&v| f64::from(v)).sum::<f64>();
    let (mut worst, mut moved, mut pairs, mut large) = (0.0f64, 0usize, 0usize, 0usize);
    let first = render(&mut lit, &camera(eye(0), 45.0), W, H);
    let mut last = first.clone();
    for k in 1..frames {
        let cam = camera(eye(k), 45.0);
        let img = render(&mut lit, &cam, W, H);
        // The contrast of each pixel: its reflection wholly seen against wholly hidden.
        let (on, off) = (
            render(&mut seen, &cam, W, H),
            render(&mut hidden, &cam, W, H),
        );
        let inside_before: Vec<(u32, u32)> = classify(&camera(eye(k - 1), 45.0))
            .into_iter()
            .filter(|p| p.2.is_some())
            .map(|p| (p.0, p.1))
            .collect();
        for (x, y, hit) in classify(&cam) {
            if hit.is_none() || !inside_before.contains(&(x, y)) {
                continue;
            }
            let i = 3 * (y * W + x) as usize;
            let contrast = sum(&on[i..i + 3]) - sum(&off[i..i + 3]);
            assert!(contrast > 0.05, "pixel ({x}, {y}): contrast {contrast}");
            let jump: f64 = (0..3)
                .map(|c| f64::from((img[i + c] - last[i + c]).abs()))
                .sum();
            worst = worst.max(jump / contrast);
            pairs += 1;
            large += usize::from(jump > 0.1 * contrast);
            if k == frames - 1 {
                let change: f64 = (0..3)
                    .map(|c| f64::from((img[i + c] - first[i + c]).abs()))
                    .sum();
                moved += usize::from(change > 0.3 * contrast);
            }
        }
        last = img;
    }
    // Filtered as the prefiltered cubes are, the lookup is continuous but at face corners
    // (where a fourth texel is missing and taken from one of the corner's faces) and, to
    // within a texel's rounding, along face edges: a few jumps there, none of a whole texel.
    eprintln!("worst jump {worst:.3} of the contrast; {large} of {pairs} over 0.1");
    assert!(
        worst < 0.3,
        "a frame-to-frame jump of {worst:.3} of the contrast"
    );
    assert!(
        large * 200 < pairs,
        "{large} of {pairs} frame-to-frame jumps over a tenth of the contrast"
    );
    // Not vacuous: over the 9 degrees the reflection did change.
    assert!(
        moved > 50,
        "{moved} pixels changed by a third of their contrast"
    );
}

#[test]
fn a_texture_multiplies_kd_at_each_pixel() {
    let kd = [0.8, 0.6, 0.9];
    let mut bake = diffuse_quad(kd);
    // 2 x 2 texels: bilinear across the quad.
    let tex = vec![
        1.0, 0.2, 0.2, 0.2, 1.0, 0.2, //
        0.2, 0.2, 1.0, 1.0, 1.0, 1.0,
    ];
    bake.set_texture(0, 2, 2, tex.clone());
    let texels: Vec<[f32; 3]> = tex.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let (_dir, mut r) = open(&bake);
    let cam = camera([0.3, 2.0, 2.5], 45.0);
    let img = render(&mut r, &cam, W, H);
    let e = cube_cosine_integral(UP) / std::f64::consts::PI;
    for (x, y, hit) in classify(&cam) {
        let Some(p) = hit else { continue };
        let uv = [((p[0] + 1.0) / 2.0) as f32, ((p[2] + 1.0) / 2.0) as f32];
        let t = sample_bilinear(&texels, 2, 2, uv);
        let want: [f64; 3] = std::array::from_fn(|c| (kd[c] * t[c] * L[c]) as f64 * e);
        close(
            &img[3 * (y * W + x) as usize..][..3],
            want,
            2e-3,
            &format!("pixel ({x}, {y})"),
        );
    }
}

#[test]
fn reflected_light_reaches_the_last_reflection_through_sh_and_the_uniform_term() {
    // No direct light (T0 and visibility zero); one reflection off slot 0 arrives as SH
    // coefficients 0 and 2 (Y_00 and Y_10 in the vertex frame), two reflections as a uniform
    // radiance. With U^i = 1: E = U = Ehat_0 I1_0 + Ehat_2 I1_2 + pi I2, and the split sees
    // S_w = g_w0 I1_0 Y_00 + g_w1 I1_2 Y_10(r) + I2 with the normalized Gaussian's factors.
    let (a, refl) = (0.05f32, [0.2f32, 0.1, 0.3, 0.1]);
    let basis = constant_basis(a, refl, false);
    // Width 0 is rendered as a grid cell's Gaussian (`ShadingBasis::spike_width_deg`).
    let spike = f64::from(basis.spike_width_deg());
    let mesh = Mesh::quad(UP, 0);
    let rows: Vec<_> = (0..4).map(|_| vec![vec![0.0f32; 8]; 2]).collect();
    let mut g = Group::new(vec![0, 1, 2, 3], &rows, 1, 1, 1);
    g.visibility.fill(0);
    let (v0, v2, v_two) = (0.002f32, 0.001f32, 0.01f32);
    for v in 0..4 {
        for l in 0..384 {
            g.t1[(v * 384 + l) * 16] = v0;
            g.t1[(v * 384 + l) * 16 + 2] = v2;
        }
        for l in 0..24 {
            g.t2[v * 24 + l] = v_two;
        }
    }
    let (kd, ks) = ([0.3f32, 0.5, 0.7], [0.6f32, 0.4, 0.2]);
    let m = material("metal", Family::Ggx, kd, ks, 0.3);
    let mut bake = Bake::new(mesh, vec![m], vec![(0, g, Some(0))], vec![basis], L);
    bake.meta.reflections = 3;
    let (_dir, mut r) = open(&bake);
    let cam = camera([0.4, 2.0, 2.5], 50.0);
    let img = render(&mut r, &cam, W, H);
    let pi = std::f64::consts::PI;
    let (t, b) = vertex_frame(UP);
    // The slot coefficient of slot 0 (the material's Kd).
    let factors: Vec<[f64; 4]> = [spike, 7.0, 14.0, 21.0]
        .iter()
        .map(|&w| {
            let s = f64::to_radians(w);
            let f = prt_formats::lighting::prefilter::sh_factors(s).expect("factors");
            let k = prt_formats::lighting::prefilter::kernel_integral(s).expect("integral");
            f.map(|x| x / k)
        })
        .collect();
    for (x, y, hit) in classify(&cam) {
        let Some(p) = hit else { continue };
        let eye = cam.position.map(f64::from);
        let d: [f64; 3] = std::array::from_fn(|i| eye[i] - p[i]);
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let wo_l = to_local(t, b, UP, d.map(|c| (c / len) as f32));
        let want: [f64; 3] = std::array::from_fn(|ch| {
            let (c, l) = (kd[ch] as f64, L[ch] as f64);
            let i1_0 = c * l * 384.0 * v0 as f64;
            let i1_2 = c * l * 384.0 * v2 as f64;
            let i2 = c * c * l * 24.0 * v_two as f64;
            let e = pi.sqrt() / 2.0 * i1_0 + (pi / 3.0).sqrt() * i1_2 + pi * i2;
            // Y_00 and Y_10 = sqrt(3 / (4 pi)) z at the mirror direction (z unchanged).
            let (y0, y2) = (0.5 / pi.sqrt(), (3.0 / (4.0 * pi)).sqrt() * wo_l[2] as f64);
            let split: f64 = refl
                .iter()
                .zip(&factors)
                .map(|(&rw, g)| rw as f64 * (g[0] * i1_0 * y0 + g[1] * i1_2 * y2 + i2))
                .sum();
            c * e / pi + ks[ch] as f64 * (a as f64 * e + split)
        });
        let px = &img[3 * (y * W + x) as usize..][..3];
        close(px, want, 1e-4, &format!("pixel ({x}, {y})"));
    }
}
