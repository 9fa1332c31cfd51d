//! The Vulkan instance, the adapters that can run our kernels, and the device with its
//! error reporting.
use std::sync::{Arc, Mutex};

use super::pipelines::{wide_ao, Pipelines};
use crate::bail;
use crate::error::{Error, Result};
use crate::integrator::Kernel;

/// A Vulkan instance; the viewer passes its display so that it can present to windows.
pub fn instance(display: Option<Box<dyn wgpu::wgt::WgpuHasDisplayHandle>>) -> wgpu::Instance {
    let base = match display {
        Some(d) => wgpu::InstanceDescriptor::new_with_display_handle(d),
        None => wgpu::InstanceDescriptor::new_without_display_handle(),
    };
    wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        // No validation layers by default even though release builds keep debug assertions;
        // WGPU_VALIDATION=1 / WGPU_DEBUG=1 turn them on.
        flags: wgpu::InstanceFlags::empty().with_env(),
        ..base
    })
}

/// What an adapter must offer to run our kernels: SPIR-V passthrough, and subgroup
/// operations (the AO walk's votes, `kernels::subgroup`: wgpu offers ballots only with
/// the rest of Vulkan 1.1's subgroup operations, which every desktop GPU has).
pub const REQUIRED_FEATURES: wgpu::Features =
    wgpu::Features::PASSTHROUGH_SHADERS.union(wgpu::Features::SUBGROUP);

/// The Vulkan adapters that can run our kernels ([`REQUIRED_FEATURES`]), best first:
/// hardware GPUs, then software rasterisers such as lavapipe. Listed once per process:
/// `--backend auto` asks before the scene loads (`backend::expects_cpu`) and again when
/// it opens the backend.
pub fn adapters() -> Vec<wgpu::Adapter> {
    static ADAPTERS: std::sync::OnceLock<Vec<wgpu::Adapter>> = std::sync::OnceLock::new();
    ADAPTERS
        .get_or_init(|| adapters_of(&instance(None)))
        .clone()
}

pub fn adapters_of(instance: &wgpu::Instance) -> Vec<wgpu::Adapter> {
    let mut list: Vec<wgpu::Adapter> =
        pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN))
            .into_iter()
            .filter(|a| a.features().contains(REQUIRED_FEATURES))
            .collect();
    list.sort_by_key(|a| is_software(a) as u8);
    list
}

pub fn is_software(adapter: &wgpu::Adapter) -> bool {
    adapter.get_info().device_type == wgpu::DeviceType::Cpu
}

/// Device, queue and the kernels' pipelines.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    /// The adapter has timestamp queries (per-pass GPU times).
    pub timestamps: bool,
    pub pipelines: Pipelines,
    /// Validation errors and device loss, reported by wgpu's callbacks.
    errors: Arc<Mutex<Option<String>>>,
}

impl GpuContext {
    pub fn new(adapter: &wgpu::Adapter) -> Result<Self> {
        let info = adapter.get_info();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let mut features = REQUIRED_FEATURES;
        if timestamps {
            features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        // Take the adapter's own limits: large scenes need its full buffer sizes.
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("runner"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| Error(format!("cannot open GPU '{}': {e}", info.name)))?;

        let errors = Arc::new(Mutex::new(None));
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            sink.lock()
                .unwrap()
                .get_or_insert(format!("GPU error: {e}"));
        }));
        let sink = errors.clone();
        device.set_device_lost_callback(move |reason, msg| {
            sink.lock()
                .unwrap()
                .get_or_insert(format!("GPU device lost ({reason:?}): {msg}"));
        });
        let pipelines = Pipelines::new(&device, wide_ao(&info));
        let ctx = Self {
            device,
            queue,
            info,
            limits,
            timestamps,
            pipelines,
            errors,
        };
        ctx.check_errors()?;
        Ok(ctx)
    }

    /// Make the pipelines `kernel` runs, if not made yet.
    pub fn ensure_pipelines(&mut self, kernel: Kernel) -> Result<()> {
        self.pipelines.ensure(&self.device, kernel);
        self.check_errors()
    }

    /// The first error wgpu reported since the last check.
    pub fn check_errors(&self) -> Result<()> {
        match self.errors.lock().unwrap().take() {
            Some(e) => Err(Error(e)),
            None => Ok(()),
        }
    }

    /// Wait until the GPU has done all submitted work.
    pub fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error(format!("GPU wait failed: {e}")))?;
        self.check_errors()
    }

    /// Map `buffer`, copy its bytes out, unmap.
    pub fn read_buffer(&self, buffer: &wgpu::Buffer) -> Result<Vec<u8>> {
        let status = Arc::new(Mutex::new(None));
        let s = status.clone();
        buffer.map_async(wgpu::MapMode::Read, .., move |r| {
            *s.lock().unwrap() = Some(r);
        });
        self.wait()?;
        match status.lock().unwrap().take() {
            Some(Ok(())) => {}
            Some(Err(e)) => bail!("GPU readback failed: {e}"),
            None => bail!("GPU readback did not complete"),
        }
        let bytes = buffer
            .get_mapped_range(..)
            .map_err(|e| Error(format!("GPU readback failed: {e}")))?
            .to_vec();
        buffer.unmap();
        Ok(bytes)
    }

    pub fn describe(&self) -> String {
        format!(
            "gpu ({}, {:?}, {})",
            self.info.name, self.info.device_type, self.info.driver_info
        )
    }
}
