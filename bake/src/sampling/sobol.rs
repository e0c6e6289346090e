//! The numbers one camera sample draws: Owen-scrambled Sobol points, shuffled per draw.
//!
//! Why not independent random numbers: a pixel's samples are one integral estimated spp times,
//! and points that stratify each draw (film jitter, light position, BRDF direction, ...) over
//! the pixel's samples reach a given error with fewer of them. This is pbrt-v4's padded Sobol
//! sampler, with the hash-based scrambling of Burley, "Practical Hash-based Owen Scrambling"
//! (JCGT 2020) and Vegdahl's improved hash constants:
//!
//! - every draw (a 1D or a 2D number) of sample s of a pixel with spp samples takes point
//!   `shuffle(s)` of the Sobol sequence's first one or two dimensions (a (0,2)-sequence: every
//!   prefix of 2^k points is stratified in every elementary interval of area 2^-k);
//! - `shuffle` is a random permutation of 0..spp (two of Kensler's hashed permutations composed;
//!   pbrt-v4's padded Sobol sampler uses one), with a seed per (pixel, draw), so the draws of one sample are
//!   independent of each other (padding). Why not Burley's shuffle (a nested scramble of the
//!   index): it keeps the partition of the samples by their index's low bit, so every draw
//!   splits a pixel's samples into the same two halves, a correlation the tests measured;
//! - each coordinate is Owen-scrambled with its own seed per (pixel, draw), which keeps the net
//!   and makes each coordinate uniform on [0, 1), so estimates stay unbiased.
//!
//! The draws are keyed by (seed, pixel, draw index) only, so a pixel's samples are the same
//! whatever the thread or the order they are traced in.

use glam::Vec2;

use super::{mix64, Rng};

/// Sobol dimension 1's direction numbers bit-reversed, folded into one table per byte of the
/// index: `SOBOL1_REV[k][b]` is the XOR of the reversed direction numbers of the set bits of
/// b << 8k. Reversed because the scramble works on reversed bits (see `owen`).
static SOBOL1_REV: [[u32; 256]; 4] = sobol1_tables();

const fn sobol1_tables() -> [[u32; 256]; 4] {
    // Dimension 1 (polynomial x + 1): v_0 = 1 << 31, v_i = v_{i-1} ^ (v_{i-1} >> 1).
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut i = 1;
    while i < 32 {
        v[i] = v[i - 1] ^ (v[i - 1] >> 1);
        i += 1;
    }
    let mut t = [[0u32; 256]; 4];
    let mut k = 0;
    while k < 4 {
        let mut b = 0;
        while b < 256 {
            let mut x = 0u32;
            let mut j = 0;
            while j < 8 {
                if b & (1 << j) != 0 {
                    x ^= v[8 * k + j].reverse_bits();
                }
                j += 1;
            }
            t[k][b] = x;
            b += 1;
        }
        k += 1;
    }
    t
}

/// Sobol dimension 1 of `index`, bit-reversed.
#[inline]
fn sobol1_reversed(index: u32) -> u32 {
    let b = index.to_le_bytes();
    SOBOL1_REV[0][b[0] as usize]
        ^ SOBOL1_REV[1][b[1] as usize]
        ^ SOBOL1_REV[2][b[2] as usize]
        ^ SOBOL1_REV[3][b[3] as usize]
}

/// A random permutation of 32-bit values in which each bit flips depending only on the bits
/// below it (Laine-Karras): applied to a bit-reversed value, it is an Owen scramble (each
/// digit flips depending only on the more significant digits). Vegdahl's constants.
#[inline]
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x ^= x.wrapping_mul(0x3d20_adea);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6c56);
    x ^= x.wrapping_mul(0x53a2_2864);
    x
}

/// Element i of a random permutation of 0..l chosen by `p` (Kensler, "Correlated Multi-Jittered
/// Sampling", 2013: a hash that is a bijection on the next power of two, walked until it lands
/// below l; pbrt-v4's `PermutationElement`).
#[inline]
fn permutation_element(mut i: u32, l: u32, p: u32) -> u32 {
    let mut w = l.wrapping_sub(1);
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    loop {
        i ^= p;
        i = i.wrapping_mul(0xe170_893d);
        i ^= p >> 16;
        i ^= (i & w) >> 4;
        i ^= p >> 8;
        i = i.wrapping_mul(0x0929_eb3f);
        i ^= p >> 23;
        i ^= (i & w) >> 1;
        i = i.wrapping_mul(1 | p >> 27);
        i = i.wrapping_mul(0x6935_fa69);
        i ^= (i & w) >> 11;
        i = i.wrapping_mul(0x74dc_b303);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0x9e50_1cc3);
        i ^= (i & w) >> 2;
        i = i.wrapping_mul(0xc860_a3df);
        i &= w;
        i ^= i >> 5;
        if i < l {
            // pbrt's `(i + p) % l`, without the division: any offset modulo l keeps it a
            // permutation, and i + (p & w) < 3 l.
            let mut j = i + (p & w);
            while j >= l {
                j -= l;
            }
            return j;
        }
    }
}

/// Point `i` of the first two Sobol dimensions, each coordinate Owen-scrambled by its seed.
#[inline]
fn sobol_point(i: u32, sx: u32, sy: u32) -> Vec2 {
    let x = laine_karras(i, sx).reverse_bits();
    let y = laine_karras(sobol1_reversed(i), sy).reverse_bits();
    Vec2::new(unit(x), unit(y))
}

/// 24 bits of a value in [0, 2^32) as a float in [0, 1), never rounded up to 1.
#[inline]
fn unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Most draws [`PixelSampler`] prepares: the camera jitter and five per vertex for the longest
/// path (`sampling::MAX_REFLECTIONS`). Draws past the prepared ones take independent random
/// numbers, which keeps them unbiased.
const TABLE_DRAWS: usize = 1 + 5 * super::MAX_REFLECTIONS;

/// Largest spp whose shuffles are tabulated (at most 21 draws x 4096 x 4 bytes = 344 KB per
/// thread);
/// above it each draw computes its permutation element as it goes.
const SHUFFLE_TABLE_SPP: u32 = 4096;

/// Stream of the Fisher-Yates shuffles and of draws past `TABLE_DRAWS` (apart from the other
/// uses of `Rng::for_sample` with a pixel key).
const SHUFFLE_STREAM: u64 = 1 << 62;

/// The draws of one pixel's samples (see the module comment), prepared once for all of them.
/// Why prepare: a permutation element per draw and sample cost 20 % of a render (two of
/// Kensler's hashes, a chain of 18 dependent multiplications, on every draw); a table of
/// Fisher-Yates shuffles costs a few percent, and its permutations are uniform.
#[derive(Clone, Debug)]
pub struct PixelSampler {
    /// Key of the pixel (seed and pixel index mixed).
    key: u64,
    spp: u32,
    /// Draws prepared, at most `TABLE_DRAWS`.
    draws: usize,
    /// Per draw: the seeds of the two permutations (when not tabulated), and the Owen
    /// scrambles' seeds of its coordinates.
    seeds: [[u32; 4]; TABLE_DRAWS],
    /// `shuffle[d * spp + s]`: the Sobol index of sample s in draw d (empty above
    /// `table_spp`).
    shuffle: Vec<u32>,
    table_spp: u32,
}

impl PixelSampler {
    /// A sampler for pixels with `spp` samples whose paths make `draws` draws (the
    /// integrator's `draws_per_sample`); [`PixelSampler::start`] picks the pixel.
    pub fn new(spp: u32, draws: usize) -> PixelSampler {
        PixelSampler::with_table_limit(spp, draws, SHUFFLE_TABLE_SPP)
    }

    fn with_table_limit(spp: u32, draws: usize, table_spp: u32) -> PixelSampler {
        let spp = spp.max(1);
        PixelSampler {
            key: 0,
            spp,
            // At least the film jitter, which `extra_film_point` continues.
            draws: draws.clamp(1, TABLE_DRAWS),
            seeds: [[0; 4]; TABLE_DRAWS],
            shuffle: Vec::new(),
            table_spp,
        }
    }

    /// Prepares the draws of `pixel` in a run with `seed`.
    pub fn start(&mut self, seed: u64, pixel: u64) {
        self.key = mix64(seed ^ mix64(pixel.wrapping_mul(0xD134_2543_DE82_EF95)));
        for (d, s) in self.seeds[..self.draws].iter_mut().enumerate() {
            let h = mix64(self.key ^ (d as u64).wrapping_mul(0xA24B_AED4_963E_E407));
            let g = mix64(h);
            *s = [h as u32, (h >> 32) as u32, g as u32, (g >> 32) as u32];
        }
        if self.spp > self.table_spp {
            return;
        }
        let n = self.spp as usize;
        self.shuffle.resize(self.draws * n, 0);
        for (d, perm) in self.shuffle.chunks_exact_mut(n).enumerate() {
            for (i, p) in perm.iter_mut().enumerate() {
                *p = i as u32;
            }
            let mut rng = Rng::for_sample(self.key, d as u64, SHUFFLE_STREAM);
            for i in (1..n).rev() {
                // Lemire's multiply-shift: an index in 0..=i (bias below 2^-20 at 4096).
                let j = ((rng.next_u32() as u64 * (i as u64 + 1)) >> 32) as usize;
                perm.swap(i, j);
            }
        }
    }

    /// The film point of extra camera sample `j` of the pixel started last: Sobol point
    /// `spp + j` of the first draw (the film jitter), under that draw's scrambles.
    ///
    /// Why these points: the pixel's samples take points 0..spp of that draw in shuffled
    /// order, so samples and extras together take the first `spp + j + 1` points of one
    /// scrambled (0,2)-sequence, and with `spp x k` points in all (k a power of two, spp too)
    /// they form one net, stratified as a single run of that many samples would be. Each point
    /// is uniform on the pixel (Owen scrambling), so an average over them is unbiased.
    #[inline]
    pub fn extra_film_point(&self, j: u32) -> Vec2 {
        let [_, _, sx, sy] = self.seeds[0];
        sobol_point(self.spp.wrapping_add(j), sx, sy)
    }

    /// The draws of sample `sample` (below spp) of the pixel started last.
    #[inline]
    pub fn sample(&self, sample: u32) -> PathSampler<'_> {
        PathSampler {
            pixel: self,
            index: sample % self.spp,
            draw: 0,
        }
    }
}

/// The draws of one camera sample (see the module comment). Draws are numbered in the order
/// they are made; the integrator makes them in a fixed order whatever happens along the path,
/// so draw d of every sample of a pixel estimates the same dimension of the path integral.
#[derive(Clone, Debug)]
pub struct PathSampler<'a> {
    pixel: &'a PixelSampler,
    /// The sample index.
    index: u32,
    /// Draws made so far.
    draw: usize,
}

impl PathSampler<'_> {
    /// This draw's shuffled Sobol index and its coordinates' scramble seeds, or `None` past the
    /// prepared draws.
    #[inline]
    fn next_draw(&mut self) -> Option<(u32, u32, u32)> {
        let d = self.draw;
        self.draw += 1;
        let px = self.pixel;
        if d >= px.draws {
            return None;
        }
        let [a, b, sx, sy] = px.seeds[d];
        let i = match px.shuffle.get(d * px.spp as usize + self.index as usize) {
            Some(&i) => i,
            // One of Kensler's permutations is not random enough for small spp: at 16
            // samples the draws' correlation (the test's mean r^2) was 0.087 where
            // independent draws give 0.067; composed with a second, 0.067-0.068.
            None => permutation_element(permutation_element(self.index, px.spp, a), px.spp, b),
        };
        Some((i, sx, sy))
    }

    /// Independent numbers for draws past the prepared ones.
    fn unprepared(&self) -> Rng {
        let px = self.pixel;
        Rng::for_sample(px.key, self.index as u64, SHUFFLE_STREAM + self.draw as u64)
    }

    /// A number in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        let Some((i, sx, _)) = self.next_draw() else {
            return self.unprepared().next_f32();
        };
        // Dimension 0 is the van der Corput sequence, reverse(i); scrambled in reversed form.
        unit(laine_karras(i, sx).reverse_bits())
    }

    /// A point in [0, 1)^2.
    #[inline]
    pub fn next_vec2(&mut self) -> Vec2 {
        let Some((i, sx, sy)) = self.next_draw() else {
            return self.unprepared().next_vec2();
        };
        sobol_point(i, sx, sy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sobol dimension 1 by its definition, bit by bit.
    fn sobol1(index: u32) -> u32 {
        let mut v = 1u32 << 31;
        let mut x = 0;
        for bit in 0..32 {
            if index >> bit & 1 == 1 {
                x ^= v;
            }
            v ^= v >> 1;
        }
        x
    }

    #[test]
    fn byte_tables_equal_the_definition() {
        let mut z = 1u64;
        for i in (0..4096u32).chain((0..4096).map(|_| {
            z = mix64(z);
            z as u32
        })) {
            assert_eq!(sobol1_reversed(i), sobol1(i).reverse_bits(), "index {i}");
        }
        // The first points of dimension 1: 0, 1/2, 3/4, 1/4.
        let first: Vec<u32> = (0..4).map(sobol1).collect();
        assert_eq!(first, [0, 1 << 31, 3 << 30, 1 << 30]);
    }

    /// Every prefix of 2^k samples of a pixel puts exactly one point in each of the 2^k
    /// elementary intervals of every shape (2^a x 2^b cells, a + b = k), for every draw:
    /// the (0,k,2)-net property the variance reduction rests on.
    #[test]
    fn each_draw_is_a_net_over_a_pixels_samples() {
        for (k, table_spp) in [
            (4u32, 0),
            (4, SHUFFLE_TABLE_SPP),
            (6, 0),
            (8, SHUFFLE_TABLE_SPP),
        ] {
            let n = 1u32 << k;
            let mut sampler = PixelSampler::with_table_limit(n, 12, table_spp);
            for pixel in 0..3u64 {
                let mut points: Vec<Vec<Vec2>> = vec![Vec::new(); 6];
                let mut ones: Vec<Vec<f32>> = vec![Vec::new(); 6];
                sampler.start(7, pixel);
                for s in 0..n {
                    let mut p = sampler.sample(s);
                    for d in 0..6 {
                        ones[d].push(p.next_f32());
                        points[d].push(p.next_vec2());
                    }
                }
                for d in 0..6 {
                    for a in 0..=k {
                        let (cx, cy) = (1u32 << a, 1u32 << (k - a));
                        let mut seen = vec![false; n as usize];
                        for q in &points[d] {
                            let cell = (q.x * cx as f32) as u32 * cy + (q.y * cy as f32) as u32;
                            assert!(!seen[cell as usize], "k {k} draw {d} shape {cx}x{cy}");
                            seen[cell as usize] = true;
                        }
                    }
                    let mut seen = vec![false; n as usize];
                    for &x in &ones[d] {
                        let cell = (x * n as f32) as usize;
                        assert!(!seen[cell], "k {k} 1D draw {d}");
                        seen[cell] = true;
                    }
                }
            }
        }
    }

    /// A pixel's film jitters (draw 0 of its spp samples) and its `(m - 1) spp` extra film
    /// points together are one net of `m spp` points, with and without the shuffle table:
    /// what makes oversampled emission stratified as one run of `m spp` samples would be.
    /// Fails if the extras restart the sequence (they would repeat the samples' points).
    #[test]
    fn extra_film_points_complete_the_jitters_net() {
        for (spp, m, table_spp) in [
            (16u32, 2u32, SHUFFLE_TABLE_SPP),
            (16, 4, 0),
            (64, 4, SHUFFLE_TABLE_SPP),
        ] {
            let n = spp * m;
            let k = n.trailing_zeros();
            let mut sampler = PixelSampler::with_table_limit(spp, 6, table_spp);
            for pixel in 0..3u64 {
                sampler.start(11, pixel);
                let mut points: Vec<Vec2> =
                    (0..spp).map(|s| sampler.sample(s).next_vec2()).collect();
                points.extend((0..n - spp).map(|j| sampler.extra_film_point(j)));
                for a in 0..=k {
                    let (cx, cy) = (1u32 << a, 1u32 << (k - a));
                    let mut seen = vec![false; n as usize];
                    for q in &points {
                        let cell = (q.x * cx as f32) as u32 * cy + (q.y * cy as f32) as u32;
                        assert!(!seen[cell as usize], "spp {spp} x {m}: shape {cx}x{cy}");
                        seen[cell as usize] = true;
                    }
                }
            }
        }
    }

    /// Each coordinate is uniform (means 1/2 over many pixels), and the draws of one sample
    /// are independent of each other (the shuffle): within a pixel, the correlation over its
    /// samples between two draws has E[r^2] = 1/(n - 1) when their pairing is a random
    /// permutation, as for independent draws. Without the shuffle every draw takes the same
    /// point order, and r^2 is near 1. Statistical bounds: 5 standard errors. Both ways of
    /// shuffling: the table (Fisher-Yates) and, past its spp, the hashed permutations.
    #[test]
    fn draws_are_uniform_and_independent_of_each_other() {
        draws_are_uniform_and_independent(SHUFFLE_TABLE_SPP);
        draws_are_uniform_and_independent(0);
    }

    fn draws_are_uniform_and_independent(table_spp: u32) {
        let (pixels, spp) = (4096u64, 16usize);
        let mut sampler = PixelSampler::with_table_limit(spp as u32, 3, table_spp);
        let mut sums = [0f64; 4];
        let mut r2 = [0f64; 3];
        for pixel in 0..pixels {
            let mut v = vec![[0f64; 4]; spp];
            sampler.start(3, pixel);
            for (s, v) in v.iter_mut().enumerate() {
                let mut p = sampler.sample(s as u32);
                let a = p.next_vec2();
                *v = [
                    a.x as f64,
                    a.y as f64,
                    p.next_f32() as f64,
                    p.next_f32() as f64,
                ];
                for (sum, x) in sums.iter_mut().zip(*v) {
                    *sum += x;
                }
            }
            let corr = |i: usize, j: usize| {
                let m = |k: usize| v.iter().map(|x| x[k]).sum::<f64>() / spp as f64;
                let (mi, mj) = (m(i), m(j));
                let c: f64 = v.iter().map(|x| (x[i] - mi) * (x[j] - mj)).sum();
                let si: f64 = v.iter().map(|x| (x[i] - mi).powi(2)).sum();
                let sj: f64 = v.iter().map(|x| (x[j] - mj).powi(2)).sum();
                c * c / (si * sj)
            };
            r2[0] += corr(0, 2);
            r2[1] += corr(1, 3);
            r2[2] += corr(2, 3);
        }
        // Pixels are independent; a pixel's mean of a uniform coordinate over a net of 16 has
        // variance at most that of 16 independent ones, 1/12/16.
        let n = (pixels * spp as u64) as f64;
        let se_mean = (1.0 / 12.0 / n).sqrt();
        for (i, sum) in sums.iter().enumerate() {
            let mean = sum / n;
            assert!(
                (mean - 0.5).abs() < 5.0 * se_mean,
                "coordinate {i}: mean {mean}"
            );
        }
        // r^2 of independent pairs: mean 1/(n - 1), standard deviation below 2/(n - 1).
        let expected = 1.0 / (spp as f64 - 1.0);
        let se = 2.0 * expected / (pixels as f64).sqrt();
        for (i, r) in r2.iter().enumerate() {
            let r = r / pixels as f64;
            assert!(
                (r - expected).abs() < 5.0 * se,
                "table up to {table_spp} spp, pair {i}: mean r^2 {r}, independent draws give \
                 {expected}"
            );
        }
    }

    /// Draws past the prepared ones are uniform numbers: mean 1/2 and variance 1/12 (5
    /// standard errors each).
    #[test]
    fn draws_past_the_prepared_ones_are_uniform() {
        let mut sampler = PixelSampler::new(16, 1);
        let mut values = Vec::new();
        for pixel in 0..256 {
            sampler.start(5, pixel);
            for s in 0..16 {
                let mut p = sampler.sample(s);
                p.next_vec2();
                let q = p.next_vec2();
                values.extend([q.x as f64, q.y as f64, p.next_f32() as f64]);
            }
        }
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        assert!(
            (mean - 0.5).abs() < 5.0 * (1.0 / 12.0 / values.len() as f64).sqrt(),
            "{mean}"
        );
        let n = values.len() as f64;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        // The variance of (U - 1/2)^2 is 1/180.
        assert!(
            (var - 1.0 / 12.0).abs() < 5.0 * (1.0 / 180.0 / n).sqrt(),
            "{var}"
        );
    }

    #[test]
    fn same_key_same_numbers_other_pixel_other_numbers() {
        let draw = |seed, pixel, s| {
            let mut sampler = PixelSampler::new(8, 2);
            sampler.start(seed, pixel);
            let mut p = sampler.sample(s);
            (p.next_vec2(), p.next_f32())
        };
        assert_eq!(draw(1, 5, 3), draw(1, 5, 3));
        assert_ne!(draw(1, 5, 3), draw(1, 6, 3));
        assert_ne!(draw(1, 5, 3), draw(2, 5, 3));
    }
}
