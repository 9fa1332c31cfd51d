//! Compiles `shader-crate` to SPIR-V with rust-gpu and exposes the module path as
//! `env!("kernels.spv")`. The runner's cargo features that select kernel variants are
//! forwarded to the shader crate, so the GPU and the CPU backend run the same variant.
use spirv_builder::{Capability, SpirvBuilder, SpirvMetadata};

/// Runner features that are really shader-crate features (see runner/Cargo.toml).
const FORWARDED_FEATURES: &[&str] = &[
    "intersect-moller-trumbore",
    "traversal-brute-force",
    "traversal-bvh2",
    "restir-unbiased",
];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // spirv-builder reports the shader sources by absolute path; also name them relative
    // to this package, so that a checkout elsewhere sharing the target directory (a CI
    // clone, say) still rebuilds the SPIR-V when its own sources change.
    println!("cargo:rerun-if-changed=../shader-crate/src");
    println!("cargo:rerun-if-changed=../shader-crate/Cargo.toml");
    let features: Vec<String> = FORWARDED_FEATURES
        .iter()
        .filter(|f| {
            let var = format!("CARGO_FEATURE_{}", f.to_uppercase().replace('-', "_"));
            std::env::var_os(var).is_some()
        })
        .map(|f| f.to_string())
        .collect();
    let mut builder = SpirvBuilder::new("../shader-crate", "spirv-unknown-vulkan1.2")
        .shader_crate_default_features(false)
        .shader_crate_features(features)
        .spirv_metadata(SpirvMetadata::None)
        // Subgroup votes (`shader_crate::subgroup`): every Vulkan GPU we target has them.
        .capability(Capability::GroupNonUniform)
        .capability(Capability::GroupNonUniformBallot);
    builder.build_script.defaults = true;
    builder.build_script.env_shader_spv_path = Some(true);
    builder.build()?;
    Ok(())
}
