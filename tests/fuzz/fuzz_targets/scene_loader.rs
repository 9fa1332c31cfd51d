//! PLY, or OBJ + MTL, bytes → scene → BVH → a tiny CPU render. Errors are fine; panics, hangs and
//! non-finite pixels are bugs. Crashing inputs go to tests/fuzz/regressions/, which
//! tests/fuzz_regressions.rs replays in CI.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(image) = runner::fuzz::load_and_render_bytes(data) {
        assert!(image.pixels.iter().all(|p| p.is_finite()));
    }
});
