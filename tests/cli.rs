//! The real `runner` binary: help, the default render, and clean failures.
use std::path::PathBuf;
use std::process::{Command, Output};

fn runner(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_runner"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("runner binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn out_path(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn help_explains_the_commands_and_flags() {
    let o = runner(&["--help"]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("render"), "{text}");
    let o = runner(&["render", "--help"]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    for flag in [
        "--scene",
        "--integrator",
        "--width",
        "--height",
        "--spp",
        "--eye",
        "--target",
        "--up",
        "--up-axis",
        "--fov",
        "--ao-rays",
        "--ao-distance",
        "--backend",
        "--seed",
        "--out",
    ] {
        assert!(text.contains(flag), "render --help lacks {flag}:\n{text}");
    }
}

/// Mean (r, g, b) of the pixels in columns `x0..x1` and rows `y0..y1` of an image.
fn region_mean(path: &std::path::Path, (x0, x1): (u32, u32), (y0, y1): (u32, u32)) -> [f32; 3] {
    let img = image::open(path).expect("valid image").to_rgb32f();
    let mut sum = [0.0f32; 3];
    for y in y0..y1 {
        for x in x0..x1 {
            for (s, c) in sum.iter_mut().zip(img.get_pixel(x, y).0) {
                *s += c;
            }
        }
    }
    sum.map(|s| s / ((x1 - x0) * (y1 - y0)) as f32)
}

/// What people run first: `render` with no options is the path-traced Cornell box in
/// colour (red wall on the left, green on the right, a lit white floor), on the CPU backend
/// and on whatever `auto` picks.
#[test]
fn default_render_is_the_path_traced_cornell_box() {
    for backend in ["cpu", "auto"] {
        let out = out_path(&format!("default_{backend}.png"));
        let _ = std::fs::remove_file(&out);
        let o = runner(&[
            "render",
            "--width",
            "64",
            "--height",
            "64",
            "--spp",
            "16",
            "--backend",
            backend,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{backend}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("integrator mis"),
            "{backend}: {}",
            stderr(&o)
        );
        let [r, g, b] = region_mean(&out, (2, 8), (16, 48));
        assert!(
            r > 2.0 * g && r > 2.0 * b && r > 0.2,
            "{backend}: left wall not red: {r} {g} {b}"
        );
        let [r, g, b] = region_mean(&out, (56, 62), (16, 48));
        // The green wall's albedo (0.14, 0.45, 0.09) under the warm light.
        assert!(
            g > 1.3 * r && g > 3.0 * b && g > 0.15,
            "{backend}: right wall not green: {r} {g} {b}"
        );
        let [r, g, b] = region_mean(&out, (24, 40), (54, 62));
        // The white floor under the warm (17, 12, 4) light.
        assert!(
            (r + g + b) / 3.0 > 0.15 && r > g && g > b,
            "{backend}: floor not lit: {r} {g} {b}"
        );
    }
}

/// The one summary line names the output, the time, the samples and the rays.
#[test]
fn render_ends_with_a_summary_line() {
    let out = out_path("summary.png");
    let o = runner(&[
        "render",
        "--width",
        "16",
        "--height",
        "16",
        "--spp",
        "2",
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let last = err.lines().last().unwrap_or_default();
    assert!(
        last.starts_with(&format!("wrote {} in ", out.display())),
        "{err}"
    );
    assert!(
        last.contains(" s: 16x16, 2 spp x 1 frame(s), ") && last.contains(" rays/s "),
        "{err}"
    );
}

#[test]
fn exr_output_keeps_linear_values() {
    let out = out_path("ao.exr");
    let o = runner(&[
        "render",
        "--integrator",
        "ao",
        "--width",
        "32",
        "--height",
        "32",
        "--spp",
        "1",
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).expect("valid EXR").to_rgb32f();
    assert_eq!(img.dimensions(), (32, 32));
    // AO values are fractions k / ao_rays averaged: inside [0, 1], some strictly between.
    assert!(img
        .pixels()
        .all(|p| p.0.iter().all(|&c| (0.0..=1.0).contains(&c))));
    assert!(img.pixels().any(|p| p.0[0] > 0.0 && p.0[0] < 1.0));
}

#[test]
fn bad_input_fails_with_one_clear_line() {
    let cases: &[(&[&str], &str)] = &[
        (&["render", "--no-such-flag"], "--no-such-flag"),
        (
            &[
                "render",
                "--scene",
                "/nonexistent/scene.obj",
                "--backend",
                "cpu",
            ],
            "cannot read scene",
        ),
        (
            &["render", "--out", "image.bmp", "--backend", "cpu"],
            "unknown image format",
        ),
        (
            &[
                "render",
                "--out",
                "/nonexistent-dir/x.png",
                "--backend",
                "cpu",
            ],
            "does not exist",
        ),
        (
            &["render", "--width", "0", "--backend", "cpu"],
            "at least 1x1",
        ),
        (&["render", "--fov", "180", "--backend", "cpu"], "--fov"),
        (
            &[
                "render",
                "--eye",
                "1,2,3",
                "--target",
                "1,2,3",
                "--backend",
                "cpu",
            ],
            "same point",
        ),
        (
            &[
                "render",
                "--up",
                "0,0,1",
                "--eye",
                "0,0,0",
                "--target",
                "0,0,5",
                "--backend",
                "cpu",
            ],
            "parallel",
        ),
        (&["render", "--spp", "0", "--backend", "cpu"], "--spp"),
        (&["render", "--integrator", "nope"], "nope"),
    ];
    for (args, needle) in cases {
        let o = runner(args);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(
            err.contains(needle),
            "{args:?}: stderr lacks '{needle}':\n{err}"
        );
        assert!(!err.contains("panicked"), "{args:?} panicked:\n{err}");
    }
}

/// `RUNNER_LOG` turns on the log (wgpu's Vulkan backend included); a bad level is an error.
#[test]
fn runner_log_prints_the_log_and_rejects_unknown_levels() {
    let out = out_path("log.png");
    let run = |level: &str| {
        Command::new(env!("CARGO_BIN_EXE_runner"))
            .args([
                "render",
                "--backend",
                "cpu",
                "--width",
                "8",
                "--height",
                "8",
                "--spp",
                "1",
                "--out",
            ])
            .arg(&out)
            .env("RUNNER_LOG", level)
            .output()
            .unwrap()
    };
    let o = run("loud");
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("RUNNER_LOG='loud' is not a log level"),
        "{}",
        stderr(&o)
    );
    let o = run("debug");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("[DEBUG "),
        "no log lines:\n{}",
        stderr(&o)
    );
}

/// `bench` counts one frame's rays and times the frames: on a plane that fills the view
/// every camera sample hits and casts all its AO rays, so a frame traces exactly
/// w·h·spp·(1 + ao-rays) rays; rays/s is that over the median frame time.
#[test]
fn bench_counts_the_rays_of_one_frame() {
    let plane = out_path("bench_plane.obj");
    std::fs::write(
        &plane,
        "v -1000 0 -1000\nv 1000 0 -1000\nv 1000 0 1000\nv -1000 0 1000\nf 1 3 2\nf 1 4 3\n",
    )
    .unwrap();
    let o = runner(&[
        "bench",
        "--integrator",
        "ao",
        "--scene",
        plane.to_str().unwrap(),
        "--eye",
        "0,5,0",
        "--target",
        "0,0,0.001",
        "--backend",
        "cpu",
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "2",
        "--ao-rays",
        "3",
        "--runs",
        "3",
        "--warmup",
        "0",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json = String::from_utf8_lossy(&o.stdout).into_owned();
    let field = |name: &str| -> f64 {
        let at = json
            .find(&format!("\"{name}\":"))
            .unwrap_or_else(|| panic!("no {name} in {json}"));
        let rest = &json[at + name.len() + 3..];
        rest[..rest.find([',', '}']).unwrap()].parse().unwrap()
    };
    assert_eq!(field("rays_per_frame"), (32 * 24 * 2 * (1 + 3)) as f64);
    let (min, median) = (field("frame_ms_min"), field("frame_ms_median"));
    assert!(0.0 < min && min <= median, "{json}");
    // Two passes of one sample each per frame.
    assert!(field("pass_ms_min") <= median / 2.0 + 1e-3, "{json}");
    let rate = field("rays_per_second");
    assert!(
        (rate - 6144.0 / (median * 1e-3)).abs() < 1e-3 * rate,
        "{json}"
    );

    for bad in ["--warmup=-1", "--warmup=nan", "--runs=0"] {
        let o = runner(&[
            "bench",
            "--backend",
            "cpu",
            "--width",
            "8",
            "--height",
            "8",
            bad,
        ]);
        assert_eq!(o.status.code(), Some(1), "{bad}");
        assert!(
            stderr(&o).contains("error:") && !stderr(&o).contains("panicked"),
            "{bad}: {}",
            stderr(&o)
        );
    }
}

/// `--backend auto` never runs on a software Vulkan driver (the CPU backend is faster), and
/// when it does not take a GPU it says why in one `note:` line; `--backend gpu` still runs
/// on a software driver when that is all there is.
#[test]
fn auto_backend_takes_a_hardware_gpu_or_the_cpu_and_says_why() {
    let out = out_path("auto_backend.png");
    let o = runner(&[
        "render",
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "1",
        "--backend",
        "auto",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let chosen = err
        .lines()
        .find_map(|l| l.split_once(", backend ").map(|(_, b)| b.to_string()))
        .expect(&err);
    if chosen.starts_with("cpu") {
        let notes: Vec<&str> = err.lines().filter(|l| l.starts_with("note: ")).collect();
        assert_eq!(notes.len(), 1, "{err}");
        assert!(notes[0].contains("CPU backend"), "{err}");
    } else {
        assert!(
            chosen.starts_with("gpu (") && !chosen.contains(", Cpu,"),
            "auto took a software driver: {err}"
        );
    }
    // Where the only adapter is a software driver (CI: lavapipe), `gpu` still uses it.
    let o = runner(&[
        "render",
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "1",
        "--backend",
        "gpu",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains(", backend gpu ("), "{}", stderr(&o));
}

/// The CWBVH is priced for where the kernels run (`collapse::set_for_cpu`): the CPU
/// backend's tree differs from the GPU's, and `--backend auto` builds the tree of the
/// backend it takes — the CPU's on a machine without a hardware GPU, which it knows
/// before the scene loads.
#[test]
fn the_tree_is_priced_for_the_backend_that_runs_it() {
    let bench = |backend: &str| {
        let args = "bench --scene spheres-50k --integrator ao --width 8 --height 8 --spp 1 \
                    --ao-rays 1 --runs 1 --warmup 0 --json --backend";
        let mut args: Vec<&str> = args.split_whitespace().collect();
        args.push(backend);
        let o = runner(&args);
        let json = String::from_utf8_lossy(&o.stdout).into_owned();
        let nodes = json
            .split_once("\"bvh_nodes\":")
            .map(|(_, rest)| rest[..rest.find(',').unwrap()].parse::<usize>().unwrap());
        let ran = json
            .split_once("\"backend\":\"")
            .map(|(_, rest)| rest[..3].to_string());
        (nodes, ran, stderr(&o))
    };
    let (cpu, _, err) = bench("cpu");
    let cpu = cpu.expect(&err);
    let (auto, ran, err) = bench("auto");
    let auto = auto.expect(&err);
    if ran.as_deref() == Some("cpu") {
        assert_eq!(auto, cpu, "auto ran on the CPU with another tree: {err}");
    }
    // Where a Vulkan adapter exists (CI: lavapipe), the GPU's tree is another one.
    if let (Some(gpu), _, _) = bench("gpu") {
        assert_ne!(gpu, cpu, "the GPU's tree is priced as the CPU's");
        if ran.as_deref() == Some("gpu") {
            assert_eq!(auto, gpu, "auto ran on the GPU with another tree: {err}");
        }
    }
}
