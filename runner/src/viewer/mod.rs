//! `runner view`: the GPU output in a window, redrawn every frame, with the camera in the
//! user's hands. `controls` holds the per-frame logic (tested without a window); `app` the
//! window and the present pass; `present` how frames reach the window.
pub mod app;
pub mod controls;
pub mod present;
