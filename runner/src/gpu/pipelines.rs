//! The kernels' SPIR-V module and their compute pipelines, made on first use.
use std::borrow::Cow;
use std::collections::HashMap;

use kernels::bindings;
use kernels::integrators::ao;

use super::bindings::layout;
use crate::integrator::{Integrator, Kernel};
use crate::restir::RestirPass;

/// The kernels' SPIR-V, compiled from shader-crate by runner/build.rs.
const SPIRV: &[u8] = include_bytes!(env!("kernels.spv"));

/// Workgroup size of the integrators' image kernels (`kernel!(threads(8, 8), ..)` in
/// entry.rs): two warps of 8×4 pixels.
pub const IMAGE_WORKGROUP: (u32, u32) = (8, 8);
/// Workgroup size of the AO kernels (`ao_kernel!` in entry.rs), whose threads share one
/// pool of AO rays (`kernels::integrators::ao::render_group_pixel`): 16×56 where `wide`
/// (`wide_ao`), else 16×8.
pub fn ao_workgroup(wide: bool) -> (u32, u32) {
    let threads = if wide {
        ao::WIDE_GROUP
    } else {
        ao::SMALL_GROUP
    };
    (ao::GROUP_WIDTH as u32, (threads / ao::GROUP_WIDTH) as u32)
}
/// AO's kernels in 16×56 workgroups, by the integrator table's (16×8) name.
const WIDE_AO: [(&str, &str); 2] = [
    ("entry::ao_main", "entry::ao_wide_main"),
    ("entry::ao_plain_main", "entry::ao_plain_wide_main"),
];
/// PCI vendor id of NVIDIA's adapters.
const NVIDIA: u32 = 0x10de;

/// Whether an adapter runs AO in 16×56 workgroups: NVIDIA's, where they were 2–5% faster
/// (H100; docs/PERFORMANCE.md, "Occupancy measured"). Elsewhere 16×8, as lavapipe needs (see
/// `ao::SMALL_GROUP`) and as no other GPU was measured with.
pub fn wide_ao(info: &wgpu::AdapterInfo) -> bool {
    info.vendor == NVIDIA && info.device_type != wgpu::DeviceType::Cpu
}

/// The entry point that runs the table's entry point `name` (`wide`: see `wide_ao`).
fn entry_name(name: &'static str, wide: bool) -> &'static str {
    match WIDE_AO.iter().find(|(small, _)| *small == name) {
        Some((_, wide_name)) if wide => wide_name,
        _ => name,
    }
}
/// Workgroup size of ReSTIR's passes (`threads(16, 8)`): four warps of 16×2 pixels. On the
/// H100, 1–3% faster than 8×8 for every ReSTIR scene measured, while NEE and pt on the 1M
/// suite scenes were 2–4% slower at 16×8 (docs/PERFORMANCE.md, "Workgroup shape").
pub const RESTIR_WORKGROUP: (u32, u32) = (16, 8);
// The initial pass's light tiles are meant to be its warps (32 invocations, whole rows of
// the workgroup): if the workgroup changes shape, the tiles must follow it.
const _: () = {
    let tile = kernels::integrators::restir::LIGHT_TILE;
    assert!(tile.0 == RESTIR_WORKGROUP.0 && tile.0 * tile.1 == 32);
};

/// Whether `entry_point` is one of AO's kernels (see `AO_WORKGROUP`), as the integrator
/// table names them.
fn is_ao(entry_point: &str) -> bool {
    Integrator::Ao
        .kernels()
        .into_iter()
        .any(|k| matches!(k, Kernel::Image { entry_point: e, .. } if e == entry_point))
}

/// The workgroup size of a kernel's entry points (`wide`: see `wide_ao`).
pub fn workgroup(kernel: Kernel, wide: bool) -> (u32, u32) {
    match kernel {
        Kernel::Image { entry_point, .. } if is_ao(entry_point) => ao_workgroup(wide),
        Kernel::Image { .. } => IMAGE_WORKGROUP,
        Kernel::Restir { .. } => RESTIR_WORKGROUP,
    }
}

/// Workgroups that cover a `width`×`height` image.
pub fn workgroups(kernel: Kernel, wide: bool, width: u32, height: u32) -> (u32, u32) {
    let (wx, wy) = workgroup(kernel, wide);
    (width.div_ceil(wx), height.div_ceil(wy))
}

/// The kernels' SPIR-V as 32-bit words.
pub fn spirv_words() -> Vec<u32> {
    SPIRV
        .as_chunks::<4>()
        .0
        .iter()
        .map(|w| u32::from_le_bytes(*w))
        .collect()
}

/// The compute entry points of a kernel: an image kernel's one, or ReSTIR's passes
/// (`wide`: see `wide_ao`).
pub fn entry_points(kernel: Kernel, wide: bool) -> Vec<&'static str> {
    match kernel {
        Kernel::Image { entry_point, .. } => vec![entry_name(entry_point, wide)],
        Kernel::Restir { plain } => RestirPass::ENTRY_POINTS
            .iter()
            .map(|p| p.entry_point(plain))
            .collect(),
    }
}

/// The compute entry points of a kernel on any adapter (AO's in both workgroup sizes, which
/// the module holds), each once and with its workgroup size.
pub fn every_entry_point(kernel: Kernel) -> Vec<(&'static str, (u32, u32))> {
    let mut all = Vec::new();
    for wide in [false, true] {
        for name in entry_points(kernel, wide) {
            let entry = (name, workgroup(kernel, wide));
            if !all.contains(&entry) {
                all.push(entry);
            }
        }
    }
    all
}

/// The module, the layouts of both descriptor sets, and the pipelines made so far.
pub struct Pipelines {
    module: wgpu::ShaderModule,
    pub scene_layout: wgpu::BindGroupLayout,
    pub restir_layout: wgpu::BindGroupLayout,
    image_pipeline_layout: wgpu::PipelineLayout,
    restir_pipeline_layout: wgpu::PipelineLayout,
    /// Compute pipelines by entry point, made on first use: the driver compiles each one,
    /// and a render that runs one integrator should not wait for all ten (on a cold NVIDIA
    /// shader cache that was seconds).
    made: HashMap<&'static str, wgpu::ComputePipeline>,
    /// AO in 16×56 workgroups (`wide_ao`).
    wide: bool,
}

impl Pipelines {
    pub fn new(device: &wgpu::Device, wide: bool) -> Self {
        // Every entry point of the module, in either workgroup size.
        let mut names: Vec<(&'static str, (u32, u32))> = Integrator::ALL
            .into_iter()
            .flat_map(Integrator::kernels)
            .flat_map(every_entry_point)
            .collect();
        names.sort_unstable();
        names.dedup();
        let entry_points: Vec<wgpu::PassthroughShaderEntryPoint> = names
            .into_iter()
            .map(|(name, (wx, wy))| wgpu::PassthroughShaderEntryPoint {
                name: Cow::Borrowed(name),
                workgroup_size: (wx, wy, 1),
            })
            .collect();
        // SAFETY: the module is rust-gpu output validated by spirv-val at build time, and the
        // layouts below come from the binding tables its entry points declare (checked by
        // tests/bindings.rs against the module itself).
        let module = unsafe {
            device.create_shader_module_passthrough(wgpu::ShaderModuleDescriptorPassthrough {
                label: Some("kernels"),
                entry_points: Cow::Owned(entry_points),
                spirv: Some(Cow::Owned(spirv_words())),
                ..Default::default()
            })
        };
        let compute = wgpu::ShaderStages::COMPUTE;
        let scene_layout = layout(device, "scene", &bindings::SCENE, compute);
        let restir_layout = layout(device, "restir", &bindings::RESTIR, compute);
        let pipeline_layout = |label, sets: &[Option<&wgpu::BindGroupLayout>]| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: sets,
                immediate_size: 0,
            })
        };
        let image_pipeline_layout = pipeline_layout("image", &[Some(&scene_layout)]);
        let restir_pipeline_layout =
            pipeline_layout("restir", &[Some(&scene_layout), Some(&restir_layout)]);
        Self {
            module,
            scene_layout,
            restir_layout,
            image_pipeline_layout,
            restir_pipeline_layout,
            made: HashMap::new(),
            wide,
        }
    }

    /// Make the pipelines `kernel` runs, if not made yet.
    pub fn ensure(&mut self, device: &wgpu::Device, kernel: Kernel) {
        let layout = match kernel {
            Kernel::Image { .. } => &self.image_pipeline_layout,
            Kernel::Restir { .. } => &self.restir_pipeline_layout,
        };
        for name in entry_points(kernel, self.wide) {
            if self.made.contains_key(name) {
                continue;
            }
            let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(name),
                layout: Some(layout),
                module: &self.module,
                entry_point: Some(name),
                compilation_options: Default::default(),
                cache: None,
            });
            self.made.insert(name, pipeline);
        }
    }

    /// The pipeline of the table's entry point `entry_point`, made by `ensure`.
    pub fn get(&self, entry_point: &'static str) -> &wgpu::ComputePipeline {
        &self.made[entry_name(entry_point, self.wide)]
    }

    /// Workgroups of `kernel` that cover a `width`×`height` image on this adapter.
    pub fn workgroups(&self, kernel: Kernel, width: u32, height: u32) -> (u32, u32) {
        workgroups(kernel, self.wide, width, height)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ao_kernels_dispatch_in_their_workgroups_and_the_others_in_theirs() {
        for integrator in Integrator::ALL {
            for kernel in integrator.kernels() {
                for wide in [false, true] {
                    let want = match (integrator, kernel) {
                        (Integrator::Ao, _) => ao_workgroup(wide),
                        (_, Kernel::Image { .. }) => IMAGE_WORKGROUP,
                        (_, Kernel::Restir { .. }) => RESTIR_WORKGROUP,
                    };
                    assert_eq!(workgroup(kernel, wide), want, "{integrator:?}");
                }
            }
        }
    }
}
