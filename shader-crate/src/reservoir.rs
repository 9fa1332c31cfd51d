//! Weighted reservoir sampling (the course's WRS), as used by RIS and ReSTIR DI.
//! A reservoir streams over candidates, keeps one with probability proportional to its
//! weight, and remembers the weight sum and how many candidates it has seen (M).
use crate::types::INVALID;

/// A reservoir's `triangle` when its sample is a direction of the environment map or the
/// sun rather than a point on an emissive triangle; (b1, b2) then hold the direction,
/// octahedrally encoded (`sampling::octahedral_encode`).
pub const DIRECTION_SAMPLE: u32 = INVALID - 1;

/// The selected light sample (a light triangle and barycentrics of the point on it, or a
/// direction: see `DIRECTION_SAMPLE`),
/// `w_sum`, `m`, the unbiased contribution weight `w` (W) and the target pdf p̂ of the
/// sample at the reservoir's owner. 32 bytes, stored in GPU buffers between passes.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct Reservoir {
    pub triangle: u32,
    pub b1: f32,
    pub b2: f32,
    pub w_sum: f32,
    pub m: f32,
    pub w: f32,
    pub target_pdf: f32,
    pub _pad: f32,
}

impl Reservoir {
    pub fn empty() -> Self {
        Self {
            triangle: INVALID,
            ..Default::default()
        }
    }

    pub fn has_sample(&self) -> bool {
        self.triangle != INVALID
    }

    /// Stream one candidate of resampling weight `weight` through the reservoir: it
    /// replaces the kept sample with probability weight / w_sum (after adding it). `u` is
    /// a uniform number in [0, 1). Returns whether it was kept.
    pub fn update(
        &mut self,
        triangle: u32,
        b1: f32,
        b2: f32,
        weight: f32,
        target_pdf: f32,
        u: f32,
    ) -> bool {
        self.m += 1.0;
        self.add(triangle, b1, b2, weight, target_pdf, u)
    }

    // `!(weight > 0.0)` on purpose: a NaN weight is refused along with zero and negatives.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn add(
        &mut self,
        triangle: u32,
        b1: f32,
        b2: f32,
        weight: f32,
        target_pdf: f32,
        u: f32,
    ) -> bool {
        if !(weight > 0.0) {
            return false;
        }
        self.w_sum += weight;
        if u * self.w_sum < weight {
            self.triangle = triangle;
            self.b1 = b1;
            self.b2 = b2;
            self.target_pdf = target_pdf;
            return true;
        }
        false
    }

    /// Generalised RIS (Lin et al. 2022): take another reservoir's sample y as a candidate
    /// of weight m(y) · p̂_here(y) · W, where `mis_weight` m is that reservoir's resampling
    /// MIS weight (all the weights of one merge sum to one wherever the target is non-zero:
    /// finalize with 1). Its M still counts towards this reservoir's confidence.
    pub fn resample(
        &mut self,
        other: &Reservoir,
        target_pdf_here: f32,
        mis_weight: f32,
        u: f32,
    ) -> bool {
        self.m += other.m;
        if !other.has_sample() {
            return false;
        }
        let weight = target_pdf_here * other.w * mis_weight;
        self.add(
            other.triangle,
            other.b1,
            other.b2,
            weight,
            target_pdf_here,
            u,
        )
    }

    /// W = w_sum / (normaliser · p̂(y)): the normaliser is M for candidates weighted 1/M
    /// (`update`) and 1 for MIS-weighted ones (`resample`).
    pub fn finalize(&mut self, normaliser: f32) {
        self.w = if self.has_sample() && self.target_pdf > 0.0 && normaliser > 0.0 {
            self.w_sum / (normaliser * self.target_pdf)
        } else {
            0.0
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    #[test]
    fn follows_the_courses_worked_example() {
        // p1 with weight 0.2 always enters an empty reservoir; p2 (0.6) then replaces it
        // with probability 0.6 / 0.8 = 0.75.
        let mut r = Reservoir::empty();
        assert!(r.update(1, 0.0, 0.0, 0.2, 1.0, 0.999));
        assert_eq!((r.triangle, r.w_sum, r.m), (1, 0.2, 1.0));
        let mut kept_p2 = 0;
        let mut rng = Rng::from_seed(1);
        for _ in 0..100_000 {
            let mut s = r;
            if s.update(2, 0.0, 0.0, 0.6, 1.0, rng.next_f32()) {
                kept_p2 += 1;
            }
            assert!((s.w_sum - 0.8).abs() < 1e-6 && s.m == 2.0);
        }
        let p = kept_p2 as f64 / 100_000.0;
        assert!(
            (p - 0.75).abs() < 5.0 * (0.75f64 * 0.25 / 100_000.0).sqrt(),
            "{p}"
        );
    }

    #[test]
    fn zero_weight_candidates_count_but_are_never_kept() {
        let mut r = Reservoir::empty();
        assert!(!r.update(7, 0.0, 0.0, 0.0, 0.0, 0.0));
        assert!(!r.has_sample() && r.m == 1.0);
        r.finalize(r.m);
        assert_eq!(r.w, 0.0);
    }
}
