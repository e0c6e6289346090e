//! The checkpoint of a per-vertex bake (docs/vertex.md, "Progress and resume"): a folder
//! `<output>.partial/` beside the output holding
//!
//! - `manifest.json`: the checkpoint format and the bake's [`Fingerprint`];
//! - `group<G>-wave<W>.bin`: the traced f32 results of wave W of group G, one file per wave,
//!   as the blocks that traced it (so that appending them again sums the group's f64 figures
//!   in the same order as the uninterrupted bake).
//!
//! Every file is written atomically (a temporary file, fsynced, renamed), so a kill leaves
//! whole pieces only and loses at most the wave being traced. The pieces hold what tracing
//! produced, before any conversion to storage: the per-group scales need the whole group, and
//! whatever is done to a finished group is simply done again on resume.
//!
//! A piece file: `PRTVWAV1`, then u32 group, wave, first vertex, vertex count, block count;
//! per block u64 rays, f64 t0_total, f64 t0_dropped, and five arrays (t0_index u16, t0_value
//! f32, visibility u8, t1 f32, t2 f32), each a u64 length then its values; finally the CRC-32
//! of everything before it. All little-endian.

use std::collections::BTreeSet;
use std::fs::File;
use std::io::{self, BufReader, Read, Write};
use std::path::{Path, PathBuf};

use prt_formats::container::write_file_atomic;
use prt_formats::vertex::{cube_len, VISIBILITY_CUBE};

use super::buffers::GroupBuffers;
use super::error::CheckpointError;
use super::fingerprint::Fingerprint;

/// The manifest's `format`: changes whenever the pieces' layout does.
const FORMAT: &str = "prt-bake vertex checkpoint 1";
const MANIFEST: &str = "manifest.json";
const MAGIC: &[u8; 8] = b"PRTVWAV1";

/// The checkpoint folder of a bake written to `output`: `<output>.partial`.
pub fn checkpoint_folder(output: &Path) -> PathBuf {
    let mut name = output.as_os_str().to_os_string();
    name.push(".partial");
    PathBuf::from(name)
}

#[derive(serde::Serialize, serde::Deserialize)]
struct Manifest {
    format: String,
    fingerprint: Fingerprint,
}

/// An open checkpoint: where it is and which waves it holds.
#[derive(Debug)]
pub struct Checkpoint {
    dir: PathBuf,
    saved: BTreeSet<(usize, usize)>,
}

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> CheckpointError + '_ {
    move |source| CheckpointError::Io {
        path: path.to_path_buf(),
        source,
    }
}

impl Checkpoint {
    /// Refuses when `dir` exists: an interrupted bake's checkpoint is not reused silently.
    pub fn ensure_absent(dir: &Path) -> Result<(), CheckpointError> {
        if dir.exists() {
            Err(CheckpointError::Exists(dir.to_path_buf()))
        } else {
            Ok(())
        }
    }

    /// Starts an empty checkpoint at `dir` for a bake with `fingerprint`; refuses an existing
    /// folder.
    pub fn create(dir: &Path, fingerprint: &Fingerprint) -> Result<Checkpoint, CheckpointError> {
        // The output's folder may not exist yet (the bake file's writer creates it too).
        if let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(io_err(parent))?;
        }
        // create_dir (not _all) fails on an existing folder: two bakes never share one.
        std::fs::create_dir(dir).map_err(|e| match e.kind() {
            io::ErrorKind::AlreadyExists => CheckpointError::Exists(dir.to_path_buf()),
            _ => io_err(dir)(e),
        })?;
        write_manifest(dir, fingerprint)?;
        Ok(Checkpoint {
            dir: dir.to_path_buf(),
            saved: BTreeSet::new(),
        })
    }

    /// Opens the checkpoint at `dir` to continue a bake with `fingerprint`, refusing one made
    /// with other inputs (naming them). A folder left without its manifest (killed right after
    /// creating it) and holding no pieces is taken as an empty checkpoint.
    pub fn resume(dir: &Path, fingerprint: &Fingerprint) -> Result<Checkpoint, CheckpointError> {
        let saved = pieces(dir)?;
        let manifest_path = dir.join(MANIFEST);
        let text = match std::fs::read_to_string(&manifest_path) {
            Err(e) if e.kind() == io::ErrorKind::NotFound && saved.is_empty() => {
                write_manifest(dir, fingerprint)?;
                return Ok(Checkpoint {
                    dir: dir.to_path_buf(),
                    saved,
                });
            }
            r => r.map_err(io_err(&manifest_path))?,
        };
        let unreadable = |message: String| CheckpointError::Unreadable {
            path: manifest_path.clone(),
            message,
        };
        let manifest: Manifest =
            serde_json::from_str(&text).map_err(|e| unreadable(e.to_string()))?;
        if manifest.format != FORMAT {
            return Err(unreadable(format!(
                "format '{}', this program writes '{FORMAT}'",
                manifest.format
            )));
        }
        let changes = fingerprint.differences(&manifest.fingerprint);
        if !changes.is_empty() {
            return Err(CheckpointError::Mismatch {
                dir: dir.to_path_buf(),
                changes,
            });
        }
        Ok(Checkpoint {
            dir: dir.to_path_buf(),
            saved,
        })
    }

    /// The checkpoint folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// How many waves it held when opened.
    pub fn saved_waves(&self) -> usize {
        self.saved.len()
    }

    /// Removes the folder and everything in it (once the output is in place).
    pub fn remove(self) -> Result<(), CheckpointError> {
        std::fs::remove_dir_all(&self.dir).map_err(io_err(&self.dir))
    }

    /// Whether wave `wave` of group `group` was saved.
    pub(crate) fn has(&self, group: usize, wave: usize) -> bool {
        self.saved.contains(&(group, wave))
    }

    fn piece(&self, group: usize, wave: usize) -> PathBuf {
        self.dir.join(format!("group{group}-wave{wave}.bin"))
    }

    /// Saves the blocks that traced wave `wave` (vertices `vertices`) of group `group`.
    pub(crate) fn save(
        &self,
        group: usize,
        wave: usize,
        vertices: &[u32],
        blocks: &[GroupBuffers],
    ) -> Result<(), CheckpointError> {
        let path = self.piece(group, wave);
        write_file_atomic(&path, |w| {
            let mut w = Crc(w, crc32fast::Hasher::new());
            w.write_all(MAGIC)?;
            for v in [
                group as u32,
                wave as u32,
                vertices.first().copied().unwrap_or(0),
                vertices.len() as u32,
                blocks.len() as u32,
            ] {
                w.write_all(&v.to_le_bytes())?;
            }
            for b in blocks {
                w.write_all(&b.rays.to_le_bytes())?;
                w.write_all(&b.t0_total.to_le_bytes())?;
                w.write_all(&b.t0_dropped.to_le_bytes())?;
                put(&mut w, &b.t0_index)?;
                put(&mut w, &b.t0_value)?;
                put(&mut w, &b.visibility)?;
                put(&mut w, &b.t1)?;
                put(&mut w, &b.t2)?;
            }
            let crc = w.1.finalize();
            w.0.write_all(&crc.to_le_bytes())
        })
        .map_err(io_err(&path))
    }

    /// Loads what [`Checkpoint::save`] saved for this wave, checking that it is whole and
    /// belongs to these vertices.
    pub(crate) fn load(
        &self,
        group: usize,
        wave: usize,
        vertices: &[u32],
    ) -> Result<Vec<GroupBuffers>, CheckpointError> {
        let path = self.piece(group, wave);
        let unreadable = |message: String| CheckpointError::Unreadable {
            path: path.clone(),
            message,
        };
        let file = File::open(&path).map_err(io_err(&path))?;
        let len = file.metadata().map_err(io_err(&path))?.len();
        let mut r = PieceReader {
            inner: Crc(
                BufReader::with_capacity(1 << 20, file),
                crc32fast::Hasher::new(),
            ),
            left: len,
        };
        let short = |e: io::Error| match e.kind() {
            io::ErrorKind::UnexpectedEof => unreadable("cut short".into()),
            _ => io_err(&path)(e),
        };
        let mut magic = [0u8; 8];
        r.read(&mut magic).map_err(short)?;
        if &magic != MAGIC {
            return Err(unreadable("not a wave of a per-vertex bake".into()));
        }
        let mut header = [0u32; 5];
        for h in &mut header {
            *h = u32::from_le_bytes(r.array().map_err(short)?);
        }
        let expected = [
            group as u32,
            wave as u32,
            vertices.first().copied().unwrap_or(0),
            vertices.len() as u32,
        ];
        if header[..4] != expected {
            return Err(unreadable(format!(
                "it holds group {} wave {} (vertices {}.., {} of them), expected group {group} \
                 wave {wave} (vertices {}.., {})",
                header[0], header[1], header[2], header[3], expected[2], expected[3]
            )));
        }
        let mut blocks = Vec::with_capacity(header[4] as usize);
        let mut counted = 0;
        for _ in 0..header[4] {
            let b = GroupBuffers {
                rays: u64::from_le_bytes(r.array().map_err(short)?),
                t0_total: f64::from_le_bytes(r.array().map_err(short)?),
                t0_dropped: f64::from_le_bytes(r.array().map_err(short)?),
                t0_index: r.values().map_err(short)?,
                t0_value: r.values().map_err(short)?,
                visibility: r.values().map_err(short)?,
                t1: r.values().map_err(short)?,
                t2: r.values().map_err(short)?,
            };
            counted += b.visibility.len() / cube_len(VISIBILITY_CUBE);
            blocks.push(b);
        }
        let crc = r.inner.1.clone().finalize();
        let stored = u32::from_le_bytes(r.array().map_err(short)?);
        if stored != crc {
            return Err(unreadable(
                "its checksum does not match its contents".into(),
            ));
        }
        if r.left != 0 {
            return Err(unreadable(format!("{} bytes after its end", r.left)));
        }
        if counted != vertices.len() {
            return Err(unreadable(format!(
                "it holds {counted} vertices, expected {}",
                vertices.len()
            )));
        }
        Ok(blocks)
    }
}

fn write_manifest(dir: &Path, fingerprint: &Fingerprint) -> Result<(), CheckpointError> {
    let path = dir.join(MANIFEST);
    let manifest = Manifest {
        format: FORMAT.to_string(),
        fingerprint: fingerprint.clone(),
    };
    let text = serde_json::to_string_pretty(&manifest).map_err(|e| CheckpointError::Io {
        path: path.clone(),
        source: io::Error::other(e),
    })?;
    write_file_atomic(&path, |w| w.write_all(text.as_bytes())).map_err(io_err(&path))
}

/// The (group, wave) of every piece in `dir` (temporary files of interrupted writes, named
/// `.NAME.XXXXXX.tmp`, are not pieces).
fn pieces(dir: &Path) -> Result<BTreeSet<(usize, usize)>, CheckpointError> {
    let mut out = BTreeSet::new();
    for entry in std::fs::read_dir(dir).map_err(io_err(dir))? {
        let name = entry.map_err(io_err(dir))?.file_name();
        let Some(rest) = name
            .to_str()
            .and_then(|n| n.strip_prefix("group"))
            .and_then(|n| n.strip_suffix(".bin"))
        else {
            continue;
        };
        if let Some((g, w)) = rest.split_once("-wave") {
            if let (Ok(g), Ok(w)) = (g.parse(), w.parse()) {
                out.insert((g, w));
            }
        }
    }
    Ok(out)
}

/// A writer or reader that also feeds a CRC-32 with every byte it passes.
struct Crc<T>(T, crc32fast::Hasher);

impl<W: Write> Write for Crc<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.0.write(buf)?;
        self.1.update(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.0.flush()
    }
}

impl<R: Read> Read for Crc<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.0.read(buf)?;
        self.1.update(&buf[..n]);
        Ok(n)
    }
}

/// Values that a piece stores as little-endian bytes.
trait Value: Copy {
    const BYTES: usize;
    fn put(self, out: &mut [u8]);
    fn get(bytes: &[u8]) -> Self;
}

macro_rules! value {
    ($t:ty) => {
        impl Value for $t {
            const BYTES: usize = std::mem::size_of::<$t>();
            fn put(self, out: &mut [u8]) {
                out.copy_from_slice(&self.to_le_bytes());
            }
            fn get(bytes: &[u8]) -> Self {
                let mut a = [0u8; std::mem::size_of::<$t>()];
                a.copy_from_slice(bytes);
                <$t>::from_le_bytes(a)
            }
        }
    };
}
value!(u8);
value!(u16);
value!(f32);

/// Values converted per this many at a time (bounds the scratch buffer).
const CHUNK: usize = 1 << 14;

/// Writes `values` as a u64 count and their bytes.
fn put<T: Value>(w: &mut impl Write, values: &[T]) -> io::Result<()> {
    w.write_all(&(values.len() as u64).to_le_bytes())?;
    let mut scratch = vec![0u8; CHUNK.min(values.len()) * T::BYTES];
    for chunk in values.chunks(CHUNK) {
        let bytes = &mut scratch[..chunk.len() * T::BYTES];
        for (v, out) in chunk.iter().zip(bytes.chunks_exact_mut(T::BYTES)) {
            v.put(out);
        }
        w.write_all(bytes)?;
    }
    Ok(())
}

/// Reads a piece, knowing how many bytes are left so that a damaged count is refused before
/// anything is allocated for it.
struct PieceReader<R: Read> {
    inner: Crc<R>,
    left: u64,
}

impl<R: Read> PieceReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<()> {
        if (buf.len() as u64) > self.left {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        self.inner.read_exact(buf)?;
        self.left -= buf.len() as u64;
        Ok(())
    }

    fn array<const N: usize>(&mut self) -> io::Result<[u8; N]> {
        let mut a = [0u8; N];
        self.read(&mut a)?;
        Ok(a)
    }

    fn values<T: Value>(&mut self) -> io::Result<Vec<T>> {
        let n = u64::from_le_bytes(self.array()?);
        if n.saturating_mul(T::BYTES as u64) > self.left {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        let n = n as usize;
        let mut out = Vec::with_capacity(n);
        let mut scratch = vec![0u8; CHUNK.min(n) * T::BYTES];
        let mut done = 0;
        while done < n {
            let k = CHUNK.min(n - done);
            let bytes = &mut scratch[..k * T::BYTES];
            self.read(bytes)?;
            out.extend(bytes.chunks_exact(T::BYTES).map(T::get));
            done += k;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(seed: u32, vertices: usize) -> GroupBuffers {
        let f = |i: usize| (seed as f32 + i as f32 * 0.37).sin() * 1e3;
        GroupBuffers {
            t0_index: (0..vertices * 3)
                .map(|i| (i as u16) ^ seed as u16)
                .collect(),
            t0_value: (0..vertices * 3).map(f).collect(),
            visibility: (0..vertices * cube_len(VISIBILITY_CUBE))
                .map(|i| (i * 7 + seed as usize) as u8)
                .collect(),
            t1: (0..vertices * 50).map(|i| f(i + 1)).collect(),
            t2: (0..vertices * 5).map(|i| f(i + 2)).collect(),
            rays: 1000 + seed as u64,
            t0_total: 1.0 / (3.0 + seed as f64),
            t0_dropped: 1.0 / (7.0 + seed as f64),
        }
    }

    /// A checkpoint in a fresh folder under the system's temp dir.
    fn scratch(name: &str) -> (PathBuf, Checkpoint) {
        let dir = std::env::temp_dir().join(format!(
            "prt-checkpoint-{name}-{}.partial",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        let c = Checkpoint::create(&dir, &test_fingerprint()).expect("create");
        (dir, c)
    }

    fn test_fingerprint() -> Fingerprint {
        serde_json::from_str(r#"{"entries": [["seed", "3"]]}"#).expect("fingerprint")
    }

    #[test]
    fn pieces_load_as_saved_and_damage_is_refused_naming_the_file() {
        let (dir, c) = scratch("pieces");
        let vertices: Vec<u32> = (100..109).collect();
        let blocks = vec![block(1, 4), block(2, 4), block(3, 1)];
        c.save(2, 5, &vertices, &blocks).expect("save");
        // Reopened, it knows the wave and gives back the very blocks, in order.
        let c = Checkpoint::resume(&dir, &test_fingerprint()).expect("resume");
        assert!(c.has(2, 5) && !c.has(2, 4) && c.saved_waves() == 1);
        assert_eq!(c.load(2, 5, &vertices).expect("load"), blocks);

        // Another wave's vertices: refused, saying what the piece holds.
        let e = c.load(2, 5, &vertices[1..]).expect_err("other vertices");
        assert!(e.to_string().contains("group2-wave5.bin"), "{e}");
        assert!(
            e.to_string()
                .contains("expected group 2 wave 5 (vertices 101.."),
            "{e}"
        );

        let piece = dir.join("group2-wave5.bin");
        let good = std::fs::read(&piece).expect("piece");
        // One flipped bit in a T1 value, and a piece cut short.
        let mut flipped = good.clone();
        flipped[good.len() / 2] ^= 0x10;
        std::fs::write(&piece, &flipped).expect("write");
        let e = c.load(2, 5, &vertices).expect_err("flipped bit");
        assert!(e.to_string().contains("checksum"), "{e}");
        std::fs::write(&piece, &good[..good.len() - 9]).expect("write");
        let e = c.load(2, 5, &vertices).expect_err("cut short");
        assert!(e.to_string().contains("cut short"), "{e}");

        // Another bake's inputs, and a second checkpoint in the same place.
        let other: Fingerprint =
            serde_json::from_str(r#"{"entries": [["seed", "4"]]}"#).expect("fingerprint");
        let e = Checkpoint::resume(&dir, &other).expect_err("other inputs");
        assert!(
            e.to_string().contains("seed (3 in the checkpoint, 4 now)"),
            "{e}"
        );
        let e = Checkpoint::create(&dir, &test_fingerprint()).expect_err("exists");
        assert!(matches!(e, CheckpointError::Exists(_)), "{e}");
        c.remove().expect("remove");
        assert!(!dir.exists());
    }
}
