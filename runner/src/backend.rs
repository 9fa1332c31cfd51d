//! What the renderer needs from a backend: run one pass of a kernel over the image,
//! adding into an accumulation buffer (rgb = sum of samples, a = their count).
use kernels::types::FrameParams;

use crate::cli::Integrator;
use crate::error::Result;

pub trait Backend {
    /// One line for the user: which device runs the kernels.
    fn describe(&self) -> String;
    /// Run `integrator` for `params.samples` samples per pixel, adding to the accumulation.
    /// Returns the pass's device time in milliseconds where the backend measures it
    /// (GPU timestamps), else the wall-clock time.
    fn pass(&mut self, integrator: Integrator, params: &FrameParams) -> Result<f64>;
    /// Per-pass times of the last multi-pass frame (ReSTIR), in ms; empty otherwise.
    fn pass_breakdown(&self) -> Vec<(&'static str, f64)> {
        Vec::new()
    }
    fn read_accumulation(&mut self) -> Result<Vec<[f32; 4]>>;
    /// Rays traced since the last `clear` (camera, bounce, shadow and AO rays).
    fn rays_traced(&mut self) -> Result<u64>;
    fn clear(&mut self) -> Result<()>;
}
