//! A STREAM-like read bandwidth measurement: the bound the relight timings are compared with.

use std::time::Instant;

use rayon::prelude::*;

use crate::util::median;

/// A STREAM-like read bandwidth measurement.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Bandwidth {
    pub bytes: u64,
    pub runs: usize,
    pub threads: usize,
    /// Median over the runs, bytes per second.
    pub median: f64,
    pub best: f64,
    /// Every run's rate, bytes per second.
    pub rates: Vec<f64>,
    /// Writing instead (the same array, with non-temporal stores as the relight writes its
    /// frames): the median over its runs, bytes per second.
    pub write_median: f64,
    /// Every write run's rate, bytes per second.
    pub write_rates: Vec<f64>,
}

fn sum_chunk(c: &[f32]) -> f32 {
    let mut acc = [0.0f32; 16];
    let mut it = c.chunks_exact(16);
    for ch in &mut it {
        for k in 0..16 {
            acc[k] += ch[k];
        }
    }
    let tail: f32 = it.remainder().iter().sum();
    acc.iter().sum::<f32>() + tail
}

/// A STREAM-like read benchmark: sums a large f32 array on all rayon threads.
pub struct StreamBench {
    data: Vec<f32>,
}

impl StreamBench {
    const CHUNK: usize = 1 << 16;

    /// Allocates and writes the array in parallel (every page resident), then runs one
    /// warm-up pass.
    pub fn new(bytes: usize) -> StreamBench {
        let n = (bytes / 4).max(Self::CHUNK);
        let mut data = vec![0.0f32; n];
        data.par_chunks_mut(Self::CHUNK)
            .enumerate()
            .for_each(|(i, c)| {
                for (j, v) in c.iter_mut().enumerate() {
                    *v = ((i + j) % 7) as f32 * 0.25;
                }
            });
        let b = StreamBench { data };
        b.run();
        b
    }

    pub fn bytes(&self) -> u64 {
        (self.data.len() * 4) as u64
    }

    /// One pass; the read rate in bytes per second.
    pub fn run(&self) -> f64 {
        let t = Instant::now();
        let s: f32 = self.data.par_chunks(Self::CHUNK).map(sum_chunk).sum();
        let dt = t.elapsed().as_secs_f64();
        std::hint::black_box(s);
        self.bytes() as f64 / dt.max(1e-12)
    }

    /// One writing pass over the array; the write rate in bytes per second.
    pub fn run_write(&mut self) -> f64 {
        let t = Instant::now();
        self.data
            .par_chunks_mut(Self::CHUNK)
            .enumerate()
            .for_each(|(i, c)| write_chunk(c, (i % 7) as f32));
        let dt = t.elapsed().as_secs_f64();
        self.bytes() as f64 / dt.max(1e-12)
    }

    /// The figures of a set of read runs and write runs.
    pub fn figures(&self, rates: Vec<f64>, write_rates: Vec<f64>) -> Bandwidth {
        Bandwidth {
            bytes: self.bytes(),
            runs: rates.len(),
            threads: rayon::current_num_threads(),
            median: median(&rates),
            best: rates.iter().copied().fold(0.0, f64::max),
            rates,
            write_median: median(&write_rates),
            write_rates,
        }
    }
}

/// Fills `c` with `v`. On x86-64 with AVX, with non-temporal stores, the way the runtime
/// writes a frame (its `stream_out` is internal to it, and this is the machine's figure for
/// that way of writing, not the runtime's code under test).
fn write_chunk(c: &mut [f32], v: f32) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU supports AVX (checked just above).
        unsafe { write_chunk_avx(c, v) };
        return;
    }
    c.fill(v);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn write_chunk_avx(c: &mut [f32], v: f32) {
    use std::arch::x86_64::{_mm256_set1_ps, _mm256_stream_ps, _mm_sfence};
    let head = c.as_ptr().align_offset(32).min(c.len());
    c[..head].fill(v);
    let body = (c.len() - head) / 8 * 8;
    let x = _mm256_set1_ps(v);
    for k in (head..head + body).step_by(8) {
        // SAFETY: k + 8 <= c.len(), and c + k is 32-byte aligned (head aligns it).
        _mm256_stream_ps(c.as_mut_ptr().add(k), x);
    }
    c[head + body..].fill(v);
    _mm_sfence();
}

/// Streaming read bandwidth over `bytes` bytes: the median of `runs` passes after a warm-up.
pub fn stream_read_bandwidth(bytes: usize, runs: usize) -> Bandwidth {
    let mut b = StreamBench::new(bytes);
    let rates = (0..runs.max(1)).map(|_| b.run()).collect();
    let write_rates = (0..runs.max(1)).map(|_| b.run_write()).collect();
    b.figures(rates, write_rates)
}
