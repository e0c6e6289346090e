//! Compact lights (docs/vertex.md, "Compact lights"): the few bright, small parts of the map
//! (a sun, a studio lamp) taken out of it and shaded per pixel with the material's true lobe.
//!
//! Why: a glossy pixel's specular part is otherwise the shading basis (the Tucker-compressed
//! lobe against the incident projections `U`, plus the split's isotropic Gaussians about the
//! mirror direction). Under a light smaller than the lobe that gives the Gaussians' shape, not
//! the lobe's (a streak where the true highlight is a compact oval); the error budget measured
//! it as most of the glossy objects' error (docs/report-vertex.md). A light a few texels wide
//! reflected through the true lobe is one evaluation per light per pixel, as a real-time
//! renderer shades its analytic lights; the rest of the map, smooth once the lights are out,
//! stays with the basis.
//!
//! What is taken out: of each texel brighter than [`THRESHOLD_OVER_MEAN`] times the map's mean
//! radiance (luminance), the part above that level, grouped around the brightest such texels
//! into at most [`MAX_LIGHTS`] lights of angular radius [`CLUSTER_RADIUS_DEG`], each kept only
//! when it carries at least [`MIN_SHARE`] of the map's light. A light is a direction (the
//! power-weighted mean of its texels' centres) and a power (`sum` radiance x solid angle, RGB).
//! The residual keeps everything else, so residual + lights = the map, texel by texel: the
//! diffuse light (`E`) and the reflected light (I1, I2) are the whole map's as before; the
//! glossy rows (`U`) and the split's prefiltered cubes are the residual's.

use prt_formats::envmap::LatLongMap;
use prt_formats::latlong::{texel_centre, uv_to_direction};
use prt_formats::lighting::cubemap::{bilinear_taps, direction_to_face_st};
use prt_formats::vertex::VISIBILITY_CUBE;

/// A texel is a light's candidate above this many times the map's mean radiance (luminance):
/// on the three maps of `scenes/envmaps` that is the sun of `sky` (4 cube texels, 54 % of the
/// map's light) and the lamp of `studio` (53-70 %), while `sunset`'s brightest texels (the sun
/// behind haze, 1 % of the light) stay with the basis.
pub const THRESHOLD_OVER_MEAN: f32 = 20.0;

/// The most lights taken out: each costs a lobe evaluation and a visibility lookup per glossy
/// pixel.
pub const MAX_LIGHTS: usize = 8;

/// A light's texels lie within this angle of its brightest: small against the sharpest lobe
/// the bases model (GGX alpha 0.05 reflects through about 6 degrees), so one direction stands
/// for them all.
pub const CLUSTER_RADIUS_DEG: f32 = 2.0;

/// A light carrying less than this share of the map's light (luminance times solid angle) is
/// left in the map: it would cost per pixel and change little.
pub const MIN_SHARE: f32 = 0.01;

/// One compact light: its direction and its power.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompactLight {
    /// Unit direction towards the light (the map's frame, or the world's once turned).
    pub direction: [f32; 3],
    /// `sum` over its texels of the radiance taken out times the texel's solid angle, RGB
    /// (irradiance on a surface facing it).
    pub power: [f32; 3],
}

/// A map split into its compact lights and the rest.
#[derive(Clone, Debug)]
pub struct Extraction {
    /// The lights, brightest first (empty: nothing compact and bright enough).
    pub lights: Vec<CompactLight>,
    /// The map less the lights (the map itself when there are none).
    pub residual: LatLongMap,
}

fn luminance(t: [f32; 3]) -> f32 {
    0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2]
}

/// The solid angle of a texel of row `y` of a `width x height` lat-long map.
fn row_solid_angle(y: usize, width: usize, height: usize) -> f64 {
    let pi = std::f64::consts::PI;
    let c0 = (pi * y as f64 / height as f64).cos();
    let c1 = (pi * (y + 1) as f64 / height as f64).cos();
    2.0 * pi / width as f64 * (c0 - c1)
}

/// Splits `map` into its compact lights and the rest (see the module documentation).
pub fn extract(map: &LatLongMap) -> Extraction {
    let (w, h) = (map.width, map.height);
    let omega: Vec<f64> = (0..h).map(|y| row_solid_angle(y, w, h)).collect();
    let total: f64 = map
        .texels
        .iter()
        .enumerate()
        .map(|(i, &t)| f64::from(luminance(t)) * omega[i / w])
        .sum();
    let mut residual = map.clone();
    let none = |residual| Extraction {
        lights: Vec::new(),
        residual,
    };
    if total.is_nan() || total <= 0.0 {
        return none(residual);
    }
    let level = (f64::from(THRESHOLD_OVER_MEAN) * total / (4.0 * std::f64::consts::PI)) as f32;
    // Candidates: (texel, direction, its excess luminance power).
    let mut candidates: Vec<(usize, [f32; 3], f64)> = map
        .texels
        .iter()
        .enumerate()
        .filter_map(|(i, &t)| {
            let l = luminance(t);
            (l > level).then(|| {
                let (u, v) = texel_centre(i % w, i / w, w, h);
                (
                    i,
                    uv_to_direction(u, v),
                    f64::from(l - level) * omega[i / w],
                )
            })
        })
        .collect();
    // Brightest first; ties by texel index, so the order is the map's alone.
    candidates.sort_by(|a, b| b.2.total_cmp(&a.2).then(a.0.cmp(&b.0)));
    let cos_radius = CLUSTER_RADIUS_DEG.to_radians().cos();
    let mut taken = vec![false; candidates.len()];
    let mut lights = Vec::new();
    for seed in 0..candidates.len() {
        if lights.len() == MAX_LIGHTS {
            break;
        }
        if taken[seed] {
            continue;
        }
        let centre = candidates[seed].1;
        let members: Vec<usize> = (seed..candidates.len())
            .filter(|&k| {
                let d = candidates[k].1;
                !taken[k] && d[0] * centre[0] + d[1] * centre[1] + d[2] * centre[2] >= cos_radius
            })
            .collect();
        let share: f64 = members.iter().map(|&k| candidates[k].2).sum::<f64>() / total;
        if share < f64::from(MIN_SHARE) {
            // Seeds come brightest first, but a weaker seed can gather more texels: go on.
            continue;
        }
        let mut power = [0.0f64; 3];
        let mut dir = [0.0f64; 3];
        for &k in &members {
            taken[k] = true;
            let (i, d, weight) = candidates[k];
            let t = map.texels[i];
            // The part above the level, in the texel's own colour.
            let keep = level / luminance(t);
            let out = t.map(|c| c * (1.0 - keep));
            residual.texels[i] = t.map(|c| c * keep);
            for c in 0..3 {
                power[c] += f64::from(out[c]) * omega[i / w];
                dir[c] += weight * f64::from(d[c]);
            }
        }
        let len = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
        lights.push(CompactLight {
            direction: dir.map(|c| (c / len) as f32),
            power: power.map(|c| c as f32),
        });
    }
    Extraction { lights, residual }
}

/// `light` turned by the rotation `to_world` (the map's frame into the world's).
pub fn turned(light: &CompactLight, to_world: &[[f64; 3]; 3]) -> CompactLight {
    let d = light.direction.map(f64::from);
    CompactLight {
        direction: std::array::from_fn(|i| {
            (to_world[i][0] * d[0] + to_world[i][1] * d[1] + to_world[i][2] * d[2]) as f32
        }),
        power: light.power,
    }
}

/// The visibility cubes' bilinear taps in each compact light's direction.
pub(super) fn light_taps(lights: &[CompactLight]) -> Vec<[(usize, f64); 4]> {
    lights
        .iter()
        .map(|l| {
            let d = l.direction;
            let (face, fs, ft) =
                direction_to_face_st([f64::from(d[0]), f64::from(d[1]), f64::from(d[2])]);
            bilinear_taps(VISIBILITY_CUBE, face, fs, ft)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use prt_formats::latlong::{direction_to_uv, uv_to_texel};

    fn map(w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3]) -> LatLongMap {
        let texels = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y));
        LatLongMap::new(w, h, texels.collect(), 1.0).expect("map").0
    }

    fn integral(m: &LatLongMap) -> [f64; 3] {
        let mut s = [0.0f64; 3];
        for (i, t) in m.texels.iter().enumerate() {
            let o = row_solid_angle(i / m.width, m.width, m.height);
            for c in 0..3 {
                s[c] += f64::from(t[c]) * o;
            }
        }
        s
    }

    /// A sun of a few texels on a dim sky: one light towards it with the sun's light above
    /// the level, and the residual plus the light is the map (per channel, to rounding).
    #[test]
    fn a_sun_becomes_one_light_and_the_map_keeps_its_light() {
        let sun = [0.3f32, 0.8, -0.52];
        let len = (sun[0] * sun[0] + sun[1] * sun[1] + sun[2] * sun[2]).sqrt();
        let sun = sun.map(|c| c / len);
        // 3 x 3 texels of 0.35 degrees: within one light's radius.
        let (w, h) = (1024, 512);
        let (u, v) = direction_to_uv(sun);
        let (sx, sy) = uv_to_texel(u, v, w, h);
        let m = map(w, h, |x, y| {
            if x.abs_diff(sx) <= 1 && y.abs_diff(sy) <= 1 {
                [5000.0, 4000.0, 3000.0]
            } else {
                [0.2, 0.3, 0.5]
            }
        });
        let e = extract(&m);
        assert_eq!(e.lights.len(), 1, "{:?}", e.lights);
        let l = e.lights[0];
        let cos = l.direction[0] * sun[0] + l.direction[1] * sun[1] + l.direction[2] * sun[2];
        assert!(
            cos > (0.5f32).to_radians().cos(),
            "direction {:?}",
            l.direction
        );
        let (whole, rest) = (integral(&m), integral(&e.residual));
        for c in 0..3 {
            let sum = rest[c] + f64::from(l.power[c]);
            assert!((sum - whole[c]).abs() <= 1e-5 * whole[c], "channel {c}");
        }
        // Nearly all of the sun's light is out (the level is 20x a mean of ~1.9).
        assert!(f64::from(l.power[0]) > 0.95 * (whole[0] - 0.2 * 4.0 * std::f64::consts::PI));
        // Far from the sun the residual is the map.
        assert_eq!(e.residual.texels[0], m.texels[0]);
    }

    /// A smooth map has nothing compact: no light, the residual is the map.
    #[test]
    fn a_smooth_map_has_no_lights() {
        let m = map(64, 32, |x, y| {
            [1.0 + x as f32 * 0.05, 0.5 + y as f32 * 0.1, 0.7]
        });
        let e = extract(&m);
        assert!(e.lights.is_empty());
        assert_eq!(e.residual, m);
        let black = map(8, 4, |_, _| [0.0; 3]);
        assert!(extract(&black).lights.is_empty());
    }

    /// Two suns far apart are two lights; more than MAX_LIGHTS bright spots give MAX_LIGHTS
    /// lights, the rest staying in the residual.
    #[test]
    fn lights_are_separate_and_capped() {
        let (w, h) = (360, 180);
        let spots: Vec<(usize, usize)> =
            (0..12).map(|k| (15 + 30 * k, 60 + (k % 3) * 20)).collect();
        let m = map(w, h, |x, y| {
            if spots.contains(&(x, y)) {
                [3000.0; 3]
            } else {
                [0.1; 3]
            }
        });
        let e = extract(&m);
        assert_eq!(e.lights.len(), MAX_LIGHTS);
        let kept = spots
            .iter()
            .filter(|&&(x, y)| e.residual.texels[y * w + x] == m.texels[y * w + x])
            .count();
        assert_eq!(kept, spots.len() - MAX_LIGHTS);
    }
}
