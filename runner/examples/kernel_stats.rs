//! What the driver made of each kernel: the compile-time statistics a Vulkan driver reports
//! through VK_KHR_pipeline_executable_properties (on NVIDIA: registers, shared and local
//! memory, instructions; on lavapipe: LLVM's), one line per entry point. wgpu creates its
//! pipelines without asking for them, so this builds the same pipelines (the same SPIR-V,
//! the same descriptor set layouts from `kernels::bindings`) through ash directly.
//!
//! `cargo run --release --example kernel_stats [-- --ir DIR] [--cache FILE]`: with `--ir`,
//! each executable's internal representations (where the driver gives any; NVIDIA's 580
//! driver gives none) go to DIR; with `--cache`, the pipeline cache the pipelines were made
//! in goes to FILE (NVIDIA's holds each kernel's machine code as an ELF image that
//! `nvdisasm` reads).
use std::ffi::CStr;

use ash::vk;
use kernels::bindings::{self, Binding};
use runner::gpu::{entry_points, spirv_words};
use runner::integrator::Integrator;

const EXTENSION: &CStr = ash::khr::pipeline_executable_properties::NAME;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path_after = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .map(std::path::PathBuf::from)
    };
    let (ir_dir, cache_file) = (path_after("--ir"), path_after("--cache"));
    if let Err(e) = unsafe { run(ir_dir.as_deref(), cache_file.as_deref()) } {
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

unsafe fn run(
    ir_dir: Option<&std::path::Path>,
    cache_file: Option<&std::path::Path>,
) -> Result<(), String> {
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

    let cache = device
        .create_pipeline_cache(&vk::PipelineCacheCreateInfo::default(), None)
        .map_err(|e| format!("pipeline cache: {e}"))?;
    let mut flags = vk::PipelineCreateFlags::CAPTURE_STATISTICS_KHR;
    if ir_dir.is_some() {
        flags |= vk::PipelineCreateFlags::CAPTURE_INTERNAL_REPRESENTATIONS_KHR;
    }
    let mut seen = std::collections::HashSet::new();
    for kernel in Integrator::ALL.into_iter().flat_map(Integrator::kernels) {
        let layout = match kernel {
            runner::integrator::Kernel::Image { .. } => image_layout,
            runner::integrator::Kernel::Restir { .. } => restir_layout,
        };
        for name in entry_points(kernel) {
            if !seen.insert(name) {
                continue;
            }
            let cname = std::ffi::CString::new(name).expect("entry point names have no NUL");
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(&cname);
            let info = vk::ComputePipelineCreateInfo::default()
                .flags(flags)
                .stage(stage)
                .layout(layout);
            let pipeline = device
                .create_compute_pipelines(cache, &[info], None)
                .map_err(|(_, e)| format!("{name}: pipeline: {e}"))?[0];
            let pipeline_info = vk::PipelineInfoKHR::default().pipeline(pipeline);
            let list = executables
                .get_pipeline_executable_properties(&pipeline_info)
                .map_err(|e| format!("{name}: executables: {e}"))?;
            for (index, _) in list.iter().enumerate() {
                let exe = vk::PipelineExecutableInfoKHR::default()
                    .pipeline(pipeline)
                    .executable_index(index as u32);
                let stats = executables
                    .get_pipeline_executable_statistics(&exe)
                    .map_err(|e| format!("{name}: statistics: {e}"))?;
                let row: Vec<String> = stats
                    .iter()
                    .map(|s| format!("{}={}", text(&s.name), value(s)))
                    .collect();
                println!("{name}: {}", row.join(", "));
                if let Some(dir) = ir_dir {
                    dump_ir(&executables, &exe, dir, name, index)?;
                }
            }
            device.destroy_pipeline(pipeline, None);
        }
    }
    if let Some(file) = cache_file {
        let data = device
            .get_pipeline_cache_data(cache)
            .map_err(|e| format!("pipeline cache data: {e}"))?;
        std::fs::write(file, data).map_err(|e| format!("{}: {e}", file.display()))?;
    }
    device.destroy_pipeline_cache(cache, None);
    device.destroy_shader_module(module, None);
    device.destroy_pipeline_layout(image_layout, None);
    device.destroy_pipeline_layout(restir_layout, None);
    device.destroy_descriptor_set_layout(scene, None);
    device.destroy_descriptor_set_layout(restir, None);
    device.destroy_device(None);
    instance.destroy_instance(None);
    Ok(())
}

/// Write each internal representation of one executable to `dir` (two calls: sizes, then
/// the data).
unsafe fn dump_ir(
    executables: &ash::khr::pipeline_executable_properties::Device,
    exe: &vk::PipelineExecutableInfoKHR,
    dir: &std::path::Path,
    name: &str,
    index: usize,
) -> Result<(), String> {
    let mut reps = executables
        .get_pipeline_executable_internal_representations(exe)
        .map_err(|e| format!("{name}: internal representations: {e}"))?;
    let mut buffers: Vec<Vec<u8>> = reps.iter().map(|r| vec![0u8; r.data_size]).collect();
    for (r, b) in reps.iter_mut().zip(buffers.iter_mut()) {
        r.p_data = b.as_mut_ptr().cast();
    }
    let fp = executables.fp();
    let mut count = reps.len() as u32;
    (fp.get_pipeline_executable_internal_representations_khr)(
        executables.device(),
        exe,
        &mut count,
        reps.as_mut_ptr(),
    )
    .result()
    .map_err(|e| format!("{name}: internal representations: {e}"))?;
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    for (i, (r, b)) in reps.iter().zip(&buffers).enumerate() {
        let file = dir.join(format!("{}-{index}-{i}.txt", name.replace("::", "_")));
        std::fs::write(&file, &b[..r.data_size]).map_err(|e| e.to_string())?;
        println!(
            "  {} ({} bytes): {}",
            text(&r.name),
            r.data_size,
            file.display()
        );
    }
    Ok(())
}
