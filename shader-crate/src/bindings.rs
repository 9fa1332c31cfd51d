//! The kernels' storage-buffer bindings, declared once. The host builds its bind group
//! layouts and bind groups from these tables; the entry points in `entry.rs` must write
//! the same numbers as literals (SPIR-V attributes take no constants), and a test reads
//! the compiled module's decorations to hold the two to each other (tests/bindings.rs).

/// One storage buffer of a descriptor set.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Binding {
    pub set: u32,
    pub binding: u32,
    /// What it holds, for labels and messages.
    pub name: &'static str,
    /// The kernels only read it.
    pub read_only: bool,
}

const fn scene(binding: u32, name: &'static str, read_only: bool) -> Binding {
    Binding {
        set: 0,
        binding,
        name,
        read_only,
    }
}

const fn restir(binding: u32, name: &'static str, read_only: bool) -> Binding {
    Binding {
        set: 1,
        binding,
        name,
        read_only,
    }
}

/// Set 0, bound by every image kernel and ReSTIR pass.
pub const SCENE: [Binding; 11] = [
    scene(0, "frame params", true),
    scene(1, "triangles", true),
    scene(2, "materials", true),
    scene(3, "BVH nodes", true),
    scene(4, "lights", true),
    // rgb = sum of samples, a = their count, per pixel
    scene(5, "accumulation", false),
    scene(6, "rays traced per pixel", false),
    scene(7, "triangle shading attributes", true),
    scene(8, "texture table", true),
    scene(9, "texels", true),
    scene(10, "environment distribution", true),
];

/// Set 1, bound by the ReSTIR passes besides set 0.
pub const RESTIR: [Binding; 5] = [
    restir(0, "current G-buffer", false),
    restir(1, "previous G-buffer", true),
    restir(2, "input reservoirs", true),
    restir(3, "output reservoirs", false),
    restir(4, "previous frame's reservoirs", true),
];

/// Set 0 of the viewer's present pass (its fragment shader).
pub const PRESENT: [Binding; 2] = [
    scene(0, "present params", true),
    scene(1, "accumulation", true),
];
