//! The window (winit), the swapchain (wgpu surface) and the present pass (rust-gpu vertex
//! and fragment shaders that tonemap the accumulation buffer). Each redraw runs one frame
//! of the chosen integrator on the GPU backend, accumulating while the camera stands still.
use std::borrow::Cow;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use kernels::present::PresentParams;
use kernels::types::FrameParams;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use super::controls::{action_for, FlyCamera, Held, Key, ViewState};
use super::present::{self, Presenter};
use super::ViewArgs;
use crate::backend::Backend;
use crate::backend::BackendChoice;
use crate::bail;
use crate::error::{Error, Result};
use crate::gpu::{spirv_words, GpuBackend, GpuContext};
use crate::integrator::Integrator;
use crate::options::frame_params;
use crate::output::{check_writable, write_image, Image};
use crate::render::pass_params;
use crate::restir::continue_history;
use crate::scene::Scene;

/// Refuse what `view` cannot do before loading the scene or opening a window.
pub fn check_args(args: &ViewArgs) -> Result<()> {
    if args.device.backend == BackendChoice::Cpu {
        bail!("`view` draws with a Vulkan device (a GPU, or lavapipe); --backend cpu is for `render` and `bench`");
    }
    if !(args.exposure.is_finite() && args.exposure > 0.0) {
        bail!(
            "--exposure must be a positive number, got {}",
            args.exposure
        );
    }
    if let Some(path) = &args.screenshot {
        if args.exit_after.is_none() {
            bail!("--screenshot saves the last frame of --exit-after N; give both (P saves while viewing)");
        }
        check_writable(path)?;
    }
    Ok(())
}

/// winit's OS errors read "os error at /home/.../winit-0.30/src/...rs:123: what happened":
/// a person needs only what happened.
fn without_source_location(message: &str) -> &str {
    match message.strip_prefix("os error at ") {
        Some(rest) => rest.split_once(": ").map_or(rest, |(_, what)| what),
        None => message,
    }
}

/// Open the window and run until it closes (or `--exit-after` frames).
pub fn run(args: &ViewArgs, mut scene: Scene) -> Result<()> {
    let has_display = ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|d| !d.is_empty()));
    if !has_display {
        bail!("`view` needs a display and neither DISPLAY nor WAYLAND_DISPLAY is set; `render` needs none");
    }
    let event_loop = EventLoop::new().map_err(|e| {
        Error(format!(
            "cannot open a window ({}); `view` needs a display it can connect to, `render` does not",
            without_source_location(&e.to_string())
        ))
    })?;
    let copy = present::use_copy(args.present)?;
    let mut params = frame_params(&args.scene, &args.kernel, &mut scene)?;
    // Keys switch to AO at any time: its walk order is chosen now, whatever runs first.
    if args.kernel.integrator != Integrator::Ao {
        params.ao_order = crate::ao_order::choose(args.kernel.ao_order, &scene, &params);
    }
    let pose = crate::camera::camera_pose(&args.scene, &scene)?;
    let camera = FlyCamera::new(pose.eye, pose.target, pose.up, pose.fov, scene.extent());
    let mut app = App {
        args: args.clone(),
        scene,
        params,
        camera,
        state: ViewState::new(
            args.kernel.integrator,
            params.restir_flags,
            params.spatial_passes,
        ),
        held: Held::default(),
        drag: None,
        gfx: None,
        copy,
        error: None,
        last_frame: Instant::now(),
        last_title: Instant::now(),
        restart: true,
        gpu_ms: 0.0,
        present_ms: 0.0,
        saved: 0,
        frame_times: Vec::new(),
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| Error(format!("window event loop failed: {e}")))?;
    if !app.frame_times.is_empty() {
        let median = |mut v: Vec<f64>| {
            v.sort_by(|a, b| a.total_cmp(b));
            v[v.len() / 2]
        };
        let gpu = median(app.frame_times.iter().map(|t| t.0).collect());
        let present = median(app.frame_times.iter().map(|t| t.1).collect());
        let wall = median(app.frame_times.iter().map(|t| t.2).collect());
        eprintln!(
            "viewer: {:?} {}x{}: {} frames, median {gpu:.3} ms GPU (integrator), {present:.3} ms presenting, {wall:.3} ms per frame in all",
            app.state.integrator,
            app.params.width,
            app.params.height,
            app.frame_times.len()
        );
    }
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// Everything that exists only while the window does.
struct Gfx {
    window: Arc<Window>,
    presenter: Presenter,
    backend: GpuBackend,
    present: wgpu::RenderPipeline,
    present_params: wgpu::Buffer,
    present_group: wgpu::BindGroup,
}

struct App {
    args: ViewArgs,
    scene: Scene,
    params: FrameParams,
    camera: FlyCamera,
    state: ViewState,
    held: Held,
    drag: Option<(f64, f64)>,
    gfx: Option<Gfx>,
    /// Copy frames to the window through the CPU instead of a swapchain (see `present`).
    copy: bool,
    error: Option<Error>,
    last_frame: Instant,
    last_title: Instant,
    restart: bool,
    gpu_ms: f64,
    saved: u32,
    /// Wall ms of the last frame's presentation work on the CPU (present pass; copying: the
    /// previous frame into the window, overlapped with the GPU's integration).
    present_ms: f64,
    /// (GPU ms of the integrator, wall ms presenting, wall ms of the whole frame) of every frame.
    frame_times: Vec<(f64, f64, f64)>,
}

fn key_of(code: KeyCode) -> Option<Key> {
    Some(match code {
        KeyCode::KeyW => Key::W,
        KeyCode::KeyA => Key::A,
        KeyCode::KeyS => Key::S,
        KeyCode::KeyD => Key::D,
        KeyCode::KeyQ => Key::Q,
        KeyCode::KeyE => Key::E,
        KeyCode::KeyR => Key::R,
        KeyCode::KeyP => Key::P,
        KeyCode::KeyT => Key::T,
        KeyCode::KeyB => Key::B,
        KeyCode::Equal | KeyCode::NumpadAdd => Key::PlusSpatial,
        KeyCode::Minus | KeyCode::NumpadSubtract => Key::MinusSpatial,
        KeyCode::BracketLeft => Key::TurnEnvLeft,
        KeyCode::BracketRight => Key::TurnEnvRight,
        KeyCode::Escape => Key::Escape,
        KeyCode::Digit1 => Key::Digit(1),
        KeyCode::Digit2 => Key::Digit(2),
        KeyCode::Digit3 => Key::Digit(3),
        KeyCode::Digit4 => Key::Digit(4),
        KeyCode::Digit5 => Key::Digit(5),
        KeyCode::Digit6 => Key::Digit(6),
        _ => return None,
    })
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: Error) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }

    fn create(&mut self, event_loop: &ActiveEventLoop) -> Result<Gfx> {
        let (w, h) = (self.params.width, self.params.height);
        let attrs = Window::default_attributes()
            .with_title("runner view")
            .with_inner_size(PhysicalSize::new(w, h))
            .with_resizable(false);
        let window = Arc::new(
            event_loop
                .create_window(attrs)
                .map_err(|e| Error(format!("cannot create a window: {e}")))?,
        );
        let (adapter, pending) = present::open(&window, event_loop, self.copy)?;
        let ctx = GpuContext::new(&adapter)?;
        let presenter = pending.finish(&adapter, &ctx.device, &window, w, h)?;

        let device = &ctx.device;
        // SAFETY: as for the compute kernels (see gpu/pipelines.rs): rust-gpu output validated at build
        // time, bindings mirrored below.
        let module = unsafe {
            device.create_shader_module_passthrough(wgpu::ShaderModuleDescriptorPassthrough {
                label: Some("present"),
                entry_points: Cow::Owned(vec![
                    wgpu::PassthroughShaderEntryPoint {
                        name: Cow::Borrowed("entry::present_vs"),
                        workgroup_size: (0, 0, 0),
                    },
                    wgpu::PassthroughShaderEntryPoint {
                        name: Cow::Borrowed("entry::present_fs"),
                        workgroup_size: (0, 0, 0),
                    },
                ]),
                spirv: Some(Cow::Owned(spirv_words())),
                ..Default::default()
            })
        };
        let layout = crate::gpu::layout(
            device,
            "present",
            &kernels::bindings::PRESENT,
            wgpu::ShaderStages::FRAGMENT,
        );
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("present"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let present = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("present"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("entry::present_vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("entry::present_fs"),
                compilation_options: Default::default(),
                targets: &[Some(presenter.format().into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        let present_params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("present params"),
            size: std::mem::size_of::<PresentParams>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let backend = GpuBackend::new(ctx, &self.scene, w, h)?;
        let present_group = crate::gpu::bind_group(
            &backend.context().device,
            "present",
            &layout,
            &kernels::bindings::PRESENT,
            [&present_params, backend.accumulation_buffer()],
        );
        eprintln!("viewer: {}, {}", backend.describe(), presenter.describe());
        Ok(Gfx {
            window,
            presenter,
            backend,
            present,
            present_params,
            present_group,
        })
    }

    /// One frame: integrate, present, update the title, and save when asked.
    fn frame(&mut self) -> Result<()> {
        let wall_ms = self.last_frame.elapsed().as_secs_f64() * 1e3;
        if self.state.frame > 0 {
            self.frame_times
                .push((self.gpu_ms, self.present_ms, wall_ms));
        }
        let dt = self.last_frame.elapsed().as_secs_f32();
        self.last_frame = Instant::now();
        if self.camera.fly(&self.held, dt) {
            self.restart = true;
        }
        let gfx = self.gfx.as_mut().expect("window exists");
        let (w, h) = (self.params.width, self.params.height);
        let mut base = self.params;
        let prev_camera = base.camera;
        base.camera = self.camera.camera(w as f32 / h as f32);
        base.restir_flags = self.state.restir_flags;
        base.spatial_passes = self.state.spatial_passes;
        base.env_rotation += self.state.env_turn.to_radians();
        self.params.camera = base.camera;
        let n = if self.restart {
            0
        } else {
            self.state.accumulated
        };
        // ReSTIR's frame index is the viewer's frame count, which never resets, so a moving
        // camera draws new numbers every frame (a still camera from the start renders
        // exactly `render`'s frames). The other integrators count samples of the
        // accumulation, as `render` does.
        if self.state.integrator == Integrator::Restir {
            base.frame = self.state.frame.wrapping_sub(n);
        }
        let mut p = pass_params(self.state.integrator, &base, n, 1);
        // ReSTIR's history survives restarts of the accumulation: it follows the camera
        // by reprojection from the previous frame.
        if self.state.restir_history {
            continue_history(&mut p, prev_camera);
        }
        if self.restart {
            gfx.backend.clear()?;
        }
        // While the GPU integrates, the CPU puts the previous frame in the window (copying).
        gfx.backend.submit_pass(self.state.integrator, &p)?;
        let present_start = Instant::now();
        gfx.presenter
            .show_previous(&gfx.backend.context().device, &gfx.window)?;
        let mut present_ms = present_start.elapsed().as_secs_f64() * 1e3;
        self.gpu_ms = gfx.backend.finish_pass()?;
        self.state.frame_done(self.restart);
        self.restart = false;

        let ctx = gfx.backend.context();
        let pp = PresentParams {
            width: w,
            height: h,
            exposure: self.args.exposure,
            tonemap: kernels::present::TONEMAP_CLAMP,
        };
        ctx.queue
            .write_buffer(&gfx.present_params, 0, bytemuck::bytes_of(&pp));
        let (pipeline, group) = (&gfx.present, &gfx.present_group);
        let present_start = Instant::now();
        gfx.presenter
            .present(&ctx.device, &ctx.queue, &gfx.window, |encoder, view| {
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("present"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    ..Default::default()
                });
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, group, &[]);
                pass.draw(0..3, 0..1);
            })?;
        present_ms += present_start.elapsed().as_secs_f64() * 1e3;
        self.present_ms = present_ms;

        if self.last_title.elapsed().as_secs_f32() > 0.25 {
            gfx.window.set_title(&self.state.title(w, h, self.gpu_ms));
            self.last_title = Instant::now();
        }
        let done = self.args.exit_after.is_some_and(|n| self.state.frame >= n);
        if self.state.save_requested || (done && self.args.screenshot.is_some()) {
            self.state.save_requested = false;
            let accum = gfx.backend.read_accumulation()?;
            // Every pixel holds as many samples as the fullest one, or the driver cut the
            // kernels short (`render::check_complete`).
            let most = accum.iter().map(|a| a[3]).fold(0.0, f32::max);
            crate::render::check_complete(&accum, most as u32)?;
            let image = Image::from_accumulation(w, h, &accum);
            let path = match &self.args.screenshot {
                Some(p) if done => p.clone(),
                _ => {
                    self.saved += 1;
                    PathBuf::from(format!("view_{:04}.png", self.saved))
                }
            };
            write_image(&path, &image)?;
            if path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("png"))
            {
                write_image(&path.with_extension("exr"), &image)?;
            }
            eprintln!(
                "saved {} ({} frames accumulated)",
                path.display(),
                self.state.accumulated
            );
        }
        if done {
            self.state.quit = true;
        }
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_none() {
            match self.create(event_loop) {
                Ok(g) => {
                    g.window.request_redraw();
                    self.gfx = Some(g);
                }
                Err(e) => self.fail(event_loop, e),
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::KeyboardInput { event, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else {
                    return;
                };
                let Some(key) = key_of(code) else { return };
                let down = event.state == ElementState::Pressed;
                if !self.held.set(key, down) && down && !event.repeat {
                    if let Some(action) = action_for(key) {
                        self.restart |= self.state.apply(action, &mut self.camera);
                    }
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => {
                if state == ElementState::Released {
                    self.drag = None;
                } else {
                    self.drag = Some((f64::NAN, f64::NAN));
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let Some((x, y)) = self.drag {
                    if x.is_finite()
                        && self
                            .camera
                            .look((position.x - x) as f32, (position.y - y) as f32)
                    {
                        self.restart = true;
                    }
                    self.drag = Some((position.x, position.y));
                }
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let notches = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => (p.y / 40.0) as f32,
                };
                self.camera.scroll(notches);
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame() {
                    return self.fail(event_loop, e);
                }
                if self.state.quit {
                    event_loop.exit();
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(g) = &self.gfx {
            g.window.request_redraw();
        }
    }
}
