//! The multi-sample pass against the pixel-centre pass at 16 times the resolution: the 4 x 4
//! multi-jittered pattern puts every sample of a pixel exactly at the centre of one of the
//! 16 x 16 finer pixels over it, so each sample must see the triangle the fine raster sees
//! there (ties and rounding aside: a handful of samples on an edge may differ).

use super::*;
use crate::vertex::raster::samples::{Part, SAMPLES};

#[test]
fn each_sample_sees_what_the_raster_at_16x_sees_there() {
    let views: &[(&str, &str, u32, u32)] = &[
        ("sphere", "eye=0.3,0.8,3.2 target=0,0,0 fov=45", 16, 12),
        ("floor", "eye=0.3,1.5,2 target=0,0.6,-3 fov=60", 20, 11),
        ("overlapping", "eye=4,1,2 target=0,0,-4 fov=40", 13, 13),
        ("fan", "eye=-3,0.5,1 target=0,0,-2 fov=25", 18, 10),
        ("torus 20K", "eye=0.5,2.2,3 target=0,0,0 fov=50", 24, 18),
    ];
    let scenes = scenes();
    let (mut samples, mut differ, mut covered) = (0usize, 0usize, 0usize);
    for (name, spec, w, h) in views {
        let mesh = &scenes.iter().find(|s| s.0 == *name).expect("scene").1;
        let cam = camera(spec);
        let mut r = Rasterizer::new();
        let mut vis = VisibilityBuffer {
            width: 0,
            height: 0,
            near: 0.0,
            fragments: Vec::new(),
        };
        r.render(&mesh.positions, &mesh.triangles, &cam, *w, *h, &mut vis)
            .expect("render");
        let every: Vec<u32> = (0..w * h).collect();
        let mut parts: Vec<Part> = Vec::new();
        r.samples(&mesh.triangles, &cam, &vis, &every, &mut parts)
            .expect("samples");
        let fine =
            rasterize(&mesh.positions, &mesh.triangles, &cam, 16 * w, 16 * h).expect("fine raster");
        let mut masks = vec![0u32; (w * h) as usize];
        for p in &parts {
            let (x, y) = (p.pixel % w, p.pixel / w);
            assert_eq!(
                masks[p.pixel as usize] & u32::from(p.samples),
                0,
                "{name}: pixel ({x}, {y}) has a sample in two parts"
            );
            masks[p.pixel as usize] |= u32::from(p.samples);
            if p.triangle != NO_TRIANGLE {
                let w0 = 1.0 - p.bary[0] - p.bary[1];
                assert!(
                    p.bary.iter().chain([&w0]).all(|&b| b > -1e-5),
                    "{name}: pixel ({x}, {y}) shades triangle {} outside it: {:?}",
                    p.triangle,
                    p.bary
                );
            }
            for k in (0..SAMPLES).filter(|k| p.samples & (1 << k) != 0) {
                let (a, b) = (k as u32 % 4, k as u32 / 4);
                let (fx, fy) = (16 * x + 4 * a + b, 16 * y + 4 * b + a);
                let seen = fine.fragments[(fy * 16 * w + fx) as usize].triangle;
                samples += 1;
                covered += usize::from(p.triangle != NO_TRIANGLE);
                differ += usize::from(seen != p.triangle);
            }
        }
        assert!(
            masks.iter().all(|&m| m == (1 << SAMPLES) - 1),
            "{name}: a pixel's parts do not hold each of its samples once"
        );
    }
    eprintln!("{samples} samples ({covered} on a triangle), {differ} differ from the fine raster");
    assert!(covered * 4 > samples, "the views see little");
    assert!(
        differ * 10_000 <= samples,
        "{differ} of {samples} samples differ"
    );
}
