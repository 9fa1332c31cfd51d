//! The interactive viewer under a virtual display (Xvfb; software Vulkan in CI): it opens
//! a window, renders frames, saves a screenshot, and the screenshot matches `render` of the
//! same camera and sample count (the same kernels draw the same random numbers).
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

struct Xvfb(Child);

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Start Xvfb on a free display; `-displayfd` prints its number once it accepts clients,
/// so concurrent test runs never collide and nothing races the server's start.
fn start_xvfb() -> (Xvfb, String) {
    let mut child = Command::new("Xvfb")
        .args(["-displayfd", "1", "-screen", "0", "320x240x24", "-nolisten", "tcp"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("Xvfb runs the viewer test: apt-get install xvfb");
    let mut line = String::new();
    let stdout = child.stdout.take().unwrap();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line).unwrap();
    let n: u32 = line.trim().parse().unwrap_or_else(|_| panic!("Xvfb did not report a display: '{line}'"));
    (Xvfb(child), format!(":{n}"))
}

fn runner(args: &[&str], display: Option<&str>) -> std::process::Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_runner"));
    cmd.args(args).env("XDG_RUNTIME_DIR", std::env::temp_dir()).env_remove("WAYLAND_DISPLAY");
    match display {
        Some(d) => cmd.env("DISPLAY", d),
        None => cmd.env_remove("DISPLAY"),
    };
    cmd.output().expect("runner runs")
}

#[test]
fn viewer_window_renders_what_render_renders() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let shot = dir.join("viewer_shot.png");
    let reference = dir.join("viewer_reference.exr");
    let _ = std::fs::remove_file(&shot);
    let (_x, display) = start_xvfb();
    let display = display.as_str();
    let common = ["--integrator", "nee", "--width", "64", "--height", "48", "--seed", "5"];
    let mut view = vec!["view", "--exit-after", "6", "--screenshot", shot.to_str().unwrap()];
    view.extend(common);
    let o = runner(&view, Some(display));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "viewer failed:\n{err}");
    let mut render = vec!["render", "--backend", "gpu", "--spp", "6", "--out", reference.to_str().unwrap()];
    render.extend(common);
    let o = runner(&render, None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let a = runner::output::read_image(&shot.with_extension("exr")).unwrap();
    let b = runner::output::read_image(&reference).unwrap();
    assert!(a.mean().max_element() > 0.01, "blank screenshot");
    let e = runner::output::compare(&a, &b).unwrap();
    assert!(e.identical > 0.97, "viewer and render differ: {e:?}");
}

#[test]
fn viewer_without_a_display_fails_cleanly() {
    let o = runner(&["view", "--width", "32", "--height", "32", "--exit-after", "1"], None);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("error:") && err.contains("display"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}
