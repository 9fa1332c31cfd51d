//! GPU backend: wgpu on Vulkan, running the rust-gpu SPIR-V module built by build.rs.
//! The module is passed through to the driver (naga does not read rust-gpu output), so the
//! bind group layout here must mirror the bindings declared in shader-crate/src/entry.rs.
use std::borrow::Cow;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use kernels::reservoir::Reservoir;
use kernels::types::{FrameParams, GBufferTexel};
use wgpu::util::DeviceExt;

use crate::backend::Backend;
use crate::bail;
use crate::cli::Integrator;
use crate::error::{Error, Result};
use crate::restir::{RestirPass, RestirSchedule};
use crate::scene::Scene;

/// The kernels' SPIR-V, compiled from shader-crate by runner/build.rs.
const SPIRV: &[u8] = include_bytes!(env!("kernels.spv"));

/// Workgroup size of every image kernel (`#[spirv(compute(threads(8, 8)))]`).
const WORKGROUP: (u32, u32) = (8, 8);

impl Integrator {
    /// Name of the SPIR-V entry point that runs this integrator (rust-gpu names entry
    /// points by their module path).
    pub fn entry_point(self) -> &'static str {
        match self {
            Integrator::Ao => "entry::ao_main",
            Integrator::Pt => "entry::pt_main",
            Integrator::Nee => "entry::nee_main",
            Integrator::Mis => "entry::mis_main",
            Integrator::Ris => "entry::ris_main",
            Integrator::Restir => RestirPass::Shade.entry_point(),
        }
    }
    /// Integrators with a single image kernel (ReSTIR runs a schedule of passes).
    pub const IMAGE_KERNELS: [Integrator; 5] = [
        Integrator::Ao,
        Integrator::Pt,
        Integrator::Nee,
        Integrator::Mis,
        Integrator::Ris,
    ];
}

/// A storage-buffer binding of a bind group layout (every binding of ours is one).
pub fn storage_entry(
    binding: u32,
    read_only: bool,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
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

/// The Vulkan adapters that can run our kernels (SPIR-V passthrough), best first:
/// hardware GPUs, then software rasterisers such as lavapipe.
pub fn adapters() -> Vec<wgpu::Adapter> {
    adapters_of(&instance(None))
}

pub fn adapters_of(instance: &wgpu::Instance) -> Vec<wgpu::Adapter> {
    let mut list: Vec<wgpu::Adapter> =
        pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN))
            .into_iter()
            .filter(|a| a.features().contains(wgpu::Features::PASSTHROUGH_SHADERS))
            .collect();
    list.sort_by_key(|a| is_software(a) as u8);
    list
}

pub fn is_software(adapter: &wgpu::Adapter) -> bool {
    adapter.get_info().device_type == wgpu::DeviceType::Cpu
}

/// Timestamp pairs available per frame (one pair per pass).
const MAX_TIMED_PASSES: u32 = 32;

/// Device, queue and one compute pipeline per kernel.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    timestamps: bool,
    layout: wgpu::BindGroupLayout,
    restir_layout: wgpu::BindGroupLayout,
    module: wgpu::ShaderModule,
    image_pipeline_layout: wgpu::PipelineLayout,
    restir_pipeline_layout: wgpu::PipelineLayout,
    /// Compute pipelines by entry point, made on first use: the driver compiles each one,
    /// and a render that runs one integrator should not wait for all ten (on a cold NVIDIA
    /// shader cache that was seconds).
    pipelines: HashMap<&'static str, wgpu::ComputePipeline>,
    /// Validation errors and device loss, reported by wgpu's callbacks.
    errors: Arc<Mutex<Option<String>>>,
}

impl GpuContext {
    pub fn new(adapter: &wgpu::Adapter) -> Result<Self> {
        let info = adapter.get_info();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let mut features = wgpu::Features::PASSTHROUGH_SHADERS;
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

        let words = spirv_words();
        let image_entries = Integrator::IMAGE_KERNELS.iter().map(|i| i.entry_point());
        let restir_entries = RestirPass::ENTRY_POINTS.iter().map(|p| p.entry_point());
        let names: Vec<&'static str> = image_entries.chain(restir_entries).collect();
        let entry_points: Vec<wgpu::PassthroughShaderEntryPoint> = names
            .iter()
            .map(|name| wgpu::PassthroughShaderEntryPoint {
                name: Cow::Borrowed(*name),
                workgroup_size: (WORKGROUP.0, WORKGROUP.1, 1),
            })
            .collect();
        // SAFETY: the module is rust-gpu output validated by spirv-val at build time, and the
        // bind group layout below matches the bindings it declares.
        let module = unsafe {
            device.create_shader_module_passthrough(wgpu::ShaderModuleDescriptorPassthrough {
                label: Some("kernels"),
                entry_points: Cow::Owned(entry_points),
                spirv: Some(Cow::Owned(words)),
                ..Default::default()
            })
        };

        let storage =
            |binding, read_only| storage_entry(binding, read_only, wgpu::ShaderStages::COMPUTE);
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scene"),
            entries: &[
                storage(0, true),  // FrameParams
                storage(1, true),  // triangles
                storage(2, true),  // materials
                storage(3, true),  // BVH nodes
                storage(4, true),  // lights
                storage(5, false), // accumulation
                storage(6, false), // rays traced per pixel
            ],
        });
        let restir_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("restir"),
            entries: &[
                storage(0, false), // current G-buffer
                storage(1, true),  // previous G-buffer
                storage(2, true),  // input reservoirs
                storage(3, false), // output reservoirs
                storage(4, true),  // previous frame's reservoirs
            ],
        });
        let image_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("image"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let restir_pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("restir"),
                bind_group_layouts: &[Some(&layout), Some(&restir_layout)],
                immediate_size: 0,
            });
        let ctx = Self {
            device,
            queue,
            info,
            limits,
            timestamps,
            layout,
            restir_layout,
            module,
            image_pipeline_layout: image_layout,
            restir_pipeline_layout,
            pipelines: HashMap::new(),
            errors,
        };
        ctx.check_errors()?;
        Ok(ctx)
    }

    /// Make the pipelines `integrator` runs, if not made yet.
    fn ensure_pipelines(&mut self, integrator: Integrator) -> Result<()> {
        // An integrator's pipelines are made together: one present means all are.
        if self.pipelines.contains_key(integrator.entry_point()) {
            return Ok(());
        }
        let entries: Vec<&'static str> = if integrator == Integrator::Restir {
            RestirPass::ENTRY_POINTS
                .iter()
                .map(|p| p.entry_point())
                .collect()
        } else {
            vec![integrator.entry_point()]
        };
        for name in entries {
            let layout = if integrator == Integrator::Restir {
                &self.restir_pipeline_layout
            } else {
                &self.image_pipeline_layout
            };
            let pipeline = self
                .device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(name),
                    layout: Some(layout),
                    module: &self.module,
                    entry_point: Some(name),
                    compilation_options: Default::default(),
                    cache: None,
                });
            self.pipelines.insert(name, pipeline);
        }
        self.check_errors()
    }

    fn check_errors(&self) -> Result<()> {
        match self.errors.lock().unwrap().take() {
            Some(e) => Err(Error(e)),
            None => Ok(()),
        }
    }

    fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error(format!("GPU wait failed: {e}")))?;
        self.check_errors()
    }

    pub fn describe(&self) -> String {
        format!(
            "gpu ({}, {:?}, {})",
            self.info.name, self.info.device_type, self.info.driver_info
        )
    }
}

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
    let groups = (width.div_ceil(WORKGROUP.0), height.div_ceil(WORKGROUP.1));
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
        std::mem::size_of_val(&scene.nodes[..]) as u64,
    )?;
    check_buffer_size(
        limits,
        "the light buffer",
        std::mem::size_of_val(&scene.lights[..]) as u64,
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

/// A scene and an image on the GPU.
pub struct GpuBackend {
    ctx: GpuContext,
    width: u32,
    height: u32,
    params: wgpu::Buffer,
    accum: wgpu::Buffer,
    ray_counts: wgpu::Buffer,
    readback: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    queries: Option<(wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer)>,
    restir: Option<RestirBuffers>,
    restir_pass_ms: Vec<(&'static str, f64)>,
    /// Submitted by `submit_pass`, not yet waited for by `finish_pass`.
    in_flight: Option<InFlight>,
}

/// A submitted pass (or ReSTIR frame): when it started and the names of its timed passes.
struct InFlight {
    start: Instant,
    passes: Vec<&'static str>,
}

/// ReSTIR's G-buffers and reservoirs, allocated on the first ReSTIR frame.
struct RestirBuffers {
    gbuffers: [wgpu::Buffer; 2],
    reservoirs: [wgpu::Buffer; 3],
    schedule: RestirSchedule,
}

impl GpuBackend {
    pub fn new(ctx: GpuContext, scene: &Scene, width: u32, height: u32) -> Result<Self> {
        check_fits(&ctx.limits, scene, width, height)?;
        let tri_bytes: &[u8] = bytemuck::cast_slice(&scene.triangles);
        let mat_bytes: &[u8] = bytemuck::cast_slice(&scene.materials);
        let node_bytes: &[u8] = bytemuck::cast_slice(&scene.nodes);
        let light_bytes: &[u8] = bytemuck::cast_slice(&scene.lights);
        let accum_size = width as u64 * height as u64 * ACCUMULATION_TEXEL_BYTES;

        let device = &ctx.device;
        let init = |label: &str, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let storage = wgpu::BufferUsages::STORAGE;
        let params = init(
            "params",
            bytemuck::bytes_of(&FrameParams::default()),
            storage | wgpu::BufferUsages::COPY_DST,
        );
        let triangles = init("triangles", &bytes_or_zero(tri_bytes, 48), storage);
        let materials = init("materials", &bytes_or_zero(mat_bytes, 32), storage);
        let nodes = init("bvh nodes", &bytes_or_zero(node_bytes, 80), storage);
        let lights = init("lights", &bytes_or_zero(light_bytes, 16), storage);
        let accum = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("accumulation"),
            size: accum_size,
            usage: storage | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let ray_counts = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ray counts"),
            size: accum_size / 4,
            usage: storage | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: accum_size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("scene"),
            layout: &ctx.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: triangles.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: materials.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: nodes.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: lights.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: accum.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: ray_counts.as_entire_binding(),
                },
            ],
        });
        let queries = ctx.timestamps.then(|| {
            let set = device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * MAX_TIMED_PASSES,
            });
            let resolve = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size: 16 * MAX_TIMED_PASSES as u64,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps readback"),
                size: 16 * MAX_TIMED_PASSES as u64,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            (set, resolve, read)
        });
        let backend = Self {
            ctx,
            width,
            height,
            params,
            accum,
            ray_counts,
            readback,
            bind_group,
            queries,
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

    /// Record one image-sized dispatch of `entry` into `encoder`, timed as pair `timer`.
    fn dispatch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        entry: &str,
        extra: Option<&wgpu::BindGroup>,
        timer: u32,
    ) {
        let timestamp_writes =
            self.queries
                .as_ref()
                .map(|(set, _, _)| wgpu::ComputePassTimestampWrites {
                    query_set: set,
                    beginning_of_pass_write_index: Some(2 * timer),
                    end_of_pass_write_index: Some(2 * timer + 1),
                });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(entry),
            timestamp_writes,
        });
        pass.set_pipeline(&self.ctx.pipelines[entry]);
        pass.set_bind_group(0, &self.bind_group, &[]);
        if let Some(group) = extra {
            pass.set_bind_group(1, group, &[]);
        }
        pass.dispatch_workgroups(
            self.width.div_ceil(WORKGROUP.0),
            self.height.div_ceil(WORKGROUP.1),
            1,
        );
    }

    /// Device times in ms of the first `n` timed passes (wall clock split evenly when the
    /// adapter has no timestamp queries).
    fn pass_times(&self, n: u32, wall_ms: f64) -> Result<Vec<f64>> {
        let Some((set, resolve, read)) = &self.queries else {
            return Ok(vec![wall_ms / n as f64; n as usize]);
        };
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        encoder.resolve_query_set(set, 0..2 * n, resolve, 0);
        encoder.copy_buffer_to_buffer(resolve, 0, read, 0, 16 * n as u64);
        self.ctx.queue.submit([encoder.finish()]);
        let bytes = self.read_buffer(read)?;
        let t: Vec<u64> = bytemuck::pod_collect_to_vec(&bytes[..16 * n as usize]);
        let period = self.ctx.queue.get_timestamp_period() as f64;
        Ok(t.as_chunks::<2>()
            .0
            .iter()
            .map(|[begin, end]| end.saturating_sub(*begin) as f64 * period * 1e-6)
            .collect())
    }

    fn restir_buffers(&mut self) -> Result<()> {
        if self.restir.is_some() {
            return Ok(());
        }
        // Their sizes were checked against the limits by `check_fits` in `new`.
        let g_size = self.pixels() * std::mem::size_of::<GBufferTexel>() as u64;
        let r_size = self.pixels() * std::mem::size_of::<Reservoir>() as u64;
        let make = |label: &str, size| {
            self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        self.restir = Some(RestirBuffers {
            gbuffers: [make("gbuffer a", g_size), make("gbuffer b", g_size)],
            reservoirs: [
                make("reservoirs a", r_size),
                make("reservoirs b", r_size),
                make("reservoirs c", r_size),
            ],
            schedule: RestirSchedule::default(),
        });
        Ok(())
    }

    /// One ReSTIR frame: every pass is its own dispatch (and submit, since each may need
    /// its own parameters), timed individually.
    fn submit_restir_frame(&mut self, params: &FrameParams) -> Result<()> {
        self.restir_buffers()?;
        let start = Instant::now();
        let st = self.restir.as_mut().expect("allocated above");
        let plan = st.schedule.frame(params.spatial_passes);
        if plan.len() as u32 > MAX_TIMED_PASSES {
            bail!(
                "too many ReSTIR passes per frame ({}; at most {MAX_TIMED_PASSES})",
                plan.len()
            );
        }
        let st = self.restir.as_ref().expect("allocated above");
        for (k, (pass, sl)) in plan.iter().enumerate() {
            let mut p = *params;
            if let RestirPass::Spatial(i) = pass {
                p.spatial_pass = *i;
            }
            self.ctx
                .queue
                .write_buffer(&self.params, 0, bytemuck::bytes_of(&p));
            let group = self
                .ctx
                .device
                .create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("restir"),
                    layout: &self.ctx.restir_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: st.gbuffers[sl.g_cur].as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: st.gbuffers[sl.g_prev].as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: st.reservoirs[sl.res_in].as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: st.reservoirs[sl.res_out].as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: st.reservoirs[sl.res_prev].as_entire_binding(),
                        },
                    ],
                });
            let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
            self.dispatch(&mut encoder, pass.entry_point(), Some(&group), k as u32);
            self.ctx.queue.submit([encoder.finish()]);
        }
        self.in_flight = Some(InFlight {
            start,
            passes: plan.iter().map(|(p, _)| p.name()).collect(),
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
        self.ctx.ensure_pipelines(integrator)?;
        if integrator == Integrator::Restir {
            return self.submit_restir_frame(params);
        }
        let start = Instant::now();
        self.ctx
            .queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        self.dispatch(&mut encoder, integrator.entry_point(), None, 0);
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
        let mut bytes = self.read_buffer(&self.readback)?;
        bytes.truncate(buffer.size() as usize);
        Ok(bytes)
    }

    /// Map `buffer`, copy its bytes out, unmap.
    fn read_buffer(&self, buffer: &wgpu::Buffer) -> Result<Vec<u8>> {
        let status = Arc::new(Mutex::new(None));
        let s = status.clone();
        buffer.map_async(wgpu::MapMode::Read, .., move |r| {
            *s.lock().unwrap() = Some(r);
        });
        self.ctx.wait()?;
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
