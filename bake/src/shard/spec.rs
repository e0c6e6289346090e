//! Which share of a bake a process makes (`bake CONFIG --shard I/N`), and where a cluster
//! scheduler's job arrays say it (docs/shards.md).
//!
//! A bake's work is a list of units in a fixed order (per-vertex: super-clusters; per-pixel:
//! image rows); shard `I` of `N` makes units `u` with `u % N == I`. Interleaving balances by
//! work, not by object: neighbouring units cost about the same, and every shard gets its share
//! of every object.

use std::fmt;

use super::error::ShardError;

/// Shard `index` of `count` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ShardSpec {
    pub index: u32,
    pub count: u32,
}

impl fmt::Display for ShardSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Most shards of one bake.
pub const MAX_SHARDS: u32 = 1 << 20;

impl ShardSpec {
    /// The whole bake as one shard.
    pub const WHOLE: ShardSpec = ShardSpec { index: 0, count: 1 };

    /// Checks `index < count <= MAX_SHARDS`.
    pub fn new(index: u32, count: u32) -> Result<ShardSpec, ShardError> {
        if count == 0 || count > MAX_SHARDS || index >= count {
            return Err(ShardError::BadSpec(format!(
                "shard {index} of {count}: the index must be 0 ..= count - 1 and the count \
                 1 ..= {MAX_SHARDS}"
            )));
        }
        Ok(ShardSpec { index, count })
    }

    /// Parses `I/N` (0-based index, `0/4` to `3/4`).
    pub fn parse(text: &str) -> Result<ShardSpec, ShardError> {
        let bad = || {
            ShardError::BadSpec(format!(
                "'{text}' is not a shard: write INDEX/COUNT with a 0-based index, e.g. 0/4 to 3/4"
            ))
        };
        let (i, n) = text.trim().split_once('/').ok_or_else(bad)?;
        let i: u32 = i.trim().parse().map_err(|_| bad())?;
        let n: u32 = n.trim().parse().map_err(|_| bad())?;
        ShardSpec::new(i, n)
    }

    /// Whether unit `u` of the bake is this shard's.
    pub fn owns(&self, unit: usize) -> bool {
        unit % self.count as usize == self.index as usize
    }

    /// This shard's units among `total`, in order.
    pub fn units(&self, total: usize) -> impl Iterator<Item = usize> + '_ {
        (self.index as usize..total).step_by(self.count as usize)
    }

    /// The shard a cluster scheduler's job array assigns to this process, read from `env`
    /// (a lookup of environment variables; `std::env::var` in the binary), or None when no
    /// scheduler's variables are set:
    ///
    /// - Slurm job arrays: `SLURM_ARRAY_TASK_ID` and `SLURM_ARRAY_TASK_COUNT`, with the task
    ///   ids counted from `SLURM_ARRAY_TASK_MIN` (0 when unset), so `--array=1-8` works too;
    /// - Kubernetes Indexed Jobs: `JOB_COMPLETION_INDEX`, with the count in
    ///   `PRT_SHARD_COUNT` (an Indexed Job does not export its completions; set it in the pod
    ///   spec to the Job's `completions`);
    /// - AWS Batch array jobs: `AWS_BATCH_JOB_ARRAY_INDEX` and `AWS_BATCH_JOB_ARRAY_SIZE`.
    ///
    /// A variable that is set but unusable is an error naming it.
    pub fn from_scheduler(
        env: impl Fn(&str) -> Option<String>,
    ) -> Result<Option<(ShardSpec, &'static str)>, ShardError> {
        let num = |name: &'static str| -> Result<Option<u64>, ShardError> {
            match env(name) {
                None => Ok(None),
                Some(v) => v.trim().parse::<u64>().map(Some).map_err(|_| {
                    ShardError::BadSpec(format!("{name} = '{v}' is not a non-negative integer"))
                }),
            }
        };
        let make = |i: u64, n: u64, from: &'static str| -> Result<_, ShardError> {
            let spec = ShardSpec::new(
                u32::try_from(i).unwrap_or(u32::MAX),
                u32::try_from(n).unwrap_or(u32::MAX),
            )
            .map_err(|e| ShardError::BadSpec(format!("{from}: {e}")))?;
            Ok(Some((spec, from)))
        };
        if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
            let Some(n) = num("SLURM_ARRAY_TASK_COUNT")? else {
                return Err(ShardError::BadSpec(
                    "SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not (an array \
                     job with a step, e.g. --array=0-15:2? give --shard I/N instead)"
                        .into(),
                ));
            };
            let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let Some(i) = id.checked_sub(min) else {
                return Err(ShardError::BadSpec(format!(
                    "SLURM_ARRAY_TASK_ID = {id} is below SLURM_ARRAY_TASK_MIN = {min}"
                )));
            };
            return make(i, n, "Slurm (SLURM_ARRAY_TASK_ID, SLURM_ARRAY_TASK_COUNT)");
        }
        if let Some(i) = num("JOB_COMPLETION_INDEX")? {
            let Some(n) = num("PRT_SHARD_COUNT")? else {
                return Err(ShardError::BadSpec(
                    "JOB_COMPLETION_INDEX is set (a Kubernetes Indexed Job) but PRT_SHARD_COUNT \
                     is not: set it to the Job's completions in the pod spec"
                        .into(),
                ));
            };
            return make(i, n, "Kubernetes (JOB_COMPLETION_INDEX, PRT_SHARD_COUNT)");
        }
        if let Some(i) = num("AWS_BATCH_JOB_ARRAY_INDEX")? {
            let Some(n) = num("AWS_BATCH_JOB_ARRAY_SIZE")? else {
                return Err(ShardError::BadSpec(
                    "AWS_BATCH_JOB_ARRAY_INDEX is set but AWS_BATCH_JOB_ARRAY_SIZE is not".into(),
                ));
            };
            return make(
                i,
                n,
                "AWS Batch (AWS_BATCH_JOB_ARRAY_INDEX, AWS_BATCH_JOB_ARRAY_SIZE)",
            );
        }
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn specs_parse_and_bad_ones_say_what_to_write() {
        assert_eq!(
            ShardSpec::parse("2/4").unwrap(),
            ShardSpec { index: 2, count: 4 }
        );
        assert_eq!(ShardSpec::parse(" 0 / 1 ").unwrap(), ShardSpec::WHOLE);
        for bad in ["4/4", "1/0", "x/4", "3", "-1/4", "1/4/5"] {
            let e = ShardSpec::parse(bad).unwrap_err().to_string();
            assert!(e.contains("0-based") || e.contains("0 ..="), "{bad}: {e}");
        }
        let s = ShardSpec::parse("1/3").unwrap();
        assert_eq!(s.units(10).collect::<Vec<_>>(), [1, 4, 7]);
        assert!(s.owns(7) && !s.owns(6));
        // Every unit is some shard's, exactly once.
        for total in [0, 1, 5, 17] {
            let mut seen = vec![0; total];
            for i in 0..3 {
                for u in ShardSpec::new(i, 3).unwrap().units(total) {
                    seen[u] += 1;
                }
            }
            assert!(seen.iter().all(|&c| c == 1));
        }
    }

    #[test]
    fn schedulers_job_array_variables_give_the_shard() {
        let s = |v| ShardSpec::from_scheduler(env(v)).unwrap().map(|(s, _)| s);
        assert_eq!(s(&[]), None);
        assert_eq!(
            s(&[
                ("SLURM_ARRAY_TASK_ID", "3"),
                ("SLURM_ARRAY_TASK_COUNT", "8")
            ]),
            Some(ShardSpec { index: 3, count: 8 })
        );
        // --array=1-8: ids from 1.
        assert_eq!(
            s(&[
                ("SLURM_ARRAY_TASK_ID", "8"),
                ("SLURM_ARRAY_TASK_COUNT", "8"),
                ("SLURM_ARRAY_TASK_MIN", "1")
            ]),
            Some(ShardSpec { index: 7, count: 8 })
        );
        assert_eq!(
            s(&[("JOB_COMPLETION_INDEX", "0"), ("PRT_SHARD_COUNT", "2")]),
            Some(ShardSpec { index: 0, count: 2 })
        );
        assert_eq!(
            s(&[
                ("AWS_BATCH_JOB_ARRAY_INDEX", "15"),
                ("AWS_BATCH_JOB_ARRAY_SIZE", "16")
            ]),
            Some(ShardSpec {
                index: 15,
                count: 16
            })
        );
        for (vars, names) in [
            (vec![("SLURM_ARRAY_TASK_ID", "3")], "SLURM_ARRAY_TASK_COUNT"),
            (vec![("JOB_COMPLETION_INDEX", "1")], "PRT_SHARD_COUNT"),
            (
                vec![
                    ("AWS_BATCH_JOB_ARRAY_INDEX", "x"),
                    ("AWS_BATCH_JOB_ARRAY_SIZE", "2"),
                ],
                "AWS_BATCH_JOB_ARRAY_INDEX",
            ),
            (
                vec![
                    ("SLURM_ARRAY_TASK_ID", "9"),
                    ("SLURM_ARRAY_TASK_COUNT", "8"),
                ],
                "Slurm",
            ),
        ] {
            let e = ShardSpec::from_scheduler(env(&vars))
                .unwrap_err()
                .to_string();
            assert!(e.contains(names), "{vars:?}: {e}");
        }
    }
}
