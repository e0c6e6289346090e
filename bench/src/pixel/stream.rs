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

    /// The figures of a set of runs.
    pub fn figures(&self, rates: Vec<f64>) -> Bandwidth {
        Bandwidth {
            bytes: self.bytes(),
            runs: rates.len(),
            threads: rayon::current_num_threads(),
            median: median(&rates),
            best: rates.iter().copied().fold(0.0, f64::max),
            rates,
        }
    }
}

/// Streaming read bandwidth over `bytes` bytes: the median of `runs` passes after a warm-up.
pub fn stream_read_bandwidth(bytes: usize, runs: usize) -> Bandwidth {
    let b = StreamBench::new(bytes);
    let rates = (0..runs.max(1)).map(|_| b.run()).collect();
    b.figures(rates)
}
