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
    for flag in ["--scene", "--integrator", "--width", "--height", "--spp", "--eye", "--target",
                 "--up", "--fov", "--ao-rays", "--ao-distance", "--backend", "--seed", "--out"] {
        assert!(text.contains(flag), "render --help lacks {flag}:\n{text}");
    }
}

/// Load a PNG as linear-ish grey values in [0, 1].
fn grey_values(path: &PathBuf) -> (u32, u32, Vec<f32>) {
    let img = image::open(path).expect("valid image").to_rgb8();
    let v = img.pixels().map(|p| p.0.iter().map(|&c| c as f32).sum::<f32>() / 765.0).collect();
    (img.width(), img.height(), v)
}

#[test]
fn default_render_writes_a_non_trivial_image() {
    for backend in ["cpu", "auto"] {
        let out = out_path(&format!("default_{backend}.png"));
        let _ = std::fs::remove_file(&out);
        let o = runner(&["render", "--width", "96", "--height", "64", "--spp", "2",
                         "--backend", backend, "--out", out.to_str().unwrap()]);
        assert!(o.status.success(), "{backend}: {}", stderr(&o));
        let (w, h, v) = grey_values(&out);
        assert_eq!((w, h), (96, 64));
        let mean = v.iter().sum::<f32>() / v.len() as f32;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / v.len() as f32;
        // The Cornell box under AO: mostly open surfaces (bright), darker corners.
        assert!(mean > 0.3 && mean < 0.95, "{backend}: mean {mean}");
        assert!(var.sqrt() > 0.05, "{backend}: flat image, std {}", var.sqrt());
    }
}

#[test]
fn exr_output_keeps_linear_values() {
    let out = out_path("ao.exr");
    let o = runner(&["render", "--width", "32", "--height", "32", "--spp", "1",
                     "--backend", "cpu", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).expect("valid EXR").to_rgb32f();
    assert_eq!(img.dimensions(), (32, 32));
    // AO values are fractions k / ao_rays averaged: inside [0, 1], some strictly between.
    assert!(img.pixels().all(|p| p.0.iter().all(|&c| (0.0..=1.0).contains(&c))));
    assert!(img.pixels().any(|p| p.0[0] > 0.0 && p.0[0] < 1.0));
}

#[test]
fn bad_input_fails_with_one_clear_line() {
    let cases: &[(&[&str], &str)] = &[
        (&["render", "--no-such-flag"], "--no-such-flag"),
        (&["render", "--scene", "/nonexistent/scene.obj", "--backend", "cpu"], "cannot read scene"),
        (&["render", "--out", "image.bmp", "--backend", "cpu"], "unknown image format"),
        (&["render", "--out", "/nonexistent-dir/x.png", "--backend", "cpu"], "does not exist"),
        (&["render", "--width", "0", "--backend", "cpu"], "at least 1x1"),
        (&["render", "--fov", "180", "--backend", "cpu"], "--fov"),
        (&["render", "--eye", "1,2,3", "--target", "1,2,3", "--backend", "cpu"], "same point"),
        (&["render", "--up", "0,0,1", "--eye", "0,0,0", "--target", "0,0,5", "--backend", "cpu"], "parallel"),
        (&["render", "--spp", "0", "--backend", "cpu"], "--spp"),
        (&["render", "--integrator", "nope"], "nope"),
    ];
    for (args, needle) in cases {
        let o = runner(args);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains(needle), "{args:?}: stderr lacks '{needle}':\n{err}");
        assert!(!err.contains("panicked"), "{args:?} panicked:\n{err}");
    }
}

/// `RUNNER_LOG` turns on the log (wgpu's Vulkan backend included); a bad level is an error.
#[test]
fn runner_log_prints_the_log_and_rejects_unknown_levels() {
    let out = out_path("log.png");
    let run = |level: &str| {
        Command::new(env!("CARGO_BIN_EXE_runner"))
            .args(["render", "--backend", "cpu", "--width", "8", "--height", "8", "--spp", "1", "--out"])
            .arg(&out)
            .env("RUNNER_LOG", level)
            .output()
            .unwrap()
    };
    let o = run("loud");
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("RUNNER_LOG='loud' is not a log level"), "{}", stderr(&o));
    let o = run("debug");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("[DEBUG "), "no log lines:\n{}", stderr(&o));
}

/// `bench` counts one frame's rays and times the frames: on a plane that fills the view
/// every camera sample hits and casts all its AO rays, so a frame traces exactly
/// w·h·spp·(1 + ao-rays) rays; rays/s is that over the median frame time.
#[test]
fn bench_counts_the_rays_of_one_frame() {
    let plane = out_path("bench_plane.obj");
    std::fs::write(&plane, "v -1000 0 -1000\nv 1000 0 -1000\nv 1000 0 1000\nv -1000 0 1000\nf 1 3 2\nf 1 4 3\n").unwrap();
    let o = runner(&[
        "bench", "--scene", plane.to_str().unwrap(), "--eye", "0,5,0", "--target", "0,0,0.001", "--backend", "cpu",
        "--width", "32", "--height", "24", "--spp", "2", "--ao-rays", "3", "--runs", "3", "--warmup", "0", "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json = String::from_utf8_lossy(&o.stdout).into_owned();
    let field = |name: &str| -> f64 {
        let at = json.find(&format!("\"{name}\":")).unwrap_or_else(|| panic!("no {name} in {json}"));
        let rest = &json[at + name.len() + 3..];
        rest[..rest.find([',', '}']).unwrap()].parse().unwrap()
    };
    assert_eq!(field("rays_per_frame"), (32 * 24 * 2 * (1 + 3)) as f64);
    let (min, median) = (field("frame_ms_min"), field("frame_ms_median"));
    assert!(0.0 < min && min <= median, "{json}");
    // Two passes of one sample each per frame.
    assert!(field("pass_ms_min") <= median / 2.0 + 1e-3, "{json}");
    let rate = field("rays_per_second");
    assert!((rate - 6144.0 / (median * 1e-3)).abs() < 1e-3 * rate, "{json}");

    for bad in ["--warmup=-1", "--warmup=nan", "--runs=0"] {
        let o = runner(&["bench", "--backend", "cpu", "--width", "8", "--height", "8", bad]);
        assert_eq!(o.status.code(), Some(1), "{bad}");
        assert!(stderr(&o).contains("error:") && !stderr(&o).contains("panicked"), "{bad}: {}", stderr(&o));
    }
}
