//! What can go wrong with a bake's pieces: its checkpoint folder, shard files and their merge.
//! Each message names the folder or file and says what to do.

use std::path::PathBuf;

/// Why a checkpoint could not be made, resumed or read.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// A bake without resume found the checkpoint of an earlier, interrupted one.
    #[error(
        "{} holds the checkpoint of an interrupted bake of this output: rerun with --resume to \
         continue it, or delete the folder to bake from the start",
        .0.display()
    )]
    Exists(PathBuf),
    /// The checkpoint was made by a bake with other inputs.
    #[error(
        "cannot resume from {}: this bake's inputs differ from the interrupted one's: {}; \
         resume with the same inputs, or delete the folder to bake from the start",
        dir.display(),
        changes.join(", ")
    )]
    Mismatch {
        /// The checkpoint folder.
        dir: PathBuf,
        /// What changed, one phrase per input ([`super::Fingerprint::differences`]).
        changes: Vec<String>,
    },
    /// A file of the checkpoint is not what this program writes.
    #[error(
        "{} is not a checkpoint piece this program can read ({message}): delete its folder to \
         bake from the start",
        path.display()
    )]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// Reading or writing the checkpoint failed.
    #[error("checkpoint {}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
}

/// Why a shard could not be chosen, written, read or merged.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    /// `--shard` or a scheduler's variable is unusable.
    #[error("{0}")]
    BadSpec(String),
    /// A file given to merge cannot be opened or is damaged (a truncated copy, a disk error).
    #[error("shard {}: {source}", path.display())]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// What the container reader found (boxed: the cold path).
        source: Box<prt_formats::FormatError>,
    },
    /// A file given to merge is not a shard of a bake.
    #[error("{}: not a shard of a bake ({why}); merge takes the files `bake --shard I/N` wrote", path.display())]
    NotAShard {
        /// The file.
        path: PathBuf,
        /// What it is or lacks.
        why: String,
    },
    /// A shard belongs to another bake (other config, scene, flags or program).
    #[error(
        "{} is a shard of another bake than {}: {}; merge shards of one bake only",
        path.display(), first.display(), changes.join(", ")
    )]
    Foreign {
        /// The shard that differs.
        path: PathBuf,
        /// The shard it was compared with (the first given).
        first: PathBuf,
        /// What differs ([`super::Fingerprint::differences_from`]).
        changes: Vec<String>,
    },
    /// Two files are the same shard.
    #[error("{} and {} are both shard {index}/{count}: give each shard once", a.display(), b.display())]
    Duplicate {
        /// The first file.
        a: PathBuf,
        /// The second file.
        b: PathBuf,
        /// Their shard index.
        index: u32,
        /// Shards of the bake.
        count: u32,
    },
    /// Shards of the bake were not given.
    #[error("the bake has {count} shards but {} {} missing: bake {} with --shard I/{count} and merge again", missing_list(.missing), if .missing.len() == 1 { "is" } else { "are" }, if .missing.len() == 1 { "it" } else { "them" })]
    Missing {
        /// Shards of the bake.
        count: u32,
        /// The indices not given.
        missing: Vec<u32>,
    },
    /// A shard does not hold all of its units (a bug, or a file assembled by hand).
    #[error("{}: shard {index}/{count} should hold {expected} units but holds {found}", path.display())]
    Incomplete {
        /// The file.
        path: PathBuf,
        /// Its index.
        index: u32,
        /// Shards of the bake.
        count: u32,
        /// Units it should hold.
        expected: usize,
        /// Units it holds.
        found: usize,
    },
    /// A piece of a unit is missing or malformed inside a shard or checkpoint.
    #[error("{}: unit {unit}: {message}", path.display())]
    BadPiece {
        /// The shard file or checkpoint piece.
        path: PathBuf,
        /// The unit.
        unit: usize,
        /// What is wrong.
        message: String,
    },
    /// Writing a shard file failed.
    #[error("writing shard {}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What went wrong (boxed: the cold path).
        source: Box<prt_formats::FormatError>,
    },
    /// The checkpoint behind a shard failed.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
}

fn missing_list(missing: &[u32]) -> String {
    let shown: Vec<String> = missing.iter().take(8).map(|i| i.to_string()).collect();
    let more = if missing.len() > 8 {
        format!(" and {} more", missing.len() - 8)
    } else {
        String::new()
    };
    format!(
        "shard{} {}{more}",
        if missing.len() == 1 { "" } else { "s" },
        shown.join(", ")
    )
}
