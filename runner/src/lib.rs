//! The `runner` library: scene loading, the CPU and GPU backends, output, and the CLI's
//! pieces. `main.rs` is a thin shell over it; tests use it directly.
pub mod accel;
pub mod backend;
pub mod bench;
pub mod cli;
pub mod cpu;
pub mod error;
pub mod generate;
pub mod gpu;
pub mod lights;
pub mod logging;
pub mod memory;
pub mod output;
pub mod render;
pub mod restir;
pub mod scene;
pub mod setup;
pub mod viewer;
