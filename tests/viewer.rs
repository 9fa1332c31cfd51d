//! The interactive viewer under a virtual display (Xvfb; software Vulkan in CI): it opens
//! a window, renders frames, saves a screenshot, and the screenshot matches `render` of the
//! same camera and sample count (the same kernels draw the same random numbers).
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// A running Xvfb; its stdout pipe stays open as long as the server runs, so a later write
/// to it cannot kill the server with SIGPIPE.
struct Xvfb(Child, #[allow(dead_code)] std::process::ChildStdout);

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// How long a fresh Xvfb may take to accept its first client.
const XVFB_READY: std::time::Duration = std::time::Duration::from_secs(20);

/// Start Xvfb on a free display; `-displayfd` prints its number, so concurrent test runs
/// never collide; then wait until a client can connect, so nothing races the server's start.
fn start_xvfb(extra: &[&str]) -> (Xvfb, String) {
    let mut child = Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "320x240x24",
            "-nolisten",
            "tcp",
        ])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("Xvfb runs the viewer test: apt-get install xvfb");
    let mut line = String::new();
    let mut stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    std::io::BufRead::read_line(&mut stdout, &mut line).unwrap();
    let n: u32 = line
        .trim()
        .parse()
        .unwrap_or_else(|_| panic!("Xvfb did not report a display: '{line}'"));
    let display = format!(":{n}");
    let deadline = std::time::Instant::now() + XVFB_READY;
    while let Err(e) = x11rb::connect(Some(&display)) {
        assert!(
            std::time::Instant::now() < deadline,
            "Xvfb on {display} accepts no client: {e}"
        );
        assert!(
            child.try_wait().unwrap().is_none(),
            "Xvfb on {display} exited"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    (Xvfb(child, stdout.into_inner()), display)
}

/// The runner binary with `args`, on X display `display` (none: no display at all).
fn runner_command(args: &[&str], display: Option<&str>) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_runner"));
    cmd.args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .env_remove("WAYLAND_DISPLAY");
    match display {
        Some(d) => cmd.env("DISPLAY", d),
        None => cmd.env_remove("DISPLAY"),
    };
    cmd
}

fn runner(args: &[&str], display: Option<&str>) -> std::process::Output {
    runner_command(args, display).output().expect("runner runs")
}

#[test]
fn viewer_renders_what_render_renders() {
    for present in ["swapchain", "copy"] {
        screenshot_matches_render(present);
    }
}

fn screenshot_matches_render(present: &str) {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let shot = dir.join(format!("viewer_shot_{present}.png"));
    let reference = dir.join("viewer_reference.exr");
    let _ = std::fs::remove_file(&shot);
    let (_x, display) = start_xvfb(&[]);
    let display = display.as_str();
    let common = [
        "--integrator",
        "nee",
        "--width",
        "64",
        "--height",
        "48",
        "--seed",
        "5",
    ];
    let mut view = vec![
        "view",
        "--present",
        present,
        "--exit-after",
        "6",
        "--screenshot",
        shot.to_str().unwrap(),
    ];
    view.extend(common);
    let o = runner(&view, Some(display));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "viewer failed:\n{err}");
    let mut render = vec![
        "render",
        "--backend",
        "gpu",
        "--spp",
        "6",
        "--out",
        reference.to_str().unwrap(),
    ];
    render.extend(common);
    let o = runner(&render, None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let a = runner::output::read_image(&shot.with_extension("exr")).unwrap();
    let b = runner::output::read_image(&reference).unwrap();
    assert!(a.mean().max_element() > 0.01, "blank screenshot");
    let e = runner::output::compare(&a, &b).unwrap();
    assert!(
        e.identical > 0.97,
        "viewer ({present}) and render differ: {e:?}"
    );
}

/// The XWD header's `file_version`.
const XWD_FILE_VERSION: usize = 7;

/// An XWD image (what `Xvfb -fbdir` keeps its screen in) as 8-bit RGB rows; None while
/// the file is not readable or its header not yet written.
fn read_xwd(path: &Path) -> Option<(usize, usize, Vec<[u8; 3]>)> {
    let bytes = std::fs::read(path).ok()?;
    let field = |i: usize| -> Option<usize> {
        Some(u32::from_be_bytes(bytes.get(4 * i..4 * i + 4)?.try_into().ok()?) as usize)
    };
    // A header read while Xvfb was still writing it once gave its words byte-swapped (32
    // bits per pixel read as 2^29): until the file version reads 7 big-endian, the header
    // is not ready, and the caller reads the file again.
    if field(1)? != XWD_FILE_VERSION {
        return None;
    }
    let (header, width, height, lsb_first) = (field(0)?, field(4)?, field(5)?, field(7)? == 0);
    let (bits, row, ncolors) = (field(11)?, field(12)?, field(19)?);
    let masks = [field(14)? as u32, field(15)? as u32, field(16)? as u32];
    assert_eq!(
        bits, 32,
        "the test starts Xvfb with 24-bit colour (32 bits per pixel)"
    );
    let start = header + 12 * ncolors;
    let mut pixels = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            let b: [u8; 4] = bytes
                .get(start + y * row + 4 * x..start + y * row + 4 * x + 4)?
                .try_into()
                .ok()?;
            let v = if lsb_first {
                u32::from_le_bytes(b)
            } else {
                u32::from_be_bytes(b)
            };
            pixels.push(masks.map(|m| ((v & m) >> m.trailing_zeros()) as u8));
        }
    }
    Some((width, height, pixels))
}

/// What the window shows (read from the X server's framebuffer), for both ways to the
/// window: equal to `render`'s PNG. The scene is chosen so that every frame is the same
/// image apart from anti-aliased edges: the Cornell box from far away, lit by a coloured sky
/// (which also checks the channel order), one segment per path (no noise).
#[test]
fn window_shows_the_rendered_image() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let common = [
        "--integrator",
        "pt",
        "--max-depth",
        "1",
        "--sky",
        "0.9,0.45,0.1",
        "--eye",
        "278,273,-2600",
        "--target",
        "278,273,280",
        "--width",
        "64",
        "--height",
        "48",
        "--seed",
        "3",
    ];
    let reference = dir.join("window_reference.png");
    let mut render = vec![
        "render",
        "--backend",
        "gpu",
        "--spp",
        "64",
        "--out",
        reference.to_str().unwrap(),
    ];
    render.extend(common);
    let o = runner(&render, None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let reference = image::open(&reference).unwrap().to_rgb8();
    let sky = reference.get_pixel(0, 0).0;
    assert!(sky[0] > sky[1] && sky[1] > sky[2], "sky colour {sky:?}");

    for present in ["swapchain", "copy"] {
        let fbdir = dir.join(format!("fb_{present}"));
        std::fs::create_dir_all(&fbdir).unwrap();
        let (_x, display) = start_xvfb(&["-fbdir", fbdir.to_str().unwrap()]);
        let mut view = vec!["view", "--present", present, "--exit-after", "100000"];
        view.extend(common);
        let mut viewer = runner_command(&view, Some(&display))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Poll the framebuffer until the window's pixels match (they appear after the
        // window maps and the first frames are drawn).
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
        let mut best = 0.0;
        while best < 0.97 && std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_millis(200));
            assert!(
                viewer.try_wait().unwrap().is_none(),
                "the viewer ({present}) exited early"
            );
            let Some((w, _, screen)) = read_xwd(&fbdir.join("Xvfb_screen0")) else {
                continue;
            };
            // No window manager: the window sits at the screen's top-left corner.
            let close = reference
                .enumerate_pixels()
                .filter(|(x, y, p)| {
                    let s = screen[*y as usize * w + *x as usize];
                    (0..3).all(|c| (s[c] as i32 - p.0[c] as i32).abs() <= 2)
                })
                .count();
            best = close as f64 / (reference.width() * reference.height()) as f64;
        }
        let _ = viewer.kill();
        let _ = viewer.wait();
        assert!(
            best >= 0.97,
            "the window ({present}) shows a different image: {:.1}% of pixels match",
            100.0 * best
        );
    }
}

#[test]
fn viewer_without_a_display_fails_cleanly() {
    // No display at all, and a display name that nothing answers.
    for display in [None, Some(":987654")] {
        let o = runner(
            &[
                "view",
                "--width",
                "32",
                "--height",
                "32",
                "--exit-after",
                "1",
            ],
            display,
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{display:?}: {err}");
        assert!(
            err.starts_with("error:") && err.contains("display") && err.lines().count() == 1,
            "{display:?}: {err}"
        );
        // A person is told what happened, not where in a dependency's source it was noticed.
        assert!(
            !err.contains(".rs:") && !err.contains("/src/"),
            "{display:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

#[test]
fn viewer_refuses_what_it_cannot_do_before_opening_a_window() {
    let shot = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("never.png");
    let cases: &[(&[&str], &str)] = &[
        (&["view", "--backend", "cpu"], "--backend cpu"),
        (
            &[
                "view",
                "--screenshot",
                "/nonexistent-dir/x.png",
                "--exit-after",
                "1",
            ],
            "does not exist",
        ),
        (
            &["view", "--screenshot", shot.to_str().unwrap()],
            "--exit-after",
        ),
        (&["view", "--present", "sideways"], "sideways"),
    ];
    for (args, needle) in cases {
        // With a display name that cannot be opened: the checks come first.
        let o = runner(args, Some(":987654"));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(
            o.status.code(),
            Some(if needle == &"sideways" { 2 } else { 1 }),
            "{args:?}: {err}"
        );
        assert!(
            err.contains(needle),
            "{args:?}: stderr lacks '{needle}':\n{err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

/// Type keys into the viewer's window through XTEST (Xvfb has it): `2` switches to path
/// tracing and restarts the accumulation, `P` saves what has accumulated since, `Esc` quits.
/// The saved image must be exactly `render --integrator pt` with as many samples as the
/// viewer reports, so keys, integrator switch, restart and save all work end to end.
#[test]
fn keys_switch_the_integrator_save_and_quit() {
    use std::io::BufRead;
    use x11rb::connection::Connection;
    use x11rb::protocol::xproto::{
        ConnectionExt as _, InputFocus, KEY_PRESS_EVENT, KEY_RELEASE_EVENT, MOTION_NOTIFY_EVENT,
    };
    use x11rb::protocol::xtest::ConnectionExt as _;

    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("keys");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (_x, display) = start_xvfb(&[]);
    let common = ["--width", "48", "--height", "32", "--seed", "9"];
    let mut view = vec!["view", "--integrator", "ao"];
    view.extend(common);
    let mut viewer = runner_command(&view, Some(&display))
        .current_dir(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (lines_tx, lines) = std::sync::mpsc::channel::<String>();
    let stderr = viewer.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(|l| l.ok())
        {
            if lines_tx.send(line).is_err() {
                break;
            }
        }
    });
    let wait_for = |needle: &str| -> String {
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
        while std::time::Instant::now() < deadline {
            if let Ok(line) = lines.recv_timeout(std::time::Duration::from_millis(100)) {
                if line.contains(needle) {
                    return line;
                }
            }
        }
        panic!("the viewer never printed '{needle}'");
    };
    wait_for("viewer: gpu"); // the window and the GPU are up

    let (conn, screen) = x11rb::connect(Some(&display)).unwrap();
    let root = conn.setup().roots[screen].root;
    let min = conn.setup().min_keycode;
    let count = conn.setup().max_keycode - min + 1;
    let map = conn
        .get_keyboard_mapping(min, count)
        .unwrap()
        .reply()
        .unwrap();
    let per = map.keysyms_per_keycode as usize;
    let keycode = |keysym: u32| -> u8 {
        let i = map
            .keysyms
            .iter()
            .position(|&k| k == keysym)
            .expect("keysym in the keymap");
        min + (i / per) as u8
    };
    // No window manager to give the window the keyboard focus: give it ourselves (the
    // viewer's is the only window on this server), and put the pointer over it.
    let children = conn.query_tree(root).unwrap().reply().unwrap().children;
    let window = *children
        .iter()
        .find(|&&w| {
            conn.get_geometry(w)
                .unwrap()
                .reply()
                .is_ok_and(|g| (g.width, g.height) == (48, 32))
        })
        .expect("the viewer's 48x32 window");
    conn.set_input_focus(InputFocus::PARENT, window, x11rb::CURRENT_TIME)
        .unwrap();
    conn.xtest_fake_input(MOTION_NOTIFY_EVENT, 0, 0, root, 10, 10, 0)
        .unwrap();
    let tap = |keysym: u32| {
        let code = keycode(keysym);
        conn.xtest_fake_input(KEY_PRESS_EVENT, code, 0, root, 0, 0, 0)
            .unwrap();
        conn.xtest_fake_input(KEY_RELEASE_EVENT, code, 0, root, 0, 0, 0)
            .unwrap();
        conn.flush().unwrap();
    };
    std::thread::sleep(std::time::Duration::from_millis(300));
    tap(0x32); // '2': pt
    std::thread::sleep(std::time::Duration::from_millis(800));
    tap(0x70); // 'p': save
    let saved = wait_for("saved view_0001.png");
    tap(0xff1b); // Escape
    let status = viewer.wait().unwrap();
    assert!(status.success(), "viewer exited with {status}");

    // "saved view_0001.png (N frames accumulated)"
    let n: u32 = saved
        .split('(')
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap();
    assert!(n >= 1, "{saved}");
    let reference = dir.join("reference.exr");
    let spp = n.to_string();
    let mut render = vec![
        "render",
        "--backend",
        "gpu",
        "--integrator",
        "pt",
        "--spp",
        &spp,
        "--out",
        reference.to_str().unwrap(),
    ];
    render.extend(common);
    let o = runner(&render, None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let a = runner::output::read_image(&dir.join("view_0001.exr")).unwrap();
    let b = runner::output::read_image(&reference).unwrap();
    let e = runner::output::compare(&a, &b).unwrap();
    assert!(
        e.identical > 0.97,
        "after '2' and 'P' the viewer saved something else than pt with {n} spp: {e:?}"
    );
}
