//! The number of clusters of a compressed group, chosen from the error target
//! (docs/vertex.md "Compression"): when `[vertex] cluster_vertices` is not given, each group is
//! compressed at the default cluster size and then at one neighbour, and the smallest stored
//! result that meets the target is kept. Small clusters fit their vertices with low ranks but
//! repeat the light and element factors often; large ones share the factors but need higher
//! ranks (or miss the target at the rank caps); which wins depends on the group, so it is
//! measured, not guessed.
//!
//! The search: the default size first; when it meets the target, the next larger size (fewer
//! clusters, so fewer bytes if it meets the target too); when it does not, the next smaller
//! one (which may meet it, at more bytes). When no size tried meets the target, the default
//! size is kept: what is left then is the error the rank caps leave, on the scenes measured
//! mostly the dense tensors' Monte Carlo noise, and smaller clusters buy little of it back at
//! a quarter more bytes or more (`vitrine`: image 1.04 % from the dense relight at 128
//! vertices per cluster, 1.00 % at 64, for 13.6 against 17.0 MB).

/// Vertices per cluster tried when `cluster_vertices` is not given, smallest first.
pub const AUTO_CLUSTER_VERTICES: [u32; 3] = [64, 128, 256];

/// Relative slack on the error target when deciding whether a candidate meets it: the group's
/// error is a ratio of f64 sums rounded to f32, so a candidate whose every cluster met the
/// target exactly can read a few ulps above it.
const TARGET_SLACK: f64 = 1e-4;

/// One cluster size tried for a group: what it stores and the errors it makes.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ClusterCandidate {
    /// Vertices per cluster aimed at.
    pub cluster_vertices: u32,
    /// Clusters made.
    pub clusters: usize,
    /// Bytes stored for the compressed tensors (cluster indices, ranks, factors, cores,
    /// vertex rows).
    pub bytes: u64,
    /// Relative L2 error of T1, and of T2 when the bake has it.
    pub errors: Vec<f32>,
}

impl ClusterCandidate {
    /// Whether every tensor meets `target`.
    pub fn meets(&self, target: f32) -> bool {
        self.errors
            .iter()
            .all(|&e| f64::from(e) <= f64::from(target) * (1.0 + TARGET_SLACK))
    }
}

/// The cluster sizes to try for a group of `vertices` vertices: the explicit `cluster_vertices`
/// alone, or [`AUTO_CLUSTER_VERTICES`] less those that would make the same number of clusters
/// as a smaller size (a group of 100 vertices tries 64 and 128: 256 also makes one cluster).
pub(crate) fn candidate_sizes(explicit: Option<u32>, vertices: usize) -> Vec<u32> {
    if let Some(n) = explicit {
        return vec![n];
    }
    let mut out: Vec<u32> = Vec::new();
    let mut last_count = None;
    for n in AUTO_CLUSTER_VERTICES {
        let count = vertices.div_ceil(n as usize);
        if last_count != Some(count) {
            out.push(n);
            last_count = Some(count);
        }
    }
    out
}

/// The default cluster size of the search (the first tried).
pub const DEFAULT_AUTO_CLUSTER_VERTICES: u32 = 128;

/// The next cluster size to try after `tried` (in the order tried), or None when the search
/// is over (see the module documentation): the explicit size once; else the default size (or
/// the nearest size [`candidate_sizes`] keeps), then its larger neighbour when it met `target`
/// or its smaller one when it did not.
pub(crate) fn next_size(
    explicit: Option<u32>,
    vertices: usize,
    tried: &[ClusterCandidate],
    target: f32,
) -> Option<u32> {
    let sizes = candidate_sizes(explicit, vertices);
    let largest = *sizes.last()?;
    let start = sizes
        .iter()
        .position(|&n| n >= DEFAULT_AUTO_CLUSTER_VERTICES.min(largest))?;
    match tried {
        [] => Some(sizes[start]),
        [first] if explicit.is_none() => {
            if first.meets(target) {
                sizes.get(start + 1).copied()
            } else {
                start.checked_sub(1).map(|i| sizes[i])
            }
        }
        _ => None,
    }
}

/// Which candidate to keep: the smallest stored size among those meeting `target` (the first
/// tried on a tie), or, when none does, the first tried (the default size). None for no
/// candidates.
pub(crate) fn pick(candidates: &[ClusterCandidate], target: f32) -> Option<usize> {
    let meeting = candidates
        .iter()
        .enumerate()
        .filter(|(_, c)| c.meets(target))
        .min_by_key(|(i, c)| (c.bytes, *i))
        .map(|(i, _)| i);
    meeting.or((!candidates.is_empty()).then_some(0))
}

/// A line saying what was tried and why `chosen` was kept, for the progress note.
pub(crate) fn describe(candidates: &[ClusterCandidate], chosen: usize, target: f32) -> String {
    if candidates.len() < 2 {
        return String::new();
    }
    let tried: Vec<String> = candidates
        .iter()
        .map(|c| {
            let errors: Vec<String> = c
                .errors
                .iter()
                .map(|e| format!("{:.2}", 100.0 * e))
                .collect();
            format!(
                "{} -> {:.2} MB at {} %",
                c.cluster_vertices,
                c.bytes as f64 / 1e6,
                errors.join("/")
            )
        })
        .collect();
    let why = if candidates[chosen].meets(target) {
        "the smallest meeting the target"
    } else {
        "none meets the target (the rank caps bind): the default size"
    };
    format!(
        "clusters of {} vertices chosen, {why} (tried {})",
        candidates[chosen].cluster_vertices,
        tried.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(cluster_vertices: u32, bytes: u64, errors: &[f32]) -> ClusterCandidate {
        ClusterCandidate {
            cluster_vertices,
            clusters: 1,
            bytes,
            errors: errors.to_vec(),
        }
    }

    #[test]
    fn sizes_are_the_explicit_one_or_the_distinct_auto_ones() {
        assert_eq!(candidate_sizes(Some(24), 5000), [24]);
        assert_eq!(candidate_sizes(None, 5000), [64, 128, 256]);
        assert_eq!(candidate_sizes(None, 100), [64, 128]);
        assert_eq!(candidate_sizes(None, 64), [64]);
        assert_eq!(candidate_sizes(None, 0), [64]);
    }

    #[test]
    fn the_search_starts_at_the_default_and_goes_towards_meeting_the_target() {
        let target = 0.1;
        assert_eq!(next_size(None, 5000, &[], target), Some(128));
        // Met at 128: try larger clusters; missed: try smaller ones; then stop.
        let met = candidate(128, 10, &[0.05]);
        let missed = candidate(128, 10, &[0.3]);
        assert_eq!(
            next_size(None, 5000, std::slice::from_ref(&met), target),
            Some(256)
        );
        assert_eq!(
            next_size(None, 5000, std::slice::from_ref(&missed), target),
            Some(64)
        );
        assert_eq!(next_size(None, 5000, &[missed, met], target), None);
        // A small group: the sizes that make distinct cluster counts only.
        assert_eq!(next_size(None, 100, &[], target), Some(128));
        assert_eq!(next_size(None, 64, &[], target), Some(64));
        let small = candidate(64, 10, &[0.3]);
        assert_eq!(next_size(None, 64, &[small], target), None);
        // Explicit: that size once.
        assert_eq!(next_size(Some(24), 5000, &[], target), Some(24));
        let once = candidate(24, 10, &[0.3]);
        assert_eq!(next_size(Some(24), 5000, &[once], target), None);
    }

    #[test]
    fn the_smallest_meeting_the_target_is_kept_else_the_default() {
        let target = 0.1;
        // The smallest size misses the target (T2 does): the next smallest that meets it wins.
        let c = [
            candidate(64, 100, &[0.09, 0.11]),
            candidate(128, 300, &[0.1, 0.08]),
            candidate(256, 200, &[0.095, 0.1]),
        ];
        assert_eq!(pick(&c, target), Some(2));
        // Never a meeting candidate larger than another meeting one, whatever the order.
        for rotation in 0..3 {
            let mut r = c.to_vec();
            r.rotate_left(rotation);
            let chosen = &r[pick(&r, target).unwrap()];
            assert!(chosen.meets(target));
            assert!(r
                .iter()
                .all(|o| !o.meets(target) || o.bytes >= chosen.bytes));
        }
        // None meets it: the first tried (the search's default size), whatever the others.
        let c = [
            candidate(128, 900, &[0.25, 0.12]),
            candidate(64, 100, &[0.2, 0.3]),
        ];
        assert_eq!(pick(&c, target), Some(0));
        assert_eq!(pick(&[], target), None);
        // A hair above the target from rounding still meets it; a real miss does not.
        assert!(candidate(64, 1, &[0.1 * (1.0 + 1e-6)]).meets(0.1));
        assert!(!candidate(64, 1, &[0.1 * 1.01]).meets(0.1));
        assert!(describe(&c, 1, target).contains("none meets the target"));
    }
}
