//! Ray-tracing kernels. Every function here is plain Rust that runs in three places:
//! compiled to SPIR-V by rust-gpu (through the thin wrappers in `entry`), in the runner's
//! CPU backend (rayon over pixels), and in `#[test]`s. Kernels read no globals: all inputs
//! come in as arguments (slices for buffers, `&FrameParams` for uniforms).
#![cfg_attr(target_arch = "spirv", no_std)]
#![cfg_attr(target_arch = "spirv", feature(asm_experimental_arch))]
#![deny(warnings)]

pub mod bindings;
pub mod bits;
pub mod bsdf;
#[cfg(not(target_arch = "spirv"))]
pub mod bundle;
pub mod bvh;
pub mod camera;
pub mod env;
pub mod integrators;
pub mod intersect;
pub mod lights;
pub mod math;
pub mod present;
pub mod reservoir;
pub mod rng;
pub mod sampling;
pub mod skip;
pub mod subgroup;
pub mod texture;
pub mod types;

#[cfg(target_arch = "spirv")]
pub mod entry;

pub use spirv_std::glam;
