//! Closed forms for bakes relit by the runtime: scenes whose radiance is known exactly (or by
//! an independent quadrature), baked once and relit for several material settings. They check
//! the whole chain (sampling, slot accumulation over up to four reflections, compaction, the
//! file, the coefficients and the contraction) against mathematics rather than against the
//! reference tracer, which shares the integrator.

use std::path::PathBuf;

use glam::{DVec3, Vec3};
use prt_bake::brdf::{BrdfParams, Family};
use prt_bake::pixel::{self, PixelBake, PixelBakeOptions, Precision, SlotLayout};
use prt_bake::progress::Silent;
use prt_bake::run::{build_bases, load, BasisCount};
use prt_bake::scene::Scene;
use prt_bake::testing::{
    albedo, camera_samples, closed_sphere_radiance, convex_furnace_scene, inside_sphere_scene,
    SPLIT_GEOMETRY,
};
use prt_formats::basis::BrdfBasis;
use prt_runtime::PixelRelighter;
use prt_tests::temp_path;

/// Bakes `scene` at `size` with `spp` samples, `reflections` reflections and `seed`, writes
/// the file; returns the bake (for its groups), the layout and the file's path.
fn bake(
    scene: &Scene,
    size: (u32, u32),
    spp: u32,
    reflections: u32,
    seed: u64,
    name: &str,
) -> (PixelBake, SlotLayout, PathBuf) {
    let bases = build_bases(scene, BasisCount::Default, &Silent).expect("bases");
    let layout = SlotLayout::new(scene, &bases).expect("layout");
    let opts = PixelBakeOptions {
        width: size.0,
        height: size.1,
        spp,
        // The identities below hold per camera sample (a pixel's emission and transfer from
        // the same samples add up to what they cover), so no extra emission samples.
        emission_oversampling: 1,
        reflections,
        seed,
        precision: Precision::F32,
        max_memory: None,
        compress_rank: None,
    };
    let bake = pixel::bake(scene, &layout, &opts, None).expect("bake");
    let path = temp_path(name);
    pixel::write_bake_file(&bake, &path, Precision::F32).expect("write bake file");
    (bake, layout, path)
}

/// Relights the bake at `path` with the `--set` edits.
fn relight(path: &PathBuf, edits: &[String]) -> Vec<[f32; 3]> {
    let mut r = PixelRelighter::open(path).expect("open bake");
    for e in edits {
        prt_tests::edit_pixel(&mut r, e).expect("apply");
    }
    r.render().expect("relight").pixels
}

/// For each material, the pixels whose camera samples all hit it: no other group, and no
/// light reaching the camera unreflected unless `emitters` (a pixel of an emitting material
/// receives its emission there).
fn pure_pixels(bake: &PixelBake, materials: usize, emitters: bool) -> Vec<Vec<usize>> {
    let n = (bake.meta.width * bake.meta.height) as usize;
    let mut owner: Vec<Option<usize>> = vec![None; n];
    let mut shared = vec![false; n];
    for (g, meta) in bake.groups.iter().zip(&bake.meta.groups) {
        for &p in &g.pixels {
            let p = p as usize;
            shared[p] |= owner[p].is_some();
            owner[p] = Some(meta.material as usize);
        }
    }
    let mut out = vec![Vec::new(); materials];
    for p in 0..n {
        let background = !emitters && bake.emission[3 * p..3 * p + 3] != [0.0; 3];
        match owner[p] {
            Some(m) if !shared[p] && !background => out[m].push(p),
            _ => {}
        }
    }
    out
}

/// Mean of `values` and the standard error of that mean, per channel, from their spread.
fn mean_and_se(values: impl Iterator<Item = DVec3>) -> (DVec3, DVec3, usize) {
    let (mut n, mut sum, mut sum2) = (0usize, DVec3::ZERO, DVec3::ZERO);
    for v in values {
        n += 1;
        sum += v;
        sum2 += v * v;
    }
    let nf = n.max(2) as f64;
    let mean = sum / nf;
    let var = ((sum2 - sum * mean) / (nf - 1.0)).max(DVec3::ZERO);
    (mean, (var / nf).map(f64::sqrt), n)
}

/// The closed sphere baked once per reflection count (1 to 4: T0 up to T3) with both halves
/// editable, relit for edited albedos: one grey, one per channel, and the two halves
/// different (so a slot read from the wrong material, or a path product missing a vertex,
/// changes the answer by percents). Every pixel covered by one half only is an independent
/// estimate of that half's radiance (each pixel owns its random streams), so the spread of the
/// pixels measures the standard error of their mean; the mean must be within 4.5 of them.
#[test]
fn closed_sphere_bake_relit_is_a_geometric_series() {
    let le = Vec3::new(1.0, 0.8, 0.6);
    let scene = inside_sphere_scene(Vec3::splat(0.5), Vec3::splat(0.5), le, true);
    let settings = [
        (Vec3::splat(0.5), Vec3::splat(0.5)),
        (Vec3::new(0.2, 0.5, 0.9), Vec3::new(0.2, 0.5, 0.9)),
        (Vec3::splat(0.2), Vec3::splat(0.9)),
        (Vec3::new(0.9, 0.6, 0.3), Vec3::new(0.3, 0.1, 0.8)),
    ];
    let set = |name: &str, kd: Vec3| format!("{name}.kd={},{},{}", kd.x, kd.y, kd.z);
    for n in 1..=4u32 {
        let (bake, _, path) = bake(
            &scene,
            (24, 24),
            16,
            n,
            5,
            &format!("closed-sphere-{n}.prtbake"),
        );
        let regions = pure_pixels(&bake, 2, true);
        for (upper, lower) in settings {
            let pixels = relight(&path, &[set("upper", upper), set("lower", lower)]);
            let m = 0.5 * (upper + lower);
            let geometry = if upper != lower { SPLIT_GEOMETRY } else { 0.0 };
            for (material, a) in [(0usize, upper), (1, lower)] {
                let (mean, se, count) = mean_and_se(
                    regions[material]
                        .iter()
                        .map(|&p| Vec3::from_array(pixels[p]).as_dvec3()),
                );
                assert!(count > 150, "material {material}: {count} pixels");
                let expect = closed_sphere_radiance(le, a, m, n as usize);
                for c in 0..3 {
                    let d = mean[c] - expect[c];
                    let allowed =
                        4.5 * se[c] + 1e-6 * expect[c] + geometry * (expect[c] - le[c] as f64);
                    eprintln!(
                        "closed sphere bake, N = {n}, kd {upper}/{lower}, material {material}, \
                         channel {c}: {:.6} vs {:.6} ({:+.1e} relative, {:+.2} standard errors)",
                        mean[c],
                        expect[c],
                        d / expect[c],
                        d / se[c]
                    );
                    assert!(
                        d.abs() <= allowed,
                        "closed sphere baked with {n} reflections, relit with kd {upper} / \
                         {lower}: material {material}, channel {c}: mean {} vs closed form {} \
                         ({:.1} standard errors of {:.1e}; allowed {allowed:.1e})",
                        mean[c],
                        expect[c],
                        d / se[c],
                        se[c]
                    );
                }
            }
        }
        let _ = std::fs::remove_file(&path);
    }
}

/// Directional albedo of the basis-projected lobe, `sum_b a_b(p) A_b(cos_o)`, with `A_b` the
/// albedo of basis BRDF b tabulated by the independent quadrature at 1-degree steps: what a
/// relit bake converges to for lobe parameter `p` (with Ks = 1, Kd = 0).
struct ProjectedAlbedo {
    basis: BrdfBasis,
    tables: Vec<albedo::Table>,
}

impl ProjectedAlbedo {
    fn new(basis: &BrdfBasis, width: f64) -> ProjectedAlbedo {
        let nb = basis.num_bases;
        let nodes = 91;
        // Each basis BRDF's albedo at `nodes` angles, all bases in one pass per angle.
        let per_angle: Vec<Vec<f64>> = (0..nodes)
            .map(|k| {
                let c = (0.5 * std::f64::consts::PI * k as f64 / (nodes - 1) as f64).cos();
                albedo::hemisphere_many(width, c, 192, nb, |wo, wi, out| {
                    let mut v = [0.0f32; 16];
                    basis.eval_all_local(wi.as_vec3().to_array(), wo.as_vec3().to_array(), &mut v);
                    for (o, v) in out.iter_mut().zip(v) {
                        *o = v as f64;
                    }
                })
            })
            .collect();
        let tables = (0..nb)
            .map(|b| {
                albedo::Table::new(nodes, |c| {
                    let k = (c.clamp(0.0, 1.0).acos() / (0.5 * std::f64::consts::PI)
                        * (nodes - 1) as f64)
                        .round() as usize;
                    per_angle[k][b]
                })
            })
            .collect();
        ProjectedAlbedo {
            basis: basis.clone(),
            tables,
        }
    }

    fn at(&self, param: f32, cos_o: f64) -> f64 {
        let (a, _) = self.basis.coefficients(param);
        a.iter()
            .zip(&self.tables)
            .map(|(&a, t)| a as f64 * t.at(cos_o))
            .sum()
    }
}

/// The furnace with a glossy editable sphere (`convex_furnace_scene`, flat facets), baked once
/// and relit for several lobe parameters and Kd/Ks: every camera sample that hits the sphere
/// has radiance `Kd + Ks a(wo)`. A relit pixel is the mean of its samples, each the projected
/// BRDF's albedo for that sample's exact view direction (the replayed camera jitter); the
/// residual (relit minus that) has mean zero, and its mean over the pixels of each quarter of
/// `cos^2(theta_o)` must be within 4.5 standard errors measured from the pixels' spread. The
/// projected albedo in turn must be within `PROJECTION` of the true one (the basis'
/// reconstruction error, docs/brdf-basis.md).
#[test]
fn glossy_furnace_bake_relit_equals_directional_albedo() {
    /// Largest difference between the projected and the true directional albedo allowed
    /// over theta_o up to 80 degrees, relative to the lobe's largest albedo (an absolute
    /// measure: where the albedo is small, at grazing angles for sharp Blinn-Phong lobes, a
    /// small absolute error is a large relative one).
    const PROJECTION: f64 = 0.015;
    let (size, spp, seed) = ((48u32, 48u32), 16u32, 5u64);
    // (family, baked lobe parameter, relit (Kd, Ks, lobe parameter) settings)
    type Settings = &'static [(f32, f32, f32)];
    let cases: [(Family, f32, Settings); 2] = [
        (
            Family::Ggx,
            0.3,
            &[
                (0.0, 1.0, 0.1),
                (0.0, 1.0, 0.3),
                (0.0, 1.0, 0.6),
                (0.3, 0.5, 0.2),
            ],
        ),
        (
            Family::BlinnPhong,
            30.0,
            &[(0.0, 1.0, 5.0), (0.0, 1.0, 30.0), (0.0, 1.0, 120.0)],
        ),
    ];
    for (family, baked, settings) in cases {
        let brdf = BrdfParams {
            family,
            kd: Vec3::ZERO,
            ks: Vec3::ONE,
            param: baked,
        };
        let scene = convex_furnace_scene(brdf, true, Vec3::ONE);
        let (_, layout, path) = bake(
            &scene,
            size,
            spp,
            1,
            seed,
            &format!("glossy-furnace-{family}.prtbake"),
        );
        // The camera samples of the bake, replayed: which facet each one sees, and from where.
        let samples = camera_samples(&scene, 1, size, spp, seed, false);
        let basis = &layout.bases[0];
        let width = match family {
            Family::Ggx => 0.05,
            _ => (2.0f64 / 202.0).sqrt(),
        };
        let projected = ProjectedAlbedo::new(basis, width);
        let param_name = if family == Family::Ggx {
            "alpha"
        } else {
            "shininess"
        };
        for &(kd, ks, p) in settings {
            let pixels = relight(
                &path,
                &[
                    format!("sphere.kd={kd}"),
                    format!("sphere.ks={ks}"),
                    format!("sphere.{param_name}={p}"),
                ],
            );
            // (ii) the projection error, against the independent quadrature.
            let truth = albedo::Table::new(91, |c| match family {
                Family::Ggx => albedo::ggx(p as f64, c, 192),
                _ => albedo::blinn_phong(p as f64, c, 192),
            });
            let (mut worst, mut peak) = (0.0f64, 0.0f64);
            for deg in 0..=80 {
                let c = (deg as f64).to_radians().cos();
                let (a, t) = (projected.at(p, c), truth.at(c));
                worst = worst.max((a - t).abs());
                peak = peak.max(t);
            }
            let worst = worst / peak;
            eprintln!(
                "{family} {param_name} {p}: projected albedo within {worst:.4} of the true one"
            );
            assert!(
                worst <= PROJECTION,
                "{family} {param_name} {p}: the projected lobe's albedo is up to {worst:.4} of \
                 the largest albedo off the true one (theta_o <= 80 degrees)"
            );
            // (i) relit pixels against the projected albedo of their own samples.
            let n = (size.0 * size.1) as usize;
            let mut expect = vec![0.0f64; n];
            let mut cos2 = vec![0.0f64; n];
            let mut hits = vec![0u32; n];
            for s in &samples {
                let p_i = s.pixel as usize;
                expect[p_i] += match s.hit {
                    Some(hit) => {
                        let c = hit.ns.dot(-s.dir) as f64;
                        cos2[p_i] += c * c;
                        hits[p_i] += 1;
                        kd as f64 + ks as f64 * projected.at(p, c)
                    }
                    None => 1.0,
                } / spp as f64;
            }
            let mut bins: Vec<Vec<DVec3>> = vec![Vec::new(); 4];
            for p_i in 0..n {
                if hits[p_i] == 0 {
                    continue;
                }
                let b = ((cos2[p_i] / hits[p_i] as f64 * 4.0) as usize).min(3);
                bins[b].push(Vec3::from_array(pixels[p_i]).as_dvec3() - DVec3::splat(expect[p_i]));
            }
            for (b, bin) in bins.iter().enumerate() {
                let (mean, se, count) = mean_and_se(bin.iter().copied());
                assert!(count > 40, "bin {b}: {count} pixels");
                eprintln!(
                    "{family} {param_name} {p} kd {kd} ks {ks}, cos^2 in quarter {b}: {count} \
                     pixels, mean residual {:+.2e} ({:+.2} standard errors)",
                    mean.x,
                    mean.x / se.x
                );
                for c in 0..3 {
                    assert!(
                        mean[c].abs() <= 4.5 * se[c] + 1e-5,
                        "{family} baked at {baked}, relit with {param_name} {p}, kd {kd}, ks \
                         {ks}: pixels with cos^2(theta_o) in quarter {b}, channel {c}: mean \
                         residual {:+.2e} against the projected albedo ({:.1} standard errors \
                         of {:.1e})",
                        mean[c],
                        mean[c] / se[c],
                        se[c]
                    );
                }
            }
        }
        let _ = std::fs::remove_file(&path);
    }
}

/// `scenes/furnace` (a smooth-shaded Lambert sphere of albedo 0.5 under a constant white sky,
/// two reflections) baked and relit with `sphere.kd = x`: every pixel is `E + x (1 - E)`
/// exactly, E the background's share of the pixel (the relit image at x = 0), so pixels the
/// sphere covers entirely are x. Each camera sample's transfer is exactly 1 (the cosine
/// sampling of the environment and of the BRDF have the same density, so the MIS weights sum
/// to 1; see `furnace_sphere_radiance_equals_albedo` in the bake crate), the second reflection
/// adds nothing on a convex object, and relighting multiplies by x: the result is x up to
/// float rounding (bound 1e-5 relative, measured 49 ulps at most per sample).
#[test]
fn furnace_scene_bake_relit_gives_kd_exactly() {
    let config = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenes/furnace/bake.toml");
    let (config, scene) = load(&config, &Silent).expect("load scenes/furnace");
    let (bake, _, path) = bake(
        &scene,
        (32, 32),
        8,
        config.reflections,
        3,
        "furnace-kd.prtbake",
    );
    let sphere = scene.material_index("sphere").expect("sphere");
    let interior = &pure_pixels(&bake, scene.materials.len(), false)[sphere];
    assert!(interior.len() > 300, "{} interior pixels", interior.len());
    // E: light reaching the camera unreflected (the background's share of the pixel), and
    // T: the sphere's transfer, so that relighting is E + x T.
    let background = relight(&path, &["sphere.kd=0".to_string()]);
    let full = relight(&path, &["sphere.kd=1".to_string()]);
    let mut lossy = 0;
    for (p, (e, f)) in background.iter().zip(&full).enumerate() {
        for c in 0..3 {
            // At most every sample that misses the background returns its light; fewer at
            // the silhouette, where a camera ray can meet a facet from below its shading
            // normal (the integrator makes that sample black).
            assert!(f[c] <= 1.0 + 1e-5, "pixel {p}: {} > 1", f[c]);
            if f[c] < 1.0 - 1e-5 {
                lossy += 1;
                assert!(
                    e[c] > 0.0,
                    "pixel {p} is inside the sphere but returns {}",
                    f[c]
                );
            }
        }
    }
    for &p in interior {
        assert_eq!(background[p], [0.0; 3], "interior pixel {p} has background");
    }
    for kd in [
        Vec3::splat(0.1),
        Vec3::splat(0.5),
        Vec3::splat(0.9),
        Vec3::new(0.2, 0.6, 1.0),
    ] {
        let pixels = relight(&path, &[format!("sphere.kd={},{},{}", kd.x, kd.y, kd.z)]);
        let mut worst = 0.0f32;
        for &p in interior {
            for c in 0..3 {
                let rel = (pixels[p][c] - kd[c]).abs() / kd[c];
                worst = worst.max(rel);
                assert!(
                    rel <= 1e-5,
                    "kd {kd}: interior pixel {p} channel {c} is {}",
                    pixels[p][c]
                );
            }
        }
        // Every pixel, silhouette included: E + x T, to rounding.
        for (p, got) in pixels.iter().enumerate() {
            for c in 0..3 {
                let expect = background[p][c] + kd[c] * (full[p][c] - background[p][c]);
                assert!(
                    (got[c] - expect).abs() <= 1e-5 * expect.max(1e-3),
                    "kd {kd}: pixel {p} channel {c} is {} but E + x T = {expect}",
                    got[c]
                );
            }
        }
        eprintln!(
            "furnace relit with kd {kd}: {} interior pixels, worst relative difference \
             {worst:.1e}; {lossy} silhouette pixel channels lose light",
            interior.len()
        );
    }
    let _ = std::fs::remove_file(&path);
}
