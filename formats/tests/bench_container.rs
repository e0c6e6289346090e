//! Throughput measurements of the container (not assertions; timings depend on the machine):
//!
//! ```text
//! cargo test --release -p prt-formats --test bench_container -- --ignored --nocapture
//! ```
//!
//! Writes a 100 MB bake (4 tensors: 3 F32 and 1 F16) and reports write throughput (including
//! fsync), `open` (structure + header checksum + full CRC-32 pass), `open_unchecked`, and
//! `verify_checksums` alone. Reads are warm (the file was just written and is in the page cache).

use std::time::{Duration, Instant};

use half::f16;
use prt_formats::{BakeFile, BakeWriter};

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

#[test]
#[ignore = "measurement; run explicitly with --ignored --nocapture"]
fn bench_100mb_write_open_verify() {
    let dir = std::env::temp_dir().join(format!("prt-bench-{}", std::process::id()));
    let path = dir.join("bench.prtbake");
    let n = 7_000_001; // odd sizes, so padding is exercised
    let a: Vec<f32> = (0..n).map(|i| (i as f32).sin()).collect();
    let b: Vec<f32> = (0..n).map(|i| (i as f32) * 1e-3).collect();
    let c: Vec<f32> = (0..n).map(|i| (i % 977) as f32).collect();
    let h: Vec<f16> = (0..n).map(|i| f16::from_f32((i % 1000) as f32)).collect();
    let mut w = BakeWriter::new();
    w.add_f32("a", &[n], &a).unwrap();
    w.add_f32("b", &[n], &b).unwrap();
    w.add_f32("c", &[n], &c).unwrap();
    w.add_f16("h", &[n], &h).unwrap();
    let len = w.file_len().unwrap();
    let mb = len as f64 / 1e6;

    let runs = 5;
    let mut write = Vec::new();
    for _ in 0..runs {
        let t = Instant::now();
        w.write_atomic(&path).unwrap();
        write.push(t.elapsed());
    }
    let mut open = Vec::new();
    let mut unchecked = Vec::new();
    let mut verify = Vec::new();
    for _ in 0..runs {
        let t = Instant::now();
        let f = BakeFile::open(&path).unwrap();
        open.push(t.elapsed());
        drop(f);
        let t = Instant::now();
        let f = BakeFile::open_unchecked(&path).unwrap();
        unchecked.push(t.elapsed());
        let t = Instant::now();
        f.verify_checksums().unwrap();
        verify.push(t.elapsed());
    }
    let (write, open, unchecked, verify) = (
        median(write),
        median(open),
        median(unchecked),
        median(verify),
    );
    println!("file: {mb:.1} MB, median of {runs} runs");
    println!(
        "write_atomic (incl. fsync): {:.1} ms = {:.0} MB/s",
        write.as_secs_f64() * 1e3,
        mb / write.as_secs_f64()
    );
    println!(
        "open (verify all):          {:.1} ms = {:.0} MB/s",
        open.as_secs_f64() * 1e3,
        mb / open.as_secs_f64()
    );
    println!(
        "open_unchecked:             {:.3} ms",
        unchecked.as_secs_f64() * 1e3
    );
    println!(
        "verify_checksums:           {:.1} ms = {:.0} MB/s",
        verify.as_secs_f64() * 1e3,
        mb / verify.as_secs_f64()
    );
    let _ = std::fs::remove_dir_all(&dir);
}
