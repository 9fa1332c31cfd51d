//! What the driver made of each kernel: the compile-time statistics a Vulkan driver reports
//! through VK_KHR_pipeline_executable_properties, one line per entry point (NVIDIA 580:
//! registers, binary size, stack, local and shared memory; lavapipe does not offer the
//! extension). wgpu creates its pipelines without asking for them, so this builds the same
//! pipelines (the same SPIR-V, the same descriptor set layouts from `kernels::bindings`)
//! through ash directly: `cargo run --release --example kernel_stats [NAME...]`, every
//! entry point, or those whose names contain one of the NAMEs (the driver takes ~100 s
//! for all of them on the H100). The local memory size it reports is offset by 2^36.
//!
//! Neither internal representations nor the pipeline cache gave NVIDIA's machine code (the
//! 580 driver returns no representation, and its cache holds no ELF image), so this asks
//! for the statistics alone.
use std::ffi::CStr;

use ash::vk;
use kernels::bindings::{self, Binding};
use runner::gpu::{every_entry_point, spirv_words};
use runner::integrator::Integrator;

const EXTENSION: &CStr = ash::khr::pipeline_executable_properties::NAME;

fn main() {
    if let Err(e) = unsafe { run() } {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn text(chars: &[std::ffi::c_char]) -> String {
    // SAFETY: Vulkan fills these fixed arrays with NUL-terminated strings.
    unsafe { CStr::from_ptr(chars.as_ptr()) }
        .to_string_lossy()
        .into_owned()
}

fn value(s: &vk::PipelineExecutableStatisticKHR) -> String {
    // SAFETY: `format` says which member of the union the driver wrote.
    unsafe {
        match s.format {
            vk::PipelineExecutableStatisticFormatKHR::BOOL32 => (s.value.b32 != 0).to_string(),
            vk::PipelineExecutableStatisticFormatKHR::INT64 => s.value.i64.to_string(),
            vk::PipelineExecutableStatisticFormatKHR::UINT64 => s.value.u64.to_string(),
            vk::PipelineExecutableStatisticFormatKHR::FLOAT64 => format!("{:.3}", s.value.f64),
            _ => "?".into(),
        }
    }
}

unsafe fn set_layout(
    device: &ash::Device,
    table: &[Binding],
) -> Result<vk::DescriptorSetLayout, String> {
    let entries: Vec<vk::DescriptorSetLayoutBinding> = table
        .iter()
        .map(|b| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(b.binding)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::COMPUTE)
        })
        .collect();
    let info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&entries);
    device
        .create_descriptor_set_layout(&info, None)
        .map_err(|e| format!("descriptor set layout: {e}"))
}

unsafe fn run() -> Result<(), String> {
    let entry = ash::Entry::load().map_err(|e| format!("no Vulkan loader: {e}"))?;
    let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_2);
    let instance = entry
        .create_instance(
            &vk::InstanceCreateInfo::default().application_info(&app),
            None,
        )
        .map_err(|e| format!("Vulkan instance: {e}"))?;
    let has_extension = |pd: vk::PhysicalDevice| {
        instance
            .enumerate_device_extension_properties(pd)
            .unwrap_or_default()
            .iter()
            .any(|e| e.extension_name_as_c_str() == Ok(EXTENSION))
    };
    let mut candidates: Vec<vk::PhysicalDevice> = instance
        .enumerate_physical_devices()
        .map_err(|e| format!("physical devices: {e}"))?
        .into_iter()
        .filter(|&pd| has_extension(pd))
        .collect();
    // A discrete GPU before a software one.
    candidates.sort_by_key(|&pd| {
        instance.get_physical_device_properties(pd).device_type
            != vk::PhysicalDeviceType::DISCRETE_GPU
    });
    let pd = *candidates
        .first()
        .ok_or("no Vulkan device offers VK_KHR_pipeline_executable_properties")?;
    let props = instance.get_physical_device_properties(pd);
    println!(
        "device: {} (driver {:#x})",
        text(&props.device_name),
        props.driver_version
    );
    let family = instance
        .get_physical_device_queue_family_properties(pd)
        .iter()
        .position(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE))
        .ok_or("no compute queue")? as u32;
    let priorities = [1.0];
    let queues = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(family)
        .queue_priorities(&priorities)];
    let extensions = [EXTENSION.as_ptr()];
    let mut feature = vk::PhysicalDevicePipelineExecutablePropertiesFeaturesKHR::default()
        .pipeline_executable_info(true);
    let device = instance
        .create_device(
            pd,
            &vk::DeviceCreateInfo::default()
                .queue_create_infos(&queues)
                .enabled_extension_names(&extensions)
                .push_next(&mut feature),
            None,
        )
        .map_err(|e| format!("device: {e}"))?;
    let executables = ash::khr::pipeline_executable_properties::Device::new(&instance, &device);

    let scene = set_layout(&device, &bindings::SCENE)?;
    let restir = set_layout(&device, &bindings::RESTIR)?;
    let layout_of = |sets: &[vk::DescriptorSetLayout]| {
        device
            .create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default().set_layouts(sets),
                None,
            )
            .map_err(|e| format!("pipeline layout: {e}"))
    };
    let image_layout = layout_of(&[scene])?;
    let restir_layout = layout_of(&[scene, restir])?;
    let words = spirv_words();
    let module = device
        .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
        .map_err(|e| format!("shader module: {e}"))?;

    let wanted: Vec<String> = std::env::args().skip(1).collect();
    let mut seen = std::collections::HashSet::new();
    for kernel in Integrator::ALL.into_iter().flat_map(Integrator::kernels) {
        let layout = match kernel {
            runner::integrator::Kernel::Image { .. } => image_layout,
            runner::integrator::Kernel::Restir { .. } => restir_layout,
        };
        // Both workgroup sizes of AO (`runner::gpu::wide_ao`).
        for (name, _) in every_entry_point(kernel) {
            let asked = wanted.is_empty() || wanted.iter().any(|w| name.contains(w.as_str()));
            if !asked || !seen.insert(name) {
                continue;
            }
            let cname = std::ffi::CString::new(name).expect("entry point names have no NUL");
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(&cname);
            let info = vk::ComputePipelineCreateInfo::default()
                .flags(vk::PipelineCreateFlags::CAPTURE_STATISTICS_KHR)
                .stage(stage)
                .layout(layout);
            let pipeline = device
                .create_compute_pipelines(vk::PipelineCache::null(), &[info], None)
                .map_err(|(_, e)| format!("{name}: pipeline: {e}"))?[0];
            let pipeline_info = vk::PipelineInfoKHR::default().pipeline(pipeline);
            let list = executables
                .get_pipeline_executable_properties(&pipeline_info)
                .map_err(|e| format!("{name}: executables: {e}"))?;
            for index in 0..list.len() as u32 {
                let exe = vk::PipelineExecutableInfoKHR::default()
                    .pipeline(pipeline)
                    .executable_index(index);
                let stats = executables
                    .get_pipeline_executable_statistics(&exe)
                    .map_err(|e| format!("{name}: statistics: {e}"))?;
                let row: Vec<String> = stats
                    .iter()
                    .map(|s| format!("{}={}", text(&s.name), value(s)))
                    .collect();
                println!("{name}: {}", row.join(", "));
            }
            device.destroy_pipeline(pipeline, None);
        }
    }
    device.destroy_shader_module(module, None);
    device.destroy_pipeline_layout(image_layout, None);
    device.destroy_pipeline_layout(restir_layout, None);
    device.destroy_descriptor_set_layout(scene, None);
    device.destroy_descriptor_set_layout(restir, None);
    device.destroy_device(None);
    instance.destroy_instance(None);
    Ok(())
}
