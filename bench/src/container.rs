//! `bench container`: throughput of the bake file container (timings depend on the machine).
//!
//! Writes a bake of about 100 MB (4 tensors: 3 F32 and 1 F16, odd sizes so padding is
//! exercised) and reports write throughput (including fsync), `open` (structure + header
//! checksum + full CRC-32 pass), `open_unchecked`, and `verify_checksums` alone. Reads are warm
//! (the file was just written and is in the page cache).

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use half::f16;
use prt_formats::{BakeFile, BakeWriter};

/// Medians of one measurement.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ContainerFigures {
    pub file_bytes: u64,
    pub runs: usize,
    pub write_s: f64,
    pub open_s: f64,
    pub open_unchecked_s: f64,
    pub verify_s: f64,
}

fn median(mut v: Vec<Duration>) -> f64 {
    v.sort();
    v[v.len() / 2].as_secs_f64()
}

/// Writes a bake of four tensors of `n` values each into `dir` and times `runs` writes,
/// opens and checksum passes (medians). The file is removed afterwards.
pub fn measure(dir: &Path, n: usize, runs: usize) -> Result<ContainerFigures> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join("bench-container.prtbake");
    let a: Vec<f32> = (0..n).map(|i| (i as f32).sin()).collect();
    let b: Vec<f32> = (0..n).map(|i| (i as f32) * 1e-3).collect();
    let c: Vec<f32> = (0..n).map(|i| (i % 977) as f32).collect();
    let h: Vec<f16> = (0..n).map(|i| f16::from_f32((i % 1000) as f32)).collect();
    let mut w = BakeWriter::new();
    w.add_f32("a", &[n], &a)?;
    w.add_f32("b", &[n], &b)?;
    w.add_f32("c", &[n], &c)?;
    w.add_f16("h", &[n], &h)?;
    let file_bytes = w.file_len()?;
    let runs = runs.max(1);
    let (mut write, mut open, mut unchecked, mut verify) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let result = (|| -> Result<()> {
        for _ in 0..runs {
            let t = Instant::now();
            w.write_atomic(&path)?;
            write.push(t.elapsed());
        }
        for _ in 0..runs {
            let t = Instant::now();
            let f = BakeFile::open(&path)?;
            open.push(t.elapsed());
            drop(f);
            let t = Instant::now();
            let f = BakeFile::open_unchecked(&path)?;
            unchecked.push(t.elapsed());
            let t = Instant::now();
            f.verify_checksums()?;
            verify.push(t.elapsed());
        }
        Ok(())
    })();
    let _ = std::fs::remove_file(&path);
    result.with_context(|| format!("measuring {}", path.display()))?;
    Ok(ContainerFigures {
        file_bytes,
        runs,
        write_s: median(write),
        open_s: median(open),
        open_unchecked_s: median(unchecked),
        verify_s: median(verify),
    })
}

/// Prints the figures as a small table.
pub fn print(f: &ContainerFigures) {
    let mb = f.file_bytes as f64 / 1e6;
    println!("file: {mb:.1} MB, median of {} runs", f.runs);
    println!(
        "write_atomic (incl. fsync): {:.1} ms = {:.0} MB/s",
        f.write_s * 1e3,
        mb / f.write_s
    );
    println!(
        "open (verify all):          {:.1} ms = {:.0} MB/s",
        f.open_s * 1e3,
        mb / f.open_s
    );
    println!(
        "open_unchecked:             {:.3} ms",
        f.open_unchecked_s * 1e3
    );
    println!(
        "verify_checksums:           {:.1} ms = {:.0} MB/s",
        f.verify_s * 1e3,
        mb / f.verify_s
    );
}
