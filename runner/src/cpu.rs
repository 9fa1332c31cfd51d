//! CPU backend: rayon over image rows, calling the very kernel functions the GPU runs.
//! ReSTIR runs its passes one after another over the whole image, like the GPU dispatches.
use std::time::Instant;

use kernels::integrators::restir;
use kernels::reservoir::Reservoir;
use kernels::types::{FrameParams, GBufferTexel};
use rayon::prelude::*;

use crate::backend::Backend;
use crate::error::Result;
use crate::integrator::{Integrator, Kernel};
use crate::restir::{RestirPass, RestirState};
use crate::scene::Scene;

pub struct CpuBackend {
    scene: Scene,
    width: u32,
    accum: Vec<[f32; 4]>,
    ray_counts: Vec<u32>,
    /// Made on the first ReSTIR frame.
    restir: Option<RestirState<Vec<GBufferTexel>, Vec<Reservoir>>>,
    restir_pass_ms: Vec<(&'static str, f64)>,
}

/// Run `f(x, y, out, rays)` for every pixel in parallel, rows at a time.
fn per_pixel<T: Send>(
    width: u32,
    out: &mut [T],
    ray_counts: &mut [u32],
    f: impl Fn(u32, u32, &mut T, &mut u32) + Sync,
) {
    // A slice of `()` takes no memory.
    let mut none = vec![(); out.len()];
    per_pixel_pair(width, out, &mut none, ray_counts, |x, y, o, _, rays| {
        f(x, y, o, rays)
    });
}

/// `per_pixel` for passes with two outputs per pixel: `f(x, y, a, b, rays)`.
fn per_pixel_pair<A: Send, B: Send>(
    width: u32,
    a: &mut [A],
    b: &mut [B],
    ray_counts: &mut [u32],
    f: impl Fn(u32, u32, &mut A, &mut B, &mut u32) + Sync,
) {
    let w = width as usize;
    a.par_chunks_mut(w)
        .zip(b.par_chunks_mut(w))
        .zip(ray_counts.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, ((row_a, row_b), counts))| {
            let texels = row_a.iter_mut().zip(row_b).zip(counts);
            for (x, ((oa, ob), c)) in texels.enumerate() {
                let mut rays = 0;
                f(x as u32, y as u32, oa, ob, &mut rays);
                *c = c.wrapping_add(rays);
            }
        });
}

impl CpuBackend {
    pub fn new(scene: &Scene, width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            scene: scene.clone(),
            width,
            accum: vec![[0.0; 4]; n],
            ray_counts: vec![0; n],
            restir: None,
            restir_pass_ms: Vec::new(),
        }
    }

    /// One ReSTIR frame, pass by pass, in the kernels' variant for plain scenes or not.
    fn restir_frame<const PLAIN: bool>(&mut self, params: &FrameParams) {
        let n = self.accum.len();
        let st = self.restir.get_or_insert_with(|| {
            RestirState::new(
                |_| vec![GBufferTexel::default(); n],
                |_| vec![Reservoir::empty(); n],
            )
        });
        self.restir_pass_ms.clear();
        let scene = self.scene.kernel();
        let width = self.width;
        for (pass, sl, p) in st.frame(params) {
            let start = Instant::now();
            let p = &p;
            // Take the written buffer out so the read ones can be borrowed alongside.
            let mut g_cur = std::mem::take(&mut st.gbuffers[sl.g_cur]);
            let g_prev = &st.gbuffers[sl.g_prev];
            match pass {
                RestirPass::Primary => {
                    per_pixel(width, &mut g_cur, &mut self.ray_counts, |x, y, o, rays| {
                        *o = restir::primary_hit::<PLAIN>(&scene, p, x, y, rays);
                    })
                }
                RestirPass::Shade | RestirPass::SpatialShade(_) => {
                    let (g, r) = (&g_cur, &st.reservoirs[sl.res_in]);
                    per_pixel(
                        width,
                        &mut self.accum,
                        &mut self.ray_counts,
                        |x, y, acc, rays| {
                            let i = (y * width + x) as usize;
                            let l = if pass == RestirPass::Shade {
                                restir::shade_pass::<PLAIN>(&scene, p, &g[i], &r[i], i as u32, rays)
                            } else {
                                restir::spatial_shade_pass::<PLAIN>(&scene, p, g, r, x, y, rays)
                            };
                            *acc = [acc[0] + l.x, acc[1] + l.y, acc[2] + l.z, acc[3] + 1.0];
                        },
                    );
                }
                RestirPass::PrimaryInitial => {
                    let mut out = std::mem::take(&mut st.reservoirs[sl.res_out]);
                    per_pixel_pair(
                        width,
                        &mut g_cur,
                        &mut out,
                        &mut self.ray_counts,
                        |x, y, g, r, rays| {
                            (*g, *r) = restir::primary_initial_pass::<PLAIN>(&scene, p, x, y, rays);
                        },
                    );
                    st.reservoirs[sl.res_out] = out;
                }
                _ => {
                    let mut out = std::mem::take(&mut st.reservoirs[sl.res_out]);
                    let (res_in, res_prev) =
                        (&st.reservoirs[sl.res_in], &st.reservoirs[sl.res_prev]);
                    let g = &g_cur;
                    per_pixel(width, &mut out, &mut self.ray_counts, |x, y, o, rays| {
                        let i = y * width + x;
                        *o = match pass {
                            RestirPass::Initial => {
                                restir::initial_pass::<PLAIN>(&scene, p, &g[i as usize], i, rays)
                            }
                            RestirPass::Temporal => restir::temporal_pass::<PLAIN>(
                                &scene,
                                p,
                                &g[i as usize],
                                res_in[i as usize],
                                g_prev,
                                res_prev,
                                i,
                                rays,
                            ),
                            _ => restir::spatial_pass::<PLAIN>(&scene, p, g, res_in, x, y, rays),
                        };
                    });
                    st.reservoirs[sl.res_out] = out;
                }
            }
            st.gbuffers[sl.g_cur] = g_cur;
            self.restir_pass_ms
                .push((pass.name(), start.elapsed().as_secs_f64() * 1e3));
        }
    }
}

impl Backend for CpuBackend {
    fn describe(&self) -> String {
        format!("cpu ({} threads)", rayon::current_num_threads())
    }

    fn pass(&mut self, integrator: Integrator, params: &FrameParams) -> Result<f64> {
        let start = Instant::now();
        let plain = crate::integrator::plain_scene(self.scene.all_diffuse(), params);
        let pixel = match integrator.kernel(plain) {
            Kernel::Image { pixel, .. } => pixel,
            Kernel::Restir { plain: true } => {
                self.restir_frame::<true>(params);
                return Ok(start.elapsed().as_secs_f64() * 1e3);
            }
            Kernel::Restir { plain: false } => {
                self.restir_frame::<false>(params);
                return Ok(start.elapsed().as_secs_f64() * 1e3);
            }
        };
        let scene = self.scene.kernel();
        per_pixel(
            self.width,
            &mut self.accum,
            &mut self.ray_counts,
            |x, y, acc, rays| {
                let r = pixel(&scene, params, x, y);
                *acc = [
                    acc[0] + r.sum.x,
                    acc[1] + r.sum.y,
                    acc[2] + r.sum.z,
                    acc[3] + params.samples as f32,
                ];
                *rays = r.rays;
            },
        );
        Ok(start.elapsed().as_secs_f64() * 1e3)
    }

    fn pass_breakdown(&self) -> Vec<(&'static str, f64)> {
        self.restir_pass_ms.clone()
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
