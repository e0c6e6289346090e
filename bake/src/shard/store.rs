//! The checkpoint of a bake (docs/vertex.md, "Progress and resume"): a folder beside the
//! output (`<output>.partial/`) holding one piece file per finished unit, written atomically
//! (a temporary file, fsynced, renamed), and `manifest.json`: the pieces' format, the bake's
//! mode and the [`Fingerprint`]s of what they depend on. A kill loses at most the units in
//! flight; `--resume` takes the saved pieces instead of making them again, and the file
//! assembled from them is the same bytes.
//!
//! A per-vertex bake can also keep each unit's **traced** tensors before compression
//! (`unit<U>.traced`, `bake --keep-traced`): their fingerprint leaves out the compression
//! settings, so a resume with other compression settings compresses those units again without
//! tracing a ray (the finished pieces of the old settings are dropped).
//!
//! The folder is also the bake's working storage: the file is assembled from the pieces once
//! every unit is done, so the bake never holds more than the units in flight. Without
//! checkpoints (`--no-checkpoint`) the folder is scratch: marked not resumable, replaced by
//! the next run, and removed when the run fails.

use std::collections::BTreeSet;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use prt_formats::container::write_file_atomic;
use prt_formats::BakeFile;

use super::error::{CheckpointError, ShardError};
use super::fingerprint::Fingerprint;
use super::piece::{piece_path, Piece, PieceOut, PieceSource};

/// The manifest's `format`: changes whenever the pieces' layout does.
const FORMAT: &str = "prt-bake pieces 2";
const MANIFEST: &str = "manifest.json";

/// The checkpoint folder of a bake written to `output`: `<output>.partial`.
pub fn checkpoint_folder(output: &Path) -> PathBuf {
    let mut name = output.as_os_str().to_os_string();
    name.push(".partial");
    PathBuf::from(name)
}

/// What a store's pieces depend on.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StoreFingerprints {
    /// "vertex" or "pixel".
    pub mode: String,
    /// Everything the finished pieces depend on.
    pub pieces: Fingerprint,
    /// Everything the traced pieces depend on (the pieces' fingerprint less the compression
    /// settings); equal to `pieces` for a mode without compression.
    pub traced: Fingerprint,
}

#[derive(serde::Serialize, serde::Deserialize)]
struct Manifest {
    format: String,
    resumable: bool,
    fingerprints: StoreFingerprints,
}

/// What a resumed store held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Restored {
    /// Finished pieces taken as they are.
    pub pieces: usize,
    /// Units with traced tensors to compress again (their finished pieces were made with other
    /// compression settings and were dropped).
    pub traced: usize,
    /// Finished pieces dropped because the compression settings changed.
    pub dropped: usize,
}

/// An open checkpoint folder.
#[derive(Debug)]
pub struct PieceStore {
    dir: PathBuf,
    pieces: BTreeSet<usize>,
    traced: BTreeSet<usize>,
    resumable: bool,
}

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> CheckpointError + '_ {
    move |source| CheckpointError::Io {
        path: path.to_path_buf(),
        source,
    }
}

impl PieceStore {
    /// Refuses when `dir` holds a resumable checkpoint (an interrupted bake's is not reused
    /// silently); removes a scratch folder a run without checkpoints left.
    pub fn ensure_absent(dir: &Path) -> Result<(), CheckpointError> {
        if !dir.exists() {
            return Ok(());
        }
        if read_manifest(dir).is_ok_and(|m| !m.resumable) {
            return std::fs::remove_dir_all(dir).map_err(io_err(dir));
        }
        Err(CheckpointError::Exists(dir.to_path_buf()))
    }

    /// Starts an empty store at `dir` (refusing an existing resumable one); `resumable` false
    /// marks it scratch (see the module documentation).
    pub fn create(
        dir: &Path,
        fingerprints: &StoreFingerprints,
        resumable: bool,
    ) -> Result<PieceStore, CheckpointError> {
        Self::ensure_absent(dir)?;
        if let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(io_err(parent))?;
        }
        // create_dir (not _all) fails on an existing folder: two bakes never share one.
        std::fs::create_dir(dir).map_err(|e| match e.kind() {
            io::ErrorKind::AlreadyExists => CheckpointError::Exists(dir.to_path_buf()),
            _ => io_err(dir)(e),
        })?;
        write_manifest(dir, fingerprints, resumable)?;
        Ok(PieceStore {
            dir: dir.to_path_buf(),
            pieces: BTreeSet::new(),
            traced: BTreeSet::new(),
            resumable,
        })
    }

    /// Opens the store at `dir` to continue a bake with `fingerprints`, refusing one made with
    /// other inputs (naming them). When only the compression settings changed, the finished
    /// pieces are dropped and the traced ones kept. A folder left without its manifest (killed
    /// right after creating it) and holding no pieces is taken as empty.
    pub fn resume(
        dir: &Path,
        fingerprints: &StoreFingerprints,
    ) -> Result<(PieceStore, Restored), CheckpointError> {
        let (mut pieces, traced) = list(dir)?;
        let manifest = match read_manifest(dir) {
            Err(CheckpointError::Io { source, .. })
                if source.kind() == io::ErrorKind::NotFound
                    && pieces.is_empty()
                    && traced.is_empty() =>
            {
                write_manifest(dir, fingerprints, true)?;
                let store = PieceStore {
                    dir: dir.to_path_buf(),
                    pieces,
                    traced,
                    resumable: true,
                };
                return Ok((store, Restored::default()));
            }
            r => r?,
        };
        let saved = &manifest.fingerprints;
        if saved.mode != fingerprints.mode {
            return Err(CheckpointError::Mismatch {
                dir: dir.to_path_buf(),
                changes: vec![format!(
                    "mode ({} in the checkpoint, {} now)",
                    saved.mode, fingerprints.mode
                )],
            });
        }
        let changes = fingerprints.traced.differences(&saved.traced);
        if !changes.is_empty() {
            return Err(CheckpointError::Mismatch {
                dir: dir.to_path_buf(),
                changes,
            });
        }
        let mut restored = Restored::default();
        if !fingerprints.pieces.differences(&saved.pieces).is_empty() {
            // Only what the finished pieces add (compression) changed: drop them.
            for &u in &pieces {
                let p = piece_path(dir, u);
                std::fs::remove_file(&p).map_err(io_err(&p))?;
            }
            restored.dropped = pieces.len();
            pieces.clear();
        }
        write_manifest(dir, fingerprints, true)?;
        restored.pieces = pieces.len();
        restored.traced = traced.difference(&pieces).count();
        let store = PieceStore {
            dir: dir.to_path_buf(),
            pieces,
            traced,
            resumable: true,
        };
        Ok((store, restored))
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Whether the store is a checkpoint a later run may resume (not scratch).
    pub fn resumable(&self) -> bool {
        self.resumable
    }

    /// Whether unit `u`'s finished piece is saved.
    pub fn has(&self, u: usize) -> bool {
        self.pieces.contains(&u)
    }

    /// Whether unit `u`'s traced tensors are saved.
    pub fn has_traced(&self, u: usize) -> bool {
        self.traced.contains(&u)
    }

    /// Saves unit `u`'s finished piece.
    pub fn save(&mut self, u: usize, piece: &PieceOut) -> Result<(), CheckpointError> {
        write_piece(&piece_path(&self.dir, u), piece)?;
        self.pieces.insert(u);
        Ok(())
    }

    /// Saves unit `u`'s traced tensors (see the module documentation).
    pub fn save_traced(&mut self, u: usize, piece: &PieceOut) -> Result<(), CheckpointError> {
        write_piece(&traced_path(&self.dir, u), piece)?;
        self.traced.insert(u);
        Ok(())
    }

    /// Unit `u`'s traced tensors, checked.
    pub fn traced(&self, u: usize) -> Result<Piece<'static>, CheckpointError> {
        open_piece(&traced_path(&self.dir, u), u)
    }

    /// Checks every saved piece's checksums (a resume's pieces come from an earlier run).
    pub fn verify(&self) -> Result<(), CheckpointError> {
        for &u in &self.pieces {
            open_piece(&piece_path(&self.dir, u), u)?;
        }
        Ok(())
    }

    /// Removes the folder and everything in it (once the output is in place).
    pub fn remove(self) -> Result<(), CheckpointError> {
        std::fs::remove_dir_all(&self.dir).map_err(io_err(&self.dir))
    }
}

impl PieceSource for PieceStore {
    fn piece(&self, unit: usize) -> Result<Piece<'_>, ShardError> {
        if !self.has(unit) {
            return Err(ShardError::BadPiece {
                path: self.dir.clone(),
                unit,
                message: "no piece was saved for it".into(),
            });
        }
        // Checked when written, or by `verify` on resume: read unchecked (no data pass).
        let path = piece_path(&self.dir, unit);
        let file = BakeFile::open_unchecked(&path).map_err(|e| ShardError::Unreadable {
            path: path.clone(),
            source: Box::new(e),
        })?;
        Ok(Piece::from_file(file, unit))
    }
}

fn traced_path(dir: &Path, u: usize) -> PathBuf {
    dir.join(format!("unit{u}.traced"))
}

fn write_piece(path: &Path, piece: &PieceOut) -> Result<(), CheckpointError> {
    let w = piece.writer().map_err(|e| CheckpointError::Unreadable {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    w.write_atomic(path).map_err(|e| CheckpointError::Io {
        path: path.to_path_buf(),
        source: io::Error::other(e.to_string()),
    })
}

fn open_piece(path: &Path, u: usize) -> Result<Piece<'static>, CheckpointError> {
    let file = BakeFile::open(path).map_err(|e| CheckpointError::Unreadable {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    Ok(Piece::from_file(file, u))
}

fn read_manifest(dir: &Path) -> Result<Manifest, CheckpointError> {
    let path = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&path).map_err(io_err(&path))?;
    let unreadable = |message: String| CheckpointError::Unreadable {
        path: path.clone(),
        message,
    };
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| unreadable(e.to_string()))?;
    let format = value.get("format").and_then(|f| f.as_str()).unwrap_or("");
    if format != FORMAT {
        return Err(unreadable(format!(
            "format '{format}', this program writes '{FORMAT}'"
        )));
    }
    serde_json::from_value(value).map_err(|e| unreadable(e.to_string()))
}

fn write_manifest(
    dir: &Path,
    fingerprints: &StoreFingerprints,
    resumable: bool,
) -> Result<(), CheckpointError> {
    let path = dir.join(MANIFEST);
    let manifest = Manifest {
        format: FORMAT.to_string(),
        resumable,
        fingerprints: fingerprints.clone(),
    };
    let text = serde_json::to_string_pretty(&manifest).map_err(|e| CheckpointError::Io {
        path: path.clone(),
        source: io::Error::other(e),
    })?;
    write_file_atomic(&path, |w| w.write_all(text.as_bytes())).map_err(io_err(&path))
}

/// The units with a finished piece and with traced tensors in `dir` (temporary files of
/// interrupted writes, named `.NAME.XXXXXX.tmp`, are neither).
fn list(dir: &Path) -> Result<(BTreeSet<usize>, BTreeSet<usize>), CheckpointError> {
    let mut pieces = BTreeSet::new();
    let mut traced = BTreeSet::new();
    for entry in std::fs::read_dir(dir).map_err(io_err(dir))? {
        let name = entry.map_err(io_err(dir))?.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix("unit")) else {
            continue;
        };
        if let Some(u) = rest.strip_suffix(".piece").and_then(|u| u.parse().ok()) {
            pieces.insert(u);
        } else if let Some(u) = rest.strip_suffix(".traced").and_then(|u| u.parse().ok()) {
            traced.insert(u);
        }
    }
    Ok((pieces, traced))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fingerprints(seed: &str, error: &str) -> StoreFingerprints {
        let mut traced = Fingerprint::new();
        traced.literal("seed", seed);
        let mut pieces = traced.clone();
        pieces.literal("vertex.compress_error", error);
        StoreFingerprints {
            mode: "vertex".into(),
            pieces,
            traced,
        }
    }

    fn piece(x: f32) -> PieceOut {
        let mut p = PieceOut::new(serde_json::json!({"x": x}));
        p.add("values", &[x, 2.0 * x, 3.0 * x]);
        p.add::<u16>("index", &[1, 2]);
        p
    }

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("prt-store-{name}-{}.partial", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn pieces_read_back_and_a_resume_checks_the_inputs() {
        let dir = scratch("resume");
        let fp = fingerprints("3", "0.1");
        let mut s = PieceStore::create(&dir, &fp, true).unwrap();
        s.save(4, &piece(1.5)).unwrap();
        s.save_traced(4, &piece(9.0)).unwrap();
        s.save_traced(5, &piece(7.0)).unwrap();
        let p = s.piece(4).unwrap();
        assert_eq!(&*p.values::<f32>("values").unwrap(), &[1.5, 3.0, 4.5]);
        assert_eq!(p.field::<f32>("x").unwrap(), 1.5);
        assert!(p
            .section("nothing")
            .unwrap_err()
            .to_string()
            .contains("unit 4"));
        assert!(s.piece(3).is_err());
        drop(p);

        // The same inputs: everything is taken.
        let (s, r) = PieceStore::resume(&dir, &fp).unwrap();
        assert_eq!(
            r,
            Restored {
                pieces: 1,
                traced: 1,
                dropped: 0
            }
        );
        assert!(s.has(4) && s.has_traced(5) && !s.has(5));
        s.verify().unwrap();
        // Other compression: the finished piece goes, the traced ones stay.
        let (s, r) = PieceStore::resume(&dir, &fingerprints("3", "0.2")).unwrap();
        assert_eq!(
            r,
            Restored {
                pieces: 0,
                traced: 2,
                dropped: 1
            }
        );
        assert!(!s.has(4) && s.has_traced(4));
        assert_eq!(s.traced(4).unwrap().field::<f32>("x").unwrap(), 9.0);
        // Another trace: refused, naming what changed.
        let e = PieceStore::resume(&dir, &fingerprints("4", "0.2")).unwrap_err();
        assert!(
            e.to_string().contains("seed (3 in the checkpoint, 4 now)"),
            "{e}"
        );
        // A new bake refuses the resumable folder.
        let e = PieceStore::create(&dir, &fp, true).unwrap_err();
        assert!(matches!(e, CheckpointError::Exists(_)), "{e}");
        s.remove().unwrap();
        assert!(!dir.exists());
    }

    #[test]
    fn damaged_pieces_are_refused_and_scratch_folders_are_replaced() {
        let dir = scratch("damage");
        let fp = fingerprints("1", "0.1");
        let mut s = PieceStore::create(&dir, &fp, false).unwrap();
        s.save(0, &piece(2.0)).unwrap();
        let path = piece_path(&dir, 0);
        let mut bytes = std::fs::read(&path).unwrap();
        let n = bytes.len();
        bytes[n - 3] ^= 0x40;
        std::fs::write(&path, &bytes).unwrap();
        let e = s.verify().unwrap_err().to_string();
        assert!(e.contains("unit0.piece"), "{e}");
        // A scratch folder (no checkpoint) is replaced by the next bake.
        let s2 = PieceStore::create(&dir, &fp, true).unwrap();
        assert!(!s2.has(0));
        s2.remove().unwrap();
    }
}
