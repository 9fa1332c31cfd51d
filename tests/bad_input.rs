//! Bad input never crashes, hangs or lies: one clear line on stderr and a non-zero exit,
//! through the real binary. Also: determinism and finite output on extreme scenes.
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn runner(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_runner"));
    cmd.args(args).env("XDG_RUNTIME_DIR", std::env::temp_dir());
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("runner binary runs")
}

fn dir() -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("bad_input");
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(name: &str, text: &[u8]) -> PathBuf {
    let p = dir().join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Render `scene` on the CPU into a scratch PNG with extra flags.
fn render_scene(scene: &Path, extra: &[&str]) -> Output {
    let out = dir().join("out.png");
    let mut args = vec![
        "render",
        "--backend",
        "cpu",
        "--width",
        "16",
        "--height",
        "16",
        "--spp",
        "1",
    ];
    args.extend([
        "--scene",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    args.extend(extra);
    runner(&args, &[])
}

/// The failure contract: non-zero exit, the message on one `error:` line, no panic.
fn assert_fails_with(o: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "succeeded; stderr:\n{err}");
    assert_eq!(o.status.code(), Some(1), "exit code; stderr:\n{err}");
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(lines.len(), 1, "expected one error line:\n{err}");
    assert!(
        lines[0].contains(needle),
        "'{needle}' not in '{}'",
        lines[0]
    );
    assert!(
        !err.contains("panicked") && !err.contains("RUST_BACKTRACE"),
        "{err}"
    );
}

const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

#[test]
fn malformed_obj_files_name_the_line() {
    let cases: &[(&str, String, &str)] = &[
        (
            "badnum.obj",
            "v 0 0 0\nv 1 zz 0\nv 0 1 0\nf 1 2 3\n".into(),
            "badnum.obj:2: bad vertex coordinate 'zz'",
        ),
        (
            "nan.obj",
            "v 0 0 0\nv 1 0 0\nv 0 NaN 0\nf 1 2 3\n".into(),
            "nan.obj:3: vertex coordinate 'NaN' is not a finite number",
        ),
        (
            "inf.obj",
            "v inf 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".into(),
            "inf.obj:1: vertex coordinate 'inf' is not a finite number",
        ),
        (
            "short.obj",
            "v 0 0\n".into(),
            "short.obj:1: vertex needs 3 coordinates",
        ),
        (
            "eight.obj",
            "v 0 0 0\nv 1 0 0 1 1 1 1 1\nv 0 1 0\nf 1 2 3\n".into(),
            "eight.obj:2: vertex has 8 numbers; expected 3",
        ),
        (
            "five.obj",
            "v 0 0 0 1 1\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".into(),
            "five.obj:1: vertex has 5 numbers",
        ),
        (
            "weight0.obj",
            "v 0 0 0\nv 1 0 0 0\nv 0 1 0\nf 1 2 3\n".into(),
            "weight0.obj:2: vertex weight 0 leaves no finite position",
        ),
        (
            "weightnan.obj",
            "v 0 0 0\nv 1 0 0 nan\nv 0 1 0\nf 1 2 3\n".into(),
            "weightnan.obj:2: vertex weight 'nan' is not a finite number",
        ),
        (
            "weighttiny.obj",
            "v 0 0 0\nv 1e30 0 0 1e-30\nv 0 1 0\nf 1 2 3\n".into(),
            "weighttiny.obj:2: vertex weight 1e-30 leaves no finite position",
        ),
        (
            "colour.obj",
            "v 0 0 0 1 x 1\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".into(),
            "colour.obj:1: vertex colour 'x' is not a finite number",
        ),
        (
            "oob.obj",
            format!("{TRI}f 1 2 9\n"),
            "oob.obj:4: face index 9 is out of range (3 vertices so far)",
        ),
        (
            "zero.obj",
            format!("{TRI}f 0 1 2\n"),
            "zero.obj:4: face index 0",
        ),
        (
            "negoob.obj",
            format!("{TRI}f -1 -2 -4\n"),
            "negoob.obj:4: face index -4 is out of range",
        ),
        (
            "two.obj",
            format!("{TRI}f 1 2\n"),
            "two.obj:4: face has 2 vertices",
        ),
        (
            "badidx.obj",
            format!("{TRI}f 1 2 three\n"),
            "badidx.obj:4: bad face index 'three'",
        ),
        ("empty.obj", String::new(), "the scene has no triangles"),
        ("points.obj", TRI.into(), "the scene has no triangles"),
        (
            "allflat.obj",
            "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n".into(),
            "the scene has no triangles",
        ),
    ];
    for (name, text, needle) in cases {
        let o = render_scene(&write(name, text.as_bytes()), &[]);
        assert_fails_with(&o, needle);
    }
}

#[test]
fn files_that_are_not_obj_or_do_not_exist() {
    let noise: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    assert_fails_with(
        &render_scene(&write("noise.obj", &noise), &[]),
        "no triangles",
    );
    assert_fails_with(
        &render_scene(Path::new("/nonexistent/x.obj"), &[]),
        "cannot read scene '/nonexistent/x.obj'",
    );
    assert_fails_with(&render_scene(&dir(), &[]), "cannot read scene");
    assert_fails_with(
        &render_scene(Path::new("no-such-scene"), &[]),
        "no built-in scene of that name",
    );
}

#[test]
fn missing_or_broken_mtl_warns_and_uses_grey() {
    for (name, mtl) in [
        ("nomtl.obj", None),
        ("badmtl.obj", Some("newmtl m\nKd 1 x\n")),
    ] {
        if let Some(text) = mtl {
            write("bad.mtl", text.as_bytes());
        }
        let lib = if mtl.is_some() {
            "bad.mtl"
        } else {
            "missing.mtl"
        };
        let obj = write(
            name,
            format!("mtllib {lib}\n{TRI}usemtl m\nf 1 2 3\n").as_bytes(),
        );
        let o = render_scene(&obj, &["--integrator", "ao"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert!(
            err.contains("warning: materials of") && err.contains("grey default"),
            "{err}"
        );
    }
}

#[test]
fn degenerate_triangles_are_dropped_and_counted() {
    let obj = write(
        "degen.obj",
        format!("{TRI}v 5 0 0\nf 1 2 3\nf 1 2 4\nf 2 2 3\n").as_bytes(),
    );
    let o = render_scene(&obj, &["--integrator", "ao"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("dropped 2 degenerate triangle(s)"), "{err}");
    assert!(err.contains("1 triangles"), "{err}");
}

#[test]
fn a_scene_without_emitters() {
    let obj = write("dark.obj", format!("{TRI}f 1 2 3\n").as_bytes());
    for i in ["pt", "nee", "mis", "ris", "restir"] {
        // A black sky asked for: nothing would light it.
        assert_fails_with(
            &render_scene(&obj, &["--integrator", i, "--sky", "0,0,0"]),
            "no emitters",
        );
    }
    // Nothing asked for: the built-in sky lights it (tests/environment.rs), with a note.
    let o = render_scene(&obj, &["--integrator", "nee"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("built-in sky"), "{err}");
    // Lit by the sky instead: a warning, and a real image.
    let o = render_scene(
        &obj,
        &[
            "--integrator",
            "nee",
            "--sky",
            "1,1,1",
            "--eye",
            "0.2,0.2,2",
            "--target",
            "0.2,0.2,0",
        ],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && err.contains("warning: the scene has no emitters"),
        "{err}"
    );
    // AO needs no lights.
    assert!(render_scene(&obj, &["--integrator", "ao"]).status.success());
}

#[test]
fn absurd_or_contradictory_options() {
    let cornell = Path::new("cornell-box");
    let cases: &[(&[&str], &str)] = &[
        (&["--width", "0"], "at least 1x1"),
        (&["--height", "100000"], "too large"),
        (&["--width", "20000", "--height", "20000"], "too large"),
        (&["--spp", "0"], "--spp must be between 1 and"),
        (&["--spp", "4294967295"], "--spp must be between 1 and"),
        (&["--ao-rays", "0"], "--ao-rays"),
        (&["--fov", "0"], "--fov must be in (0, 180)"),
        (&["--fov", "-5"], "--fov must be in (0, 180)"),
        (&["--fov", "180"], "--fov must be in (0, 180)"),
        (&["--eye", "1,2,3", "--target", "1,2,3"], "same point"),
        (&["--eye", "278,273,-1e20"], "too far apart"),
        (
            &["--eye", "0,0,0", "--target", "0,5,0", "--up", "0,1,0"],
            "parallel",
        ),
        (&["--up", "0,0,0"], "--up"),
        (&["--eye", "1,2"], "expected X,Y,Z"),
        (&["--eye", "1,nan,2"], "not a finite number"),
        (&["--max-depth", "0"], "--max-depth"),
        (&["--candidates", "0"], "--candidates"),
        (&["--spatial-neighbours", "99"], "--spatial-neighbours"),
        (
            &["--disocclusion-neighbours", "17"],
            "--disocclusion-neighbours",
        ),
        (&["--frames", "0"], "--frames"),
        (&["--integrator", "photon-mapping"], "photon-mapping"),
        (&["--bogus-flag"], "--bogus-flag"),
    ];
    let out = dir().join("absurd.png");
    for (extra, needle) in cases {
        // Only the flag under test: every case must fail before any rendering.
        let mut args = vec![
            "render",
            "--backend",
            "cpu",
            "--scene",
            cornell.to_str().unwrap(),
        ];
        args.extend(["--out", out.to_str().unwrap()]);
        args.extend(*extra);
        let o = runner(&args, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{extra:?} succeeded");
        assert!(err.contains(needle), "{extra:?}: '{needle}' not in:\n{err}");
        assert!(!err.contains("panicked"), "{extra:?}:\n{err}");
    }
}

#[test]
fn unwritable_or_unknown_outputs_fail_before_rendering() {
    let base = [
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
    ];
    // A directory that is named like an image (the render would be lost at its end).
    let folder = dir().join("folder.png");
    std::fs::create_dir_all(&folder).unwrap();
    for (out, needle) in [
        ("/nonexistent-dir/x.png", "does not exist"),
        ("picture.jpg", "unknown image format"),
        ("noext", "unknown image format"),
        (folder.to_str().unwrap(), "is a directory"),
    ] {
        let mut args = base.to_vec();
        args.push(out);
        let o = runner(&args, &[]);
        assert_fails_with(&o, needle);
        // Before rendering: no scene was loaded.
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!err.contains("triangles"), "{err}");
    }
}

#[test]
fn no_vulkan_adapter_falls_back_or_fails_as_asked() {
    // Point the Vulkan loader at no driver at all.
    let env = [
        ("VK_ICD_FILENAMES", "/nonexistent.json"),
        ("VK_DRIVER_FILES", "/nonexistent.json"),
    ];
    let out = dir().join("fallback.png");
    let args = [
        "render",
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "1",
        "--out",
        out.to_str().unwrap(),
    ];
    let o = runner(&args, &env);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("note: no Vulkan adapter found; rendering on the CPU backend"),
        "{err}"
    );
    let mut gpu = args.to_vec();
    gpu.extend(["--backend", "gpu"]);
    assert_fails_with(&runner(&gpu, &env), "no Vulkan adapter");
}

#[test]
fn buffer_limits_are_checked_with_numbers() {
    let limits = wgpu::Limits {
        max_storage_buffer_binding_size: 1000,
        max_buffer_size: 4000,
        ..Default::default()
    };
    assert!(runner::gpu::check_buffer_size(&limits, "the triangle buffer", 1000).is_ok());
    let e = runner::gpu::check_buffer_size(&limits, "the triangle buffer", 1048).unwrap_err();
    assert!(
        e.0.contains("the triangle buffer needs 1048 bytes")
            && e.0.contains("limit of 1000")
            && e.0.contains("by 48"),
        "{e}"
    );
}

#[test]
fn same_command_and_seed_give_identical_bytes() {
    for (integrator, backend) in [("mis", "cpu"), ("restir", "cpu"), ("nee", "gpu")] {
        let files: Vec<Vec<u8>> = (0..2)
            .map(|k| {
                let out = dir().join(format!("det_{integrator}_{backend}_{k}.exr"));
                let o = runner(
                    &[
                        "render",
                        "--integrator",
                        integrator,
                        "--backend",
                        backend,
                        "--width",
                        "24",
                        "--height",
                        "16",
                        "--spp",
                        "3",
                        "--seed",
                        "42",
                        "--out",
                        out.to_str().unwrap(),
                    ],
                    &[],
                );
                assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
                std::fs::read(&out).unwrap()
            })
            .collect();
        assert!(
            files[0] == files[1],
            "{integrator} on {backend}: outputs differ"
        );
    }
}

#[test]
fn extreme_emission_and_tiny_triangles_stay_finite() {
    // A 1e20 emitter (the largest radiance allowed), a 1e-6-sized triangle fan, huge and tiny
    // geometry in one scene.
    let mut obj = String::from(
        "mtllib x.mtl\nusemtl hot\nv -1 2 -1\nv 1 2 -1\nv 0 2 1\nf 1 3 2\nusemtl grey\n",
    );
    obj.push_str("v -50 0 -50\nv 50 0 -50\nv 0 0 50\nf 4 6 5\n");
    let mut k = 7;
    for i in 0..50 {
        let x = i as f32 * 1e-6;
        obj.push_str(&format!(
            "v {x} 0.5 0\nv {} 0.5 0\nv {x} 0.500001 1e-7\nf {k} {} {}\n",
            x + 1e-6,
            k + 1,
            k + 2
        ));
        k += 3;
    }
    write(
        "x.mtl",
        b"newmtl hot\nKd 0.9 0.9 0.9\nKe 1e20 1e20 1e20\nnewmtl grey\nKd 0.99 0.99 0.99\n",
    );
    let scene = write("extreme.obj", obj.as_bytes());
    for i in ["pt", "nee", "mis", "ris", "restir", "ao"] {
        let out = dir().join(format!("extreme_{i}.exr"));
        let o = runner(
            &[
                "render",
                "--scene",
                scene.to_str().unwrap(),
                "--integrator",
                i,
                "--backend",
                "cpu",
                "--width",
                "24",
                "--height",
                "24",
                "--spp",
                "4",
                "--eye",
                "0,1,4",
                "--target",
                "0,0.5,0",
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert!(
            o.status.success(),
            "{i}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let img = image::open(&out).unwrap().to_rgb32f();
        assert!(
            img.pixels().all(|p| p.0.iter().all(|c| c.is_finite())),
            "{i}: non-finite pixel"
        );
    }
}

/// Output is never lost or reported written when it was not: a write error (a full device
/// behind a symbolic link) is reported; a failing run leaves an existing output untouched
/// and creates no --out-dir; the scene file itself and generate's MTL are refused as --out.
#[test]
fn output_is_complete_or_untouched_and_failures_are_reported() {
    let good = dir().join("keep.png");
    let base = [
        "render",
        "--backend",
        "cpu",
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "1",
        "--integrator",
        "ao",
    ];
    let mut args = base.to_vec();
    args.extend(["--out", good.to_str().unwrap()]);
    assert!(runner(&args, &[]).status.success());
    let before = std::fs::read(&good).unwrap();
    assert!(image::load_from_memory(&before).is_ok(), "a complete PNG");

    // A PNG of a few hundred bytes written into a full device: reported, not "wrote".
    if Path::new("/dev/full").exists() {
        let link = dir().join("full.png");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink("/dev/full", &link).unwrap();
        let mut args = base.to_vec();
        args.extend(["--out", link.to_str().unwrap()]);
        let o = runner(&args, &[]);
        assert_fails_with(&o, "cannot write");
        assert!(!String::from_utf8_lossy(&o.stderr).contains("wrote "));
    }

    // A run that fails on its scene leaves the old output and creates no --out-dir.
    let bad = write("fails.obj", b"v 0 0 0\nf 1 2 3\n");
    let frames = dir().join("never_created");
    let _ = std::fs::remove_dir_all(&frames);
    let mut args = base.to_vec();
    args.extend([
        "--scene",
        bad.to_str().unwrap(),
        "--out",
        good.to_str().unwrap(),
        "--out-dir",
        frames.to_str().unwrap(),
    ]);
    assert_fails_with(&runner(&args, &[]), "fails.obj");
    assert_eq!(
        std::fs::read(&good).unwrap(),
        before,
        "the old output must be untouched"
    );
    assert!(!frames.exists(), "--out-dir created by a failed run");
    // No temporary files are left beside the output. Only this test's output counts: tests
    // run in parallel in the same folder, and another test's write may be in flight.
    let leftovers: Vec<_> = std::fs::read_dir(dir())
        .unwrap()
        .flatten()
        .filter(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with(".keep.png.partial-")
        })
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");

    // The scene itself as --out, --out-dir that is a file, generate --out x.mtl.
    let scene = write("self.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let self_png = dir().join("self.png");
    std::fs::copy(&scene, &self_png).unwrap();
    let mut args = base.to_vec();
    args.extend([
        "--scene",
        self_png.to_str().unwrap(),
        "--out",
        self_png.to_str().unwrap(),
    ]);
    assert_fails_with(&runner(&args, &[]), "is the scene file itself");
    let mut args = base.to_vec();
    args.extend([
        "--out-dir",
        scene.to_str().unwrap(),
        "--out",
        good.to_str().unwrap(),
    ]);
    assert_fails_with(&runner(&args, &[]), "is not a directory");
    let mtl = dir().join("scene.mtl");
    assert_fails_with(
        &runner(
            &["generate", "many-lights", "--out", mtl.to_str().unwrap()],
            &[],
        ),
        "names the MTL file",
    );
}

/// Inputs that are not regular files (a FIFO, a directory) end at once with one line,
/// instead of blocking or reading forever; so does a reader that goes away.
#[test]
fn special_files_and_closed_pipes() {
    let fifo = dir().join("scene_fifo.obj");
    let _ = std::fs::remove_file(&fifo);
    let made = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    if made {
        assert_fails_with(
            &render_scene(&fifo, &["--integrator", "ao"]),
            "not a regular file",
        );
    }
    // `compare ... | head -0`: the reader is gone before we print.
    let img = dir().join("pipe.exr");
    assert!(runner(
        &[
            "render",
            "--backend",
            "cpu",
            "--width",
            "4",
            "--height",
            "4",
            "--spp",
            "1",
            "--out",
            img.to_str().unwrap()
        ],
        &[]
    )
    .status
    .success());
    let mut child = Command::new(env!("CARGO_BIN_EXE_runner"))
        .args(["compare", img.to_str().unwrap(), img.to_str().unwrap()])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // close the read end
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !err.contains("panicked") && !err.contains("internal error"),
        "{err}"
    );
    assert!(
        matches!(o.status.code(), Some(0) | Some(141)),
        "{:?}: {err}",
        o.status
    );
}

/// Absurd counts are refused before any work starts.
#[test]
fn unbounded_work_is_refused() {
    for (args, needle) in [
        (
            &["render", "--backend", "cpu", "--candidates", "4294967295"][..],
            "--candidates",
        ),
        (
            &["bench", "--backend", "cpu", "--runs", "4294967295"][..],
            "--runs",
        ),
        (
            &[
                "render",
                "--backend",
                "cpu",
                "--frames",
                "4294967295",
                "--spp",
                "2",
            ][..],
            "2^32 samples",
        ),
    ] {
        assert_fails_with(&runner(args, &[]), needle);
    }
}

/// `compare` refuses images with NaN or infinite pixels instead of printing "rmse NaN".
#[test]
fn compare_refuses_non_finite_images() {
    let good = dir().join("finite.exr");
    let bad = dir().join("nan.exr");
    let mut img = image::Rgb32FImage::from_pixel(4, 3, image::Rgb([0.5, 0.5, 0.5]));
    img.save_with_format(&good, image::ImageFormat::OpenExr)
        .unwrap();
    img.put_pixel(2, 1, image::Rgb([f32::NAN, 0.0, f32::INFINITY]));
    img.save_with_format(&bad, image::ImageFormat::OpenExr)
        .unwrap();
    let o = runner(
        &["compare", bad.to_str().unwrap(), good.to_str().unwrap()],
        &[],
    );
    assert_fails_with(&o, "non-finite pixel at (2, 1)");
    let o = runner(
        &["compare", good.to_str().unwrap(), bad.to_str().unwrap()],
        &[],
    );
    assert_fails_with(&o, "the reference has a non-finite pixel");
}

/// Files people have: a byte-order mark, tabs, comments after data — they load; texture
/// and normal indices out of range (or near the i64 limits) are errors with line numbers,
/// not panics inside the OBJ reader.
#[test]
fn obj_quirks_load_and_bad_texcoord_or_normal_indices_name_the_line() {
    let mtl = write(
        "quirks.mtl",
        b"\xEF\xBB\xBFnewmtl\tlamp # a lamp\nKd 0.5 0.5 0.5\nKe 4 4 4 # bright\n",
    );
    let _ = mtl;
    let obj = "\u{feff}mtllib quirks.mtl\nv 0 0 0 # origin\nv\t1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nusemtl\tlamp\nf 1/1/1 2/1/1 3/1/1 # the lamp\n";
    let o = render_scene(
        &write("quirks.obj", obj.as_bytes()),
        &["--eye", "0.2,0.2,2", "--target", "0.2,0.2,0"],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("3 triangles (1 emissive)") || err.contains("1 triangles (1 emissive)"),
        "the lamp's Ke was lost: {err}"
    );

    let base = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n";
    for (face, needle) in [
        ("f 1/-5 2/-5 3/-5", "quirk1.obj:6: texture coordinate index -5 is out of range (1 texture coordinates so far)"),
        ("f 1//-9 2//1 3//1", "quirk2.obj:6: normal index -9 is out of range"),
        ("f 1//9223372036854775807 2//1 3//1", "normal index 9223372036854775807 is out of range"),
        ("f 1/-9223372036854775808 2/1 3/1", "texture coordinate index -9223372036854775808 is out of range"),
        ("f 1/x 2/1 3/1", "bad texture coordinate index"),
    ]
    .iter()
    .enumerate()
    .map(|(i, (f, n))| (format!("quirk{}.obj", i + 1), f, n))
    .map(|(name, f, n)| (write(&name, format!("{base}{f}\n").as_bytes()), *n))
    .collect::<Vec<_>>()
    {
        assert_fails_with(&render_scene(&face, &["--integrator", "ao"]), needle);
    }
}

/// Values that overflow are errors, not black or infinite images: a radiance of 1e39 (read
/// as infinity) or inf in the MTL, with its line; a sky near f32's limit; a camera line
/// without eye and target.
#[test]
fn overflowing_values_are_errors_with_their_line() {
    for (i, ke) in ["1e39 1 1", "inf 0 0", "1 nan 1"].iter().enumerate() {
        let mtl_name = format!("hot{i}.mtl");
        write(
            &mtl_name,
            format!("newmtl m\nKd 0.5 0.5 0.5\nKe {ke}\n").as_bytes(),
        );
        let obj = write(
            &format!("hot{i}.obj"),
            format!("mtllib {mtl_name}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n").as_bytes(),
        );
        assert_fails_with(&render_scene(&obj, &[]), &format!("{mtl_name}:3: Ke value"));
    }
    let tri = write("plain.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert_fails_with(
        &render_scene(&tri, &["--sky", "3e38,3e38,3e38"]),
        "--sky must be between 0 and",
    );
    let bare = write(
        "bare_camera.obj",
        b"# camera:\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    assert_fails_with(
        &render_scene(&bare, &["--integrator", "ao"]),
        "bare_camera.obj:1: the camera line needs",
    );
    assert_fails_with(
        &render_scene(
            &tri,
            &[
                "--integrator",
                "ao",
                "--eye",
                "3e38,273,0",
                "--target",
                "-3e38,273,0",
            ],
        ),
        "not finite",
    );
}

/// Small things: a `usemtl` no MTL defines is named in a warning; typo'd built-in counts, a
/// NaN exposure and a missing subcommand are errors.
#[test]
fn unknown_materials_warn_and_small_mistakes_are_errors() {
    write("known.mtl", b"newmtl lamp\nKe 1 1 1\n");
    let obj = write("unknown_mtl.obj", b"mtllib known.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl lamp\nf 1 2 3\nusemtl nosuch\nf 1 3 2\n");
    let o = render_scene(&obj, &["--eye", "0.2,0.2,2", "--target", "0.2,0.2,0"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("unknown_mtl.obj:7: usemtl 'nosuch' names no material"),
        "{err}"
    );
    assert!(!err.contains("'lamp' names no"), "{err}");
    for name in ["rocks-0.5", "rocks-1e-300"] {
        assert_fails_with(
            &runner(&["render", "--backend", "cpu", "--scene", name], &[]),
            "bad triangle count",
        );
    }
    assert_fails_with(&runner(&["view", "--exposure", "NaN"], &[]), "--exposure");
    let o = runner(&[], &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).starts_with("error:"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Degeneracy is scale-free: a ground of edge 2e10 and a triangle of area ~1e-30 are
/// triangles (their area once overflowed or underflowed to "zero area"), collinear
/// vertices are not.
#[test]
fn huge_and_tiny_triangles_are_kept_and_only_flat_ones_dropped() {
    let obj = "v -1e10 0 -1e10\nv 1e10 0 -1e10\nv 0 0 1e10\nf 1 3 2\n\
               v 0 1 0\nv 1e-15 1 0\nv 0 1.000001 1e-15\nf 4 5 6\n\
               v 0 2 0\nv 1 2 0\nv 2 2 0\nf 7 8 9\n";
    let o = render_scene(
        &write("scales.obj", obj.as_bytes()),
        &["--integrator", "ao", "--eye", "0,5,5", "--target", "0,0,0"],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("dropped 1 degenerate triangle(s)") && err.contains("2 triangles"),
        "{err}"
    );
}

/// `mtllib a.mtl b.mtl` loads both files; an MTL named by a path that does not exist is
/// found by its base name next to the OBJ (as Blender exports it); one found nowhere is a
/// warning that names the paths tried.
#[test]
fn several_mtl_files_and_mtl_found_by_base_name() {
    write("first.mtl", b"newmtl a\nKd 0.2 0.2 0.2\n");
    write("second.mtl", b"newmtl lamp\nKe 2 2 2\n");
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let view = ["--eye", "0.2,0.2,2", "--target", "0.2,0.2,0"];
    let obj = write(
        "two_libs.obj",
        format!("mtllib first.mtl second.mtl\n{tri}usemtl a\nf 1 2 3\nusemtl lamp\nf 1 2 3\n")
            .as_bytes(),
    );
    let o = render_scene(&obj, &view);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && err.contains("(1 emissive)") && !err.contains("warning"),
        "{err}"
    );

    let obj = write(
        "elsewhere.obj",
        format!("mtllib C:\\exports\\textures\\second.mtl\n{tri}usemtl lamp\nf 1 2 3\n").as_bytes(),
    );
    let o = render_scene(&obj, &view);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("(1 emissive)"), "{err}");

    let obj = write(
        "missing_lib.obj",
        format!("mtllib lost/nowhere.mtl\n{tri}f 1 2 3\n").as_bytes(),
    );
    let o = render_scene(&obj, &["--integrator", "ao"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("mtllib 'lost/nowhere.mtl' not found (tried '")
            && err.contains("nowhere.mtl'"),
        "{err}"
    );
}

/// Under a file-size limit (`ulimit -f`) the write fails: the run says so with one line and
/// a non-zero exit, and the output that was there stays whole.
#[test]
fn a_file_size_limit_is_reported_and_keeps_the_old_output() {
    let out = dir().join("limited.png");
    let render = |size: &str| -> Vec<String> {
        [
            "render",
            "--backend",
            "cpu",
            "--integrator",
            "ao",
            "--spp",
            "1",
            "--width",
            size,
            "--height",
            size,
            "--out",
        ]
        .iter()
        .map(|s| s.to_string())
        .chain([out.to_str().unwrap().to_string()])
        .collect()
    };
    let small: Vec<String> = render("8");
    assert!(
        runner(&small.iter().map(String::as_str).collect::<Vec<_>>(), &[])
            .status
            .success()
    );
    let before = std::fs::read(&out).unwrap();
    // A 64x64 PNG of AO noise is well over the limit of one 1 KiB block (sh's ulimit -f).
    let o = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -f 1 && exec \"$0\" {}",
            render("64").join(" ")
        ))
        .arg(env!("CARGO_BIN_EXE_runner"))
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    assert_fails_with(&o, "cannot write");
    assert_eq!(
        std::fs::read(&out).unwrap(),
        before,
        "the old output must be untouched"
    );
}

/// A scene that cannot fit in the memory this process may use is refused at once with the
/// numbers (under `ulimit -v`), instead of an abort in an allocation.
#[test]
fn scenes_too_large_for_memory_are_refused_with_numbers() {
    let obj = dir().join("never.obj");
    for args in [
        format!("generate rocks-50m --out {}", obj.display()),
        format!(
            "render --backend cpu --scene rocks-20m --out {}",
            dir().join("never.png").display()
        ),
        // Within PLOC's estimate (1.6 GB), not the SBVH's (2.4 GB).
        format!(
            "render --backend cpu --scene rocks-5m --bvh-quality high --out {}",
            dir().join("never.png").display()
        ),
    ] {
        let o = Command::new("sh")
            .arg("-c")
            .arg(format!("ulimit -v 2000000 && exec \"$0\" {args}"))
            .arg(env!("CARGO_BIN_EXE_runner"))
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap();
        assert_fails_with(&o, "GB of memory, but only");
    }
    assert!(!obj.exists());
}

/// A glTF of one triangle's 48 bytes whose POSITION is a sparse accessor without a buffer
/// view (zeros but for the triangle) of `vertices` vertices, its mesh placed by `copies`
/// nodes: a small file that names as many triangles as it likes.
fn gltf_naming_many_triangles(vertices: u64, copies: usize) -> String {
    // Three f32 corners and the u32 indices 0, 1, 2.
    const TRIANGLE: &str = "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAEAAAACAAAA";
    let nodes = vec![r#"{"mesh":0}"#; copies].join(",");
    let roots: Vec<String> = (0..copies).map(|i| i.to_string()).collect();
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[{}]}}],"nodes":[{nodes}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
"accessors":[{{"componentType":5126,"count":{vertices},"type":"VEC3","min":[0,0,0],"max":[1,1,0],
"sparse":{{"count":3,"indices":{{"bufferView":1,"componentType":5125}},"values":{{"bufferView":0}}}}}}],
"bufferViews":[{{"buffer":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":12}}],
"buffers":[{{"byteLength":48,"uri":"data:application/octet-stream;base64,{TRIANGLE}"}}]}}"#,
        roots.join(",")
    )
}

/// A glTF file of a few bytes that names billions of vertices (a sparse accessor's count)
/// or a mesh placed by many nodes is refused with the numbers before any geometry is read;
/// it was an abort in an allocation (24 GB for the first), or the machine's memory.
#[test]
fn small_gltf_files_that_name_huge_geometry_are_refused_with_numbers() {
    // The same file naming few vertices loads: the test's file is a valid scene.
    let small = write(
        "sparse_small.gltf",
        gltf_naming_many_triangles(3, 2).as_bytes(),
    );
    let o = render_scene(&small, &["--integrator", "ao"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // 2·10⁹ vertices in one accessor; 200 nodes each placing 100k triangles (20M).
    for (file, vertices, copies) in [
        ("sparse_huge.gltf", 2_000_000_000, 1),
        ("instanced_huge.gltf", 300_000, 200),
    ] {
        let path = write(
            file,
            gltf_naming_many_triangles(vertices, copies).as_bytes(),
        );
        let o = Command::new("sh")
            .arg("-c")
            .arg(
                "ulimit -v 2000000 && exec \"$0\" render --backend cpu --scene \"$1\" --out \"$2\"",
            )
            .arg(env!("CARGO_BIN_EXE_runner"))
            .arg(&path)
            .arg(dir().join("never.png"))
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap();
        assert_fails_with(&o, "triangles) needs about");
    }
}

#[test]
fn stacks_of_duplicate_triangles_load() {
    // 20,000 copies of one triangle (exporters write such stacks): their BVH was 2,857
    // levels deep and took 16 s to build before being refused. The duplicates are dropped
    // with a warning, and the scene renders.
    let mut text = String::from(TRI);
    for _ in 0..20_000 {
        text += "f 1 2 3\n";
    }
    let obj = write("duplicates.obj", text.as_bytes());
    let o = render_scene(&obj, &["--integrator", "ao"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("dropped 19999 duplicate triangle(s)"), "{err}");
}

#[test]
fn stacks_of_distinct_overlapping_triangles_load() {
    // 20,000 different triangles all spanning one box (the apexes move along an edge): not
    // duplicates, and PLOC's build was quadratic in them (7-15 s for 20,000, 40-100 s for
    // 50,000). Their boxes cover the scene's 20,000 times over, so the loader builds the
    // balanced tree at once and says so.
    let mut text = String::from("v 0 0 0\nv 1 0 0\n");
    for i in 0..20_000 {
        text += &format!("v {} 1 0\n", i as f32 / 20_000.0);
    }
    for i in 0..20_000 {
        text += &format!("f 1 2 {}\n", i + 3);
    }
    let obj = write("overlapping.obj", text.as_bytes());
    let o = render_scene(&obj, &["--integrator", "ao"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("built a balanced one"), "{err}");
}

#[test]
fn usemtl_before_mtllib_still_finds_its_material() {
    // The format does not order the two; tobj resolves names as it reads, so this face
    // used to come out grey without a word.
    let scene = runner::scene::parse_obj_text(
        "late_mtllib.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\nmtllib late.mtl\n",
        Some("newmtl red\nKd 0.9 0.1 0.1\n"),
    )
    .unwrap();
    let t = scene.triangles[0];
    assert_eq!(scene.materials[t.material as usize].albedo, [0.9, 0.1, 0.1]);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}

/// A regular polygon of `n` corners in the y = 0 plane (radius 1), then a small emitter.
fn polygon_obj(n: usize, faces: impl Fn(usize) -> String) -> String {
    let mut text = String::new();
    for i in 0..n {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        text += &format!("v {} 0 {}\n", a.cos(), a.sin());
    }
    text += &faces(n);
    text += "v -0.2 3 -0.2\nv 0.2 3 -0.2\nv 0 3 0.2\n";
    text += &format!("f {} {} {}\n", n + 1, n + 2, n + 3);
    text
}

#[test]
fn large_polygons_load_as_well_shaped_triangles() {
    // An 800-corner disk and a 1024-segment cylinder's caps (as CAD tools and Blender
    // export them) were split into fans of slivers sharing one corner, whose BVH was 33–45
    // levels deep and refused as "pathological". They load, cover exactly the polygon, and
    // render.
    for n in [5, 6, 7, 64, 800, 4096] {
        let text = polygon_obj(n, |n| {
            format!(
                "f {}\n",
                (1..=n).map(|i| i.to_string()).collect::<Vec<_>>().join(" ")
            )
        });
        let scene = runner::scene::parse_obj_text("disk.obj", &text, None).unwrap();
        assert_eq!(
            scene.triangle_count,
            n - 2 + 1,
            "{n}-gon: n − 2 triangles and the light"
        );
        // (The loader may reorder triangles: the disk's are those in the plane y = 0.)
        let distinct = scene.distinct_triangles();
        let disk: Vec<_> = distinct.iter().filter(|t| t.p0[1] == 0.0).collect();
        assert_eq!(disk.len(), n - 2);
        let area: f64 = disk.iter().map(|t| 0.5 * t.cross().length() as f64).sum();
        let exact = 0.5 * n as f64 * (std::f64::consts::TAU / n as f64).sin();
        assert!(
            (area - exact).abs() < 1e-5 * exact,
            "{n}-gon: area {area} vs {exact}"
        );
        // Every triangle keeps the polygon's winding (its normal points the same way).
        assert!(disk.iter().all(|t| t.cross().y < 0.0), "{n}-gon");
    }
    let disk = write(
        "disk_800.obj",
        polygon_obj(800, |n| {
            format!(
                "f {}\n",
                (1..=n).map(|i| i.to_string()).collect::<Vec<_>>().join(" ")
            )
        })
        .as_bytes(),
    );
    let o = render_scene(&disk, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The same disk written as explicit triangles fanned from one corner: the slivers stay
    // (they are the file's). The SBVH (`auto`'s build at this size) splits them into a tree
    // of ordinary depth; PLOC (`fast`) nests them too deep, and the BVH is built balanced
    // instead, with a warning.
    let fan = write(
        "fan_800.obj",
        polygon_obj(800, |n| {
            (2..n).map(|i| format!("f 1 {i} {}\n", i + 1)).collect()
        })
        .as_bytes(),
    );
    let o = render_scene(&fan, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && !err.contains("balanced"), "{err}");
    let o = render_scene(&fan, &["--bvh-quality", "fast"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("balanced"), "{err}");
    // The cylinder: 1024 quads around, a 1024-gon at each end: 2048 + 2 × 1022 triangles.
    let n = 1024;
    let mut text = String::new();
    for i in 0..n {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        text += &format!("v {} 0 {}\nv {} 1 {}\n", a.cos(), a.sin(), a.cos(), a.sin());
    }
    for i in 0..n {
        let j = (i + 1) % n;
        text += &format!(
            "f {} {} {} {}\n",
            2 * i + 1,
            2 * j + 1,
            2 * j + 2,
            2 * i + 2
        );
    }
    let cap = |k: &dyn Fn(usize) -> usize| {
        format!(
            "f {}\n",
            (0..n)
                .map(|i| k(i).to_string())
                .collect::<Vec<_>>()
                .join(" ")
        )
    };
    text += &cap(&|i| 2 * i + 1);
    text += &cap(&|i| 2 * (n - 1 - i) + 2);
    let cylinder = write("cylinder_1024.obj", text.as_bytes());
    let o = render_scene(&cylinder, &["--sky", "1,1,1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("4092 triangles"));
}

#[test]
fn coordinates_too_large_for_f32_areas_are_one_error() {
    // Finite, but a box surface area (∝ extent²) overflows f32 beyond ~1.8e19: obvhs then
    // built a corrupt BVH and panicked (fuzzer, 2.2e34). Refused with the limit named.
    let obj = write(
        "far.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 3e20\nf 1 2 3\nv 0 0 1\nv 1 0 1\nv 0 1 1\nf 4 5 6\n",
    );
    let o = render_scene(&obj, &[]);
    assert_fails_with(&o, "at most 1e15");
}
