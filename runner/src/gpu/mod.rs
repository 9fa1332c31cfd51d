//! GPU backend: wgpu on Vulkan, running the rust-gpu SPIR-V module built by build.rs.
//! The module is passed through to the driver (naga does not read rust-gpu output), so the
//! bind group layouts are built from the same binding tables the entry points declare
//! (`kernels::bindings`). Split by concern:
//! - `device`: Vulkan instance, adapters, the device and its error reporting;
//! - `bindings`: bind group layouts and bind groups from the binding tables;
//! - `pipelines`: the SPIR-V module and one compute pipeline per entry point, on first use;
//! - `timestamps`: per-pass GPU times from timestamp queries;
//! - `backend`: the scene and image buffers and the `Backend` that runs integrators.
mod backend;
mod bindings;
mod device;
mod pipelines;
mod timestamps;

pub use backend::{check_buffer_size, check_fits, GpuBackend};
pub use bindings::{bind_group, layout};
pub use device::{adapters, adapters_of, instance, is_software, GpuContext};
pub use pipelines::{every_entry_point, spirv_words, wide_ao};
