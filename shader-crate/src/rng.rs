//! Counter-based random numbers: the stream of a sample is a pure function of
//! (pixel, frame, sample, seed), and the n-th draw from it is "dimension" n. Integer-only,
//! so the CPU and the GPU draw bit-identical numbers.

use crate::bits::shr;

/// PCG-RXS-M-XS 32-bit output permutation of one LCG step (Jarzynski & Olano 2020,
/// "Hash Functions for GPU Rendering": the recommended 1D hash).
pub fn pcg_hash(input: u32) -> u32 {
    pcg_output(lcg_step(input))
}

/// One step of PCG's 32-bit LCG.
fn lcg_step(state: u32) -> u32 {
    state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453)
}

/// PCG's RXS-M-XS output permutation of an LCG state (the shift below 32: `bits::shr`).
fn pcg_output(state: u32) -> u32 {
    let word = (shr(state, (state >> 28) + 4) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// Two uniform numbers in [0, 1) for item `index` of the family `key` (a number drawn from
/// another stream), 16 bits each from one hash: an AO ray's jitter, made by whichever
/// thread traces the ray (see `ao::AoRays`), where a stream of its own cost four hashes.
/// `index` is spread by the golden ratio's multiplier before it meets the key, so that
/// neighbouring indices differ in high bits too.
pub fn keyed_pair(key: u32, index: u32) -> (f32, f32) {
    const SCALE: f32 = 1.0 / 65_536.0;
    let h = pcg_hash(key ^ index.wrapping_mul(0x9e37_79b9));
    ((h >> 16) as f32 * SCALE, (h & 0xffff) as f32 * SCALE)
}

#[derive(Copy, Clone, Debug)]
pub struct Rng {
    state: u32,
}

impl Rng {
    /// The stream for one sample of one pixel.
    pub fn new(pixel: u32, frame: u32, sample: u32, seed: u32) -> Self {
        let h = pcg_hash(seed);
        let h = pcg_hash(h ^ frame);
        let h = pcg_hash(h ^ sample);
        Self {
            state: pcg_hash(h ^ pixel),
        }
    }

    /// A stream keyed by an arbitrary integer (tests, per-light streams).
    pub fn from_seed(seed: u32) -> Self {
        Self {
            state: pcg_hash(seed),
        }
    }

    pub fn next_u32(&mut self) -> u32 {
        // PCG: advance the LCG, output the permuted state.
        self.state = lcg_step(self.state);
        pcg_output(self.state)
    }

    /// Uniform in [0, 1): the top 24 bits, exactly representable in f32.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_key_same_stream_and_different_keys_differ() {
        let mut a = Rng::new(7, 1, 2, 3);
        let mut b = Rng::new(7, 1, 2, 3);
        let mut c = Rng::new(8, 1, 2, 3);
        let xa: [u32; 4] = core::array::from_fn(|_| a.next_u32());
        let xb: [u32; 4] = core::array::from_fn(|_| b.next_u32());
        let xc: [u32; 4] = core::array::from_fn(|_| c.next_u32());
        assert_eq!(xa, xb);
        assert_ne!(xa, xc);
    }

    #[test]
    fn uniform_mean_and_variance() {
        // Mean 1/2 and variance 1/12; with n draws the standard error of the mean is
        // sqrt(1/12/n): assert within 5 of them.
        let n = 200_000;
        let mut rng = Rng::new(1, 0, 0, 0);
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let x = rng.next_f32() as f64;
            assert!((0.0..1.0).contains(&x));
            sum += x;
            sum2 += x * x;
        }
        let mean = sum / n as f64;
        let var = sum2 / n as f64 - mean * mean;
        let se = (1.0 / 12.0 / n as f64).sqrt();
        assert!((mean - 0.5).abs() < 5.0 * se, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 0.002, "var {var}");
    }

    #[test]
    fn neighbouring_pixels_are_uncorrelated() {
        // Correlation of first draws across adjacent pixel indices ~ N(0, 1/n).
        let n = 100_000u32;
        let xs: Vec<f64> = (0..=n)
            .map(|p| Rng::new(p, 0, 0, 0).next_f32() as f64 - 0.5)
            .collect();
        let corr: f64 = xs.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / n as f64 * 12.0;
        assert!(corr.abs() < 5.0 / (n as f64).sqrt(), "corr {corr}");
    }

    #[test]
    fn keyed_pairs_are_uniform_and_uncorrelated() {
        // As AO uses them: indices 0..64 of many keys. Both numbers uniform (mean within 5
        // standard errors of 1/2), uncorrelated with each other and with the next index's,
        // and the pairs even over a 16 × 16 grid (chi-square with 255 degrees of freedom:
        // mean 255, sd 22.6; 5 sd above is 368).
        let mut key_rng = Rng::from_seed(7);
        let mut pairs = Vec::new();
        for _ in 0..2_000 {
            let key = key_rng.next_u32();
            pairs.extend((0..64).map(|k| keyed_pair(key, k)));
        }
        let n = pairs.len() as f64;
        let centred: Vec<(f64, f64)> = pairs
            .iter()
            .map(|&(a, b)| (a as f64 - 0.5, b as f64 - 0.5))
            .collect();
        let se = (1.0 / 12.0 / n).sqrt();
        let mean_a = centred.iter().map(|c| c.0).sum::<f64>() / n;
        let mean_b = centred.iter().map(|c| c.1).sum::<f64>() / n;
        assert!(
            mean_a.abs() < 5.0 * se && mean_b.abs() < 5.0 * se,
            "{mean_a} {mean_b}"
        );
        // Correlations scaled by 1/variance: ~N(0, 1/n).
        let bound = 5.0 / n.sqrt();
        let within = centred.iter().map(|c| c.0 * c.1).sum::<f64>() / n * 12.0;
        let next = centred.windows(2).map(|w| w[0].0 * w[1].0).sum::<f64>() / n * 12.0;
        assert!(
            within.abs() < bound && next.abs() < bound,
            "{within} {next}"
        );
        let mut cells = [0u32; 256];
        for &(a, b) in &pairs {
            cells[(a * 16.0) as usize * 16 + (b * 16.0) as usize] += 1;
        }
        let expected = n / 256.0;
        let chi2: f64 = cells
            .iter()
            .map(|&c| (c as f64 - expected).powi(2) / expected)
            .sum();
        assert!(chi2 < 368.0, "chi2 {chi2}");
        assert_ne!(keyed_pair(1, 0), keyed_pair(2, 0));
    }
}
