//! The GPU (SPIR-V through wgpu; lavapipe in CI) and the CPU backend run the same kernel
//! functions with the same random streams: their images must agree pixel by pixel.
use runner::ao_order::AoOrder;
use runner::backend::Backend;
use runner::cpu::CpuBackend;
use runner::gpu::{adapters, GpuBackend, GpuContext};
use runner::integrator::{AoSampling, Integrator, LightSampling};
use runner::light_shares::LightShares;
use runner::options::{frame_params, KernelOptions, SceneOptions, UpAxis};
use runner::output::Image;
use runner::render::render;
use runner::scene::{load as load_scene, Scene};

fn scene_args(width: u32, height: u32) -> SceneOptions {
    SceneOptions {
        scene: None,
        width,
        height,
        eye: None,
        target: None,
        up: None,
        up_axis: UpAxis::Y,
        fov: None,
        bvh_quality: None,
        bvh_splits: None,
    }
}

fn kernel_args(integrator: Integrator, spp: u32) -> KernelOptions {
    KernelOptions {
        integrator,
        spp,
        candidates: 8,
        temporal_cap: 20.0,
        spatial_neighbours: 2,
        disocclusion_neighbours: 5,
        spatial_radius: Some(10.0),
        restir_bias: None,
        spatial_passes: 2,
        no_temporal: false,
        no_visibility_reuse: false,
        split_passes: false,
        max_depth: 4,
        sky: None,
        env: None,
        env_rotate: 0.0,
        env_scale: 1.0,
        sun: None,
        sun_radiance: glam::Vec3::ZERO,
        sun_angle: 0.53,
        light_sampling: LightSampling::Power,
        light_shares: LightShares::Seen,
        ao_rays: 4,
        ao_distance: None,
        ao_sampling: AoSampling::Stratified,
        ao_order: AoOrder::Auto,
        seed: 7,
    }
}

fn gpu_backend(scene: &Scene, w: u32, h: u32) -> GpuBackend {
    let adapter = adapters()
        .into_iter()
        .next()
        .expect("no Vulkan adapter: install mesa-vulkan-drivers (lavapipe) to run the GPU tests");
    let ctx = GpuContext::new(&adapter).expect("GPU device");
    GpuBackend::new(ctx, scene, w, h).expect("GPU backend")
}

fn render_both(integrator: Integrator, w: u32, h: u32, spp: u32) -> (Image, Image) {
    render_both_with(&kernel_args(integrator, spp), w, h)
}

fn render_both_with(ka: &KernelOptions, w: u32, h: u32) -> (Image, Image) {
    let (integrator, spp) = (ka.integrator, ka.spp);
    let sa = scene_args(w, h);
    let mut scene = load_scene(&sa).unwrap();
    let params = frame_params(&sa, ka, &mut scene).unwrap();
    let mut gpu = gpu_backend(&scene, w, h);
    let mut cpu = CpuBackend::new(&scene, w, h);
    eprintln!("comparing {} with {}", gpu.describe(), cpu.describe());
    let (g, _) = render(&mut gpu, integrator, &params, spp, 2, false).unwrap();
    let (c, _) = render(&mut cpu, integrator, &params, spp, 1, false).unwrap();
    (g, c)
}

#[test]
fn ao_gpu_matches_cpu_pixel_by_pixel() {
    // Not a multiple of the 8×8 workgroup: the AO kernel's threads beyond the image
    // trace their neighbours' rays.
    let (w, h, spp) = (61, 45, 4);
    // Both orders of the GPU's walk (`runner::ao_order`; the CPU's bundles have their own).
    for ao_order in [AoOrder::Near, AoOrder::Far] {
        let ka = KernelOptions {
            ao_order,
            ..kernel_args(Integrator::Ao, spp)
        };
        ao_images_agree(render_both_with(&ka, w, h), w, h, spp * ka.ao_rays);
    }
}

/// AO images of `rays` rays a pixel (spp · ao_rays) from the GPU and the CPU.
fn ao_images_agree((g, c): (Image, Image), w: u32, h: u32, rays: u32) {
    // A pixel's AO is a count of open rays over `rays`. The two sides compute the same
    // rays, but float rounding (FMA contraction on the GPU) can flip a ray that grazes an
    // edge, changing a pixel by a multiple of 1/rays: allow that for very few pixels, and
    // require almost all to be identical.
    let step = 1.0 / rays as f32;
    let n = (w * h) as usize;
    let mut differ = 0;
    for (i, (a, b)) in g.pixels.iter().zip(&c.pixels).enumerate() {
        let d = (*a - *b).abs().max_element();
        if d > 1e-5 {
            differ += 1;
            assert!(d <= 2.0 * step + 1e-5, "pixel {i}: gpu {a} vs cpu {b}");
        }
    }
    assert!(differ * 100 <= n, "{differ} of {n} pixels differ");
    assert!(
        g.mean().x > 0.2,
        "GPU image is (nearly) black: mean {}",
        g.mean()
    );
}

/// A kernel that the driver cuts short is an error, never an image with holes: lavapipe
/// (CI's driver) ends a shader's loops after 65,535 iterations in all, which the AO
/// workgroup pool inside shell-100k at 64 rays a point runs past, and the invocations it
/// stops write nothing (`render::check_complete`). A driver without that limit must give
/// the CPU's image.
#[test]
fn a_kernel_cut_short_is_an_error_not_an_image() {
    let (w, h) = (64, 32);
    let sa = SceneOptions {
        scene: Some("shell-100k".into()),
        ..scene_args(w, h)
    };
    let ka = KernelOptions {
        ao_rays: 64,
        ..kernel_args(Integrator::Ao, 1)
    };
    let mut scene = load_scene(&sa).unwrap();
    let params = frame_params(&sa, &ka, &mut scene).unwrap();
    let mut gpu = gpu_backend(&scene, w, h);
    let mut cpu = CpuBackend::new(&scene, w, h);
    let (c, _) = render(&mut cpu, Integrator::Ao, &params, 1, 1, false).unwrap();
    match render(&mut gpu, Integrator::Ao, &params, 1, 1, false) {
        Ok((g, _)) => ao_images_agree((g, c), w, h, ka.ao_rays),
        Err(e) => {
            let e = e.to_string();
            assert!(
                e.contains("pixels without") && e.contains("--backend cpu"),
                "{e}"
            );
        }
    }
}

#[test]
fn split_into_passes_does_not_change_the_image() {
    // Sample s draws stream s whatever pass it falls in: 1 pass of 4 == 4 passes of 1.
    let sa = scene_args(32, 32);
    let ka = kernel_args(Integrator::Ao, 4);
    let mut scene = load_scene(&sa).unwrap();
    let params = frame_params(&sa, &ka, &mut scene).unwrap();
    let mut cpu = CpuBackend::new(&scene, 32, 32);
    let (a, _) = render(&mut cpu, Integrator::Ao, &params, 4, 4, false).unwrap();
    let (b, _) = render(&mut cpu, Integrator::Ao, &params, 4, 1, false).unwrap();
    for (x, y) in a.pixels.iter().zip(&b.pixels) {
        assert!((*x - *y).abs().max_element() < 1e-6);
    }
}

#[test]
fn path_integrators_gpu_match_cpu() {
    // ReSTIR: 3 frames, so every pass (temporal and spatial with history) takes part.
    for integrator in [
        Integrator::Pt,
        Integrator::Nee,
        Integrator::Mis,
        Integrator::Ris,
        Integrator::Restir,
    ] {
        let (w, h, spp) = (48, 48, 3);
        let (g, c) = render_both(integrator, w, h, spp);
        let n = g.pixels.len();
        let same = g
            .pixels
            .iter()
            .zip(&c.pixels)
            .filter(|(a, b)| (**a - **b).abs().max_element() <= 1e-4 * a.max_element().max(1.0))
            .count();
        eprintln!(
            "{integrator:?}: {same} of {n} pixels identical; means gpu {} cpu {}",
            g.mean(),
            c.mean()
        );
        assert!(g.pixels.iter().all(|p| p.is_finite()));
        // Same kernels, same random streams: a path only diverges where float rounding
        // differs on a knife edge, and then the pixel is a different sample of the same
        // distribution. Nearly every pixel must be identical.
        assert!(
            same * 100 >= n * 97,
            "{integrator:?}: only {same} of {n} pixels agree"
        );
    }
}

#[test]
fn textures_and_vertex_normals_gpu_match_cpu() {
    // A textured floor with a different normal at each corner (interpolated across it), a
    // normal map bending it further and a checkered cut-out mask, an emitter whose emission
    // is textured, a back wall under a height (bump) map, under an emitter and an environment map with a sun: the
    // texel buffer, the bilinear and mip-level lookups, sRGB, linear and RGBE decoding, shading normals, the mask
    // test inside traversal and the map's importance sampling (NEE picks it half the time;
    // RIS and ReSTIR hold its directions in reservoirs) run on both sides.
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("gpu_cpu_surfaces");
    std::fs::create_dir_all(&dir).unwrap();
    // 64² texels tiled twice across the floor, about 3 to a pixel: read from mip levels.
    let texels: Vec<u8> = (0..64u32 * 64)
        .flat_map(|i| {
            [
                (i * 7 % 256) as u8,
                (i * 13 % 256) as u8,
                (i * 29 % 256) as u8,
                255,
            ]
        })
        .collect();
    image::RgbaImage::from_raw(64, 64, texels)
        .unwrap()
        .save(dir.join("noise.png"))
        .unwrap();
    let checker: Vec<u8> = (0..4u32 * 4)
        .map(|i| if (i + i / 4) % 2 == 0 { 255 } else { 0 })
        .collect();
    image::GrayImage::from_raw(4, 4, checker)
        .unwrap()
        .save(dir.join("checker.png"))
        .unwrap();
    // A normal map of bumps leaning up to ~27° every way (linear bytes, z leading).
    let bumps: Vec<u8> = (0..8u32 * 8)
        .flat_map(|i| {
            let (x, y) = ((i % 8) as f32 / 7.0 - 0.5, (i / 8) as f32 / 7.0 - 0.5);
            let m = glam::Vec3::new(x, -y, 1.0).normalize();
            let byte = |c: f32| ((c * 0.5 + 0.5) * 255.0).round() as u8;
            [byte(m.x), byte(m.y), byte(m.z), 255]
        })
        .collect();
    image::RgbaImage::from_raw(8, 8, bumps)
        .unwrap()
        .save(dir.join("bumps.png"))
        .unwrap();
    std::fs::write(
        dir.join("s.mtl"),
        "newmtl floor\nKd 1 1 1\nmap_Kd noise.png\nmap_d checker.png\nnorm bumps.png\nnewmtl light\nKd 0 0 0\nKe 20 20 20\nmap_Ke noise.png\nnewmtl wall\nKd 0.8 0.8 0.8\nmap_Bump -bm 0.05 noise.png\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("s.obj"),
        "mtllib s.mtl\nv -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\n\
         v -0.3 1 -0.3\nv 0.3 1 -0.3\nv 0.3 1 0.3\nv -0.3 1 0.3\n\
         vt 0 0\nvt 0 2\nvt 2 2\nvt 2 0\n\
         vn 0.3 1 0\nvn 0 1 0.3\nvn -0.3 1 0\nvn 0 1 -0.3\n\
         v -0.9 0 -0.9\nv -0.9 0.8 -0.9\nv 0.9 0.8 -0.9\nv 0.9 0 -0.9\n\
         usemtl floor\nf 1/1/1 2/2/2 3/3/3 4/4/4\nusemtl light\nf 5/1 6/2 7/3 8/4\n\
         usemtl wall\nf 9/1 12/4 11/3 10/2\n",
    )
    .unwrap();
    let sky: Vec<image::Rgb<f32>> = (0..16u32 * 32)
        .map(|i| {
            let (x, y) = (i % 32, i / 32);
            if x == 20 && y == 4 {
                image::Rgb([400.0, 350.0, 300.0])
            } else {
                image::Rgb([0.2 + 0.01 * x as f32, 0.3, 0.5 - 0.02 * y as f32])
            }
        })
        .collect();
    image::codecs::hdr::HdrEncoder::new(std::fs::File::create(dir.join("sky.hdr")).unwrap())
        .encode(&sky, 32, 16)
        .unwrap();
    let (w, h, spp) = (40, 40, 2);
    let mut sa = scene_args(w, h);
    sa.scene = Some(dir.join("s.obj"));
    sa.eye = Some(glam::DVec3::new(0.0, 2.5, 1.5));
    sa.target = Some(glam::DVec3::ZERO);
    let mut scene = load_scene(&sa).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    for integrator in [
        Integrator::Nee,
        Integrator::Mis,
        Integrator::Ris,
        Integrator::Restir,
    ] {
        let mut ka = kernel_args(integrator, spp);
        ka.env = Some(dir.join("sky.hdr"));
        let params = frame_params(&sa, &ka, &mut scene).unwrap();
        let mut gpu = gpu_backend(&scene, w, h);
        let mut cpu = CpuBackend::new(&scene, w, h);
        let (g, _) = render(&mut gpu, integrator, &params, spp, 1, false).unwrap();
        let (c, _) = render(&mut cpu, integrator, &params, spp, 1, false).unwrap();
        let n = g.pixels.len();
        // The map's samples go through sin, cos and atan2, which the GPU computes a few ulps
        // away from the CPU's libm: a sun texel's radiance / pdf then differs by ~1e-4 of a
        // large value, and a direction on a texel edge can land in the next texel (another
        // sample of the same distribution, as knife edges do in the other tests). So: 1e-3
        // relative, 95% of pixels, and the means within 1e-3.
        let same = g
            .pixels
            .iter()
            .zip(&c.pixels)
            .filter(|(a, b)| (**a - **b).abs().max_element() <= 1e-3 * a.max_element().max(1.0))
            .count();
        assert!(g.mean().max_element() > 0.01, "{integrator:?}: lit");
        assert!(
            ((g.mean() - c.mean()).abs() / c.mean()).max_element() < 1e-3,
            "{integrator:?}: means gpu {} cpu {}",
            g.mean(),
            c.mean()
        );
        assert!(
            same * 100 >= n * 95,
            "{integrator:?}: only {same} of {n} pixels agree (gpu {} cpu {})",
            g.mean(),
            c.mean()
        );
    }
}

/// Workgroup memory for `ao_workgroup_pool_matches_per_pixel`: words shared by real
/// threads, a barrier they all wait at.
struct SharedWords<'a> {
    words: &'a [std::sync::atomic::AtomicU32],
    barrier: &'a std::sync::Barrier,
}

impl kernels::integrators::ao::GroupMemory for SharedWords<'_> {
    fn load(&self, word: usize) -> u32 {
        self.words[word].load(std::sync::atomic::Ordering::SeqCst)
    }

    fn store(&mut self, word: usize, value: u32) {
        self.words[word].store(value, std::sync::atomic::Ordering::SeqCst);
    }

    fn fetch_add(&mut self, word: usize, value: u32) -> u32 {
        self.words[word].fetch_add(value, std::sync::atomic::Ordering::SeqCst)
    }

    fn barrier(&mut self) {
        self.barrier.wait();
    }
}

use kernels::integrators::ao::{SMALL_GROUP, WIDE_GROUP};

#[test]
fn ao_workgroup_pool_matches_per_pixel() {
    // The GPU's AO kernel: a workgroup's threads share their pixels' rays. Run it with as
    // many threads on the CPU, in the GPU's rows of 16 pixels, over a tile that sticks out
    // of the image (threads without a pixel) and over one inside it, and hold every pixel
    // to the per-pixel function's result: the same rays are traced whoever traces them, so
    // the sums must be identical. Either walk order (`runner::ao_order`): the same answer
    // for every ray.
    let orders = [kernels::types::AO_NEAR_FIRST, kernels::types::AO_FAR_FIRST];
    let tiles = [(0, 0, orders[0]), (8, 8, orders[0]), (0, 0, orders[1])];
    let hits = pool_matches_per_pixel::<SMALL_GROUP>(None, (13, 11), (3, 5), &tiles);
    assert!(
        hits > 10,
        "only {hits} pixels with AO rays: the test tests little"
    );
    // A full pool: every thread's camera ray hits (from inside a closed sphere), each point
    // with the renderer's default 64 rays, 8,192 rays for the workgroup.
    let tile = [(0, 0, orders[1])];
    let hits = pool_matches_per_pixel::<SMALL_GROUP>(Some("shell-20k"), (16, 16), (1, 64), &tile);
    assert_eq!(hits, 128, "every thread of the tile should hold a point");
    // The 16×56 workgroup of NVIDIA adapters, full: 896 points in one pool, whose point
    // list keeps each point's thread in 16 bits.
    let hits = pool_matches_per_pixel::<WIDE_GROUP>(Some("shell-20k"), (16, 64), (1, 8), &tile);
    assert_eq!(
        hits, WIDE_GROUP as u32,
        "every thread of the tile should hold a point"
    );
}

/// `ao_workgroup_pool_matches_per_pixel` on `scene` (None: the Cornell box) of `(w, h)`
/// pixels, `(spp, ao_rays)`, over tiles of a workgroup of `G` threads in rows of
/// `GROUP_WIDTH`, at `(x, y, walk order)`: the pixels with AO rays.
fn pool_matches_per_pixel<const G: usize>(
    scene: Option<&str>,
    (w, h): (u32, u32),
    (spp, ao_rays): (u32, u32),
    tiles: &[(u32, u32, u32)],
) -> u32 {
    use kernels::integrators::ao::{group_words, render_group_pixel, render_pixel, GROUP_WIDTH};
    let mut sa = scene_args(w, h);
    sa.scene = scene.map(Into::into);
    let mut ka = kernel_args(Integrator::Ao, spp);
    ka.ao_rays = ao_rays;
    let mut scene = load_scene(&sa).unwrap();
    let mut params = frame_params(&sa, &ka, &mut scene).unwrap();
    params.samples = spp;
    let buffers = scene.kernel();
    let mut hits = 0;
    for &(tx, ty, order) in tiles {
        params.ao_order = order;
        let words: Vec<_> = (0..group_words(G)).map(|_| Default::default()).collect();
        let barrier = std::sync::Barrier::new(G);
        let results: Vec<_> = std::thread::scope(|s| {
            let threads: Vec<_> = (0..G)
                .map(|t| {
                    let (words, barrier, buffers, params) = (&words, &barrier, &buffers, &params);
                    s.spawn(move || {
                        let (x, y) = (tx + (t % GROUP_WIDTH) as u32, ty + (t / GROUP_WIDTH) as u32);
                        let inside = x < w && y < h;
                        let mut memory = SharedWords { words, barrier };
                        let r = render_group_pixel::<false, G, _>(
                            buffers,
                            params,
                            &mut memory,
                            t,
                            x,
                            y,
                            inside,
                        );
                        (x, y, inside, r)
                    })
                })
                .collect();
            threads.into_iter().map(|t| t.join().unwrap()).collect()
        });
        for (x, y, inside, r) in results {
            if !inside {
                assert_eq!(r.rays, 0, "({x}, {y}) is outside the image");
                continue;
            }
            let want = render_pixel::<false>(&buffers, &params, x, y);
            assert_eq!((r.sum, r.rays), (want.sum, want.rays), "pixel ({x}, {y})");
            hits += (want.rays > params.samples) as u32;
        }
    }
    hits
}
