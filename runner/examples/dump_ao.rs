//! Diagnostic (not part of the product): dump what one AO frame's rays need — the GPU's
//! CWBVH nodes, the triangles and each pixel's AO point (origin, triangle, normal word,
//! key) — for the CUDA port of the walk to profile (tests/bench/cuda_ao). Usage:
//! `dump_ao <out dir> <bench options...>`, e.g. `dump_ao /tmp/d --scene shell-1m
//! --width 1920 --height 1080 --bvh-quality high --integrator ao --spp 1 --ao-rays 64`.
use std::io::Write;

use clap::Parser;
use kernels::integrators::ao::{self, AoRays};
use kernels::integrators::camera_sample;
use kernels::types::INVALID;

#[derive(Parser)]
struct Cli {
    out: std::path::PathBuf,
    #[command(flatten)]
    bench: runner::bench::BenchArgs,
}

fn main() {
    let cli = Cli::parse();
    let args = &cli.bench;
    let (scene, params) = runner::bench::scene_and_params(args).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    });
    std::fs::create_dir_all(&cli.out).unwrap();
    std::fs::write(
        cli.out.join("nodes.bin"),
        bytemuck::cast_slice(&scene.nodes),
    )
    .unwrap();
    std::fs::write(
        cli.out.join("tris.bin"),
        bytemuck::cast_slice(&scene.triangles),
    )
    .unwrap();
    let buffers = scene.kernel();
    let (w, h) = (params.width, params.height);
    let reference = std::env::var_os("DUMP_REF").is_some();
    let strata = ao::strata(&params);
    let rows: Vec<(Vec<u32>, Vec<f32>)> = {
        use rayon::prelude::*;
        (0..h)
            .into_par_iter()
            .map(|y| {
                let mut row = Vec::with_capacity(6 * w as usize);
                let mut open = Vec::with_capacity(w as usize);
                for x in 0..w {
                    let (ray, mut rng) = camera_sample(&params, x, y, 0);
                    let Some((p, prim, n)) = ao::camera_hit::<true>(&buffers, &ray) else {
                        row.extend([0, 0, 0, 0, 0, INVALID]);
                        if reference {
                            open.push(0.0);
                        }
                        continue;
                    };
                    let r = AoRays::new(&buffers, p, prim, n, &mut rng);
                    if reference {
                        open.push(ao::ambient_occlusion::<true>(
                            &buffers,
                            r,
                            params.ao_rays,
                            strata,
                            params.ao_distance,
                        ));
                    }
                    row.extend([
                        r.origin.x.to_bits(),
                        r.origin.y.to_bits(),
                        r.origin.z.to_bits(),
                        r.normal,
                        r.key,
                        prim,
                    ]);
                }
                (row, open)
            })
            .collect()
    };
    let mut f = std::fs::File::create(cli.out.join("points.bin")).unwrap();
    for (r, _) in &rows {
        f.write_all(bytemuck::cast_slice(r)).unwrap();
    }
    if reference {
        let mut f = std::fs::File::create(cli.out.join("ref.bin")).unwrap();
        for (_, o) in &rows {
            f.write_all(bytemuck::cast_slice(o)).unwrap();
        }
    }
    std::fs::write(
        cli.out.join("params.txt"),
        format!(
            "{} {} {} {} {} {} {}\n",
            w,
            h,
            params.ao_rays,
            params.ao_distance,
            params.ao_order,
            scene.nodes.len(),
            scene.triangles.len()
        ),
    )
    .unwrap();
    eprintln!(
        "dumped {}: {} nodes, {} triangles, {}x{}, ao {} rays to {}, order {}",
        cli.out.display(),
        scene.nodes.len(),
        scene.triangles.len(),
        w,
        h,
        params.ao_rays,
        params.ao_distance,
        params.ao_order
    );
}
