//! `runner view`: the GPU output in a window, redrawn every frame, with the camera in the
//! user's hands. `controls` holds the per-frame logic (tested without a window); `app` the
//! window and the present pass; `present` how frames reach the window.
pub mod app;
pub mod controls;
pub mod present;

use std::path::PathBuf;

use clap::{Args, ValueEnum};

use crate::backend::DeviceOptions;
use crate::options::{KernelOptions, SceneOptions};

#[derive(Args, Debug, Clone)]
pub struct ViewArgs {
    #[command(flatten)]
    pub scene: SceneOptions,
    #[command(flatten)]
    pub kernel: KernelOptions,
    #[command(flatten)]
    pub device: DeviceOptions,
    /// Multiply the displayed radiance by this
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f32,
    /// Close after this many frames (for scripts and tests)
    #[arg(long, value_name = "N")]
    pub exit_after: Option<u32>,
    /// With --exit-after: save the final image here (PNG also writes an EXR beside it)
    #[arg(long, value_name = "FILE")]
    pub screenshot: Option<PathBuf>,
    /// How frames reach the window
    #[arg(long, value_enum, default_value_t = PresentChoice::Auto)]
    pub present: PresentChoice,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum PresentChoice {
    /// The window's Vulkan swapchain if the GPU can present to this display (checked in a
    /// child process: some drivers crash on displays they cannot drive, such as NVIDIA's
    /// on Xvfb), else copy
    Auto,
    /// The window's Vulkan swapchain: the GPU draws straight into the window
    Swapchain,
    /// Render off-screen on the GPU and copy each frame to the window through the CPU
    /// (virtual displays and remote X, where the GPU cannot present)
    Copy,
}
