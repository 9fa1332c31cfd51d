//! The `runner` library: scene loading, the CPU and GPU backends, output, and the command
//! line on top of them. `main.rs` is a thin shell over it; tests use it directly.
pub mod accel;
pub mod backend;
pub mod bench;
pub mod camera;
pub mod cli;
pub mod cpu;
pub mod environment;
pub mod error;
pub mod fuzz;
pub mod generate;
pub mod gltf_lights;
pub mod gltf_scene;
pub mod gpu;
pub mod integrator;
pub mod light_shares;
pub mod lights;
pub mod logging;
pub mod memory;
pub mod options;
pub mod output;
pub mod ply_scene;
pub mod render;
pub mod restir;
pub mod scene;
pub mod textures;
pub mod viewer;
