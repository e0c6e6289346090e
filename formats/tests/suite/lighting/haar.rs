//! The area-weighted Haar transform, its layout, keep-k and the sparse products.

use super::*;

#[test]
fn haar_inverse_undoes_forward() {
    for n in [1, 2, 4, 8, 64] {
        let h = HaarCube::new(n).unwrap();
        let mut g = Gen(n as u64);
        let x: Vec<f64> = (0..h.len()).map(|_| g.signed()).collect();
        let back = h.inverse_f64(&h.forward_f64(&x).unwrap()).unwrap();
        for (a, b) in x.iter().zip(&back) {
            assert!((a - b).abs() < 1e-12, "{n}: {a} vs {b}");
        }
        let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        let back = h.inverse(&h.forward(&xf).unwrap()).unwrap();
        for (a, b) in xf.iter().zip(&back) {
            assert!((a - b).abs() < 1e-5, "{n}: {a} vs {b}");
        }
    }
}

#[test]
fn haar_of_unit_texels_is_orthonormal() {
    // The function that is 1 / sqrt(solid angle) on one texel and 0 elsewhere has unit norm in
    // the solid-angle metric; the transforms of all of them must be orthonormal vectors.
    let n = 4;
    let h = HaarCube::new(n).unwrap();
    let omega = face_solid_angles(n);
    let len = h.len();
    let columns: Vec<Vec<f64>> = (0..len)
        .map(|t| {
            let mut e = vec![0.0; len];
            e[t] = 1.0 / omega[t % (n * n)].sqrt();
            h.forward_f64(&e).unwrap()
        })
        .collect();
    for a in 0..len {
        for b in 0..len {
            let d: f64 = columns[a].iter().zip(&columns[b]).map(|(x, y)| x * y).sum();
            let want = if a == b { 1.0 } else { 0.0 };
            assert!((d - want).abs() < 1e-12, "{a} {b}: {d}");
        }
    }
}

#[test]
fn haar_parseval_and_products_in_the_solid_angle_metric() {
    let n = 16;
    let h = HaarCube::new(n).unwrap();
    let omega = face_solid_angles(n);
    let mut g = Gen(11);
    let a: Vec<f64> = (0..h.len()).map(|_| g.signed()).collect();
    let b: Vec<f64> = (0..h.len()).map(|_| g.unit()).collect();
    let (wa, wb) = (h.forward_f64(&a).unwrap(), h.forward_f64(&b).unwrap());
    let integral = |x: &[f64], y: &[f64]| -> f64 {
        (0..x.len()).map(|t| x[t] * y[t] * omega[t % (n * n)]).sum()
    };
    let energy: f64 = wa.iter().map(|c| c * c).sum();
    assert!((energy - integral(&a, &a)).abs() < 1e-12 * energy);
    let prod: f64 = wa.iter().zip(&wb).map(|(x, y)| x * y).sum();
    assert!((prod - integral(&a, &b)).abs() < 1e-12 * energy);
}

#[test]
fn haar_layout_means_what_it_says() {
    // One DetailS coefficient at level 0 on +Y: the weighted values (value * sqrt(solid
    // angle)) are +1/N on the left half of the face and -1/N on the right half.
    let n = 8;
    let h = HaarCube::new(n).unwrap();
    let omega = face_solid_angles(n);
    let c = HaarCoefficient {
        face: Face::PosY,
        kind: HaarKind::DetailS,
        level: 0,
        row: 0,
        col: 0,
    };
    let idx = haar_index(n, c).unwrap();
    assert_eq!(idx, 2 * n * n + 1);
    assert_eq!(haar_coefficient(n, idx), Some(c));
    let mut coeffs = vec![0.0; h.len()];
    coeffs[idx] = 1.0;
    let v = h.inverse_f64(&coeffs).unwrap();
    for face in Face::ALL {
        for j in 0..n {
            for i in 0..n {
                let k = texel_index(n, face, i, j);
                let weighted = v[k] * omega[j * n + i].sqrt();
                let want = match (face, i < n / 2) {
                    (Face::PosY, true) => 1.0 / n as f64,
                    (Face::PosY, false) => -1.0 / n as f64,
                    _ => 0.0,
                };
                assert!(
                    (weighted - want).abs() < 1e-14,
                    "{face:?} {i} {j}: {weighted}"
                );
            }
        }
    }
    // The finest DetailT of square (row 1, col 2) on -Z: +1/2 on texel row 2, -1/2 on row 3,
    // columns 4 and 5 only.
    let c = HaarCoefficient {
        face: Face::NegZ,
        kind: HaarKind::DetailT,
        level: 2,
        row: 1,
        col: 2,
    };
    let mut coeffs = vec![0.0; h.len()];
    coeffs[haar_index(n, c).unwrap()] = 1.0;
    let v = h.inverse_f64(&coeffs).unwrap();
    for j in 0..n {
        for i in 0..n {
            let k = texel_index(n, Face::NegZ, i, j);
            let weighted = v[k] * omega[j * n + i].sqrt();
            let want = match (i, j) {
                (4 | 5, 2) => 0.5,
                (4 | 5, 3) => -0.5,
                _ => 0.0,
            };
            assert!((weighted - want).abs() < 1e-14, "{i} {j}: {weighted}");
        }
    }
    // A map constant on each face has an exact scaling coefficient: value * sum sqrt(omega) / N.
    let face_values = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    let x: Vec<f64> = (0..h.len()).map(|k| face_values[k / (n * n)]).collect();
    let w = h.forward_f64(&x).unwrap();
    let root_sum: f64 = omega.iter().map(|o| o.sqrt()).sum();
    for (f, v) in face_values.iter().enumerate() {
        assert!((w[f * n * n] - v * root_sum / n as f64).abs() < 1e-12);
    }
}

#[test]
fn keep_k_keeps_the_largest_and_reconstructs_maps_it_holds() {
    let n = 8;
    let h = HaarCube::new(n).unwrap();
    let len = h.len();
    let mut g = Gen(21);
    // A lighting with exactly k = 12 non-zero wavelet terms (distinct magnitudes).
    let mut coeffs = vec![0.0f32; len];
    let mut chosen = Vec::new();
    while chosen.len() < 12 {
        let i = (g.next_u64() % len as u64) as usize;
        if !chosen.contains(&i) {
            chosen.push(i);
            coeffs[i] =
                ((1.0 + chosen.len() as f64) * if g.unit() < 0.5 { -1.0 } else { 1.0 }) as f32;
        }
    }
    let map = h.inverse(&coeffs).unwrap();
    let w = h.forward(&map).unwrap();
    let kept = SparseVector::keep_largest(&w, 12).unwrap();
    chosen.sort_unstable();
    assert_eq!(
        kept.indices(),
        chosen.iter().map(|&i| i as u32).collect::<Vec<_>>()
    );
    let back = h.inverse(&kept.to_dense()).unwrap();
    for (a, b) in map.iter().zip(&back) {
        assert!((a - b).abs() <= 1e-5 * a.abs().max(1.0), "{a} vs {b}");
    }

    // On a random map: the kept magnitudes are the k largest, indices sorted and unique.
    let x: Vec<f32> = (0..len).map(|_| g.signed() as f32).collect();
    let w = h.forward(&x).unwrap();
    for k in [0, 1, 10, 100, len] {
        let s = SparseVector::keep_largest(&w, k).unwrap();
        assert_eq!(s.nnz(), k.min(len));
        assert!(s.indices().windows(2).all(|p| p[0] < p[1]));
        let smallest_kept = s
            .values()
            .iter()
            .map(|v| v.abs())
            .fold(f32::INFINITY, f32::min);
        let dense = s.to_dense();
        for (i, &v) in w.iter().enumerate() {
            if dense[i] == 0.0 {
                assert!(
                    v.abs() <= smallest_kept,
                    "k {k}: dropped {v} > kept {smallest_kept}"
                );
            } else {
                assert_eq!(dense[i], v);
            }
        }
    }
}

#[test]
fn sparse_products_are_the_lighting_integral() {
    let n = 8;
    let h = HaarCube::new(n).unwrap();
    let omega = face_solid_angles(n);
    let mut g = Gen(31);
    let light: Vec<f32> = (0..h.len()).map(|_| (4.0 * g.unit()) as f32).collect();
    let transfer: Vec<f32> = (0..h.len()).map(|_| g.unit() as f32).collect();
    let integral: f64 = (0..h.len())
        .map(|t| light[t] as f64 * transfer[t] as f64 * omega[t % (n * n)])
        .sum();
    let (wl, wt) = (h.forward(&light).unwrap(), h.forward(&transfer).unwrap());
    let all_l = SparseVector::keep_largest(&wl, h.len()).unwrap();
    let all_t = SparseVector::keep_largest(&wt, h.len()).unwrap();
    assert!((all_l.dot_dense(&wt).unwrap() - integral).abs() < 1e-5 * integral);
    assert!((all_l.dot(&all_t).unwrap() - integral).abs() < 1e-5 * integral);
    // Truncated lighting: the product is the integral of the truncated lighting's map.
    let some_l = SparseVector::keep_largest(&wl, 40).unwrap();
    let approx = h.inverse(&some_l.to_dense()).unwrap();
    let want: f64 = (0..h.len())
        .map(|t| approx[t] as f64 * transfer[t] as f64 * omega[t % (n * n)])
        .sum();
    assert!((some_l.dot_dense(&wt).unwrap() - want).abs() < 1e-5 * integral);
    let some_t = SparseVector::keep_largest(&wt, 60).unwrap();
    let by_merge = some_l.dot(&some_t).unwrap();
    let by_dense = some_l.dot_dense(&some_t.to_dense()).unwrap();
    assert!((by_merge - by_dense).abs() < 1e-12 * integral);
}
