//! CPU backend: rayon over image rows, calling the very kernel functions the GPU runs.
use std::time::Instant;

use kernels::integrators::{ao, path};
use kernels::types::FrameParams;
use rayon::prelude::*;

use crate::backend::Backend;
use crate::cli::Integrator;
use crate::error::Result;
use crate::scene::Scene;

pub struct CpuBackend {
    scene: Scene,
    width: u32,
    accum: Vec<[f32; 4]>,
    ray_counts: Vec<u32>,
}

impl CpuBackend {
    pub fn new(scene: &Scene, width: u32, height: u32) -> Self {
        Self {
            scene: scene.clone(),
            width,
            accum: vec![[0.0; 4]; width as usize * height as usize],
            ray_counts: vec![0; width as usize * height as usize],
        }
    }
}

impl Backend for CpuBackend {
    fn describe(&self) -> String {
        format!("cpu ({} threads)", rayon::current_num_threads())
    }

    fn pass(&mut self, integrator: Integrator, params: &FrameParams) -> Result<f64> {
        let start = Instant::now();
        let scene = self.scene.kernel();
        let width = self.width as usize;
        self.accum
            .par_chunks_mut(width)
            .zip(self.ray_counts.par_chunks_mut(width))
            .enumerate()
            .for_each(|(y, (row, counts))| {
                for (x, (acc, count)) in row.iter_mut().zip(counts).enumerate() {
                    let (x, y) = (x as u32, y as u32);
                    let r = match integrator {
                        Integrator::Ao => ao::render_pixel(&scene, params, x, y),
                        Integrator::Pt => path::render_pixel(&scene, params, x, y, path::BSDF),
                        Integrator::Nee => path::render_pixel(&scene, params, x, y, path::NEE),
                        Integrator::Mis => path::render_pixel(&scene, params, x, y, path::MIS),
                    };
                    acc[0] += r.sum.x;
                    acc[1] += r.sum.y;
                    acc[2] += r.sum.z;
                    acc[3] += params.samples as f32;
                    *count = count.wrapping_add(r.rays);
                }
            });
        Ok(start.elapsed().as_secs_f64() * 1e3)
    }

    fn read_accumulation(&mut self) -> Result<Vec<[f32; 4]>> {
        Ok(self.accum.clone())
    }

    fn rays_traced(&mut self) -> Result<u64> {
        Ok(self.ray_counts.iter().map(|&c| c as u64).sum())
    }

    fn clear(&mut self) -> Result<()> {
        self.accum.iter_mut().for_each(|a| *a = [0.0; 4]);
        self.ray_counts.iter_mut().for_each(|c| *c = 0);
        Ok(())
    }
}
