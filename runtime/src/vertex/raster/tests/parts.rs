//! The rasterizer's parts: the tie rule of shared edges and the film mapping.

use super::*;

#[test]
fn ties_go_to_exactly_one_of_two_opposite_edges() {
    for n in [
        [1.0, -2.0, 3.0],
        [0.0, 2.0, -1.0],
        [0.0, -0.5, 7.0],
        [0.0, 0.0, 1.0],
        [-0.0, 0.0, -3.0],
    ] {
        let m = n.map(|x: f64| -x);
        assert_ne!(owns_ties(n), owns_ties(m), "{n:?}");
    }
}

#[test]
fn film_pixel_and_camera_space_invert_the_film_formula() {
    let camera = CameraFrame {
        position: [1.0, 2.0, 3.0],
        forward: [0.6, 0.0, -0.8],
        right: [0.8, 0.0, 0.6],
        up: [0.0, 1.0, 0.0],
        yfov: 0.7,
    };
    let rays = ViewRays::new(&camera, 37, 23).expect("rays");
    let (film, space) = (Film::new(&rays, 1e-3), CameraSpace::new(&rays));
    for (x, y) in [(0.5, 0.5), (36.5, 22.5), (12.25, 3.75), (0.0, 23.0)] {
        let (sx, sy) = rays.film(x, y);
        let (px, py) = film.pixel(sx, sy);
        assert!((px - x).abs() < 1e-12 && (py - y).abs() < 1e-12, "{x} {y}");
        // A point 2.5 along the film ray is at (2.5 sx, 2.5 sy, 2.5) in camera space.
        let d = rays.world(sx, sy);
        let c = space.to_camera(std::array::from_fn(|i| (rays.eye()[i] + 2.5 * d[i]) as f32));
        assert!((c[0] / c[2] - sx).abs() < 1e-6 && (c[1] / c[2] - sy).abs() < 1e-6);
        assert!((c[2] - 2.5).abs() < 1e-5);
    }
}
