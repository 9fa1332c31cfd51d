//! The integrators `--integrator` names, and the one table of what runs each: an image
//! kernel (its SPIR-V entry point and the same per-pixel function for the CPU backend), or
//! ReSTIR's schedule of passes (`restir.rs`). The GPU backend, the CPU backend and the
//! viewer all read this table.
use clap::ValueEnum;
use kernels::bvh::SceneBuffers;
use kernels::integrators::{ao, path, PixelResult};
use kernels::types::FrameParams;

#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, ValueEnum)]
pub enum Integrator {
    /// Ambient occlusion: fraction of cosine-weighted rays that escape within --ao-distance
    Ao,
    /// Path tracing (the course's loop): emission counts when a bounce hits it
    Pt,
    /// Path tracing with next-event estimation: a light sample and shadow ray per vertex
    Nee,
    /// NEE and BSDF sampling combined by multiple importance sampling (power heuristic)
    Mis,
    /// Resampled importance sampling of direct light (--candidates per pixel, WRS)
    Ris,
    /// ReSTIR DI: RIS plus temporal and spatial reuse of reservoirs across frames/pixels
    Restir,
}

/// The per-pixel function of an image kernel: the sum of the pixel's `params.samples`
/// samples and the rays traced for them.
pub type PixelFn = fn(&SceneBuffers, &FrameParams, u32, u32) -> PixelResult;

/// What runs an integrator.
#[derive(Copy, Clone)]
pub enum Kernel {
    /// One dispatch over the image: the SPIR-V entry point (rust-gpu names entry points by
    /// their module path in shader-crate/src/entry.rs) and the function it wraps.
    Image {
        entry_point: &'static str,
        pixel: PixelFn,
    },
    /// The ReSTIR frame: a schedule of passes (`restir::RestirPass`), in their variant
    /// for plain scenes or the general one.
    Restir { plain: bool },
}

impl Integrator {
    /// Every integrator, in the order of the viewer's number keys (1-6).
    pub const ALL: [Integrator; 6] = [
        Integrator::Ao,
        Integrator::Pt,
        Integrator::Nee,
        Integrator::Mis,
        Integrator::Ris,
        Integrator::Restir,
    ];

    /// The name `--integrator` takes, and what runs it: for any scene, and for scenes whose
    /// materials are all Lambertian (kernels without the other BSDFs' code: faster).
    fn table(self) -> (&'static str, [Kernel; 2]) {
        let image = |entry_point, pixel| Kernel::Image { entry_point, pixel };
        match self {
            Integrator::Ao => (
                "ao",
                [
                    image("entry::ao_main", ao::render_pixel::<false>),
                    image("entry::ao_plain_main", ao::render_pixel::<true>),
                ],
            ),
            Integrator::Pt => (
                "pt",
                [
                    image("entry::pt_main", path::pt_pixel::<false>),
                    image("entry::pt_diffuse_main", path::pt_pixel::<true>),
                ],
            ),
            Integrator::Nee => (
                "nee",
                [
                    image("entry::nee_main", path::nee_pixel::<false>),
                    image("entry::nee_diffuse_main", path::nee_pixel::<true>),
                ],
            ),
            Integrator::Mis => (
                "mis",
                [
                    image("entry::mis_main", path::mis_pixel::<false>),
                    image("entry::mis_diffuse_main", path::mis_pixel::<true>),
                ],
            ),
            Integrator::Ris => (
                "ris",
                [
                    image("entry::ris_main", path::ris_pixel::<false>),
                    image("entry::ris_diffuse_main", path::ris_pixel::<true>),
                ],
            ),
            Integrator::Restir => (
                "restir",
                [
                    Kernel::Restir { plain: false },
                    Kernel::Restir { plain: true },
                ],
            ),
        }
    }

    /// The name `--integrator` takes.
    pub fn name(self) -> &'static str {
        self.table().0
    }

    /// What runs this integrator: the variant for plain scenes (`plain_scene`) or the
    /// general one.
    pub fn kernel(self, plain: bool) -> Kernel {
        self.table().1[plain as usize]
    }

    /// Both variants: for any scene, and for all-Lambertian scenes.
    pub fn kernels(self) -> [Kernel; 2] {
        self.table().1
    }
}

/// Whether a pass may run the kernels for plain scenes: every material Lambertian and
/// untextured (`Scene::all_diffuse`), and no environment map or sun in `params` (the sky a
/// constant at most).
pub fn plain_scene(all_diffuse: bool, params: &FrameParams) -> bool {
    all_diffuse && params.env_texture == kernels::types::INVALID && params.sun_radiance == [0.0; 3]
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum RestirBias {
    /// MIS weights with visibility at the other pixels: converges to the right image
    Unbiased,
    /// MIS weights without visibility: no extra shadow rays, a little darker where
    /// visibility varies
    Biased,
}

impl RestirBias {
    /// The mode the build chose (the `restir-unbiased` feature).
    pub const COMPILED_DEFAULT: RestirBias = if kernels::integrators::restir::UNBIASED_BY_DEFAULT {
        RestirBias::Unbiased
    } else {
        RestirBias::Biased
    };
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum LightSampling {
    /// Every emissive triangle equally likely (the course)
    Uniform,
    /// In proportion to emitted power (alias table)
    Power,
}

impl LightSampling {
    /// The kernels' `FrameParams::light_sampling` value.
    pub fn kernel_value(self) -> u32 {
        match self {
            LightSampling::Uniform => kernels::types::LIGHT_SAMPLING_UNIFORM,
            LightSampling::Power => kernels::types::LIGHT_SAMPLING_POWER,
        }
    }
}

/// How a pixel's AO rays are spread over the hemisphere (`--ao-sampling`).
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum AoSampling {
    /// Jittered strata, one ray per cell, the cells in the same order in every pixel:
    /// less noise, and neighbouring pixels' k-th rays run side by side on a GPU
    Stratified,
    /// Each ray drawn from the whole hemisphere (incoherent rays)
    Independent,
}

impl AoSampling {
    /// The kernels' `FrameParams::ao_sampling` value.
    pub fn kernel_value(self) -> u32 {
        match self {
            AoSampling::Stratified => kernels::types::AO_STRATIFIED,
            AoSampling::Independent => kernels::types::AO_INDEPENDENT,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_what_the_command_line_takes() {
        for i in Integrator::ALL {
            let parsed = Integrator::from_str(i.name(), false).expect("a valid --integrator");
            assert_eq!(parsed, i);
        }
        assert_eq!(Integrator::ALL.len(), Integrator::value_variants().len());
    }
}
