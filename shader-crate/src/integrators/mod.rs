//! Per-pixel integrators. Each `render_pixel` returns the *sum* of `params.samples`
//! samples and the number of rays it traced; the caller adds the sum to the accumulation
//! buffer (and divides by the total count at the end) and the rays to the statistics.
pub mod ao;
pub mod path;
pub mod restir;
pub mod ris;

use crate::camera::jittered_ray;
use crate::glam::Vec3;
use crate::intersect::Ray;
use crate::rng::Rng;
use crate::types::FrameParams;

/// Sum of a pixel's samples and the rays traced for them.
#[derive(Copy, Clone, Debug, Default)]
pub struct PixelResult {
    pub sum: Vec3,
    pub rays: u32,
}

/// Sample `s` of pixel (x, y): its camera ray and the rest of its random stream (pixel,
/// frame, sample_offset + s, seed), whose first two numbers jittered the ray.
pub fn camera_sample(params: &FrameParams, x: u32, y: u32, s: u32) -> (Ray, Rng) {
    let pixel = y * params.width + x;
    let mut rng = Rng::new(pixel, params.frame, params.sample_offset + s, params.seed);
    let ray = jittered_ray(&params.camera, params.width, params.height, x, y, &mut rng);
    (ray, rng)
}

/// The sample loop shared by all integrators: sample `s` of pixel (x, y) draws the stream
/// (pixel, frame, sample_offset + s, seed); its first two numbers jitter the position in
/// the pixel, the rest belong to `radiance`, which also counts the rays it traces.
/// Non-finite samples are dropped (counted as 0) so one bad path can never poison a pixel.
pub fn accumulate_samples<F: Fn(Ray, &mut Rng, &mut u32) -> Vec3>(
    params: &FrameParams,
    x: u32,
    y: u32,
    radiance: F,
) -> PixelResult {
    let mut sum = Vec3::ZERO;
    let mut rays = 0u32;
    let mut s = 0;
    while s < params.samples {
        let (ray, mut rng) = camera_sample(params, x, y, s);
        let l = radiance(ray, &mut rng, &mut rays);
        if l.is_finite() {
            sum += l;
        }
        s += 1;
    }
    PixelResult { sum, rays }
}
