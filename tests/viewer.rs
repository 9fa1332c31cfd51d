//! The interactive viewer under a virtual display (Xvfb; software Vulkan in CI): it opens
//! a window, renders frames, saves a screenshot, and the screenshot matches `render` of the
//! same camera and sample count (the same kernels draw the same random numbers).
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

struct Xvfb(Child);

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn start_xvfb(display: &str) -> Xvfb {
    let child = Command::new("Xvfb")
        .args([display, "-screen", "0", "320x240x24", "-nolisten", "tcp"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("Xvfb runs the viewer test: apt-get install xvfb");
    let socket = PathBuf::from(format!("/tmp/.X11-unix/X{}", &display[1..]));
    for _ in 0..100 {
        if socket.exists() {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    Xvfb(child)
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
    let display = ":93";
    let _x = start_xvfb(display);
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
