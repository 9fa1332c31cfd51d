//! Bind group layouts and bind groups built from the kernels' binding tables
//! (`kernels::bindings`), so that the host and the shaders declare each binding once.
use kernels::bindings::Binding;

/// The layout of one descriptor set: every binding of ours is a storage buffer.
pub fn layout(
    device: &wgpu::Device,
    label: &str,
    table: &[Binding],
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayout {
    let entries: Vec<wgpu::BindGroupLayoutEntry> = table
        .iter()
        .map(|b| wgpu::BindGroupLayoutEntry {
            binding: b.binding,
            visibility,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage {
                    read_only: b.read_only,
                },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries,
    })
}

/// A bind group of `layout` with `buffers[i]` bound whole at `table[i]`. An array of the
/// table's length, so a missing or extra buffer does not compile.
pub fn bind_group<const N: usize>(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    table: &[Binding; N],
    buffers: [&wgpu::Buffer; N],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = table
        .iter()
        .zip(buffers)
        .map(|(b, buffer)| wgpu::BindGroupEntry {
            binding: b.binding,
            resource: buffer.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}
