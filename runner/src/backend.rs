//! What the renderer needs from a backend: run one pass of a kernel over the image,
//! adding into an accumulation buffer (rgb = sum of samples, a = their count).
use kernels::types::FrameParams;

use clap::{Args, ValueEnum};

use crate::bail;
use crate::cpu::CpuBackend;
use crate::error::Result;
use crate::gpu::{adapters, check_fits, is_software, GpuBackend, GpuContext};
use crate::integrator::Integrator;
use crate::scene::Scene;

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

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum BackendChoice {
    /// A hardware GPU that the scene fits on, else the CPU backend (which runs the kernels
    /// faster than a software Vulkan driver such as lavapipe)
    Auto,
    /// A Vulkan adapter (hardware preferred, else a software driver); fail if there is none
    Gpu,
    /// The CPU backend: the same kernel functions, rayon over pixels
    Cpu,
}

/// Where the kernels run (`render`, `bench` and `view`).
#[derive(Args, Debug, Clone)]
pub struct DeviceOptions {
    /// Where to run: auto, gpu or cpu
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
}

/// Open the backend the user asked for. `auto` takes the first hardware GPU that the scene
/// fits on, else the CPU backend, and says why on stderr when it is not the GPU.
pub fn open(
    choice: BackendChoice,
    scene: &Scene,
    width: u32,
    height: u32,
) -> Result<Box<dyn Backend>> {
    if choice == BackendChoice::Cpu {
        return Ok(Box::new(CpuBackend::new(scene, width, height)));
    }
    let list = adapters();
    let adapter = match choice {
        BackendChoice::Gpu => match list.first() {
            Some(a) => a,
            None => bail!(
                "no Vulkan adapter with SPIR-V passthrough and subgroup operations found \
                 (install a Vulkan driver, e.g. mesa-vulkan-drivers, or use --backend cpu)"
            ),
        },
        _ => {
            let fits: Vec<AdapterFit> = list
                .iter()
                .map(|a| AdapterFit {
                    name: a.get_info().name,
                    software: is_software(a),
                    fits: check_fits(&a.limits(), scene, width, height),
                })
                .collect();
            match choose_auto(&fits) {
                AutoChoice::Gpu(i) => &list[i],
                AutoChoice::Cpu(why) => {
                    eprintln!("note: {why}");
                    return Ok(Box::new(CpuBackend::new(scene, width, height)));
                }
            }
        }
    };
    let ctx = GpuContext::new(adapter)?;
    Ok(Box::new(GpuBackend::new(ctx, scene, width, height)?))
}

/// Whether the kernels will run on the CPU backend, as far as that is known before a scene
/// loads, so that its tree can be priced for the CPU (`collapse::set_for_cpu`): `cpu`, or
/// `auto` on a machine without a hardware GPU, where `choose_auto` takes the CPU whatever
/// the scene. (A scene too large for the GPU is the one case that runs on the CPU backend
/// with the GPU's tree: that is decided only once it has loaded.)
pub fn expects_cpu(choice: BackendChoice) -> bool {
    match choice {
        BackendChoice::Cpu => true,
        BackendChoice::Gpu => false,
        BackendChoice::Auto => !adapters().iter().any(|a| !is_software(a)),
    }
}

/// A Vulkan adapter as `--backend auto` weighs it.
#[derive(Clone, Debug)]
pub struct AdapterFit {
    pub name: String,
    /// A software rasteriser (lavapipe, SwiftShader): it runs our SPIR-V, but slower than
    /// the CPU backend runs the same kernels (README, "Using the renderer": `--backend auto`).
    pub software: bool,
    /// Whether the scene and image fit the adapter's limits, and if not, why.
    pub fits: Result<()>,
}

/// What `--backend auto` runs on.
#[derive(Clone, Debug, PartialEq)]
pub enum AutoChoice {
    /// The adapter at this index of the list.
    Gpu(usize),
    /// The CPU backend, and one line for the user saying why.
    Cpu(String),
}

/// `--backend auto`: the first hardware GPU the scene fits on; else the CPU backend. A
/// software Vulkan driver is never chosen: on the machines we measured, the CPU backend
/// ran the same kernels 4-7x faster in a fraction of the memory.
pub fn choose_auto(adapters: &[AdapterFit]) -> AutoChoice {
    if let Some(i) = adapters.iter().position(|a| !a.software && a.fits.is_ok()) {
        return AutoChoice::Gpu(i);
    }
    if let Some(a) = adapters.iter().find(|a| !a.software) {
        let why = a
            .fits
            .as_ref()
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        return AutoChoice::Cpu(format!(
            "the scene does not fit on GPU '{}' ({why}); rendering on the CPU backend instead",
            a.name
        ));
    }
    match adapters.iter().find(|a| a.software) {
        Some(a) => AutoChoice::Cpu(format!(
            "no hardware GPU; rendering on the CPU backend, which runs the same kernels faster than \
             the software Vulkan driver '{}' (--backend gpu runs them there)",
            a.name
        )),
        None => AutoChoice::Cpu("no Vulkan adapter found; rendering on the CPU backend".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    fn adapter(name: &str, software: bool, fits: bool) -> AdapterFit {
        let fits = if fits {
            Ok(())
        } else {
            Err(Error("the triangle buffer needs 9 bytes".into()))
        };
        AdapterFit {
            name: name.into(),
            software,
            fits,
        }
    }

    #[test]
    fn auto_prefers_a_hardware_gpu_the_scene_fits_on() {
        let list = [
            adapter("llvmpipe", true, true),
            adapter("small", false, false),
            adapter("big", false, true),
        ];
        assert_eq!(choose_auto(&list), AutoChoice::Gpu(2));
    }

    #[test]
    fn auto_falls_back_to_the_cpu_and_says_why() {
        let AutoChoice::Cpu(why) = choose_auto(&[
            adapter("small", false, false),
            adapter("llvmpipe", true, true),
        ]) else {
            panic!("a scene that fits no hardware GPU must go to the CPU backend");
        };
        assert!(
            why.contains("'small'") && why.contains("triangle buffer needs 9 bytes"),
            "{why}"
        );
        let AutoChoice::Cpu(why) = choose_auto(&[adapter("llvmpipe", true, true)]) else {
            panic!("a software driver must not be chosen");
        };
        assert!(
            why.contains("no hardware GPU") && why.contains("'llvmpipe'"),
            "{why}"
        );
        let AutoChoice::Cpu(why) = choose_auto(&[]) else {
            panic!("no adapter: CPU")
        };
        assert!(why.contains("no Vulkan adapter"), "{why}");
    }
}
