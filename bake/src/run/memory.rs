//! The memory check both modes run before tracing: the estimate as a note and against a
//! limit, `--max-memory` or by default the memory the machine has available.

use crate::error::BakeError;
use crate::units::human_bytes;

/// A bake's estimated peak memory and its parts (both modes' estimates reduce to these), as
/// the summaries report them.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct EstimatedMemory {
    /// The estimated peak: resident plus the larger of the basis build and the trace.
    #[serde(rename = "estimated_bytes")]
    pub bytes: u64,
    /// Held throughout.
    #[serde(rename = "estimated_resident_bytes")]
    pub resident_bytes: u64,
    /// The basis build's peak.
    #[serde(rename = "estimated_basis_bytes")]
    pub basis_bytes: u64,
    /// The trace and write's peak.
    #[serde(rename = "estimated_trace_bytes")]
    pub trace_bytes: u64,
}

impl EstimatedMemory {
    /// The note printed before tracing.
    pub fn note(&self) -> String {
        format!(
            "memory estimate: {} peak ({} resident + the larger of basis build {} and trace {})",
            human_bytes(self.bytes),
            human_bytes(self.resident_bytes),
            human_bytes(self.basis_bytes),
            human_bytes(self.trace_bytes),
        )
    }

    /// Refuses when the estimate exceeds `limit` ([`memory_limit`]), saying what to change.
    pub fn check(&self, limit: Option<(u64, &'static str)>, advice: &str) -> Result<(), BakeError> {
        match limit {
            Some((limit, from)) if self.bytes > limit => Err(BakeError::MemoryLimit {
                needed: self.bytes,
                limit,
                from,
                advice: advice.to_string(),
            }),
            _ => Ok(()),
        }
    }
}

/// The limit a bake is checked against: `explicit` (`--max-memory`), else the memory the
/// machine has available now (Linux: `MemAvailable` in /proc/meminfo), else none.
pub fn memory_limit(explicit: Option<u64>) -> Option<(u64, &'static str)> {
    match explicit {
        Some(l) => Some((l, "--max-memory")),
        None => {
            available_memory().map(|a| (a, "the memory available (give --max-memory to override)"))
        }
    }
}

/// The memory the machine has available for a new process, when the system says.
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line
        .trim_start_matches("MemAvailable:")
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_estimate_is_refused_above_the_limit_naming_both_and_the_advice() {
        let e = EstimatedMemory {
            bytes: 3 << 30,
            resident_bytes: 1 << 30,
            basis_bytes: 1 << 20,
            trace_bytes: 2 << 30,
        };
        assert!(e.check(None, "x").is_ok());
        assert!(e.check(Some((4 << 30, "--max-memory")), "x").is_ok());
        let err = e
            .check(Some((2 << 30, "--max-memory")), "lower the resolution")
            .unwrap_err()
            .to_string();
        assert!(err.contains("3.00 GB") || err.contains("3.22 GB"), "{err}");
        assert!(
            err.contains("--max-memory") && err.contains("lower the resolution"),
            "{err}"
        );
        assert_eq!(memory_limit(Some(5)), Some((5, "--max-memory")));
        if cfg!(target_os = "linux") {
            assert!(available_memory().is_some_and(|a| a > 0));
        }
    }
}
