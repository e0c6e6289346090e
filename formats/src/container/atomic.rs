//! Atomic file writing, shared by the bake writer and the image writers (`crate::image_io`).
//!
//! The temporary file is a [`tempfile::NamedTempFile`] in the destination folder (so the final
//! rename stays on one filesystem and is therefore atomic); its drop guard removes it on every
//! error and on panic, and `persist` renames it over the target.

use std::ffi::OsString;
use std::fs::File;
use std::io::{self, BufWriter};
use std::path::Path;

/// Writes a file atomically: `write` fills a temporary file in the destination folder, which is
/// then flushed, fsynced and renamed over `path`. On any error (or panic) the temporary file is
/// removed and an existing file at `path` is left untouched. Missing parent folders are created.
///
/// The temporary file is named `.NAME.XXXXXX.tmp` (random `XXXXXX`) and the written file gets
/// the permissions of any newly created file (`0o666` less the umask on Unix), not the
/// owner-only mode `tempfile` would use by default.
///
/// Readers that memory-mapped the old file keep seeing it: rename replaces the directory entry,
/// never the old file's bytes, which is what makes our `mmap` reads safe against our own writers.
pub fn write_file_atomic<F>(path: impl AsRef<Path>, write: F) -> io::Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> io::Result<()>,
{
    let path = path.as_ref();
    let file_name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("'{}' does not name a file", path.display()),
        )
    })?;
    // The temporary file must be in the same folder so the rename stays on one filesystem
    // (and is therefore atomic).
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir)
        .map_err(|e| with_context(e, format!("creating folder {}", dir.display())))?;

    let mut prefix = OsString::from(".");
    prefix.push(file_name);
    prefix.push(".");
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    // tempfile creates files readable by the owner only (0o600); a bake file or image is an
    // ordinary output, so ask for the mode `File::create` uses (0o666, reduced by the umask).
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    let tmp = builder
        .tempfile_in(dir)
        .map_err(|e| with_context(e, format!("creating a temporary file in {}", dir.display())))?;
    // From here on, dropping `tmp_path` (on an error return or a panic in `write`) deletes the
    // temporary file.
    let (file, tmp_path) = tmp.into_parts();

    let mut writer = BufWriter::with_capacity(1 << 20, file);
    write(&mut writer)?;
    let file = writer.into_inner().map_err(|e| e.into_error())?;
    file.sync_all()
        .map_err(|e| with_context(e, "syncing the temporary file".to_string()))?;
    drop(file);

    let tmp_display = tmp_path.display().to_string();
    // On failure the error carries the `TempPath`, which is dropped here and removes the file.
    tmp_path.persist(path).map_err(|e| {
        with_context(
            e.error,
            format!("renaming {tmp_display} to {}", path.display()),
        )
    })?;
    // Make the rename itself durable. Best effort: not every filesystem or platform lets a
    // folder be opened and synced, and the data is already safely in place.
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// `e` with `what` (the step that failed) prepended to its message, keeping its kind.
fn with_context(e: io::Error, what: String) -> io::Error {
    io::Error::new(e.kind(), format!("{what}: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;
    use std::io::Write;

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("prt-atomic-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A write that fails half-way must leave the previous file untouched and no temp file.
    #[test]
    fn failed_write_keeps_old_file_and_removes_temp() {
        let dir = scratch("unit");
        let target = dir.join("a.bin");
        fs::write(&target, b"old contents").unwrap();
        let r = write_file_atomic(&target, |w| {
            w.write_all(&[7u8; 3 << 20])?;
            Err(io::Error::other("injected failure"))
        });
        assert!(r.unwrap_err().to_string().contains("injected failure"));
        assert_eq!(fs::read(&target).unwrap(), b"old contents");
        let entries: Vec<_> = fs::read_dir(&dir).unwrap().collect();
        assert_eq!(entries.len(), 1, "temp file left behind");
        fs::remove_dir_all(&dir).unwrap();
    }

    /// A panic inside the write closure also removes the temporary file.
    #[test]
    fn panicking_write_removes_temp() {
        let dir = scratch("panic");
        let target = dir.join("b.bin");
        let r = std::panic::catch_unwind(|| {
            let _ = write_file_atomic(&target, |w| {
                w.write_all(b"some bytes")?;
                panic!("injected panic");
            });
        });
        assert!(r.is_err());
        assert_eq!(
            fs::read_dir(&dir).unwrap().count(),
            0,
            "temp file left behind"
        );
        fs::remove_dir_all(&dir).unwrap();
    }

    /// Written files get the same permissions as files made by `File::create` (not tempfile's
    /// owner-only default).
    #[cfg(unix)]
    #[test]
    fn written_file_has_ordinary_permissions() {
        use std::os::unix::fs::PermissionsExt;
        let dir = scratch("mode");
        let ours = dir.join("ours.bin");
        let plain = dir.join("plain.bin");
        write_file_atomic(&ours, |w| w.write_all(b"x")).unwrap();
        fs::write(&plain, b"x").unwrap();
        let mode = |p: &Path| fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&ours), mode(&plain));
        fs::remove_dir_all(&dir).unwrap();
    }
}
