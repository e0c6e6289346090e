//! Sparse coefficient vectors: the k largest wavelet terms of a lighting, and dot products
//! with dense or sparse transfer vectors.

use super::error::LightingError;
use std::cmp::Ordering;

/// A sparse vector of dense length `len`: strictly increasing `u32` indices below `len` and
/// one finite `f32` value per index. Products accumulate in f64.
#[derive(Clone, Debug, PartialEq)]
pub struct SparseVector {
    len: usize,
    indices: Vec<u32>,
    values: Vec<f32>,
}

impl SparseVector {
    /// A sparse vector from its parts: `indices` strictly increasing and below `len`,
    /// `values` as many and finite, `len` at most `u32::MAX + 1`.
    pub fn new(len: usize, indices: Vec<u32>, values: Vec<f32>) -> Result<Self, LightingError> {
        check_len(len)?;
        if values.len() != indices.len() {
            return Err(LightingError::LengthMismatch {
                what: "sparse values (one per index)",
                expected: indices.len(),
                got: values.len(),
            });
        }
        for (position, &index) in indices.iter().enumerate() {
            let problem = if index as usize >= len {
                "past the end"
            } else if position > 0 && index <= indices[position - 1] {
                "not above the previous index"
            } else {
                continue;
            };
            return Err(LightingError::BadSparseIndex {
                len,
                position,
                index,
                problem,
            });
        }
        check_finite("sparse values", &values)?;
        Ok(SparseVector {
            len,
            indices,
            values,
        })
    }

    /// The `k` entries of `dense` of largest magnitude, as a sparse vector sorted by index.
    ///
    /// Ties in magnitude go to the smaller index, so the choice is deterministic. Entries that
    /// are exactly zero are never kept (they contribute nothing), so the result holds at most
    /// `k` terms. `dense` must be finite; O(len) expected time plus O(k log k).
    pub fn keep_largest(dense: &[f32], k: usize) -> Result<Self, LightingError> {
        check_len(dense.len())?;
        check_finite("dense coefficients", dense)?;
        let mut order: Vec<u32> = (0..dense.len() as u64).map(|i| i as u32).collect();
        // A total order (magnitude descending, then index ascending): the selection is the
        // same whatever the selection algorithm's internal choices.
        let rank = |a: &u32, b: &u32| -> Ordering {
            let (va, vb) = (dense[*a as usize].abs(), dense[*b as usize].abs());
            vb.total_cmp(&va).then(a.cmp(b))
        };
        let k = k.min(order.len());
        if k == 0 {
            return SparseVector::new(dense.len(), Vec::new(), Vec::new());
        }
        if k < order.len() {
            order.select_nth_unstable_by(k - 1, rank);
        }
        let mut kept: Vec<u32> = order[..k]
            .iter()
            .copied()
            .filter(|&i| dense[i as usize] != 0.0)
            .collect();
        kept.sort_unstable();
        let values = kept.iter().map(|&i| dense[i as usize]).collect();
        Ok(SparseVector {
            len: dense.len(),
            indices: kept,
            values,
        })
    }

    /// The dense length.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the dense length is 0.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The number of stored terms.
    #[inline]
    pub fn nnz(&self) -> usize {
        self.indices.len()
    }

    /// The stored indices, strictly increasing.
    #[inline]
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// The stored values, one per index.
    #[inline]
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// The dense vector (zeros where nothing is stored).
    pub fn to_dense(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.len];
        for (&i, &v) in self.indices.iter().zip(&self.values) {
            out[i as usize] = v;
        }
        out
    }

    /// `sum_i self_i dense_i`, accumulated in f64; `dense` must have the dense length.
    pub fn dot_dense(&self, dense: &[f32]) -> Result<f64, LightingError> {
        if dense.len() != self.len {
            return Err(LightingError::DimensionMismatch {
                left: self.len,
                right: dense.len(),
            });
        }
        Ok(self
            .indices
            .iter()
            .zip(&self.values)
            .map(|(&i, &v)| v as f64 * dense[i as usize] as f64)
            .sum())
    }

    /// `sum_i self_i other_i` by merging the sorted index lists, accumulated in f64; both must
    /// have the same dense length.
    pub fn dot(&self, other: &SparseVector) -> Result<f64, LightingError> {
        if other.len != self.len {
            return Err(LightingError::DimensionMismatch {
                left: self.len,
                right: other.len,
            });
        }
        let (mut a, mut b, mut sum) = (0, 0, 0.0f64);
        while a < self.indices.len() && b < other.indices.len() {
            match self.indices[a].cmp(&other.indices[b]) {
                Ordering::Less => a += 1,
                Ordering::Greater => b += 1,
                Ordering::Equal => {
                    sum += self.values[a] as f64 * other.values[b] as f64;
                    a += 1;
                    b += 1;
                }
            }
        }
        Ok(sum)
    }
}

fn check_len(len: usize) -> Result<(), LightingError> {
    let max = u32::MAX as usize + 1;
    if len > max {
        return Err(LightingError::TooLarge {
            what: "sparse vector length",
            value: len,
            max,
        });
    }
    Ok(())
}

fn check_finite(what: &'static str, v: &[f32]) -> Result<(), LightingError> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(LightingError::NonFinite {
            what,
            index,
            value: v[index] as f64,
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_malformed_parts() {
        assert!(SparseVector::new(4, vec![0, 2], vec![1.0, 2.0]).is_ok());
        assert!(matches!(
            SparseVector::new(4, vec![2, 2], vec![1.0, 2.0]),
            Err(LightingError::BadSparseIndex { position: 1, .. })
        ));
        assert!(matches!(
            SparseVector::new(4, vec![4], vec![1.0]),
            Err(LightingError::BadSparseIndex { index: 4, .. })
        ));
        assert!(matches!(
            SparseVector::new(4, vec![1], vec![]),
            Err(LightingError::LengthMismatch { .. })
        ));
        assert!(matches!(
            SparseVector::new(4, vec![1], vec![f32::NAN]),
            Err(LightingError::NonFinite { .. })
        ));
        assert!(SparseVector::keep_largest(&[1.0, f32::INFINITY], 1).is_err());
    }

    #[test]
    fn ties_go_to_the_smaller_index_and_zeros_are_dropped() {
        let v = [0.0, -2.0, 2.0, 1.0, -2.0, 0.0];
        let s = SparseVector::keep_largest(&v, 2).unwrap();
        assert_eq!(s.indices(), &[1, 2]);
        assert_eq!(s.values(), &[-2.0, 2.0]);
        let s = SparseVector::keep_largest(&v, 100).unwrap();
        assert_eq!(s.indices(), &[1, 2, 3, 4]);
        assert_eq!(SparseVector::keep_largest(&v, 0).unwrap().nnz(), 0);
        assert_eq!(s.to_dense(), v.to_vec());
    }

    #[test]
    fn dots_refuse_different_lengths() {
        let a = SparseVector::new(3, vec![0], vec![1.0]).unwrap();
        let b = SparseVector::new(4, vec![0], vec![1.0]).unwrap();
        assert!(matches!(
            a.dot(&b),
            Err(LightingError::DimensionMismatch { .. })
        ));
        assert!(a.dot_dense(&[1.0; 4]).is_err());
        assert_eq!(a.dot_dense(&[2.0, 5.0, 7.0]), Ok(2.0));
    }
}
