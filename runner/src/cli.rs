//! The command line (clap): the subcommands and their options. Each subcommand's options
//! live with the module that runs it; this file only puts them together, and only
//! `main.rs` reads it.
use clap::{Parser, Subcommand};

use crate::bench::BenchArgs;
use crate::generate::GenerateArgs;
use crate::output::CompareArgs;
use crate::render::RenderArgs;
use crate::viewer::ViewArgs;

#[derive(Parser, Debug)]
#[command(
    // No subcommand is an error (one `error:` line and the usage), not a help page.
    subcommand_required = true,
    arg_required_else_help = false,
    name = "runner",
    version,
    about = "GPU ray tracer in Rust: the same no_std kernels run as SPIR-V through wgpu and on the CPU",
    long_about = "GPU ray tracer in Rust. Kernels (ambient occlusion, ...) are no_std Rust compiled \
to SPIR-V by rust-gpu and run through wgpu (Vulkan); the very same functions run on the CPU \
backend. Scenes are OBJ + MTL (Kd, Ks, Ns, Ni, illum, Pr/Pm and map_Kd map onto a BSDF family \
of diffuse, metal, glass and coated surfaces; Ke and map_Ke emit from the counter-clockwise \
front side; map_d cuts out, norm or a normal map in map_Bump bends normals), glTF 2.0 (base \
colour, normal, metallic-roughness and emissive textures) or PLY; --sky, --env (an HDR map) \
and --sun light them from outside."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render an image (PNG or EXR)
    Render(RenderArgs),
    /// Time a render workload: ms per frame from GPU timestamps, rays per second
    Bench(BenchArgs),
    /// Write a built-in scene (many-lights, light-hall, rocks-<N>) as OBJ + MTL
    Generate(GenerateArgs),
    /// Compare an image with a reference: RMSE, relMSE, identical pixels
    Compare(CompareArgs),
    /// Interactive viewer: WASD/QE move, drag to look, scroll = speed, R reset camera,
    /// 1-6 integrator (ao pt nee mis ris restir), T temporal, +/- spatial passes,
    /// B biased/unbiased, [ ] turn the environment map, P save PNG+EXR, Esc quit
    View(ViewArgs),
}
