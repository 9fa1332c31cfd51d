//! A scene and an image on the GPU: the buffers of the binding tables, and the `Backend`
//! that dispatches an integrator's kernels over them.
use std::borrow::Cow;
use std::time::Instant;

use kernels::bindings;
use kernels::reservoir::Reservoir;
use kernels::types::{
    FrameParams, GBufferTexel, Light, Material, TextureInfo, Triangle, TriangleShading,
};
use wgpu::util::DeviceExt;

use super::bindings::bind_group;
use super::device::GpuContext;
use super::pipelines::{IMAGE_WORKGROUP, RESTIR_WORKGROUP};
use super::timestamps::{Timestamps, MAX_TIMED_PASSES};
use crate::backend::Backend;
use crate::bail;
use crate::error::{Context, Result};
use crate::integrator::{Integrator, Kernel};
use crate::restir::RestirState;
use crate::scene::Scene;

/// Check a buffer against the device limits before allocating anything.
pub fn check_buffer_size(limits: &wgpu::Limits, what: &str, bytes: u64) -> Result<()> {
    let max = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    if bytes > max {
        bail!(
            "{what} needs {bytes} bytes, over this GPU's storage buffer limit of {max} bytes \
             (by {} bytes)",
            bytes - max
        );
    }
    Ok(())
}

/// Bytes per pixel of the accumulation buffer (rgb sum and sample count, f32 each).
const ACCUMULATION_TEXEL_BYTES: u64 = 16;

/// Check that a scene and an image of `width`×`height` fit this GPU's limits (every buffer
/// any integrator allocates, ReSTIR's included), before allocating anything.
pub fn check_fits(limits: &wgpu::Limits, scene: &Scene, width: u32, height: u32) -> Result<()> {
    // The most workgroups any kernel dispatches over the image: the smallest workgroup's.
    let (wx, wy) = (
        IMAGE_WORKGROUP.0.min(RESTIR_WORKGROUP.0),
        IMAGE_WORKGROUP.1.min(RESTIR_WORKGROUP.1),
    );
    let groups = (width.div_ceil(wx), height.div_ceil(wy));
    let max_groups = limits.max_compute_workgroups_per_dimension;
    if groups.0 > max_groups || groups.1 > max_groups {
        bail!(
            "image {width}x{height} needs {}x{} workgroups, over this GPU's limit of {max_groups} per dimension",
            groups.0,
            groups.1
        );
    }
    let pixels = width as u64 * height as u64;
    check_buffer_size(
        limits,
        "the triangle buffer",
        std::mem::size_of_val(&scene.triangles[..]) as u64,
    )?;
    check_buffer_size(
        limits,
        "the material buffer",
        std::mem::size_of_val(&scene.materials[..]) as u64,
    )?;
    check_buffer_size(
        limits,
        "the BVH node buffer",
        (scene.nodes.len() * std::mem::size_of::<crate::accel::GpuNode>()) as u64,
    )?;
    check_buffer_size(
        limits,
        "the light buffer",
        std::mem::size_of_val(&scene.lights[..]) as u64,
    )?;
    check_buffer_size(
        limits,
        "the shading attribute buffer",
        std::mem::size_of_val(&scene.attributes.shading[..]) as u64,
    )?;
    check_buffer_size(
        limits,
        "the texel buffer",
        std::mem::size_of_val(&scene.attributes.texels[..]) as u64,
    )?;
    check_buffer_size(
        limits,
        "the environment distribution",
        std::mem::size_of_val(&scene.attributes.env_distribution[..]) as u64,
    )?;
    check_buffer_size(
        limits,
        "the image buffer",
        pixels * ACCUMULATION_TEXEL_BYTES,
    )?;
    check_buffer_size(
        limits,
        "the ReSTIR G-buffer",
        pixels * std::mem::size_of::<GBufferTexel>() as u64,
    )?;
    check_buffer_size(
        limits,
        "the ReSTIR reservoir buffer",
        pixels * std::mem::size_of::<Reservoir>() as u64,
    )?;
    Ok(())
}

/// Storage buffers must not be empty: pad with one zeroed element.
fn bytes_or_zero(bytes: &[u8], elem: usize) -> Cow<'_, [u8]> {
    if bytes.is_empty() {
        Cow::Owned(vec![0; elem])
    } else {
        Cow::Borrowed(bytes)
    }
}

/// A storage buffer of `items` each converted by `convert` (one zeroed element when there
/// are none), written into the buffer a chunk at a time: no converted copy of the whole
/// array on the host.
fn upload_converted<S, T: bytemuck::Pod>(
    device: &wgpu::Device,
    label: &str,
    items: &[S],
    convert: impl Fn(&S) -> T,
) -> Result<wgpu::Buffer> {
    const CHUNK: usize = 4096;
    let size = std::mem::size_of::<T>();
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: (items.len().max(1) * size) as u64,
        usage: wgpu::BufferUsages::STORAGE,
        // wgpu zeroes a buffer mapped at creation.
        mapped_at_creation: true,
    });
    {
        let mut view = buffer
            .slice(..)
            .get_mapped_range_mut()
            .context(|| format!("mapping the {label} buffer to write it"))?;
        let mut converted = Vec::with_capacity(CHUNK);
        for (k, chunk) in items.chunks(CHUNK).enumerate() {
            converted.clear();
            converted.extend(chunk.iter().map(&convert));
            let start = k * CHUNK * size;
            view.slice(start..start + chunk.len() * size)
                .copy_from_slice(bytemuck::cast_slice(&converted));
        }
    }
    buffer.unmap();
    Ok(buffer)
}

/// A scene and an image on the GPU.
pub struct GpuBackend {
    ctx: GpuContext,
    width: u32,
    height: u32,
    params: wgpu::Buffer,
    accum: wgpu::Buffer,
    ray_counts: wgpu::Buffer,
    readback: wgpu::Buffer,
    scene_group: wgpu::BindGroup,
    timestamps: Option<Timestamps>,
    /// Every material is Lambertian: run the kernels specialised for that.
    all_diffuse: bool,
    restir: Option<RestirState<wgpu::Buffer, wgpu::Buffer>>,
    restir_pass_ms: Vec<(&'static str, f64)>,
    /// Submitted by `submit_pass`, not yet waited for by `finish_pass`.
    in_flight: Option<InFlight>,
}

/// A submitted pass (or ReSTIR frame): when it started and the names of its timed passes.
struct InFlight {
    start: Instant,
    passes: Vec<&'static str>,
}

impl GpuBackend {
    pub fn new(ctx: GpuContext, scene: &Scene, width: u32, height: u32) -> Result<Self> {
        check_fits(&ctx.limits, scene, width, height)?;
        let accum_size = width as u64 * height as u64 * ACCUMULATION_TEXEL_BYTES;
        let device = &ctx.device;
        let storage = wgpu::BufferUsages::STORAGE;
        // Scene buffers, each padded to one element when empty.
        fn upload<T: bytemuck::Pod>(
            device: &wgpu::Device,
            label: &str,
            items: &[T],
        ) -> wgpu::Buffer {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: &bytes_or_zero(bytemuck::cast_slice(items), std::mem::size_of::<T>()),
                usage: wgpu::BufferUsages::STORAGE,
            })
        }
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("params"),
            contents: bytemuck::bytes_of(&FrameParams::default()),
            usage: storage | wgpu::BufferUsages::COPY_DST,
        });
        let triangles = upload::<Triangle>(device, "triangles", &scene.triangles);
        let materials = upload::<Material>(device, "materials", &scene.materials);
        let nodes = upload_converted(device, "bvh nodes", &scene.nodes, crate::accel::gpu_node)?;
        let lights = upload::<Light>(device, "lights", &scene.lights);
        let shading = upload::<TriangleShading>(device, "shading", &scene.attributes.shading);
        let textures = upload::<TextureInfo>(device, "textures", &scene.attributes.textures);
        let texels = upload::<u32>(device, "texels", &scene.attributes.texels);
        let env_distribution = upload::<f32>(
            device,
            "environment distribution",
            &scene.attributes.env_distribution,
        );
        let buffer = |label, size, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let accum = buffer("accumulation", accum_size, storage | copy);
        let ray_counts = buffer("ray counts", accum_size / 4, storage | copy);
        let readback = buffer(
            "readback",
            accum_size,
            wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        );
        let scene_group = bind_group(
            device,
            "scene",
            &ctx.pipelines.scene_layout,
            &bindings::SCENE,
            [
                &params,
                &triangles,
                &materials,
                &nodes,
                &lights,
                &accum,
                &ray_counts,
                &shading,
                &textures,
                &texels,
                &env_distribution,
            ],
        );
        let timestamps = Timestamps::new(&ctx);
        let backend = Self {
            ctx,
            width,
            height,
            params,
            accum,
            ray_counts,
            readback,
            scene_group,
            timestamps,
            all_diffuse: scene.all_diffuse(),
            restir: None,
            restir_pass_ms: Vec::new(),
            in_flight: None,
        };
        backend.ctx.wait()?;
        Ok(backend)
    }

    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// The accumulation buffer (rgb = sum, a = count per pixel), for the viewer to show.
    pub fn accumulation_buffer(&self) -> &wgpu::Buffer {
        &self.accum
    }

    fn pixels(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    /// Record one image-sized dispatch of `entry`, an entry point of `kernel`, into
    /// `encoder`, timed as pair `timer`.
    fn dispatch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        kernel: Kernel,
        entry: &'static str,
        restir_group: Option<&wgpu::BindGroup>,
        timer: u32,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(entry),
            timestamp_writes: self.timestamps.as_ref().map(|t| t.writes(timer)),
        });
        pass.set_pipeline(self.ctx.pipelines.get(entry));
        pass.set_bind_group(0, &self.scene_group, &[]);
        if let Some(group) = restir_group {
            pass.set_bind_group(1, group, &[]);
        }
        let (gx, gy) = self
            .ctx
            .pipelines
            .workgroups(kernel, self.width, self.height);
        pass.dispatch_workgroups(gx, gy, 1);
    }

    /// Device times in ms of the first `n` timed passes (wall clock split evenly when the
    /// adapter has no timestamp queries).
    fn pass_times(&self, n: u32, wall_ms: f64) -> Result<Vec<f64>> {
        match &self.timestamps {
            Some(t) => t.read_ms(&self.ctx, n),
            None => Ok(vec![wall_ms / n as f64; n as usize]),
        }
    }

    /// One ReSTIR frame: every pass is its own dispatch (and submit, since each may need
    /// its own parameters), timed individually.
    fn submit_restir_frame(&mut self, params: &FrameParams, plain: bool) -> Result<()> {
        if self.restir.is_none() {
            // Their sizes were checked against the limits by `check_fits` in `new`.
            let g_size = self.pixels() * std::mem::size_of::<GBufferTexel>() as u64;
            let r_size = self.pixels() * std::mem::size_of::<Reservoir>() as u64;
            let device = &self.ctx.device;
            let make = |size| {
                move |label: &str| {
                    device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(label),
                        size,
                        usage: wgpu::BufferUsages::STORAGE,
                        mapped_at_creation: false,
                    })
                }
            };
            self.restir = Some(RestirState::new(make(g_size), make(r_size)));
        }
        let start = Instant::now();
        let st = self.restir.as_mut().expect("made above");
        let plan = st.frame(params);
        if plan.len() as u32 > MAX_TIMED_PASSES {
            bail!(
                "too many ReSTIR passes per frame ({}; at most {MAX_TIMED_PASSES})",
                plan.len()
            );
        }
        let st = self.restir.as_ref().expect("made above");
        for (k, (pass, sl, p)) in plan.iter().enumerate() {
            self.ctx
                .queue
                .write_buffer(&self.params, 0, bytemuck::bytes_of(p));
            let group = bind_group(
                &self.ctx.device,
                "restir",
                &self.ctx.pipelines.restir_layout,
                &bindings::RESTIR,
                [
                    &st.gbuffers[sl.g_cur],
                    &st.gbuffers[sl.g_prev],
                    &st.reservoirs[sl.res_in],
                    &st.reservoirs[sl.res_out],
                    &st.reservoirs[sl.res_prev],
                ],
            );
            let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
            self.dispatch(
                &mut encoder,
                Kernel::Restir { plain },
                pass.entry_point(plain),
                Some(&group),
                k as u32,
            );
            self.ctx.queue.submit([encoder.finish()]);
        }
        self.in_flight = Some(InFlight {
            start,
            passes: plan.iter().map(|(p, _, _)| p.name()).collect(),
        });
        Ok(())
    }

    /// Start a pass (a whole frame for ReSTIR) on the GPU without waiting for it, so that the
    /// caller can work meanwhile (the viewer copies the previous frame to the window);
    /// `finish_pass` waits and returns its GPU time. `Backend::pass` is the two in a row.
    pub fn submit_pass(&mut self, integrator: Integrator, params: &FrameParams) -> Result<()> {
        if self.in_flight.is_some() {
            bail!("internal: a pass was submitted before the previous one finished");
        }
        let kernel = integrator.kernel(crate::integrator::plain_scene(self.all_diffuse, params));
        self.ctx.ensure_pipelines(kernel)?;
        let entry_point = match kernel {
            Kernel::Image { entry_point, .. } => entry_point,
            Kernel::Restir { plain } => return self.submit_restir_frame(params, plain),
        };
        let start = Instant::now();
        self.ctx
            .queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        self.dispatch(&mut encoder, kernel, entry_point, None, 0);
        self.ctx.queue.submit([encoder.finish()]);
        self.in_flight = Some(InFlight {
            start,
            passes: Vec::new(),
        });
        Ok(())
    }

    /// Wait for the submitted pass; its GPU time in ms (the sum over a ReSTIR frame's passes,
    /// whose breakdown `pass_breakdown` then reports).
    pub fn finish_pass(&mut self) -> Result<f64> {
        let Some(InFlight { start, passes }) = self.in_flight.take() else {
            bail!("internal: no pass in flight");
        };
        self.ctx.wait()?;
        let wall_ms = start.elapsed().as_secs_f64() * 1e3;
        let times = self.pass_times(passes.len().max(1) as u32, wall_ms)?;
        if !passes.is_empty() {
            self.restir_pass_ms = passes.into_iter().zip(times.iter().copied()).collect();
        }
        Ok(times.iter().sum())
    }

    /// Copy a storage buffer into the readback buffer and return its bytes.
    fn download(&self, buffer: &wgpu::Buffer) -> Result<Vec<u8>> {
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &self.readback, 0, buffer.size());
        self.ctx.queue.submit([encoder.finish()]);
        let mut bytes = self.ctx.read_buffer(&self.readback)?;
        bytes.truncate(buffer.size() as usize);
        Ok(bytes)
    }
}

impl Backend for GpuBackend {
    fn describe(&self) -> String {
        self.ctx.describe()
    }

    fn pass(&mut self, integrator: Integrator, params: &FrameParams) -> Result<f64> {
        self.submit_pass(integrator, params)?;
        self.finish_pass()
    }

    fn pass_breakdown(&self) -> Vec<(&'static str, f64)> {
        self.restir_pass_ms.clone()
    }

    fn read_accumulation(&mut self) -> Result<Vec<[f32; 4]>> {
        let bytes = self.download(&self.accum)?;
        // Mapped bytes carry no alignment guarantee: copy into properly typed storage.
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    fn rays_traced(&mut self) -> Result<u64> {
        let bytes = self.download(&self.ray_counts)?;
        let counts: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes);
        Ok(counts.iter().map(|&c| c as u64).sum())
    }

    fn clear(&mut self) -> Result<()> {
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        encoder.clear_buffer(&self.accum, 0, None);
        encoder.clear_buffer(&self.ray_counts, 0, None);
        self.ctx.queue.submit([encoder.finish()]);
        self.ctx.wait()
    }
}
