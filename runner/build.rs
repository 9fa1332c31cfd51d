//! Compiles `shader-crate` to SPIR-V with rust-gpu and exposes the module path as
//! `env!("kernels.spv")`. The runner's cargo features that select kernel variants are
//! forwarded to the shader crate, so the GPU and the CPU backend run the same variant.
use spirv_builder::{Capability, ShaderPanicStrategy, SpirvBuilder, SpirvMetadata};

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
    // `RT_SHADER_PANICS=report`: each panic that survives optimisation prints its source
    // line (debugPrintf) before returning from the kernel, so the SPIR-V holds those lines
    // as strings: `tests/bench/panic_sites.sh` lists them. Every panic costs a kernel its
    // loops' early-exit flags (docs/PERFORMANCE.md, "Panics in the walk's loop").
    println!("cargo:rerun-if-env-changed=RT_SHADER_PANICS");
    if std::env::var("RT_SHADER_PANICS").as_deref() == Ok("report") {
        builder = builder.shader_panic_strategy(ShaderPanicStrategy::DebugPrintfThenExit {
            print_inputs: false,
            print_backtrace: false,
        });
    }
    builder.build_script.defaults = true;
    builder.build_script.env_shader_spv_path = Some(true);
    builder.build()?;
    Ok(())
}
