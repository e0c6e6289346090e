//! The Haar terms a compressed group keeps per T0 row, chosen from an error target
//! (docs/vertex.md "Compression"): the trace keeps `t0_terms` terms per row; a group whose
//! direct light needs fewer stores the fewest `K` whose relative L2 error over the group, against
//! the rows the trace kept, meets the target, every row cut to its `K` largest terms.
//!
//! The stored terms of a row are its `t0_terms` largest coefficients, so its `K` largest
//! stored terms are exactly its `K` largest coefficients (ties to the smaller Haar index, as
//! `SparseVector::keep_largest` breaks them): cutting here equals tracing with `K` terms.

/// The share of `[vertex] compress_error` that T0's cut may use. Direct light carries most of
/// an image and its error reaches the image almost undiluted: on the vitrine (docs/vertex.md,
/// section 7) cutting T0 to the full 10 % moves the relit image by 3.9 % from the bake with
/// every stored term, half of it by 2.1 %, a quarter by 0.5 %. A quarter keeps T0's part of
/// the image error under about 1 %, beside what T1's compression adds.
pub const T0_ERROR_SHARE: f32 = 0.25;

/// What [`choose_t0_terms`] chose for a group.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct T0Choice {
    /// Terms kept per row.
    pub terms: usize,
    /// Sum of squares of the stored terms cut (past the `terms` largest of each row).
    pub cut: f64,
    /// Sum of squares of all the stored terms.
    pub stored: f64,
}

impl T0Choice {
    /// Relative L2 error of the cut against the stored rows (the uncompressed bake's T0).
    pub fn error(&self) -> f64 {
        relative(self.cut, self.stored)
    }
}

fn relative(part: f64, whole: f64) -> f64 {
    if whole > 0.0 {
        (part.max(0.0) / whole).sqrt()
    } else {
        0.0
    }
}

/// The fewest terms `K` in `1 ..= terms` whose relative L2 error over a group, against the
/// rows as stored (`terms` values each in `value`), meets `target`:
/// `sqrt(energy of the stored terms past the K largest of each row / energy of all of them)`.
///
/// The error is measured against the stored rows, not against the untruncated functions,
/// because the target is an error against the uncompressed bake (which stores those rows),
/// as T1's and T2's are against their dense tensors: the trace's own truncation to `terms`
/// is typically 10-20 % of a row's energy already (cosine-weighted visibility is not sparse
/// in Haar), yet the sky's light meets mostly the largest terms, so the image barely moves.
#[cfg(test)]
pub(crate) fn choose_t0_terms(value: &[f32], terms: usize, target: f64) -> T0Choice {
    choose_from_energy(&energy_at(value, terms), target)
}

/// `energy_at[p]`: the sum over the rows of `value` (`terms` stored terms each) of the square
/// of each row's (p+1)-th largest term. Sums of these over the units of a group, in unit
/// order, give the group's, so each unit computes its own and the choice needs no unit's rows.
pub(crate) fn energy_at(value: &[f32], terms: usize) -> Vec<f64> {
    let mut energy_at = vec![0.0f64; terms];
    if terms == 0 {
        return energy_at;
    }
    let mut squares = Vec::with_capacity(terms);
    for row in value.chunks_exact(terms) {
        squares.clear();
        squares.extend(row.iter().map(|&x| f64::from(x) * f64::from(x)));
        squares.sort_unstable_by(|a, b| b.total_cmp(a));
        for (e, s) in energy_at.iter_mut().zip(&squares) {
            *e += s;
        }
    }
    energy_at
}

/// [`choose_t0_terms`] from a group's [`energy_at`] (its length is the stored terms).
pub(crate) fn choose_from_energy(energy_at: &[f64], target: f64) -> T0Choice {
    let terms = energy_at.len();
    if terms == 0 {
        return T0Choice {
            terms: 0,
            cut: 0.0,
            stored: 0.0,
        };
    }
    let stored: f64 = energy_at.iter().sum();
    // Walk K down from `terms`, adding the energy of the K-th largest terms as they go.
    let mut best = T0Choice {
        terms,
        cut: 0.0,
        stored,
    };
    let mut cut = 0.0f64;
    for k in (1..terms).rev() {
        cut += energy_at[k];
        if relative(cut, stored) > target {
            break;
        }
        best = T0Choice {
            terms: k,
            cut,
            stored,
        };
    }
    best
}

/// Cuts every row of `terms` stored terms (`index`, `value`, each row sorted by Haar index
/// and padded with (0, 0)) to its `k` largest in magnitude, in place, keeping the same layout:
/// sorted by index, padded to `k`.
pub(crate) fn cut_rows(index: &mut Vec<u16>, value: &mut Vec<f32>, terms: usize, k: usize) {
    if k >= terms || terms == 0 {
        return;
    }
    let rows = value.len() / terms;
    let mut order: Vec<usize> = Vec::with_capacity(terms);
    for r in 0..rows {
        let (at, to) = (r * terms, r * k);
        order.clear();
        order.extend((0..terms).filter(|&t| value[at + t] != 0.0));
        // Magnitude descending, then Haar index ascending (`SparseVector::keep_largest`).
        order.sort_unstable_by(|&a, &b| {
            let (va, vb) = (value[at + a].abs(), value[at + b].abs());
            vb.total_cmp(&va).then(index[at + a].cmp(&index[at + b]))
        });
        order.truncate(k);
        order.sort_unstable_by_key(|&t| index[at + t]);
        let kept: Vec<(u16, f32)> = order
            .iter()
            .map(|&t| (index[at + t], value[at + t]))
            .collect();
        for (slot, j) in (to..to + k).enumerate() {
            let (i, v) = kept.get(slot).copied().unwrap_or((0, 0.0));
            index[j] = i;
            value[j] = v;
        }
    }
    index.truncate(rows * k);
    value.truncate(rows * k);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows of `terms` stored terms from dense rows, as the trace stores them, with the sums
    /// of squares of all coefficients and of the dropped ones.
    fn stored(rows: &[Vec<f32>], terms: usize) -> (Vec<u16>, Vec<f32>, f64, f64) {
        let (mut index, mut value) = (Vec::new(), Vec::new());
        let (mut total, mut kept) = (0.0, 0.0);
        for row in rows {
            let sq = |v: &[f32]| v.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>();
            total += sq(row);
            let s = prt_formats::lighting::sparse::SparseVector::keep_largest(row, terms).unwrap();
            kept += sq(s.values());
            index.extend(s.indices().iter().map(|&i| i as u16));
            value.extend_from_slice(s.values());
            index.extend(std::iter::repeat_n(0, terms - s.nnz()));
            value.extend(std::iter::repeat_n(0.0, terms - s.nnz()));
        }
        (index, value, total, total - kept)
    }

    fn rows() -> Vec<Vec<f32>> {
        // Decaying coefficients in a scrambled order, one row with few non-zeros.
        let mut out = Vec::new();
        for r in 0..6 {
            out.push(
                (0..40)
                    .map(|i| {
                        let p = (i * 17 + r * 5) % 40;
                        (if (i + r) % 2 == 0 { 1.0 } else { -1.0 }) / (1.0 + p as f32).powf(1.3)
                    })
                    .collect(),
            );
        }
        let mut sparse = vec![0.0; 40];
        sparse[3] = 2.0;
        sparse[30] = -0.5;
        out.push(sparse);
        out
    }

    /// The error of keeping `k` of the `terms` stored terms per row, measured by cutting the
    /// dense rows to `k` and to `terms`.
    fn measured(rows: &[Vec<f32>], terms: usize, k: usize) -> f64 {
        let (_, stored_k, _, _) = stored(rows, k);
        let (_, stored_all, _, _) = stored(rows, terms);
        let sq = |v: &[f32]| v.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>();
        ((sq(&stored_all) - sq(&stored_k)) / sq(&stored_all)).sqrt()
    }

    #[test]
    fn the_fewest_terms_meeting_the_target_are_chosen() {
        let rows = rows();
        let terms = 24;
        let (_, value, _, _) = stored(&rows, terms);
        for target in [0.05, 0.1, 0.2, 0.4] {
            let c = choose_t0_terms(&value, terms, target);
            let (k, e) = (c.terms, c.error());
            assert!((e - measured(&rows, terms, k)).abs() < 1e-6, "{e}");
            assert!(e <= target, "target {target}: K {k} makes {e}");
            assert!(k > 1 && k < terms, "target {target}: K {k}");
            assert!(
                measured(&rows, terms, k - 1) > target,
                "target {target}: K - 1 meets it"
            );
        }
        // A zero target keeps every non-zero term; no energy keeps one.
        let c = choose_t0_terms(&value, terms, 0.0);
        assert!(c.cut == 0.0 && c.terms == terms, "{c:?}");
        assert_eq!(choose_t0_terms(&[0.0; 24], terms, 0.1).terms, 1);
    }

    #[test]
    fn cutting_rows_equals_keeping_fewer_terms_from_the_start() {
        let rows = rows();
        let (mut index, mut value, _, _) = stored(&rows, 24);
        cut_rows(&mut index, &mut value, 24, 9);
        let (index9, value9, _, _) = stored(&rows, 9);
        assert_eq!(index, index9);
        assert_eq!(value, value9);
        // K at or above the stored count changes nothing.
        let (mut index, mut value, _, _) = stored(&rows, 24);
        cut_rows(&mut index, &mut value, 24, 24);
        assert_eq!(value.len(), rows.len() * 24);
    }
}
