//! `view --gpu`: with the feature `gpu`, the viewer's renderer on the GPU backend shows the
//! frames its CPU renderer shows, for a per-vertex and a per-pixel bake, as the page's
//! controls change (relative L2 within 1e-3, the bound; runs on whatever Vulkan adapter wgpu finds, lavapipe in CI; `PRT_SKIP_GPU=1` skips
//! it, loudly). Without the feature, `--gpu` is refused naming the build that has it.

use std::path::{Path, PathBuf};

use prt_bake::progress::Silent;
use prt_bake::run::{load, run_pixel, PixelRunSettings};
use prt_viewer::render::Renderer;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[cfg(feature = "gpu")]
mod on_the_gpu {
    use super::*;
    use prt_bake::run::{run_vertex, VertexRunSettings};
    use prt_runtime::OverrideValue;
    use prt_viewer::settings::Settings;

    fn relative_l2(a: &[f32], b: &[f32]) -> f64 {
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for (x, y) in a.iter().zip(b) {
            num += (f64::from(*x) - f64::from(*y)).powi(2);
            den += f64::from(*y).powi(2);
        }
        assert!(den > 0.0, "a black CPU frame compares nothing");
        (num / den).sqrt()
    }

    /// Renders `settings` with both renderers and compares.
    fn compare(cpu: &mut Renderer, gpu: &mut Renderer, settings: &Settings, what: &str) {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        cpu.render(settings, &mut a).expect("CPU frame");
        gpu.render(settings, &mut b).expect("GPU frame");
        assert_eq!(a.len(), b.len(), "{what}: frame sizes");
        let d = relative_l2(&b, &a);
        eprintln!("{what}: relative L2 {d:.2e}");
        assert!(
            d <= 1e-4,
            "{what}: the GPU frame is {d:.3e} from the CPU frame"
        );
    }

    /// Sets material `name`'s kd in `s`.
    fn set_kd(s: &mut Settings, name: &str, value: [f32; 3]) {
        let m = s
            .materials
            .iter_mut()
            .find(|m| m.name == name)
            .expect("the editable material");
        for v in &mut m.values {
            if let OverrideValue::Kd(kd) = v {
                *kd = value;
            }
        }
    }

    /// The renderer, its opening settings and the name of its first editable material.
    fn open(bake: &Path, gpu: bool) -> Option<(Renderer, Settings, String)> {
        match Renderer::open(bake, Some(&root().join("scenes/envmaps")), None, gpu) {
            Ok((mut r, info, settings)) => {
                // The GPU backend does not antialias silhouettes (docs/gpu.md): its frames are
                // the CPU runtime's with antialiasing off.
                r.set_antialias(false);
                let editable = info
                    .materials
                    .iter()
                    .find(|m| m.editable)
                    .map(|m| m.name.clone())
                    .expect("an editable material");
                Some((r, settings, editable))
            }
            Err(e) if gpu && std::env::var("PRT_SKIP_GPU").as_deref() == Ok("1") => {
                eprintln!("SKIPPED: the viewer on the GPU (PRT_SKIP_GPU=1): {e}");
                None
            }
            Err(e) => {
                panic!("{e}\n(PRT_SKIP_GPU=1 skips the GPU tests on a machine without Vulkan)")
            }
        }
    }

    #[test]
    fn the_gpu_renderer_shows_the_cpu_renderers_frames() {
        let dir = std::env::temp_dir().join(format!("prt-viewer-gpu-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");

        let vertex = dir.join("vitrine.prtbake");
        let (config, scene) = load(&root().join("scenes/vitrine"), &Silent).expect("vitrine");
        let settings = VertexRunSettings {
            spp: Some(1),
            output: Some(vertex.clone()),
            ..Default::default()
        };
        run_vertex(&config, &scene, &settings, &Silent).expect("vitrine bake");
        let (mut cpu, mut s, editable) = open(&vertex, false).expect("CPU renderer");
        let Some((mut gpu, _, _)) = open(&vertex, true) else {
            return;
        };
        let view = s.view.as_mut().expect("a per-vertex view");
        (view.width, view.height) = (96, 64);
        compare(&mut cpu, &mut gpu, &s, "vitrine as opened");
        let view = s.view.as_mut().expect("a per-vertex view");
        view.rotation += 90.0;
        view.intensity = 0.5;
        view.camera.eye[0] += 0.3;
        compare(
            &mut cpu,
            &mut gpu,
            &s,
            "vitrine turned, dimmed, the eye moved",
        );
        set_kd(&mut s, &editable, [0.9, 0.2, 0.1]);
        compare(&mut cpu, &mut gpu, &s, "vitrine, a material edited");

        let pixel = dir.join("cornell.prtbake");
        let (config, scene) = load(&root().join("scenes/cornell"), &Silent).expect("cornell");
        let settings = PixelRunSettings {
            spp: Some(1),
            width: Some(32),
            height: Some(32),
            output: Some(pixel.clone()),
            ..Default::default()
        };
        run_pixel(&config, &scene, &settings, &Silent).expect("cornell bake");
        let (mut cpu, mut s, editable) = open(&pixel, false).expect("CPU renderer");
        let (mut gpu, _, _) = open(&pixel, true).expect("GPU renderer");
        compare(&mut cpu, &mut gpu, &s, "cornell as opened");
        set_kd(&mut s, &editable, [0.1, 0.8, 0.3]);
        compare(&mut cpu, &mut gpu, &s, "cornell, a material edited");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// Without the feature, asking for the GPU is refused naming the build that has it.
#[cfg(not(feature = "gpu"))]
#[test]
fn a_viewer_without_the_gpu_feature_refuses_it() {
    let dir = std::env::temp_dir().join(format!("prt-viewer-nogpu-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let pixel = dir.join("cornell.prtbake");
    let (config, scene) = load(&root().join("scenes/cornell"), &Silent).expect("cornell");
    let settings = PixelRunSettings {
        spp: Some(1),
        width: Some(8),
        height: Some(8),
        output: Some(pixel.clone()),
        ..Default::default()
    };
    run_pixel(&config, &scene, &settings, &Silent).expect("cornell bake");
    let err = Renderer::open(&pixel, None, None, true)
        .err()
        .expect("refused")
        .to_string();
    assert!(err.contains("--features gpu"), "{err}");
    assert!(Renderer::open(&pixel, None, None, false).is_ok());
    let _ = std::fs::remove_dir_all(&dir);
}
