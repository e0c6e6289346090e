//! How many clusters a unit is compressed as, chosen from the error target (docs/vertex.md
//! "Compression"): a unit (a super-cluster of up to 256 vertices, `units.rs`) is compressed
//! as its two halves first; when they meet the target, once more as one cluster (it shares
//! its light and element factors, so it is smaller if it meets the target too); when they do
//! not, as its four quarters (smaller clusters fit their vertices at lower ranks, at more
//! bytes). The smallest stored result that meets the target is kept; when none does, the
//! halves: what is left then is the error the rank caps leave, and quarters buy little of it
//! back at a quarter more bytes or more. Small clusters fit their vertices at low ranks but
//! repeat the factors; large ones share them but need higher ranks; which wins depends on the
//! unit, so it is measured, not guessed, and per unit: a floor far from everything and the
//! part of it under an object want different sizes.
//!
//! With `[vertex] cluster_vertices` given, every unit is compressed once, as the split whose
//! clusters' size is nearest to it (units are made as large as it when it exceeds the default
//! unit size: [`unit_vertices`]).

use super::units::UNIT_VERTICES;

/// Relative slack on the error target when deciding whether a candidate meets it: the error is
/// a ratio of f64 sums, so a candidate whose every cluster met the target exactly can read a
/// few ulps above it.
const TARGET_SLACK: f64 = 1e-4;

/// The default split of a unit when clusters are chosen: its halves.
pub const DEFAULT_PARTS: usize = 2;

/// One split of a unit tried: what it stores and the errors it makes.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct PartsCandidate {
    /// Clusters the unit was split into (1, 2 or 4).
    pub parts: usize,
    /// Bytes stored for the compressed tensors (ranks, factors, cores, vertex rows).
    pub bytes: u64,
    /// Relative L2 error beyond the noise of T1, and of T2 when the bake has it.
    pub errors: Vec<f64>,
}

impl PartsCandidate {
    /// Whether every tensor meets `target`.
    pub fn meets(&self, target: f32) -> bool {
        self.errors
            .iter()
            .all(|&e| e <= f64::from(target) * (1.0 + TARGET_SLACK))
    }
}

/// The largest unit for the compression settings: [`UNIT_VERTICES`], or an explicit cluster
/// size above it.
pub fn unit_vertices(explicit: Option<u32>) -> usize {
    explicit.map_or(UNIT_VERTICES, |c| (c as usize).max(UNIT_VERTICES))
}

/// The split of a unit of `vertices` whose cluster size is nearest to an explicit
/// `cluster_vertices` (fewer clusters on a tie), at most one cluster per vertex.
fn explicit_parts(cluster_vertices: u32, vertices: usize) -> usize {
    let c = cluster_vertices as f64;
    [1usize, 2, 4]
        .into_iter()
        .filter(|&p| p <= vertices.max(1))
        .min_by(|&a, &b| {
            let da = (vertices as f64 / a as f64 - c).abs();
            let db = (vertices as f64 / b as f64 - c).abs();
            da.total_cmp(&db).then(a.cmp(&b))
        })
        .unwrap_or(1)
}

/// The next split to try after `tried` (in the order tried), or None when the search is over
/// (see the module documentation). `vertices`: the unit's.
pub(crate) fn next_parts(
    explicit: Option<u32>,
    vertices: usize,
    tried: &[PartsCandidate],
    target: f32,
) -> Option<usize> {
    if let Some(c) = explicit {
        return tried.is_empty().then(|| explicit_parts(c, vertices));
    }
    match tried {
        // A unit of one vertex has one cluster whatever the split.
        [] => Some(if vertices >= 2 { DEFAULT_PARTS } else { 1 }),
        [first] if first.parts == DEFAULT_PARTS => {
            if first.meets(target) {
                Some(1)
            } else {
                (vertices >= 4).then_some(4)
            }
        }
        _ => None,
    }
}

/// Which candidate to keep: the smallest stored size among those meeting `target` (the first
/// tried on a tie), or, when none does, the first tried (the default split). None for no
/// candidates.
pub(crate) fn pick(candidates: &[PartsCandidate], target: f32) -> Option<usize> {
    let meeting = candidates
        .iter()
        .enumerate()
        .filter(|(_, c)| c.meets(target))
        .min_by_key(|(i, c)| (c.bytes, *i))
        .map(|(i, _)| i);
    meeting.or((!candidates.is_empty()).then_some(0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(parts: usize, bytes: u64, errors: &[f64]) -> PartsCandidate {
        PartsCandidate {
            parts,
            bytes,
            errors: errors.to_vec(),
        }
    }

    #[test]
    fn the_search_starts_with_halves_and_goes_towards_meeting_the_target() {
        let target = 0.1;
        assert_eq!(next_parts(None, 200, &[], target), Some(2));
        let met = candidate(2, 10, &[0.05]);
        let missed = candidate(2, 10, &[0.3]);
        assert_eq!(
            next_parts(None, 200, std::slice::from_ref(&met), target),
            Some(1)
        );
        assert_eq!(
            next_parts(None, 200, std::slice::from_ref(&missed), target),
            Some(4)
        );
        assert_eq!(next_parts(None, 200, &[missed.clone(), met], target), None);
        // Tiny units.
        assert_eq!(next_parts(None, 1, &[], target), Some(1));
        assert_eq!(
            next_parts(None, 1, &[candidate(1, 1, &[0.3])], target),
            None
        );
        assert_eq!(
            next_parts(None, 3, std::slice::from_ref(&missed), target),
            None
        );
        // Explicit sizes: the nearest split, once.
        assert_eq!(next_parts(Some(64), 256, &[], target), Some(4));
        assert_eq!(next_parts(Some(100), 256, &[], target), Some(2));
        assert_eq!(next_parts(Some(256), 256, &[], target), Some(1));
        assert_eq!(next_parts(Some(512), 512, &[], target), Some(1));
        assert_eq!(next_parts(Some(80), 160, &[], target), Some(2));
        assert_eq!(next_parts(Some(64), 3, &[], target), Some(1));
        assert_eq!(next_parts(Some(1), 3, &[], target), Some(2));
        assert_eq!(next_parts(Some(64), 256, &[missed], target), None);
        assert_eq!(unit_vertices(Some(512)), 512);
        assert_eq!(unit_vertices(Some(64)), UNIT_VERTICES);
        assert_eq!(unit_vertices(None), UNIT_VERTICES);
    }

    #[test]
    fn the_smallest_meeting_the_target_is_kept_else_the_default() {
        let target = 0.1;
        let c = [
            candidate(2, 100, &[0.09, 0.11]),
            candidate(4, 300, &[0.1, 0.08]),
            candidate(1, 200, &[0.095, 0.1]),
        ];
        assert_eq!(pick(&c, target), Some(2));
        for rotation in 0..3 {
            let mut r = c.to_vec();
            r.rotate_left(rotation);
            let chosen = &r[pick(&r, target).unwrap()];
            assert!(chosen.meets(target));
            assert!(r
                .iter()
                .all(|o| !o.meets(target) || o.bytes >= chosen.bytes));
        }
        let c = [
            candidate(2, 900, &[0.25, 0.12]),
            candidate(4, 100, &[0.2, 0.3]),
        ];
        assert_eq!(pick(&c, target), Some(0));
        assert_eq!(pick(&[], target), None);
        assert!(candidate(2, 1, &[0.1 * (1.0 + 1e-6)]).meets(0.1));
        assert!(!candidate(2, 1, &[0.1 * 1.01]).meets(0.1));
    }
}
