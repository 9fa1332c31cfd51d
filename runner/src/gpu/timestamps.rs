//! Per-pass GPU times from timestamp queries: a pair of timestamps around each compute
//! pass of a frame, resolved and read back once the frame is done.
use super::device::GpuContext;
use crate::error::Result;

/// Timestamp pairs available per frame (one pair per pass).
pub const MAX_TIMED_PASSES: u32 = 32;
/// Bytes of one resolved pair (two u64 ticks).
const PAIR_BYTES: u64 = 16;

pub struct Timestamps {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    read: wgpu::Buffer,
}

impl Timestamps {
    /// None when the adapter has no timestamp queries.
    pub fn new(ctx: &GpuContext) -> Option<Self> {
        if !ctx.timestamps {
            return None;
        }
        let device = &ctx.device;
        let size = PAIR_BYTES * MAX_TIMED_PASSES as u64;
        Some(Self {
            set: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * MAX_TIMED_PASSES,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            read: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps readback"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        })
    }

    /// The writes that time a compute pass as pair `timer`.
    pub fn writes(&self, timer: u32) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2 * timer),
            end_of_pass_write_index: Some(2 * timer + 1),
        }
    }

    /// Device times in ms of the first `n` timed passes.
    pub fn read_ms(&self, ctx: &GpuContext, n: u32) -> Result<Vec<f64>> {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        encoder.resolve_query_set(&self.set, 0..2 * n, &self.resolve, 0);
        encoder.copy_buffer_to_buffer(&self.resolve, 0, &self.read, 0, PAIR_BYTES * n as u64);
        ctx.queue.submit([encoder.finish()]);
        let bytes = ctx.read_buffer(&self.read)?;
        let t: Vec<u64> = bytemuck::pod_collect_to_vec(&bytes[..(PAIR_BYTES * n as u64) as usize]);
        let period = ctx.queue.get_timestamp_period() as f64;
        Ok(t.as_chunks::<2>()
            .0
            .iter()
            .map(|[begin, end]| end.saturating_sub(*begin) as f64 * period * 1e-6)
            .collect())
    }
}
