//! The fuzz targets, one file each, and what they share.

use std::path::{Path, PathBuf};

pub mod bake_file;
pub mod config;
pub mod gltf;

/// The files of corpus folders, in name order (folders that do not exist are skipped; files
/// named `README*` describe a folder and are not inputs).
pub fn read_corpus_files(dirs: &[PathBuf]) -> anyhow::Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    for path in corpus_entries(dirs)? {
        if path.is_file() {
            out.push(std::fs::read(&path)?);
        }
    }
    Ok(out)
}

/// The entries of corpus folders, in name order.
pub fn corpus_entries(dirs: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for dir in dirs {
        if !dir.is_dir() {
            continue;
        }
        let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)?
            .map(|e| e.map(|e| e.path()))
            .collect::<Result<_, _>>()?;
        entries.retain(|p| !is_readme(p));
        entries.sort();
        out.extend(entries);
    }
    Ok(out)
}

fn is_readme(p: &Path) -> bool {
    p.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.starts_with("README"))
}
