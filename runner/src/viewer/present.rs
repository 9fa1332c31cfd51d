//! How frames reach the window. The GPU always draws the present pass (tonemapping the
//! accumulation buffer), either straight into the window's Vulkan swapchain or, where the
//! GPU cannot present to the display (a virtual X server such as Xvfb, remote X), into an
//! off-screen texture whose pixels are copied to the window through the CPU (softbuffer) —
//! what VirtualGL does for OpenGL.
//!
//! Whether the swapchain works is asked in a child process: NVIDIA's driver does not return
//! "unsupported" for an X server it cannot drive, it crashes (SIGSEGV in
//! vkGetPhysicalDeviceSurfaceSupportKHR on Xvfb), and a crash must not take the viewer down.
use std::num::NonZeroU32;
use std::process::{Command, ExitStatus, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::window::{Window, WindowId};

use super::PresentChoice;
use crate::bail;
use crate::error::{Error, Result};
use crate::gpu::{adapters, adapters_of, instance};

/// Set in the environment of the child process that only asks whether the swapchain works.
pub const PROBE_ENV: &str = "RUNNER_VIEW_PRESENT_PROBE";
/// The child's exit status when it ran but no adapter can present to the display.
const PROBE_UNSUPPORTED: i32 = 3;
const PROBE_TIMEOUT: Duration = Duration::from_secs(30);

/// Copy through the CPU? With `auto`, the child process decides; the reason for copying is
/// printed so that nobody mistakes the copy's cost for the renderer's.
pub fn use_copy(choice: PresentChoice) -> Result<bool> {
    Ok(match choice {
        PresentChoice::Swapchain => false,
        PresentChoice::Copy => true,
        PresentChoice::Auto => {
            match probe_in_child()? {
                Ok(()) => false,
                Err(why) => {
                    eprintln!("viewer: {why}; copying frames to the window through the CPU (--present copy)");
                    true
                }
            }
        }
    })
}

/// Run the probe (this binary, with [`PROBE_ENV`] set) and read its verdict.
fn probe_in_child() -> Result<std::result::Result<(), String>> {
    let exe = std::env::current_exe()
        .map_err(|e| Error(format!("cannot find the runner binary: {e}")))?;
    let mut child = Command::new(exe)
        .env(PROBE_ENV, "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| Error(format!("cannot start the display probe: {e}")))?;
    let start = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break Some(status),
            Ok(None) if start.elapsed() < PROBE_TIMEOUT => {
                std::thread::sleep(Duration::from_millis(10))
            }
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
        }
    };
    let mut stderr = String::new();
    if let Some(mut pipe) = child.stderr.take() {
        let _ = std::io::Read::read_to_string(&mut pipe, &mut stderr);
    }
    Ok(probe_verdict(status, &stderr))
}

/// What the probe's exit says about the swapchain (Err: why not).
pub fn probe_verdict(status: Option<ExitStatus>, stderr: &str) -> std::result::Result<(), String> {
    let Some(status) = status else {
        return Err(format!(
            "the Vulkan driver did not answer within {} s whether it can present to this display",
            PROBE_TIMEOUT.as_secs()
        ));
    };
    if status.success() {
        return Ok(());
    }
    if let Some(signal) = std::os::unix::process::ExitStatusExt::signal(&status) {
        return Err(format!(
            "the Vulkan driver crashed (signal {signal}) when asked to present to this display"
        ));
    }
    if status.code() == Some(PROBE_UNSUPPORTED) {
        return Err("no Vulkan adapter that runs the kernels can present to this display".into());
    }
    let last = stderr
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("no message");
    Err(format!("the display probe failed ({status}: {last})"))
}

/// The child's side: open a hidden window, make a Vulkan surface for it and ask every
/// adapter whether it can present there. Exit 0 if one can, [`PROBE_UNSUPPORTED`] if none.
pub fn probe_child() -> std::process::ExitCode {
    struct Probe(Option<Result<bool>>);
    impl ApplicationHandler for Probe {
        fn resumed(&mut self, event_loop: &ActiveEventLoop) {
            if self.0.is_none() {
                self.0 = Some(surface_supported(event_loop));
                event_loop.exit();
            }
        }
        fn window_event(&mut self, _: &ActiveEventLoop, _: WindowId, _: WindowEvent) {}
    }
    fn surface_supported(event_loop: &ActiveEventLoop) -> Result<bool> {
        let attrs = Window::default_attributes()
            .with_visible(false)
            .with_inner_size(winit::dpi::PhysicalSize::new(64, 64));
        let window = Arc::new(
            event_loop
                .create_window(attrs)
                .map_err(|e| Error(format!("cannot create a window: {e}")))?,
        );
        Ok(swapchain_surface(window, event_loop)?.1.is_some())
    }
    let mut probe = Probe(None);
    let outcome = EventLoop::new()
        .map_err(|e| Error(format!("cannot open the display: {e}")))
        .and_then(|l| {
            l.run_app(&mut probe)
                .map_err(|e| Error(format!("event loop: {e}")))
        })
        .and_then(|()| {
            probe
                .0
                .unwrap_or_else(|| Err(Error("the window never opened".into())))
        });
    match outcome {
        Ok(true) => std::process::ExitCode::SUCCESS,
        Ok(false) => std::process::ExitCode::from(PROBE_UNSUPPORTED as u8),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// A way to the window chosen before the GPU device exists (the swapchain needs the
/// adapter that can present; the copy takes the best adapter).
pub enum Pending {
    Swapchain(wgpu::Surface<'static>),
    Copy(softbuffer::Surface<Arc<Window>, Arc<Window>>),
}

/// Pick the adapter and the way to the window.
pub fn open(
    window: &Arc<Window>,
    event_loop: &ActiveEventLoop,
    copy: bool,
) -> Result<(wgpu::Adapter, Pending)> {
    if copy {
        let Some(adapter) = adapters().into_iter().next() else {
            bail!("no Vulkan adapter can run the kernels");
        };
        let context = softbuffer::Context::new(window.clone())
            .map_err(|e| Error(format!("cannot copy to the window: {e}")))?;
        let surface = softbuffer::Surface::new(&context, window.clone())
            .map_err(|e| Error(format!("cannot copy to the window: {e}")))?;
        return Ok((adapter, Pending::Copy(surface)));
    }
    let (surface, adapter) = swapchain_surface(window.clone(), event_loop)?;
    let Some(adapter) = adapter else {
        bail!("no Vulkan adapter can both run the kernels and present to this window (try --present copy)");
    };
    Ok((adapter, Pending::Swapchain(surface)))
}

/// A Vulkan surface for the window, and the best adapter that runs the kernels and can
/// present to it, if any (the question that crashes some drivers: see the module docs).
fn swapchain_surface(
    window: Arc<Window>,
    event_loop: &ActiveEventLoop,
) -> Result<(wgpu::Surface<'static>, Option<wgpu::Adapter>)> {
    log::debug!("creating the Vulkan instance and surface");
    let instance = instance(Some(Box::new(event_loop.owned_display_handle())));
    let surface = instance
        .create_surface(window)
        .map_err(|e| Error(format!("cannot present to the window: {e}")))?;
    log::debug!("surface created; asking each adapter whether it can present to it");
    let adapter = adapters_of(&instance)
        .into_iter()
        .find(|a| a.is_surface_supported(&surface));
    Ok((surface, adapter))
}

/// The frame's way to the window, once the device exists.
pub enum Presenter {
    Swapchain {
        surface: wgpu::Surface<'static>,
        config: wgpu::SurfaceConfiguration,
    },
    Copy(CopyTarget),
}

/// Off-screen colour target and its CPU read-backs, for [`Presenter::Copy`]. Two
/// read-backs: frame N is copied into one while frame N−1, in the other, goes to the window
/// as the GPU works on frame N+1 (see [`Presenter::show_previous`]).
pub struct CopyTarget {
    window: softbuffer::Surface<Arc<Window>, Arc<Window>>,
    texture: wgpu::Texture,
    readbacks: [wgpu::Buffer; 2],
    /// The read-back the next frame is copied into.
    next: usize,
    /// A read-back holding a frame not shown yet, with the submission that fills it.
    unshown: Option<(usize, wgpu::SubmissionIndex)>,
    /// Bytes per row in the read-backs (a multiple of 256, as copies require).
    row_bytes: u32,
}

impl Pending {
    pub fn finish(
        self,
        adapter: &wgpu::Adapter,
        device: &wgpu::Device,
        window: &Window,
        width: u32,
        height: u32,
    ) -> Result<Presenter> {
        match self {
            Pending::Swapchain(surface) => {
                let size = window.inner_size();
                let mut config = surface
                    .get_default_config(adapter, size.width.max(1), size.height.max(1))
                    .ok_or_else(|| {
                        Error("the window surface has no usable configuration".into())
                    })?;
                // An sRGB swapchain encodes the linear colour the present shader writes.
                if let Some(f) = surface
                    .get_capabilities(adapter)
                    .formats
                    .iter()
                    .find(|f| f.is_srgb())
                {
                    config.format = *f;
                }
                config.present_mode = wgpu::PresentMode::AutoNoVsync;
                log::debug!("configuring the swapchain: {config:?}");
                surface.configure(device, &config);
                Ok(Presenter::Swapchain { surface, config })
            }
            Pending::Copy(window) => {
                let texture = device.create_texture(&wgpu::TextureDescriptor {
                    label: Some("copy target"),
                    size: wgpu::Extent3d {
                        width,
                        height,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: COPY_FORMAT,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                    view_formats: &[],
                });
                let row_bytes = (4 * width).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
                let readback = || {
                    device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("copy read-back"),
                        size: row_bytes as u64 * height as u64,
                        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    })
                };
                Ok(Presenter::Copy(CopyTarget {
                    window,
                    texture,
                    readbacks: [readback(), readback()],
                    next: 0,
                    unshown: None,
                    row_bytes,
                }))
            }
        }
    }
}

/// sRGB, so that the hardware encodes the linear colour the present shader writes, as the
/// swapchain does; the bytes read back only need reordering for the window.
const COPY_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

impl Presenter {
    pub fn format(&self) -> wgpu::TextureFormat {
        match self {
            Presenter::Swapchain { config, .. } => config.format,
            Presenter::Copy(_) => COPY_FORMAT,
        }
    }

    pub fn describe(&self) -> &'static str {
        match self {
            Presenter::Swapchain { .. } => "Vulkan swapchain",
            Presenter::Copy(_) => "copied through the CPU",
        }
    }

    /// Copying: put the previous frame's pixels in the window (a no-op for the swapchain).
    /// The viewer calls this while the GPU renders the next frame, so the copy through the
    /// CPU costs frame time only where it takes longer than the GPU's work.
    pub fn show_previous(&mut self, device: &wgpu::Device, window: &Window) -> Result<()> {
        match self {
            Presenter::Swapchain { .. } => Ok(()),
            Presenter::Copy(target) => target.show_previous(device, window),
        }
    }

    /// Let `draw` record the present pass into the frame's colour target, then show it
    /// (swapchain) or start copying it back (copy; shown by the next `show_previous`).
    pub fn present(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        window: &Window,
        draw: impl FnOnce(&mut wgpu::CommandEncoder, &wgpu::TextureView),
    ) -> Result<()> {
        let mut encoder = device.create_command_encoder(&Default::default());
        match self {
            Presenter::Swapchain { surface, config } => {
                log::trace!("acquiring the swapchain image");
                let frame = match surface.get_current_texture() {
                    wgpu::CurrentSurfaceTexture::Success(t)
                    | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
                    wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                        surface.configure(device, config);
                        return Ok(());
                    }
                    _ => return Ok(()), // timeout or occluded: skip this frame
                };
                draw(
                    &mut encoder,
                    &frame.texture.create_view(&Default::default()),
                );
                queue.submit([encoder.finish()]);
                window.pre_present_notify();
                log::trace!("presenting");
                queue.present(frame);
                Ok(())
            }
            Presenter::Copy(target) => target.present(queue, encoder, draw),
        }
    }
}

impl CopyTarget {
    fn present(
        &mut self,
        queue: &wgpu::Queue,
        mut encoder: wgpu::CommandEncoder,
        draw: impl FnOnce(&mut wgpu::CommandEncoder, &wgpu::TextureView),
    ) -> Result<()> {
        let readback = &self.readbacks[self.next];
        draw(&mut encoder, &self.texture.create_view(&Default::default()));
        encoder.copy_texture_to_buffer(
            self.texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.row_bytes),
                    rows_per_image: None,
                },
            },
            self.texture.size(),
        );
        let submission = queue.submit([encoder.finish()]);
        readback.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        self.unshown = Some((self.next, submission));
        self.next ^= 1;
        Ok(())
    }

    fn show_previous(&mut self, device: &wgpu::Device, window: &Window) -> Result<()> {
        let Some((index, submission)) = self.unshown.take() else {
            return Ok(());
        };
        // Wait for that copy only, not for the work submitted after it.
        device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(submission),
                timeout: None,
            })
            .map_err(|e| Error(format!("GPU error while copying the frame: {e}")))?;
        let result = self.put(index, window);
        self.readbacks[index].unmap();
        result
    }

    /// The pixels of mapped read-back `index` into the window.
    fn put(&mut self, index: usize, window: &Window) -> Result<()> {
        let (w, h) = (
            self.texture.width() as usize,
            self.texture.height() as usize,
        );
        let size = window.inner_size();
        let (Some(ww), Some(wh)) = (NonZeroU32::new(size.width), NonZeroU32::new(size.height))
        else {
            return Ok(()); // minimised
        };
        let failed =
            |e: softbuffer::SoftBufferError| Error(format!("cannot copy to the window: {e}"));
        self.window.resize(ww, wh).map_err(failed)?;
        let mut buffer = self.window.buffer_mut().map_err(failed)?;
        {
            let bytes = self.readbacks[index]
                .slice(..)
                .get_mapped_range()
                .map_err(|e| Error(format!("cannot read the frame back: {e}")))?;
            let (ww, wh) = (ww.get() as usize, wh.get() as usize);
            for (y, out) in buffer.chunks_exact_mut(ww).take(wh).enumerate() {
                let shown = if y < h { w.min(ww) } else { 0 };
                let row = &bytes[y.min(h - 1) * self.row_bytes as usize..][..4 * shown];
                // softbuffer's pixels are 0x00RRGGBB.
                for (px, rgba) in out[..shown].iter_mut().zip(row.as_chunks::<4>().0) {
                    *px = u32::from_be_bytes([0, rgba[0], rgba[1], rgba[2]]);
                }
                out[shown..].fill(0);
            }
        }
        window.pre_present_notify();
        buffer.present().map_err(failed)
    }
}

#[cfg(test)]
mod tests {
    use std::os::unix::process::ExitStatusExt;

    use super::*;

    #[test]
    fn probe_verdicts() {
        // A raw wait status: exit code in bits 8..16, terminating signal in the low bits.
        let exited = |code: i32| ExitStatus::from_raw(code << 8);
        assert_eq!(probe_verdict(Some(exited(0)), ""), Ok(()));
        let crashed = probe_verdict(Some(ExitStatus::from_raw(11)), "").unwrap_err();
        assert!(crashed.contains("crashed (signal 11)"), "{crashed}");
        let unsupported = probe_verdict(Some(exited(PROBE_UNSUPPORTED)), "").unwrap_err();
        assert!(unsupported.contains("no Vulkan adapter"), "{unsupported}");
        let failed = probe_verdict(
            Some(exited(1)),
            "warning: x\nerror: cannot open the display: gone\n\n",
        )
        .unwrap_err();
        assert!(
            failed.ends_with("error: cannot open the display: gone)"),
            "{failed}"
        );
        assert!(probe_verdict(None, "")
            .unwrap_err()
            .contains("did not answer"));
    }
}
